"""Servoing (``arm.servo()``): twists and poses followed live, slowing and stopping near a singularity,
a joint limit and a wall, at rest when commands stop.

Lock step on arm6; the tool is measured with the test's own forward kinematics (a model of its own)
from the simulator's joint angles.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

import akarm
from akarm.config.workspace import Workspace
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, CollisionError, StateError

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FK = RobotModel(ARM6)
V_MAX = np.array([j.limits.velocity for j in ARM6.joints])
LOWER = np.array([j.limits.lower for j in ARM6.joints])
UPPER = np.array([j.limits.upper for j in ARM6.joints])


def tool(sim: akarm.sim.SimulatedRobot) -> np.ndarray:
    return FK.tool_pose(sim.q)


def servo_for(arm: akarm.Arm, s: akarm.motion.servo.Servo, twist: list[float], seconds: float, sim=None,
              every: float = 0.01) -> float:
    """Send ``twist`` every ``every`` s for ``seconds`` of the arm's clock; the largest measured joint speed
    as a share of its limit."""
    end = arm.clock.now() + seconds
    worst = 0.0
    while arm.clock.now() < end - 1e-9:
        s.twist(twist)
        arm.sleep(every)
        if sim is not None:
            worst = max(worst, float(np.max(np.abs(sim.dq) / V_MAX)))
    return worst


def until_rest(arm: akarm.Arm, sim, limit: float = 1.0, speed: float = 0.01) -> float:
    """s until every simulated joint is slower than ``speed`` rad/s and the command at rest."""
    start = arm.clock.now()
    while arm.clock.now() - start < limit:
        arm.sleep(1.0 / arm.config.rate_hz)
        if np.max(np.abs(sim.dq)) < speed and np.max(np.abs(arm.telemetry(arm.clock.now() - 0.01).dq_des[-1])) < 1e-6:
            return arm.clock.now() - start
    return np.inf


def test_a_second_of_twist_up_rises_50_mm_straight_then_comes_to_rest(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        start = tool(sim)
        with arm.servo(timeout=0.1) as s:
            worst = servo_for(arm, s, [0.0, 0.0, 0.05, 0.0, 0.0, 0.0], 1.0, sim)
            after = tool(sim)
            assert s.status.state == "ok"
            rest = until_rest(arm, sim)
            assert s.status.state == "stopped" and s.status.reason == "no command"
            end = tool(sim)
        rise = after[2, 3] - start[2, 3]
        sideways = float(np.linalg.norm(after[:2, 3] - start[:2, 3]))
        turned = float(np.linalg.norm(pin.log3(after[:3, :3] @ start[:3, :3].T)))
        assert 0.045 <= rise <= 0.055, f"rose {rise * 1e3:.1f} mm"
        assert sideways < 0.003 and turned < 0.02
        assert rest <= 0.3, f"at rest {rest:.3f} s after the last command"
        assert np.linalg.norm(end[:2, 3] - start[:2, 3]) < 0.003  # (it went on for the timeout, up)
        assert worst < 1.0
        log = arm.telemetry()
        assert np.all(np.abs(log.dq_des) <= V_MAX * (1 + 1e-9))
        assert arm.enabled and arm.fault is None


def test_servoing_into_the_stretched_arm_slows_and_stops_short_of_the_singularity(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with arm.servo(timeout=0.1) as s:
            worst = servo_for(arm, s, [0.15, 0.0, 0.0, 0.0, 0.0, 0.0], 4.0, sim)
            assert s.status.state == "stopped" and s.status.reason == "singularity"
            assert until_rest(arm, sim) < 0.3
        assert arm.enabled and arm.fault is None
        log = arm.telemetry()
        assert np.all(log.q_des >= LOWER) and np.all(log.q_des <= UPPER)
        assert np.all(np.abs(log.dq_des) <= V_MAX * (1 + 1e-9)) and worst < 1.0
        assert np.max(np.abs(sim.dq)) < 0.01
        sigma = np.linalg.svd(FK.jacobian(sim.q)[:3], compute_uv=False)[-1]
        assert sigma > 0.01  # stopped before the singular pose (elbow straight: 0)
        assert abs(sim.q[2]) > 0.04


def test_servoing_up_under_a_wall_stops_within_5_mm_of_it(channel: str) -> None:
    top = FK.tool_pose(READY)[2, 3] + 0.03
    config = dataclasses.replace(ARM6, workspace=Workspace.box([-1.5, -1.5, -0.5], [1.5, 1.5, top]))
    with lockstep_arm(config, channel, q0=READY, enable=True) as (arm, sim):
        with arm.servo(timeout=0.1) as s:
            servo_for(arm, s, [0.0, 0.0, 0.05, 0.0, 0.0, 0.0], 1.5)
            assert s.status.state == "stopped" and s.status.reason == "wall"
            z = tool(sim)[2, 3]
            # and away from the wall it goes again, at once
            servo_for(arm, s, [0.0, 0.0, -0.05, 0.0, 0.0, 0.0], 0.2)
            assert s.status.state == "ok"
        assert top - 0.005 <= z <= top + 0.001, f"{(top - z) * 1e3:.1f} mm under the wall"
        assert arm.fault is None


def test_a_joint_stops_at_its_range_less_the_margin_and_says_so(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        y_tool = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]  # pitch about the tool's y: the wrist pitch turns
        with arm.servo(timeout=0.1, frame="tool", max_rotation=1.5) as s:
            servo_for(arm, s, y_tool, 3.0)
            assert s.status.state == "stopped" and s.status.reason == "joint limit"
            joint = s.status.joint
        assert joint == "wrist_pitch"
        k = ARM6.joint_names.index(joint)
        log = arm.telemetry()
        assert np.all(log.q_des[:, k] <= UPPER[k]) and np.all(log.q_des[:, k] >= LOWER[k])
        assert 0.03 < UPPER[k] - sim.q[k] < 0.07  # its range less the 0.05 rad margin
        assert arm.fault is None


def test_a_pose_is_tracked_and_a_pause_resumes_smoothly(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        goal = FK.tool_pose(READY)
        goal[:3, 3] += [-0.05, 0.0, 0.04]  # (a pan would need the wrist far from its singular `ready`)
        with arm.servo(timeout=0.1) as s:
            for _ in range(60):
                s.pose(goal)
                arm.sleep(0.01)
            assert np.linalg.norm(tool(sim)[:3, 3] - goal[:3, 3]) < 0.002
            arm.sleep(0.3)  # no commands: at rest, held
            servo_for(arm, s, [0.0, 0.05, 0.0, 0.0, 0.0, 0.0], 0.3)
        log = arm.telemetry()
        acc = np.diff(log.dq_des, axis=0) * arm.config.rate_hz
        a_max = np.array([j.limits.acceleration for j in ARM6.joints])
        assert np.all(np.abs(acc) <= a_max * 1.01)  # resumed without a jump


def test_servo_arguments_and_states_are_checked(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY) as (arm, _sim):
        with pytest.raises(StateError):
            arm.servo()
        arm.enable()
        for bad in ({"timeout": 0.0}, {"frame": "world"}, {"max_speed": float("nan")}):
            with pytest.raises(ArgumentError):
                arm.servo(**bad)
        with arm.servo() as s:
            with pytest.raises(ArgumentError, match="6 finite numbers"):
                s.twist([0.0, 0.0, 0.1])
            with pytest.raises(ArgumentError):
                s.twist([0.0, 0.0, float("inf"), 0.0, 0.0, 0.0])
            s.twist([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
            arm.sleep(0.05)
            arm.move_to("ready")  # another motion ends servoing
            with pytest.raises(StateError, match="servoing ended"):
                s.twist([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])


def test_a_stream_taking_over_late_is_moved_itself_and_still_ends() -> None:
    """A plan from rest takes over later than planned (real time): the stream moves its own start, so the
    end it sets when it comes to rest is the one the controller sees (a wrapper kept its endless one)."""
    from akarm.motion.servo import ServoStream
    from akarm.motion.trajectory import JointLimits

    lim = [j.limits for j in ARM6.joints]
    limits = JointLimits(ARM6.joint_names, LOWER, UPPER, V_MAX, np.array([x.acceleration for x in lim]),
                         np.array([x.jerk for x in lim]))
    s = ServoStream(FK, limits, None, 1 / 480, 0.1, "base", 0.25, 1.0)
    assert s.begin((READY, np.zeros(6), np.zeros(6)), 1.0).shifted(0.25) is s
    assert s.t0 == 1.25 and s.last == 1.25
    s.command_twist(np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.0]), 1.25)
    for k in range(1, 100):
        s.sample(1.25 + k / 480)
    s.finish()
    k = 100
    while not s.done(1.25 + k / 480) and k < 1000:
        s.sample(1.25 + k / 480)
        k += 1
    assert s.done(1.25 + k / 480) and np.all(s.v == 0.0)


def test_a_stop_inside_the_block_is_raised_when_the_block_ends_normally(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        with pytest.raises(CollisionError), arm.servo(timeout=0.1) as s:
            s.twist([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
            push = np.zeros(6)
            push[2] = 6.0  # the elbow hit: past its 1.1 N·m threshold
            sim.set_external_torque(push)
            arm.clock.sleep_until(arm.clock.now() + 1.0)  # the clock goes on; nothing in the block asks the arm
        assert not arm.enabled and isinstance(arm.fault, CollisionError)
        sim.set_external_torque(None)
        arm.enable()
        with pytest.raises(ZeroDivisionError), arm.servo(timeout=0.1) as s:  # an exception leaving it: unchanged
            s.twist([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
            sim.set_external_torque(push)
            arm.clock.sleep_until(arm.clock.now() + 1.0)
            _ = 1 / 0
