"""What a simulator reports about itself: a driver's state, a frame its drivers took in or sent.

:meth:`SimulatedRobot.driver_states <akarm.sim.robot.SimulatedRobot.driver_states>` and
:meth:`~akarm.sim.robot.SimulatedRobot.logged_frames` make them in the simulator's process;
:class:`~akarm.sim.channel.SimulatorControl` rebuilds the same records from its control channel's answers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

__all__ = ["DriverState", "Frame"]


@dataclass(frozen=True)
class DriverState:
    """One simulated driver as it is now (joint side, SI).

    Attributes:
        name: the joint. enabled: its output is driven (MIT: motor mode; servo: not released).
        position: rad. velocity: rad/s. torque: N·m the motor applies. temperature: °C.
        error: the error code it reports (0: none). faults: the faults in force, as text.
        frames_in: frames addressed to it that it took in. frames_out: frames it sent.
    """

    name: str
    enabled: bool
    position: float
    velocity: float
    torque: float
    temperature: float
    error: int
    faults: tuple[str, ...]
    frames_in: int
    frames_out: int


class Frame(NamedTuple):
    """A CAN frame a simulated driver took in or sent.

    Attributes:
        t: simulated time, s. bus: the bus's name in the robot file.
        arbitration_id, is_extended, data: the frame.
        joint: the driver it was addressed to or sent by (``None``: nobody's).
        to_motor: ``True`` taken in (a command to the motor), ``False`` sent (a reply or status frame).
    """

    t: float
    bus: str
    arbitration_id: int
    is_extended: bool
    data: bytes
    joint: str | None
    to_motor: bool
