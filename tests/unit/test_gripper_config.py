"""The robot file's `gripper:` entry and the gripper's angle/width/force helpers (pure)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from akarm import ArgumentError, ConfigError
from akarm.config import GripperConfig
from akarm.config.busload import bus_loads
from akarm.protocol.motors import default_catalogue
from akarm.robotfile.load import load_robot
from akarm.robotfile.starter import suggest

from .conftest import ROBOTS
from .test_config import BASE, problems, write

GRIPPER = """\
gripper:
  motor: AK40-10
  can_id: 7
  stroke: 0.08
  travel: 2.0
  force_limit: 40.0
"""


def make(**kw: object) -> GripperConfig:
    args: dict = dict(name="gripper", motor=default_catalogue().get("AK40-10"), can_id=7, bus="arm", stroke=0.08,
                      travel=2.0, force_limit=40.0)
    args.update(kw)
    return GripperConfig(**args)


def test_linear_width_angle_and_force() -> None:
    g = make()
    assert g.width_at(0.0) == 0.0 and g.width_at(2.0) == pytest.approx(0.08)
    assert g.width_at(0.75) == pytest.approx(0.03)
    assert g.angle_at(0.03) == pytest.approx(0.75)
    # 0.04 m/rad: 0.8 N·m closing squeezes 20 N; and back
    assert g.force_at(0.8, 1.0) == pytest.approx(20.0)
    assert g.torque_at(20.0, 1.0) == pytest.approx(0.8)
    assert g.torque_limit == pytest.approx(1.6)  # 40 N at 0.04 m/rad, under the AK40-10's 5 N·m
    j = g.joint
    assert (j.limits.lower, j.limits.upper, j.limits.torque) == (0.0, 2.0, pytest.approx(1.6))
    assert (j.gains.kp, j.gains.kd, j.can_id, j.name) == (5.0, 0.2, 7, "gripper")


def test_table_is_piecewise_linear() -> None:
    g = make(table=((0.0, 0.0), (1.0, 0.045), (2.0, 0.08)))
    assert g.width_at(0.5) == pytest.approx(0.0225)
    assert g.width_at(1.5) == pytest.approx(0.0625)
    for w in (0.0, 0.01, 0.045, 0.07, 0.08):
        assert g.width_at(g.angle_at(w)) == pytest.approx(w)
    assert g.slope_at(0.5) == pytest.approx(0.045) and g.slope_at(1.5) == pytest.approx(0.035)
    assert g.force_at(0.35, 1.5) == pytest.approx(10.0)
    assert g.max_slope == pytest.approx(0.045)


@pytest.mark.parametrize("width", [-0.001, 0.0801, math.nan, math.inf, "wide", None])
def test_a_width_outside_the_stroke_is_refused(width: object) -> None:
    with pytest.raises(ArgumentError) as info:
        make().check_width(width)  # type: ignore[arg-type]
    assert info.value.joint == "gripper" and "0..0.08" in info.value.fix


@pytest.mark.parametrize("force", [-1.0, math.nan, 40.5, "hard"])
def test_a_bad_force_is_refused(force: object) -> None:
    with pytest.raises(ArgumentError) as info:
        make().check_force(force)  # type: ignore[arg-type]
    assert info.value.joint == "gripper"


def test_default_force_is_a_fraction_of_the_limit() -> None:
    assert make().check_force(None) == pytest.approx(20.0)
    assert make().check_force(40) == 40.0


def test_robot_file_with_a_gripper(tmp_path: Path) -> None:
    config = load_robot(write(tmp_path, BASE + GRIPPER))
    g = config.gripper
    assert g is not None
    assert (g.name, g.motor.name, g.can_id, g.bus, g.mode, g.stroke, g.travel, g.force_limit) == \
        ("gripper", "AK40-10", 7, "arm", "mit", 0.08, 2.0, 40.0)
    assert config.joint_names == ("shoulder", "elbow")  # not one of the arm's joints
    assert [m.name for m in config.motors] == ["shoulder", "elbow", "gripper"]
    assert len(bus_loads(config)["arm"].joints) == 3  # its motor loads the bus


def test_a_servo_mode_gripper_loads_with_its_status_rate(tmp_path: Path) -> None:
    """Issue 36's `mode: servo`: the force-limited grasp on the servo firmware's current loop."""
    config = load_robot(write(tmp_path, BASE + GRIPPER.replace("  can_id: 7\n", "  can_id: 7\n  mode: servo\n"
                                                                               "  status_rate_hz: 200\n")))
    g = config.gripper
    assert g is not None and (g.mode, g.status_rate_hz) == ("servo", 200.0)
    assert (g.joint.mode, g.joint.status_rate_hz) == ("servo", 200.0)


def test_robot_file_without_a_gripper(tmp_path: Path) -> None:
    assert load_robot(write(tmp_path, BASE)).gripper is None


@pytest.mark.parametrize(("edit", "fragment"), [
    ("  can_id: 7\n", "  can_id: 2\n"),                    # another motor's CAN ID
    ("  motor: AK40-10\n", "  motor: AK41-10\n"),          # unknown model
    ("  stroke: 0.08\n", "  stroke: -0.08\n"),             # not positive
    ("  force_limit: 40.0\n", ""),                         # required
    ("  can_id: 7\n", "  can_id: 7\n  status_rate_hz: 0\n"),  # servo status rate 1-500 Hz
])
def test_gripper_problems(tmp_path: Path, edit: str, fragment: str) -> None:
    text = BASE + GRIPPER.replace(edit, fragment)
    found = problems(tmp_path, text)
    assert found and all("gripper" in p.message for p in found), [str(p) for p in found]


def test_gripper_named_like_a_joint_and_a_bad_table(tmp_path: Path) -> None:
    found = problems(tmp_path, BASE + GRIPPER + "  name: elbow\n  table: [[0, 0], [1, 0.05], [0.5, 0.08]]\n")
    text = " / ".join(p.message for p in found)
    assert "name of a joint" in text and "must both increase" in text


def test_travel_past_the_motor_range_is_refused(tmp_path: Path) -> None:
    found = problems(tmp_path, BASE + GRIPPER.replace("travel: 2.0", "travel: 30.0"))
    assert any("outside the AK40-10's ±12.5 rad" in p.message for p in found)


def test_bus_load_counts_the_gripper(tmp_path: Path) -> None:
    six = BASE.replace("rate_hz: 500", "rate_hz: 1500")
    load_robot(write(tmp_path, six))  # two motors carry 1.5 kHz...
    with pytest.raises(ConfigError):  # ...three do not
        load_robot(write(tmp_path, six + GRIPPER))


def test_arm6g_ships_with_a_gripper() -> None:
    config = load_robot(ROBOTS / "arm6g.yaml")
    assert config.gripper is not None and config.gripper.fingers == ("left_finger_joint", "right_finger_joint")
    assert "left_finger_joint" in config.locked and "right_finger_joint" in config.locked
    assert not config.warnings or all("finger" not in w.message for w in config.warnings)


def test_init_writes_a_gripper_for_prismatic_fingers(tmp_path: Path) -> None:
    out = tmp_path / "g.yaml"
    s = suggest(ROBOTS / "arm6g.urdf", out, gripper=True)
    assert "\ngripper:" in s.text and "stroke: 0.08" in s.text
    out.write_text(s.text)
    config = load_robot(out)
    assert config.gripper is not None and config.gripper.can_id == 7
