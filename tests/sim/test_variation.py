"""A simulated unit that is not its datasheet (akarm.sim.Variation): what it draws and what it does.

The draws: deterministic per seed, within the documented spreads, the nominal model by default. The
physics, measured on planar2 held by a stiff MIT PD at rest: the motor reports the gravity torque
divided by the unit's torque scale; its link masses scale gravity; backlash shifts the reading by half
the play in the direction of the load; friction's load-dependent part shows in a slow move.
"""

from __future__ import annotations

import math

import can
import numpy as np
import pytest

from akarm.config import RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot, Variation, default_params
from akarm.sim.variation import SPREADS, kt_out

from .conftest import ROBOTS, drain

ARM6 = load_robot(ROBOTS / "arm6.yaml")


def test_draws_are_per_seed_repeatable_within_the_spreads_and_nominal_without_a_seed() -> None:
    assert Variation(seed=4).truth(ARM6) == Variation(seed=4).truth(ARM6)
    assert Variation(seed=4).truth(ARM6) != Variation(seed=5).truth(ARM6)
    scales = []
    for seed in range(50):
        truth = Variation(seed=seed).truth(ARM6)
        for j, link, jc in zip(truth.joints, truth.links, ARM6.joints, strict=True):
            p = default_params(jc.motor)
            assert SPREADS["kt"][0] <= j.kt <= SPREADS["kt"][1]
            assert 0.7 <= j.true_over_reported <= 1.0
            assert j.torque_scale == pytest.approx(j.kt * j.true_over_reported)
            assert 0.5 * p.coulomb <= j.coulomb <= 2.0 * p.coulomb and 0.5 * p.viscous <= j.viscous <= 2.0 * p.viscous
            assert 0.0 <= j.coulomb_load <= 0.06 * kt_out(jc)
            assert 0.0 <= j.backlash <= 0.005 and 0.0 <= j.reply_jitter <= 0.001
            assert 0.8 <= link.mass <= 1.2 and 0.8 <= link.com <= 1.2
            scales.append(j.torque_scale)
    assert min(scales) < 0.6 and max(scales) > 1.15  # the spreads are used, not a corner of them
    nominal = Variation().truth(ARM6)
    assert all(j.torque_scale == 1.0 and j.coulomb_load == 0.0 and j.backlash == 0.0 for j in nominal.joints)
    twice = Variation(friction=2.0).truth(ARM6)
    assert [j.coulomb for j in twice.joints] == [2.0 * default_params(j.motor).coulomb for j in ARM6.joints]
    with pytest.raises(ArgumentError, match="seed"):
        Variation(seed=-1)
    with pytest.raises(ArgumentError, match="friction"):
        Variation(friction=0.0)
    with pytest.raises(ArgumentError, match="not given to a simulator"):
        Variation(seed=1).truth()


def _hold(planar2: RobotConfig, channel: str, variation: Variation | None, q: float = 0.0) -> SimulatedRobot:
    """planar2 held at (q, 0) by a stiff PD for 1.5 s; the simulator, still open, is returned closed."""
    with SimulatedRobot(planar2, "virtual", channel, realtime=False, q0=[q, 0.0], variation=variation) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        for j in planar2.joints:
            bus.send(can.Message(arbitration_id=j.can_id, data=mit.ENTER, is_extended_id=False))
            bus.send(can.Message(arbitration_id=j.can_id, data=mit.encode_command(j.motor, q if j is planar2.joints[0]
                                                                                   else 0.0, 0.0, 300.0, 5.0, 0.0),
                                 is_extended_id=False))
        sim.run_for(1.5)
        drain(bus)
        return sim


def test_a_varied_unit_reports_gravity_over_its_torque_scale_and_reads_half_its_play_off(
        planar2: RobotConfig, channel: str) -> None:
    nominal = _hold(planar2, channel + "-a", None)
    v = Variation(seed=11)
    varied = _hold(planar2, channel + "-b", v)
    truth = v.truth()
    assert varied.truth == truth and nominal.truth is None
    reported = np.array([d.torque for d in varied.drivers])  # what the motors report (motor side = joint side here)
    reference = RobotModel(planar2)
    reference.scale_links({x.name: (x.mass, x.com) for x in truth.links})
    g = reference.gravity(varied.q)
    scale = np.array([j.torque_scale for j in truth.joints])
    # at rest the joints get exactly the gravity torque: scale × the reported one
    assert reported * scale == pytest.approx(g, abs=5e-3)
    assert np.abs(reported - RobotModel(planar2).gravity(nominal.q)).max() > 0.05  # not what the datasheet says
    # at rest the PD holds the encoder at -reported / kp, and the link is half the play behind it
    # (against the motor's torque): the plant's tanh over 5 % of t_max
    j0, m0 = truth.joints[0], planar2.joints[0].motor
    c = varied.drivers[0].stored_command  # as quantised on the wire
    encoder = c.position + (c.kd * c.velocity + c.torque - reported[0]) / c.kp
    play = 0.5 * j0.backlash * math.tanh(g[0] / (0.05 * m0.t_max))
    assert abs(play) > 5e-4
    assert varied.q[0] == pytest.approx(encoder - play, abs=2e-5)
