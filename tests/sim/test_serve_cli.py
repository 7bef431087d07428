"""A lock-step Arm cannot be served: ArmServer needs the wall clock (akarm serve and its clients:
tests/system/test_serve_cli.py)."""

from __future__ import annotations

import pytest

import akarm
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS

PLANAR2 = ROBOTS / "planar2.yaml"


def test_a_lock_step_arm_cannot_be_served(channel):
    config = akarm.load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm, \
            pytest.raises(akarm.StateError, match="wall clock"):
        akarm.ArmServer(arm)
