"""Timing profiles (akarm.timing): what normal keeps and what slow changes, in the Arm, the simulator
and the verbs. In lock step, so the watchdog's and the enable's limits show exactly."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from akarm import Arm, FeedbackTimeout, load_robot
from akarm.control.controller import RELEASES
from akarm.sim import SimulatedRobot, faults
from akarm.timing import PROFILES

from .conftest import ROBOTS, lockstep_arm

PLANAR2 = ROBOTS / "planar2.yaml"
SERVO3 = ROBOTS / "servo3.yaml"
HANGING = [-math.pi / 2, 0.0]


@pytest.mark.parametrize(("robot", "joint", "profile", "options", "limit_ms"), [
    (PLANAR2, "elbow", "normal", {}, 20), (PLANAR2, "elbow", "slow", {}, 1000),
    (SERVO3, "pan", "normal", {}, 15), (SERVO3, "pan", "slow", {}, 1000),         # the file's own 15 ms
    (PLANAR2, "elbow", "normal", {"feedback_timeout": 0.1}, 100),
    (PLANAR2, "elbow", "slow", {"feedback_timeout": 0.1}, 1000),                  # not below the profile's
], ids=["planar2-normal", "planar2-slow", "servo3-normal", "servo3-slow", "arg-normal", "arg-slow"])
def test_the_watchdog_of_each_profile_stops_the_arm_at_its_limit(channel: str, robot: Path, joint: str, profile: str,
                                                                  options: dict, limit_ms: int) -> None:
    config = load_robot(robot).with_bus(interface="virtual", channel=channel)
    q0 = HANGING if robot == PLANAR2 else None
    with SimulatedRobot(config, realtime=False, q0=q0, timing=profile) as sim, \
            Arm(config, clock=sim.clock, timing=profile, **options) as arm:
        assert arm.timing is PROFILES[profile]
        assert arm.config.rate_hz == (config.rate_hz if profile == "normal" else 25.0)
        arm.enable()
        sim.inject(joint, faults.Unplugged())
        t0 = arm.clock.now()
        with pytest.raises(FeedbackTimeout, match=f"{joint}.*limit {limit_ms} ms") as stop:
            arm.sleep(3.0)
        assert limit_ms / 1e3 < stop.value.age <= limit_ms / 1e3 + 2.0 / arm.config.rate_hz
        # then the 0.3 s stop, and the exit frames on RELEASES cycles
        assert arm.clock.now() - t0 < limit_ms / 1e3 + 0.3 + 0.1 + RELEASES / arm.config.rate_hz


@pytest.mark.parametrize(("profile", "wait_ms"), [("normal", 500), ("slow", 5000)])
def test_enable_waits_for_the_first_answers_as_long_as_the_profile_says(channel: str, profile: str,
                                                                          wait_ms: int) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False, q0=HANGING) as sim, Arm(config, clock=sim.clock, timing=profile) as arm:
        sim.inject("shoulder", faults.Unplugged())
        with pytest.raises(FeedbackTimeout, match=f"no answer within {wait_ms} ms from: shoulder"):
            arm.enable()
        assert not sim.joint("elbow").enabled                 # nothing was enabled


def test_the_slow_profile_still_tracks(channel: str) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with lockstep_arm(config, channel, q0=HANGING, timing="slow") as (arm, sim):
        assert sim.dt == pytest.approx(1 / 250)
        arm.enable()
        arm.move_to("up")
        arm.sleep(0.5)
        assert np.allclose(sim.q, config.pose("up"), atol=5e-3)
        log = arm.telemetry()
        assert np.diff(log.t).max() == pytest.approx(0.04)   # 25 Hz


def test_the_simulator_integrates_at_the_profiles_rate_unless_told(channel: str) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    assert SimulatedRobot(config, realtime=False).dt == pytest.approx(0.0005)
    assert SimulatedRobot(config, realtime=False, timing="slow").dt == pytest.approx(0.004)
    assert SimulatedRobot(config, realtime=False, timing="slow", dt=0.001).dt == pytest.approx(0.001)


@pytest.mark.parametrize(("lag", "stops"), [(0.25, False), (0.0, True)])
def test_the_slow_profiles_lag_lets_a_late_simulator_run_a_fast_move(channel: str, lag: float, stops: bool) -> None:
    """Replies 0.15 s late read as a joint still at rest while its command is under way (planar2's shoulder:
    stuck travel 27 mrad), then as one up to 0.6 rad behind at 4 rad/s (following-error limit 18 N·m /
    40 N·m/rad = 0.45 rad); the profile's lag (0.25 s × 4 rad/s) widens both."""
    from akarm import TrackingError

    profile = replace(PROFILES["slow"], lag=lag)
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    late = {name: faults.DelayReplies(0.15) for name in config.joint_names}
    with lockstep_arm(config, channel, q0=HANGING, timing=profile, sim_options={"faults": late}) as (arm, sim):
        arm.enable()
        if stops:
            with pytest.raises(TrackingError, match="shoulder"):
                arm.move_to("up")
        else:
            arm.move_to("up")
            arm.sleep(1.0)
            assert np.allclose(sim.q, config.pose("up"), atol=0.01)


@pytest.mark.parametrize(("lag", "delay"), [(1.0, 0.5), (0.0, 0.04)])
def test_a_move_returns_when_late_readings_show_the_arm_there(channel: str, lag: float, delay: float) -> None:
    """Readings 0.5 s late (a simulator that cannot keep time): with the slow profile's lag, move_to
    returns once they show every joint at its target; without a lag (where readings 0.5 s late stop the
    arm) it returns at the plan's end."""
    from akarm.arm import ARRIVED

    profile = replace(PROFILES["slow"], lag=lag)
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    late = {name: faults.DelayReplies(delay) for name in config.joint_names}
    target = np.array(config.pose("up"))
    with lockstep_arm(config, channel, q0=HANGING, timing=profile, sim_options={"faults": late}) as (arm, sim):
        arm.enable()
        motion = arm.move_to("up", speed=0.5)
        behind = arm.clock.now() - motion.plan.t_end
        error = np.abs(arm.state().q - target).max()
        if lag:
            assert error < ARRIVED
            assert 0.3 < behind < 2.0 * lag       # about the replies' delay: not the whole window
        else:
            assert behind < 0.05                  # not a cycle more
