"""Guarded moves: the tool moved along a direction until it feels a force (``arm.move_until_contact``).

:class:`ContactWatch` runs on the control loop's thread, once a cycle, after the collision observer's
update: it turns the observer's external torque estimate into a wrench at the tool (``Jᵀ·F = τ_ext``,
least squares) and fires when the force against the motion passes the threshold, or the force in any
direction passes twice it (something hit from the side). The controller then stops the motion
(jerk-limited, from this cycle's command) and holds: the collision reflex's "stop and report"
reaction, whose report is the watch's :attr:`ContactWatch.contact`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from akarm.dynamics.model import RobotModel

__all__ = ["Contact", "ContactWatch"]


@dataclass(frozen=True)
class Contact:
    """Where a guarded move felt contact (or ``touched`` False: it went its whole way without).

    Attributes:
        touched: whether the force passed the threshold. force: the force against the motion then, N.
        position: the tool frame's origin then (m, base frame, measured). wrench: the estimated wrench
            then (N, N·m, base axes). distance: how far the tool had gone along the direction, m.
        pose: the measured tool pose (4×4) when the move ended (after the stop, or the back-off).
    """

    touched: bool
    force: float
    position: np.ndarray
    wrench: np.ndarray
    distance: float
    pose: np.ndarray


class ContactWatch:
    """Fires when the external force against ``direction`` (a unit vector, base frame) reaches ``force`` N.

    Args:
        model: a model of its own (the loop's thread uses it). start: the tool position at the start, m.
    """

    def __init__(self, model: RobotModel, direction: np.ndarray, force: float, start: np.ndarray) -> None:
        self.model = model
        self.direction = np.asarray(direction, dtype=float)
        self.force = float(force)
        self.start = np.asarray(start, dtype=float)
        self.fired = False
        self.peak = 0.0  # N: the largest force against the motion seen
        self.found: tuple[float, np.ndarray, np.ndarray, float] | None = None  # (force, position, wrench, distance)

    def step(self, q: Sequence[float], tau_ext: Sequence[float]) -> bool:
        """True (once) when the force passes the threshold; the contact is then in :attr:`found`."""
        if self.fired:
            return False
        J = self.model.jacobian(q)
        wrench = np.linalg.lstsq(J.T, np.asarray(tau_ext, dtype=float), rcond=1e-3)[0]
        against = -float(wrench[:3] @ self.direction)
        self.peak = max(self.peak, against)
        if against < self.force and float(np.linalg.norm(wrench[:3])) < 2.0 * self.force:
            return False
        p = self.model.tool_pose(q)[:3, 3]
        self.fired = True
        self.found = (against, p.copy(), np.asarray(wrench), float((p - self.start) @ self.direction))
        return True
