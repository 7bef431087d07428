"""akarm's hardware-in-the-loop simulator: AK drivers on a CAN bus, moving a simulated arm.

Nobody needs a robot to develop or test akarm: :class:`SimulatedRobot` puts one simulated driver per
configured joint on the config's buses, answering the real wire protocol exactly as the firmware
does (through :mod:`akarm.protocol`, motor side), and moves a Pinocchio model of the arm with the
torques the firmware would apply. ``akarm sim ROBOT.yaml -i socketcan -c vcan0`` runs the same as
its own process, for a controller or ``candump`` to talk to as to hardware.

::

    from akarm.sim import SimulatedRobot, faults
    with SimulatedRobot(config, interface="virtual", channel="demo", realtime=False) as sim:
        sim.joint("elbow").inject(faults.DropReplies(0.3))
        sim.run_for(1.0)

Modules: :mod:`~akarm.sim.robot` (the robot and its time), :mod:`~akarm.sim.drivers` (firmware
state machines and loops), :mod:`~akarm.sim.plant` (dynamics, friction, hard stops, heating),
:mod:`~akarm.sim.faults` (faults to inject), :mod:`~akarm.sim.params` (constants per actuator),
:mod:`~akarm.sim.variation` (a real unit, not the datasheet),
:mod:`~akarm.sim.records` (what it reports: driver states, frames), :mod:`~akarm.sim.channel` (its
control channel), :mod:`~akarm.sim.process` (a simulator in a process of its own).
The plant and the robot (numpy, Pinocchio) load on first use, so ``akarm.sim.faults`` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akarm.sim import faults
from akarm.sim.params import MotorSimParams, default_params

if TYPE_CHECKING:
    from akarm.sim.drivers import MitDriver, ServoDriver, SimulatedDriver, TrapezoidProfile
    from akarm.sim.plant import Plant
    from akarm.sim.robot import SimulatedRobot
    from akarm.sim.variation import Truth, Variation

__all__ = [
    "MitDriver",
    "MotorSimParams",
    "Plant",
    "ServoDriver",
    "SimulatedDriver",
    "SimulatedRobot",
    "TrapezoidProfile",
    "Truth",
    "Variation",
    "default_params",
    "faults",
]

_LAZY = {
    "MitDriver": "drivers",
    "ServoDriver": "drivers",
    "SimulatedDriver": "drivers",
    "TrapezoidProfile": "drivers",
    "Plant": "plant",
    "SimulatedRobot": "robot",
    "Truth": "variation",
    "Variation": "variation",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
