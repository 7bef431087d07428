"""An Arm driving servo3's joints over UART (akarm_uart on pseudo-terminal pairs, the simulated drivers on the
other ends), in lock step: enable, moves, replay and disable as over CAN, with tracking comparable to
CAN's; the supervisor's checks; and every fault of the line stops the arm with its named error.

benchmarks/bench_uart.py prints the numbers (a longer program, and in real time).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

import akarm
from akarm import BusLost, FeedbackTimeout, MotorFault, UartBadCrc, UartNoise, UartPartialFrame, UartSilent
from akarm.motion.recording import PathRecording
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS

ALL = ("pan", "shoulder", "elbow")


@contextmanager
def servo3(channel: str, serial: tuple[str, ...], **sim_options) -> Iterator[tuple[akarm.Arm, SimulatedRobot]]:
    config = load_robot(ROBOTS / "servo3.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False, serial=dict.fromkeys(serial, "pty"), log_frames=True,
                        **sim_options) as sim, akarm.Arm(sim.config, clock=sim.clock, remember_positions=False) as arm:
        yield arm, sim


def wiggle(arm: akarm.Arm) -> PathRecording:
    """1.5 s about "pick", starting and ending at rest there."""
    t = np.arange(0.0, 1.51, 0.02)
    shape = ((1 - np.cos(2 * np.pi * t / 1.5)) / 2) ** 2
    return PathRecording(arm.names, t, np.array(arm.config.pose("pick")) + np.outer(shape, [0.3, -0.2, 0.25]))


def program(arm: akarm.Arm, sim: SimulatedRobot) -> tuple[np.ndarray, np.ndarray]:
    """enable, a move, a replay, disable; the RMS tracking error while moving and the error at rest (rad)."""
    arm.enable()
    t0 = arm.state().time
    arm.move_to("pick")
    arm.replay(wiggle(arm))
    moving = arm.telemetry(since=t0)
    arm.sleep(0.3)
    at_rest = np.abs(arm.state().q - np.array(arm.config.pose("pick")))
    assert np.abs(sim.q - arm.state().q).max() < 2e-3  # what the arm reads is where the simulated arm is
    arm.disable()
    assert not any(s.enabled for s in sim.driver_states())
    e = moving.tracking_error()
    return np.sqrt(np.mean(e * e, axis=0)), at_rest


@pytest.fixture(scope="module")
def over_can() -> tuple[np.ndarray, np.ndarray]:
    with servo3("uart-arm-can-baseline", ()) as (arm, sim):
        return program(arm, sim)


@pytest.mark.parametrize("serial", [ALL, ("pan",)], ids=["every joint over UART", "pan over UART, the rest CAN"])
def test_servo3_over_uart_runs_the_program_and_tracks_as_over_can(channel: str, serial: tuple[str, ...],
                                                                  over_can: tuple[np.ndarray, np.ndarray]) -> None:
    with servo3(channel, serial) as (arm, sim):
        assert {arm.config.buses[arm.config.joint(j).bus].interface for j in serial} == {"akarm_uart"}
        rms, at_rest = program(arm, sim)
        log = sim.logged_frames()[0]
    rms_can, at_rest_can = over_can
    # one control cycle (5 ms) more of feedback delay: a poll's reply is read at the next cycle, where
    # the lock-step CAN status frame is fresh (bench_uart.py: about 10 % more RMS error)
    assert np.all(rms <= 1.25 * rms_can + 2e-3), (rms, rms_can)
    assert np.all(at_rest < 5e-3) and np.all(at_rest_can < 5e-3), (at_rest, at_rest_can)
    on_uart = {f.joint for f in log if f.bus.startswith("uart-")}
    assert on_uart == set(serial)
    sent = [f for f in log if f.joint == serial[0] and f.to_motor]
    assert sent[0].data == bytes.fromhex("02 05 5C 00 00 00 00 9E 19 03")  # multi-turn, the manual's frame
    assert {f.arbitration_id for f in sent} >= {50, 91, 6}  # polls, position-speed, zero current (disable)


def test_the_supervisor_reads_the_motors_fault_over_uart(channel: str) -> None:
    with servo3(channel, ("pan",)) as (arm, sim):
        arm.enable()
        sim.inject("pan", faults.ErrorCode(1))  # sent on the line as the serial fault OVER_TEMP_MOTOR
        with pytest.raises(MotorFault, match="over-temperature") as e:
            arm.sleep(0.1)
        assert e.value.joint == "pan" and e.value.code == 1
        assert not any(s.enabled for s in sim.driver_states())


FAULTS = [(faults.BadCrc(), UartBadCrc), (faults.PartialFrame(), UartPartialFrame),
          (faults.CorruptBytes(), UartNoise), (faults.SilentPort(), UartSilent)]


@pytest.mark.parametrize(("fault", "error"), FAULTS, ids=[type(f).__name__ for f, _ in FAULTS])
def test_each_fault_of_the_line_stops_the_arm_with_its_named_error(channel: str, fault: faults.Fault,
                                                                   error: type[akarm.UartError]) -> None:
    with servo3(channel, ("pan",)) as (arm, sim):
        arm.enable()
        arm.move_to("pick", wait=False)
        arm.sleep(0.2)
        t = sim.t
        sim.inject("pan", fault)
        with pytest.raises(BusLost) as e:
            arm.sleep(0.2)
        assert isinstance(e.value.__cause__, error), repr(e.value.__cause__)
        assert e.value.bus == "uart-pan" and e.value.__cause__.port == sim.serial_ports["pan"]
        assert e.value.at is not None and e.value.at - t <= 0.015 + 1e-9  # two polls: within 15 ms
        assert not any(s.enabled for s in sim.driver_states())  # the stop's frames still went out: released


def test_a_lone_bad_reply_costs_one_status_frame_and_nothing_more(channel: str) -> None:
    with servo3(channel, ("pan",)) as (arm, sim):
        arm.enable()
        motion = arm.move_to("pick", wait=False)
        arm.sleep(0.1)
        sim.inject("pan", faults.BadCrc())
        arm.sleep(0.005)  # one cycle
        sim.clear_faults("pan")
        motion.wait()
        bus = arm.observe.buses["uart-pan"]
        assert bus.bad_crc == 1 and arm.enabled  # type: ignore[attr-defined]


@pytest.mark.parametrize(("fault", "says"), [(faults.BadCrc(), "fail their CRC"),
                                             (faults.CorruptBytes(), "no frame: check the baud rate"),
                                             (faults.SilentPort(), "nothing came back on serial port")],
                         ids=lambda x: type(x).__name__ if isinstance(x, faults.Fault) else "")
def test_an_enable_that_hears_nothing_good_says_what_the_line_carried(channel: str, fault: faults.Fault,
                                                                       says: str) -> None:
    with servo3(channel, ("pan",), faults={"pan": fault}) as (arm, sim):
        with pytest.raises(FeedbackTimeout, match="no answer") as e:
            arm.enable()
        assert e.value.joint == "pan" and says in e.value.fix
        assert not any(s.enabled for s in sim.driver_states())


def test_the_test_rig_puts_named_joints_and_the_robot_files_serial_ones_on_pty_pairs(tmp_path) -> None:
    from akarm.testing.rig import SimulatedArm

    with SimulatedArm.start(ROBOTS / "servo3.yaml", "virtual", serial=["pan"], pose="home") as rig:
        assert rig.config.buses[rig.config.joint("pan").bus].interface == "akarm_uart"
        assert rig.config.buses[rig.config.joint("elbow").bus].interface == "virtual"
        with rig.arm() as arm:
            arm.enable()
            arm.move_to("pick")
            arm.sleep(0.3)  # servo motors trail their plan (as over CAN)
            assert np.allclose(arm.state().q, arm.config.pose("pick"), atol=5e-3)
            rig.inject("pan", "silent")  # the --fault text form
            with pytest.raises(BusLost) as e:
                arm.sleep(0.1)
            assert isinstance(e.value.__cause__, UartSilent)
        assert rig.enabled_joints() == []
        assert any(f.joint == "pan" and f.arbitration_id == 91 for f in rig.frames(to_motor=True))  # UART SET_POS_SPD
    # a robot file that puts a joint on a serial port: the rig gives it a pty pair of its own
    text = (ROBOTS / "servo3.yaml").read_text().replace("arm: {channel: can0}", "arm: {channel: can0}\n"
                                                        "  wire: {interface: akarm_uart, channel: /dev/ttyUSB0}")
    text = text.replace("mode: servo", "mode: servo\n  bus: arm")
    text = text.replace("motor: AK60-6", "motor: AK60-6\n    bus: wire")
    (tmp_path / "servo3.urdf").write_text((ROBOTS / "servo3.urdf").read_text())
    (tmp_path / "servo3.yaml").write_text(text)
    with SimulatedArm.start(tmp_path / "servo3.yaml", "virtual") as rig:
        wire = rig.config.buses[rig.config.joint("elbow").bus]
        assert wire.interface == "akarm_uart" and wire.channel.startswith("/dev/pts/")
        with rig.arm() as arm:
            arm.enable()
            assert rig.enabled_joints() == ["pan", "shoulder", "elbow"]
            assert np.allclose(arm.state().q, 0.0, atol=1e-3)
        assert rig.enabled_joints() == []
