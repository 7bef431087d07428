"""Jerk-limited, time-synchronised trajectories (ruckig), checked against joint limits.

A :class:`Plan` is a chain of ruckig segments with absolute start times; it is sampled at
wall-clock (or simulated) time by the control loop. Every segment is planned from an exact state
(position, velocity, acceleration), so a chain is continuous in all three by construction: moves
start from wherever the commanded trajectory is, retargeting is smooth, and waypoints are passed
through without stopping.

ruckig's Community Version does not enforce position limits and its waypoint feature calls a cloud
server: akarm checks every segment's position extrema itself (:func:`position_extrema`: ruckig's
own miss a reversal at constant acceleration, which retargets have) and chains segments for
waypoints. A retarget to a slower speed than the motion it interrupts first settles within the
slower limits at the joints' own (:meth:`Planner.settle`).
"""

from __future__ import annotations

import bisect
import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import ruckig

from akarm.errors import ArgumentError, LimitError, TrajectoryError, num

__all__ = ["MAX_RANGE_MARGIN", "RELEASE_CHUNK", "Chain", "JointLimits", "Plan", "Planner", "Segment", "Shifted",
           "State", "Timed", "Vector", "position_extrema", "release"]

#: rad: the most a move may start past a joint's range (a margin past it lets a plan go past the limits).
MAX_RANGE_MARGIN = 0.5
#: Joint values in config order: a list or an array.
Vector = Sequence[float] | np.ndarray
#: A commanded state (q rad, dq rad/s, ddq rad/s², config order).
State = tuple[Vector, Vector, Vector]


#: rad a target may differ from its joint's start and still count as staying there (a joint outside
#: its range may stay where it is: :meth:`JointLimits.check_position`)
STAY = 1e-6


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits as arrays in config order (rad, rad/s, rad/s², rad/s³)."""

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    def scaled(self, speed: float) -> JointLimits:
        """Limits for a motion ``speed`` times as fast (time scaling: v·s, a·s², j·s³)."""
        if not 0.0 < speed <= 1.0:
            raise ArgumentError(f"speed must be in (0, 1], got {speed}", fix="pass a fraction of the joint limits")
        return JointLimits(self.names, self.lower, self.upper, self.velocity * speed,
                           self.acceleration * speed**2, self.jerk * speed**3)

    def check_position(self, q: Vector, what: str = "target", tol: float = 1e-9, start: Vector | None = None) -> None:
        """Raise :class:`LimitError` naming the first joint of ``q`` outside its position range.

        ``start``: where a move to ``q`` starts. A joint that starts outside its range (an arm that
        sagged past a limit while it was off) may stay exactly where it is (within :data:`STAY`), so
        that a move of the other joints (a jog of one) is not refused for it; any other target of
        it must be inside the range (the path back in is checked by :meth:`Planner.bounds_from`)."""
        for i, name in enumerate(self.names):
            v = float(q[i])
            if not math.isfinite(v):
                raise ArgumentError(f"{what} position is {v}", joint=name, fix="give a finite angle in rad")
            lo, hi = float(self.lower[i]), float(self.upper[i])
            if lo - tol <= v <= hi + tol or (start is not None and abs(v - float(start[i])) <= STAY):
                continue
            raise LimitError(
                f"{what} {num(v)} rad is outside the joint's range [{num(lo)}, {num(hi)}] rad"
                + ("" if start is None or lo <= float(start[i]) <= hi else
                   f" (it starts at {num(float(start[i]))} rad: it may stay there, or move into the range)"),
                joint=name, fix="choose a position inside the range (URDF limits, narrowed in the robot YAML)")


def _phase_extrema(t: float, p: float, v: float, a: float, j: float, t_off: float,
                   ext: list[float]) -> None:
    """Widen ``ext`` = [min, t_min, max, t_max] by one constant-jerk phase of ``t`` s starting at
    ``t_off`` from (p, v, a) with jerk ``j``: its start, and where its velocity passes zero inside it
    (``v + a·τ + j·τ²/2 = 0``: two roots with jerk, one without: the case ruckig misses)."""
    taus = [0.0]  # the start; then the reversals strictly inside
    if j != 0.0:
        d = a * a - 2.0 * j * v
        if d >= 0.0:
            r = math.sqrt(d)
            taus += [x for x in ((-a - r) / j, (-a + r) / j) if 0.0 < x < t]
    elif a != 0.0 and 0.0 < -v / a < t:
        taus.append(-v / a)
    for tau in taus:
        x = p + tau * (v + tau * (0.5 * a + tau * j / 6.0))
        if x < ext[0]:
            ext[0], ext[1] = x, t_off + tau
        if x > ext[2]:
            ext[2], ext[3] = x, t_off + tau


def position_extrema(traj: ruckig.Trajectory) -> list[tuple[float, float, float, float]]:
    """Per DOF ``(min, t_min, max, t_max)`` of a ruckig trajectory's position (rad, s from its start),
    exact: from its profiles' phases (the brake that brings a start outside the limits back within
    them, then the seven phases), and its end.

    ruckig's own ``position_extrema`` (Community Version; seen with 0.19.4) misses a reversal
    (velocity through zero) inside a phase of constant acceleration: a move that starts moving away
    from its target (a retarget) turns around in such a phase, and passes the reported extrema by up
    to the whole overshoot (0.11 rad in tests/unit/test_trajectory.py).
    """
    out = []
    end = traj.at_time(traj.duration)[0]
    for dof, prof in enumerate(traj.profiles[0]):
        ext = [math.inf, 0.0, -math.inf, 0.0]
        t_off = 0.0
        brake = prof.brake
        if brake.duration > 0.0:
            for k in range(2):
                if brake.t[k] > 0.0:
                    _phase_extrema(brake.t[k], brake.p[k], brake.v[k], brake.a[k], brake.j[k], t_off, ext)
                    t_off += brake.t[k]
        pt, pp, pv, pa, pj = prof.t, prof.p, prof.v, prof.a, prof.j
        for k in range(7):
            _phase_extrema(pt[k], pp[k], pv[k], pa[k], pj[k], t_off, ext)
            t_off += pt[k]
        _phase_extrema(0.0, float(end[dof]), 0.0, 0.0, 0.0, traj.duration, ext)  # the end (and a DOF done early)
        out.append((ext[0], ext[1], ext[2], ext[3]))
    return out


class Segment:
    """One ruckig trajectory starting at absolute time ``t0`` (s)."""

    __slots__ = ("duration", "end", "t0", "traj")

    def __init__(self, traj: ruckig.Trajectory, t0: float) -> None:
        self.traj = traj
        self.t0 = t0
        self.duration = traj.duration
        p, v, a = traj.at_time(traj.duration)
        self.end = (np.array(p), np.array(v), np.array(a))

    def at(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """Position, velocity, acceleration at absolute time ``t`` (clamped to the segment)."""
        dt = t - self.t0
        if dt < 0.0:
            dt = 0.0
        elif dt > self.duration:
            dt = self.duration
        return self.traj.at_time(dt)


class Timed:
    """What the control loop follows: desired states over ``[t0, t_end]`` (absolute clock time, s).

    Subclasses set ``t0`` and ``t_end`` and implement ``sample(t) -> (q, dq, ddq)``.
    """

    t0: float
    t_end: float

    @property
    def duration(self) -> float:
        """Total duration, s."""
        return self.t_end - self.t0

    def done(self, t: float) -> bool:
        """True once ``t`` (absolute, s) is at or past the end."""
        return t >= self.t_end

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired (q rad, dq rad/s, ddq rad/s²) at absolute time ``t`` (s), config order."""
        raise NotImplementedError

    def shifted(self, dt: float) -> Timed:
        """The same motion ``dt`` s later (earlier if negative), made in constant time: the controller
        starts a plan from a state of rest later than it was planned for, without planning it again."""
        return self if dt == 0.0 else Shifted(self, dt)


class Shifted(Timed):
    """``plan`` run ``dt`` s later (:meth:`Timed.shifted`): the same states, each ``dt`` s later. Its
    other attributes are the plan's (those that are not times: a path's samples, its speed)."""

    def __init__(self, plan: Timed, dt: float) -> None:
        self.plan = plan
        self.dt = dt
        self.t0 = plan.t0 + dt
        self.t_end = plan.t_end + dt

    def __getattr__(self, name: str) -> Any:
        if name == "plan":  # not set yet (a copy being made): not the plan's
            raise AttributeError(name)
        return getattr(self.plan, name)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.plan.sample(t - self.dt)

    def shifted(self, dt: float) -> Timed:
        return self if dt == 0.0 else Shifted(self.plan, self.dt + dt)


def _pass_velocities(nodes: list[np.ndarray], legs: list[float], factor: float,
                     v_max: np.ndarray) -> list[np.ndarray]:
    """The velocity through each intermediate node: the central difference over the two legs'
    rest-to-rest durations, zero where a joint reverses, times ``factor``, within ``v_max``."""
    out = []
    for k in range(1, len(nodes) - 1):
        before, after = nodes[k] - nodes[k - 1], nodes[k + 1] - nodes[k]
        span = legs[k - 1] + legs[k]
        v = (nodes[k + 1] - nodes[k - 1]) / span if span > 0 else np.zeros(len(nodes[k]))
        v[np.sign(before) != np.sign(after)] = 0.0
        out.append(np.clip(v * factor, -v_max, v_max))
    return out


#: list items freed at a time by :func:`release`
RELEASE_CHUNK = 200


def release(items: list[Any]) -> None:
    """Empty a long list (segments, arrays) a chunk at a time: freeing thousands of ruckig trajectories
    in one go is one C loop that holds the interpreter lock (13 ms for a 5000-keyframe path here), and
    the control loop's thread waits for it; between chunks it gets its turn."""
    while items:
        del items[-RELEASE_CHUNK:]


class Plan(Timed):
    """A chain of segments, each starting when the previous one ends; holds the last state after.

    Sampling finds the segment by bisection (a plan of thousands of segments costs the loop no more
    than one of a few). A plan :meth:`shifted` in time shares its segments, whose own times are then
    :attr:`offset` s earlier than the plan's.
    """

    def __init__(self, segments: list[Segment], waypoints: int = 0) -> None:
        if not segments:
            raise ValueError("a plan needs at least one segment")
        self.segments = segments
        self.offset = 0.0
        self.t0 = segments[0].t0
        self.t_end = segments[-1].t0 + segments[-1].duration
        self.waypoints = waypoints
        self._ends = [s.t0 + s.duration for s in segments]

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired (q, dq, ddq) at absolute time ``t`` as arrays."""
        segs = self.segments
        u = t - self.offset
        k = bisect.bisect_right(self._ends, u) if len(segs) > 1 else 0
        p, v, a = segs[min(k, len(segs) - 1)].at(u)
        return np.asarray(p), np.asarray(v), np.asarray(a)

    def shifted(self, dt: float) -> Plan:
        if dt == 0.0:
            return self
        out = copy.copy(self)
        out.offset, out.t0, out.t_end = self.offset + dt, self.t0 + dt, self.t_end + dt
        return out


class Chain(Timed):
    """Plans run one after the other (each must start where and when the previous one ends)."""

    def __init__(self, plans: list[Timed]) -> None:
        self.plans = plans
        self.t0 = plans[0].t0
        self.t_end = plans[-1].t_end
        self.segments = [s for p in plans for s in getattr(p, "segments", ())]

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired (q, dq, ddq) at absolute time ``t``."""
        for p in self.plans:
            if t < p.t_end:
                return p.sample(t)
        return self.plans[-1].sample(t)

    def shifted(self, dt: float) -> Timed:
        return self if dt == 0.0 else Chain([p.shifted(dt) for p in self.plans])


class Planner:
    """Plans moves, waypoint paths and stops under one arm's joint limits.

    A move may start outside a joint's range, anywhere up to ``range_margin`` rad past its
    mechanical range (``outer``: the URDF's limits, which the YAML's may narrow): an arm that sagged
    onto its hard stop while limp. It is planned back toward the range, and refused only if it would
    go further out. Targets are always inside.
    """

    def __init__(self, limits: JointLimits, range_margin: float = 0.05,
                 outer: tuple[Vector, Vector] | None = None) -> None:
        if not (isinstance(range_margin, int | float) and not isinstance(range_margin, bool)
                and 0 <= range_margin <= MAX_RANGE_MARGIN):
            raise ArgumentError(f"range_margin {range_margin!r} must be a distance from 0 to {MAX_RANGE_MARGIN:g} rad",
                                fix="e.g. 0.05 (how far past its range a joint resting on its hard stop may be)")
        self.limits = limits
        self.range_margin = float(range_margin)
        lo, hi = outer if outer is not None else (limits.lower, limits.upper)
        self._outer_lo = np.minimum(np.asarray(lo, dtype=float), limits.lower) - self.range_margin
        self._outer_hi = np.maximum(np.asarray(hi, dtype=float), limits.upper) + self.range_margin
        self.dofs = len(limits.names)
        self._ruckig = ruckig.Ruckig(self.dofs)

    def bounds_from(self, q0: Vector) -> tuple[np.ndarray, np.ndarray]:
        """The position bounds of a path starting at ``q0``: the joint ranges, widened to take in a start
        outside them but within the mechanical range plus ``range_margin`` (so the path may come back,
        not go further out).

        Raises:
            LimitError: a joint starts further out than that.
        """
        q = np.asarray(q0, dtype=float)
        lim = self.limits
        lo, hi = lim.lower.astype(float), lim.upper.astype(float)
        for i, name in enumerate(lim.names):
            v = float(q[i])
            if not self._outer_lo[i] - 1e-9 <= v <= self._outer_hi[i] + 1e-9:
                side = "below its lower" if v < lo[i] else "above its upper"
                out = lo[i] - v if v < lo[i] else v - hi[i]
                m = self.range_margin
                raise LimitError(
                    f"starts at {v:+.4f} rad, {out:.4f} rad {side} limit ({lo[i]:+.4f}..{hi[i]:+.4f} rad): past its "
                    f"mechanical range ({self._outer_lo[i] + m:+.4f}..{self._outer_hi[i] - m:+.4f} rad) by more "
                    f"than the {m:.3f} rad a move may start from", joint=name,
                    fix="move the joint back into its range by hand (arm.teach() or disabled), or raise range_margin")
            if v < lo[i]:
                lo[i] = v
            elif v > hi[i]:
                hi[i] = v
        return lo, hi

    # -- single segments ----------------------------------------------------------------------
    def _input(self, limits: JointLimits, p0: Vector, v0: Vector, a0: Vector) -> ruckig.InputParameter:
        inp = ruckig.InputParameter(self.dofs)
        inp.current_position = [float(x) for x in p0]
        inp.current_velocity = [float(x) for x in v0]
        inp.current_acceleration = [float(x) for x in a0]
        inp.max_velocity = [float(x) for x in limits.velocity]
        inp.max_acceleration = [float(x) for x in limits.acceleration]
        inp.max_jerk = [float(x) for x in limits.jerk]
        inp.synchronization = ruckig.Synchronization.Time
        return inp

    def _calculate(self, inp: ruckig.InputParameter, t0: float) -> Segment:
        traj = ruckig.Trajectory(self.dofs)
        try:
            result = self._ruckig.calculate(inp, traj)
        except ValueError as e:  # a result code the binding's enum lacks: -101, a duration past its numerical limit
            code = str(e).split(" ", 1)[0]
            raise TrajectoryError(f"ruckig could not plan the motion: it would last too long (ruckig result {code})",
                                  fix="use a larger speed factor (a speed near 0 makes a motion endless), or check "
                                      "the joint limits in the robot YAML") from None
        except ruckig.RuckigError as e:
            if "error in step" not in str(e):
                raise TrajectoryError(f"ruckig could not plan the motion: {str(e).strip()}",
                                      fix="check the limits are positive and the start state is within them") from None
            # A numerical edge case of ruckig's solver for particular floats: the same problem with
            # limits a millionth lower (still within the limits) solves.
            inp.max_jerk = [x * (1 - 1e-6) for x in inp.max_jerk]
            inp.max_acceleration = [x * (1 - 1e-6) for x in inp.max_acceleration]
            try:
                result = self._ruckig.calculate(inp, traj)
            except ruckig.RuckigError as e2:
                raise TrajectoryError(f"ruckig could not plan the motion: {str(e2).strip()}",
                                      fix="report this input to akarm; try a slightly different target") from None
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise TrajectoryError(f"ruckig could not plan the motion ({result})",
                                  fix="check the joint limits in the robot YAML")
        return Segment(traj, t0)

    def check_extrema(self, seg: Segment, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Raise :class:`LimitError` if ``seg`` passes outside any joint's position range (or ``bounds``,
        from :meth:`bounds_from`)."""
        lower, upper = bounds if bounds is not None else (self.limits.lower, self.limits.upper)
        for i, (q_min, t_min, q_max, t_max) in enumerate(position_extrema(seg.traj)):
            lo, hi = lower[i], upper[i]
            if q_min < lo - 1e-9 or q_max > hi + 1e-9:
                worst, t = (q_min, t_min) if q_min < lo - 1e-9 else (q_max, t_max)
                raise LimitError(
                    f"the planned path reaches {worst:.4f} rad at t = {t:.3f} s, outside [{lo:.4f}, {hi:.4f}] rad",
                    joint=self.limits.names[i],
                    fix="move more slowly (speed=), or through an intermediate point away from the limit")

    def move(self, start: State, target: Vector, t0: float, speed: float = 1.0,
             target_velocity: Vector | None = None, min_duration: float = 0.0, synchronize: bool = True) -> Segment:
        """A time-synchronised move from ``start`` = (q, dq, ddq) to rest (or ``target_velocity``) at ``target``,
        taking at least ``min_duration`` s (ruckig's ``minimum_duration``; longer where the limits need it).
        ``synchronize=False``: each joint reaches its target as soon as its own limits allow (tracking a
        stream of targets: a joint that moves little is not slowed to the pace of the one that moves most).

        Raises:
            LimitError: the target, or a position the path passes through, is outside a joint's range.
            TrajectoryError: ruckig failed.
        """
        self.limits.check_position(target, start=start[0])
        bounds = self.bounds_from(start[0])
        limits = self.limits if speed == 1.0 else self.limits.scaled(speed)
        inp = self._input(limits, *start)
        if not synchronize:
            inp.synchronization = ruckig.Synchronization.No
        inp.target_position = [float(x) for x in target]
        inp.target_velocity = [0.0] * self.dofs if target_velocity is None else [float(x) for x in target_velocity]
        inp.target_acceleration = [0.0] * self.dofs
        if min_duration > 0.0:
            inp.minimum_duration = float(min_duration)
        seg = self._calculate(inp, t0)
        self.check_extrema(seg, bounds)
        return seg

    def settle(self, start: State, t0: float, speed: float) -> Segment | None:
        """The segment that brings a start moving faster than ``speed`` allows (a retarget to a slower
        speed) within the slower limits, at the joints' own limits; ``None`` if it is within them.

        Every joint's acceleration goes to zero at its full jerk, and its velocity to where that
        leaves it, or to the slower velocity limit if that is less (velocity interface, each joint as
        soon as it can). Planned at the slower jerk instead (ruckig's own brake), a joint accelerating
        at 12 rad/s² into a move at speed 0.3 (3.2 rad/s³) would keep accelerating for seconds,
        to ten times its velocity limit. Checked against the position ranges like a move.

        Raises:
            LimitError: the joint's path, settling, leaves its range.
        """
        if speed >= 1.0:
            return None
        slow = self.limits.scaled(speed)
        v0, a0 = np.asarray(start[1], dtype=float), np.asarray(start[2], dtype=float)
        tol = 1e-9
        # the speed where the acceleration's ramp to 0 at the slower jerk would end: a start within the
        # slower limits can still pass the velocity limit on its way (a₀ = a_slow at v₀ = v_slow)
        v_slow_free = v0 + a0 * np.abs(a0) / (2.0 * slow.jerk)
        if np.all(np.abs(v_slow_free) <= slow.velocity * (1 + tol)) and \
                np.all(np.abs(a0) <= slow.acceleration * (1 + tol)):
            return None
        v_free = v0 + a0 * np.abs(a0) / (2.0 * self.limits.jerk)  # where the acceleration's ramp to 0 ends
        inp = self._input(self.limits, *start)
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.synchronization = ruckig.Synchronization.No
        inp.target_velocity = [float(x) for x in np.clip(v_free, -slow.velocity, slow.velocity)]
        inp.target_acceleration = [0.0] * self.dofs
        seg = self._calculate(inp, t0)
        self.check_extrema(seg, self.bounds_from(start[0]))
        return seg

    def move_from(self, start: State, target: Vector, t0: float, speed: float = 1.0,
                  synchronize: bool = True) -> Plan:
        """:meth:`move` from any commanded state: first :meth:`settle` if the start moves faster than
        ``speed`` allows (a retarget to a slower speed), then the move at ``speed`` (``synchronize``:
        as :meth:`move`).

        Raises:
            LimitError, TrajectoryError: as :meth:`move`; nothing is planned in part.
        """
        self.limits.check_position(target, start=start[0])
        first = self.settle(start, t0, speed)
        if first is None:
            return Plan([self.move(start, target, t0, speed, synchronize=synchronize)])
        return Plan([first, self.move(first.end, target, t0 + first.duration, speed, synchronize=synchronize)])

    def stop(self, start: State, t0: float) -> Segment:
        """The jerk-limited stop to rest from ``start`` (velocity interface: no position target).

        Not checked against position limits: stopping is always the safest thing to do.
        """
        inp = self._input(self.limits, *start)
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.target_velocity = [0.0] * self.dofs
        inp.target_acceleration = [0.0] * self.dofs
        return self._calculate(inp, t0)

    # -- paths --------------------------------------------------------------------------------
    def through(self, start: State, points: Sequence[Vector], t0: float, speed: float = 1.0) -> Plan:
        """A path through every point of ``points`` without stopping at the intermediate ones.

        Each intermediate waypoint is passed exactly, with a pass-through velocity per joint: the
        central difference of the neighbouring points over the rest-to-rest durations of the two
        segments (zero where the joint reverses), scaled down from 1 to 0.25 until the whole chain
        respects every limit; the fastest valid chain is kept (ruckig plans cost microseconds).
        Ends at rest on the last point. A start moving faster than ``speed`` allows is first
        brought within its limits (:meth:`settle`: one more segment, before the waypoints').
        """
        pts = [np.asarray(p, dtype=float) for p in points]
        if not pts:
            raise ArgumentError("move_through needs at least one point", fix="pass a list of joint vectors")
        for k, p in enumerate(pts):
            if p.shape != (self.dofs,):
                raise ArgumentError(f"waypoint {k} has {p.size} values, the arm has {self.dofs} joints",
                                    fix="give one angle per joint, in config order")
            self.limits.check_position(p, what=f"waypoint {k}")
        if len(pts) == 1:
            return self.move_from(start, pts[0], t0, speed)
        first = self.settle(start, t0, speed)  # a start faster than `speed` allows: within its limits first
        if first is not None:
            start, t0 = first.end, t0 + first.duration

        q0 = np.asarray(start[0], dtype=float)
        nodes = [q0, *pts]
        # Rest-to-rest durations of each leg estimate how fast the path goes there.
        legs = [self.move((nodes[k], np.zeros(self.dofs), np.zeros(self.dofs)), nodes[k + 1], 0.0, speed).duration
                for k in range(len(pts))]
        limits = self.limits if speed == 1.0 else self.limits.scaled(speed)
        best: Plan | None = None
        errors: list[Exception] = []
        vias: list[np.ndarray] = []
        for factor in (1.0, 0.75, 0.5, 0.25, 0.0):
            release(vias)
            vias = _pass_velocities(nodes, legs, factor, limits.velocity)
            try:
                segs = [] if first is None else [first]
                state: tuple = start
                t = t0
                for k, p in enumerate(pts):
                    tv = vias[k] if k < len(vias) else None
                    seg = self.move(state, p, t, speed, target_velocity=tv)
                    segs.append(seg)
                    t += seg.duration
                    state = seg.end
                plan = Plan(segs, waypoints=len(pts))
            except LimitError as e:
                errors.append(e)
                release(segs)
                continue
            if best is None or plan.duration < best.duration:
                best, plan = plan, best
            if plan is not None:
                release(plan.segments)
        release(vias)
        if best is None:
            raise errors[-1]
        return best
