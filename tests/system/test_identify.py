"""Identification against the simulator, whose friction and payload are known: friction within 15 %,
payload mass within 10 % and centre of mass within 1 cm; the thresholds it suggests stop nothing in
five minutes of motion; results saved into the robot file with a backup.

In lock step, but long: each identification or payload estimate is 30 to 50 simulated seconds (a
minute or more of this machine's time), the five minutes of motion about 150 s; so they are system
tests, with `akarm identify` against the real-time simulator (refusals before moving:
tests/sim/test_identify.py; the parts on exact data: tests/unit/test_identify.py).

The identification runs the simulator at 5 kHz instead of its default 2 kHz: viscous friction of
the joints gravity loads is sensitive to when the torque a motor reports was applied (0.5 kg at
the tool makes the shoulder's viscous estimate move by half its value per millisecond), and the
simulator's first-order step delays its gravity by half a step.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

import akarm
from akarm.arm import Arm
from akarm.cli import main
from akarm.identify import Identification, apply_identification, estimate_payload, identify
from akarm.sim import SimulatedRobot
from akarm.sim.params import default_params

from .conftest import ROBOTS, relaxed_robot, wait_until

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
PAYLOAD = (0.5, (0.01, -0.02, 0.05))  # kg, m in the tool frame


@dataclass
class Identified:
    result: Identification
    applied_payload: tuple | None
    thresholds_before: dict


@pytest.fixture(scope="module")
def identified() -> Identified:
    cfg = ARM6.with_bus(interface="virtual", channel=f"identify-{time.monotonic_ns()}")
    with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home"), dt=0.0002) as sim, \
            Arm(cfg, clock=sim.clock, telemetry_seconds=120) as arm:
        sim.set_payload(*PAYLOAD)
        before = arm.collision_thresholds
        # an unknown payload is an external torque: the reflex would stop the arm as soon as it holds it
        arm.set_collision(thresholds=[None] * 6)
        arm.enable()
        result = identify(arm, duration=30.0, amplitude=0.7)
        return Identified(result, arm.payload, before)


def test_friction_is_within_15_percent_of_the_simulators(identified: Identified) -> None:
    for fit, joint in zip(identified.result.joints, ARM6.joints, strict=True):
        truth = default_params(joint.motor)
        assert fit.coulomb == pytest.approx(truth.coulomb, rel=0.15), fit
        assert fit.viscous == pytest.approx(truth.viscous, rel=0.15), fit
        assert abs(fit.offset) < 0.05  # the simulator has none
        assert 0 < fit.rms < 0.1  # N·m: the model explains the torques


def test_the_payload_is_within_10_percent_and_1_cm(identified: Identified) -> None:
    p = identified.result.payload
    assert p is not None and p.mass == pytest.approx(PAYLOAD[0], rel=0.10)
    assert np.linalg.norm(np.subtract(p.com, PAYLOAD[1])) < 0.01
    assert identified.applied_payload is not None  # and the arm carries it now
    assert identified.applied_payload[0] == pytest.approx(p.mass)


def test_the_results_read_as_robot_yaml(identified: Identified) -> None:
    r = identified.result
    doc = yaml.safe_load(r.fragment())
    assert doc["payload"]["mass"] == pytest.approx(r.payload.mass, abs=1e-4)
    for entry, fit in zip(doc["joints"], r.joints, strict=True):
        assert entry["name"] == fit.name
        assert entry["friction"]["coulomb"] == pytest.approx(fit.coulomb, abs=1e-4)
        assert entry["collision"]["threshold"] == pytest.approx(fit.threshold, abs=0.01)
    table = r.table()
    assert "RMS Nm" in table and "threshold Nm" in table and all(j.name in table for j in ARM6.joints)
    assert 0 < r.speed <= 1 and r.duration == pytest.approx(30.0 / r.speed, rel=0.02)


@pytest.mark.slow
def test_five_minutes_of_motion_with_the_suggested_thresholds_stop_nothing(identified: Identified,
                                                                          channel: str) -> None:
    """With the identified friction and payload applied and the suggested thresholds armed: random
    moves (0.3 to 0.7 of the joint limits), paths through waypoints and straight lines for 300 s."""
    r = identified.result
    thresholds = [j.threshold for j in r.joints]
    assert all(t is not None and t >= 0.2 for t in thresholds)
    cfg = ARM6.with_bus(interface="virtual", channel=channel)
    rng = np.random.default_rng(5)
    # a box that keeps the shoulder's torque moderate, and pauses between moves: a working arm's duty
    # (moving without a break with 0.5 kg, the shoulder's AK70-10 passes 80 °C in about 4 minutes)
    lo = np.array([-1.5, -0.3, -0.5, -1.5, -1.2, -2.0])
    hi = np.array([1.5, 0.3, 1.0, 1.5, 1.4, 2.0])
    with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home")) as sim, \
            Arm(cfg, clock=sim.clock, telemetry_seconds=30) as arm:
        sim.set_payload(*PAYLOAD)
        apply_identification(arm, r)  # the identified payload and friction
        arm.set_collision(thresholds=thresholds)
        arm.enable()
        arm.reset_collision_peak()
        t0 = arm.clock.now()
        moves = 0
        while arm.clock.now() - t0 < 300.0:
            kind = moves % 5
            speed = float(rng.uniform(0.3, 0.7))
            if kind == 3:
                arm.move_through([lo + rng.random(6) * (hi - lo) for _ in range(3)], speed=speed)
            elif kind == 4:
                pose = arm.tool_pose()
                pose[:3, 3] += rng.uniform(-0.08, 0.08, 3)
                with contextlib.suppress(akarm.LimitError):  # a line the arm refuses (a singularity): not moved
                    arm.move_linear(pose, speed=speed)
            else:
                arm.move_to(lo + rng.random(6) * (hi - lo), speed=speed)
            arm.sleep(float(rng.uniform(0.2, 1.2)))
            moves += 1
        assert arm.last_collision is None and arm.enabled
        ratio = arm.collision_peak / np.array(thresholds)
        assert np.all(ratio < 1.0), ratio
        assert np.max(sim.temperatures) < 75.0, sim.temperatures
    assert moves > 60


def test_estimate_payload_at_rest(channel: str) -> None:
    cfg = ARM6.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home")) as sim, Arm(cfg, clock=sim.clock) as arm:
        arm.set_collision(thresholds=[None] * 6)  # an unannounced payload is what we measure here
        sim.set_payload(0.5, (0.0, 0.03, 0.06))
        arm.enable()
        start = arm.state().q_des
        p = estimate_payload(arm)
        assert p.mass == pytest.approx(0.5, rel=0.10)
        assert np.linalg.norm(np.subtract(p.com, (0.0, 0.03, 0.06))) < 0.01
        assert p.determined == (True, True, True)
        assert arm.payload[0] == pytest.approx(p.mass)  # applied
        assert np.allclose(arm.state().q_des, start)  # and back where it started


def test_a_planar_arm_cannot_tell_the_centre_of_mass_along_its_axes(planar2, channel: str) -> None:
    cfg = planar2.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=[0.3, -0.6]) as sim, Arm(cfg, clock=sim.clock) as arm:
        sim.set_payload(0.3, (0.02, 0.05, 0.0))
        arm.enable()
        p = estimate_payload(arm, apply=False)
    # tool0's y axis is the joints' axis: gravity never acts across it
    assert p.determined == (True, False, True) and p.com[1] == 0.0
    assert p.mass == pytest.approx(0.3, rel=0.10) and p.com[0] == pytest.approx(0.02, abs=0.01)


def test_identify_without_apply_leaves_the_arms_payload_as_it_was(planar2, channel: str,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    # identify carries a rough estimate at rest during the excitation: it must not stay behind
    cfg = planar2.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=[0.3, -0.6]) as sim, Arm(cfg, clock=sim.clock) as arm:
        arm.set_collision(thresholds=[None] * 2)
        sim.set_payload(0.3, (0.02, 0.0, 0.0))
        arm.enable()
        result = identify(arm, duration=8.0, apply=False)
        assert result.payload is not None and result.payload.mass > 0.2  # it saw the load
        assert arm.payload is None
        arm.set_payload(0.1, (0.0, 0.0, 0.01))
        monkeypatch.setattr(arm, "replay", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("in the excitation")))
        with pytest.raises(RuntimeError):
            identify(arm, duration=8.0)  # an error after the estimate at rest, with apply
        assert arm.payload is not None and arm.payload[0] == pytest.approx(0.1)
        assert np.allclose(arm.payload[1], (0.0, 0.0, 0.01))


def test_save_writes_the_values_in_place_with_a_backup(identified: Identified, tmp_path: Path) -> None:
    robot = tmp_path / "arm6.yaml"
    original = (ROBOTS / "arm6.yaml").read_text()
    robot.write_text(original)
    (tmp_path / "arm6.urdf").write_text((ROBOTS / "arm6.urdf").read_text())
    path, backup = identified.result.save(robot)
    assert backup.read_text() == original
    config = akarm.load_robot(path)
    r = identified.result
    assert config.payload.mass == pytest.approx(r.payload.mass, abs=1e-4)
    for joint, fit in zip(config.joints, r.joints, strict=True):
        assert joint.friction.coulomb == pytest.approx(fit.coulomb, abs=1e-4)
        assert joint.friction.viscous == pytest.approx(fit.viscous, abs=1e-5)
        assert joint.collision_threshold == pytest.approx(fit.threshold, abs=0.01)
    text = path.read_text()
    for line in original.splitlines():  # every comment and every line the user wrote is still there,
        if "collision:" not in line:  # but the thresholds, which it replaced
            assert line in text, line
    assert text.count("collision:") == 6
    # a second save replaces, and keeps another backup
    _, backup2 = r.save(robot)
    assert backup2 != backup and path.read_text() == text


def test_save_refuses_a_result_for_other_joints(identified: Identified, tmp_path: Path) -> None:
    robot = tmp_path / "planar2.yaml"
    robot.write_text((ROBOTS / "planar2.yaml").read_text())
    (tmp_path / "planar2.urdf").write_text((ROBOTS / "planar2.urdf").read_text())
    with pytest.raises(akarm.ConfigError):
        identified.result.save(robot)
    assert robot.read_text() == (ROBOTS / "planar2.yaml").read_text()
    assert not list(tmp_path.glob("*.bak"))


def test_cli_identify_saves_into_the_robot_file(tmp_path: Path, channel: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    relaxed_planar2 = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)  # the simulator shares this process
    cfg = akarm.load_robot(relaxed_planar2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=True, q0=[-math.pi / 2 + 0.6, 0.3]) as sim:
        result: list[int] = []
        th = threading.Thread(target=lambda: result.append(main(
            ["identify", str(relaxed_planar2), "-i", "virtual", "-c", channel, "--seconds", "10", "--no-payload",
             "--amplitude", "0.4", "--save"])), daemon=True)
        th.start()
        th.join(60.0)
        assert wait_until(lambda: not any(d.enabled for d in sim.drivers), 2.0)
    out, err = capsys.readouterr()
    assert result == [0], out + err
    assert "RMS Nm" in out and "saved into" in out and out.rstrip().endswith("disabled")
    config = akarm.load_robot(relaxed_planar2)
    assert all(j.friction is not None and j.collision_threshold is not None for j in config.joints)
    assert len(list(relaxed_planar2.parent.glob(f"{relaxed_planar2.name}.*.bak"))) == 1
