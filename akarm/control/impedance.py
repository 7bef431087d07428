"""Impedance control: the arm soft in Cartesian space (or joint space), a spring-damper about a target.

:class:`ImpedanceLaw` runs on the control loop's thread, once a cycle, from the *measured* joint
positions and velocities (:meth:`akarm.control.controller.Controller.set_torque_law`); its torque goes
out as the MIT commands' feed-forward, with kp = 0 (the joints' weight carried at the measured pose
by the feed-forward, :mod:`akarm.control.feedforward`):

- Cartesian: ``τ = Jᵀ(K·e + D·ė) + N·(k_n·(q₀ − q) − d_n·q̇)`` with ``e`` the tool's pose error
  (position, and rotation as a rotation vector, base axes), ``D = 2ζ·sqrt(K·Λ)`` per axis (``Λ``: the
  Cartesian inertia's diagonal at the start, bounded), and ``N`` the null space of ``Jᵀ``: a posture
  that keeps redundant joints (and a wrist at its singularity) where they were;
- joint: ``τ = K_j·(q_t − q) + D_j·(q̇_t − q̇)``, ``D_j = 2ζ·sqrt(K_j·M_jj)``;
- plus friction at the target's velocity; a target moves jerk-limited (:meth:`ImpedanceLaw.set_target`),
  the stiffness changes over :data:`STIFFNESS_RAMP` s; the torque changes by at most
  :data:`TORQUE_STEP` of each joint's limit a cycle;
- a deviation from the target past the bound is a :class:`~akarm.DeviationError` safety stop.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
import pinocchio as pin
import ruckig

from akarm.config.workspace import Workspace
from akarm.dynamics.ik import as_pose
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, DeviationError, LimitError, StateError, num
from akarm.motion.trajectory import JointLimits
from akarm.motion.walls import WALL_TOLERANCE

__all__ = ["CARTESIAN_INERTIA", "MOVED", "POSTURE", "STIFFNESS_RAMP", "TARGET_LIMITS", "TORQUE_STEP", "Impedance",
           "ImpedanceLaw", "stiffness_values"]

#: s over which a new stiffness is reached (linearly)
STIFFNESS_RAMP = 0.2
#: the most each joint's torque changes in one cycle, as a share of its torque limit
TORQUE_STEP = 0.02
#: the Cartesian inertia's diagonal the damping is computed with is kept within these (kg; kg·m²)
CARTESIAN_INERTIA = ((0.2, 20.0), (0.002, 0.5))
#: a target's motion limits: m/s, m/s², m/s³ (rad for a joint target; rotations as 0.1 m per rad)
TARGET_LIMITS = (0.1, 0.5, 5.0)
#: N·m/rad and N·m·s/rad: the null-space posture's stiffness and damping
POSTURE = (2.0, 0.2)
#: rad: a joint further than this from where ``arm.impedance()`` found it when its block begins: the handle
#: is stale (its target would spring the arm back there), and is refused
MOVED = 0.01
_W_ROT = 0.1


class _Move:
    """A target on its way: from ``start`` to ``end`` along ``s`` in [0, 1], jerk-limited (ruckig, 1 DOF)."""

    def __init__(self, t0: float, start: np.ndarray, end: np.ndarray, length: float) -> None:
        self.t0, self.start, self.end = t0, start, end
        inp = ruckig.InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
        inp.target_position, inp.target_velocity, inp.target_acceleration = [1.0], [0.0], [0.0]
        size = max(length, 1e-9)
        inp.max_velocity = [TARGET_LIMITS[0] / size]
        inp.max_acceleration = [TARGET_LIMITS[1] / size]
        inp.max_jerk = [TARGET_LIMITS[2] / size]
        self.traj = ruckig.Trajectory(1)
        ruckig.Ruckig(1).calculate(inp, self.traj)

    def at(self, t: float) -> tuple[float, float]:
        """(s, ds/dt) at clock time ``t``."""
        dt = min(max(t - self.t0, 0.0), self.traj.duration)
        p, v, _ = self.traj.at_time(dt)
        return float(p[0]), float(v[0])


class ImpedanceLaw:
    """The per-cycle torque of impedance control (see the module).

    Args:
        model: a dynamics model of its own (the loop's thread uses it).
        names: joint names, config order. torque_limit: N·m per joint.
        q0: the measured joint positions at the start (the first target, and the posture).
        stiffness: 6 values (N/m, N·m/rad) for Cartesian impedance, or ``None`` with ``joint_stiffness``.
        joint_stiffness: one per joint (N·m/rad) for joint impedance.
        damping_ratio: ζ (1: critically damped).
        max_deviation: (m, rad): Cartesian position and orientation (rad also for joint impedance) from the
            target past which the arm stops.
        coulomb, viscous: friction per joint, compensated at the target's velocity.
    """

    def __init__(self, model: RobotModel, names: Sequence[str], torque_limit: Sequence[float] | np.ndarray,
                 q0: np.ndarray, stiffness: np.ndarray | None, joint_stiffness: np.ndarray | None, damping_ratio: float,
                 max_deviation: tuple[float, float], coulomb: Sequence[float], viscous: Sequence[float]) -> None:
        self.model = model
        self.names = tuple(names)
        self.n = len(self.names)
        self.joint = joint_stiffness is not None
        self.zeta = float(damping_ratio)
        self.max_deviation = max_deviation
        self._lim = np.asarray(torque_limit, dtype=float)
        self._step = TORQUE_STEP * self._lim
        self._c, self._b = np.asarray(coulomb, dtype=float), np.asarray(viscous, dtype=float)
        self.q0 = np.array(q0, dtype=float)
        self._lock = threading.Lock()
        if self.joint:
            assert joint_stiffness is not None
            self.k = np.array(joint_stiffness, dtype=float)
            self.target = self.q0.copy()
            self._inertia = np.diag(model.mass_matrix(self.q0)).copy()
        else:
            assert stiffness is not None
            self.k = np.array(stiffness, dtype=float)
            self.target = model.tool_pose(self.q0)
            J = model.jacobian(self.q0)
            Minv = np.linalg.inv(model.mass_matrix(self.q0))
            lam = np.diag(np.linalg.inv(J @ Minv @ J.T + 1e-6 * np.eye(6)))
            (lo_t, hi_t), (lo_r, hi_r) = CARTESIAN_INERTIA
            self._inertia = np.concatenate([np.clip(lam[:3], lo_t, hi_t), np.clip(lam[3:], lo_r, hi_r)])
        self.k_goal = self.k.copy()
        self._move: _Move | None = None
        self._last_t: float | None = None
        self.tau = np.zeros(self.n)
        self.error = np.zeros(6 if not self.joint else self.n)  # the last deviation (m, rad)
        self.steps = 0

    # -- the caller's side ------------------------------------------------------------------------
    def set_target(self, target: np.ndarray, now: float) -> None:
        """Move the target to ``target`` (a 4×4 pose, or joint positions), jerk-limited from where it is now."""
        with self._lock:
            here = self._target_now(now)[0]
            if self.joint:
                start, end = np.asarray(here, dtype=float), np.asarray(target, dtype=float)
                length = float(np.max(np.abs(end - start)))
            else:
                start, end = here, np.asarray(target, dtype=float)
                dr = np.asarray(pin.log3(end[:3, :3] @ start[:3, :3].T))
                length = max(float(np.linalg.norm(end[:3, 3] - start[:3, 3])), _W_ROT * float(np.linalg.norm(dr)))
            self._move = _Move(now, start, end, length)

    def target_at(self, now: float) -> np.ndarray:
        """(Any thread) Where the target is at plan time ``now`` (a 4×4 pose, or joint positions)."""
        with self._lock:
            return np.array(self._target_now(now)[0], dtype=float)

    def set_stiffness(self, k: np.ndarray) -> None:
        with self._lock:
            self.k_goal = np.array(k, dtype=float)

    # -- the loop's side --------------------------------------------------------------------------
    def _target_now(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The target at clock time ``t`` and its velocity (joint: rad/s; Cartesian: twist, base axes)."""
        move = self._move
        if move is None:
            return self.target, np.zeros(self.n if self.joint else 6)
        s, ds = move.at(t)
        if self.joint:
            delta = move.end - move.start
            return move.start + s * delta, ds * delta
        dp = move.end[:3, 3] - move.start[:3, 3]
        dr = np.asarray(pin.log3(move.end[:3, :3] @ move.start[:3, :3].T))
        T = np.eye(4)
        T[:3, 3] = move.start[:3, 3] + s * dp
        T[:3, :3] = pin.exp3(s * dr) @ move.start[:3, :3]
        return T, ds * np.concatenate([dp, dr])

    def step(self, t: float, q: Sequence[float], dq: Sequence[float]) -> list[float] | DeviationError:
        """This cycle's torque (N·m per joint) from the measured ``q``, ``dq``; or the stop, past the bound."""
        self.steps += 1
        with self._lock:
            target, velocity = self._target_now(t)
            move = self._move
            if move is not None and t - move.t0 >= move.traj.duration:
                self.target, self._move = move.end, None
            k_goal = self.k_goal
        dt = 0.0 if self._last_t is None else max(0.0, t - self._last_t)
        self._last_t = t
        rate = np.maximum(np.abs(k_goal), np.abs(self.k)) * dt / STIFFNESS_RAMP
        self.k = self.k + np.clip(k_goal - self.k, -rate, rate)
        qa, va = np.asarray(q, dtype=float), np.asarray(dq, dtype=float)
        if self.joint:
            tau, stop = self._joint(qa, va, target, velocity)
            joint_velocity = velocity
        else:
            tau, stop, joint_velocity = self._cartesian(qa, va, target, velocity)
        if stop is not None:
            stop.at = t
            return stop
        tau = tau + self._c * np.tanh(joint_velocity / 0.02) + self._b * joint_velocity
        tau = self.tau + np.clip(tau - self.tau, -self._step, self._step)
        self.tau = np.clip(tau, -self._lim, self._lim)
        return self.tau.tolist()

    def _joint(self, q: np.ndarray, dq: np.ndarray, target: np.ndarray,
               velocity: np.ndarray) -> tuple[np.ndarray, DeviationError | None]:
        e = target - q
        self.error = e
        worst = int(np.argmax(np.abs(e)))
        if abs(e[worst]) > self.max_deviation[1]:
            return np.zeros(self.n), self._stop(abs(float(e[worst])), self.max_deviation[1], "rad", self.names[worst])
        d = 2.0 * self.zeta * np.sqrt(self.k * self._inertia)
        return self.k * e + d * (velocity - dq), None

    def _cartesian(self, q: np.ndarray, dq: np.ndarray, target: np.ndarray,
                   twist: np.ndarray) -> tuple[np.ndarray, DeviationError | None, np.ndarray]:
        model = self.model
        T = model.tool_pose(q)
        J = model.jacobian(q)
        ep = target[:3, 3] - T[:3, 3]
        er = np.asarray(pin.log3(target[:3, :3] @ T[:3, :3].T))
        self.error = np.concatenate([ep, er])
        dp, dr = float(np.linalg.norm(ep)), float(np.linalg.norm(er))
        if dp > self.max_deviation[0]:
            return np.zeros(self.n), self._stop(dp, self.max_deviation[0], "m", None), np.zeros(self.n)
        if dr > self.max_deviation[1]:
            return np.zeros(self.n), self._stop(dr, self.max_deviation[1], "rad", None), np.zeros(self.n)
        d = 2.0 * self.zeta * np.sqrt(self.k * self._inertia)
        force = self.k * self.error + d * (twist - J @ dq)
        tau = J.T @ force
        # the null space of Jᵀ: the posture (redundant joints, a wrist at its singularity)
        Jp = np.linalg.pinv(J, rcond=1e-3)
        N = np.eye(self.n) - J.T @ Jp.T
        tau += N @ (POSTURE[0] * (self.q0 - q) - POSTURE[1] * dq)
        joint_velocity = Jp @ twist if np.any(twist) else np.zeros(self.n)
        return tau, None, joint_velocity

    def _stop(self, value: float, limit: float, unit: str, joint: str | None) -> DeviationError:
        what = "the joint" if joint else ("the tool's position" if unit == "m" else "the tool's orientation")
        shown = f"{value * 1e3:.0f} mm" if unit == "m" else f"{value:.3f} rad"
        bound = f"{limit * 1e3:.0f} mm" if unit == "m" else f"{limit:.3f} rad"
        return DeviationError(f"impedance: {what} was {shown} from its target, past the bound of {bound} (pushed "
                              "far away, or held); the arm was damped and disabled", deviation=value, limit=limit,
                              joint=joint, fix="find what pushed or held the arm; raise max_deviation if such "
                                               "deviations are meant, or lower the stiffness")



class _Controller(Protocol):
    @property
    def law(self) -> ImpedanceLaw | None: ...

    def begin_torque_law(self, law: ImpedanceLaw, kd: Sequence[float]) -> None: ...

    def end_torque_law(self) -> None: ...

    def external_torque(self) -> np.ndarray: ...

    def plan_now(self) -> float: ...

    def require_enabled(self) -> None: ...

    def raise_fault(self) -> None: ...


class Impedance:
    """The handle of ``arm.impedance(...)``: ``with arm.impedance(stiffness=[...]) as imp:`` makes the arm
    soft about its pose (or its joint positions) until the block ends, when it holds where it is, stiff
    again (the gains ramping up from zero). A handle serves one block: before it, after it, or after a stop
    ended it, its commands are refused (:class:`~akarm.StateError`), as is a second block. A safety stop
    that ended the block is raised by the next command, or by the block's end if nothing else did.

    Args (from :meth:`akarm.Arm.impedance`): the controller, the law, each joint's damping (kd) meanwhile,
    a model for the caller's thread, and how joint positions are read; the joint limits and the robot
    file's walls a target must keep to (a target past them is a :class:`~akarm.LimitError`, nothing moves),
    and ``reach(T)``, which raises unless joint positions within the ranges put the tool at the pose ``T``
    (inverse kinematics: an :class:`~akarm.UnreachableError` or a LimitError, nothing moves).
    """

    def __init__(self, ctl: _Controller, law: ImpedanceLaw, kd: Sequence[float], model: RobotModel,
                 measured: Callable[[], np.ndarray], limits: JointLimits | None = None,
                 walls: Workspace | None = None, reach: Callable[[np.ndarray], object] | None = None) -> None:
        self._ctl, self.law, self._kd, self._model, self._measured = ctl, law, list(kd), model, measured
        self._limits, self._walls, self._reach = limits, walls, reach
        self._used = False

    def __enter__(self) -> Impedance:
        if self._used:
            raise StateError("this impedance handle served its block once already",
                             fix="make a new one where the arm is: `with arm.impedance(...) as imp:`")
        self._used = True
        moved = np.abs(self._measured() - self.law.q0)
        worst = int(np.argmax(moved))
        if moved[worst] > MOVED:  # its target is where the arm was: it would spring back there
            raise StateError(f"the arm moved {moved[worst]:.3f} rad since arm.impedance() made this handle",
                             joint=self.law.names[worst],
                             fix="make the handle where the arm is: `with arm.impedance(...) as imp:`")
        self._ctl.begin_torque_law(self.law, self._kd)
        return self

    def __exit__(self, *exc: object) -> None:
        self._ctl.end_torque_law()
        if exc[0] is None:
            self._ctl.raise_fault()  # a stop that ended the block (an exception leaving it goes on unchanged)

    def _require_in_block(self) -> None:
        """The arm's safety stop, if it stopped; else a StateError unless this handle's block is in force."""
        self._ctl.require_enabled()
        if self._ctl.law is not self.law:
            raise StateError("this impedance handle commands nothing outside its `with` block (not begun, ended, "
                             "or ended by a stop)", fix="command it inside `with arm.impedance(...) as imp:`")

    def set_target(self, target: object) -> None:
        """Move the target, jerk-limited from where it is: a pose (as :meth:`akarm.Arm.move_to_pose` takes
        it) under Cartesian impedance, one position per joint (rad) under joint impedance.

        Raises:
            ArgumentError: not a pose, or not one finite angle per joint. LimitError: a joint target past
                a joint's limits, a pose no joint positions within the ranges reach (UnreachableError: out of
                reach), a line to the target that leaves the workspace (nothing moves).
            StateError: outside the handle's block (or the arm's safety stop, if it stopped)."""
        law = self.law
        if law.joint:
            try:
                q = np.asarray(target, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                q = np.full(0, np.nan)
            if q.shape != (law.n,) or not np.all(np.isfinite(q)):
                raise ArgumentError(f"a joint target must be {law.n} finite angles (rad), got {target!r}",
                                    fix="one per joint, config order: " + ", ".join(law.names))
            value = q
        else:
            value, _ = as_pose(target, law.target)
        self._within_limits(np.array(value, dtype=float))
        self._require_in_block()
        law.set_target(np.array(value, dtype=float), self._ctl.plan_now())

    def _within_limits(self, value: np.ndarray) -> None:
        """A joint target within each joint's range; a Cartesian target's line (from the target now) inside
        the walls, further out than it starts nowhere: else a LimitError."""
        law, lim = self.law, self._limits
        if law.joint and lim is not None:
            for i, (q, lo, hi) in enumerate(zip(value.tolist(), lim.lower.tolist(), lim.upper.tolist(), strict=True)):
                if not lo <= q <= hi:
                    raise LimitError(f"the impedance target is at {num(q, sign=True)} rad, outside "
                                     f"[{num(lo, sign=True)}, {num(hi, sign=True)}] rad; nothing moved",
                                     joint=law.names[i], fix="give a target within the joint's limits")
        if law.joint:
            return
        if self._reach is not None:  # a pose out of reach: the spring would pull the arm out until it stopped
            self._reach(value)
        walls = self._walls
        if walls is None:
            return
        a, b = law.target_at(self._ctl.plan_now())[:3, 3], value[:3, 3]
        start = walls.outside(a)
        for s in np.linspace(0.0, 1.0, max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.005) + 1)).tolist():
            p = a + s * (b - a)
            out = walls.outside(p)
            if out > start + WALL_TOLERANCE:
                raise LimitError(f"the impedance target's line takes the tool {out * 1e3:.1f} mm outside the "
                                 f"workspace ({walls.describe()}) at [{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}] m; "
                                 "nothing moved", fix="choose a target inside the workspace, or widen `workspace:` "
                                                      "in the robot file")

    def set_stiffness(self, stiffness: Sequence[float]) -> None:
        """New stiffness (6 values N/m, N·m/rad; or one per joint N·m/rad under joint impedance), reached
        smoothly over :data:`STIFFNESS_RAMP` s."""
        k = stiffness_values(stiffness, self.law.k.size, "stiffness")
        self._require_in_block()
        self.law.set_stiffness(k)

    @property
    def error(self) -> np.ndarray:
        """The last deviation from the target: (dx, dy, dz, rx, ry, rz) m and rad, base axes (joint: rad)."""
        return self.law.error.copy()

    def wrench(self) -> np.ndarray:
        """The external wrench on the tool, ``[fx, fy, fz, tx, ty, tz]`` (N, N·m at the tool frame's origin,
        base axes), from the collision reflex's external torque estimate: ``Jᵀ·F = τ_ext`` solved by least
        squares (an arm with fewer than six joints feels only the part its joints can)."""
        J = self._model.jacobian(self._measured())
        tau = self._ctl.external_torque()
        return np.asarray(np.linalg.lstsq(J.T, tau, rcond=1e-3)[0])


def stiffness_values(values: object, n: int, what: str) -> np.ndarray:
    """``values`` as ``n`` finite numbers ≥ 0, else :class:`~akarm.ArgumentError`."""
    try:
        v = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        v = np.full(0, np.nan)
    if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0):
        raise ArgumentError(f"{what} must be {n} finite numbers ≥ 0, got {values!r}",
                            fix="N/m for x, y, z and N·m/rad for rx, ry, rz (or one N·m/rad per joint)")
    return v
