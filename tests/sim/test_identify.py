"""Identification too fast for the joint limits, or centred where its amplitude would leave them, is
refused before anything moves (identification runs: tests/system/test_identify.py)."""

from __future__ import annotations

import numpy as np
import pytest

import akarm
from akarm.arm import Arm
from akarm.errors import LimitError
from akarm.identify import identify
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")


def test_identification_too_fast_or_off_centre_is_refused_before_moving(channel: str) -> None:
    cfg = ARM6.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home")) as sim, Arm(cfg, clock=sim.clock) as arm:
        arm.enable()
        before = arm.state().q_des
        with pytest.raises(LimitError) as e:
            identify(arm, speed=1.0, amplitude=0.7)
        assert e.value.joint in ARM6.joint_names and "speed" in e.value.fix
        with pytest.raises(LimitError):
            identify(arm, center=[0, 2.0, 0, 0, 0, 0])  # shoulder_lift's range is ±1.7
        arm.sleep(0.1)
        assert np.allclose(arm.state().q_des, before) and not arm.moving
