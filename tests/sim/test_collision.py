"""The collision reflex: the external torque estimate, detection, reactions, teach mode, payload.

The observer is checked against exact rigid-body data first (no simulator: the estimate must follow
an external torque step with its own time constant), then arm6 runs in lock step against the
simulator, which pushes the arm with ``set_external_torque`` and carries payloads the arm may or
may not be told about.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.arm import Arm
from akarm.control.collision import DEFAULT_GAIN, MomentumObserver
from akarm.control.modes import Mode
from akarm.dynamics.model import RobotModel
from akarm.errors import CollisionError, ConfigError, StateError
from akarm.sim import SimulatedRobot
from akarm.telemetry.log import load as load_telemetry

from .conftest import ROBOTS

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
PLANAR2 = akarm.load_robot(ROBOTS / "planar2.yaml")
THRESHOLDS = [j.collision_threshold for j in ARM6.joints]  # what `akarm identify` suggested (robots/arm6.yaml)


@contextmanager
def lockstep(channel: str, q0=None, **arm_options) -> Iterator[tuple[Arm, SimulatedRobot]]:
    cfg = ARM6.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home") if q0 is None else q0) as sim, \
            Arm(cfg, clock=sim.clock, **arm_options) as arm:
        arm.enable()
        yield arm, sim


# ------------------------------------------------------------------------------------------------
# the observer on exact data
# ------------------------------------------------------------------------------------------------
def test_the_observer_follows_an_external_torque_step_with_its_time_constant() -> None:
    """planar2 integrated finely under a smooth torque, a 1.5 N·m push on the elbow from t = 0.5 s;
    the observer sees positions, velocities and the motor torque every 2 ms."""
    model = RobotModel(PLANAR2, armature=True)
    obs = MomentumObserver(model, [0.2, 0.1], [0.02, 0.01], [0.0, 0.0])
    q, v = np.array([0.3, -0.6]), np.zeros(2)
    h, every = 1e-4, 20  # integration step (s), steps per observer sample
    push = np.array([0.0, 1.5])
    out = []
    for k in range(int(0.7 / h)):
        t = k * h
        if k % every == 0:
            tau_m = model.gravity(q) + np.array([2.0 * math.sin(3 * t), 0.8 * math.cos(5 * t)])
            if k == 0:
                obs.reset(q, v, tau_m)
            else:
                out.append((t, obs.update(q, v, tau_m, every * h).copy()))
        ext = push if t >= 0.5 else np.zeros(2)
        friction = np.array([0.2, 0.1]) * np.tanh(v / 0.02) + np.array([0.02, 0.01]) * v
        v = v + h * model.forward_dynamics(q, v, tau_m - friction + ext)
        q = q + h * v
    times = np.array([t for t, _ in out])
    r = np.array([x for _, x in out])
    assert np.max(np.abs(r[times < 0.5])) < 0.02  # nothing pushes: (almost) nothing seen
    at = lambda s: r[np.argmin(np.abs(times - (0.5 + s)))]  # noqa: E731
    tau = 1.0 / DEFAULT_GAIN
    assert at(tau)[1] == pytest.approx(1.5 * (1 - math.exp(-1)), abs=0.1)  # 63 % after one time constant
    assert at(5 * tau)[1] == pytest.approx(1.5, abs=0.05)
    assert abs(at(5 * tau)[0]) < 0.05  # and on the joint it is on, only


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
        assert arm.collision is e.value
        arm.sleep(0.6)
        assert arm.enabled and not arm.moving and arm.state().mode is Mode.ACTIVE
        held = arm.state().q
        arm.sleep(0.3)
        assert np.max(np.abs(arm.state().q - held)) < 0.01  # at rest, short of the target
        assert np.max(np.abs(held - np.array(ARM6.pose("reach")))) > 0.2
        # the obstacle still pushes: the reflex waits for it to go before it watches again
        assert arm.collision is e.value
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
        assert arm.state().mode is Mode.TEACH and arm.collision is None
        arm.end_teach()
        arm.sleep(0.3)
        assert arm.enabled and arm.collision is None  # ... and the reflex watches again
        sim.set_external_torque(hand)
        with pytest.raises(CollisionError):
            arm.sleep(0.2)
        sim.set_external_torque(None)


def test_no_stop_in_fast_moves_payload_changes_and_the_demo_recording(channel: str) -> None:
    """With arm6.yaml's thresholds: moves at full speed between every pose, a payload picked up and
    put down (told to the arm), and the demo's figure eight; the reflex must not fire."""
    with lockstep(channel, telemetry_seconds=120) as (arm, sim):
        arm._ctl.reflex.clear_peak()
        for pose in ("ready", "left", "reach", "upright", "home", "reach", "ready"):
            arm.move_to(pose)
        arm.set_payload(0.4, (0.0, 0.0, 0.05))
        sim.set_payload(0.4, (0.0, 0.0, 0.05))
        arm.move_through(["ready", "left", "reach", "home"])
        arm.clear_payload()
        sim.clear_payload()
        arm.replay(Path(akarm.__file__).parent / "data" / "demo_path.csv")
        assert arm.collision is None and arm.enabled
        ratio = arm._ctl.reflex.peak / np.array(THRESHOLDS)
        assert np.all(ratio < 1.0), ratio  # not even before the reflex armed


def _within_range_and_limits(arm: Arm, log) -> None:
    lo, hi = arm.limits.lower, arm.limits.upper
    beyond = np.maximum(lo - log.q_des, log.q_des - hi).max(axis=0)
    assert np.all(beyond <= 1e-9), f"commanded past a joint's range by {beyond.max() * 1e3:.1f} mrad"
    fastest = np.abs(log.dq_des).max(axis=0) / arm.limits.velocity
    assert np.all(fastest <= 1.0 + 1e-6), f"commanded {fastest.max():.2f} times a joint's velocity limit"


def test_moves_retargeted_mid_way_stay_in_range_and_are_never_taken_for_a_collision(channel: str) -> None:
    """Random targets over the whole range, each retargeted after a random share of the last move, at
    a random speed factor (a user streaming targets). ruckig's own extrema miss a reversal at constant
    acceleration: such paths ran up to 21 mrad past a range, into the simulated hard stop, and the
    reflex rightly stopped the arm (26.6 s into this run)."""
    rng = np.random.default_rng(0)
    with lockstep(channel, telemetry_seconds=60) as (arm, sim):
        arm._ctl.reflex.clear_peak()
        lo, hi = arm.limits.lower + 0.02, arm.limits.upper - 0.02
        moves = 0
        while sim.t < 30.0:
            try:
                motion = arm.move_to(rng.uniform(lo, hi), speed=float(rng.uniform(0.3, 1.0)), wait=False)
            except akarm.LimitError:  # a path that would leave the range: refused, the last move goes on
                continue
            moves += 1
            arm.sleep(float(rng.uniform(0.1, 0.8)) * motion.duration)
        assert moves >= 25 and arm.collision is None and arm.enabled
        _within_range_and_limits(arm, arm.telemetry())
        ratio = arm._ctl.reflex.peak / np.array(THRESHOLDS)
        assert np.all(ratio < 0.6), ratio


def test_a_stick_streaming_targets_at_changing_speeds_is_followed_within_the_limits(channel: str) -> None:
    """``stream_to`` every 10-50 ms, to a noisy sweep over nearly the whole range, at speed factors
    0.3, 0.6 or 1 (a joystick with a speed button). A retarget to a slower speed first settles at
    the joints' own limits: planned at the slower ones instead, 36 % of these targets were refused
    (paths of hundreds of rad) and the rest commanded up to 1.4 times a joint's velocity limit."""
    rng = np.random.default_rng(0)
    with lockstep(channel, telemetry_seconds=60) as (arm, sim):
        arm._ctl.reflex.clear_peak()
        lo, hi = arm.limits.lower, arm.limits.upper
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        freq, phase = rng.uniform(0.1, 0.6, 6), rng.uniform(0.0, 2 * np.pi, 6)
        t0 = sim.t
        streamed = 0
        while sim.t - t0 < 12.0:
            stick = mid + 0.98 * half * np.sin(2 * np.pi * freq * (sim.t - t0) + phase) + rng.normal(0.0, 0.05, 6)
            arm.stream_to(np.clip(stick, lo, hi), speed=float(rng.choice([0.3, 0.6, 1.0])))  # never refused
            streamed += 1
            arm.sleep(0.01 * int(rng.integers(1, 6)))
        assert streamed > 300 and arm.collision is None and arm.enabled
        log = arm.telemetry()
        _within_range_and_limits(arm, log)
        assert np.abs(log.tracking_error()).max() < 0.05  # the arm follows its commands closely
        assert np.all(arm._ctl.reflex.peak / np.array(THRESHOLDS) < 0.6)


# ------------------------------------------------------------------------------------------------
# configuration and API
# ------------------------------------------------------------------------------------------------
def test_thresholds_come_from_the_yaml_and_change_at_run_time(tmp_path: Path, channel: str) -> None:
    text = (ROBOTS / "planar2.yaml").read_text().replace("urdf: planar2.urdf", f"urdf: {ROBOTS / 'planar2.urdf'}")
    text = text.replace("  limits: {velocity: 4.0, acceleration: 20.0, jerk: 200.0}",
                        "  limits: {velocity: 4.0, acceleration: 20.0, jerk: 200.0}\n  collision: {threshold: 1.5}")
    text = text.replace("    gains: {kp: 20.0, kd: 0.8}", "    gains: {kp: 20.0, kd: 0.8}\n"
                                                           "    collision: {threshold: 0.7}\n"
                                                           "    friction: {coulomb: 0.3, viscous: 0.03, offset: -0.05}")
    path = tmp_path / "planar2.yaml"
    path.write_text(text)
    config = akarm.load_robot(path)
    assert [j.collision_threshold for j in config.joints] == [1.5, 0.7]  # `defaults:` and the joint's own
    assert config.joints[1].friction.offset == -0.05
    arm = Arm(config)
    assert arm.collision_thresholds == {"shoulder": 1.5, "elbow": 0.7}
    arm.set_collision(thresholds={"elbow": None}, reaction="hold")
    assert arm.collision_thresholds == {"shoulder": 1.5, "elbow": None}
    assert arm._ctl.reflex.reaction == "hold"
    for bad in ({"wrist": 1.0}, [1.0], [1.0, -2.0], [1.0, math.inf]):
        with pytest.raises(StateError):
            arm.set_collision(thresholds=bad)
    with pytest.raises(StateError):
        arm.set_collision(reaction="ignore")
    with pytest.raises(StateError):
        Arm(config, collision_reaction="ignore")

    path.write_text(text.replace("collision: {threshold: 0.7}", "collision: {threshold: -1}"))
    with pytest.raises(ConfigError) as e:
        akarm.load_robot(path)
    assert "collision threshold" in str(e.value) and ":" in str(e.value.problems[0])


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


def test_collision_error_is_a_safety_stop_naming_joint_and_torque() -> None:
    e = CollisionError("collision: an external torque of +2.50 N·m", torque=2.5, threshold=1.1, joint="elbow",
                       fix="clear the obstacle")
    assert isinstance(e, akarm.SafetyStop) and isinstance(e, akarm.AkarmError)
    assert str(e).startswith("joint 'elbow': collision: an external torque of +2.50 N·m")
    assert e.torque == 2.5 and e.threshold == 1.1 and e.reaction == "disable"


def test_the_gravity_check_follows_the_payload_set_at_run_time() -> None:
    arm = Arm(ARM6)
    empty = {p.joint: p.torque for p in arm.gravity_check()}
    assert empty["shoulder_lift"] == pytest.approx(14.7, abs=0.1)  # akarm check's number for the file
    with warnings.catch_warnings():
        warnings.simplefilter("error", akarm.ConfigWarning)
        arm.set_payload(0.5, (0.0, 0.0, 0.05))  # the motors hold this everywhere: no warning
    loaded = {p.joint: p.torque for p in arm.gravity_check()}
    assert loaded["shoulder_lift"] > empty["shoulder_lift"] + 4.0  # 0.5 kg about a metre out
    with pytest.warns(akarm.ConfigWarning, match="shoulder_lift needs up to"):
        arm.set_payload(5.0, (0.0, 0.0, 0.05))
    arm.clear_payload()
    assert {p.joint: p.torque for p in arm.gravity_check()} == empty
