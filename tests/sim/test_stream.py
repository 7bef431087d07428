"""A policy's targets streamed into the loop (akarm.server.streaming.TargetStream), in lock step: a
target past the range clamped and counted, NaN or a missing joint refused with the arm held, a client
that goes silent leaves the arm decelerating to a hold, and no command step above a joint's limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm import ArgumentError
from akarm.server.streaming import DEFAULT_TIMEOUT, TargetStream, check_timeout

from .conftest import lockstep_arm

FRAME = 1.0 / 30.0  # s between a LeRobot policy's actions


def run(arm, stream, seconds):
    """Let ``seconds`` pass in steps of 5 ms, the stream's watchdog looking at each."""
    for _ in range(round(seconds / 0.005)):
        arm.sleep(0.005)
        stream.check()


def within_limits(arm, log):
    """Each command step within the joints' velocity and acceleration limits (the jerk-limited retargeting)."""
    dt = 1.0 / arm.config.rate_hz
    lim = arm.limits
    assert np.all(np.abs(np.diff(log.q_des, axis=0)) <= lim.velocity * dt * 1.001 + 1e-12)
    assert np.all(np.abs(np.diff(log.dq_des, axis=0)) <= lim.acceleration * dt * 1.001 + 1e-12)
    assert np.all(log.q_des >= lim.lower - 1e-9) and np.all(log.q_des <= lim.upper + 1e-9)


def test_a_target_past_the_range_is_clamped_counted_and_said_once(channel):
    said: list[str] = []
    with lockstep_arm("planar2", channel, enable=True) as (arm, sim):
        t0 = sim.clock.now()
        stream = TargetStream(arm, log=said.append)
        upper = arm.limits.upper[0]
        for _ in range(30):  # 1 s of a policy asking 1 rad past the shoulder's limit
            report = stream.send({"shoulder": upper + 1.0, "elbow": 0.3})
            run(arm, stream, FRAME)
        assert report.clamped == ("shoulder",)
        assert stream.clamped == 30 and report.clamped_total == 30
        assert len(said) == 1 and "shoulder" in said[0] and "past its range" in said[0]
        log = arm.telemetry(since=t0)
        within_limits(arm, log)
        np.testing.assert_allclose(log.q_des[-1], [upper, 0.3], atol=1e-9)  # at the edge, not past it
        assert abs(arm.state().q[0] - upper) < 0.02


def test_nan_or_a_missing_joint_is_refused_and_the_arm_holds(channel):
    with lockstep_arm("planar2", channel, enable=True) as (arm, sim):
        stream = TargetStream(arm)
        stream.send([1.5, -1.5])
        run(arm, stream, 0.2)
        assert arm.moving
        t0 = sim.clock.now()
        with pytest.raises(ArgumentError, match="not a finite number") as e:
            stream.send([math.nan, 0.0])
        assert e.value.joint == "shoulder"
        run(arm, stream, 1.0)
        assert not arm.moving
        log = arm.telemetry(since=t0)
        within_limits(arm, log)
        held = log.q_des[-1]
        assert held[0] < 1.4 and held[1] > -1.4  # stopped short of the old target: it does not go on to it
        np.testing.assert_allclose(log.q_des[-200:], np.tile(held, (200, 1)), atol=1e-12)  # and holds
        for bad, joint in (({"shoulder": 0.1}, "elbow"), ({"shoulder": None, "elbow": 0.0}, "shoulder")):
            with pytest.raises(ArgumentError) as e:
                stream.send(bad)
            assert e.value.joint == joint
        with pytest.raises(ArgumentError, match="no joint named 'wrist'"):
            stream.send({"shoulder": 0.0, "elbow": 0.0, "wrist": 0.0})
        with pytest.raises(ArgumentError, match="has no gripper"):
            stream.send([0.0, 0.0], gripper=0.02)
        assert stream.refused == 5
        np.testing.assert_allclose(arm.state().q_des, held, atol=1e-12)  # nothing of them moved the arm
        for _ in range(25):  # partial targets: the shoulder keeps its command
            stream.send({"elbow": 0.2}, partial=True)
            run(arm, stream, FRAME)
        assert stream.timeouts == 0
        np.testing.assert_allclose(arm.state().q_des, [held[0], 0.2], atol=1e-9)


def test_a_silent_client_leaves_the_arm_decelerating_to_a_hold_and_the_next_target_resumes(channel):
    said: list[str] = []
    with lockstep_arm("planar2", channel, enable=True) as (arm, sim):
        stream = TargetStream(arm, log=said.append)
        assert stream.timeout == DEFAULT_TIMEOUT
        t0 = sim.clock.now()
        stream.send([1.6, 0.0])  # far: 1 s or so at the limits
        run(arm, stream, 0.15)
        assert stream.timeouts == 0 and arm.moving
        run(arm, stream, 1.0)  # nothing for 1 s
        assert stream.timeouts == 1 and not arm.moving
        assert len(said) == 1 and "decelerates to a hold" in said[0]
        log = arm.telemetry(since=t0)
        silent = log.t - t0 >= DEFAULT_TIMEOUT + 0.01
        assert log.q_des[-1][0] < 1.3  # stopped short of the stale target
        speed = np.abs(log.dq_des[:, 0])
        assert speed[~silent].max() > 1.0 and speed[-1] == 0.0  # it was moving, and came to rest
        t1 = sim.clock.now()
        for _ in range(30):  # the next targets resume it, without a jump
            stream.send([0.5, 0.5])
            run(arm, stream, FRAME)
        assert stream.timeouts == 1
        within_limits(arm, arm.telemetry(since=t0))
        np.testing.assert_allclose(arm.telemetry(since=t1).q_des[-1], [0.5, 0.5], atol=1e-9)


def test_a_gripper_width_past_its_stroke_is_clamped_counted_and_said_once(channel):
    """arm6g's gripper (80 mm stroke) asked 0.12 m then -0.02 m by a policy: each taken to the stroke's
    edge, counted with the joints and named in the report; the jaws go there."""
    said: list[str] = []
    with lockstep_arm("arm6g", channel, enable=True) as (arm, sim):
        assert arm.gripper is not None
        stream = TargetStream(arm, log=said.append)
        q = arm.state().q_des.tolist()
        for _ in range(30):
            report = stream.send(q, gripper=0.12)
            run(arm, stream, FRAME)
        assert report.gripper == pytest.approx(0.08) and report.clamped == ("gripper",)
        assert stream.clamped == 30 and report.clamped_total == 30
        assert sim.gripper_width() == pytest.approx(0.08, abs=0.002)
        for _ in range(30):
            report = stream.send(q, gripper=-0.02)
            run(arm, stream, FRAME)
        assert report.gripper == 0.0 and report.clamped_total == 60
        assert sim.gripper_width() == pytest.approx(0.0, abs=0.002)
        report = stream.send(q, gripper=0.05)  # within the stroke: taken as it is, not counted
        assert report.gripper == 0.05 and report.clamped == () and report.clamped_total == 60
        assert len(said) == 1 and "past its stroke" in said[0]
        with pytest.raises(ArgumentError, match="not a finite number") as e:
            stream.send(q, gripper=math.nan)
        assert e.value.joint == "gripper"


def test_the_timeout_is_checked():
    assert check_timeout(1) == 1.0
    for bad in (0.0, -1.0, math.nan, 60.0, True, "1"):
        with pytest.raises(ArgumentError, match="timeout"):
            check_timeout(bad)


def sway_error(channel, lead):
    """Stream a 1.5 s sway (0.8 rad, 1.7 rad/s at its fastest) at 30 Hz, then its end for 0.5 s: the
    largest distance from the commanded position to the sway, the end's error, the log."""
    with lockstep_arm("planar2", channel, enable=True) as (arm, sim):
        stream = TargetStream(arm, lead=lead)
        t0 = sim.clock.now()
        errors = []
        for k in range(60):
            t = min(k * FRAME, 1.5)
            want = 0.4 * (1.0 - math.cos(math.pi * t / 1.5))
            stream.send([want, -want])
            run(arm, stream, FRAME)
            errors.append(abs(arm.state().q_des[0] - want))
        log = arm.telemetry(since=t0)
        within_limits(arm, log)
        return max(errors[5:45]), abs(log.q_des[-1][0] - 0.8), stream.timeouts


def test_a_moving_stream_is_led_by_its_braking_distance(channel):
    led, led_end, timeouts = sway_error(channel, True)
    trailed, trailed_end, _ = sway_error(channel + "-b", False)
    print(f"sway tracking: led {led:.4f} rad, trailed {trailed:.4f} rad; ends {led_end:.2e}, {trailed_end:.2e}")
    assert timeouts == 0
    assert led < 0.5 * trailed
    assert led_end < 1e-6 and trailed_end < 1e-6  # a stream that stops moving is reached and held
