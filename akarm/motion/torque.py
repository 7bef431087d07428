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
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from akarm.config import RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError

__all__ = ["IDENTIFIED_SHARE", "MIN_DYNAMIC_SHARE", "UNIDENTIFIED_SHARE", "TorqueBudget"]

#: share of an unidentified joint's torque limit a move may plan to use: a unit may give 30 % less
UNIDENTIFIED_SHARE = 0.7
#: share of an identified joint's (limit × its torque scale): the rest is for the feedback
IDENTIFIED_SHARE = 0.9
#: share of the limit kept for acceleration where gravity alone takes more than the share
MIN_DYNAMIC_SHARE = 0.1
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
        limit, share = [], []
        for j in config.joints:
            identified = j.friction is not None
            scale = j.friction_model().torque_scale if identified else 1.0
            limit.append(j.limits.torque * scale)
            share.append(IDENTIFIED_SHARE if identified else UNIDENTIFIED_SHARE)
        #: N·m per joint at the joint: the limit the motor is held to, times the torque it gets per N·m
        self.limit = np.array(limit, dtype=float)
        #: N·m per joint a move may plan to use
        self.budget = self.limit * np.array(share)

    def set_payload(self, payload: tuple[float, np.ndarray] | None) -> None:
        """The payload the arm carries (its model's), or ``None``."""
        if payload is None:
            if self.model.payload is not None:
                self.model.clear_payload()
        elif self.model.payload is None or self.model.payload[0] != payload[0] or not np.array_equal(
                self.model.payload[1], payload[1]):
            self.model.set_payload(payload[0], payload[1])

    def speed_factor(self, sample: Callable[[float], tuple[Any, Any, Any]],
                     t0: float, t_end: float) -> tuple[float, int]:
        """The largest factor (≤ 1) on a plan's speed that keeps every joint's model torque within its
        budget, and the joint that sets it (-1: none). ``sample(t)`` gives (q, dq, ddq) at plan time ``t``.

        Raises:
            LimitError: gravity alone needs more than a joint's whole limit somewhere on the path.
        """
        f2, joint = 1.0, -1
        model = self.model
        for t in np.linspace(t0, t_end, _SAMPLES):
            q, dq, ddq = sample(float(t))
            g = model.gravity(q)
            rest = model.inverse_dynamics(q, dq, ddq) - g
            for i in range(len(g)):
                lim, gi, ri = self.limit[i], abs(g[i]), abs(rest[i])
                if gi > lim:
                    raise LimitError(f"holding the arm at {np.round(np.asarray(q), 3).tolist()} needs {gi:.1f} N·m, "
                                     f"more than the joint's {lim:.1f} N·m", joint=self.names[i],
                                     fix="a pose where the arm's weight (and the payload's) loads the joint less")
                room = max(self.budget[i] - gi, MIN_DYNAMIC_SHARE * lim)  # for the accelerations, N·m
                if ri > room:
                    s2 = room / ri
                    if s2 < f2:
                        f2, joint = s2, i
        return math.sqrt(f2), joint
