"""Will the motors hold it: the largest gravity torque per joint, refused above the torque limit,
warned above the rated torque, printed by `akarm check`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from akarm import ConfigError
from akarm.cli import main
from akarm.dynamics.gravity import gravity_peaks, peak_abs
from akarm.dynamics.model import RobotModel
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS

URDFS = Path(__file__).resolve().parent.parent / "urdfs"


def sampled_max(config, n: int = 20000, seed: int = 7) -> np.ndarray:
    model = RobotModel(config)
    lo = np.array([j.limits.lower for j in config.joints])
    hi = np.array([j.limits.upper for j in config.joints])
    qs = lo + np.random.default_rng(seed).random((n, lo.size)) * (hi - lo)
    return np.max([np.abs(model.gravity(q)) for q in qs], axis=0)


def test_planar2_peaks_are_the_closed_form() -> None:
    # arm horizontal: shoulder g (m1 c1 + m2 (L1 + c2)), elbow g m2 c2 (planar2.urdf's numbers)
    config = load_robot(ROBOTS / "planar2.yaml")
    sh, el = gravity_peaks(config)
    assert sh.torque == pytest.approx(9.81 * (0.432 * 0.2594 + 0.209 * (0.30 + 0.2148)), abs=1e-9)
    assert el.torque == pytest.approx(9.81 * 0.209 * 0.2148, abs=1e-9)
    assert sh.q[0] == pytest.approx(0.0, abs=1e-9) and sh.q[1] == pytest.approx(0.0, abs=1e-9)
    assert abs(math.sin(el.q[0] + el.q[1])) < 1e-9  # the forearm horizontal
    assert sh.pose() == "[+0.00, +0.00] rad"


@pytest.mark.parametrize("robot", ["arm6.yaml", "servo3.yaml", "biarm.yaml"])
def test_peaks_are_at_least_what_dense_sampling_finds(robot: str) -> None:
    config = load_robot(ROBOTS / robot)
    peaks = gravity_peaks(config)
    found = sampled_max(config)
    model = RobotModel(config)
    for p, s in zip(peaks, found, strict=True):
        assert p.torque >= s - 1e-9, (p.joint, p.torque, s)
        assert abs(model.gravity(p.q)[config.joint_names.index(p.joint)]) == pytest.approx(p.torque, abs=1e-9)
    # arm6: the shoulder_lift at full reach (the arm horizontal) is the worst case, as its URDF says
    if robot == "arm6.yaml":
        lift = peaks[1]
        reach = np.zeros(6)
        reach[1] = math.pi / 2
        assert lift.torque == pytest.approx(abs(model.gravity(reach)[1]), abs=1e-7)
        assert lift.torque == pytest.approx(14.7, abs=0.05)


def test_seven_joint_arm_with_a_gripper(tmp_path: Path) -> None:
    from .test_urdf import ARM7

    path = tmp_path / "arm7.yaml"
    path.write_text(ARM7)
    config = load_robot(path)
    peaks = gravity_peaks(config)
    found = sampled_max(config)
    assert all(p.torque >= s - 1e-9 for p, s in zip(peaks, found, strict=True))
    # exact: the same answer from other sample sets
    model = RobotModel(config)
    lo = [j.limits.lower for j in config.joints]
    hi = [j.limits.upper for j in config.joints]
    for seed in (2, 3, 4):
        again = peak_abs(model.gravity, lo, hi, seed=seed)
        np.testing.assert_allclose([t for t, _ in again], [p.torque for p in peaks], rtol=1e-7, atol=1e-9)


def test_payload_and_the_margin_add_m_g_r() -> None:
    config = load_robot(ROBOTS / "planar2.yaml")
    base = gravity_peaks(config)[0].torque
    # 1 kg at tool0, 0.55 m from the shoulder with the arm horizontal
    assert gravity_peaks(config, extra_payload=1.0)[0].torque == pytest.approx(base + 9.81 * 0.55, abs=1e-9)


UR5 = f"""\
name: ur5_like
urdf: {URDFS / "ur5_like.urdf"}
tool_frame: tool0
defaults:
  limits: {{lower: -3.1, upper: 3.1, velocity: 1.0, acceleration: 5.0, jerk: 50.0}}
  gains: {{kp: 50.0, kd: 2.0}}
joints:
  - {{name: shoulder_pan_joint, can_id: 1, motor: AK10-9}}
  - {{name: shoulder_lift_joint, can_id: 2, motor: AK60-6}}
  - {{name: elbow_joint, can_id: 3, motor: AK80-64}}
  - {{name: wrist_1_joint, can_id: 4, motor: AK80-9}}
  - {{name: wrist_2_joint, can_id: 5, motor: AK80-9}}
  - {{name: wrist_3_joint, can_id: 6, motor: AK60-6}}
"""


def test_motors_that_cannot_hold_the_arm_are_refused_at_their_line(tmp_path: Path) -> None:
    """The issue's case: a UR5-sized arm with an AK60-6 at the shoulder (15 N·m against over 50)."""
    path = tmp_path / "ur5.yaml"
    path.write_text(UR5)
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    (p,) = info.value.problems
    assert "joint 'shoulder_lift_joint': gravity alone needs up to 53.7 N·m" in p.message
    assert "above the AK60-6's 15 N·m" in p.message and "stronger motor" in p.fix
    assert p.line == UR5.splitlines().index("  - {name: shoulder_lift_joint, can_id: 2, motor: AK60-6}") + 1
    # a torque limit below the gravity is refused too, at the limit's line
    text = UR5.replace("motor: AK60-6}", "motor: AK80-64}", 1).replace(
        "{name: elbow_joint, can_id: 3, motor: AK80-64}",
        "{name: elbow_joint, can_id: 3, motor: AK80-64,\n     limits: {torque: 10.0}}")
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    (p,) = info.value.problems
    assert "joint 'elbow_joint'" in p.message and "above its torque limit 10 N·m" in p.message
    assert p.line == text.splitlines().index("     limits: {torque: 10.0}}") + 1


def test_above_the_rated_torque_is_a_warning_in_the_config_not_a_python_warning() -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config = load_robot(ROBOTS / "arm6.yaml")
    (w,) = config.warnings
    assert "'shoulder_lift': gravity needs up to 14.7 N·m" in w.message and "rated (continuous) torque 8.3" in w.message
    lines = (ROBOTS / "arm6.yaml").read_text().splitlines()
    assert lines[w.line - 1].strip() == "motor: AK70-10"


def test_check_prints_gravity_and_the_payload_margin(capsys: pytest.CaptureFixture[str]) -> None:
    arm6 = str(ROBOTS / "arm6.yaml")
    assert main(["check", arm6]) == 0
    out = capsys.readouterr().out
    assert "gravity max (N·m)" in out and "14.7, above rated 8.3" in out and "5.5, within rated 9" in out
    assert "shoulder_lift  gravity max 14.7 N·m at [" in out and "] rad of 25 N·m" in out
    assert "warning: joint 'shoulder_lift': gravity needs up to 14.7 N·m" in out
    # 2 kg more: the shoulder_lift needs about 14.7 + 2 g 0.99 = 34 N·m, past its AK70-10's 25: refused
    assert main(["check", arm6, "--payload", "2"]) == 1
    captured = capsys.readouterr()
    assert "+2 kg" in captured.out and "ABOVE the limit 25" in captured.out
    assert "joint 'shoulder_lift': with 2 kg more at the tool, gravity needs up to 34" in captured.err
    assert main(["check", arm6, "--payload", "0.3"]) == 0
    assert main(["check", arm6, "--payload", "-1"]) == 1


def test_a_payload_built_in_code_with_a_list_com_is_taken_as_its_tuple() -> None:
    # the cache key once held the Payload itself: a list com made it unhashable (TypeError)
    from dataclasses import replace

    from akarm.config import Payload

    config = load_robot(ROBOTS / "planar2.yaml")
    listed = gravity_peaks(replace(config, payload=Payload(0.4, [0.05, 0.0, 0.0])))  # type: ignore[arg-type]
    tupled = gravity_peaks(replace(config, payload=Payload(0.4, (0.05, 0.0, 0.0))))
    assert [p.torque for p in listed] == [p.torque for p in tupled]
    assert listed[0].torque > gravity_peaks(config)[0].torque  # and the payload counts
