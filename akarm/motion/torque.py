"""The speed a move's torque allows: the planner's limits are kinematic (velocity, acceleration, jerk);
the torque a move asks depends on the pose, and near a joint's torque limit a real unit saturates.

A real unit is not its datasheet: a motor's torque constant differs by ±30 % between units, and the
torque the joint gets per N·m the motor reports is 0.5-1.3 of it (``akarm.sim.Variation``, from
measured motors). A move planned to use all of a joint's torque limit on the model (arm6's move to
``reach`` at full speed asks its shoulder for 25.2 of 25 N·m) saturates a weaker unit: the arm overshoots
with its motor at its limit, and the supervisor stops it. That is physics, not a model error: the move
must be slower on that unit.

:class:`TorqueBudget` says how much slower. A joint's budget is its torque limit times its identified
torque scale (what the robot file's ``friction: {torque_scale: ...}`` says it gets per N·m reported)
times a share: :data:`IDENTIFIED_SHARE` for an identified joint, :data:`UNIDENTIFIED_SHARE` for one
that is not (the ±30 % of an unknown unit's torque constant). A move is the same path at any speed
(velocities scale by ``s``, accelerations by ``s²``), so its torque is ``g(q) + s²·(the rest)``, and
the largest ``s`` that keeps every joint within its budget is found from samples of the plan at speed 1.
Gravity alone is not slowed away: where it takes more than the share, the move keeps
:data:`MIN_DYNAMIC_SHARE` of the limit for acceleration; where it takes more than the whole limit the
move is refused (:class:`~akarm.LimitError`, naming the joint): the motor cannot hold the arm there.

**What the unit was measured to need.** A share of the limit covers a unit up to 1/0.7 weaker than its
model; a weaker one (0.5 N·m per N·m reported), links heavier than the URDF's, or an object grasped whose
mass nobody told the arm, ask more. Where the arm holds still, the torque its motors report against the
model's gravity says by how much: :meth:`TorqueBudget.measure_hold` keeps, per joint that gravity loads
(at least :data:`HOLD_MIN_SHARE` of its limit), the ratio of the two (``load``, at least 1). A move then
plans with the model's torque times ``load``, plus the friction a real unit has to move from a hold (twice
the catalogue's Coulomb friction and 6 % of the load; 1.3 times the identified ones), within
:data:`MEASURED_SHARE` of the limit, and one that cannot keep gravity and friction within it is refused
before anything moves, naming what was measured: a unit that cannot hold the arm at the target and move
it from there is told so, instead of saturating there and being stopped.
A new payload (``set_payload``) starts the ratios over.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from akarm.config import RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError

__all__ = ["HOLD_MIN_SHARE", "IDENTIFIED_SHARE", "MAX_LOAD", "MEASURED_SHARE", "MIN_DYNAMIC_SHARE",
           "MIN_MEASURED_DYNAMIC_SHARE", "UNIDENTIFIED_SHARE", "TorqueBudget"]

#: share of an unidentified joint's torque limit a move may plan to use: a unit may give 30 % less
UNIDENTIFIED_SHARE = 0.7
#: share of an identified joint's (limit × its torque scale): the rest is for the feedback
IDENTIFIED_SHARE = 0.9
#: share of the limit kept for acceleration where gravity alone takes more than the share
MIN_DYNAMIC_SHARE = 0.1
#: share of the limit a move may plan to use with the model's torque times the measured ``load``, and the
#: friction to move from a hold (the rest is for what the ratio, gravity's, does not say of the
#: accelerations, and for the feedback)
MEASURED_SHARE = 0.9
#: share of the limit (over ``load``) kept for acceleration at the least, where a measured joint's gravity
#: takes all of its measured share: the move is as slow as it must be to stay within what the motor has
MIN_MEASURED_DYNAMIC_SHARE = 0.02
#: share of a joint's limit its model gravity must take at a hold for the hold to be measured (less: its
#: friction, ±0.3-1 N·m on these motors, would be most of what is read)
HOLD_MIN_SHARE = 0.15
#: the largest ratio believed (more: not the model's error, something holds or pushes the arm)
MAX_LOAD = 3.0
_SAMPLES = 48


class TorqueBudget:
    """Per joint, the torque (N·m at the joint, the model's) a move may plan to use; :meth:`speed_factor`
    says how much slower a plan must be to keep within it (see the module's docstring).

    Args:
        config: the robot (torque limits; identified torque scales in the joints' ``friction:``).
        model: a model of it for this object alone (Pinocchio's data is not shared between threads);
            :meth:`set_payload` keeps its payload the arm's.
    """

    def __init__(self, config: RobotConfig, model: RobotModel) -> None:
        self.model = model
        self.names = config.joint_names
        limit, share, scales, friction, friction_load = [], [], [], [], []
        for j in config.joints:
            identified = j.friction is not None
            fr = j.friction_model()  # (the catalogue's, unidentified: torque scale 1, no load share)
            limit.append(j.limits.torque * fr.torque_scale)
            share.append(IDENTIFIED_SHARE if identified else UNIDENTIFIED_SHARE)
            scales.append(fr.torque_scale)
            # friction to allow for where a measured joint moves from a hold: twice the catalogue's Coulomb
            # friction and 6 % of the load (real units), or 1.3 times the identified ones
            friction.append((1.3 if identified else 2.0) * fr.coulomb)
            friction_load.append(1.3 * fr.load if identified else 0.06)
        #: N·m per joint at the joint: the limit the motor is held to, times the torque it gets per N·m
        self.limit = np.array(limit, dtype=float)
        #: N·m per joint a move may plan to use
        self.budget = self.limit * np.array(share)
        self._scale = np.array(scales, dtype=float)
        self._friction = np.array(friction, dtype=float)
        self._friction_load = np.array(friction_load, dtype=float)
        self._load = np.ones(len(limit))
        self._held: list[list[float] | None] = [None] * len(limit)  # where each joint's load was measured, rad

    @property
    def load(self) -> np.ndarray:
        """Per joint, N·m the joint was measured to need per N·m of the model's gravity at a hold (at
        least 1; 1 where none was measured): :meth:`measure_hold` (a new array)."""
        return self._load.copy()

    def measure_hold(self, q: Any, tau: Any) -> None:
        """The arm holds still at ``q`` (rad) with its motors reporting ``tau`` (N·m, config order): each
        joint that gravity loads by at least :data:`HOLD_MIN_SHARE` of its limit, and whose torque pushes
        the way gravity asks, gets ``load`` = the torque it gets (``tau`` times its identified torque
        scale) over the model's gravity, within 1 and :data:`MAX_LOAD`; the others keep theirs."""
        q = np.asarray(q, dtype=float)
        g = self.model.gravity(q)
        delivered = np.asarray(tau, dtype=float) * self._scale
        for i in range(len(g)):
            if abs(g[i]) >= HOLD_MIN_SHARE * self.limit[i] and delivered[i] * g[i] > 0.0:
                self._load[i] = min(max(delivered[i] / g[i], 1.0), MAX_LOAD)
                self._held[i] = [round(float(x), 3) for x in q]

    def set_payload(self, payload: tuple[float, np.ndarray] | None) -> None:
        """The payload the arm carries (its model's), or ``None``."""
        if payload is None:
            if self.model.payload is not None:
                self.model.clear_payload()
        elif self.model.payload is None or self.model.payload[0] != payload[0] or not np.array_equal(
                self.model.payload[1], payload[1]):
            self.model.set_payload(payload[0], payload[1])
        else:
            return
        self._load = np.ones(len(self.limit))  # (measured against the model without it)
        self._held = [None] * len(self.limit)

    def speed_factor(self, sample: Callable[[float], tuple[Any, Any, Any]],
                     t0: float, t_end: float) -> tuple[float, int]:
        """The largest factor (≤ 1) on a plan's speed that keeps every joint's model torque within its
        budget, and the joint that sets it (-1: none). ``sample(t)`` gives (q, dq, ddq) at plan time ``t``.

        Raises:
            LimitError: gravity alone needs more than a joint's whole limit somewhere on the path.
        """
        f2, joint = 1.0, -1
        model = self.model
        load = self._load
        for t in np.linspace(t0, t_end, _SAMPLES):
            q, dq, ddq = sample(float(t))
            g = model.gravity(q)
            rest = model.inverse_dynamics(q, dq, ddq) - g
            for i in range(len(g)):
                lim, gi, ri = self.limit[i], abs(g[i]), abs(rest[i])
                if gi > lim:
                    raise LimitError(f"holding the arm at {np.round(np.asarray(q), 3).tolist()} needs {gi:.1f} "
                                     f"N·m, more than the joint's {lim:.1f} N·m", joint=self.names[i],
                                     fix="a pose where the arm's weight (and the payload's) loads the joint less")
                room = max(self.budget[i] - gi, MIN_DYNAMIC_SHARE * lim)  # for the accelerations, N·m
                if self._held[i] is not None:  # measured: the model's torque times load, and friction, within
                    # MEASURED_SHARE (never more room than the model's budget gives)
                    held = gi * load[i]
                    need = held + self._friction[i] + self._friction_load[i] * held  # to move it from there
                    cap = MEASURED_SHARE * lim
                    if need > cap:
                        raise LimitError(
                            f"holding the arm at {np.round(np.asarray(q), 3).tolist()} and moving it from there "
                            f"needs about {need:.1f} N·m, more than the {cap:.1f} N·m a move may use of the joint's "
                            f"{lim:.1f}: {gi:.1f} N·m of gravity on the model, times the {load[i]:.2f} this arm was "
                            f"measured to need holding at {self._held[i]} (a weaker unit, heavier links, or a "
                            f"payload it was not told), and {need - held:.1f} N·m of friction",
                            joint=self.names[i],
                            fix="tell the arm its payload (arm.set_payload), identify the unit (akarm identify), "
                                "or a pose where the arm's weight loads the joint less")
                    # for the accelerations (N·m of the model's): what is left, however little (a slow move)
                    room = min(room, max((cap - need) / load[i], MIN_MEASURED_DYNAMIC_SHARE * lim / load[i]))
                if ri > room:
                    s2 = room / ri
                    if s2 < f2:
                        f2, joint = s2, i
        return math.sqrt(f2), joint
