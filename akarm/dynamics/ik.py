"""Tool poses and inverse kinematics on the arm's Pinocchio model.

A *pose* is a 4×4 homogeneous transform of the YAML's ``tool_frame`` in the URDF's base frame
(translation in m). :func:`as_pose` accepts what users write: a 4×4, ``(xyz, quaternion xyzw)``,
or a position alone (the orientation then stays as it is, on arms with six joints or more; arms
with fewer cannot hold an orientation, and a position alone is a position-only target for them).

:class:`IKSolver` finds joint positions for a pose. It is a damped least-squares (Levenberg-Marquardt)
iteration on Pinocchio's frame Jacobian, started from the arm's current position and, if that does
not converge, from a fixed set of other starts; each step is clipped to the joint ranges, so a
solution is always within them. When none converges it tells apart, by solving once more without
the ranges, a pose that needs a joint past its limit (:class:`~akarm.LimitError` naming the joint)
from one out of reach (:class:`~akarm.UnreachableError`); a solution at a singularity is refused
(:class:`~akarm.SingularityError`).

Why not ``pin-pink``: it is differential IK (one velocity step per call, limits as QP
constraints) for task-space control loops; solving a pose with it means iterating its QP from
Python, and it pulls in qpsolvers, a QP back-end and SciPy (over 100 MB). A pose solve here is a
few damped least-squares steps of a 6×6 system; ``benchmarks/bench_ik.py`` measures both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from akarm.dynamics.model import ArrayLike, RobotModel
from akarm.errors import ArgumentError, LimitError, SingularityError, UnreachableError, num

__all__ = ["ROTATION_WEIGHT", "IKSolver", "as_pose", "make_pose", "pose_error", "quaternion"]

#: m per rad: how rotation errors and rotational Jacobian rows count next to positions (1 rad as
#: 0.1 m: a tool 10 cm long turning by 1 rad moves its tip by about as much).
ROTATION_WEIGHT = 0.1
#: The smallest singular value (m/rad, rotations weighted as above) below which a pose is singular:
#: there, 1 mm/s of tool motion in some direction needs more than 1 rad/s of joint motion.
SINGULAR_SIGMA = 1e-3


def make_pose(xyz: Sequence[float], rpy: Sequence[float] | None = None,
              quaternion: Sequence[float] | None = None) -> np.ndarray:
    """A 4×4 pose from a position (m) and an orientation given as roll-pitch-yaw (rad, URDF
    convention: ``R = Rz(yaw)·Ry(pitch)·Rx(roll)``) or a quaternion ``(x, y, z, w)``; identity if neither."""
    p = _vector(xyz, 3, "position (m)")
    T = np.eye(4)
    T[:3, 3] = p
    if rpy is not None and quaternion is not None:
        raise ArgumentError("give the orientation as rpy or as a quaternion, not both")
    if rpy is not None:
        r = _vector(rpy, 3, "roll-pitch-yaw (rad)")
        T[:3, :3] = pin.rpy.rpyToMatrix(*r)
    elif quaternion is not None:
        T[:3, :3] = _rotation_from_quaternion(quaternion)
    return T


def quaternion(T: np.ndarray) -> np.ndarray:
    """The orientation of a pose as a unit quaternion ``(x, y, z, w)``."""
    return np.array(pin.Quaternion(np.asarray(T, dtype=float)[:3, :3]).coeffs())


def _vector(x: Any, n: int, what: str) -> np.ndarray:
    try:
        v = np.asarray(x, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ArgumentError(f"a {what} must be {n} numbers, not {x!r}", fix=f"give {n} numbers") from None
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        shown = [float(e) for e in v] if v.ndim == 1 and v.size <= 16 else x  # [nan, 0.0, 0.0], not a numpy repr
        raise ArgumentError(f"a {what} must be {n} finite numbers, not {shown!r}", fix=f"give {n} finite numbers")
    return v


def _rotation_from_quaternion(q: Any) -> np.ndarray:
    v = _vector(q, 4, "quaternion (x, y, z, w)")
    norm = float(np.linalg.norm(v))
    if not 0.9 < norm < 1.1:
        raise ArgumentError(f"quaternion {list(v)} is not of unit length ({norm:.3f})",
                            fix="give (x, y, z, w) with x² + y² + z² + w² = 1")
    x, y, z, w = v / norm
    return np.array(pin.Quaternion(w, x, y, z).toRotationMatrix())


def as_pose(pose: Any, current: np.ndarray) -> tuple[np.ndarray, bool]:
    """A 4×4 pose from a 4×4, ``(xyz, quaternion xyzw)``, an object with ``.homogeneous`` (a
    ``pinocchio.SE3``) or a position alone, which keeps the orientation of ``current`` (a 4×4);
    and whether an orientation was given.

    Raises:
        ArgumentError: something that is none of these, or not finite.
    """
    if hasattr(pose, "homogeneous"):
        pose = np.asarray(pose.homogeneous)
    if isinstance(pose, tuple | list) and len(pose) == 2 and np.size(pose[0]) == 3 and np.size(pose[1]) == 4:
        return make_pose(pose[0], quaternion=pose[1]), True
    try:
        a = np.asarray(pose, dtype=float)
    except (TypeError, ValueError):
        a = np.empty(0)
    if a.shape == (3,):
        T = np.array(current, dtype=float)
        T[:3, 3] = _vector(a, 3, "position (m)")
        return T, False
    if a.shape == (4, 4) and np.all(np.isfinite(a)):
        R = a[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or abs(np.linalg.det(R) - 1) > 1e-6 or \
                not np.allclose(a[3], (0, 0, 0, 1)):
            raise ArgumentError("the 4×4 pose's rotation is not a rotation matrix (orthonormal, determinant 1), "
                                "or its last row is not (0, 0, 0, 1)",
                                fix="build it with akarm.dynamics.ik.make_pose(xyz, rpy)")
        return a.copy(), True
    raise ArgumentError(f"a pose must be a 4×4 transform, (xyz, quaternion xyzw) or a position (x, y, z), "
                        f"not {pose!r}",
                        fix="e.g. arm.move_to_pose([0.4, 0.0, 0.3]) or akarm.dynamics.ik.make_pose(xyz, rpy=...)")


def pose_error(T: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """How far pose ``T`` is from ``target``: position (m) and orientation (rad)."""
    dp = float(np.linalg.norm(target[:3, 3] - T[:3, 3]))
    dr = float(np.linalg.norm(pin.log3(target[:3, :3] @ T[:3, :3].T)))
    return dp, dr


class IKSolver:
    """Joint positions for tool poses (see the module's docstring).

    Args:
        model: the arm's model (use one of its own: a model is not shared between threads).
        lower, upper: the joint ranges, rad, config order.
        tolerance: m (and rad) the solution's pose may be off, at most.
        starts: how many other starting points to try when the current position does not converge.
    """

    def __init__(self, model: RobotModel, lower: ArrayLike, upper: ArrayLike, *,
                 tolerance: float = 1e-6, starts: int = 32, max_iterations: int = 100) -> None:
        self.model = model
        self.names = model.joint_names
        self.n = len(self.names)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        rng = np.random.default_rng(1)  # fixed: the same target always gives the same answer
        self._starts = self.lower + rng.random((starts, self.n)) * (self.upper - self.lower)

    # ------------------------------------------------------------------------------------------
    def position_only(self, orientation_given: bool) -> bool:
        """Whether a target is a position only: it gave none, and the arm has fewer than six joints."""
        return not orientation_given and self.n < 6

    def residual(self, q: np.ndarray, target: np.ndarray, position_only: bool) -> tuple[np.ndarray, np.ndarray]:
        """The task error (m; rotations weighted by :data:`ROTATION_WEIGHT`) and its Jacobian at ``q``."""
        T = self.model.tool_pose(q)
        J = self.model.jacobian(q)
        ep = target[:3, 3] - T[:3, 3]
        if position_only:
            return ep, J[:3]
        er = pin.log3(target[:3, :3] @ T[:3, :3].T) * ROTATION_WEIGHT
        return np.concatenate([ep, er]), np.vstack([J[:3], J[3:] * ROTATION_WEIGHT])

    def sigma_min(self, q: np.ndarray, position_only: bool) -> float:
        """The task Jacobian's smallest singular value at ``q`` (m/rad): near 0 at a singularity."""
        J = self.model.jacobian(q)
        Jt = J[:3] if position_only else np.vstack([J[:3], J[3:] * ROTATION_WEIGHT])
        s = np.linalg.svd(Jt, compute_uv=False)
        rank = min(Jt.shape)
        return float(s[rank - 1]) if len(s) >= rank else 0.0

    def _converged(self, e: np.ndarray) -> bool:
        tol = self.tolerance
        if float(np.linalg.norm(e[:3])) > tol:
            return False
        return e.size == 3 or float(np.linalg.norm(e[3:])) <= tol * ROTATION_WEIGHT

    def iterate(self, q0: np.ndarray, target: np.ndarray, position_only: bool, bounded: bool = True,
                max_iterations: int | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
        """Levenberg-Marquardt from ``q0``: returns (q, task error, converged)."""
        lo, hi = (self.lower, self.upper) if bounded else (self.lower - 10.0, self.upper + 10.0)
        q = np.clip(np.asarray(q0, dtype=float), lo, hi)
        e, J = self.residual(q, target, position_only)
        cost = float(e @ e)
        lam = 1e-6
        m = e.size
        for _ in range(max_iterations or self.max_iterations):
            if self._converged(e):
                return q, e, True
            while True:
                A = J @ J.T + (lam + 1e-12) * np.eye(m)
                dq = J.T @ np.linalg.solve(A, e)
                big = float(np.max(np.abs(dq)))
                if big > 0.5:  # at most 0.5 rad per step: stay where the linearisation holds
                    dq *= 0.5 / big
                q_new = np.clip(q + dq, lo, hi)
                e_new, J_new = self.residual(q_new, target, position_only)
                c_new = float(e_new @ e_new)
                if c_new < cost:
                    q, e, J, cost = q_new, e_new, J_new, c_new
                    lam = max(lam * 0.3, 1e-9)
                    break
                lam *= 10.0
                if lam > 1e2:  # no step lowers the error: a local minimum (a limit, or out of reach)
                    return q, e, self._converged(e)
        return q, e, self._converged(e)

    # ------------------------------------------------------------------------------------------
    def solve(self, target: np.ndarray, seed: ArrayLike, position_only: bool = False,
              check_singular: bool = True) -> np.ndarray:
        """Joint positions (rad, config order, within the ranges) putting the tool at ``target``.

        Starts from ``seed`` (the arm's position: the solution found is the one the arm reaches by
        the least joint motion), then from the other starts, nearest first; of the (at most three)
        solutions found, the one nearest ``seed`` wins.

        Raises:
            LimitError: the pose needs a joint past its range (names the joint).
            UnreachableError: no joint positions put the tool there (says how close it gets).
            SingularityError: the only solution found is at a singularity.
        """
        q_seed = np.asarray(seed, dtype=float)
        q, _, ok = self.iterate(q_seed, target, position_only)
        if not ok:  # the other starts, nearest the seed first; three solutions are enough to choose from
            found = []
            order = np.argsort(np.max(np.abs(self._starts - q_seed), axis=1))
            for other in self._starts[order]:
                qs, _, oks = self.iterate(other, target, position_only)
                if oks:
                    found.append(qs)
                    if len(found) == 3:
                        break
            if found:  # nearest the seed (not the last start tried): the least joint motion from here
                q = min(found, key=lambda x: float(np.max(np.abs(x - q_seed))))
                ok = True
        if not ok:
            q, failure = self._without_ranges(target, q_seed, position_only)
            if failure is not None:
                raise failure
        if check_singular:
            sigma = self.sigma_min(q, position_only)
            if sigma < SINGULAR_SIGMA:
                raise SingularityError(
                    f"the pose is reached only at a singularity (the tool Jacobian's smallest singular value is "
                    f"{sigma:.1e} m/rad at {_fmt(q)} rad): some tool motions there need enormous joint motions",
                    sigma=sigma, fix="move there in joint space (arm.move_to), or choose a pose a little away from "
                                     "it (arm stretched out, or two joint axes in line)")
        return q

    def _without_ranges(self, target: np.ndarray, seed: np.ndarray,
                        position_only: bool) -> tuple[np.ndarray, Exception | None]:
        """Solve ignoring the joint ranges: a solution that whole turns bring into the ranges is
        one after all; else the error: a joint past its limit, or out of reach."""
        best: tuple[float, np.ndarray] | None = None
        for start in (seed, *self._starts):
            q, _, ok = self.iterate(start, target, position_only, bounded=False)
            if not ok:
                continue
            q = self._wrap_into_range(q)
            over = np.maximum(self.lower - q, q - self.upper)
            worst = float(np.max(over))
            if worst <= 1e-9:
                return q, None
            qb, _, okb = self.iterate(q, target, position_only)  # from just inside the ranges
            if okb:
                return qb, None
            if best is None or worst < best[0]:
                best = (worst, q)
        if best is not None:
            q = best[1]
            k = int(np.argmax(np.maximum(self.lower - q, q - self.upper)))
            return q, LimitError(
                f"the pose needs {num(q[k], 3, True)} rad, outside the joint's range [{num(self.lower[k], 3, True)}, "
                f"{num(self.upper[k], 3, True)}] rad (and no joint positions within the ranges reach it)",
                joint=self.names[k], fix="choose a pose the arm reaches within its joint limits")
        # out of reach: how close does it get?
        q, e, _ = self.iterate(seed, target, position_only, bounded=True, max_iterations=300)
        dp = float(np.linalg.norm(e[:3]))
        dr = float(np.linalg.norm(e[3:])) / ROTATION_WEIGHT if e.size > 3 else 0.0
        what = f"{dp * 1e3:.1f} mm" + (f" and {math.degrees(dr):.1f}°" if e.size > 3 else "")
        return q, UnreachableError(
            f"the pose is out of reach: the tool comes no closer than {what} to it (at {_fmt(q)} rad)",
            distance=(dp, dr), fix="choose a pose within the arm's reach" +
                                   ("" if position_only else ", or an orientation the arm can take there"))

    def _wrap_into_range(self, q: np.ndarray) -> np.ndarray:
        """Each angle moved by whole turns into its range where that is possible (revolute joints)."""
        out = q.copy()
        for i in range(self.n):
            k = math.ceil((self.lower[i] - q[i]) / (2 * math.pi) - 1e-12)
            cand = q[i] + 2 * math.pi * k
            if cand <= self.upper[i] + 1e-9:
                out[i] = cand
        return out


def _fmt(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:+.3f}" for x in q) + "]"
