"""Every fault the simulator can inject, from Python and from command-line text."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import can
import numpy as np
import pinocchio as pin
import pytest

from akarm.config import RobotConfig
from akarm.errors import AkarmError
from akarm.protocol import mit, servo
from akarm.robotfile.load import load_robot
from akarm.sim import MitDriver, SimulatedRobot, faults
from akarm.sim.params import default_params

from .conftest import ROBOTS, drain, send

SHOULDER, ELBOW = 1, 2


@pytest.fixture
def rig(planar2: RobotConfig, channel: str) -> Iterator[tuple[SimulatedRobot, can.BusABC]]:
    with SimulatedRobot(planar2, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        yield sim, bus


def poll_pattern(sim: SimulatedRobot, bus: can.BusABC, n: int) -> list[bool]:
    """Send ENTER to the elbow n times, one per 1 ms; which of them got a reply."""
    got = []
    for _ in range(n):
        send(bus, ELBOW, mit.ENTER)
        sim.run_for(0.001)
        got.append(len(drain(bus)) == 1)
    return got


def test_drop_replies_loses_that_share_repeatably(planar2: RobotConfig, channel: str) -> None:
    patterns = []
    for run in range(2):
        with SimulatedRobot(planar2, "virtual", f"{channel}-{run}", realtime=False) as sim, \
                can.Bus(interface="virtual", channel=f"{channel}-{run}") as bus:
            sim.joint("elbow").inject(faults.DropReplies(0.3, seed=7))
            patterns.append(poll_pattern(sim, bus, 1000))
            send(bus, SHOULDER, mit.ENTER)            # the other joint is not affected
            sim.run_for(0.001)
            assert len(drain(bus)) == 1
            assert sim.joint("elbow").frames_received == 1000  # the commands still get in
    assert patterns[0] == patterns[1]                   # seeded: the same frames are lost every run
    answered = sum(patterns[0])
    assert 700 - 45 <= answered <= 700 + 45             # 30 % lost (± 3 σ of a binomial, 1000 draws)


def test_drop_replies_also_drops_servo_status_frames(channel: str) -> None:
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.joint("pan").inject(faults.DropReplies(0.5, seed=1))
        sim.run_for(1.0)
        ids = [m.arbitration_id for m in drain(bus)]
    assert ids.count(0x2902) == 200
    assert 100 - 22 <= ids.count(0x2901) <= 100 + 22


def test_delay_replies_sends_them_late_with_the_state_of_when_they_were_made(
        rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[1].motor
    sim.set_state([0.0, 0.0], [0.0, 2.0])                     # the elbow swings at 2 rad/s
    sim.joint("elbow").inject(faults.DelayReplies(0.005))
    send(bus, ELBOW, mit.ENTER)
    q_then = sim.q[1]
    sim.run_for(0.0045)
    assert drain(bus) == []
    sim.run_for(0.001)
    (reply,) = drain(bus)
    assert mit.decode_reply(model, reply.data).position == pytest.approx(q_then, abs=4e-4)
    assert sim.q[1] - q_then > 5e-3                           # the arm has moved on since
    sim.joint("elbow").clear_faults()
    send(bus, ELBOW, mit.ENTER)
    sim.run_for(0.0005)
    assert len(drain(bus)) == 1


def test_delay_keeps_the_order_of_frames(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.set_state([0.0, 0.0], [0.0, 2.0])
    sim.joint("elbow").inject(faults.DelayReplies(0.003))
    for _ in range(5):
        send(bus, ELBOW, mit.ENTER)
        sim.run_for(0.001)
    sim.run_for(0.01)
    positions = [mit.decode_reply(sim.config.joints[1].motor, m.data).position for m in drain(bus)]
    assert len(positions) == 5
    assert positions == sorted(positions) and positions[0] < positions[-1]  # swinging up: in the order made


def test_unplugged_motor_keeps_its_last_command_and_hears_nothing(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    send(bus, SHOULDER, mit.ENTER)
    send(bus, SHOULDER, mit.encode_command(model, 0.3, 0.0, 60.0, 2.0, 0.0))
    sim.run_for(1.0)
    drain(bus)
    drv = sim.joint("shoulder")
    held = drv.stored_command  # type: ignore[attr-defined]
    drv.inject(faults.Unplugged())
    send(bus, SHOULDER, mit.encode_command(model, -1.0, 0.0, 60.0, 2.0, 0.0))
    send(bus, SHOULDER, mit.EXIT)
    sim.run_for(1.0)
    assert drain(bus) == []                                    # no replies
    assert drv.stored_command == held and drv.enabled          # commands not received
    assert sim.q[0] == pytest.approx(0.3, abs=0.05)            # still holding where it was told
    drv.clear_faults()
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.001)
    assert len(drain(bus)) == 1


def test_unplugged_with_power_lost_goes_limp_and_restarts_cold(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    send(bus, SHOULDER, mit.ENTER)
    send(bus, SHOULDER, mit.encode_command(model, 0.3, 0.0, 60.0, 2.0, 0.0))
    sim.run_for(1.0)
    drv = sim.joint("shoulder")
    assert isinstance(drv, MitDriver)
    drv.inject(faults.Unplugged(power_lost=True))
    sim.run_for(0.01)
    assert sim.tau[0] == 0.0 and not drv.enabled and not drv.powered
    sim.run_for(1.0)
    assert sim.q[0] < 0.0                                     # fell
    drv.clear_faults()
    assert drv.stored_command == mit.MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)  # power-up state
    assert not drv.enabled


def test_unplugged_servo_releases_after_its_timeout(channel: str) -> None:
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        send(bus, *servo.encode_current(1, 1.0), extended=True)
        sim.run_for(0.01)
        sim.joint("pan").inject(faults.Unplugged())
        drain(bus)
        sim.run_for(0.5)
        assert 0x2901 not in [m.arbitration_id for m in drain(bus)]
        assert sim.joint("pan").enabled                       # still applying its current
        sim.run_for(0.6)
        assert not sim.joint("pan").enabled                   # its own 1 s timeout released it


def test_error_code_is_reported_in_replies_and_status_frames(rig: tuple[SimulatedRobot, can.BusABC],
                                                              channel: str) -> None:
    sim, bus = rig
    sim.joint("elbow").inject(faults.ErrorCode(1))
    send(bus, ELBOW, mit.ENTER)
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.001)
    replies = {m.data[0]: mit.decode_reply(sim.config.joints[0].motor, m.data) for m in drain(bus)}
    assert replies[ELBOW].error == 1 and replies[SHOULDER].error == 0
    sim.clear_faults()
    send(bus, ELBOW, mit.ENTER)
    sim.run_for(0.001)
    assert drain(bus)[0].data[7] == 0
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel + "-servo", realtime=False) as s3, \
            can.Bus(interface="virtual", channel=channel + "-servo") as b3:
        s3.joint("elbow").inject(faults.ErrorCode(int(servo.ServoErrorCode.ENCODER_FAULT)))
        s3.run_for(0.01)
        status = {m.arbitration_id & 0xFF: servo.decode_status(m.arbitration_id, m.data) for m in drain(b3)}
    assert status[3].error == 5 and status[1].error == 0


def test_frozen_encoder_reports_a_still_position_while_the_joint_moves(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    sim.set_state([0.5, 0.0])
    sim.joint("shoulder").inject(faults.FrozenEncoder())
    sim.run_for(0.5)                                          # limp: the arm falls
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.001)
    (reply,) = drain(bus)
    got = mit.decode_reply(model, reply.data)
    assert got.position == pytest.approx(0.5, abs=4e-4)
    assert got.velocity == pytest.approx(0.0, abs=0.02)        # within a 12-bit step of 0
    assert sim.q[0] < 0.0
    sim.clear_faults()
    send(bus, SHOULDER, mit.ENTER)
    sim.run_for(0.001)
    assert mit.decode_reply(model, drain(bus)[0].data).position == pytest.approx(sim.q[0], abs=0.01)


def test_frozen_encoder_can_fool_the_firmware_loop_too(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    sim.model.set_gravity((0.0, 0.0, 0.0))
    send(bus, SHOULDER, mit.ENTER)
    send(bus, SHOULDER, mit.encode_command(model, 0.0, 0.0, 20.0, 0.0, 0.0))
    sim.run_for(0.1)
    sim.joint("shoulder").inject(faults.FrozenEncoder(affects_control=True))
    sim.set_state([0.2, 0.0])                                 # pushed away: the loop cannot see it
    sim.run_for(0.5)
    assert sim.q[0] > 0.19                                    # not pulled back (only friction slows it)


def test_fault_after_reports_its_code_from_that_time(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.run_for(0.5)
    sim.joint("elbow").inject(faults.FaultAfter(2.0, code=7))
    sim.run_for(1.99)
    send(bus, ELBOW, mit.ENTER)
    sim.run_for(0.001)
    assert drain(bus)[0].data[7] == 0
    sim.run_for(0.01)                                         # 2.0 s after injection
    send(bus, ELBOW, mit.ENTER)
    sim.run_for(0.001)
    assert drain(bus)[0].data[7] == 7
    assert sim.joint("elbow").error == 7


def test_faults_on_an_unknown_joint_name_it(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, _ = rig
    with pytest.raises(AkarmError, match="joints are: shoulder, elbow"):
        sim.inject("wrist", faults.ErrorCode(1))


def test_forged_replies_come_from_another_node_with_the_claimed_position(
        rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[1].motor
    sim.joint("elbow").inject(faults.ForgedReply(12.45, count=3, interval=0.01))
    sim.run_for(0.0005)
    first = drain(bus)
    sim.run_for(0.03)
    rest = drain(bus)
    frames = first + rest
    assert len(first) == 1 and len(frames) == 3
    for f in frames:  # a MIT reply on ID 0 in the elbow's name, at the claimed position
        assert not f.is_extended_id and f.arbitration_id == 0 and f.data[0] == ELBOW
        assert mit.decode_reply(model, f.data).position == pytest.approx(12.45, abs=4e-4)
    assert sim.joint("elbow").frames_sent == 0  # the driver sent none of them


def test_forged_status_frames_for_servo_joints(channel: str) -> None:
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.joint("pan").inject(faults.ForgedReply(1.0))
        sim.run_for(0.0001)
        (f,) = drain(bus)
        st = servo.decode_status(f.arbitration_id, f.data)
        assert f.arbitration_id == 0x2901 and st.position_deg == pytest.approx(57.3, abs=0.05)


@pytest.mark.parametrize("on_bus", [True, False])
def test_rogue_exit_disables_the_driver_seen_or_unseen(rig: tuple[SimulatedRobot, can.BusABC], on_bus: bool) -> None:
    sim, bus = rig
    model = sim.config.joints[0].motor
    send(bus, SHOULDER, mit.ENTER)
    send(bus, SHOULDER, mit.encode_command(model, 0.0, 0.0, 60.0, 2.0, 0.0))
    sim.run_for(0.01)
    drain(bus)
    drv = sim.joint("shoulder")
    assert drv.enabled
    drv.inject(faults.RogueExit(on_bus=on_bus))
    sim.run_for(0.001)
    frames = drain(bus)
    assert not drv.enabled
    if on_bus:  # the EXIT on the shoulder's command ID, and the driver's answer to it
        assert (frames[0].arbitration_id, bytes(frames[0].data)) == (SHOULDER, mit.EXIT)
        assert frames[1].arbitration_id == 0 and frames[1].data[0] == SHOULDER
    else:
        assert frames == []
    send(bus, SHOULDER, mit.encode_command(model, 0.5, 0.0, 60.0, 2.0, 0.0))  # ignored until ENTER
    sim.run_for(0.2)
    assert sim.tau[0] == 0.0


def test_rogue_exit_releases_a_servo_joint(channel: str) -> None:
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        send(bus, *servo.encode_current(1, 1.0), extended=True)
        sim.run_for(0.01)
        assert abs(sim.tau[0]) > 0.5
        drain(bus)
        sim.joint("pan").inject(faults.RogueExit())
        sim.run_for(0.01)
        assert sim.tau[0] == 0.0                                  # zero current: limp
        assert (0x0101, servo.encode_current(1, 0.0)[1]) in [(m.arbitration_id, bytes(m.data)) for m in drain(bus)]


def test_blocked_joint_stays_put_whatever_the_torque(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    model = sim.config.joints[1].motor
    sim.set_state([0.0, 0.3], [0.0, 2.0])
    sim.joint("elbow").inject(faults.Blocked())
    send(bus, ELBOW, mit.ENTER)
    send(bus, ELBOW, mit.encode_command(model, 1.5, 0.0, 20.0, 0.5, 5.0))
    sim.run_for(0.5)
    assert sim.q[1] == pytest.approx(0.3, abs=1e-12) and sim.dq[1] == 0.0
    assert abs(sim.tau[1]) > 5.0                              # pushing as hard as the command says
    sim.joint("elbow").clear_faults()
    sim.run_for(0.2)
    assert sim.q[1] > 0.5                                     # free again: it goes where it is told


def test_a_blocked_shoulder_holds_the_other_joints_as_the_reduced_model_says(channel: str) -> None:
    # arm6 mid-motion, no friction, motors off, a push on every joint; shoulder_lift blocked: the
    # other joints move as the arm with that joint locked (Pinocchio's reduced model) does
    arm6 = load_robot(ROBOTS / "arm6.yaml")
    free = replace(default_params(arm6.joints[0].motor), viscous=0.0, coulomb=0.0)
    with SimulatedRobot(arm6, "virtual", channel, realtime=False, params={j.name: free for j in arm6.joints}) as sim:
        q = np.array([0.3, 0.6, -0.9, 0.4, 0.8, -0.2])
        sim.set_state(q, [0.5, 1.5, -1.0, 0.8, -0.6, 1.2])
        tau = np.array([0.5, -1.0, 2.0, 0.3, -0.2, 0.1])
        sim.set_external_torque(tau)
        assert sim.model.identity_mapping
        before = sim.dq.copy()
        sim.joint("shoulder_lift").inject(faults.Blocked())
        q, dq = sim.q.copy(), sim.dq.copy()
        M = sim.model.mass_matrix(q)  # the stop's impulse acts on joint 1 only: the others' momentum is kept
        assert np.allclose(np.delete(M @ dq, 1), np.delete(M @ before, 1), rtol=1e-12, atol=1e-12)
        sim.plant.step(0.0)
        pm = sim.model.pin_model
        reduced = pin.buildReducedModel(pm, [pm.getJointId("shoulder_lift")], q)
        reduced.armature = np.delete(np.array(pm.armature), 1)
        expected = pin.aba(reduced, reduced.createData(), np.delete(q, 1), np.delete(dq, 1), np.delete(tau, 1))
        assert sim.plant.ddq[1] == 0.0 and dq[1] == 0.0
        assert np.allclose(np.delete(sim.plant.ddq, 1), expected, rtol=1e-9, atol=1e-9), \
            (np.delete(sim.plant.ddq, 1), expected)


def test_a_fault_from_the_start_is_in_force_before_the_first_frame(planar2: RobotConfig, channel: str) -> None:
    with SimulatedRobot(planar2, "virtual", channel, realtime=False,
                        faults={"elbow": faults.DelayReplies(0.06), "shoulder": [faults.ErrorCode(4)]}) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        assert sim.joint("elbow").faults == (faults.DelayReplies(0.06),)
        send(bus, ELBOW, mit.ENTER)
        send(bus, SHOULDER, mit.ENTER)
        sim.run_for(0.001)
        (first,) = drain(bus)
        assert first.data[0] == SHOULDER and first.data[7] == 4
        sim.run_for(0.06)
        assert [f.data[0] for f in drain(bus)] == [ELBOW]
