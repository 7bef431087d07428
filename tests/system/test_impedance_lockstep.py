"""Impedance control (``arm.impedance()``): a push moves the tool as its spring says, it returns on release,
the wrench is estimated, targets and stiffness change smoothly, a deviation past the bound stops the arm.

Lock step on arm6; the push is an external wrench the simulator applies as joint torques ``Jᵀ·F`` every
step; the tool is measured with the test's own forward kinematics from the simulator's joint angles.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import akarm
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, DeviationError, StateError

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FK = RobotModel(ARM6)


def tool(sim) -> np.ndarray:
    return FK.tool_pose(sim.q)


def test_a_10_newton_push_on_500_newtons_per_metre_moves_the_tool_20_mm_and_it_returns(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with arm.impedance(stiffness=[500, 500, 500, 30, 30, 30], damping_ratio=1.0) as imp:
            arm.sleep(0.2)
            target = imp.law.target.copy()
            sim.set_external_wrench([0.0, 0.0, -10.0, 0.0, 0.0, 0.0])
            arm.sleep(1.5)
            pushed = tool(sim)
            wrench = imp.wrench()
            sim.set_external_wrench(None)
            arm.sleep(1.0)
            back = tool(sim)
        assert arm.enabled and arm.fault is None
    dz = target[2, 3] - pushed[2, 3]
    assert 0.015 <= dz <= 0.025, f"moved {dz * 1e3:.1f} mm"
    assert np.linalg.norm(pushed[:2, 3] - target[:2, 3]) < 0.003
    assert np.linalg.norm(pin.log3(pushed[:3, :3] @ target[:3, :3].T)) < 0.05
    assert np.linalg.norm(back[:3, 3] - target[:3, 3]) < 0.002
    assert abs(wrench[2] + 10.0) <= 3.0 and np.linalg.norm(wrench[:2]) <= 3.0


def test_the_target_moves_jerk_limited_and_the_stiffness_changes_smoothly(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with arm.impedance(stiffness=[800, 800, 800, 40, 40, 40]) as imp:
            goal = tool(sim)
            goal[:3, 3] += [0.0, 0.0, 0.03]
            imp.set_target(goal)
            arm.sleep(1.5)
            assert np.linalg.norm(tool(sim)[:3, 3] - goal[:3, 3]) < 0.003
            imp.set_stiffness([200, 200, 200, 20, 20, 20])
            arm.sleep(0.1)
            assert 200 < imp.law.k[0] < 800  # on its way
            arm.sleep(0.3)
            assert np.allclose(imp.law.k, [200, 200, 200, 20, 20, 20])
            with pytest.raises(StateError, match="impedance"):
                arm.move_to("ready")
        log = arm.telemetry()
        step = np.abs(np.diff(log.tau_ff, axis=0))
        limits = np.array([j.limits.torque for j in ARM6.joints])
        assert np.all(step <= 0.02 * limits + 0.6)  # the law's step, plus the weight's own change a cycle
        # after the block the arm holds where it is, stiff again
        here = sim.q.copy()
        arm.sleep(0.5)
        assert np.allclose(sim.q, here, atol=3e-3)
        assert np.all(arm.gains[0] > 0)


def test_joint_impedance_holds_each_joint_as_a_spring(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        k = [40.0, 40.0, 40.0, 5.0, 5.0, 5.0]
        with arm.impedance(joint_stiffness=k) as imp:
            arm.sleep(0.2)
            q0 = imp.law.target.copy()
            push = np.zeros(6)
            push[0] = 2.0  # N·m on the pan: 50 mrad at 40 N·m/rad
            sim.set_external_torque(push)
            arm.sleep(1.5)
            moved = sim.q[0] - q0[0]
            sim.set_external_torque(None)
            target = q0.copy()
            target[5] += 0.2
            imp.set_target(target)
            arm.sleep(2.0)
            assert abs(sim.q[5] - target[5]) < 0.03
    assert 0.025 <= moved <= 0.06, f"moved {moved:.3f} rad"  # 50 mrad less what friction holds


def test_a_deviation_past_the_bound_is_a_named_safety_stop(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with pytest.raises(DeviationError, match="from its target") as info, \
                arm.impedance(stiffness=[100, 100, 100, 20, 20, 20], max_deviation=(0.03, 0.5)):
            sim.set_external_wrench([0.0, 0.0, -10.0, 0.0, 0.0, 0.0])  # 100 mm at 100 N/m: past 30 mm
            arm.sleep(3.0)
        assert info.value.limit == 0.03 and info.value.deviation > 0.03
        assert not arm.enabled
        sim.set_external_wrench(None)
        arm.enable()  # the gains are back: the arm holds again
        assert np.all(arm.gains[0] > 0)


def test_a_stop_inside_the_block_is_raised_when_the_block_ends_normally(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with pytest.raises(DeviationError, match="from its target"), \
                arm.impedance(stiffness=[100, 100, 100, 20, 20, 20], max_deviation=(0.03, 0.5)):
            sim.set_external_wrench([0.0, 0.0, -10.0, 0.0, 0.0, 0.0])
            arm.clock.sleep_until(arm.clock.now() + 3.0)  # the clock goes on; nothing in the block asks the arm
        assert not arm.enabled and arm.fault is not None


def test_impedance_arguments_are_checked(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, _sim):
        for bad in ({}, {"stiffness": [1, 2, 3]}, {"stiffness": [500] * 6, "joint_stiffness": [1] * 6},
                    {"stiffness": [-1, 0, 0, 0, 0, 0]}, {"stiffness": [500] * 6, "damping_ratio": 0.0},
                    {"joint_stiffness": [1.0] * 5}):
            with pytest.raises(ArgumentError):
                arm.impedance(**bad)
        with arm.impedance(stiffness=[500] * 6) as imp:
            with pytest.raises(ArgumentError):
                imp.set_stiffness([1.0, float("nan"), 0, 0, 0, 0])
            with pytest.raises(ArgumentError):
                imp.set_target("nowhere")


def test_servo_mode_joints_are_refused(channel: str) -> None:
    config = akarm.load_robot(ROBOTS / "servo3.yaml")
    with lockstep_arm(config, channel, enable=True) as (arm, _sim), pytest.raises(StateError, match="servo mode"):
        arm.impedance(joint_stiffness=[10.0] * arm.n)
