"""arm.gripper in lock step on the simulator (issue 36's acceptance): arm6g's AK40-10 gripper, 80 mm
of stroke over 2 rad, a 40 N limit. Widths and squeezes are the simulator's own (the truth), never
the controller's estimate alone."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import akarm
from akarm import ArgumentError, FeedbackTimeout, Gripper, GripperState, MotorFault, StateError
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS


def gripper_of(arm: object) -> Gripper:
    g = arm.gripper  # type: ignore[attr-defined]
    assert isinstance(g, Gripper)
    return g


def close_watching(arm: object, sim: SimulatedRobot, force: float | None) -> tuple[GripperState, float]:
    """Close (without waiting), then follow the move cycle by cycle: its end state and the largest
    squeeze the simulator saw on the way."""
    g = gripper_of(arm)
    g.close(force=force, wait=False)
    peak = 0.0
    for _ in range(2000):
        arm.sleep(0.0025)  # type: ignore[attr-defined]
        peak = max(peak, sim.object_force())
        s = g.state()
        if not s.moving:
            return s, peak
    raise AssertionError("the close did not end")


def test_open_and_move_to_end_within_a_millimetre(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        g = gripper_of(arm)
        assert (g.name, g.stroke, g.force_limit) == ("gripper", 0.08, 40.0)
        assert arm.state().q.shape == (6,)  # the arm's vectors keep the arm's joints only
        s = g.open()
        assert abs(sim.gripper_width() - 0.08) < 0.001 and not s.moving and not s.grasped
        for w in (0.05, 0.012, 0.07):
            s = g.move_to(w)
            assert abs(sim.gripper_width() - w) < 0.001, (w, sim.gripper_width())
            assert abs(s.width - sim.gripper_width()) < 1e-4 and s.target == pytest.approx(w)
        log = g.telemetry(since=arm.clock.now() - 0.5)  # the per-cycle record, beside arm.telemetry()
        assert 190 <= len(log.t) <= 201 and np.all(np.diff(log.t) > 0)  # 400 Hz
        assert log.width[-1] == pytest.approx(sim.gripper_width(), abs=1e-4) and log.target[-1] == pytest.approx(0.07)


def test_close_on_an_object_holds_it_at_the_force_asked(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        g = gripper_of(arm)
        g.open()
        sim.place_object(0.03)
        s, peak = close_watching(arm, sim, 20.0)
        assert s.grasped and not s.moving
        assert abs(sim.gripper_width() - 0.03) < 0.002
        assert peak <= 22.0, peak  # never more than 10 % over the force asked
        squeeze = []
        for _ in range(int(2.5 / 0.0025)):  # 2.5 s of holding, every cycle
            arm.sleep(0.0025)
            squeeze.append(sim.object_force())
        assert min(squeeze) >= 16.0 and max(squeeze) <= 24.0, (min(squeeze), max(squeeze))
        s = g.state()
        assert s.grasped and abs(s.force - sim.object_force()) < 1.0  # the estimate matches the truth
        assert 25.0 <= s.temperature < 30.0  # reported


def test_the_force_limit_is_never_passed(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        g = gripper_of(arm)
        sim.place_object(0.03)
        before = sim.gripper_width()
        with pytest.raises(ArgumentError) as info:
            g.close(force=60.0)  # over the 40 N limit: refused, nothing moves
        assert info.value.joint == "gripper"
        arm.sleep(0.2)
        assert sim.gripper_width() == pytest.approx(before, abs=2e-4) and sim.object_force() == 0.0
        s, peak = close_watching(arm, sim, 40.0)
        squeeze = []
        for _ in range(200):
            arm.sleep(0.0025)
            squeeze.append(sim.object_force())
        assert s.grasped and max(peak, *squeeze) <= 44.0, (peak, max(squeeze))


def test_an_empty_close_ends_closed_and_is_no_grasp(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        s = gripper_of(arm).close()
        assert not s.grasped and sim.gripper_width() < 0.001 and s.width < 0.001


def test_bad_input_is_refused_and_nothing_moves(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        g = gripper_of(arm)
        before = sim.gripper_width()
        target = sim.joint("gripper").stored_command.position  # type: ignore[attr-defined]
        for width, force in [(0.081, None), (-0.001, None), (math.nan, None), ("wide", None), (0.03, -1.0),
                             (0.03, math.nan), (0.03, 40.1)]:
            with pytest.raises(ArgumentError) as info:
                g.move_to(width, force)  # type: ignore[arg-type]
            assert info.value.joint == "gripper" and info.value.fix
        arm.sleep(0.2)
        assert sim.gripper_width() == pytest.approx(before, abs=2e-4)
        assert sim.joint("gripper").stored_command.position == target  # type: ignore[attr-defined]
        assert not g.state().moving


def test_the_gripper_going_silent_while_holding_is_a_named_stop_within_50_ms(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        sim.place_object(0.03)
        assert gripper_of(arm).close(force=20.0).grasped
        t = arm.clock.now()
        sim.joint("gripper").inject(faults.Unplugged())
        with pytest.raises(FeedbackTimeout) as info:
            arm.sleep(0.5)
        assert info.value.joint == "gripper" and info.value.at - t <= 0.050, info.value.at - t
        assert not arm.enabled


def test_a_motor_fault_on_the_gripper_stops_the_arm_and_names_it(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        sim.joint("gripper").inject(faults.ErrorCode(2))
        with pytest.raises(MotorFault) as info:
            arm.sleep(0.1)
        assert info.value.joint == "gripper"


def test_disable_opens_nothing(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        sim.place_object(0.03)
        gripper_of(arm).close(force=20.0)
        arm.disable(wait=False)
        squeeze = []
        while arm.mode.powered:
            arm.sleep(0.0025)
            squeeze.append(sim.object_force())
        assert min(squeeze[:-5]) > 16.0  # held while the arm was damped
        assert sim.gripper_width() < 0.0305  # limp: the object springs the jaws back, no more
        with pytest.raises(StateError):
            gripper_of(arm).open()  # nothing moves a disabled gripper


def test_calibrate_finds_closed_after_the_motor_lost_its_zero(channel: str) -> None:
    config = akarm.load_robot(ROBOTS / "arm6g.yaml").with_bus(interface="virtual", channel=channel)
    assert config.gripper is not None
    lost = replace(config, gripper=replace(config.gripper, offset=0.3))  # the file says 0.3 rad too far
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(lost, clock=sim.clock) as arm:
        arm.enable()
        g = gripper_of(arm)
        assert abs(g.state().width - sim.gripper_width() - 0.012) < 1e-3  # 0.3 rad at 40 mm/rad off
        with pytest.warns(UserWarning, match="set `offset: 0.000"):
            offset = g.calibrate()
        assert offset == pytest.approx(0.3, abs=0.005)
        g.move_to(0.04)
        assert abs(sim.gripper_width() - 0.04) < 0.001 and abs(g.state().width - 0.04) < 0.001


def test_the_gripper_works_while_the_arm_moves(lockstep) -> None:
    with lockstep("arm6g", enable=True) as (arm, sim):
        motion = arm.move_to("ready", wait=False)
        s = gripper_of(arm).close()
        assert not motion.done  # closed while the arm was still on its way
        motion.wait()
        assert not s.grasped and sim.gripper_width() < 0.001
        assert np.abs(arm.state().q - arm.config.pose("ready")).max() < 0.01


def test_without_a_gripper_there_is_none(lockstep) -> None:
    with lockstep("planar2") as (arm, sim):
        assert arm.gripper is None


def test_a_hot_gripper_motor_is_a_named_stop(channel: str) -> None:
    """Holding at the limit heats the AK40-10 (the temperature is reported); past the gripper's
    max_temperature the supervisor stops the arm and names the gripper."""
    config = akarm.load_robot(ROBOTS / "arm6g.yaml").with_bus(interface="virtual", channel=channel)
    assert config.gripper is not None
    config = replace(config, gripper=replace(config.gripper, max_temperature=26.0))
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        sim.place_object(0.03)
        g = gripper_of(arm)
        assert g.close(force=40.0).grasped
        t0, temp0 = arm.clock.now(), g.state().temperature
        with pytest.raises(akarm.OverTemperature) as info:
            for _ in range(100):
                arm.sleep(0.1)
                assert g.state().temperature >= temp0  # reported, and rising
        assert info.value.joint == "gripper" and 1.0 < info.value.at - t0 < 4.0, info.value.at - t0  # 2.15 s
        assert not arm.enabled
