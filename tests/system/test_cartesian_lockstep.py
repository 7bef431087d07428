"""Cartesian moves: to poses and along straight lines, and the refusals before motion (poses and
inverse kinematics on their own: tests/unit/test_cartesian.py).

The motion tests run arm6 (and planar2) against the simulator in lock step and measure the tool's
pose from the *simulator's* joint positions (the plant's truth, not the replies the arm reads).
"""

from __future__ import annotations

import math
from contextlib import AbstractContextManager

import numpy as np
import pinocchio as pin
import pytest

import akarm
from akarm.arm import Arm
from akarm.dynamics.ik import make_pose, pose_error, quaternion
from akarm.errors import LimitError, SingularityError, StateError, UnreachableError
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
PLANAR2 = akarm.load_robot(ROBOTS / "planar2.yaml")


def lockstep(config, channel: str, q0) -> AbstractContextManager[tuple[Arm, SimulatedRobot]]:
    """The shared lock-step arm (tests/conftest.py), enabled at ``q0``."""
    return lockstep_arm(config, channel, q0=q0, enable=True)


def sim_pose(sim: SimulatedRobot) -> np.ndarray:
    return sim.model.tool_pose(sim.q)


def line_deviation(arm: Arm, sim: SimulatedRobot, motion, p0: np.ndarray, p1: np.ndarray) -> float:
    """The largest distance (m) of the simulator's tool position from the line p0-p1, every cycle."""
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    worst = 0.0
    while not motion.done:
        arm.sleep(1.0 / arm.config.rate_hz)
        d = sim_pose(sim)[:3, 3] - p0
        worst = max(worst, float(np.linalg.norm(d - (d @ u) * u)))
    return worst


# ------------------------------------------------------------------------------------------------
# moves on the simulator
# ------------------------------------------------------------------------------------------------
def test_tool_pose_is_the_pose_at_the_measured_joints(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        assert np.allclose(arm.tool_pose(), sim_pose(sim), atol=2e-3)
        assert np.allclose(arm.tool_pose(ARM6.pose("ready")), sim.model.tool_pose(ARM6.pose("ready")))


def test_move_to_pose_arrives_within_a_millimetre_and_a_hundredth_of_a_radian(channel: str) -> None:
    target = make_pose([0.40, 0.20, 0.50], rpy=[0.0, 2.0, 0.3])
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        arm.move_to_pose(target)
        arm.sleep(0.3)
        dp, dr = pose_error(sim_pose(sim), target)
        assert dp < 1e-3 and dr < 0.01
        # a position alone: the orientation stays
        before = sim_pose(sim)
        arm.move_to_pose(([0.30, -0.20, 0.60], quaternion(before)))
        arm.move_to_pose([0.35, -0.10, 0.55], speed=0.5)
        arm.sleep(0.3)
        after = sim_pose(sim)
        assert np.linalg.norm(after[:3, 3] - [0.35, -0.10, 0.55]) < 1e-3
        assert pose_error(after, before)[1] < 0.01


def test_move_linear_stays_within_a_millimetre_of_the_line(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        start = arm.tool_pose()
        target = start.copy()
        target[:3, 3] += [0.10, 0.15, -0.20]
        target[:3, :3] = start[:3, :3] @ pin.rpy.rpyToMatrix(0.2, 0.0, 0.3)
        motion = arm.move_linear(target, wait=False)
        deviation = line_deviation(arm, sim, motion, start[:3, 3], target[:3, 3])
        arm.sleep(0.3)
        dp, dr = pose_error(sim_pose(sim), target)
    assert deviation < 1e-3, f"{deviation * 1e3:.2f} mm off the line"
    assert dp < 1e-3 and dr < 0.01


def test_move_linear_respects_every_joint_limit_at_every_speed(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        target = arm.tool_pose()
        target[:3, 3] += [0.0, 0.30, -0.10]
        for speed in (1.0, 0.3):
            plan = akarm.motion.cartesian.plan_linear(arm.ik, arm.limits, arm.state().q_des, target, speed=speed)
            _, q, v, a, j = plan.joint_profile()
            lim = arm.limits
            assert np.all(np.abs(v) <= lim.velocity * speed * (1 + 1e-6))
            assert np.all(np.abs(a) <= lim.acceleration * speed**2 * (1 + 1e-6))
            assert np.all(np.abs(j) <= lim.jerk * speed**3 * (1 + 1e-6))
            # one of them is at its limit: the line is as fast as the joints allow
            top = max(np.max(np.abs(v) / lim.velocity) / speed, np.max(np.abs(a) / lim.acceleration) / speed**2,
                      np.max(np.abs(j) / lim.jerk) / speed**3)
            assert top > 0.97
        capped = akarm.motion.cartesian.plan_linear(arm.ik, arm.limits, arm.state().q_des, target, max_velocity=0.05)
        assert capped.duration > 0.316 / 0.05  # 0.316 m at 5 cm/s at most


def _nothing_moved(arm: Arm, sim: SimulatedRobot, q_before: np.ndarray) -> None:
    """No motion was started: the command is where enable() held the arm, the arm still there."""
    arm.sleep(0.2)
    assert not arm.moving
    log = arm.telemetry()
    assert np.all(np.ptp(log.q_des[log.t > 0.45], axis=0) == 0.0)  # after enable's ramp: not one change
    assert np.allclose(arm.state().q_des, q_before, atol=1e-3)
    assert np.allclose(sim.q, q_before, atol=3e-3)


def test_unreachable_poses_and_paths_through_limits_are_refused_with_nothing_moved(channel: str) -> None:
    home = np.array(ARM6.pose("home"))
    with lockstep(ARM6, channel, home) as (arm, sim):
        start = arm.tool_pose()
        far = start.copy()
        far[:3, 3] = [1.5, 0.0, 0.4]
        with pytest.raises(UnreachableError):
            arm.move_to_pose(far)
        with pytest.raises(UnreachableError) as e:
            arm.move_linear(far)
        assert "along the line" in str(e.value)
        _nothing_moved(arm, sim, home)

    # the tool turned 0.8 rad about its own axis with wrist_roll at 2.6 rad: the line needs 3.4 rad,
    # past the joint's 3.0 (the same pose is fine by a joint-space move: wrist_roll -2.88 rad)
    q0 = home.copy()
    q0[5] = 2.6
    with lockstep(ARM6, channel + "-b", q0) as (arm, sim):
        target = arm.tool_pose(q0) @ make_pose([0, 0, 0], rpy=[0, 0, 0.8])
        with pytest.raises(LimitError) as e:
            arm.move_linear(target)
        assert e.value.joint == "wrist_roll" and "along the line" in str(e.value)
        _nothing_moved(arm, sim, q0)
        arm.move_to_pose(target)
        assert arm.state().q_des[5] == pytest.approx(2.6 + 0.8 - 2 * math.pi, abs=1e-3)


def test_a_line_through_a_singularity_is_refused(channel: str) -> None:
    ready = np.array(ARM6.pose("ready"))  # wrist_pitch 0: forearm_roll and wrist_roll in line
    with lockstep(ARM6, channel, ready) as (arm, sim):
        sideways = arm.tool_pose()
        sideways[1, 3] += 0.1  # needs a turn about the axis the aligned wrist cannot turn about
        with pytest.raises(SingularityError) as e:
            arm.move_linear(sideways)
        assert "singular" in str(e.value)
        _nothing_moved(arm, sim, ready)
        forward = arm.tool_pose()
        forward[0, 3] += 0.1  # along the forearm: fine at the same pose
        arm.move_linear(forward)


def test_move_linear_starts_from_rest(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        arm.move_to("ready", wait=False)
        arm.sleep(0.1)
        with pytest.raises(StateError):
            arm.move_linear([0.5, 0.0, 0.5])


def test_planar2_moves_to_positions_and_along_lines(channel: str) -> None:
    with lockstep(PLANAR2, channel, PLANAR2.pose("home")) as (arm, sim):
        arm.move_to_pose([0.30, 0.0, 0.40])
        arm.sleep(0.3)
        assert np.linalg.norm(sim_pose(sim)[:3, 3] - [0.30, 0.0, 0.40]) < 1e-3
        start = sim_pose(sim)[:3, 3]
        end = np.array([0.45, 0.0, 0.20])
        motion = arm.move_linear(end, wait=False)
        deviation = line_deviation(arm, sim, motion, start, end)
        arm.sleep(0.3)
        assert deviation < 1e-3 and np.linalg.norm(sim_pose(sim)[:3, 3] - end) < 1e-3
