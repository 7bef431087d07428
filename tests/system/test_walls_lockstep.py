"""Walls (the robot file's ``workspace:``): refused plans, the measured-pose stop (reading them:
tests/unit/test_workspace.py).

Lock step on arm6; the tool measured with the test's own forward kinematics from the simulator's joints.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import akarm
from akarm.config.workspace import Workspace
from akarm.errors import LimitError, WorkspaceExit

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))


def ready_xyz() -> np.ndarray:
    from akarm.dynamics.model import RobotModel

    return RobotModel(ARM6).tool_pose(READY)[:3, 3]


def walled(top_above_ready: float = 0.03, margin: float = 0.02) -> akarm.RobotConfig:
    """arm6 in a box whose top is ``top_above_ready`` m above the tool at ``ready``."""
    p = ready_xyz()
    return dataclasses.replace(ARM6, workspace=Workspace.box([-1.0, -1.0, -0.2], [1.0, 1.0, p[2] + top_above_ready],
                                                             margin))


def test_a_move_to_pose_above_the_box_is_refused_with_nothing_moving(channel: str) -> None:
    with lockstep_arm(walled(0.03), channel, q0=READY, enable=True) as (arm, sim):
        target = arm.tool_pose(READY)
        target[:3, 3] += [0.0, 0.0, 0.06]  # 30 mm over the top
        q_before = arm.state().q_des.copy()
        with pytest.raises(LimitError, match="outside the workspace"):
            arm.move_to_pose(target)
        arm.sleep(0.2)
        assert not arm.moving
        assert np.array_equal(arm.state().q_des, q_before)
        assert np.allclose(sim.q, READY, atol=3e-3)
        # inside the box: it goes; a stop is never refused
        target[:3, 3] -= [0.0, 0.0, 0.05]
        arm.move_to_pose(target)
        assert np.linalg.norm(sim.model.tool_pose(sim.q)[:3, 3] - target[:3, 3]) < 2e-3
        arm.stop()


def test_a_joint_move_whose_path_leaves_the_box_is_refused(channel: str) -> None:
    with lockstep_arm(walled(0.03), channel, q0=READY, enable=True) as (arm, _sim):
        up = READY.copy()
        up[2] -= 0.6  # the elbow straightens: the tool rises far over the top
        with pytest.raises(LimitError, match="outside the workspace"):
            arm.move_to(up)
        assert not arm.moving


def test_an_arm_pushed_out_of_the_box_is_a_named_safety_stop(channel: str) -> None:
    with lockstep_arm(walled(0.005, margin=0.01), channel, q0=READY, enable=True) as (arm, sim):
        arm.set_collision([None] * 6)  # the push is the point here, not a collision
        arm.set_gains(kp=[20.0] * 6)
        up = np.zeros(6)
        up[1] = -3.0  # the shoulder pushed back: the tool rises
        sim.set_external_torque(up)
        with pytest.raises(WorkspaceExit, match="outside the workspace") as info:
            arm.sleep(2.0)
        assert info.value.distance > 0.01 and info.value.margin == 0.01
        assert not arm.enabled
