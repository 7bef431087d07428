"""A robot made from a URDF of the corpus (tests/urdfs) moves in the simulator, in lock step: the
reduced model is what it simulates (the rest: tests/unit/test_urdf.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import akarm
from akarm.dynamics.model import RobotModel
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot

from ..unit.test_urdf import ARM7, write


def test_the_simulator_simulates_the_reduced_model(channel: str, tmp_path: Path) -> None:
    """The plant integrates the model with the fingers locked: the arm holds and tracks as with any arm."""
    config = load_robot(write(tmp_path, ARM7)).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False) as sim:
        assert sim.plant.model.pin_model.nq == 7
        np.testing.assert_allclose(sim.plant.model.gravity(config.pose("out")),
                                   RobotModel(config).gravity(config.pose("out")), atol=1e-12)
        with akarm.Arm(config, clock=sim.clock) as arm:
            arm.enable()
            for pose in ("home", "out"):
                arm.move_to(pose)
                arm.sleep(0.5)
                err = np.abs(arm.state().q - np.array(config.pose(pose)))
                assert err.max() < 2e-3, (pose, err)
