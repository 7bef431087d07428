"""URDFs as ROS tools and CAD exporters write them: a corpus that must load, and problems that must be
reported at their URDF line with a fix.

The corpus (tests/urdfs/) is written the way exporters write: xacro output with <transmission>
blocks, <gazebo> tags, package:// meshes and safety controllers (arm7_gripper: seven joints and a
two-finger gripper whose second finger mimics the first); the SolidWorks exporter's layout (one
attribute per line, CAD inertias with products of inertia, effort="0" velocity="0", a continuous
last joint: cad_arm4); ROS 2 with a <ros2_control> block, gz plugins, file:// meshes and a
prismatic axis (scara_ros2); ur_description's layout at UR5 size (ur5_like).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from akarm import ConfigError, ConfigWarning
from akarm.config.urdf import read_urdf
from akarm.dynamics.model import RobotModel
from akarm.errors import ConfigProblem
from akarm.robotfile.load import load_robot

URDFS = Path(__file__).resolve().parent.parent / "urdfs"
CORPUS = sorted(URDFS.glob("*.urdf"))

#: per corpus file: its movable joints in chain order, and how many <joint> elements the file holds
#: in all (those inside <transmission>/<ros2_control> included: they must not be read as joints)
EXPECTED = {
    "arm7_gripper": ([f"arm7_joint{k}" for k in range(1, 8)] + ["arm7_finger_joint1", "arm7_finger_joint2"], 21),
    "cad_arm4": (["Joint1", "Joint2", "Joint3", "Joint4"], 4),
    "scara_ros2": (["lift", "shoulder", "elbow", "wrist"], 9),
    "ur5_like": (["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                  "wrist_3_joint"], 16),
}

ARM7 = f"""\
name: arm7
urdf: {URDFS / "arm7_gripper.urdf"}
rate_hz: 400
tool_frame: arm7_hand_tcp
defaults:
  limits: {{velocity: 2.0, acceleration: 8.0, jerk: 80.0}}
  gains: {{kp: 60.0, kd: 2.0}}
locked: {{arm7_finger_joint1: 0.02}}
poses:
  home: [0, 0, 0, -1.5, 0, 1.5, 0]
  out: [0.5, 0.8, 0, -1.0, 0, 1.8, 0.3]
joints:
  - {{name: arm7_joint1, can_id: 1, motor: AK10-9}}
  - {{name: arm7_joint2, can_id: 2, motor: AK10-9}}
  - {{name: arm7_joint3, can_id: 3, motor: AK80-9}}
  - {{name: arm7_joint4, can_id: 4, motor: AK80-9}}
  - {{name: arm7_joint5, can_id: 5, motor: AK60-6}}
  - {{name: arm7_joint6, can_id: 6, motor: AK60-6}}
  - {{name: arm7_joint7, can_id: 7, motor: AK60-6}}
"""


def write(tmp_path: Path, text: str, name: str = "robot.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def line_of(text: str, marker: str) -> int:
    hits = [i + 1 for i, line in enumerate(text.splitlines()) if marker in line]
    assert len(hits) == 1, f"{marker!r} is on lines {hits}"
    return hits[0]


# ----------------------------------------------------------------------------- the corpus loads


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
def test_corpus_file_reads_with_only_its_own_joints(path: Path) -> None:
    urdf, found = read_urdf(path)
    assert found == [] and urdf is not None
    chain, all_joint_elements = EXPECTED[path.stem]
    assert [j.name for j in urdf.movable] == chain
    # the file really does name joints outside its own <joint> declarations (transmissions, ros2_control)
    assert len(re.findall(r"<joint\b", path.read_text())) == all_joint_elements
    assert len(urdf.joints) < all_joint_elements or path.stem == "cad_arm4"
    # and Pinocchio agrees on the movable joints (meshes are never opened: package:// and file:// paths
    # that exist nowhere here)
    model = pin.buildModelFromUrdf(str(path))
    assert sorted(model.names[1:]) == sorted(chain)
    lines = path.read_text().splitlines()
    for j in urdf.joints.values():
        assert f'name="{j.name}"' in lines[j.line - 1] or f'name="{j.name}"' in lines[j.line]


def test_corpus_has_what_exporters_write() -> None:
    text = {p.stem: p.read_text() for p in CORPUS}
    assert "<transmission" in text["arm7_gripper"] and "<gazebo" in text["arm7_gripper"]
    assert "package://" in text["arm7_gripper"] and "<mimic" in text["arm7_gripper"]
    assert "<ros2_control" in text["scara_ros2"] and "file://" in text["scara_ros2"]
    assert 'type="prismatic"' in text["scara_ros2"] and 'type="continuous"' in text["cad_arm4"]
    assert "SolidWorks to URDF Exporter" in text["cad_arm4"]


def test_seven_joint_arm_with_gripper_loads_and_its_fingers_are_locked(tmp_path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # `locked:` says where the fingers are: no warning
        config = load_robot(write(tmp_path, ARM7))
    assert config.warnings == ()
    assert len(config.joints) == 7
    # the second finger mimics the first, so it is held where the first one is
    assert config.locked == {"arm7_finger_joint1": 0.02, "arm7_finger_joint2": 0.02}
    model = RobotModel(config)
    assert model.pin_model.nq == 7 and model.locked == config.locked
    # the fingers' mass still counts: the same total as the URDF's, and the same gravity torques as
    # the full model with the fingers at 0.02 m
    full = pin.buildModelFromUrdf(str(config.urdf))
    total = sum(i.mass for i in full.inertias)
    assert sum(i.mass for i in model.pin_model.inertias) == pytest.approx(total)
    q = np.array(config.pose("out"))
    q_full = np.concatenate([q, [0.02, 0.02]])
    g_full = pin.computeGeneralizedGravity(full, full.createData(), q_full)
    np.testing.assert_allclose(model.gravity(q), g_full[:7], atol=1e-10)
    # and the tool frame is the hand's TCP beyond the locked fingers' parent
    assert model.tool_frame == "arm7_hand_tcp"


def test_an_undriven_joint_without_locked_is_held_at_zero_with_a_warning(tmp_path: Path) -> None:
    text = ARM7.replace("locked: {arm7_finger_joint1: 0.02}\n", "")
    with pytest.warns(ConfigWarning) as caught:
        config = load_robot(write(tmp_path, text))
    assert config.locked == {"arm7_finger_joint1": 0.0, "arm7_finger_joint2": 0.0}
    # one warning: the master finger's (the mimic finger follows it, which is what the URDF says)
    (w,) = config.warnings
    assert len(caught) == 1 and str(w) in str(caught[0].message)
    assert "'arm7_finger_joint1' (prismatic, URDF line" in w.message and "held at 0 m" in w.message
    assert w.line == line_of(text, "joints:") and "locked: {arm7_finger_joint1: POSITION}" in w.fix


def test_joints_a_motor_cannot_drive_are_named_with_a_fix(tmp_path: Path) -> None:
    urdf = URDFS / "arm7_gripper.urdf"
    mimic_line = next(j.line for j in read_urdf(urdf)[0].joints.values() if j.name == "arm7_finger_joint2")
    text = ARM7.replace("  - {name: arm7_joint7, can_id: 7, motor: AK60-6}\n",
                        "  - {name: arm7_joint7, can_id: 7, motor: AK60-6}\n"
                        "  - {name: arm7_finger_joint2, can_id: 8, motor: AK60-6}\n"
                        "  - {name: arm7_hand_joint, can_id: 9, motor: AK60-6}\n")
    with pytest.raises(ConfigError) as info:
        load_robot(write(tmp_path, text))
    found = {p.message: p for p in info.value.problems}
    mimic = next(p for m, p in found.items() if "'arm7_finger_joint2' follows joint 'arm7_finger_joint1'" in m)
    assert f"URDF line {mimic_line}" in mimic.message and "drive 'arm7_finger_joint1' instead" in mimic.fix
    assert mimic.line == line_of(text, "arm7_finger_joint2, can_id")
    fixed = next(p for m, p in found.items() if "'arm7_hand_joint' is fixed in the URDF" in m)
    assert fixed.line == line_of(text, "arm7_hand_joint")
    # a prismatic joint: driven by no AK motor, but it can be locked
    prismatic = ARM7.replace("locked: {arm7_finger_joint1: 0.02}\n", "").replace(
        "  - {name: arm7_joint7, can_id: 7, motor: AK60-6}\n",
        "  - {name: arm7_joint7, can_id: 7, motor: AK60-6}\n  - {name: arm7_finger_joint1, can_id: 8, motor: AK60-6}\n")
    with pytest.raises(ConfigError) as info:
        load_robot(write(tmp_path, prismatic))
    (p,) = info.value.problems
    assert "'arm7_finger_joint1' is prismatic in the URDF" in p.message and "locked: {arm7_finger_joint1" in p.fix
    # locking the mimic finger instead of its master
    locked_mimic = ARM7.replace("arm7_finger_joint1: 0.02", "arm7_finger_joint2: 0.02")
    with pytest.raises(ConfigError) as info:
        load_robot(write(tmp_path, locked_mimic))
    (p,) = info.value.problems
    assert "follows 'arm7_finger_joint1'" in p.message and "lock 'arm7_finger_joint1' instead" in p.fix


def test_prismatic_axis_and_continuous_wrist_of_a_scara(tmp_path: Path) -> None:
    text = f"""\
name: scara
urdf: {URDFS / "scara_ros2.urdf"}
locked: {{lift: 0.1}}
defaults:
  limits: {{velocity: 2.0, acceleration: 8.0, jerk: 80.0}}
  gains: {{kp: 30.0, kd: 1.0}}
joints:
  - {{name: shoulder, can_id: 1, motor: AK80-9}}
  - {{name: elbow, can_id: 2, motor: AK60-6}}
  - {{name: wrist, can_id: 3, motor: AK60-6, limits: {{lower: -3.0, upper: 3.0}}}}
"""
    config = load_robot(write(tmp_path, text))
    assert config.locked == {"lift": 0.1} and config.warnings == ()
    model = RobotModel(config)
    # the arm moves in a horizontal plane: gravity needs no torque from any of its motors
    assert np.abs(model.gravity([0.3, -1.0, 2.0])).max() < 1e-12
    # the locked lift still carries the arm: it sits 0.1 m higher than with the lift at 0
    z = model.tool_pose([0, 0, 0])[2, 3]
    assert z == pytest.approx(0.2 + 0.1 + 0.05 + 0.04 - 0.03)


def test_cad_export_loads_with_its_continuous_joint_bounded_in_the_yaml(tmp_path: Path) -> None:
    text = f"""\
name: cad_arm4
urdf: {URDFS / "cad_arm4.urdf"}
defaults:
  limits: {{velocity: 2.0, acceleration: 8.0, jerk: 80.0}}
  gains: {{kp: 30.0, kd: 1.0}}
joints:
  - {{name: Joint1, can_id: 1, motor: AK80-9}}
  - {{name: Joint2, can_id: 2, motor: AK80-9}}
  - {{name: Joint3, can_id: 3, motor: AK60-6}}
  - {{name: Joint4, can_id: 4, motor: AK60-6, limits: {{lower: -3.1, upper: 3.1}}}}
"""
    config = load_robot(write(tmp_path, text))
    assert config.joint_names == ("Joint1", "Joint2", "Joint3", "Joint4") and config.locked == {}
    model = RobotModel(config)
    assert model.pin_model.nq == 5  # the continuous joint is (cos, sin) inside Pinocchio ...
    assert model.from_pin_q(model.to_pin_q([0.1, 0.2, 0.3, 2.5]))[3] == pytest.approx(2.5)  # ... not outside


# ----------------------------------------------------------------------------- problems, at their URDF line


def urdf_problems(tmp_path: Path, urdf_text: str, yaml_extra: str = "") -> list[ConfigProblem]:
    """Problems of a one-joint robot on ``urdf_text``: every one in the URDF, with a line and a fix."""
    path = tmp_path / "r.urdf"
    path.write_text(urdf_text)
    text = (f"name: r\nurdf: r.urdf\n{yaml_extra}defaults:\n  limits: {{velocity: 2, acceleration: 8, jerk: 80}}\n"
            "  gains: {kp: 10, kd: 0.5}\njoints:\n  - {name: j1, can_id: 1, motor: AK80-9}\n")
    with pytest.raises(ConfigError) as info:
        load_robot(write(tmp_path, text))
    for p in info.value.problems:
        assert p.file == str(path.resolve()), p
        assert p.line is not None and p.fix, p
    return info.value.problems


GOOD = """\
<robot name="r">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/>
    <child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="3"/>
  </joint>
  <link name="l1">
    <inertial>
      <origin xyz="0.1 0 0"/>
      <mass value="0.5"/>
      <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/>
    </inertial>
  </link>
</robot>
"""

#: (what is changed in GOOD, message fragment, URDF line of the problem)
BROKEN = [
    (('type="revolute"', ""), "joint 'j1' has no type", 3),
    (('type="revolute"', 'type="revolut"'), "unknown type 'revolut' (did you mean 'revolute'?)", 3),
    (('<child link="l1"/>', '<child link="l2"/>'), "child link 'l2' is not declared", 3),
    (('<parent link="base"/>\n', ""), "joint 'j1' has no parent link", 3),
    (('    <limit lower="-2" upper="2" effort="10" velocity="3"/>\n', ""), "'j1' is revolute but has no <limit>", 3),
    (('effort="10" ', ""), "its <limit> has no effort", 8),
    (('lower="-2"', 'lower="x"'), "<limit lower='x'> is not a number", 8),
    (('lower="-2" upper="2"', 'lower="2" upper="-2"'), "lower 2 is above upper -2", 8),
    (('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), "its <axis> is zero", 7),
    (('<axis xyz="0 1 0"/>', '<axis xyz="0 1"/>'), "<axis xyz='0 1'> is not three numbers", 7),
    (('xyz="0 0 0.1"', 'xyz="0 0 ${h}"'), "<origin xyz='0 0 ${h}'> is not three numbers", 6),
    (('<mass value="0.5"/>', '<mass value="-0.5"/>'), "<mass value='-0.5'> is not a mass", 13),
    (('ixx="1e-3"', 'ixx="abc"'), "<inertia ixx='abc'> is not a number", 14),
    (('ixy="0"', 'ixy="5e-3"'), "its <inertia> is not physically possible", 14),
    (('<origin xyz="0.1 0 0"/>', '<origin xyz="0.1 0 0" rpy="0 0 b"/>'), "inertial: <origin rpy='0 0 b'>", 12),
    (('<link name="l1">', '<link name="base">'), "link 'base' is declared twice (first on line 2)", 10),
    (('<link name="base"/>', '<link name="base"/>\n  <link name="stray"/>'), "the URDF has 2 root links", 3),
    (('<robot name="r">', '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n  <xacro:property name="h" '
      'value="0.1"/>'), "this is a xacro file", 2),
    (('<robot name="r">', '<robt name="r">'), "not well-formed XML", 17),
    (('<robot name="r">\n', '<sdf name="r">\n'), "not well-formed XML", 17),
]


@pytest.mark.parametrize(("change", "fragment", "line"), BROKEN, ids=[b[1][:40] for b in BROKEN])
def test_every_urdf_problem_has_its_line_and_a_fix(tmp_path: Path, change: tuple[str, str], fragment: str,
                                                    line: int) -> None:
    assert change[0] in GOOD
    found = urdf_problems(tmp_path, GOOD.replace(change[0], change[1], 1))
    hits = [p for p in found if fragment in p.message]
    assert len(hits) == 1, [str(p) for p in found]
    assert hits[0].line == line, str(hits[0])


def _finger(name: str, parent: str, child: str, mimics: str) -> str:
    return (f'  <joint name="{name}" type="prismatic">\n    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
            f'    <axis xyz="1 0 0"/>\n    <limit lower="0" upper="0.04" effort="10" velocity="0.1"/>\n'
            f'    <mimic joint="{mimics}"/>\n  </joint>\n  <link name="{child}"/>\n')


def test_joints_that_mimic_each_other_in_a_loop_are_refused_with_their_lines(tmp_path: Path) -> None:
    # a loop has no position to start from: the model would hold both at 0 without a word
    text = GOOD.replace("</robot>", _finger("f1", "l1", "p1", "f2") + _finger("f2", "l1", "p2", "f1") + "</robot>")
    found = urdf_problems(tmp_path, text)
    lines = [line_of(text, 'name="f1"'), line_of(text, 'name="f2"')]
    hits = [p for p in found if "mimic" in p.message]
    assert len(hits) == 1, [str(p) for p in found]
    assert f"'f1' (line {lines[0]}) mimics 'f2' (line {lines[1]}), which mimics 'f1'" in hits[0].message
    assert hits[0].line == lines[0] and "follows a joint that follows no other" in hits[0].fix


def test_a_urdf_that_is_not_a_robot(tmp_path: Path) -> None:
    (p,) = urdf_problems(tmp_path, '<?xml version="1.0"?>\n<sdf version="1.7">\n  <model name="r"/>\n</sdf>\n')
    assert "the root element is <sdf>, not <robot>" in p.message and p.line == 2


def test_the_good_urdf_loads(tmp_path: Path) -> None:
    (tmp_path / "r.urdf").write_text(GOOD)
    text = ("name: r\nurdf: r.urdf\ndefaults:\n  limits: {velocity: 2, acceleration: 8, jerk: 80}\n"
            "  gains: {kp: 10, kd: 0.5}\njoints:\n  - {name: j1, can_id: 1, motor: AK80-9}\n")
    assert load_robot(write(tmp_path, text)).joint_names == ("j1",)


def test_tool_frame_with_a_missing_urdf_is_a_config_error(tmp_path: Path) -> None:
    """Once a TypeError from inside the loader ('NoneType' object is not iterable)."""
    text = ("name: r\nurdf: nowhere.urdf\ntool_frame: tool0\ndefaults:\n  limits: {velocity: 2, acceleration: 8, "
            "jerk: 80}\n  gains: {kp: 10, kd: 0.5}\njoints:\n  - {name: j1, can_id: 1, motor: AK80-9}\n")
    with pytest.raises(ConfigError) as info:
        load_robot(write(tmp_path, text))
    (p,) = info.value.problems
    assert "nowhere.urdf" in p.message and "not found" in p.message and p.line == 2
    # the same with a URDF that has problems of its own
    (tmp_path / "bad.urdf").write_text(GOOD.replace('type="revolute"', ""))
    with pytest.raises(ConfigError):
        load_robot(write(tmp_path, text.replace("nowhere.urdf", "bad.urdf")))
