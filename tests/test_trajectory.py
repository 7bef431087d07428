"""Trajectory planning: limits respected, synchronised arrival, waypoints, stops, limit errors."""

from __future__ import annotations

import numpy as np
import pytest

from akarm import LimitError, TrajectoryError
from akarm.trajectory import JointLimits, Plan, Planner

NAMES = ("a", "b", "c")


def limits(lower=-2.0, upper=2.0) -> JointLimits:
    return JointLimits(NAMES, np.full(3, lower), np.full(3, upper), np.array([2.0, 3.0, 1.5]),
                       np.array([10.0, 15.0, 8.0]), np.array([100.0, 150.0, 80.0]))


def rest(q) -> tuple:
    return (np.asarray(q, float), np.zeros(3), np.zeros(3))


def sampled(plan: Plan, dt: float = 1e-3):
    t = np.arange(plan.t0, plan.t_end + dt, dt)
    s = [plan.sample(x) for x in t]
    return t, np.array([x[0] for x in s]), np.array([x[1] for x in s]), np.array([x[2] for x in s])


def assert_within_limits(plan: Plan, lim: JointLimits, dt: float = 1e-3) -> None:
    _t, q, v, a = sampled(plan, dt)
    assert np.all(np.abs(v) <= lim.velocity * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(a) <= lim.acceleration * (1 + 1e-6) + 1e-9)
    jerk = np.diff(a, axis=0) / dt
    assert np.all(np.abs(jerk) <= lim.jerk * (1 + 1e-3) + 1e-6)
    assert np.all(q >= lim.lower - 1e-9) and np.all(q <= lim.upper + 1e-9)


def test_move_is_synchronised_and_within_limits() -> None:
    lim = limits()
    p = Planner(lim)
    seg = p.move(rest([0, 0, 0]), [1.0, -0.5, 0.2], t0=10.0)
    plan = Plan([seg])
    assert plan.t0 == 10.0
    q_end, v_end, _a_end = plan.sample(plan.t_end)
    np.testing.assert_allclose(q_end, [1.0, -0.5, 0.2], atol=1e-9)
    np.testing.assert_allclose(v_end, 0, atol=1e-9)
    # time synchronisation: every joint is still moving until shortly before the end
    _, q, _, _ = sampled(plan)
    moving_until = [np.max(np.nonzero(np.abs(np.diff(q[:, k])) > 1e-9)[0]) for k in range(3)]
    assert max(moving_until) - min(moving_until) < 20
    assert_within_limits(plan, lim)


def test_speed_fraction_slows_the_same_path() -> None:
    p = Planner(limits())
    full = p.move(rest([0, 0, 0]), [1.0, 1.0, 1.0], 0.0)
    half = p.move(rest([0, 0, 0]), [1.0, 1.0, 1.0], 0.0, speed=0.5)
    assert half.duration == pytest.approx(2 * full.duration, rel=1e-6)
    with pytest.raises(LimitError, match="speed must be in"):
        p.move(rest([0, 0, 0]), [1, 1, 1], 0.0, speed=1.5)


def test_target_outside_limits_names_the_joint() -> None:
    p = Planner(limits())
    with pytest.raises(LimitError) as info:
        p.move(rest([0, 0, 0]), [0.0, 2.5, 0.0], 0.0)
    assert info.value.joint == "b" and "outside the joint's range" in str(info.value)
    with pytest.raises(LimitError, match="finite"):
        p.move(rest([0, 0, 0]), [0.0, float("nan"), 0.0], 0.0)


def test_path_overshooting_a_limit_is_refused_before_moving() -> None:
    p = Planner(limits(upper=1.0))
    # moving fast towards the upper limit with a target just inside: braking overshoots it
    start = (np.array([0.8, 0, 0]), np.array([2.0, 0, 0]), np.zeros(3))
    with pytest.raises(LimitError) as info:
        p.move(start, [0.95, 0, 0], 0.0)
    assert info.value.joint == "a" and "planned path reaches" in str(info.value)


def test_bad_limits_become_trajectory_error() -> None:
    bad = JointLimits(NAMES, np.full(3, -2.0), np.full(3, 2.0), np.array([-1.0, 1, 1]), np.ones(3), np.ones(3))
    with pytest.raises(TrajectoryError, match="ruckig could not plan"):
        Planner(bad).move(rest([0, 0, 0]), [1, 0, 0], 0.0)


def test_stop_is_continuous_and_ends_at_rest() -> None:
    lim = limits()
    p = Planner(lim)
    start = (np.array([0.0, 0.1, 0.2]), np.array([1.5, -2.0, 1.0]), np.array([3.0, 0.0, -2.0]))
    plan = Plan([p.stop(start, 5.0)])
    q0, v0, a0 = plan.sample(5.0)
    np.testing.assert_allclose(q0, start[0], atol=1e-12)
    np.testing.assert_allclose(v0, start[1], atol=1e-12)
    np.testing.assert_allclose(a0, start[2], atol=1e-12)
    _, v_end, a_end = plan.sample(plan.t_end)
    np.testing.assert_allclose(v_end, 0, atol=1e-9)
    np.testing.assert_allclose(a_end, 0, atol=1e-9)
    _, _, _v, a = sampled(plan)
    assert np.all(np.abs(np.diff(a, axis=0)) / 1e-3 <= lim.jerk * 1.001 + 1e-6)


def test_through_waypoints_passes_each_exactly_and_beats_stopping() -> None:
    lim = limits()
    p = Planner(lim)
    pts = [[0.5, 0.5, 0.3], [1.0, 1.2, 0.6], [1.5, 0.8, 0.9], [1.8, 1.5, 1.2]]
    plan = p.through(rest([0, 0, 0]), pts, 0.0)
    stopping = sum(p.move(rest(a), b, 0.0).duration for a, b in zip([[0, 0, 0], *pts[:-1]], pts, strict=True))
    assert plan.duration < stopping * 0.9, (plan.duration, stopping)
    # every waypoint is reached exactly at a segment boundary
    for seg, target in zip(plan.segments, pts, strict=True):
        q, _, _ = seg.at(seg.t0 + seg.duration)
        np.testing.assert_allclose(q, target, atol=1e-9)
    # intermediate waypoints are passed with non-zero speed (not stopped at)
    assert any(np.linalg.norm(seg.end[1]) > 0.1 for seg in plan.segments[:-1])
    # continuity of position and velocity across segment boundaries, and limits everywhere
    _, q, v, _ = sampled(plan, 1e-3)
    assert np.max(np.abs(np.diff(q, axis=0))) < lim.velocity.max() * 1e-3 * 1.01
    assert np.max(np.abs(np.diff(v, axis=0))) < lim.acceleration.max() * 1e-3 * 1.01
    assert_within_limits(plan, lim)


def test_through_reversal_stops_the_reversing_joint_only() -> None:
    p = Planner(limits())
    plan = p.through(rest([0, 0, 0]), [[1.0, 1.0, 0.5], [0.0, 1.5, 1.0]], 0.0)
    v_via = plan.segments[0].end[1]
    assert v_via[0] == pytest.approx(0.0, abs=1e-9)  # joint a reverses at the waypoint
    assert v_via[1] > 0.05 and v_via[2] > 0.05


def test_through_checks_waypoints_and_sizes() -> None:
    p = Planner(limits())
    with pytest.raises(LimitError, match="waypoint 1"):
        p.through(rest([0, 0, 0]), [[0.5, 0, 0], [0, 3.0, 0]], 0.0)
    with pytest.raises(LimitError, match="has 2 values"):
        p.through(rest([0, 0, 0]), [[0.5, 0]], 0.0)
