"""Feed-forward torque per cycle: the rigid-body model, friction, a hold integral, the user's torque.

``τ_ff = model(q_d, dq_d, ddq_d) + c·tanh(dq_d / 0.02) + b·dq_d + ∫ + τ_user``, clamped to each
joint's torque limit. The model term is full inverse dynamics (RNEA), gravity only, or nothing;
joints without stiffness (MIT, kp = 0) get their gravity at the *measured* pose instead, since they
are not at the commanded one. While the arm holds still, MIT joints add integral action ``ki =
hold_integral · kp`` on the position error, clamped to 10 % of the torque limit, which removes the
steady-state error friction leaves with a pure PD.

Per-joint work is done in plain floats: for six values numpy's per-call overhead costs more than
the arithmetic (this runs every cycle).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np

from akarm.dynamics.model import RobotModel

__all__ = ["FeedForward", "FeedForwardKind"]

FeedForwardKind = Literal["full", "gravity", "none"]
_INV_FRICTION_SMOOTHING = 1.0 / 0.02  # Coulomb feed-forward is c·tanh(v_des / 0.02 rad/s): smooth through zero


class FeedForward:
    """Computes the feed-forward torque of every joint for one cycle.

    Args:
        model: the arm's dynamics.
        kind: ``"full"``, ``"gravity"`` or ``"none"``.
        coulomb, viscous: friction to compensate per joint (N·m, N·m·s/rad); zeros to compensate none.
        torque_limit: N·m per joint; every torque is clamped to it.
        hold_integral: 1/s (``ki = hold_integral · kp`` for MIT joints while holding; 0: off).
        integrating: per joint, whether the hold integral applies (MIT joints).
    """

    def __init__(self, model: RobotModel, kind: FeedForwardKind, coulomb: Sequence[float], viscous: Sequence[float],
                 torque_limit: Sequence[float] | np.ndarray, hold_integral: float, integrating: Sequence[bool]) -> None:
        self.model = model
        self.kind = kind
        self.n = len(torque_limit)
        self._c = [float(x) for x in coulomb]
        self._b = [float(x) for x in viscous]
        self._inv_scale = [1.0] * len(torque_limit)  # 1 / (N·m the joint gets per N·m asked): set_friction
        self._inv_scale_array = np.ones(len(torque_limit))
        self._load = [0.0] * len(torque_limit)
        self._lim = [float(x) for x in torque_limit]
        self._lim_array = np.array(self._lim)
        self._imax = [0.1 * x for x in self._lim]
        self._hold_integral = hold_integral
        self._integrating = list(integrating)
        self._integral = [0.0] * self.n  # ∫(q_des - q) dt while holding, rad·s
        self.extra = [0.0] * self.n  # user torque (or a torque law's), N·m at the joint
        self.set_gains([0.0] * self.n)

    def set_friction(self, coulomb: Sequence[float], viscous: Sequence[float],
                     torque_scale: Sequence[float] | None = None, load: Sequence[float] | None = None) -> None:
        """New friction to compensate per joint (N·m, N·m·s/rad), e.g. identified ones; ``torque_scale``:
        N·m each joint gets per N·m asked (a real unit's: the model's torque and friction are asked over
        it); ``load``: Coulomb friction's load-dependent part, N·m per N·m of the model's torque."""
        self._c = [float(x) for x in coulomb]
        self._b = [float(x) for x in viscous]
        if torque_scale is not None:
            self._inv_scale = [1.0 / float(x) for x in torque_scale]
            self._inv_scale_array = np.array(self._inv_scale)
        if load is not None:
            self._load = [float(x) for x in load]

    def set_gains(self, kp: Sequence[float]) -> None:
        """The joints' current kp (N·m/rad): sets the hold integral's gains and which joints are limp."""
        kp = [float(x) for x in kp]
        self._ki = [self._hold_integral * k if m else 0.0 for k, m in zip(kp, self._integrating, strict=True)]
        self.limp = [i for i in range(self.n) if self._integrating[i] and kp[i] == 0.0]  # MIT, kp = 0

    def reset_integral(self) -> None:
        """Forget the hold integral (a motion starts, or the arm is enabled)."""
        self._integral = [0.0] * self.n

    def gravity(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """Gravity torque at ``q`` (rad) as the motors are asked it and report it (over each joint's
        torque scale, as :meth:`torques` asks it), clamped to the torque limits, N·m."""
        return np.clip(self.model.gravity(q) * self._inv_scale_array, -self._lim_array, self._lim_array)

    def carried(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """Teach mode's torque at the measured ``q``: the arm's weight plus the user's extra torque
        (force feedback on a teleoperation leader), asked over the torque scale, clamped to the torque
        limits, N·m."""
        tau = (self.model.gravity(q) + np.asarray(self.extra)) * self._inv_scale_array
        return np.clip(tau, -self._lim_array, self._lim_array)

    def torques(self, q_d: np.ndarray, dq_d: np.ndarray, ddq_d: np.ndarray, q_meas: Sequence[float], holding: bool,
                dt: float, qd: list[float] | None = None, vd: list[float] | None = None,
                keep: bool = False) -> list[float]:
        """Feed-forward torque per joint (N·m) for the desired state and the measured positions.

        ``holding``: the arm holds still at ``q_d`` (the hold integral runs; otherwise it is reset, unless
        ``keep``: servoing, a slow live motion about where the arm held, goes on with the torque the integral
        found, frozen: what the model misses there, a unit's masses or torque constant, stays made up for).
        ``dt``: s since the last call (for the integral). ``qd``, ``vd``: ``q_d`` and ``dq_d`` as lists
        of floats where the caller has them already (the loop: each numpy call costs it a few µs cold).
        """
        n = self.n
        if self.kind == "full":
            model_tau = self.model.inverse_dynamics(q_d, dq_d, ddq_d).tolist()
        elif self.kind == "gravity":
            model_tau = self.model.gravity(q_d).tolist()
        else:
            model_tau = [0.0] * n
        if self.limp and self.kind != "none":
            # joints without stiffness are not at the commanded pose: carry their weight where they are
            g_meas = self.model.gravity(q_meas).tolist()
            for i in self.limp:
                model_tau[i] = g_meas[i]
        if qd is None or vd is None:
            qd, vd = q_d.tolist(), dq_d.tolist()
        c, b, ex, lim, ki, imax, integ = self._c, self._b, self.extra, self._lim, self._ki, self._imax, self._integral
        inv, load = self._inv_scale, self._load
        tanh = math.tanh
        out = [0.0] * n
        for i in range(n):
            v = vd[i]
            mt = model_tau[i]
            th = tanh(v * _INV_FRICTION_SMOOTHING)
            # (all of it N·m the joint should get: asked of the motor over its torque scale, the user's and a
            # torque law's too, or a unit whose torque constant is 0.7 of the catalogue's is 0.7 as stiff)
            t = (mt + (c[i] + load[i] * abs(mt)) * th + b[i] * v + ex[i]) * inv[i]
            if holding:
                if ki[i] > 0.0:
                    ti = ki[i] * (integ[i] + (qd[i] - q_meas[i]) * dt)
                    ti = imax[i] if ti > imax[i] else -imax[i] if ti < -imax[i] else ti
                    integ[i] = ti / ki[i]
                    t += ti
            elif keep:
                t += ki[i] * integ[i]  # (frozen; within its clamp: it was clamped as it grew)
            else:
                integ[i] = 0.0
            out[i] = lim[i] if t > lim[i] else -lim[i] if t < -lim[i] else t
        return out
