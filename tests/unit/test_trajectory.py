"""Trajectory planning: limits respected, synchronised arrival, waypoints, stops, limit errors."""

from __future__ import annotations

import numpy as np
import pytest

from akarm import ArgumentError, LimitError, TrajectoryError
from akarm.motion.trajectory import JointLimits, Plan, Planner

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
    with pytest.raises(ArgumentError, match="speed must be in"):
        p.move(rest([0, 0, 0]), [1, 1, 1], 0.0, speed=1.5)


def test_target_outside_limits_names_the_joint() -> None:
    p = Planner(limits())
    with pytest.raises(LimitError) as info:
        p.move(rest([0, 0, 0]), [0.0, 2.5, 0.0], 0.0)
    assert info.value.joint == "b" and "outside the joint's range" in str(info.value)
    with pytest.raises(ArgumentError, match="finite"):
        p.move(rest([0, 0, 0]), [0.0, float("nan"), 0.0], 0.0)


def test_a_joint_that_starts_past_its_range_may_stay_there_while_the_others_move() -> None:
    """An arm that sagged past a limit while it was off: a move of the other joints leaves that one
    where it is (a jog of one joint fills the others with their positions); a target of it outside
    the range, further out or on the way in, stays refused."""
    p = Planner(limits())
    start = rest([0.0, 2.03, 0.0])  # b sagged 0.03 rad past its upper limit
    for move in (p.move, p.move_from):
        plan = Plan([move(start, [1.0, 2.03, 0.5], 0.0)]) if move == p.move else move(start, [1.0, 2.03, 0.5], 0.0)
        _t, q, _v, _a = sampled(plan)
        assert np.abs(q[:, 1] - 2.03).max() < 1e-9 and np.abs(q[-1] - [1.0, 2.03, 0.5]).max() < 1e-9
        for target in ([0.0, 2.04, 0.0], [0.0, 2.01, 0.0], [0.0, 2.03 + 2e-6, 0.0]):
            with pytest.raises(LimitError) as info:
                move(start, target, 0.0)
            assert info.value.joint == "b"
            assert "it starts at 2.0300 rad: it may stay there, or move into the range" in str(info.value)
    # a joint that starts within its range gets the range alone, as before
    with pytest.raises(LimitError) as info:
        p.move(start, [2.01, 2.03, 0.0], 0.0)
    assert info.value.joint == "a" and "it starts at" not in str(info.value)


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
    with pytest.raises(ArgumentError, match="has 2 values"):
        p.through(rest([0, 0, 0]), [[0.5, 0]], 0.0)


def test_exact_extrema_see_a_reversal_at_constant_acceleration_that_ruckig_misses() -> None:
    """A move that starts moving away from its target (a retarget) turns around inside a phase of
    constant acceleration; ruckig's own extrema (Community Version) miss that reversal."""
    from akarm.motion.trajectory import position_extrema

    p = Planner(limits())
    start = (np.array([0.0, 0.0, 0.0]), np.array([-2.0, 0.0, 0.0]), np.zeros(3))
    seg = p.move(start, [1.0, 0.5, 0.2], 0.0)
    t = np.linspace(0.0, seg.duration, 20001)
    q = np.array([seg.traj.at_time(x)[0] for x in t])
    ours = position_extrema(seg.traj)
    np.testing.assert_allclose([e[0] for e in ours], q.min(axis=0), atol=1e-6)
    np.testing.assert_allclose([e[2] for e in ours], q.max(axis=0), atol=1e-6)
    assert abs(t[np.argmin(q[:, 0])] - ours[0][1]) < 1e-3  # and when
    assert seg.traj.position_extrema[0].min > q[:, 0].min() + 0.1  # ruckig's: 0.11 rad short
    # so a path that passes a limit this way is refused (ruckig's extrema would let it through)
    with pytest.raises(LimitError, match=r"reaches -2\.09"):
        p.move((np.array([-1.8, 0.0, 0.0]), np.array([-2.0, 0.0, 0.0]), np.zeros(3)), [1.0, 0.5, 0.2], 0.0)


@pytest.mark.parametrize("speed", [0.3, 0.6, 0.9])
def test_a_retarget_to_a_slower_speed_stays_within_the_joint_limits(speed: float) -> None:
    """Retargeted mid-move at a slower speed factor, the joints first settle within the slower limits
    at their own: ruckig alone brakes at the slower jerk, and a joint accelerating hard keeps
    accelerating for seconds (at 0.3: to 20 times its velocity limit, 1000 rad away)."""
    lim = limits()
    p = Planner(lim)
    fast = Plan([p.move(rest([0.0, 0.0, 0.0]), [1.8, -1.8, 1.5], 0.0)])
    _t, _q, _v, a = sampled(fast)
    t_hard = _t[int(np.argmax(np.abs(a[:, 1])))]  # hardest acceleration of the fastest joint
    start = fast.sample(t_hard)
    plan = p.move_from(start, [-0.5, 0.5, 0.0], t_hard, speed)
    for got, want in zip(plan.sample(t_hard), start, strict=True):
        np.testing.assert_allclose(got, want, atol=1e-9)  # no jump
    assert_within_limits(plan, lim)  # never beyond the joints' own limits, not even settling
    settled = plan.segments[0].t0 + plan.segments[0].duration
    assert len(plan.segments) == 2 and settled - t_hard < 0.5
    slow = lim.scaled(speed)
    _t2, _q2, v2, a2 = sampled(Plan(plan.segments[1:]))
    assert np.all(np.abs(v2) <= slow.velocity * (1 + 1e-6)) and np.all(np.abs(a2) <= slow.acceleration * (1 + 1e-6))
    q_end, v_end, _ = plan.sample(plan.t_end)
    np.testing.assert_allclose(q_end, [-0.5, 0.5, 0.0], atol=1e-9)
    np.testing.assert_allclose(v_end, 0.0, atol=1e-9)
    # a start the slower limits can take as it is needs no settling
    assert len(p.move_from(fast.sample(0.001), [0.1, 0.1, 0.1], 0.001, 1.0).segments) == 1
    calm = Plan([p.move(rest([0.0, 0.0, 0.0]), [1.0, 1.0, 1.0], 0.0, speed=0.2)])
    assert len(p.move_from(calm.sample(0.5), [0.0, 0.0, 0.0], 0.5, speed).segments) == 1
