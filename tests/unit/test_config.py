"""The robot YAML loader: defaults, overrides, and every validation error with its line number."""

from __future__ import annotations

import re
from dataclasses import fields
from pathlib import Path

import pytest
import yaml

from akarm import ConfigError, ConfigWarning
from akarm.config import BusConfig, JointConfig
from akarm.errors import ConfigProblem
from akarm.robotfile import reference
from akarm.robotfile.load import load_robot
from akarm.robotfile.nodes import Findings
from akarm.robotfile.schema import JOINT, NO_DEFAULT, PAYLOAD, ROBOT_FILE, Context, Section

from .conftest import ROBOTS, ROOT

URDF = (ROBOTS / "planar2.urdf").resolve()

# A valid planar2 description; tests change one thing at a time.
BASE = f"""\
name: t
urdf: {URDF}
rate_hz: 500
defaults:
  limits: {{velocity: 3.0, acceleration: 15.0, jerk: 150.0}}
  gains: {{kp: 20.0, kd: 1.0}}
joints:
  - name: shoulder
    can_id: 1
    motor: AK80-9
  - name: elbow
    can_id: 2
    motor: AK60-6
"""


def write(tmp_path: Path, text: str, name: str = "robot.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def problems(tmp_path: Path, text: str, **overrides: object) -> list[ConfigProblem]:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_robot(path, **overrides)  # type: ignore[arg-type]
    for p in info.value.problems:
        assert p.file == str(path)
        assert p.fix, f"no fix for {p}"
    return info.value.problems


def line_of(text: str, marker: str) -> int:
    """1-based line of the only line containing ``marker``."""
    hits = [i + 1 for i, line in enumerate(text.splitlines()) if marker in line]
    assert len(hits) == 1, f"{marker!r} is on lines {hits}"
    return hits[0]


def one(found: list[ConfigProblem], fragment: str) -> ConfigProblem:
    hits = [p for p in found if fragment in p.message]
    assert len(hits) == 1, f"{fragment!r} in {[str(p) for p in found]}"
    return hits[0]


# ----------------------------------------------------------------------------- valid files, defaults


def test_minimal_file_gets_sensible_defaults(tmp_path: Path) -> None:
    config = load_robot(write(tmp_path, BASE))
    assert config.name == "t"
    assert config.urdf == URDF
    assert config.source == tmp_path / "robot.yaml"
    assert config.buses == {"arm": BusConfig("arm", "socketcan", "can0", 1_000_000)}  # one bus implied
    assert config.rate_hz == 500.0
    assert config.gravity == (0.0, 0.0, -9.81)
    assert config.tool_frame is None and config.payload is None and config.poses == {}
    sh, el = config.joints
    assert config.joint_names == ("shoulder", "elbow")
    assert (sh.bus, sh.can_id, sh.motor.name, sh.mode, sh.firmware) == ("arm", 1, "AK80-9", "mit", "v2")
    assert (sh.direction, sh.offset) == (1, 0.0)
    assert (sh.limits.lower, sh.limits.upper) == (-1.8, 1.8)  # from the URDF
    assert (el.limits.lower, el.limits.upper) == (-2.4, 2.4)
    assert (sh.limits.velocity, sh.limits.acceleration, sh.limits.jerk) == (3.0, 15.0, 150.0)
    assert sh.limits.torque == 18.0 and el.limits.torque == 15.0  # default: the motor's t_max
    assert (sh.gains.kp, sh.gains.kd) == (20.0, 1.0)


def test_full_joint_and_top_level_keys(tmp_path: Path) -> None:
    text = f"""\
name: full
urdf: {URDF}
tool_frame: tool0
gravity: [0.0, 9.81, 0.0]
payload: {{mass: 0.5, com: [0.0, 0.0, 0.04]}}
rate_hz: 250
buses:
  left: {{interface: pcan, channel: PCAN_USBBUS1, bitrate: 500000}}
  right: {{channel: can1}}
poses:
  home: [0, 0]
  up: [1.0, -0.5]
motors:
  AK80-9: {{v_max: 25.64}}
  MyAK: {{base: AK60-6, t_max: 12.0, firmware: v3}}
joints:
  - name: shoulder
    bus: left
    can_id: 5
    motor: ak80-9
    mode: mit
    firmware: v3
    direction: -1
    offset: 0.25
    limits: {{lower: -1.0, upper: 1.5, velocity: 2.0, acceleration: 10.0, jerk: 100.0, torque: 12.0}}
    gains: {{kp: 60.0, kd: 2.0}}
    reply_id: 5
    feedback_timeout: 0.03
    max_temperature: 70
    can_timeout: 0.1
  - name: elbow
    bus: right
    can_id: 5
    motor: MyAK
    mode: servo
    status_rate_hz: 100
    limits: {{velocity: 2.0, acceleration: 10.0, jerk: 100.0}}
"""
    c = load_robot(write(tmp_path, text))
    assert c.tool_frame == "tool0" and c.gravity == (0.0, 9.81, 0.0) and c.rate_hz == 250.0
    assert c.payload is not None and (c.payload.mass, c.payload.com) == (0.5, (0.0, 0.0, 0.04))
    assert c.buses["left"] == BusConfig("left", "pcan", "PCAN_USBBUS1", 500_000)
    assert c.buses["right"] == BusConfig("right", "socketcan", "can1", 1_000_000)
    assert c.poses == {"home": (0.0, 0.0), "up": (1.0, -0.5)}
    sh, el = c.joints
    assert sh.motor.v_max == 25.64 and sh.motor.t_max == 18.0  # override of one field
    assert (sh.bus, sh.can_id, sh.firmware, sh.direction, sh.offset) == ("left", 5, "v3", -1, 0.25)
    assert (sh.limits.lower, sh.limits.upper, sh.limits.torque) == (-1.0, 1.5, 12.0)
    assert (sh.reply_id, sh.feedback_timeout, sh.max_temperature, sh.can_timeout) == (5, 0.03, 70.0, 0.1)
    assert el.motor.name == "MyAK" and el.motor.t_max == 12.0 and el.motor.gear_ratio == 6.0
    assert (el.mode, el.firmware, el.status_rate_hz) == ("servo", "v3", 100.0)  # firmware from the motor entry
    assert el.gains.kp == 0.0  # servo joints need no gains
    assert c.catalogue is not None and "MyAK" in c.catalogue


def test_firmware_defaults_to_the_motor_entry(tmp_path: Path) -> None:
    c = load_robot(write(tmp_path, BASE.replace("motor: AK60-6", "motor: AK60-6-V3")))
    assert c.joints[1].firmware == "v3" and c.joints[0].firmware == "v2"


def test_urdf_path_is_relative_to_the_yaml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sub = tmp_path / "robots"
    sub.mkdir()
    (sub / "arm.urdf").write_text(URDF.read_text())
    write(sub, BASE.replace(str(URDF), "arm.urdf"))
    monkeypatch.chdir(tmp_path)
    assert load_robot("robots/robot.yaml").urdf == (sub / "arm.urdf").resolve()


def test_overrides(tmp_path: Path) -> None:
    path = write(tmp_path, BASE)
    c = load_robot(path, interface="virtual", channel="sim", bitrate=500_000, rate_hz=250)
    assert c.buses["arm"] == BusConfig("arm", "virtual", "sim", 500_000)
    assert c.rate_hz == 250.0
    two = BASE.replace("rate_hz: 500", "rate_hz: 500\nbuses: {a: {channel: can0}, b: {channel: can1}}")
    two = two.replace("can_id: 1", "can_id: 1\n    bus: a").replace("can_id: 2", "can_id: 2\n    bus: b")
    c2 = load_robot(write(tmp_path, two, "two.yaml"), interface="virtual", channel="x")
    assert (c2.buses["a"].channel, c2.buses["b"].channel) == ("x-a", "x-b")
    c3 = load_robot(write(tmp_path, two, "two.yaml"), channel={"b": "vcan1"})
    assert (c3.buses["a"].channel, c3.buses["b"].channel) == ("can0", "vcan1")
    short = two.replace("{a: {channel: can0}, b: {channel: can1}}", "{a: can2, b: {bitrate: 500000}}")
    c4 = load_robot(write(tmp_path, short, "short.yaml"))
    assert c4.buses == {"a": BusConfig("a", channel="can2"), "b": BusConfig("b", bitrate=500_000)}


# ----------------------------------------------------------------------------- file-level errors


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_robot(tmp_path / "nope.yaml")
    (p,) = info.value.problems
    assert p.line is None and "not found" in p.message


@pytest.mark.parametrize(("text", "line"), [
    ("name: t\njoints:\n  - name: a\n   can_id: 1\n", 4),      # bad indentation
    ("name: t\nurdf: [a, b\njoints: []\n", 3),                 # unclosed flow sequence (found at the next key)
    ("name: t\nurdf: 'x.urdf\n", 3),                           # unclosed quote
    ("name: t\n\turdf: x\n", 2),                               # a tab
])
def test_yaml_syntax_error_is_a_config_error_with_its_line(tmp_path: Path, text: str, line: int) -> None:
    (p,) = problems(tmp_path, text)
    assert p.message.startswith("not valid YAML")
    assert p.line == line


def test_empty_file_and_wrong_root(tmp_path: Path) -> None:
    (p,) = problems(tmp_path, "# nothing\n")
    assert "empty" in p.message
    (p,) = problems(tmp_path, "- a\n- b\n")
    assert "must be a mapping" in p.message and p.line == 1


def test_unknown_top_level_key_with_did_you_mean(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nrate_hzz: 400\ntoolframe: tool0")
    found = problems(tmp_path, text)
    p = one(found, "'rate_hzz'")
    assert "unknown key" in p.message and "did you mean 'rate_hz'" in p.message
    assert p.line == line_of(text, "rate_hzz")
    assert "known keys" in p.fix
    assert "did you mean 'tool_frame'" in one(found, "'toolframe'").message


def test_unknown_joint_key_with_did_you_mean(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK60-6", "motor: AK60-6\n    gian: {kp: 1}")
    found = problems(tmp_path, text)
    p = one(found, "'gian'")
    assert "did you mean 'gain" in p.message and p.line == line_of(text, "gian")


def test_unknown_keys_in_limits_gains_defaults_and_buses(tmp_path: Path) -> None:
    text = BASE.replace("jerk: 150.0}", "jerk: 150.0, velocty: 2}").replace(
        "kd: 1.0}", "kd: 1.0}\n  can_id: 3").replace("rate_hz: 500", "rate_hz: 500\nbuses:\n  arm: {chanel: can0}")
    found = problems(tmp_path, text)
    assert "did you mean 'velocity'" in one(found, "'velocty'").message
    assert one(found, "'velocty'").line == line_of(text, "velocty")
    assert one(found, "'can_id'").line == line_of(text, "  can_id: 3")
    assert "did you mean 'channel'" in one(found, "'chanel'").message
    assert one(found, "'chanel'").line == line_of(text, "chanel")


def test_duplicate_yaml_key(tmp_path: Path) -> None:
    text = BASE.replace("    can_id: 2", "    can_id: 2\n    can_id: 3")
    p = one(problems(tmp_path, text), "given twice")
    assert p.line == line_of(text, "can_id: 3") and f"line {line_of(text, 'can_id: 2')}" in p.message


# ----------------------------------------------------------------------------- types and ranges


def test_wrong_types(tmp_path: Path) -> None:
    text = (BASE.replace("can_id: 1", "can_id: one")
            .replace("motor: AK60-6", "motor: AK60-6\n    offset: [1]\n    gains: [20, 1]")
            .replace("rate_hz: 500", "rate_hz: fast\ngravity: [0, 0]"))
    found = problems(tmp_path, text)
    assert one(found, "can_id must be a whole number").line == line_of(text, "can_id: one")
    assert one(found, "offset must be a number").line == line_of(text, "offset:")
    assert one(found, "gains must be a mapping").line == line_of(text, "gains: [20")
    assert one(found, "rate_hz must be a number").line == line_of(text, "rate_hz:")
    assert one(found, "gravity must have 3 numbers").line == line_of(text, "gravity:")


@pytest.mark.parametrize("rate", ["1.0e-300", "5", "20001"])
def test_a_loop_rate_outside_what_akarm_runs_is_refused(tmp_path: Path, rate: str) -> None:
    """rate_hz 1e-300 passed akarm check, and the loop then crashed in time.sleep (OverflowError)."""
    text = BASE.replace("rate_hz: 500", f"rate_hz: {rate}")
    assert one(problems(tmp_path, text), "rate_hz must be within 10..10000").line == line_of(text, "rate_hz:")


def test_unknown_motor_lists_the_known_ones(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK80-9", "motor: AK80-99")
    p = one(problems(tmp_path, text), "unknown motor model 'AK80-99'")
    assert p.line == line_of(text, "AK80-99")
    assert "did you mean 'AK80-9'" in p.message
    for known in ("AK10-9", "AK60-6", "AK70-10", "AK80-64"):
        assert known in p.fix
    assert "motors:" in p.fix


def test_motors_section_problems_get_their_lines(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nmotors:\n  AK80-9:\n    vmax: 25.64\n"
                        "  NewAK:\n    t_max: 10\n  Based: {base: AK99, t_max: -1}")
    found = problems(tmp_path, text)
    assert one(found, "unknown motor field 'vmax'").line == line_of(text, "vmax")
    assert "did you mean 'v_max'" in one(found, "'vmax'").message
    assert one(found, "lacks 'p_max'").line == line_of(text, "NewAK")
    assert one(found, "unknown motor model 'AK99'").line == line_of(text, "Based")
    assert one(found, "t_max must be a positive finite number").line == line_of(text, "Based")
    # a joint using a broken entry is not reported again as an unknown model
    text = text.replace("motor: AK60-6", "motor: NewAK")
    found = problems(tmp_path, text)
    assert not [p for p in found if "unknown motor model 'NewAK'" in p.message]
    assert one(found, "lacks 'p_max'")


def test_duplicate_can_id_on_one_bus(tmp_path: Path) -> None:
    text = BASE.replace("can_id: 2", "can_id: 1")
    p = one(problems(tmp_path, text), "already used")
    assert p.line == line_of(text, "motor: AK60-6") - 1  # the elbow's can_id line
    assert "CAN ID 1 on bus 'arm'" in p.message and "'shoulder'" in p.message


def test_same_can_id_on_two_buses_is_fine(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nbuses: {a: {channel: can0}, b: {channel: can1}}")
    text = text.replace("can_id: 1", "can_id: 1\n    bus: a").replace("can_id: 2", "can_id: 1\n    bus: b")
    c = load_robot(write(tmp_path, text))
    assert [(j.bus, j.can_id) for j in c.joints] == [("a", 1), ("b", 1)]


@pytest.mark.parametrize("value", [0, 128, -3])
def test_can_id_out_of_range(tmp_path: Path, value: int) -> None:
    text = BASE.replace("can_id: 2", f"can_id: {value}")
    p = one(problems(tmp_path, text), "can_id must be within 1..127")
    assert p.line == line_of(text, f"can_id: {value}") and "0 is the host" in p.fix


def test_direction_mode_firmware_choices(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    direction: 2\n    mode: torque\n    firmware: v4")
    found = problems(tmp_path, text)
    assert one(found, "direction must be 1 or -1, got 2").line == line_of(text, "direction")
    assert one(found, "mode must be mit or servo, got 'torque'").line == line_of(text, "mode:")
    assert one(found, "firmware must be v2 or v3, got 'v4'").line == line_of(text, "firmware")


def test_unknown_bus_and_missing_bus(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nbuses: {arm: {channel: can0}, aux: {channel: can1}}")
    text = text.replace("can_id: 1", "can_id: 1\n    bus: amr")
    found = problems(tmp_path, text)
    p = one(found, "unknown bus 'amr'")
    assert p.line == line_of(text, "bus: amr") and "did you mean 'arm'" in p.message and "arm, aux" in p.fix
    p = one(found, "has no `bus:`")  # two buses: the elbow must say which
    assert p.line == line_of(text, "name: elbow")


def test_joint_not_in_urdf_fixed_and_unconfigured(tmp_path: Path) -> None:
    text = BASE.replace("name: elbow", "name: elbw").replace("name: shoulder", "name: tool0_joint")
    found = problems(tmp_path, text)
    p = one(found, "'elbw' is not in the URDF")
    assert p.line == line_of(text, "elbw") and "did you mean 'elbow'" in p.message
    assert "shoulder, elbow" in p.fix
    p = one(found, "'tool0_joint' is fixed")
    urdf_line = line_of(URDF.read_text(encoding="utf-8"), '<joint name="tool0_joint"')
    assert p.line == line_of(text, "tool0_joint") and f"URDF line {urdf_line})" in p.message
    # URDF joints without a motor are not problems (they are held still, with a warning)
    assert len(found) == 2


def test_urdf_joint_without_a_motor_is_held_at_zero_with_a_warning(tmp_path: Path) -> None:
    text = BASE.replace("  - name: elbow\n    can_id: 2\n    motor: AK60-6\n", "")
    urdf_line = line_of(URDF.read_text(encoding="utf-8"), '<joint name="elbow"')
    with pytest.warns(ConfigWarning, match=f"'elbow' .revolute, URDF line {urdf_line}. has no motor in joints"):
        config = load_robot(write(tmp_path, text))
    assert config.joint_names == ("shoulder",) and config.locked == {"elbow": 0.0}
    (w,) = config.warnings
    assert w.line == line_of(text, "joints:") and "locked: {elbow: POSITION}" in w.fix
    # `locked:` says where: no warning, and the model holds it there (its mass still counts)
    held = load_robot(write(tmp_path, text + "locked: {elbow: 1.2}\n"))
    assert held.locked == {"elbow": 1.2} and held.warnings == ()


def test_locked_entries_are_checked(tmp_path: Path) -> None:
    text = BASE.replace("  - name: elbow\n    can_id: 2\n    motor: AK60-6\n", "") + (
        "locked:\n  elbw: 0.0\n  shoulder: 0.1\n")
    found = problems(tmp_path, text)
    p = one(found, "locked: 'elbw' is not a joint of the URDF")
    assert p.line == line_of(text, "elbw:") and "did you mean 'elbow'" in p.message and "elbow" in p.fix
    assert one(found, "'shoulder' is also under joints:").line == line_of(text, "shoulder: 0.1")
    bad = text.replace("  elbw: 0.0\n  shoulder: 0.1\n", "  elbow: 3.0\n")
    p = one(problems(tmp_path, bad), "locked: elbow = 3 rad is outside its URDF limits [-2.4, 2.4]")
    assert p.line == line_of(bad, "elbow: 3.0")


def test_joint_listed_twice(tmp_path: Path) -> None:
    text = BASE.replace("name: elbow", "name: shoulder")
    found = problems(tmp_path, text)
    p = one(found, "listed twice")
    assert p.line == line_of(text, "can_id: 2") - 1


def test_missing_urdf_file(tmp_path: Path) -> None:
    text = BASE.replace(str(URDF), "missing.urdf")
    (p,) = problems(tmp_path, text)  # joint checks against the URDF are skipped, the rest still run
    assert "missing.urdf" in p.message and "not found" in p.message and p.line == 2


def urdf_problems(tmp_path: Path, urdf_text: str) -> list[ConfigProblem]:
    """The problems of BASE with its URDF replaced by ``urdf_text``: reported in the URDF, at its lines."""
    (tmp_path / "u.urdf").write_text(urdf_text)
    path = write(tmp_path, BASE.replace(str(URDF), "u.urdf"))
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    for p in info.value.problems:
        assert p.file == str((tmp_path / "u.urdf").resolve()) and p.fix, p
    return info.value.problems


def test_urdf_that_is_not_xml(tmp_path: Path) -> None:
    (p,) = urdf_problems(tmp_path, "<robot name='x'>\n  <link name='a'>\n</robot>\n")
    assert "not well-formed XML" in p.message and p.line == 3


def test_urdf_link_that_does_not_exist(tmp_path: Path) -> None:
    (p,) = urdf_problems(tmp_path, "<robot name='x'><link name='a'/>\n<joint name='shoulder' type='revolute'>"
                         "<parent link='a'/><child link='b'/><limit lower='-1' upper='1' effort='1' velocity='1'/>"
                         "</joint></robot>")
    assert "joint 'shoulder': its child link 'b' is not declared" in p.message and p.line == 2


def test_urdf_that_pinocchio_rejects(tmp_path: Path) -> None:
    # what akarm's own reading does not look at: the YAML's urdf: line, with urdfdom's reason
    text = URDF.read_text().replace('<parent link="base_link"/>', '<parent link="base_link"/><calibration rising="x"/>')
    (tmp_path / "bad.urdf").write_text(text)
    p = one(problems(tmp_path, BASE.replace(str(URDF), "bad.urdf")), "not a valid robot model")
    assert p.line == 2 and "rising value (x) is not a valid float" in p.message


def test_tool_frame_not_in_urdf(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\ntool_frame: tool1")
    p = one(problems(tmp_path, text), "tool_frame 'tool1'")
    assert p.line == line_of(text, "tool1") and "did you mean 'tool0'" in p.message


# ----------------------------------------------------------------------------- limits and gains


def test_urdf_limits_outside_the_motor_position_range(tmp_path: Path) -> None:
    wide = URDF.read_text().replace('lower="-1.8" upper="1.8"', 'lower="-13.0" upper="13.0"')
    (tmp_path / "wide.urdf").write_text(wide)
    text = BASE.replace(str(URDF), "wide.urdf")
    p = one(problems(tmp_path, text), "outside the AK80-9's MIT position range ±12.5 rad")
    assert p.line == line_of(text, "name: shoulder") and "(URDF)" in p.message
    # narrowing in the YAML fixes it
    fixed = text.replace("motor: AK80-9", "motor: AK80-9\n    limits: {lower: -6.0, upper: 6.0}")
    assert load_robot(write(tmp_path, fixed)).joints[0].limits.lower == -6.0


def test_offset_and_direction_move_the_range_past_p_max(tmp_path: Path) -> None:
    # joint [-1.8, 1.8] with offset 11: motor = joint - 11 in [-12.8, -9.2], past -12.5
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    offset: 11.0")
    p = one(problems(tmp_path, text), "position range [-1.8, 1.8] rad (URDF) is motor [-12.8, -9.2]")
    assert p.line == line_of(text, "name: shoulder")
    # direction -1, offset -11: motor = -(joint + 11) in [-12.8, -9.2] as well
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    offset: -11.0\n    direction: -1")
    assert "direction -1" in one(problems(tmp_path, text), "is motor [-12.8, -9.2]").message
    # direction -1, offset +11: motor = -(joint - 11) in [9.2, 12.8]: too far the other way
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    offset: 11.0\n    direction: -1")
    one(problems(tmp_path, text), "is motor [9.2, 12.8]")
    # within range
    load_robot(write(tmp_path, BASE.replace("motor: AK80-9", "motor: AK80-9\n    offset: 10.0")))


def test_servo_joint_range_is_the_status_frame_range(tmp_path: Path) -> None:
    # a rotor-measured servo model: ±3276.7° at the rotor is ±9.53 rad at the output of a 6:1 motor
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nmotors:\n  AK60-6: {servo_position: rotor}").replace(
        "motor: AK60-6", "motor: AK60-6\n    mode: servo\n    offset: 8.0")
    p = one(problems(tmp_path, text), "servo status frame's range ±9.53")
    assert p.line == line_of(text, "name: elbow")
    # in MIT mode the same offset is fine (|8 ± 2.4| < 12.5)
    load_robot(write(tmp_path, text.replace("mode: servo", "mode: mit")))


def test_yaml_may_only_narrow_urdf_limits(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK60-6", "motor: AK60-6\n    limits: {lower: -3.0, upper: 2.0}")
    p = one(problems(tmp_path, text), "lower limit -3 is below the URDF's -2.4")
    assert p.line == line_of(text, "lower: -3.0")
    text = BASE.replace("motor: AK60-6", "motor: AK60-6\n    limits: {lower: 1.0, upper: 0.5}")
    p = one(problems(tmp_path, text), "is empty")
    assert p.line == line_of(text, "lower: 1.0")
    c = load_robot(write(tmp_path, BASE.replace("motor: AK60-6", "motor: AK60-6\n    limits: {lower: -1, upper: 2}")))
    limits = c.joints[1].limits
    assert (limits.lower, limits.upper, limits.velocity) == (-1.0, 2.0, 3.0)  # merged with defaults


def test_missing_and_non_positive_motion_limits(tmp_path: Path) -> None:
    text = BASE.replace("  limits: {velocity: 3.0, acceleration: 15.0, jerk: 150.0}\n", "").replace(
        "motor: AK60-6", "motor: AK60-6\n    limits: {velocity: 0, acceleration: -1.0}")
    found = problems(tmp_path, text)
    limits_line = line_of(text, "velocity: 0")
    assert one(found, "'elbow': velocity limit must be positive, got 0").line == limits_line
    assert one(found, "'elbow': acceleration limit must be positive, got -1").line == limits_line
    assert one(found, "'elbow': no jerk limit").line == limits_line
    # the shoulder has no limits at all: reported at its name line
    for key in ("velocity", "acceleration", "jerk"):
        assert one(found, f"'shoulder': no {key} limit").line == line_of(text, "name: shoulder")


def test_velocity_above_motor_v_max(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nmotors:\n  AK80-9: {v_max: 2.5}")
    p = one(problems(tmp_path, text), "velocity limit 3 rad/s is above the AK80-9's 2.5 rad/s")
    assert p.line == line_of(text, "velocity: 3.0")  # from the defaults block


def test_torque_limit_above_t_max(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    limits: {torque: 20.0}")
    p = one(problems(tmp_path, text), "torque limit 20 N·m is above the AK80-9's t_max 18 N·m")
    assert p.line == line_of(text, "torque: 20.0")
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    limits: {torque: 0}")
    assert one(problems(tmp_path, text), "torque limit must be positive").line == line_of(text, "torque: 0")


def test_gains_out_of_range(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK80-9", "motor: AK80-9\n    gains: {kp: 600.0, kd: 6.0}").replace(
        "motor: AK60-6", "motor: AK60-6\n    gains: {kp: -1, kd: 1.0}")
    found = problems(tmp_path, text)
    assert one(found, "kp must be within 0..500, got 600").line == line_of(text, "kp: 600.0")
    assert one(found, "kd must be within 0..5, got 6").line == line_of(text, "kp: 600.0")
    assert one(found, "kp must be within 0..500, got -1").line == line_of(text, "kp: -1")


def test_mit_joint_needs_gains_servo_joint_does_not(tmp_path: Path) -> None:
    text = BASE.replace("  gains: {kp: 20.0, kd: 1.0}\n", "").replace("motor: AK60-6", "motor: AK60-6\n    mode: servo")
    found = problems(tmp_path, text)
    assert one(found, "'shoulder': MIT joint without gain kp").line == line_of(text, "name: shoulder")
    assert all("elbow" not in p.message for p in found)


def test_continuous_joint_needs_lower_and_upper(tmp_path: Path) -> None:
    cont = URDF.read_text().replace('name="elbow" type="revolute"', 'name="elbow" type="continuous"')
    (tmp_path / "cont.urdf").write_text(cont)
    text = BASE.replace(str(URDF), "cont.urdf")
    p = one(problems(tmp_path, text), "'elbow' is continuous in the URDF and has no lower or upper limit")
    assert p.line == line_of(text, "name: elbow") and "±p_max" in p.fix
    ok = text.replace("motor: AK60-6", "motor: AK60-6\n    limits: {lower: -6.0, upper: 6.0}")
    assert load_robot(write(tmp_path, ok)).joints[1].limits.upper == 6.0
    # and that range must still fit the motor
    bad = text.replace("motor: AK60-6", "motor: AK60-6\n    limits: {lower: -13.0, upper: 6.0}")
    assert one(problems(tmp_path, bad), "MIT position range").line == line_of(bad, "lower: -13.0")


def test_prismatic_joint_is_not_supported(tmp_path: Path) -> None:
    pris = URDF.read_text().replace('name="elbow" type="revolute"', 'name="elbow" type="prismatic"')
    (tmp_path / "pris.urdf").write_text(pris)
    text = BASE.replace(str(URDF), "pris.urdf")
    assert one(problems(tmp_path, text), "'elbow' is prismatic").line == line_of(text, "name: elbow")


def test_other_joint_options_are_checked(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK60-6", "motor: AK60-6\n    status_rate_hz: 600\n    feedback_timeout: 0\n"
                        "    max_temperature: hot\n    reply_id: 4000\n    can_timeout: -1")
    found = problems(tmp_path, text)
    assert one(found, "status_rate_hz must be within 1..500").line == line_of(text, "status_rate_hz")
    assert one(found, "feedback_timeout must be positive").line == line_of(text, "feedback_timeout")
    assert one(found, "max_temperature must be a number").line == line_of(text, "max_temperature")
    assert one(found, "reply_id must be within 0..2047").line == line_of(text, "reply_id")
    assert one(found, "can_timeout must be within 0..").line == line_of(text, "can_timeout")


# ----------------------------------------------------------------------------- poses, payload, rate


def test_pose_wrong_length_and_outside_limits(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\nposes:\n  home: [0, 0, 0]\n  far:\n    - 0.0\n    - 2.5\n"
                        "  ok: [0.5, -0.5]")
    found = problems(tmp_path, text)
    p = one(found, "pose 'home' has 3 values for 2 joints")
    assert p.line == line_of(text, "home:") and "shoulder, elbow" in p.fix
    p = one(found, "pose 'far': elbow = 2.5 rad is outside its limits [-2.4, 2.4]")
    assert p.line == line_of(text, "- 2.5")
    assert len(found) == 2


def test_payload_problems(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 500\npayload: {mass: -0.5, com: [0, 0]}")
    found = problems(tmp_path, text)
    assert one(found, "payload mass must be within 0..").line == line_of(text, "payload")
    assert one(found, "payload com must have 3 numbers").line == line_of(text, "payload")


def test_rate_over_the_bus_limit(tmp_path: Path) -> None:
    text = BASE.replace("rate_hz: 500", "rate_hz: 5000")
    p = one(problems(tmp_path, text), "rate_hz 5000 puts 222 % (worst case 270 %) on bus 'arm'")
    assert p.line == line_of(text, "rate_hz")
    assert "at most 1801 Hz" in p.fix
    # the same as an override: no line in the file
    p = one(problems(tmp_path, BASE, rate_hz=5000), "given as an override")
    assert p.line is None
    # six joints: 500 Hz fits (nominal 67 %), 700 Hz does not (nominal 93 %)
    six = (ROBOTS / "arm6.yaml").read_text().replace("urdf: arm6.urdf", f"urdf: {ROBOTS / 'arm6.urdf'}")
    load_robot(write(tmp_path, six.replace("rate_hz: 480", "rate_hz: 500"), "six.yaml"))
    found = problems(tmp_path, six.replace("rate_hz: 480", "rate_hz: 700"))
    assert "93 %" in one(found, "rate_hz 700").message


def test_every_problem_is_reported_in_one_error_sorted_by_line(tmp_path: Path) -> None:
    text = f"""\
name: many
urdf: {URDF}
rate_hzz: 500
buses: {{arm: {{channel: can0}}}}
joints:
  - name: shoulder
    bus: arm
    can_id: 0
    motor: AK80-99
    mode: mitt
    direction: 0
    limits: {{velocity: -1, acceleration: 10, jerk: 100, torque: 30}}
    gains: {{kp: 1000, kd: 1}}
  - name: elbow
    bus: can
    can_id: 1
    motor: AK60-6
    limits: {{velocity: 1, acceleration: 10, jerk: 100}}
    gains: {{kp: 10, kd: 9}}
  - name: wrist
    can_id: 2
    motor: AK60-6
poses:
  home: [0, 0]
"""
    found = problems(tmp_path, text)
    expected = {
        "unknown key 'rate_hzz'": "rate_hzz",
        "can_id must be within 1..127": "can_id: 0",
        "unknown motor model 'AK80-99'": "AK80-99",
        "mode must be mit or servo, got 'mitt'": "mitt",
        "direction must be 1 or -1": "direction: 0",
        "velocity limit must be positive": "velocity: -1",
        "kp must be within 0..500": "kp: 1000",
        "unknown bus 'can'": "bus: can",
        "kd must be within 0..5, got 9": "kd: 9",
        "'wrist' is not in the URDF": "name: wrist",
    }
    for fragment, marker in expected.items():
        assert one(found, fragment).line == line_of(text, marker), fragment
    lines = [p.line for p in found if p.line is not None]
    assert lines == sorted(lines)
    assert len(found) >= len(expected)
    # the error's text lists them all, with lines
    with pytest.raises(ConfigError) as info:
        load_robot(tmp_path / "robot.yaml")
    rendered = str(info.value)
    assert f"{len(found)} problems" in rendered
    assert f"robot.yaml:{line_of(text, 'AK80-99')}: joint 'shoulder': unknown motor model" in rendered


def test_friction_per_joint_and_from_defaults(tmp_path) -> None:
    """`friction:` (identified values) overrides the catalogue's typical friction; bad values are reported."""
    from akarm.robotfile.load import load_robot

    src = (ROBOTS / "planar2.yaml").read_text()
    gains = "    gains: {kp: 40.0, kd: 1.5}"
    src = src.replace(gains, gains + "\n    friction: {coulomb: 0.2, viscous: 0.01}")
    f = tmp_path / "p.yaml"
    f.write_text(src)
    (tmp_path / "planar2.urdf").write_text((ROBOTS / "planar2.urdf").read_text())
    cfg = load_robot(f)
    assert cfg.joint("shoulder").friction_model().coulomb == 0.2
    assert cfg.joint("shoulder").friction_model().viscous == 0.01
    assert cfg.joint("elbow").friction is None
    assert cfg.joint("elbow").friction_model().coulomb == cfg.joint("elbow").motor.friction_coulomb
    f.write_text(src.replace("coulomb: 0.2", "coulomb: -1").replace("viscous: 0.01", "viscos: 0.01"))
    with pytest.raises(ConfigError) as info:
        load_robot(f)
    text = str(info.value)
    assert "friction coulomb" in text and "viscos" in text and "did you mean 'viscous'" in text


def test_supervisor_limits_per_joint_and_from_defaults(tmp_path: Path) -> None:
    text = BASE.replace("motor: AK60-6", "motor: AK60-6\n    following_error: 0.15\n    stuck_travel: 0.03")
    c = load_robot(write(tmp_path, text))
    el = c.joint("elbow")
    assert (el.following_error, el.stuck_travel) == (0.15, 0.03)
    assert c.joints[0].following_error is None  # derived by the supervisor (akarm.control.safety)
    bad = BASE.replace("motor: AK60-6", "motor: AK60-6\n    following_error: 0\n    stuck_travel: far")
    found = problems(tmp_path, bad)
    assert one(found, "following_error must be positive").line == line_of(bad, "following_error")
    assert one(found, "stuck_travel must be a number").line == line_of(bad, "stuck_travel")


def test_problems_in_defaults_are_reported_once_and_fail_every_joint(tmp_path: Path) -> None:
    text = BASE.replace("jerk: 150.0}", "jerk: -1}").replace("kd: 1.0}", "kd: 1.0}\n  max_temperature: hot")
    found = problems(tmp_path, text)
    assert one(found, "defaults: jerk limit must be positive, got -1").line == line_of(text, "jerk: -1")
    assert one(found, "defaults: max_temperature must be a number").line == line_of(text, "max_temperature")
    # the joints that take them are not built: no pose, bus load or gravity finding follows from them
    assert len(found) == 2


@pytest.mark.parametrize("key", ["1", "null", "[a]", "true"])
def test_a_key_that_is_not_text_is_a_problem_not_a_traceback(tmp_path: Path, key: str) -> None:
    for where in ("poses:\n  {key}: [0, 0]", "buses:\n  {key}: can0", "locked:\n  {key}: 0.1",
                  "buses:\n  arm: {{{key}: 1}}"):
        entry = where.format(key=key)
        text = BASE.replace("rate_hz: 500", "rate_hz: 500\n" + entry)
        p = one(problems(tmp_path, text), "is not a name")
        assert p.line == line_of(text, entry.splitlines()[-1]), entry


# ----------------------------------------------------------------------------- the schema, the one description


def test_the_schema_defaults_are_what_the_loader_gives(tmp_path: Path) -> None:
    config = load_robot(write(tmp_path, BASE.replace("rate_hz: 500\n", "") + "payload: {mass: 1.0}\n"))
    joint = config.joints[0]
    plain = [k for k in JOINT.keys if k.default is not NO_DEFAULT]
    assert {k.name for k in plain} >= {"mode", "direction", "offset", "max_temperature", "status_rate_hz"}
    for key in plain:
        assert getattr(joint, key.name) == key.default, key.name
    assert config.rate_hz == ROBOT_FILE["rate_hz"].default and config.gravity == ROBOT_FILE["gravity"].default
    assert config.payload is not None and config.payload.com == PAYLOAD["com"].default


def test_every_joint_setting_is_a_key_of_the_schema() -> None:
    """A JointConfig field the file cannot set is a schema key forgotten (or one to name here)."""
    from_sections = {"limits", "gains", "friction", "collision_threshold"}  # collision_threshold: collision: threshold
    assert {f.name for f in fields(JointConfig)} - set(JOINT.names) <= from_sections
    assert {"collision", "limits", "gains", "friction"} <= {k.name for k in JOINT.keys if isinstance(k.kind, Section)}


def test_the_reference_is_written_from_the_schema() -> None:
    written = (ROOT / "docs" / "robot-file.md").read_text(encoding="utf-8")
    assert written == reference.markdown(), "run: python -m akarm.robotfile.reference > docs/robot-file.md"
    for section in (ROBOT_FILE, JOINT, PAYLOAD):
        for key in section.keys:
            assert f"| `{key.name}` |" in written


def readme_example() -> str:
    """The annotated robot file of docs/robot-file-guide.md, with its commented-out entries (`# locked:`) taken in."""
    readme = (ROOT / "docs" / "robot-file-guide.md").read_text(encoding="utf-8")
    match = re.search(r"An annotated example.*?```yaml\n(.*?)```", readme, re.S)
    assert match is not None
    return re.sub(r"^(\s*)# ?(?=\s*\w+:)", r"\1", match.group(1), flags=re.M)


def schema_problems(text: str) -> list[ConfigProblem]:
    found = Findings("docs/robot-file-guide.md")
    ROBOT_FILE.read(yaml.compose(text, Loader=yaml.SafeLoader), "", "", found, Context())
    return found.problems


def test_the_readme_example_uses_only_the_schemas_keys() -> None:
    text = readme_example()
    assert "locked:" in text and "joints:" in text and "status_rate_hz:" in text
    assert schema_problems(text) == []
    # and the check can fail: a key the schema lacks is found, wherever it is
    for key in ("offset:", "kp:", "bitrate:", "mass:", "locked:"):
        typo = re.sub(rf"\b{key}", key[:-1] + "s:", text, count=1)
        assert any("unknown key" in p.message for p in schema_problems(typo)), key
