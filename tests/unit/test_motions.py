"""Plans made outside the loop's lock: tickets, taking over, shifting in time; and the options of a stall.

:class:`~akarm.control.motions.Motions` alone, sampled as the loop samples it, with plans from the
planner: a plan taken in must continue the commanded state exactly where it takes over.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm import ArgumentError
from akarm.control.motions import Motions
from akarm.control.options import ControllerOptions
from akarm.errors import AkarmError
from akarm.motion.trajectory import Chain, JointLimits, Plan, Planner, Shifted
from akarm.sim import faults
from akarm.timing import get_profile

DT = 0.002
LIMITS = JointLimits(("a", "b"), np.array([-3.0, -3.0]), np.array([3.0, 3.0]), np.array([2.0, 2.0]),
                     np.array([10.0, 10.0]), np.array([100.0, 100.0]))
PLANNER = Planner(LIMITS)


def motions() -> Motions:
    def wait_for(done, timeout, what):  # (not used here)
        raise AssertionError("no waiting in these tests")

    return Motions(2, wait_for)


def run(m: Motions, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample from t0 to t1 every DT as the loop does; the times and commanded positions."""
    ts = np.arange(t0, t1, DT)
    return ts, np.array([np.array(m.sample(float(t))[0], dtype=float) for t in ts])


def max_step(q: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(q, axis=0))))


def test_a_plan_taken_from_a_ticket_continues_the_moving_arm_exactly_where_it_takes_over() -> None:
    m = motions()
    ticket = m.ticket(0.0)
    assert ticket.static_from == -math.inf  # holding: a plan from it may start whenever
    first = m.take(ticket, PLANNER.move_from(ticket.state, [1.0, -1.0], ticket.t))
    assert first is not None
    run(m, 0.0, 0.3)
    # a new motion planned from 20 ms ahead, while the loop goes on
    ticket = m.ticket(0.3 + 0.02)
    assert ticket.static_from > ticket.t   # moving then (at rest from the first motion's end)
    new = PLANNER.move_from(ticket.state, [0.0, 0.5], ticket.t)
    _, q = run(m, 0.3, 0.31)               # the loop samples meanwhile (not yet past ticket.t)
    second = m.take(ticket, new)
    assert second is not None and first.done and first.superseded and not second.done
    _, q2 = run(m, 0.31, 2.0)
    assert max_step(np.vstack([q, q2])) <= 2.0 * DT + 1e-9   # no step at the handover
    np.testing.assert_allclose(q2[-1], [0.0, 0.5], atol=1e-9)
    assert second.done and not second.superseded


def test_a_plan_that_comes_after_the_loop_went_past_its_start_is_refused_while_moving() -> None:
    m = motions()
    ticket = m.ticket(0.0)
    m.take(ticket, PLANNER.move_from(ticket.state, [1.0, -1.0], 0.0))
    run(m, 0.0, 0.3)
    ticket = m.ticket(0.3)
    late = PLANNER.move_from(ticket.state, [0.0, 0.5], ticket.t)
    run(m, 0.3, 0.31)                      # the loop went on: the state at 0.3 is behind it
    assert m.take(ticket, late) is None
    assert m.moving and m.generation == 1  # nothing changed


def test_a_ticket_is_void_once_another_request_came_between() -> None:
    m = motions()
    a, b = m.ticket(0.0), m.ticket(0.0)
    assert m.take(a, PLANNER.move_from(a.state, [0.5, 0.5], 0.0)) is not None
    assert m.take(b, PLANNER.move_from(b.state, [-0.5, 0.5], 0.0)) is None
    m.cancel()
    c = m.ticket(0.0)
    m.hold_at(np.array([0.1, 0.1]))
    assert m.take(c, PLANNER.move_from(c.state, [0.0, 0.0], 0.0)) is None


def test_a_plan_from_rest_takes_over_late_shifted_in_time_without_planning_again() -> None:
    m = motions()
    m.hold_at(np.array([0.2, -0.2]))
    run(m, 0.0, 0.1)
    ticket = m.ticket(0.1)
    plan = PLANNER.move_from(ticket.state, [1.0, 1.0], ticket.t)
    run(m, 0.1, 0.5)                       # planning took 0.4 s: the loop held meanwhile
    motion = m.take(ticket, plan)
    assert motion is not None and motion.plan.t0 == pytest.approx(m.sampled)
    assert isinstance(motion.plan, Plan) and motion.plan.segments is plan.segments  # shifted, shared
    _, q = run(m, 0.5, 2.0)
    assert max_step(q) <= 2.0 * DT + 1e-9
    np.testing.assert_allclose(q[0], [0.2, -0.2], atol=1e-6)
    np.testing.assert_allclose(q[-1], [1.0, 1.0], atol=1e-9)


def test_a_plan_from_where_the_motion_in_force_comes_to_rest_takes_over_when_it_does() -> None:
    m = motions()
    t = m.ticket(0.0)
    m.take(t, PLANNER.move_from(t.state, [0.3, 0.0], 0.0))
    run(m, 0.0, 0.1)
    ticket = m.ticket(5.0)                 # far ahead: the first motion has ended by then
    assert ticket.static_from < 5.0
    second = m.take(ticket, PLANNER.move_from(ticket.state, [0.3, 0.6], ticket.t))
    assert second is not None and second.plan.t0 == pytest.approx(ticket.static_from)  # not 5 s
    _, q = run(m, 0.1, 3.0)
    assert max_step(q) <= 2.0 * DT + 1e-9
    np.testing.assert_allclose(q[-1], [0.3, 0.6], atol=1e-9)


def test_two_plans_waiting_take_over_in_turn() -> None:
    m = motions()
    t = m.ticket(0.0)
    m.take(t, PLANNER.move_from(t.state, [1.0, 0.0], 0.0))
    run(m, 0.0, 0.2)
    a = m.ticket(0.25)
    first = m.take(a, PLANNER.move_from(a.state, [0.0, 1.0], a.t))
    b = m.ticket(0.3)                      # from the state the first one gives at 0.3
    second = m.take(b, PLANNER.move_from(b.state, [-1.0, 0.0], b.t))
    assert first is not None and second is not None and not first.done
    _, q = run(m, 0.2, 3.0)
    assert max_step(q) <= 2.0 * DT + 1e-9 and first.superseded
    np.testing.assert_allclose(q[-1], [-1.0, 0.0], atol=1e-9)


def test_shifted_plans_keep_their_shape() -> None:
    plan = PLANNER.through((np.zeros(2), np.zeros(2), np.zeros(2)), [[0.5, 0.5], [1.0, 0.0], [0.0, 0.0]], 1.0)
    later = plan.shifted(2.5)
    assert later.t0 == plan.t0 + 2.5 and later.t_end == plan.t_end + 2.5 and plan.shifted(0.0) is plan
    for t in np.linspace(plan.t0, plan.t_end, 37):
        np.testing.assert_allclose(later.sample(t + 2.5)[0], plan.sample(t)[0], atol=1e-12)
    chain = Chain([plan, PLANNER.move_from(plan.sample(plan.t_end), [0.2, 0.2], plan.t_end)])
    moved = chain.shifted(-0.5)
    assert isinstance(moved, Chain) and moved.plans[0].t0 == plan.t0 - 0.5
    wrapped = Shifted(chain, 1.0)
    assert wrapped.plans is chain.plans and wrapped.shifted(-1.0).sample(3.0)[0].tolist() == \
        chain.sample(3.0)[0].tolist()


def test_sampling_a_long_plan_finds_its_segment_by_bisection() -> None:
    pts = [[0.3 * math.sin(k / 7), 0.3 * math.cos(k / 5)] for k in range(400)]
    plan = PLANNER.through((np.array(pts[0]), np.zeros(2), np.zeros(2)), pts, 0.0)
    ends = np.cumsum([s.duration for s in plan.segments])
    for k in (0, 1, 150, 398, 399):
        t = ends[k] - 1e-6
        np.testing.assert_allclose(plan.sample(t)[0], plan.segments[k].at(t)[0])


def test_stall_limit_options() -> None:
    assert ControllerOptions().loop_stall_limit == 0.2
    assert ControllerOptions(timing=get_profile("slow")).loop_stall_limit == 1.0
    assert ControllerOptions(stall_limit=0.5, timing=get_profile("slow")).loop_stall_limit == 0.5
    for bad in (0.0, -1.0, math.nan, math.inf, "0.2", True):
        with pytest.raises(ArgumentError, match="stall_limit"):
            ControllerOptions(stall_limit=bad)  # type: ignore[arg-type]


def test_the_brownout_fault_and_its_command_line_form() -> None:
    assert faults.parse("elbow:brownout:0.01") == ("elbow", faults.Brownout(0.01))
    for bad in ("elbow:brownout", "elbow:brownout:0", "elbow:brownout:-1", "elbow:brownout:x", "elbow:brownout:1,2"):
        with pytest.raises(AkarmError, match=r"bad fault|Brownout"):
            faults.parse(bad)
