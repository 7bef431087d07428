"""`akarm init` on URDFs akarm did not ship: init → check → a simulated move, for each.

The URDFs are the exporter-style corpus of tests/urdfs (see test_urdf.py): a 7-joint arm with a
two-finger gripper (xacro output, transmissions, a mimic finger), a SolidWorks export and a ROS 2
SCARA with a prismatic axis; and a UR5-sized arm whose shoulder no AK motor holds at its rated torque.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from akarm import ConfigError
from akarm.cli import main
from akarm.protocol.motors import Catalogue, default_catalogue
from akarm.robotfile.load import load_robot
from akarm.robotfile.starter import suggest

URDFS = Path(__file__).resolve().parent.parent / "urdfs"
TRIED = ["arm7_gripper", "cad_arm4", "scara_ros2"]


def init(tmp_path: Path, stem: str, *extra: str) -> tuple[Path, str]:
    """``akarm init`` on a copy of a corpus URDF in ``tmp_path``; the written file and its text."""
    urdf = tmp_path / f"{stem}.urdf"
    shutil.copy(URDFS / f"{stem}.urdf", urdf)
    assert main(["init", str(urdf), *extra]) == 0
    out = urdf.with_suffix(".yaml")
    return out, out.read_text()


@pytest.mark.parametrize("stem", TRIED)
def test_every_suggestion_is_commented_as_one(stem: str, tmp_path: Path) -> None:
    _, text = init(tmp_path, stem)
    doc = yaml.safe_load(text)
    n = len(doc["joints"])
    lines = text.splitlines()

    def line(pattern: str) -> list[str]:
        return [s for s in lines if re.search(pattern, s)]

    for pattern in (r"^\s+can_id:", r"^\s+motor:", r"^\s+limits:", r"^\s+gains:"):
        found = line(pattern)
        assert len(found) == n and all("# suggested:" in s for s in found), found
    for pattern in (r"^rate_hz:", r"^tool_frame:", r"^  rest:", r"^  arm: \{interface", r"^  mode:"):
        (found,) = line(pattern)
        assert "# suggested" in found, found
    for name in doc.get("locked", {}):
        (found,) = line(rf"^  {re.escape(name)}:")
        assert "# suggested" in found
    # joints in chain order, IDs 1..n on one bus
    assert [j["can_id"] for j in doc["joints"]] == list(range(1, n + 1))
    assert list(doc["buses"]) == ["arm"] and doc["defaults"]["bus"] == "arm"
    assert set(doc["poses"]) == {"zero", "rest"}


def test_the_gripper_arm_gets_its_fingers_locked_and_its_tool_frame(tmp_path: Path) -> None:
    out, text = init(tmp_path, "arm7_gripper")
    doc = yaml.safe_load(text)
    assert [j["name"] for j in doc["joints"]] == [f"arm7_joint{k}" for k in range(1, 8)]
    assert doc["locked"] == {"arm7_finger_joint1": 0.0}
    assert "arm7_finger_joint2 follows it (mimic)" in text
    assert doc["tool_frame"] == "arm7_hand_tcp"
    # 7 MIT joints do not fit 500 Hz on one bus in the worst case: the highest multiple of 50 that does
    assert doc["rate_hz"] == 400 and "under 80 % up to 423 Hz" in text
    config = load_robot(out)
    assert config.locked == {"arm7_finger_joint1": 0.0, "arm7_finger_joint2": 0.0}


def test_motors_cover_gravity_with_the_margin_and_the_payload(tmp_path: Path) -> None:
    urdf = URDFS / "arm7_gripper.urdf"
    plain = suggest(urdf, tmp_path / "a.yaml")
    loaded = suggest(urdf, tmp_path / "a.yaml", payload=1.0, margin=2.0)
    for a, b in zip(plain.joints, loaded.joints, strict=True):
        assert a.motor.rated_torque >= 1.5 * a.gravity.torque  # the margin (plus the inertia term)
        assert b.motor.rated_torque >= 2.0 * b.gravity.torque
        assert b.gravity.torque >= a.gravity.torque - 1e-9
    # 1 kg at the tool: the shoulder's gravity grows by at most m g × reach (~0.9 m)
    assert 0 < loaded.joints[1].gravity.torque - plain.joints[1].gravity.torque <= 9.81 * 0.95
    # the smallest that covers: the next smaller model (by rated torque) would not
    models = sorted((m for m in (default_catalogue().get(n) for n in default_catalogue().names())
                     if re.fullmatch(r"AK\d+-\d+", m.name)), key=lambda m: m.rated_torque)
    for s in plain.joints:
        smaller = [m for m in models if m.rated_torque < s.motor.rated_torque]
        assert all(m.rated_torque < s.needed for m in smaller)


def test_gains_are_near_critical_damping_with_a_modest_natural_frequency(tmp_path: Path) -> None:
    s = suggest(URDFS / "cad_arm4.urdf", tmp_path / "a.yaml")
    for j in s.joints:
        f = np.sqrt(j.kp / j.inertia) / (2 * np.pi)
        zeta = j.kd / (2 * np.sqrt(j.kp * j.inertia))
        assert f <= 4.5 and 0.85 <= zeta <= 1.15, (j.urdf.name, f, zeta)
        assert 0 < j.kp <= j.motor.kp_max and 0 < j.kd <= j.motor.kd_max


def test_a_joint_no_motor_holds_is_marked_and_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a UR5-sized arm: its shoulder needs 54 N·m, above every AK rated torque but within the AK80-64's range
    out, text = init(tmp_path, "ur5_like")
    assert "NO model's rated torque covers" in text
    assert "above the AK80-64's rated (continuous) torque 48 N·m" in capsys.readouterr().out
    # with 12 kg at the tool no catalogue motor holds it at all: the file is written, marked, and refused
    urdf = tmp_path / "ur5_like.urdf"
    assert main(["init", str(urdf), "-o", str(tmp_path / "heavy.yaml"), "--payload", "12"]) == 1
    err = capsys.readouterr().err
    assert "no catalogue motor holds shoulder_lift_joint with 12 kg at the tool" in err
    assert "NO catalogue model holds" in (tmp_path / "heavy.yaml").read_text()
    assert main(["check", str(tmp_path / "heavy.yaml"), "--payload", "12"]) == 1
    assert "joint 'shoulder_lift_joint': with 12 kg more at the tool, gravity needs up to" in capsys.readouterr().err
    # the same through the API with a smaller catalogue
    small = Catalogue({n: default_catalogue().get(n) for n in ("AK60-6", "AK80-9", "AK70-10")})
    s = suggest(urdf, tmp_path / "x.yaml", catalogue=small)
    assert "shoulder_lift_joint" in s.short


def test_init_refuses_to_overwrite_and_reports_urdf_problems(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    out, _ = init(tmp_path, "cad_arm4")
    assert main(["init", str(tmp_path / "cad_arm4.urdf")]) == 1
    assert "exists; not overwritten" in capsys.readouterr().err
    assert main(["init", str(tmp_path / "cad_arm4.urdf"), "--force"]) == 0
    bad = tmp_path / "bad.urdf"
    bad.write_text((URDFS / "cad_arm4.urdf").read_text().replace('type="revolute"', 'type="revolut"', 1))
    assert main(["init", str(bad)]) == 1
    err = capsys.readouterr().err
    assert re.search(r"line \d+: joint 'Joint1' has the unknown type 'revolut'", err) and "Traceback" not in err
    assert not (tmp_path / "bad.yaml").exists()
    with pytest.raises(ConfigError, match="no revolute or continuous joint"):
        gripper_only = tmp_path / "g.urdf"
        gripper_only.write_text('<robot name="g"><link name="a"/><link name="b"/><joint name="f" type="prismatic">'
                                '<parent link="a"/><child link="b"/><limit lower="0" upper="0.04" effort="1" '
                                'velocity="1"/></joint></robot>')
        suggest(gripper_only, tmp_path / "g.yaml")


def test_a_revolute_joint_others_mimic_is_taken_for_a_grippers_and_held(tmp_path: Path) -> None:
    """A Robotiq-style gripper: a revolute finger_joint that other revolute joints mimic."""
    text = (URDFS / "cad_arm4.urdf").read_text().replace("</robot>", """\
  <link name="knuckle"><inertial><mass value="0.02"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/>
  </inertial></link>
  <link name="inner"><inertial><mass value="0.02"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/>
  </inertial></link>
  <joint name="finger_joint" type="revolute"><parent link="link4"/><child link="knuckle"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.8" effort="1000" velocity="2"/></joint>
  <joint name="inner_finger_joint" type="revolute"><parent link="knuckle"/><child link="inner"/><axis xyz="1 0 0"/>
    <limit lower="-0.8757" upper="0" effort="1000" velocity="2"/><mimic joint="finger_joint" multiplier="-1"/></joint>
</robot>""")
    urdf = tmp_path / "g.urdf"
    urdf.write_text(text)
    s = suggest(urdf, tmp_path / "g.yaml")
    assert [j.urdf.name for j in s.joints] == ["Joint1", "Joint2", "Joint3", "Joint4"]
    assert s.locked == {"finger_joint": 0.0, "inner_finger_joint": 0.0}
    assert "a gripper's joint? move it under joints: if an AK motor drives it" in s.text
    out = tmp_path / "g.yaml"
    out.write_text(s.text)
    assert load_robot(out).warnings == ()


def test_a_locked_joint_whose_range_excludes_zero_is_printed_inside_its_range(tmp_path: Path) -> None:
    # 0 is outside both sliders' ranges: each is held at the limit nearest 0, which has 7 decimals;
    # printed with 6, it must round into the range, not out of it (the file would be refused)
    slider = """  <link name="{c}"><inertial><mass value="0.02"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>
  <joint name="{c}_joint" type="prismatic"><parent link="link4"/><child link="{c}"/><axis xyz="1 0 0"/>
    <limit lower="{lo}" upper="{hi}" effort="100" velocity="0.1"/></joint>
"""
    text = (URDFS / "cad_arm4.urdf").read_text().replace(
        "</robot>", slider.format(c="a", lo="0.0123454", hi="0.04") + slider.format(c="b", lo="-0.04", hi="-0.0123454")
        + "</robot>")
    urdf = tmp_path / "s.urdf"
    urdf.write_text(text)
    s = suggest(urdf, tmp_path / "s.yaml")
    out = tmp_path / "s.yaml"
    out.write_text(s.text)
    locked = load_robot(out).locked
    assert locked == {"a_joint": 0.012346, "b_joint": -0.012346} == s.locked
