"""Servoing, impedance and guarded moves on varied simulated units (``akarm.sim.Variation``): the issue's
acceptance checks on arms that are not the robot file's model (torque constants × 0.49-1.3 in all,
friction × 0.5-2, link masses ± 20 %, backlash, reply jitter).

Servoing is position control: it meets the nominal figures on a varied unit unidentified (the hold
integral's torque, what the model misses about the unit, is kept while servoing). Impedance and a
guarded move turn torque into force through the unit's torque constant; they are checked on the unit
identified (``arm.set_friction(..., torque_scale=...)`` with what ``akarm identify`` fits; here the
simulator's truth), against the looser figures docs/compliance.md states: friction the model does not
carry holds the tool a few mm off its target. Lock step on arm6; the tool from the simulator's joints.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import akarm
from akarm.dynamics.model import RobotModel
from akarm.sim import Variation

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FK = RobotModel(ARM6)
V_MAX = np.array([j.limits.velocity for j in ARM6.joints])
SEEDS = (1, 3)  # 3: every joint's torque constant 0.68-0.91 of the catalogue's, the pan's friction × 2
#: m: how near its target an identified unit's tool comes back after a push (nominal: 2 mm). Impedance has
#: no integral: the model's gravity error (masses ± 20 %) and Coulomb friction (not compensated at rest)
#: hold it off by their force over K (measured 1.4-5.7 mm on seeds 1-4 at K = 500 N/m)
BACK = 0.008


def tool(sim: akarm.sim.SimulatedRobot) -> np.ndarray:
    return FK.tool_pose(sim.q)


def identify(arm: akarm.Arm, variation: Variation) -> None:
    """What `akarm identify` fits, told to the arm (here the simulator's truth)."""
    truth = variation.truth(ARM6)
    arm.set_friction([j.coulomb for j in truth.joints], [j.viscous for j in truth.joints],
                     torque_scale=[j.torque_scale for j in truth.joints])


@pytest.mark.parametrize("seed", SEEDS)
def test_a_second_of_twist_up_on_a_varied_unit_rises_50_mm_straight(channel: str, seed: int) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True, sim_options={"variation": Variation(seed=seed)}) \
            as (arm, sim):
        arm.sleep(0.5)  # holding: the hold integral makes up for what the model misses
        start = tool(sim)
        with arm.servo(timeout=0.1) as s:
            end = arm.clock.now() + 1.0
            while arm.clock.now() < end - 1e-9:
                s.twist([0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
                arm.sleep(0.01)
            after = tool(sim)
        rise = after[2, 3] - start[2, 3]
        assert 0.045 <= rise <= 0.055, f"rose {rise * 1e3:.1f} mm"
        assert np.linalg.norm(after[:2, 3] - start[:2, 3]) < 0.003
        assert np.linalg.norm(pin.log3(after[:3, :3] @ start[:3, :3].T)) < 0.02
        assert np.all(np.abs(arm.telemetry().dq_des) <= V_MAX * (1 + 1e-9))
        assert arm.enabled and arm.fault is None


@pytest.mark.parametrize("seed", SEEDS)
def test_a_10_newton_push_on_a_varied_unit_identified(channel: str, seed: int) -> None:
    variation = Variation(seed=seed)
    with lockstep_arm(ARM6, channel, q0=READY, enable=True, sim_options={"variation": variation}) as (arm, sim):
        identify(arm, variation)
        arm.sleep(0.5)
        with arm.impedance(stiffness=[500, 500, 500, 30, 30, 30]) as imp:
            arm.sleep(0.2)
            target, before = imp.law.target.copy(), tool(sim)
            sim.set_external_wrench([0.0, 0.0, -10.0, 0.0, 0.0, 0.0])
            arm.sleep(1.5)
            pushed, wrench = tool(sim), imp.wrench()
            sim.set_external_wrench(None)
            arm.sleep(1.0)
            back = tool(sim)
        assert arm.enabled and arm.fault is None  # no false stop
    dz = before[2, 3] - pushed[2, 3]
    assert 0.015 <= dz <= 0.025, f"moved {dz * 1e3:.1f} mm"
    assert np.linalg.norm(pin.log3(pushed[:3, :3] @ target[:3, :3].T)) < 0.05
    assert np.linalg.norm(back[:3, 3] - target[:3, 3]) < BACK, f"{np.linalg.norm(back[:3, 3] - target[:3, 3])}"
    assert abs(wrench[2] + 10.0) <= 3.0


@pytest.mark.parametrize("seed", SEEDS[1:])  # (one seed: a guarded move takes the longest; 1-4 in the docs)
def test_a_guarded_move_on_a_varied_unit_identified(channel: str, seed: int) -> None:
    variation = Variation(seed=seed)
    with lockstep_arm(ARM6, channel, q0=READY, enable=True, sim_options={"variation": variation}) as (arm, sim):
        identify(arm, variation)
        arm.sleep(0.5)
        surface = tool(sim)[2, 3] - 0.03
        sim.set_surface(surface, stiffness=2e4)
        contact = arm.move_until_contact([0.0, 0.0, -1.0], speed=0.02, force=5.0)
        assert contact.touched and arm.fault is None
        assert sim.contact_peak <= 7.5  # at most 1.5 × the threshold
        assert abs(contact.position[2] - surface) < 0.003
