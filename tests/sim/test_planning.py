"""Planning never blocks the loop, and motions have sizes (akarm.motion.bounds), in lock step.

To see the loop run while a plan is made, a second thread steps it (``loop.step()``) while this one
plans: the controller's lock is not held while planning, so the cycles go on, and the new plan takes
over where the commanded state then is. The full-size acceptance in real time (5000 keyframes, a
one-hour path) is measured in benchmarks/bench_planning.py.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from akarm import ArgumentError, RecordingError
from akarm.motion import recording as rec_mod
from akarm.motion import timed
from akarm.motion.bounds import MAX_DURATION, MAX_KEYFRAMES, MAX_PATH_SAMPLES, MAX_TRAJECTORY_POINTS


def steps_elsewhere(arm, n: int) -> int:
    """Run ``n`` cycles of the lock-step loop from another thread and wait for them (10 s at most):
    how many ran. Called while a plan is being made, all of them run only if planning does not hold
    the controller's lock."""
    loop = arm.observe.loop
    ran = []

    def run() -> None:
        for _ in range(n):
            loop.step()
            ran.append(1)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(10.0)
    return len(ran)


def keyframes(n: int, amp: float = 0.4) -> list[list[float]]:
    return [[amp * math.sin(k / 9.0) - 0.5, amp * math.cos(k / 7.0) - 0.2] for k in range(n)]


@pytest.mark.parametrize("moving", [False, True])
def test_the_loop_runs_while_a_plan_is_made_and_it_takes_over_without_a_step(lockstep, monkeypatch,
                                                                             moving: bool) -> None:
    """While the caller plans, 20 cycles run in another thread (they would wait for the lock if
    planning held it); moving, the arm goes past the state planned from, so the plan is refused and
    made again from further ahead, and takes over there without a step. (Whether a cycle is held up
    in real time, by the interpreter rather than the lock, is measured in benchmarks/bench_planning.py.)"""
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        if moving:
            arm.move_to([0.5, -0.5], speed=0.3, wait=False)
            arm.sleep(0.1)
        points = keyframes(12)
        through = arm.planner.through
        during: list[int] = []

        def planning(*args, **kwargs):
            during.append(steps_elsewhere(arm, 20))
            return through(*args, **kwargs)

        monkeypatch.setattr(arm.planner, "through", planning)
        t_sim = arm.clock.now()
        motion = arm.move_through(points, wait=False)
        assert during and all(n == 20 for n in during), during
        assert len(during) == (2 if moving else 1)  # moving: the first plan came too late, made again ahead
        assert arm.enabled and motion.plan.t0 >= t_sim + 20 / arm.config.rate_hz - 1e-9
        arm.sleep(0.5)
        log = arm.telemetry(since=t_sim)
        steps = np.abs(np.diff(log.q_des, axis=0)) / (arm.limits.velocity / arm.config.rate_hz)
        assert steps.max() <= 1.0 + 1e-6, steps.max()  # the handover continued the commanded state
        motion.wait()
        np.testing.assert_allclose(arm.state().q_des, points[-1], atol=1e-9)


def test_a_trajectory_past_the_size_limit_is_refused_before_anything_is_planned(lockstep, monkeypatch) -> None:
    def not_planned(*args, **kwargs):
        raise AssertionError("planned")

    monkeypatch.setattr(timed, "timed_plan", not_planned)
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        n = 100_000
        times = [0.01 * (k + 1) for k in range(n)]
        positions = [[-1.0, 0.0]] * n
        with pytest.raises(ArgumentError, match=f"100000 points: a trajectory has at most {MAX_TRAJECTORY_POINTS}"):
            arm.follow(times, positions)
        with pytest.raises(ArgumentError, match=f"past the {MAX_DURATION:g} s"):
            arm.follow([1.0, MAX_DURATION + 1.0], [[-1.0, 0.0], [-1.0, 0.1]])
        with pytest.raises(ArgumentError, match=f"move_through takes at most {MAX_KEYFRAMES}"):
            arm.move_through([[-1.0, 0.0]] * (MAX_KEYFRAMES + 1))
        assert not arm.moving and arm.fault is None


def test_recordings_past_the_size_limits_are_refused_naming_the_bound(lockstep) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        names = tuple(arm.names)
        many = rec_mod.Keyframes(names, tuple(rec_mod.Keyframe((-1.0, 0.0)) for _ in range(MAX_KEYFRAMES + 1)))
        with pytest.raises(RecordingError, match="MAX_KEYFRAMES"):
            arm.replay(many)
        n = MAX_PATH_SAMPLES + 1
        long = rec_mod.PathRecording(names, np.arange(n) * 0.002, np.zeros((n, 2)))
        with pytest.raises(RecordingError, match="MAX_PATH_SAMPLES"):
            arm.replay(long)
        slow = rec_mod.PathRecording(names, np.array([0.0, 3600.0]), np.array([[-1.0, 0.0], [-1.0, 0.1]]))
        with pytest.raises(RecordingError, match="MAX_DURATION"):
            arm.replay(slow, speed=0.2)  # 5 hours
        with pytest.raises(RecordingError, match="MAX_PATH_SAMPLES"):
            arm.check_replay(long)
        assert not arm.moving and arm.fault is None


def test_a_keyframe_replay_is_planned_once_from_where_the_arm_is(lockstep, tmp_path) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        kf = rec_mod.Keyframes(tuple(arm.names), tuple(rec_mod.Keyframe(tuple(q)) for q in keyframes(5)))
        motion = arm.replay(kf, wait=False)
        assert len(motion.plan.segments) == 5  # through every keyframe, from the commanded state
        motion.wait()
        np.testing.assert_allclose(arm.state().q_des, kf.frames[-1].q, atol=1e-9)
