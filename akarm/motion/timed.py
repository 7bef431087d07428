"""Timed trajectories: a path through points, each reached at a given time, jerk-limited.

A ROS 2 ``JointTrajectory`` (and anything like it) gives points with a ``time_from_start``. Here
each point becomes one ruckig segment that ends on the point at rest or with a pass-through
velocity, and takes at least the time the message gives it (ruckig's ``minimum_duration``). Where a
point is asked for sooner than the joint limits allow, that segment takes longer and the points
after it are still aimed at their own times: the path catches up where it can, and it never
breaks a limit to keep to a time. Every segment is checked against the position limits before the
plan is returned, so a point or a path past a limit raises :class:`~akarm.LimitError` and nothing
moves.

::

    plan = timed_plan(planner, start, now, times=[1.0, 2.0], positions=[[0.1, 0.2], [0.3, 0.0]])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from akarm.errors import ArgumentError, LimitError
from akarm.motion.trajectory import Plan, Planner, Segment, State

__all__ = ["timed_plan"]

_VIA_FACTORS = (1.0, 0.5, 0.0)  # pass-through velocities tried, as fractions of the estimate


def _vias(times: np.ndarray, q: np.ndarray, q0: np.ndarray, vmax: np.ndarray) -> np.ndarray:
    """Estimated pass-through velocities: the central difference of the neighbouring points over
    their times (zero where a joint reverses, and at the last point)."""
    nodes = np.vstack([q0, q])
    t = np.concatenate([[0.0], times])
    v = np.zeros_like(q)
    for k in range(len(q) - 1):
        span = t[k + 2] - t[k]
        before, after = nodes[k + 1] - nodes[k], nodes[k + 2] - nodes[k + 1]
        est = (nodes[k + 2] - nodes[k]) / span if span > 0 else np.zeros(q.shape[1])
        est[np.sign(before) != np.sign(after)] = 0.0
        v[k] = np.clip(est, -vmax, vmax)
    return v


def _floats(values: object, what: str, fix: str) -> np.ndarray:
    """``values`` as a float array (a copy), or :class:`ArgumentError` saying ``what`` (text, None, ragged rows)."""
    try:
        if isinstance(values, str | bytes):
            raise TypeError
        return np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise ArgumentError(f"{what}, got {values!r:.80}", fix=fix) from None


def timed_plan(planner: Planner, start: State, t0: float,
               times: Sequence[float], positions: Sequence[Sequence[float]] | np.ndarray,
               velocities: Sequence[Sequence[float]] | np.ndarray | None = None) -> Plan:
    """A plan from ``start`` = (q, dq, ddq) at time ``t0`` through ``positions[k]`` at ``t0 + times[k]``.

    Args:
        planner: the arm's planner (its limits are used and checked).
        start: the commanded state to start from (continuity in position, velocity, acceleration).
        t0: absolute clock time the times count from, s.
        times: per point, s after ``t0``; increasing (equal times are taken as "as soon as possible").
        positions: per point, one position per joint, rad; NaN keeps that joint at its position in
            ``start`` (a trajectory for some of the joints).
        velocities: optional per point pass-through velocities, rad/s (clipped to the limits); the
            last point is always reached at rest. Default: estimated from the neighbouring points.

    Raises:
        LimitError: a point, or a position the path passes through, is outside a joint's range.
        ArgumentError: the points are malformed (names the problem). Nothing is started.
    """
    n = planner.dofs
    q = _floats(positions, f"a timed trajectory needs points of {n} positions", "one position per joint, rad")
    if q.ndim != 2 or q.shape[1] != n or len(q) == 0:
        raise ArgumentError(f"a timed trajectory needs points of {n} positions", fix="one position per joint, rad")
    held = np.isnan(q)
    q[held] = np.broadcast_to(np.asarray(start[0], dtype=float), q.shape)[held]
    ts = _floats(times, "the points' times must be numbers", "give each point a time_from_start, s")
    if ts.shape != (len(q),) or not np.all(np.isfinite(ts)) or np.any(ts < 0) or np.any(np.diff(ts) < 0):
        bad = [k for k in range(min(len(ts), len(q))) if not math.isfinite(ts[k]) or ts[k] < 0
               or (k and ts[k] < ts[k - 1])] if ts.ndim == 1 else []
        which = f" (point {bad[0]}: {ts[bad[0]]} s)" if bad else f" ({ts.size} times for {len(q)} points)"
        raise ArgumentError(f"the points' times must be finite, non-negative and increasing{which}",
                            fix="give each point a time_from_start later than the previous one")
    for k, p in enumerate(q):
        planner.limits.check_position(p, what=f"point {k}")
    vmax = np.asarray(planner.limits.velocity, dtype=float)
    if velocities is not None:
        given = _floats(velocities, "velocities must be numbers", "leave velocities empty to have them estimated")
        if given.shape == q.shape:
            given[held] = 0.0
        if given.shape != q.shape:
            raise ArgumentError("velocities must give one finite value per joint for every point",
                                fix="leave velocities empty to have them estimated")
        if not np.all(np.isfinite(given)):
            k, i = (int(x) for x in np.argwhere(~np.isfinite(given))[0])
            raise ArgumentError(f"point {k}: velocity {given[k, i]} is not a number", joint=planner.limits.names[i],
                                fix="give finite velocities in rad/s, or leave them empty to have them estimated")
        estimates = [np.clip(given, -vmax, vmax)]
    else:
        estimates = [_vias(ts, q, np.asarray(start[0], dtype=float), vmax)]
    error: LimitError | None = None
    for factor in _VIA_FACTORS:
        via = estimates[0] * factor
        via[-1] = 0.0
        try:
            segs: list[Segment] = []
            state: tuple[Any, Any, Any] = start
            t = t0
            for k in range(len(q)):
                seg = planner.move(state, q[k], t, target_velocity=via[k], min_duration=(t0 + ts[k]) - t)
                segs.append(seg)
                t += seg.duration
                state = seg.end
            return Plan(segs, waypoints=len(q))
        except LimitError as e:  # a pass-through velocity carried the path past a limit: slower through points
            error = e
    assert error is not None
    raise error
