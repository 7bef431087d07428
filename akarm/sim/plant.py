"""The simulated arm: whole-arm rigid-body dynamics, friction, hard stops and motor heating.

Dynamics come from the URDF through :class:`akarm.dynamics.model.RobotModel` with the motors' reflected rotor
inertia (``armature=True``), gravity and the payload, solved with Pinocchio's ABA.

Integrator: **linearly implicit (semi-implicit) Euler at a fixed step** ``dt`` (2 kHz by default).
Each step takes the torques of the drivers, friction and hard stops at the current state, together
with their stiffness ``K = -∂τ/∂q`` and damping ``D = -∂τ/∂v`` (diagonal; for the saturating
friction and brake terms the secant ``-τ/v`` instead, which never lets a step reverse the motion
they resist), and solves

    (M + dt·D + dt²·K) · Δv = dt · (τ - h(q, v) - dt·K·v),   v⁺ = v + Δv,   q⁺ = q + dt·v⁺

(``h`` = Coriolis + gravity). Without stiff terms this is symplectic Euler; with them it is backward
Euler in the stiff terms, so a kp = 500 MIT hold on a small motor, a stiff servo loop, the smooth
Coulomb friction near zero speed and the hard stops stay stable at 2 kHz. The solve costs one ABA:
adding ``dt·D + dt²·K`` to the armature (the diagonal of M) for the call turns ABA's
``(M)⁻¹(τ - h)`` into the system above.

An external torque per joint (a hand pushing the arm) can be set; it acts until changed.

A blocked joint (the ``Blocked`` fault) is held at rest: the step then solves the free joints'
rows of the system above with the blocked joints' accelerations 0 (the mass matrix and the bias
restricted to the free joints), so the others feel the reaction of what holds it; the impulse that
stops it at once acts on the others too (:meth:`Plant.block`).

Friction per joint: ``τ_f = -viscous·v - coulomb·tanh(v / coulomb_eps)``. Hard stops past the URDF
limits (revolute joints): a spring of ``limit_stiffness`` with critical damping for the joint's
inertia, pushing only (it never pulls the joint into the stop). Motor torque saturates at ``t_max``.
Thermal model per motor: ``C·dT/dt = I²R - (T - T_ambient)/R_th`` with ``I = τ / (kt·GR)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from akarm.dynamics.model import RobotModel
from akarm.errors import ModelError
from akarm.sim.params import MotorSimParams

if TYPE_CHECKING:
    from akarm.config import RobotConfig
    from akarm.sim.drivers import SimulatedDriver

__all__ = ["Plant"]


class Plant:
    """The arm's state and its integrator (joint side, config order, SI).

    Args:
        config: the robot.
        params: per joint (config order), the actuator's simulation constants.
        dt: integration step, s (default 0.5 ms = 2 kHz).

    Attributes:
        model: the :class:`~akarm.dynamics.model.RobotModel` (with armature) the plant integrates.
        q: joint positions, rad. dq: joint velocities, rad/s. ddq: last accelerations, rad/s².
        tau: torques the motors apply at the joints (after saturation), N·m.
        dt: the step, s. steps: steps taken.
    """

    def __init__(self, config: RobotConfig, params: Sequence[MotorSimParams], dt: float = 0.0005) -> None:
        if not dt > 0:
            raise ModelError(f"simulation step dt = {dt!r} s must be positive", fix="e.g. dt = 0.0005 (2 kHz)")
        self.config = config
        self.model = RobotModel(config, armature=True)
        self.dt = float(dt)
        n = len(config.joints)
        self.n = n
        self.q = np.zeros(n)
        self.dq = np.zeros(n)
        self.ddq = np.zeros(n)
        self.tau = np.zeros(n)
        self.steps = 0
        pm = self.model.pin_model
        self._pm = pm
        self._pd = self.model.pin_data
        self._arm0 = np.array(pm.armature, dtype=float)
        # per-joint constants as plain Python lists: the step loop is scalar Python
        self._dir = [float(j.direction) for j in config.joints]
        self._off = [float(j.offset) for j in config.joints]
        self._tmax = [float(j.motor.t_max) for j in config.joints]
        self._visc = [p.viscous for p in params]
        self._coul = [p.coulomb for p in params]
        self._inv_eps = [1.0 / p.coulomb_eps for p in params]
        self._res = [p.resistance for p in params]
        self._heat = [self.dt / p.thermal_capacity for p in params]
        self._cool = [1.0 / p.thermal_resistance for p in params]
        self._amb = [p.ambient for p in params]
        self._klim = [p.limit_stiffness for p in params]
        # a real unit (akarm.sim.variation): torque per N·m reported, friction per A, half the play
        self._scale = [p.torque_scale for p in params]
        self._coul_load = [p.coulomb_load for p in params]
        self._half_play = [0.5 * p.backlash for p in params]
        self._play_eps = [0.05 * float(j.motor.t_max) for j in config.joints]
        hard = [pm.joints[pm.getJointId(j.name)].nq == 1 for j in config.joints]
        self._lo = [float(lo) if h else -math.inf for lo, h in zip(self.model.lower, hard, strict=True)]
        self._hi = [float(hi) if h else math.inf for hi, h in zip(self.model.upper, hard, strict=True)]
        self._clim = [0.0] * n
        self._external = [0.0] * n
        self._wrench: np.ndarray | None = None  # N, N·m at the tool frame's origin, base axes (set_external_wrench)
        self._surface: tuple[float, float, float] | None = None  # (height m, N/m, N·s/m): set_surface
        self.contact_force = 0.0  # N: the surface's push on the tool, last step
        self.contact_peak = 0.0  # N: its largest since the surface was set
        self.blocked: dict[int, float] = {}  # joint index → the position it is held at (mechanically blocked)
        self._drivers: list[SimulatedDriver] = []
        # config order is Pinocchio's order and q/v hold nothing else: no mapping in the step
        self._identity = self.model.to_pin_q(self.q) is self.q and self.model.to_pin_v(self.dq) is self.dq
        self.update_inertia()

    def attach(self, drivers: Sequence[SimulatedDriver]) -> None:
        """The drivers (config order) whose torques drive the joints."""
        if len(drivers) != self.n:
            raise ModelError(f"{len(drivers)} drivers for {self.n} joints")
        self._drivers = list(drivers)
        self._build_rows()

    def joint_inertia(self, q: np.ndarray | None = None) -> np.ndarray:
        """Diagonal of the mass matrix at ``q`` (default: now), kg·m²: each joint's inertia, motors included."""
        return np.diag(self.model.mass_matrix(self.q if q is None else q)).copy()

    def update_inertia(self) -> None:
        """Recompute what depends on the inertia (the hard stops' damping), e.g. after a payload change."""
        j = self.joint_inertia()
        self._clim = [2.0 * math.sqrt(k * ji) for k, ji in zip(self._klim, j.tolist(), strict=True)]
        self._build_rows()

    def _build_rows(self) -> None:
        """Per joint, every constant the step loop needs, in one tuple (unpacking beats indexing)."""
        if len(self._drivers) != self.n:
            self._rows: list[tuple] = []
            return
        self._rows = list(zip(self._drivers, self._dir, self._off, self._tmax, self._heat, self._res, self._amb,
                              self._cool, self._inv_eps, self._visc, self._coul, self._lo, self._hi, self._klim,
                              self._clim, self._scale, self._coul_load, self._half_play, self._play_eps,
                              strict=True))

    def set_payload(self, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Attach a payload to the tool frame (kg, m in the tool frame); 0 kg removes it."""
        self.model.set_payload(mass, com)
        self.update_inertia()

    @property
    def external_torque(self) -> np.ndarray:
        """Torques applied to the joints from outside (a hand pushing the arm), N·m, config order."""
        return np.array(self._external)

    def set_external_torque(self, tau: Sequence[float] | np.ndarray | None) -> None:
        """Apply ``tau`` (N·m per joint, config order) from outside until changed; ``None`` clears it."""
        if tau is None:
            self._external = [0.0] * self.n
            return
        t = np.asarray(tau, dtype=float)
        if t.shape != (self.n,) or not np.all(np.isfinite(t)):
            raise ModelError(f"external torque must be {self.n} finite numbers (N·m, config order), got {tau!r}",
                             fix="give one torque per joint, or None to clear")
        self._external = t.tolist()

    def set_external_wrench(self, wrench: Sequence[float] | np.ndarray | None) -> None:
        """Apply ``wrench`` (force N and torque N·m, ``[fx, fy, fz, tx, ty, tz]``, at the tool frame's origin in
        the base frame's axes) from outside until changed, as joint torques ``Jᵀ·wrench`` at every step
        (on top of :meth:`set_external_torque`'s); ``None`` clears it."""
        if wrench is None:
            self._wrench = None
            return
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise ModelError(f"an external wrench must be 6 finite numbers (N, N·m), got {wrench!r}",
                             fix="give [fx, fy, fz, tx, ty, tz] at the tool frame's origin, base axes, or None")
        self._wrench = w

    def set_surface(self, height: float | None, stiffness: float = 2e4, damping: float = 200.0) -> None:
        """A horizontal surface at ``height`` (m, base frame z) the tool frame's origin cannot go below
        without it pushing back up: ``stiffness · depth − damping · vz`` N (never pulling), applied as
        joint torques at every step; ``None`` removes it. :attr:`contact_force` is its push, N."""
        if height is None:
            self._surface = None
            self.contact_force = 0.0
            return
        values = (float(height), float(stiffness), float(damping))
        if not all(math.isfinite(v) for v in values) or values[1] <= 0.0 or values[2] < 0.0:
            raise ModelError(f"a surface needs a finite height, a stiffness > 0 and a damping >= 0, got {values}",
                             fix="e.g. set_surface(0.3, stiffness=2e4, damping=200)")
        self._surface = values
        self.contact_peak = 0.0

    def _contact(self) -> list[float]:
        """The joint torques of the external wrench and the surface this step, N·m."""
        J = self.model.jacobian(self.q)
        w = np.zeros(6) if self._wrench is None else self._wrench.copy()
        self.contact_force = 0.0
        if self._surface is not None:
            height, k, d = self._surface
            z = float(self.model.tool_pose(self.q)[2, 3])
            if z < height:
                vz = float(J[2] @ self.dq)
                self.contact_force = max(0.0, k * (height - z) - d * vz)
                self.contact_peak = max(self.contact_peak, self.contact_force)
                w[2] += self.contact_force
        return (np.asarray(self._external) + J.T @ w).tolist()

    def motor_state(self, i: int) -> tuple[float, float]:
        """Joint ``i``'s motor-side (position rad before the driver's zero, velocity rad/s). With
        backlash the motor's encoder leads the link by half the play in the direction of its torque."""
        s = self._dir[i]
        q = float(self.q[i])
        play = self._half_play[i]
        if play:
            q += play * math.tanh(float(self.tau[i]) / self._play_eps[i])
        return (q - self._off[i]) * s, float(self.dq[i]) * s

    # C901 14 > 12: one scalar pass per joint (motor, heat, friction, hard stops), the hot path
    def step(self, t: float) -> None:  # noqa: C901
        """Advance the arm by one step ``dt`` from time ``t`` (s), with the drivers' torques at ``t``."""
        dt = self.dt
        dt2 = dt * dt
        tau_eff = []
        extra = []
        motor = []
        tanh = math.tanh
        external = self._external if self._wrench is None and self._surface is None else self._contact()
        rows = zip(self._rows, self.tau.tolist(), self.q.tolist(), self.dq.tolist(), external, strict=True)
        for (drv, s, off, cap, heat, res, amb, cool, inv_eps, visc, coul, lo, hi, klim, clim, scale, cload, play,
             peps), tprev, qi, vi, ext in rows:
            qm = qi + play * tanh(tprev / peps) if play else qi  # backlash: the encoder leads by half the play
            tm, k, d = drv.output(t, (qm - off) * s, vi * s)
            if tm > cap:
                tm, k, d = cap, 0.0, 0.0
            elif tm < -cap:
                tm, k, d = -cap, 0.0, 0.0
            drv.torque = tm
            # winding temperature: C dT/dt = I²R - (T - T_amb)/R_th
            cur = tm / drv.kt_out
            temp = drv.temperature
            drv.temperature = temp + heat * (cur * cur * res - (temp - amb) * cool)
            if cload:  # friction's load-dependent part (per A of the motor's current)
                coul = coul + cload * (cur if cur >= 0.0 else -cur)
            tj = s * tm
            if scale != 1.0:  # the unit's torque constant and gearbox: the joint gets scale × what is reported
                tj *= scale
                k *= scale
                d *= scale
            motor.append(tj)
            # smooth Coulomb + viscous friction
            # (damping: the secant coulomb·tanh(v/ε)/v, not the tangent, so a step never flips v's sign)
            x = vi * inv_eps
            th = tanh(x)
            tj -= visc * vi + coul * th
            d += visc + (coul * inv_eps if -1e-9 < x < 1e-9 else coul * th / vi)
            # hard stops: push out, never pull in
            if qi > hi:
                f = -klim * (qi - hi) - clim * vi
                if f < 0.0:
                    tj += f
                    k += klim
                    d += clim
            elif qi < lo:
                f = klim * (lo - qi) - clim * vi
                if f > 0.0:
                    tj += f
                    k += klim
                    d += clim
            tau_eff.append(tj + ext - dt * k * vi)
            extra.append(dt * d + dt2 * k)
        pm = self._pm
        if self.blocked:
            acc = self._held_acceleration(np.array(tau_eff), np.array(extra))
        elif self._identity:
            pm.armature = self._arm0 + np.array(extra)
            try:
                acc = pin.aba(pm, self._pd, self.q, self.dq, np.array(tau_eff))
            finally:
                pm.armature = self._arm0
        else:
            model = self.model
            pm.armature = self._arm0 + model.to_pin_v(extra)
            try:
                a = pin.aba(pm, self._pd, model.to_pin_q(self.q), model.to_pin_v(self.dq), model.to_pin_v(tau_eff))
            finally:
                pm.armature = self._arm0
            acc = model.from_pin_v(a)
        self.ddq = acc
        dq = self.dq
        dq += dt * acc
        self.q += dt * dq
        if self.blocked:
            for i, qb in self.blocked.items():
                self.q[i], dq[i], acc[i] = qb, 0.0, 0.0
        self.tau = np.array(motor)
        self.steps += 1

    def _held_acceleration(self, tau: np.ndarray, extra: np.ndarray) -> np.ndarray:
        """The step's accelerations with the blocked joints held (at rest, a = 0): the free joints'
        rows of ``(M + diag(extra))·a = tau - h(q, v)`` with the blocked joints' columns dropped, so
        the others feel the reaction of what holds them (ABA would treat every joint as free)."""
        free = [i for i in range(self.n) if i not in self.blocked]
        acc = np.zeros(self.n)
        if free:
            M = self.model.mass_matrix(self.q)
            M[free, free] += extra[free]
            h = self.model.nonlinear_effects(self.q, self.dq)
            acc[free] = np.linalg.solve(M[np.ix_(free, free)], tau[free] - h[free])
        return acc

    def block(self, i: int) -> None:
        """Hold joint ``i`` where it is from now on: it stops at once, and the impulse that stops it
        acts on the others too (their rows of the generalized momentum do not change)."""
        v = self.dq[i]
        self.blocked[i] = float(self.q[i])
        free = [k for k in range(self.n) if k not in self.blocked]
        if v != 0.0 and free:
            M = self.model.mass_matrix(self.q)
            self.dq[free] += np.linalg.solve(M[np.ix_(free, free)], M[free, i] * v)
        self.dq[i] = 0.0
