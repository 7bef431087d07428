"""The collision reflex: the external torque estimate, detection, reactions, teach mode, payload.

The observer on exact rigid-body data is checked in tests/unit/test_collision.py; here arm6 runs in
lock step against the simulator, which pushes the arm with ``set_external_torque`` and carries
payloads the arm may or may not be told about.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.arm import Arm
from akarm.control.modes import Mode
from akarm.dynamics.model import RobotModel
from akarm.errors import CollisionError
from akarm.sim import SimulatedRobot
from akarm.telemetry.log import load as load_telemetry

from .conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
THRESHOLDS = [j.collision_threshold for j in ARM6.joints]  # what `akarm identify` suggested (robots/arm6.yaml)


def lockstep(channel: str, q0=None, **arm_options) -> AbstractContextManager[tuple[Arm, SimulatedRobot]]:
    """The shared lock-step arm (tests/conftest.py): arm6, enabled at ``q0`` (default: its home pose)."""
    return lockstep_arm(ARM6, channel, q0=ARM6.pose("home") if q0 is None else q0, enable=True, **arm_options)


# ------------------------------------------------------------------------------------------------
# on the simulator
# ------------------------------------------------------------------------------------------------
def test_the_estimate_is_in_state_and_telemetry_and_a_told_payload_is_not_a_collision(channel: str) -> None:
    with lockstep(channel) as (arm, sim):
        arm.set_collision(thresholds=[None] * 6)  # watch, do not stop
        assert np.all(np.abs(arm.state().tau_ext) < 0.2)
        sim.set_payload(0.5, (0.0, 0.0, 0.05))  # 0.5 kg the arm was not told about
        arm.sleep(0.5)
        q = arm.state().q
        model = RobotModel(ARM6)
        expected = model.gravity(q)
        model.set_payload(0.5, (0.0, 0.0, 0.05))
        expected = expected - model.gravity(q)  # the payload's weight, as an external torque
        seen = arm.state().tau_ext
        # at rest a joint's friction holds anything within ±coulomb: the estimate is that sure
        coulomb = np.array([j.friction_model().coulomb for j in ARM6.joints])
        assert np.all(np.abs(seen - expected) < coulomb + 0.1), (seen, expected)
        assert abs(expected[1]) > 1.0 and abs(expected[2]) > 1.0  # the shoulder and elbow feel it
        log = arm.telemetry(since=arm.clock.now() - 0.01)
        assert np.allclose(log.tau_ext[-1], seen, atol=0.05)  # the same estimate, every cycle
        t_told = arm.clock.now()
        arm.set_payload(0.5, (0.0, 0.0, 0.05))  # told: nothing external any more
        arm.sleep(1.5)
        told = arm.telemetry(since=t_told + 0.5).tau_ext
        assert np.all(np.abs(told.mean(axis=0)) < 0.2), told.mean(axis=0)
        assert np.all(np.abs(told).max(axis=0) < np.array(THRESHOLDS))  # never taken for a collision
        assert "ext Nm" in str(arm.state())


@pytest.mark.parametrize("joint", ["shoulder_lift", "elbow", "wrist_pitch"])
def test_a_pulse_during_a_fast_move_is_detected_within_30_ms(channel: str, joint: str) -> None:
    k = ARM6.joint_names.index(joint)
    with lockstep(channel) as (arm, sim):
        motion = arm.move_to("reach", wait=False)  # full speed
        arm.sleep(motion.duration / 2)
        assert arm.state().dq[k] != 0.0 or np.max(np.abs(arm.state().dq)) > 0.5
        push = np.zeros(6)
        push[k] = 2.0 * THRESHOLDS[k]
        t_push = sim.t
        sim.set_external_torque(push)
        with pytest.raises(CollisionError) as e:
            arm.sleep(0.2)
        sim.set_external_torque(None)
        latency = e.value.at - t_push
        assert e.value.joint == joint and e.value.reaction == "disable"
        assert abs(e.value.torque) > THRESHOLDS[k] and e.value.threshold == THRESHOLDS[k]
        assert latency <= 0.030, f"{latency * 1e3:.0f} ms"
        assert f"joint '{joint}'" in str(e.value) and "N·m" in str(e.value)
        assert not arm.enabled and not any(d.enabled for d in sim.drivers)  # damped, then disabled


def test_the_hold_reaction_comes_to_rest_stays_enabled_and_re_arms(channel: str) -> None:
    with lockstep(channel, collision_reaction="hold") as (arm, sim):
        motion = arm.move_to("reach", wait=False)
        arm.sleep(0.4)
        sim.set_external_torque([0, 0, 3.0, 0, 0, 0])  # an obstacle against the elbow, for good
        with pytest.raises(CollisionError) as e:
            motion.wait()
        assert e.value.reaction == "hold" and e.value.joint == "elbow"
        assert arm.last_collision is e.value
        arm.sleep(0.6)
        assert arm.enabled and not arm.moving and arm.state().mode is Mode.ACTIVE
        held = arm.state().q
        arm.sleep(0.3)
        assert np.max(np.abs(arm.state().q - held)) < 0.01  # at rest, short of the target
        assert np.max(np.abs(held - np.array(ARM6.pose("reach")))) > 0.2
        # the obstacle still pushes: the reflex waits for it to go before it watches again
        assert arm.last_collision is e.value
        sim.set_external_torque(None)
        arm.move_to("home")  # the contact ended: the arm moves on, and is watched again
        motion = arm.move_to("reach", wait=False)
        arm.sleep(0.3)
        sim.set_external_torque([0, 3.0 * THRESHOLDS[1], 0, 0, 0, 0])
        with pytest.raises(CollisionError) as again:
            motion.wait()
        sim.set_external_torque(None)
        assert again.value.joint == "shoulder_lift" and arm.enabled


def test_teach_mode_is_never_stopped_by_the_hand(channel: str) -> None:
    with lockstep(channel) as (arm, sim):
        arm.teach()
        hand = np.zeros(6)
        hand[2] = 3.0 * THRESHOLDS[2]  # the hand on the elbow: three times its threshold ...
        sim.set_external_torque(hand)
        arm.sleep(0.15)
        assert arm.state().mode is Mode.TEACH
        assert arm.state().tau_ext[2] == pytest.approx(hand[2], rel=0.25)  # seen, as expected
        sim.set_external_torque(-hand)  # ... then back: the arm moves, and comes to rest again
        arm.sleep(0.15)
        assert arm.state().tau_ext[2] == pytest.approx(-hand[2], rel=0.25)
        sim.set_external_torque(None)  # the hand lets go
        arm.sleep(0.5)
        assert arm.state().mode is Mode.TEACH and arm.last_collision is None
        arm.end_teach()
        arm.sleep(0.3)
        assert arm.enabled and arm.last_collision is None  # ... and the reflex watches again
        sim.set_external_torque(hand)
        with pytest.raises(CollisionError):
            arm.sleep(0.2)
        sim.set_external_torque(None)


# ------------------------------------------------------------------------------------------------
# configuration and API
# ------------------------------------------------------------------------------------------------


def test_telemetry_keeps_tau_ext_and_reads_logs_without_it(tmp_path: Path, channel: str) -> None:
    with lockstep(channel) as (arm, sim):
        arm.sleep(0.1)
        log = arm.telemetry()
    csv_path = log.save(tmp_path / "run.csv")
    npz_path = log.save(tmp_path / "run.npz")
    for p in (csv_path, npz_path):
        back = load_telemetry(p)
        assert np.allclose(back.tau_ext, log.tau_ext, atol=1e-6, equal_nan=True)
    # a log written before tau_ext: the same columns without it
    lines = csv_path.read_text().splitlines()
    n = len(ARM6.joints)
    old = [",".join(row.split(",")[:1 + 6 * n]) for row in lines]
    (tmp_path / "old.csv").write_text("\n".join(old) + "\n")
    back = load_telemetry(tmp_path / "old.csv")
    assert np.allclose(back.tau, log.tau, atol=1e-6) and np.all(np.isnan(back.tau_ext))
