"""Straight-line tool motions: the path in joint space, its jerk-limited timing, and the checks.

:func:`plan_linear` turns "move the tool in a straight line to this pose" into a
:class:`LinearPlan`, a :class:`~akarm.motion.trajectory.Timed` the control loop follows like any other
plan. The path is parameterised by ``s`` from 0 to 1: the tool frame's origin moves along the line
``p(s) = p0 + s·(p1 - p0)`` and its orientation turns about one fixed axis (a slerp), ``R(s) =
R0·exp(s·log(R0ᵀR1))``.

1. **Joint path.** On a grid of ``s`` (at most 2 mm and 0.02 rad of tool motion, and 0.02 rad of
   any joint's motion, apart) the joint positions are solved one after the other, each from the
   last (:class:`~akarm.dynamics.ik.IKSolver`, within the joint ranges), with the joint velocity along the
   path ``dq/ds = J⁺·dx/ds``. Between grid points, cubic Hermite interpolation (values and slopes
   exact at the grid points): the tool leaves the line by micrometres.
2. **Refusals, before anything moves.** A grid point the tool cannot reach
   (:class:`~akarm.UnreachableError`), one that needs a joint past its range
   (:class:`~akarm.LimitError` naming the joint), or a stretch where the line needs a tool motion the
   joints cannot make or more than :data:`SINGULAR_GAIN` rad of joint motion per metre
   (:class:`~akarm.SingularityError`): each error says where on the line, in m from the start.
3. **Timing.** ruckig plans ``s(t)`` from rest to rest (jerk-limited, so the tool's speed along
   the line is too). The joint velocities, accelerations and jerks follow by the chain rule
   (``q̇ = q'·ṡ``, ``q̈ = q''·ṡ² + q'·s̈``, ``q⃛ = q'''·ṡ³ + 3q''·ṡ·s̈ + q'·s⃛``); they are evaluated on a
   fine time grid and the limits for ``s`` scaled until the worst joint meets its own limit (times
   ``speed``) exactly: limits scaled by ``(1/r, 1/r², 1/r³)`` stretch a ruckig profile in time by ``r``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from akarm.dynamics.ik import ROTATION_WEIGHT, IKSolver
from akarm.dynamics.model import ArrayLike
from akarm.errors import ArgumentError, LimitError, SingularityError, UnreachableError
from akarm.motion.trajectory import JointLimits, Planner, Segment, Timed

__all__ = ["SINGULAR_GAIN", "LinearPlan", "plan_linear"]

#: rad of joint motion per metre of (weighted) tool motion above which a line counts as singular.
SINGULAR_GAIN = 500.0
_MAX_TOOL_STEP = 0.002  # m between grid points (rotations weighted)
_MAX_JOINT_STEP = 0.02  # rad between grid points, any joint
_MAX_POINTS = 20000
_CHECK_DT = 0.002  # s: time grid of the limit checks


class LinearPlan(Timed):
    """A straight-line tool motion as joint states over time (see the module's docstring).

    Attributes:
        q_grid: joint positions on the grid of ``s`` (rad, rows = grid points). slope: ``dq/ds`` there.
        length: the tool's travel, m. angle: its rotation, rad. timing: the ruckig segment of ``s(t)``.
    """

    def __init__(self, q_grid: np.ndarray, slope: np.ndarray, timing: Segment, length: float, angle: float) -> None:
        self.q_grid = q_grid
        self.slope = slope
        self.timing = timing
        self.length = length
        self.angle = angle
        self.h = 1.0 / (len(q_grid) - 1)
        self.t0 = timing.t0
        self.t_end = timing.t0 + timing.duration

    def at(self, t0: float) -> LinearPlan:
        """The same plan starting at clock time ``t0`` (s)."""
        seg = Segment(self.timing.traj, t0)
        return LinearPlan(self.q_grid, self.slope, seg, self.length, self.angle)

    def path(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``q(s)`` and its first three derivatives along the path (Hermite), for one ``s`` or an array."""
        s_arr = np.atleast_1d(np.clip(np.asarray(s, dtype=float), 0.0, 1.0))
        h = self.h
        k = np.minimum((s_arr / h).astype(int), len(self.q_grid) - 2)
        u = (s_arr - k * h)[:, None] / h
        q0, q1 = self.q_grid[k], self.q_grid[k + 1]
        m0, m1 = self.slope[k] * h, self.slope[k + 1] * h
        u2, u3 = u * u, u * u * u
        q = (2 * u3 - 3 * u2 + 1) * q0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * q1 + (u3 - u2) * m1
        d1 = ((6 * u2 - 6 * u) * q0 + (3 * u2 - 4 * u + 1) * m0 + (6 * u - 6 * u2) * q1 + (3 * u2 - 2 * u) * m1) / h
        d2 = ((12 * u - 6) * q0 + (6 * u - 4) * m0 + (6 - 12 * u) * q1 + (6 * u - 2) * m1) / (h * h)
        d3 = np.broadcast_to((12 * q0 + 6 * m0 - 12 * q1 + 6 * m1) / (h ** 3), q.shape)
        return q, d1, d2, d3

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired (q, dq, ddq) at absolute time ``t``."""
        (s,), (sd,), (sdd,) = self.timing.at(t)
        q, d1, d2, _ = self.path(s)
        return q[0], d1[0] * sd, d2[0] * (sd * sd) + d1[0] * sdd

    def joint_profile(self, dt: float = _CHECK_DT) -> tuple[np.ndarray, ...]:
        """Times (from the start, s) and the joints' q, q̇, q̈, q⃛ on a grid of ``dt`` (for the checks)."""
        T = self.timing.duration
        t = np.append(np.arange(0.0, T, dt), T)
        traj = self.timing.traj
        s, sd, sdd = (np.array(x) for x in zip(*(traj.at_time(float(x)) for x in t), strict=True))
        s, sd, sdd = s[:, 0], sd[:, 0], sdd[:, 0]
        sddd = np.gradient(sdd, t) if len(t) > 2 else np.zeros_like(t)
        q, d1, d2, d3 = self.path(s)
        sd_, sdd_, sddd_ = sd[:, None], sdd[:, None], sddd[:, None]
        v = d1 * sd_
        a = d2 * sd_ ** 2 + d1 * sdd_
        j = d3 * sd_ ** 3 + 3 * d2 * sd_ * sdd_ + d1 * sddd_
        return t, q, v, a, j


def _slerp_axis(R0: np.ndarray, R1: np.ndarray) -> np.ndarray:
    """The rotation vector (body frame of ``R0``) that turns ``R0`` into ``R1``."""
    return np.asarray(pin.log3(R0.T @ R1))


class _Where:
    """A place on the line, put into words only when an error needs it."""

    def __init__(self, s: float, length: float, p0: np.ndarray, p1: np.ndarray) -> None:
        self.s, self.length, self.p0, self.p1 = s, length, p0, p1

    def __str__(self) -> str:
        p = self.p0 + self.s * (self.p1 - self.p0)
        return f"{self.s * self.length:.3f} m along the line, at (" + ", ".join(f"{x:+.3f}" for x in p) + ") m"


def plan_linear(solver: IKSolver, limits: JointLimits, q_start: ArrayLike, target: np.ndarray, *,
                speed: float = 1.0, position_only: bool = False, max_velocity: float | None = None,
                max_acceleration: float | None = None) -> LinearPlan:
    """Plan a straight-line tool motion from rest at ``q_start`` to the pose ``target`` (4×4), starting at t = 0.

    Args:
        solver: the IK solver (its model is used here; not thread-safe).
        limits: the joints' limits; every joint's velocity, acceleration and jerk stay within them
            times ``speed``, ``speed²``, ``speed³``.
        speed: fraction of the joint limits, in (0, 1].
        position_only: follow the line with the tool's origin only (arms with fewer than six joints).
        max_velocity: m/s, the tool's speed along the line at most (also rad/s of its rotation,
            weighted by 0.1 m). max_acceleration: m/s², likewise.

    Raises:
        UnreachableError, LimitError, SingularityError: see the module's docstring; nothing moved.
    """
    if not 0.0 < speed <= 1.0:
        raise ArgumentError(f"speed must be in (0, 1], got {speed}", fix="pass a fraction of the joint limits")
    for name, cap in (("max_velocity", max_velocity), ("max_acceleration", max_acceleration)):
        if cap is not None and not (isinstance(cap, int | float) and cap > 0 and math.isfinite(cap)):
            raise ArgumentError(f"{name} must be a positive number, got {cap!r}", fix="m/s or m/s²")
    q0 = np.asarray(q_start, dtype=float)
    model = solver.model
    T0 = model.tool_pose(q0)
    p0, p1 = T0[:3, 3], target[:3, 3]
    w = np.zeros(3) if position_only else _slerp_axis(T0[:3, :3], target[:3, :3])
    R0 = T0[:3, :3]
    dx = np.concatenate([p1 - p0, R0 @ w * ROTATION_WEIGHT])  # d(pose)/ds: constant along the line, world axes
    if position_only:
        dx = dx[:3]
    length, angle = float(np.linalg.norm(p1 - p0)), float(np.linalg.norm(w))
    travel = float(np.linalg.norm(dx))
    if travel < 1e-9:
        return _rest(q0, limits)

    def pose_at(s: float) -> np.ndarray:
        T = np.eye(4)
        T[:3, 3] = p0 + s * (p1 - p0)
        T[:3, :3] = R0 @ pin.exp3(s * w) if not position_only else R0
        return T

    n_points = max(8, math.ceil(travel / _MAX_TOOL_STEP))
    for _ in range(4):
        q_grid, slope = _joint_path(solver, q0, pose_at, dx, n_points, position_only, p0, p1, length)
        step = float(np.max(np.abs(np.diff(q_grid, axis=0))))
        if step <= _MAX_JOINT_STEP or n_points >= _MAX_POINTS:
            break
        n_points = min(_MAX_POINTS, math.ceil(n_points * step / (0.5 * _MAX_JOINT_STEP)))
    plan = _timed(q_grid, slope, limits, speed, travel, max_velocity, max_acceleration, length, angle)
    _check_positions(plan, limits)
    return plan


def _rest(q0: np.ndarray, limits: JointLimits) -> LinearPlan:
    """The plan of a line of length zero: stay (a segment of zero duration)."""
    grid = np.vstack([q0, q0])
    return LinearPlan(grid, np.zeros_like(grid), _plan_s(1.0, 1.0, 1.0, end=0.0), 0.0, 0.0)


def _joint_path(solver: IKSolver, q0: np.ndarray, pose_at: Callable[[float], np.ndarray], dx: np.ndarray,
                n_points: int, position_only: bool,
                p0: np.ndarray, p1: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and ``dq/ds`` on ``n_points + 1`` grid points, each solved from the last."""
    n = solver.n
    q_grid = np.empty((n_points + 1, n))
    slope = np.empty((n_points + 1, n))
    h = 1.0 / n_points
    q = q0.copy()
    travel = float(np.linalg.norm(dx))
    for k in range(n_points + 1):
        s = k * h
        where = _Where(s, length, p0, p1)
        if k > 0:
            guess = q + slope[k - 1] * h
            target = pose_at(s)
            q_new, _, ok = solver.iterate(guess, target, position_only, max_iterations=30)
            if not ok:
                raise _off_path(solver, guess, target, position_only, where)
            if float(np.max(np.abs(q_new - guess))) > max(0.05, 5.0 * float(np.max(np.abs(slope[k - 1]))) * h):
                raise SingularityError(
                    f"the line passes through a singularity {where}: the joints would have to jump",
                    sigma=math.inf, fix="split the move (through a point away from the singularity) or move in "
                                        "joint space (arm.move_to)")
            q = q_new
        _, J = solver.residual(q, pose_at(s), position_only)
        d, *_ = np.linalg.lstsq(J, dx, rcond=1e-12)
        miss = float(np.linalg.norm(J @ d - dx))
        gain = float(np.max(np.abs(d))) / travel
        if miss > 1e-3 * travel or gain > SINGULAR_GAIN:
            why = ("the tool cannot move along the line there: the joints cannot make that motion"
                   if miss > 1e-3 * travel else
                   f"it needs {gain:.0f} rad of joint motion per metre of tool motion there (more than "
                   f"{SINGULAR_GAIN:.0f})")
            raise SingularityError(f"the line is singular {where}: {why}", sigma=gain,
                                   fix="split the move (through a point away from the singularity), turn the tool "
                                       "less, or move in joint space (arm.move_to)")
        q_grid[k] = q
        slope[k] = d
    return q_grid, slope


def _off_path(solver: IKSolver, guess: np.ndarray, target: np.ndarray, position_only: bool, where: _Where) -> Exception:
    """Why a grid point cannot be solved: a joint past its range, or out of reach."""
    q, e, ok = solver.iterate(guess, target, position_only, bounded=False, max_iterations=60)
    if ok:
        over = np.maximum(solver.lower - q, q - solver.upper)
        k = int(np.argmax(over))
        if over[k] > 0:
            return LimitError(f"the line needs {q[k]:+.3f} rad {where}, outside the joint's range "
                              f"[{solver.lower[k]:+.3f}, {solver.upper[k]:+.3f}] rad", joint=solver.names[k],
                              fix="choose a line that stays within the joint limits, or move in joint space "
                                  "(arm.move_to_pose)")
    dp = float(np.linalg.norm(e[:3]))
    dr = float(np.linalg.norm(e[3:])) / ROTATION_WEIGHT if e.size > 3 else 0.0
    return UnreachableError(f"the line leaves the arm's reach {where} (the tool comes no closer than "
                            f"{dp * 1e3:.1f} mm{f' and {math.degrees(dr):.1f}°' if e.size > 3 else ''})",
                            distance=(dp, dr), fix="choose a line within the arm's reach")


def _timed(q_grid: np.ndarray, slope: np.ndarray, limits: JointLimits, speed: float, travel: float,
           max_velocity: float | None, max_acceleration: float | None, length: float, angle: float) -> LinearPlan:
    """Time the path: ruckig on ``s``, with limits scaled until the worst joint meets its own."""
    gain = np.max(np.abs(slope), axis=0)  # rad per unit of s, per joint
    gain = np.maximum(gain, 1e-12)
    v_lim, a_lim, j_lim = limits.velocity * speed, limits.acceleration * speed ** 2, limits.jerk * speed ** 3
    vs = float(np.min(v_lim / gain))
    as_ = float(np.min(a_lim / gain))
    js = float(np.min(j_lim / gain))
    # Cartesian caps, in units of s: the tool moves `travel` (m, rotations weighted) per unit of s
    v_cap = max_velocity / travel if max_velocity is not None else math.inf
    a_cap = max_acceleration / travel if max_acceleration is not None else math.inf
    j_cap = 10.0 * max_acceleration / travel if max_acceleration is not None else math.inf
    vs, as_, js = min(vs, v_cap), min(as_, a_cap), min(js, j_cap)
    plan = None
    for _ in range(6):
        seg = _plan_s(vs, as_, js)
        plan = LinearPlan(q_grid, slope, seg, length, angle)
        _, _, v, a, j = plan.joint_profile()
        r = max(float(np.max(np.abs(v) / v_lim)), math.sqrt(float(np.max(np.abs(a) / a_lim))),
                float(np.max(np.abs(j) / j_lim)) ** (1.0 / 3.0))
        # never faster than the caps allow
        r = max(r, vs / v_cap, math.sqrt(as_ / a_cap), (js / j_cap) ** (1.0 / 3.0))
        if 0.97 <= r <= 1.0 + 1e-9:
            break
        r = r * 1.001 if r > 1.0 else r
        vs, as_, js = vs / r, as_ / r ** 2, js / r ** 3
    assert plan is not None
    _, _, v, a, j = plan.joint_profile()
    for arr, lim, what in ((v, v_lim, "velocity"), (a, a_lim, "acceleration"), (j, j_lim, "jerk")):
        ratio = np.max(np.abs(arr), axis=0) / lim
        k = int(np.argmax(ratio))
        if ratio[k] > 1.0 + 1e-6:  # a last guard: the scaling above makes this unreachable
            raise LimitError(f"the line needs a joint {what} of {ratio[k]:.2f} times the limit",
                             joint=limits.names[k], fix="move more slowly (speed=)")
    return plan


def _plan_s(v: float, a: float, j: float, end: float = 1.0) -> Segment:
    """ruckig on the path parameter ``s``, from rest at 0 to rest at ``end``."""
    lim = JointLimits(("path",), np.zeros(1), np.ones(1), np.array([v]), np.array([a]), np.array([j]))
    return Planner(lim).move((np.zeros(1), np.zeros(1), np.zeros(1)), np.array([end]), 0.0)


def _check_positions(plan: LinearPlan, limits: JointLimits) -> None:
    """Every joint within its range along the whole interpolated path (the grid points are, by the IK)."""
    s = np.linspace(0.0, 1.0, 8 * (len(plan.q_grid) - 1) + 1)
    q, *_ = plan.path(s)
    for i, name in enumerate(limits.names):
        lo, hi = limits.lower[i], limits.upper[i]
        bad = np.nonzero((q[:, i] < lo - 1e-6) | (q[:, i] > hi + 1e-6))[0]
        if bad.size:
            x = float(q[bad[0], i])
            raise LimitError(f"the line reaches {x:+.4f} rad at {s[bad[0]] * plan.length:.3f} m along it, outside "
                             f"[{lo:+.4f}, {hi:+.4f}] rad", joint=name,
                             fix="choose a line that stays within the joint limits")
