"""Where today's features meet (the safety review): the gripper, walls, servoing, impedance and guarded
moves together, safety stops and disable() while one of them runs, handles used outside their block.

Lock step on arm6g (arm6 with a gripper) from ``ready``; positions are the simulator's own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import akarm
from akarm.config.workspace import Workspace
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError, MotorFault, StateError, UnreachableError
from akarm.sim import faults

from ..conftest import ROBOTS, lockstep_arm

ARM6G = akarm.load_robot(ROBOTS / "arm6g.yaml")
READY = np.array(ARM6G.pose("ready"))
FK = RobotModel(ARM6G)
SOFT = [500, 500, 500, 30, 30, 30]


def test_an_impedance_handle_commands_only_inside_its_one_block(channel: str) -> None:
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, sim):
        imp = arm.impedance(stiffness=SOFT)
        here = arm.tool_pose()
        with pytest.raises(StateError, match="block"):
            imp.set_target(here)  # not yet entered
        with imp:
            arm.sleep(0.1)
        for command in (lambda: imp.set_target(here), lambda: imp.set_stiffness(SOFT)):
            with pytest.raises(StateError, match="block"):
                command()  # the block ended: refused, not silently dropped
        with pytest.raises(StateError, match="once"), imp:
            pass
        assert arm.enabled and arm.fault is None
        # a handle made before the arm moved would spring it back to where it was: refused
        stale = arm.impedance(stiffness=SOFT)
        goal = READY + 0.05
        arm.move_to(goal)
        with pytest.raises(StateError, match="moved"), stale:
            pass
        arm.sleep(0.5)
        assert arm.enabled and arm.fault is None
        assert np.abs(sim.q - goal).max() < 0.005, np.abs(sim.q - goal).max()


def test_teach_mode_is_refused_under_impedance(channel: str) -> None:
    # (it was taken: the impedance torque of the last cycle went on as teach mode's extra torque, pushing the
    # arm away, and the law came back at end_teach with its old target: a DeviationError, or a spring back)
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, sim):
        with arm.impedance(stiffness=SOFT) as imp:
            arm.sleep(0.1)
            with pytest.raises(StateError, match="impedance"):
                arm.teach()
            held = sim.q.copy()
            arm.sleep(0.5)
            assert np.abs(sim.q - held).max() < 0.002
            imp.set_target(arm.tool_pose())  # still in force
        assert arm.enabled and arm.fault is None


def test_gains_are_not_changed_under_impedance(channel: str) -> None:
    # (they were: a kp under impedance pulled the arm toward where the block began, against the law, and the
    # gains saved at its start silently undid the change at its end)
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, _sim):
        before = arm.gains
        with arm.impedance(stiffness=SOFT):
            with pytest.raises(StateError, match="impedance"):
                arm.set_gains(kp=5.0)
            assert not np.any(arm.gains[0])  # kp = 0 on every joint, as impedance control needs
        assert all(np.array_equal(a, b) for a, b in zip(arm.gains, before, strict=True))


def test_an_impedance_target_past_a_joint_limit_or_a_wall_is_refused(channel: str) -> None:
    upper = np.array([j.limits.upper for j in ARM6G.joints])
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, sim):
        with arm.impedance(joint_stiffness=[20.0] * 6) as imp:
            arm.sleep(0.1)
            past = READY.copy()
            past[5] = upper[5] + 0.3
            with pytest.raises(LimitError, match="limit") as info:
                imp.set_target(past)
            assert info.value.joint == ARM6G.joints[5].name
            arm.sleep(1.0)
            assert np.abs(sim.q - READY).max() < 0.01  # nothing moved
        assert arm.enabled and arm.fault is None
    p = FK.tool_pose(READY)[:3, 3]
    walled = dataclasses.replace(ARM6G, workspace=Workspace.box([-1.0, -1.0, -0.2], [1.0, 1.0, p[2] + 0.02]))
    with lockstep_arm(walled, channel + "-w", q0=READY, enable=True) as (arm, sim):
        with arm.impedance(stiffness=SOFT) as imp:
            arm.sleep(0.1)
            up = arm.tool_pose()
            up[2, 3] += 0.06  # 40 mm through the ceiling
            with pytest.raises(LimitError, match="outside the workspace"):
                imp.set_target(up)
            arm.sleep(1.0)
            assert abs(FK.tool_pose(sim.q)[2, 3] - p[2]) < 0.003  # nothing moved
        assert arm.enabled and arm.fault is None


def test_a_gripper_fault_ends_impedance_and_servoing_and_their_handles_refuse(channel: str) -> None:
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, sim):
        gains = arm.gains
        sim.place_object(0.03)
        assert arm.gripper is not None and arm.gripper.close(force=20.0).grasped
        with pytest.raises(MotorFault), arm.impedance(stiffness=SOFT) as imp:
            arm.sleep(0.3)
            assert 16.0 <= sim.object_force() <= 24.0  # kp = 0 on the arm's joints only: the grasp holds
            sim.joint("gripper").inject(faults.ErrorCode(2))
            arm.sleep(0.2)
        assert not arm.enabled
        for command in (lambda: imp.set_target(arm.tool_pose()), lambda: imp.set_stiffness(SOFT),
                        lambda: arm.gripper.open()):
            with pytest.raises(MotorFault):
                command()  # the stop, named, until an enable acknowledges it
        assert all(np.array_equal(a, b) for a, b in zip(arm.gains, gains, strict=True))  # restored
    with lockstep_arm(ARM6G, channel + "-s", q0=READY, enable=True) as (arm, sim):
        with pytest.raises(MotorFault), arm.servo() as s:
            for k in range(60):
                s.twist([0.05, 0.0, 0.0, 0.0, 0.0, 0.0])
                arm.sleep(0.01)
                if k == 20:
                    sim.joint("gripper").inject(faults.ErrorCode(2))
        assert not arm.enabled
        with pytest.raises(MotorFault):
            s.twist([0.05, 0.0, 0.0, 0.0, 0.0, 0.0])
        assert not arm.mode.powered  # limp, nothing re-enabled


def test_an_impedance_target_out_of_reach_is_refused_before_anything_moves(channel: str) -> None:
    # (it was taken: the spring pulled the arm toward it until the deviation passed its bound, a stop)
    with lockstep_arm(ARM6G, channel, q0=READY, enable=True) as (arm, sim):
        with arm.impedance(stiffness=SOFT) as imp:
            arm.sleep(0.1)
            far = arm.tool_pose()
            far[0, 3] += 1.0  # a metre further out than the arm reaches
            with pytest.raises(UnreachableError):
                imp.set_target(far)
            arm.sleep(1.5)
            assert np.abs(sim.q - READY).max() < 0.01  # nothing moved
            near = arm.tool_pose()
            near[2, 3] += 0.02
            imp.set_target(near)  # one in reach is taken
            arm.sleep(1.0)
            assert abs(FK.tool_pose(sim.q)[2, 3] - near[2, 3]) < 0.003
        assert arm.enabled and arm.fault is None


def test_arm6g_servos_to_a_wall_and_makes_a_guarded_move_while_its_gripper_closes_and_holds(channel: str) -> None:
    p = FK.tool_pose(READY)[:3, 3]
    ceiling = p[2] + 0.02
    walled = dataclasses.replace(ARM6G, workspace=Workspace.box([-1.0, -1.0, -0.2], [1.0, 1.0, ceiling]))
    with lockstep_arm(walled, channel, q0=READY, enable=True, self_collision="capsules") as (arm, sim):
        assert arm.gripper is not None
        sim.place_object(0.03)
        arm.gripper.close(force=20.0, wait=False)
        with arm.servo() as s:
            for _ in range(150):
                s.twist([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
                arm.sleep(0.01)
            assert s.status.state == "stopped" and s.status.reason == "wall"
        assert -0.005 < FK.tool_pose(sim.q)[2, 3] - ceiling < 0.0  # stopped short of it
        assert arm.gripper.state().grasped and 16.0 <= sim.object_force() <= 24.0
        contact = arm.move_until_contact([0.0, 0.0, -1.0], speed=0.02, force=5.0, max_distance=0.04)
        assert not contact.touched and abs(contact.distance - 0.04) < 0.003
        assert arm.gripper.state().grasped and 16.0 <= sim.object_force() <= 24.0
        assert arm.enabled and arm.fault is None
