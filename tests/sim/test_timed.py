"""Timed trajectories (Arm.follow): points reached at their times, jerk-limited, refused whole past a limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

import akarm

NAN = math.nan


@pytest.fixture
def arm6(lockstep):
    with lockstep("arm6", enable=True) as (arm, sim):
        yield arm, sim


def test_points_are_reached_at_their_times(arm6):
    arm, sim = arm6
    q0 = arm.state().q_des
    points = [[0.3, 0.5, *q0[2:]], [0.5, 0.7, *q0[2:]], [0.2, 0.4, *q0[2:]]]
    times = [1.0, 2.0, 3.0]
    t0 = arm.clock.now()
    motion = arm.follow(times, points, wait=False)
    assert motion.duration == pytest.approx(3.0, abs=1e-6)  # each point no sooner than asked, and feasible
    for t, p in zip(times, points, strict=True):
        arm.sleep(t0 + t - arm.clock.now())
        assert np.max(np.abs(arm.state().q_des - p)) < 1e-6, "the commanded path passes the point at its time"
        assert np.max(np.abs(arm.state().q - p)) < 0.02, "and the arm follows it"
    motion.wait()
    arm.sleep(0.3)
    assert np.max(np.abs(arm.state().q - points[-1])) < 2e-3


def test_nan_keeps_the_other_joints_where_they_are_commanded(arm6):
    arm, sim = arm6
    q0 = arm.state().q_des.copy()
    arm.follow([0.5, 1.0], [[0.2, NAN, NAN, NAN, 0.3, NAN], [0.1, NAN, NAN, NAN, 0.2, NAN]])
    q_des = arm.state().q_des
    assert q_des[[0, 4]] == pytest.approx([0.1, 0.2], abs=1e-9)
    assert q_des[[1, 2, 3, 5]] == pytest.approx(q0[[1, 2, 3, 5]], abs=1e-12)


def test_a_time_the_limits_cannot_make_is_made_as_soon_as_they_allow(arm6):
    arm, sim = arm6
    q0 = arm.state().q_des
    far = [2.0, *q0[1:]]
    motion = arm.follow([0.01], [far], wait=False)
    assert motion.duration > 0.5  # 2 rad at 3 rad/s: not in 10 ms
    rest = arm.planner.move((q0, np.zeros(6), np.zeros(6)), far, 0.0)
    assert motion.duration == pytest.approx(rest.duration, rel=1e-6)  # the fastest move, no slower


def test_a_point_past_a_limit_refuses_the_whole_trajectory_and_nothing_moves(arm6):
    arm, sim = arm6
    q0 = arm.state().q.copy()
    with pytest.raises(akarm.LimitError, match="shoulder_pan") as e:
        arm.follow([1.0, 2.0], [[0.3, *q0[1:]], [5.0, *q0[1:]]])
    assert "point 1" in str(e.value)
    assert not arm.moving
    arm.sleep(0.5)
    assert np.max(np.abs(arm.state().q - q0)) < 2e-3


def test_a_new_trajectory_replaces_the_running_one_without_a_jump(arm6):
    arm, sim = arm6
    q0 = arm.state().q_des
    arm.follow([2.0], [[1.0, *q0[1:]]], wait=False)
    arm.sleep(0.8)
    before = arm.telemetry(since=arm.clock.now() - 0.05)
    arm.follow([1.0], [[-0.5, *q0[1:]]], wait=False)
    arm.sleep(1.5)
    log = arm.telemetry(since=before.t[0])
    dq = np.diff(log.dq_des[:, 0])
    # continuous in velocity: no step larger than the acceleration limit allows in one cycle
    assert np.max(np.abs(dq)) <= arm.limits.acceleration[0] / arm.config.rate_hz * 1.01
    assert log.q_des[-1, 0] == pytest.approx(-0.5, abs=1e-6)
