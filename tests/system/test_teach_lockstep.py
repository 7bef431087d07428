"""Teach and replay: limit checks with a suggested speed, replay accuracy (recordings on disk:
tests/unit/test_teach.py)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import akarm
from akarm import LimitError, Mode
from akarm.motion import recording as rec

from ..sim.test_arm import rig

NAMES = ("shoulder", "elbow")


def sweep(duration=3.0, rate=100.0, amp=(0.5, 0.4), period=(3.0, 1.5), q0=(0.0, 0.0)) -> rec.PathRecording:
    """A smooth recorded path starting at rest at q0 (cosine sweeps)."""
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    q = np.column_stack([q0[k] + amp[k] * (1 - np.cos(2 * np.pi * t / period[k])) / 2 for k in range(2)])
    return rec.PathRecording(NAMES, t, q)


# ---------------------------------------------------------------------------------------------
# limit checks
# ---------------------------------------------------------------------------------------------
def test_too_fast_path_is_refused_with_joint_time_and_a_speed_that_passes(channel) -> None:
    fast = sweep(duration=1.0, amp=(0.2, 1.2), period=(1.0, 0.5))  # the elbow swings 1.2 rad in 0.25 s
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        arm.enable()
        q_before = arm.state().q_des.copy()
        with pytest.raises(LimitError) as info:
            arm.replay(fast, speed=1.0)
        e = info.value
        assert e.joint == "elbow"
        m = re.search(r"at t = ([0-9.]+) s", str(e))
        assert m and 0.0 <= float(m.group(1)) <= 1.0
        suggested = float(re.search(r"--speed ([0-9.]+)", e.fix).group(1))
        assert 0 < suggested < 1
        np.testing.assert_allclose(arm.state().q_des, q_before)  # nothing moved
        assert not arm.moving
        # the suggested factor passes the same check
        rec.check_path(rec.PathPlan(fast, 0.0, suggested), arm.limits)


def test_path_outside_position_limits_is_refused(channel) -> None:
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        arm.enable()
        too_far = sweep(amp=(0.2, 2 * arm.limits.upper[1]), period=(3.0, 3.0))
        with pytest.raises(LimitError, match="outside") as info:
            arm.replay(too_far, speed=0.1)
        assert info.value.joint == "elbow" and "no speed factor helps" in info.value.fix


# ---------------------------------------------------------------------------------------------
# replay
# ---------------------------------------------------------------------------------------------
def replay_error(arm, path: rec.PathRecording, speed: float) -> float:
    """Max |measured - recorded| over the replayed path (after the soft start), rad."""
    t0 = arm.clock.now()
    motion = arm.replay(path, speed=speed)
    soft = motion.plan.plans[0].duration + motion.plan.plans[1].lead_in
    log = arm.telemetry(since=t0 + soft)
    t_rec = (log.t - (t0 + soft)) * speed
    keep = t_rec <= path.t[-1]
    want = np.column_stack([np.interp(t_rec[keep], path.t, path.q[:, k]) for k in range(2)])
    return float(np.max(np.abs(log.q[keep] - want)))


def test_replayed_path_follows_the_recording(channel) -> None:
    path = sweep(q0=(0.1, -0.1))
    with rig("planar2", channel, q0=[-0.3, 0.2]) as (arm, sim):
        arm.enable()
        err = replay_error(arm, path, 1.0)
        assert err < 0.02, err  # smoothing (50 ms window) + tracking
        err_slow = replay_error(arm, path, 0.5)
        assert err_slow < 0.02, err_slow


def test_keyframes_replay_through_every_pose(channel, tmp_path) -> None:
    kf = rec.Keyframes(NAMES, (rec.Keyframe((0.3, 0.2), "a"), rec.Keyframe((0.6, -0.3), "b"),
                               rec.Keyframe((0.2, 0.4), "c")))
    f = kf.save(tmp_path / "k.yaml")
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        arm.enable()
        t0 = arm.clock.now()
        motion = arm.replay(f)
        arm.sleep(0.3)
        log = arm.telemetry(since=t0)
        for seg, frame in zip(motion.plan.segments, kf.frames, strict=True):
            np.testing.assert_allclose(seg.end[0], frame.q, atol=1e-9)  # the path passes each pose exactly
            # and the 500 Hz commands come within one cycle's travel of it
            assert np.min(np.max(np.abs(log.q_des - np.array(frame.q)), axis=1)) < arm.limits.velocity.max() / 500
        np.testing.assert_allclose(arm.state().q, kf.frames[-1].q, atol=1e-3)


def test_teach_then_replay_reproduces_the_taught_path(channel) -> None:
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        arm.enable()
        arm.teach()
        assert arm.enabled and arm.mode is Mode.TEACH  # powered, under control, hand-guidable
        start = arm.keyframe("start")
        arm.start_recording(rate_hz=100)
        # a hand pushes the shoulder up and the elbow down, then lets go; a hand's force ramps
        # (here over 100 ms), it does not step; the pushes keep the arm off its hard stops
        pushes = [[1.0, -0.4], [0.6, -0.3], [0.0, 0.0], [-0.8, 0.3], [0.0, 0.0]]
        tau = np.zeros(2)
        for target in pushes:
            for k in range(20):
                tau = tau + (np.array(target) - tau) / (5 - k) if k < 5 else np.array(target, float)
                sim.set_external_torque(tau)
                arm.sleep(0.02)
        sim.set_external_torque(None)
        taught = arm.stop_recording()
        end = arm.keyframe("end")
        assert np.max(np.abs(np.array(end.q) - np.array(start.q))) > 0.1  # the arm really was moved
        arm.end_teach()
        assert arm.enabled
        try:  # as a user would: at the recorded speed, or at the speed the check suggests
            arm.check_replay(taught, 1.0)
            speed = 1.0
        except LimitError as e:
            speed = float(re.search(r"--speed ([0-9.]+)", e.fix).group(1))
        err = replay_error(arm, taught, speed)
        print(f"teach/replay: max deviation {err * 1e3:.1f} mrad over {taught.duration:.1f} s at speed {speed}")
        assert speed >= 0.5 and err < 0.03


def test_teach_carries_the_arm_weight(channel) -> None:
    with rig("planar2", channel, q0=[0.4, -0.3]) as (arm, sim):
        arm.enable()
        arm.teach()
        arm.sleep(1.0)
        drift = np.max(np.abs(sim.q - np.array([0.4, -0.3])))
        assert drift < 0.02, drift  # gravity compensated: it floats where it was left
        arm.end_teach()
        with pytest.raises(akarm.StateError, match="needs teach mode"):
            arm.start_recording()


def test_a_recording_with_a_duration_stops_itself(channel) -> None:
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        arm.enable()
        arm.teach()
        with pytest.raises(akarm.ArgumentError, match="duration must be a positive"):
            arm.start_recording(100, duration=0.0)
        arm.start_recording(100, duration=0.3)
        arm.sleep(0.2)
        assert not arm.recording_finished
        arm.sleep(0.3)  # well past the duration: no more samples are taken
        assert arm.recording_finished
        taught = arm.stop_recording()
        assert len(taught.t) == 31 and taught.duration == pytest.approx(0.3, abs=1e-6)
        assert not arm.recording_finished  # nothing is recording now
        arm.end_teach()


def test_check_replay_needs_no_enabled_arm(channel, tmp_path) -> None:
    """A recording can be validated before anything is enabled (the CLI does so before enabling)."""
    fast = sweep(duration=1.0, amp=(0.2, 1.2), period=(1.0, 0.5))
    with rig("planar2", channel, q0=[0.0, 0.0]) as (arm, sim):
        assert not arm.enabled
        with pytest.raises(LimitError) as info:
            arm.check_replay(fast)
        assert info.value.joint == "elbow"
        ok = arm.check_replay(sweep(), speed=1.0)
        assert isinstance(ok, rec.PathRecording)
        kf = rec.Keyframes(NAMES, (rec.Keyframe((0.1, 0.1)), rec.Keyframe((0.0, 9.0))))
        with pytest.raises(LimitError, match="keyframe 1 is at"):
            arm.check_replay(kf.save(tmp_path / "k.yaml"))
        assert not any(d.enabled for d in sim.drivers)
