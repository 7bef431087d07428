"""An identified torque scale (``friction: {torque_scale: ...}``, what ``akarm identify --torque-scale``
fits) counts wherever akarm asks a motor for gravity's torque or reads it back: holding and moving
(the feed-forward), settling at enable and the turn check that weighs the holding torque, and teach
mode. A unit whose motors give 0.7 N·m per N·m asked must be asked 1/0.7 of the model's torque
everywhere, or it sags in teach and its enable is judged against the wrong weight. Lock step.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import akarm
from akarm.sim import Variation

from ..conftest import ROBOTS, lockstep_arm

PLANAR2 = akarm.load_robot(ROBOTS / "planar2.yaml")
HOME = PLANAR2.pose("home")  # straight out, horizontal: the most torque gravity asks


def identified(config: akarm.RobotConfig, scale: float) -> akarm.RobotConfig:
    joints = [dataclasses.replace(j, friction=dataclasses.replace(j.friction_model(), torque_scale=scale))
              for j in config.joints]
    return dataclasses.replace(config, joints=tuple(joints))


@pytest.mark.parametrize("scale", [0.7, 1.3])
def test_an_identified_unit_enables_and_is_carried_in_teach_mode(channel: str, scale: float) -> None:
    with lockstep_arm(PLANAR2, channel, q0=HOME, config_edit=lambda c: identified(c, scale),
                      sim_options={"variation": Variation(torque_scale=scale)}) as (arm, sim):
        arm.enable()  # the turn check weighs the reported holding torque: 1/scale of the model's
        assert arm.enabled and arm.fault is None
        arm.sleep(0.3)
        start = np.array(sim.q)
        arm.teach(damping=0.1)
        arm.sleep(1.0)
        drift = np.abs(np.array(sim.q) - start)
        arm.end_teach()
        # carried: what is left is friction's stick and the ramp; asked the model's torque unscaled, a unit
        # of 0.7 gets 0.7 of its weight carried and falls (0.3 of 9 N·m against kd 0.1 N·m·s/rad)
        assert float(np.max(drift)) < 0.02, drift
