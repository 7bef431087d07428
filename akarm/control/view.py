"""Read-only observability of a controller: ``arm.observe``.

What tests, benchmarks and diagnostics look at inside the real-time side, none of which changes what
the arm does: the buses and the loop (to see them, or to make them fail in a test), the torque last
commanded, the gain ramp, the supervisor's limits. Each property is read at the moment it is asked.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import can

    from akarm.control.controller import Controller
    from akarm.control.gripper import GripperDrive
    from akarm.control.loop import ControlLoop
    from akarm.control.modes import Mode
    from akarm.control.safety import Guard

__all__ = ["ControllerView"]


class ControllerView:
    """A window on an Arm's controller (see the module's docstring); every property is read-only."""

    __slots__ = ("_controller",)

    def __init__(self, controller: Controller) -> None:
        self._controller = controller

    @property
    def mode(self) -> Mode:
        """The controller's mode (as :attr:`akarm.Arm.mode`)."""
        return self._controller.mode

    @property
    def buses(self) -> Mapping[str, can.BusABC]:
        """The open python-can buses by name (empty while the arm is closed)."""
        return self._controller.bus.buses

    @property
    def lost_buses(self) -> Mapping[str, BaseException]:
        """The buses that failed under the arm since it was opened, with what failed."""
        return self._controller.bus.lost

    @property
    def loop(self) -> ControlLoop:
        """The fixed-rate loop (its thread, statistics, real-time report)."""
        return self._controller.loop

    @property
    def gripper(self) -> GripperDrive | None:
        """The gripper's loop side (its joint, target, law: ``mode``), ``None`` without a gripper."""
        return self._controller.gripper

    @property
    def tau_ff(self) -> np.ndarray:
        """The feed-forward torque of the last command per joint, N·m (what a stop fades out from)."""
        with self._controller.lock:
            return np.array(self._controller.tau_ff, dtype=float)

    @property
    def gain_scale(self) -> float:
        """The share of kp in force (it ramps from 0 to 1 once the arm is held)."""
        return self._controller.ramp.scale

    @property
    def plan_lag(self) -> float:
        """s the plan's time trails the clock: the slots the loop missed (it waits for the motors rather
        than jump ahead after a stall)."""
        return self._controller.plan_lag

    @property
    def stall_limit(self) -> float:
        """s the loop may fail to run and resume without a stop (longer: :class:`~akarm.LoopStall`)."""
        return self._controller.stall_limit

    @property
    def guards(self) -> tuple[Guard, ...]:
        """The supervisor's limits per joint: feedback timeout, temperature, following error, stuck travel."""
        return tuple(self._controller.supervisor.guards)
