"""The robots shipped in robots/: each loads, passes `akarm check`, and is physically plausible."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from akarm.cli import main
from akarm.config import RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.robotfile.load import load_robot, read_urdf_joints

from .conftest import ROBOTS

YAMLS = sorted(ROBOTS.glob("*.yaml"))
REQUIRED = {"planar2", "arm6", "servo3", "biarm"}


def test_the_required_robots_are_there_and_nothing_else() -> None:
    assert {p.stem for p in YAMLS} >= REQUIRED
    referenced = {load_robot(p).urdf.name for p in YAMLS}
    for path in ROBOTS.iterdir():
        assert path.suffix in (".yaml", ".urdf"), f"unexpected file {path.name} in robots/"
        if path.suffix == ".urdf":
            assert path.name in referenced, f"{path.name} is not used by any robot YAML"


@pytest.mark.parametrize("path", YAMLS, ids=lambda p: p.stem)
def test_robot_loads_and_every_urdf_joint_is_configured(path: Path) -> None:
    config = load_robot(path)
    assert config.name == path.stem
    joints, _ = read_urdf_joints(config.urdf)
    movable = {n for n, j in joints.items() if j.type != "fixed"}
    fingers = set(config.gripper.fingers) if config.gripper is not None else set()  # the gripper moves them
    assert set(config.joint_names) == movable - fingers
    assert "home" in config.poses
    for j in config.joints:
        assert j.limits.torque <= j.motor.t_max
        assert j.motor.p_max >= max(abs(j.limits.lower), abs(j.limits.upper))
    model = RobotModel(config)
    for pose in config.poses.values():
        assert np.all(np.isfinite(model.gravity(pose)))


@pytest.mark.parametrize("path", YAMLS, ids=lambda p: p.stem)
def test_akarm_check_passes_and_prints_the_table_and_bus_load(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    config = load_robot(path)
    for j in config.joints:
        assert j.name in out and j.motor.name in out
    assert "bus load at" in out and "max rate" in out
    for bus in config.buses:
        assert f"\n  {bus} " in out
    assert out.rstrip().endswith("OK")


def test_check_prints_the_numbers(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(ROBOTS / "arm6.yaml")]) == 0
    out = capsys.readouterr().out
    assert "77.8 % (63.9 %)" in out  # worst case (nominal)
    assert "493 Hz" in out and "600 Hz" in out  # 80 % ceilings
    assert "warning: bus" not in out  # the shipped example stays under its own bus-load warning
    # over the limit in the worst case: the warning
    assert main(["check", str(ROBOTS / "arm6.yaml"), "--loop-rate", "500"]) == 0
    assert "warning: bus 'arm': worst-case load 81 %" in capsys.readouterr().out
    assert "[-1.700, +1.700]" in out and "120/3" in out
    # another rate and a bus override
    assert main(["check", str(ROBOTS / "arm6.yaml"), "--loop-rate", "250", "-i", "virtual", "-c", "sim0"]) == 0
    out = capsys.readouterr().out
    assert "bus load at 250 Hz" in out and "40.5 % (33.3 %)" in out and "virtual:sim0" in out
    assert "warning: bus" not in out


def test_check_on_a_broken_file_prints_every_error_and_returns_1(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (ROBOTS / "planar2.yaml").read_text().replace("urdf: planar2.urdf", f"urdf: {ROBOTS / 'planar2.urdf'}")
    text = text.replace("can_id: 2", "can_id: 1").replace("motor: AK60-6", "motor: AK60-66")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    assert main(["check", str(bad)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err
    lines = text.splitlines()
    motor_line = next(i + 1 for i, s in enumerate(lines) if "AK60-66" in s)
    assert f"{bad}: 2 problems:" in err
    assert f"line {motor_line}: joint 'elbow': unknown motor model 'AK60-66'" in err
    assert "fix: known models:" in err
    assert "already used by joint 'shoulder'" in err
    assert "Traceback" not in err


def test_check_on_broken_yaml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\njoints:\n  - name: a\n   can_id: 1\n")
    assert main(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "line 4: not valid YAML" in err and "Traceback" not in err


def test_check_rate_and_bitrate_overrides_are_checked_too(capsys: pytest.CaptureFixture[str]) -> None:
    arm6 = str(ROBOTS / "arm6.yaml")
    assert main(["check", arm6, "--loop-rate", "700"]) == 1
    err = capsys.readouterr().err
    assert "rate_hz 700 (given as an override) puts 93 % (worst case 113 %) on bus 'arm'" in err
    assert "at most 600 Hz" in err
    # the file's 480 Hz at half the bit rate: 128 %
    assert main(["check", arm6, "-b", "500000"]) == 1
    err = capsys.readouterr().err
    assert "bus 'arm' is 128 % busy" in err and "at most 300 Hz" in err
    assert main(["check", arm6, "-b", "500000", "--loop-rate", "250"]) == 0


def test_check_on_a_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(tmp_path / "none.yaml")]) == 1
    assert "robot file not found" in capsys.readouterr().err


# ----------------------------------------------------------------------------- physical plausibility


def peak_gravity_fraction(config: RobotConfig, n: int = 9) -> np.ndarray:
    """Largest |g(q)| / t_max per joint over a grid of configurations within the limits."""
    model = RobotModel(config)
    axes = [np.linspace(j.limits.lower, j.limits.upper, n) for j in config.joints]
    # the last joint of each arm rarely matters for gravity: keep the grid small where it does not
    peak = np.zeros(len(axes))
    for q in np.array(np.meshgrid(*axes)).reshape(len(axes), -1).T:
        peak = np.maximum(peak, np.abs(model.gravity(q)))
    return peak / np.array([j.motor.t_max for j in config.joints])


def test_arm6_shoulder_uses_50_to_70_percent_at_full_reach() -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    model = RobotModel(config)
    lift = config.joint_names.index("shoulder_lift")
    reach = np.zeros(6)
    reach[lift] = math.pi / 2
    frac = abs(model.gravity(reach)[lift]) / config.joints[lift].motor.t_max
    assert 0.5 <= frac <= 0.7
    # and nowhere within the limits more than that (full reach is the worst case)
    q = np.array(np.meshgrid(*[np.linspace(-1.7, 1.7, 35), np.linspace(-2.5, 2.5, 35), np.linspace(-2, 2, 9)]))
    q = q.reshape(3, -1).T
    full = np.zeros((len(q), 6))
    full[:, 1], full[:, 2], full[:, 4] = q[:, 0], q[:, 1], q[:, 2]
    peak = max(abs(model.gravity(x)[lift]) for x in full)
    assert peak == pytest.approx(frac * 25.0, rel=0.01)
    # `home` is comfortable: every joint under 25 % of its t_max
    home = np.abs(model.gravity(config.pose("home"))) / [j.motor.t_max for j in config.joints]
    assert np.all(home < 0.25)


def test_arm6_uses_the_catalogue_motor_masses() -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    model = RobotModel(config)
    moving = sum(model.pin_model.inertias[i].mass for i in range(1, model.pin_model.njoints))
    motors = sum(j.motor.mass or 0 for j in config.joints[1:])  # the pan motor is in the fixed base
    assert motors < moving < motors + 2.0  # motors plus light tubes, brackets and a gripper
    assert model.tool_pose(config.pose("reach"))[0, 3] > 0.9


@pytest.mark.parametrize("path", YAMLS, ids=lambda p: p.stem)
def test_gravity_stays_within_every_motor(path: Path) -> None:
    config = load_robot(path)
    n = 5 if len(config.joints) > 4 else 15
    frac = peak_gravity_fraction(config, n)
    assert np.all(frac < 0.75), dict(zip(config.joint_names, frac.round(3), strict=True))


def test_planar2_and_biarm_arms_are_the_same() -> None:
    p2 = RobotModel(load_robot(ROBOTS / "planar2.yaml"))
    bi = RobotModel(load_robot(ROBOTS / "biarm.yaml"))
    q = np.array([0.4, -0.7])
    np.testing.assert_allclose(bi.gravity([*q, *q]), [*p2.gravity(q), *p2.gravity(q)], atol=1e-12)
    np.testing.assert_allclose(bi.tool_pose([*q, 0, 0])[:3, 3], p2.tool_pose(q)[:3, 3] + [0, 0.25, 0], atol=1e-12)
