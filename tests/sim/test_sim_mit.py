"""Simulated MIT-mode drivers, frame by frame: what goes in on the bus and exactly what comes back.

Every test talks to the simulator through a python-can virtual bus on the same channel, in lock
step, and checks replies through the project's codecs (byte-exact where the state is exactly known).
Gravity is switched off where a test needs the arm to stay exactly where it was put.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import can
import pytest

from akarm.config import RobotConfig
from akarm.protocol import mit, servo, units
from akarm.robotfile.load import load_robot
from akarm.sim import MitDriver, SimulatedRobot

from .conftest import ROBOTS, drain, send


def with_joint(config: RobotConfig, index: int, **changes: object) -> RobotConfig:
    joints = list(config.joints)
    joints[index] = replace(joints[index], **changes)  # type: ignore[arg-type]
    return replace(config, joints=tuple(joints))


@pytest.fixture
def rig(planar2: RobotConfig, channel: str) -> Iterator[tuple[SimulatedRobot, can.BusABC]]:
    """planar2 in lock step without gravity, and a controller-side bus on the same channel."""
    with SimulatedRobot(planar2, "virtual", channel, realtime=False, zero_silence=0.5) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.model.set_gravity((0.0, 0.0, 0.0))
        yield sim, bus


SHOULDER = 1
ELBOW = 2


def test_before_enter_commands_are_answered_but_not_applied(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.set_state([0.5, -0.25])
    model = sim.config.joints[0].motor
    stored = sim.joint("shoulder").stored_command
    send(bus, SHOULDER, mit.encode_command(model, 1.5, 0.0, 50.0, 1.0, 3.0))
    sim.run_for(0.002)
    (reply,) = drain(bus)
    # state exactly as placed: byte-for-byte the codec's reply at p = 0.5, v = 0, τ = 0, 25 °C, no error
    assert (reply.arbitration_id, reply.is_extended_id) == (0, False)
    assert bytes(reply.data) == mit.encode_reply(model, SHOULDER, 0.5, 0.0, 0.0, 25.0, 0)
    sim.run_for(0.5)
    assert sim.joint("shoulder").stored_command == stored  # not stored
    assert sim.q[0] == pytest.approx(0.5, abs=1e-12)       # not applied: no motion at all
    assert sim.tau[0] == 0.0


def test_enter_then_command_is_applied_with_the_true_state(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.002)
    (reply,) = drain(bus)
    assert bytes(reply.data) == mit.encode_reply(model, SHOULDER, 0.0, 0.0, 0.0, 25.0, 0)
    assert sim.joint("shoulder").enabled
    data = mit.encode_command(model, 0.5, 0.0, 20.0, 1.0, 0.5)
    expected = mit.decode_command(model, data)
    send(bus, SHOULDER, data)
    sim.run_for(0.002)
    (reply,) = drain(bus)
    got = mit.decode_reply(model, reply.data)
    # the reply is the state when the command was handled: still at p = v = 0, so the torque is
    # kp·p_des + kd·v_des + τ_ff of the quantised command (v_des = 0 is sent as -v_max/4095: the lower code)
    step = mit.codec(model).steps.torque
    law = expected.kp * expected.position + expected.kd * expected.velocity + expected.torque
    assert got.torque == pytest.approx(law, abs=step / 2 + 1e-9)
    assert sim.joint("shoulder").stored_command == expected
    sim.run_for(3.0)
    # settles where kp·(p_des - p) + τ_ff balances friction: p = p_des + τ_ff/kp (no gravity)
    assert sim.q[0] == pytest.approx(expected.position + expected.torque / expected.kp, abs=0.01)


def test_exit_makes_the_output_limp(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    send(bus, SHOULDER, mit.ENTER)
    send(bus, SHOULDER, mit.encode_command(model, 0.0, 0.0, 0.0, 0.0, 2.0))
    sim.run_for(0.1)
    assert sim.tau[0] == pytest.approx(2.0, abs=0.01)
    drain(bus)
    send(bus, SHOULDER, mit.EXIT)
    sim.run_for(0.002)
    (reply,) = drain(bus)
    assert mit.decode_reply(model, reply.data).torque == pytest.approx(0.0, abs=0.005)
    assert not sim.joint("shoulder").enabled
    v = sim.dq[0]
    sim.run_for(0.2)
    assert sim.tau[0] == 0.0
    assert abs(sim.dq[0]) < abs(v)  # coasting down on friction alone


def test_zero_rereferences_and_goes_silent(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    sim.set_state([0.7, 0.0])
    send(bus, SHOULDER, mit.ZERO)
    sim.run_for(0.002)
    assert drain(bus) == []                      # off-line at once
    assert sim.joint("shoulder").silent
    send(bus, SHOULDER, mit.ENTER)               # ignored while silent
    send(bus, SHOULDER, mit.encode_command(model, 0.0, 0.0, 10.0, 0.0, 0.0))
    sim.run_for(0.4)
    assert drain(bus) == []
    assert not sim.joint("shoulder").enabled
    send(bus, ELBOW, mit.ENTER)                  # the other motor is not affected
    sim.run_for(0.002)
    assert [m.data[0] for m in drain(bus)] == [ELBOW]
    sim.run_for(0.2)                             # 0.6 s > zero_silence = 0.5 s
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.002)
    (reply,) = drain(bus)
    assert bytes(reply.data) == mit.encode_reply(model, SHOULDER, 0.0, 0.0, 0.0, 25.0, 0)
    assert sim.q[0] == pytest.approx(0.7, abs=1e-12)  # the joint did not move; only its zero did


def test_reply_id_is_zero_by_default_or_the_motors_own(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 1, reply_id=ELBOW)
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        send(bus, SHOULDER, mit.ENTER)
        send(bus, ELBOW, mit.ENTER)
        sim.run_for(0.002)
        replies = drain(bus)
    assert [(m.arbitration_id, m.is_extended_id, m.data[0]) for m in replies] == [
        (0, False, SHOULDER), (ELBOW, False, ELBOW)]


def test_kick_on_enable_stored_command_survives_exit_and_enter(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    drv = sim.joint("shoulder")
    assert isinstance(drv, MitDriver)
    model = sim.config.joints[0].motor
    # a command left from an earlier session, far from where the arm is now
    drv.stored_command = mit.MitCommand(1.2, 0.0, 30.0, 1.0, 0.0)
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.002)
    (reply,) = drain(bus)
    assert mit.decode_reply(model, reply.data).torque == pytest.approx(18.0)  # kp·1.2 = 36 N·m, clamped to t_max
    sim.run_for(0.05)
    assert sim.dq[0] > 1.0                      # the kick
    send(bus, SHOULDER, mit.EXIT)
    sim.run_for(1.0)
    assert drv.stored_command == mit.MitCommand(1.2, 0.0, 30.0, 1.0, 0.0)  # kept across EXIT
    sim.set_state([0.0, 0.0])
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.002)
    drain(bus)
    assert sim.tau[0] == pytest.approx(18.0)    # applied again at once, clamped to t_max


def test_torque_is_clamped_to_the_models_range(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[1].motor           # AK60-6: ±15 N·m
    send(bus, ELBOW, mit.ENTER)
    send(bus, ELBOW, mit.encode_command(model, -2.0, 0.0, 500.0, 0.0, -15.0))
    sim.run_for(0.002)
    assert sim.tau[1] == -15.0


def test_reported_position_wraps_at_p_max(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 0, offset=-12.0)  # motor = joint + 12 rad
    model = config.joints[0].motor
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.model.set_gravity((0.0, 0.0, 0.0))
        sim.set_state([0.3, 0.0])                   # motor at 12.3 rad: inside ±12.5
        send(bus, SHOULDER, mit.ENTER)
        sim.advance_to(0.001)
        sim.set_state([0.8, 0.0])                   # motor at 12.8 rad: past +12.5
        send(bus, SHOULDER, mit.ENTER)
        sim.advance_to(0.002)
        a, b = (mit.decode_reply(model, m.data).position for m in drain(bus))
    step = mit.codec(model).steps.position
    assert a == pytest.approx(12.3, abs=step)
    assert b == pytest.approx(12.8 - 25.0, abs=step)


def test_temperature_byte_follows_mit_temp_offset(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 0, motor=replace(planar2.joints[0].motor, mit_temp_offset=40.0))
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        send(bus, SHOULDER, mit.ENTER)
        sim.run_for(0.001)
        (reply,) = drain(bus)
    assert reply.data[6] == 65                      # 25 °C + 40
    assert mit.decode_reply(config.joints[0].motor, reply.data).temperature == 25.0


def test_frames_for_other_ids_get_no_answer(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    send(bus, 3, mit.ENTER)
    send(bus, SHOULDER, mit.ENTER, extended=True)   # right ID, wrong frame format
    send(bus, SHOULDER, b"\x01\x02")                # not 8 bytes: dropped by the firmware
    sim.run_for(0.01)
    assert drain(bus) == []


def test_in_lock_step_every_command_is_answered_behind_other_traffic(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    """Another node's frames (a second simulator's replies, say) ahead of a command in the queue must
    not leave the command for a later step (python-can's software filter would, on recv(0))."""
    sim, bus = rig
    for _ in range(3):
        send(bus, 0x7F0, b"\x01\x02")                    # traffic for nobody here
        send(bus, 0, b"\x05" + bytes(7))                  # another motor's reply
    send(bus, 1, mit.ENTER)
    send(bus, 2, mit.ENTER)
    sim.run_for(0.0005)
    assert sorted(m.data[0] for m in drain(bus)) == [1, 2]


def test_v3_board_extended_commands_status_replies(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 0, firmware="v3")
    model = config.joints[0].motor
    aid, ext = mit.command_arbitration_id(SHOULDER, "v3")
    assert (aid, ext) == (0x801, True)
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.model.set_gravity((0.0, 0.0, 0.0))
        sim.set_state([0.4, 0.0])
        send(bus, aid, mit.ENTER, extended=True)   # no enter frame on V3: answered, not applied
        send(bus, SHOULDER, mit.ENTER)             # a V2 frame: nobody listens to it
        sim.run_for(0.002)
        (first,) = drain(bus)
        assert not sim.joint("shoulder").enabled
        kt_out = model.kt * model.gear_ratio
        assert (first.arbitration_id, first.is_extended_id) == (0x2901, True)
        assert bytes(first.data) == servo.encode_status(
            SHOULDER, units.rad_to_servo_deg(model, 0.4), 0.0, 0.0, 25.0, 0)[1]
        data = mit.encode_command(model, 0.0, 0.0, 5.0, 0.0, 0.0, firmware="v3")
        cmd = mit.decode_command(model, data, firmware="v3")
        send(bus, aid, data, extended=True)        # applied from the first command
        sim.run_for(0.002)
        (reply,) = drain(bus)
        got = mit.decode_reply_v3(model, reply.arbitration_id, reply.data)
        assert got.driver_id == SHOULDER
        assert got.position == pytest.approx(0.4, abs=0.1 * 3.14159 / 180)  # 0.1° steps
        assert got.torque == pytest.approx(cmd.kp * (0.0 - 0.4), abs=0.01 * kt_out)  # 0.01 A steps
        assert sim.joint("shoulder").enabled
        sim.run_for(0.05)
        assert sim.tau[0] < -1.0


def test_can_timeout_makes_the_output_limp(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 0, can_timeout=0.1)
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        for m, joint in zip((SHOULDER, ELBOW), config.joints, strict=True):
            send(bus, m, mit.ENTER)
            send(bus, m, mit.encode_command(joint.motor, 0.0, 0.0, 0.0, 0.0, 1.0))
        sim.run_for(0.099)
        assert sim.tau.tolist() == pytest.approx([1.0, 1.0], abs=0.01)
        sim.run_for(0.002)
        assert not sim.joint("shoulder").enabled     # 0.1 s without a frame: limp
        assert sim.tau[0] == 0.0
        sim.run_for(2.0)
        assert sim.joint("elbow").enabled            # can_timeout = 0 (off), as on units in the field
        assert sim.tau[1] == pytest.approx(1.0, abs=0.01)


def test_two_buses_each_get_their_own_bus(channel: str) -> None:
    config = load_robot(ROBOTS / "biarm.yaml")
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=f"{channel}-left") as left, \
            can.Bus(interface="virtual", channel=f"{channel}-right") as right:
        sim.model.set_gravity((0.0, 0.0, 0.0))
        sim.set_state([0.1, 0.2, 0.3, 0.4])
        send(left, 1, mit.ENTER)
        sim.run_for(0.002)
        (on_left,) = drain(left)
        assert drain(right) == []
        send(right, 1, mit.ENTER)
        sim.run_for(0.002)
        (on_right,) = drain(right)
        assert drain(left) == []
    model = config.joints[0].motor
    assert mit.decode_reply(model, on_left.data).position == pytest.approx(0.1, abs=1e-3)
    assert mit.decode_reply(model, on_right.data).position == pytest.approx(0.3, abs=1e-3)
    assert sim.joint("left_shoulder").enabled and sim.joint("right_shoulder").enabled
    assert not sim.joint("left_elbow").enabled


def test_direction_and_offset_map_joint_to_motor(planar2: RobotConfig, channel: str) -> None:
    config = with_joint(planar2, 0, direction=-1, offset=0.2)
    model = config.joints[0].motor
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.model.set_gravity((0.0, 0.0, 0.0))
        sim.set_state([0.5, 0.0])
        send(bus, SHOULDER, mit.ENTER)
        send(bus, SHOULDER, mit.encode_command(model, 0.0, 0.0, 0.0, 0.0, 2.0))
        sim.run_for(0.002)
        first = mit.decode_reply(model, drain(bus)[0].data)
        assert first.position == pytest.approx((0.5 - 0.2) * -1, abs=1e-3)  # motor = (joint - offset)·dir
        assert sim.tau[0] == pytest.approx(-2.0, abs=0.01)                   # joint torque = dir · motor torque
