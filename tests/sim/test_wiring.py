"""Wiring mistakes named at contact, before anything is powered (issue 26), in lock step: two motors
on one CAN ID, a motor in the other mode, a servo status rate far below the configured one."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import pytest

from akarm.arm import Arm
from akarm.config import RobotConfig
from akarm.errors import DuplicateCanId, ImplausibleFeedback, ModeMismatch, MotorFault, StatusRateLow
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS


@contextmanager
def rig(robot: str, channel: str, sim_joint: str | None = None, **changes: object
        ) -> Iterator[tuple[Arm, SimulatedRobot]]:
    """An Arm configured as ``robot`` is, against a simulator where ``sim_joint`` has ``changes``
    (the motor on the bus is not the one configured)."""
    config = load_robot(ROBOTS / f"{robot}.yaml").with_bus(interface="virtual", channel=channel)
    sim_config: RobotConfig = config
    if sim_joint is not None:
        sim_config = replace(config, joints=tuple(replace(j, **changes) if j.name == sim_joint else j  # type: ignore[arg-type]
                                                  for j in config.joints))
    with SimulatedRobot(sim_config, realtime=False, log_frames=True) as sim, Arm(config, clock=sim.clock) as arm:
        yield arm, sim


def efforts(sim: SimulatedRobot) -> list[str]:
    """The MIT commands with kp > 0 any driver took in (none may go out before the wiring is known)."""
    out = []
    for f in sim.logged_frames()[0]:
        if f.to_motor and f.joint is not None and not f.is_extended and mit.special_frame(f.data) is None:
            c = mit.codec(sim.config.joint(f.joint).motor).decode_command(f.data)
            if c.kp > 0:
                out.append(f.joint)
    return out


@pytest.mark.parametrize("twin_at", [0.0, 0.7])  # the second motor where the first is, and elsewhere
def test_two_mit_motors_on_one_id_are_refused_at_contact(channel: str, twin_at: float) -> None:
    with rig("planar2", channel) as (arm, sim):
        sim.inject("elbow", faults.Twin(twin_at))
        with pytest.raises(DuplicateCanId) as e:
            arm.enable()
        assert e.value.joint == "elbow" and e.value.can_id == 2 and "CAN ID 2" in str(e.value)
        arm.sleep(0.05)
        assert efforts(sim) == [] and not arm.enabled


def test_two_servo_motors_on_one_id_are_refused_at_contact(channel: str) -> None:
    with rig("servo3", channel) as (arm, sim):
        sim.inject("pan", faults.Twin(0.0))
        with pytest.raises(DuplicateCanId) as e:
            arm.enable()
        assert e.value.joint == "pan" and e.value.can_id == sim.config.joint("pan").can_id


def test_a_servo_motor_where_mit_is_configured_is_named_with_the_mode_seen(channel: str) -> None:
    with rig("planar2", channel, "elbow", mode="servo", status_rate_hz=100.0) as (arm, sim):
        with pytest.raises(ModeMismatch) as e:
            arm.enable()
        assert e.value.joint == "elbow" and e.value.seen == "servo" and "servo-mode status frames" in str(e.value)
        assert efforts(sim) == []


def test_a_status_rate_ten_times_low_is_named_with_the_measured_rate(channel: str) -> None:
    with rig("servo3", channel, "pan", status_rate_hz=20.0) as (arm, sim):  # configured 200 Hz
        with pytest.raises(StatusRateLow) as e:
            arm.enable()
        assert e.value.joint == "pan" and e.value.configured == 200.0
        assert e.value.measured == pytest.approx(20.0, rel=0.3)
        assert "about 2" in str(e.value) and "200 Hz" in str(e.value)


def test_the_right_wiring_enables(channel: str) -> None:
    with rig("servo3", channel) as (arm, _):
        arm.enable()
        assert arm.enabled


def test_a_flood_of_forged_replies_with_a_code_no_driver_sends_is_implausible_traffic(channel: str) -> None:
    with rig("planar2", channel) as (arm, sim):
        arm.enable()
        here = float(sim.q[1])  # the elbow's motor position (direction 1, offset 0): the forgeries pass the gate
        t = arm.clock.now()
        sim.inject("elbow", faults.ForgedReply(here, count=50, interval=0.001, error=208))
        with pytest.raises(ImplausibleFeedback) as e:
            arm.sleep(0.5)
        assert e.value.joint == "elbow" and "error code 208, which no AK driver reports" in str(e.value)
        assert "implausible traffic" in str(e.value) and e.value.at is not None and e.value.at - t <= 0.01


def test_a_known_error_code_is_still_a_motor_fault(channel: str) -> None:
    with rig("planar2", channel) as (arm, sim):
        arm.enable()
        sim.inject("elbow", faults.ErrorCode(2))
        with pytest.raises(MotorFault):
            arm.sleep(0.2)


def test_a_mit_motor_where_servo_is_configured_is_named_with_the_mode_seen(channel: str) -> None:
    """Issue 39: it failed the enable as a generic FeedbackTimeout (a MIT motor ignores servo frames and
    sends no status frames), where ``akarm scan`` named it. The enable asks its ID as a MIT motor would
    be asked (EXIT: a MIT motor answers and stays limp; a servo motor ignores it) and names it."""
    with rig("servo3", channel, "pan", mode="mit") as (arm, sim):
        with pytest.raises(ModeMismatch) as e:
            arm.enable()
        assert e.value.joint == "pan" and e.value.seen == "mit" and "answers as a MIT motor" in str(e.value)
        assert efforts(sim) == [] and not any(d.enabled for d in sim.driver_states())
