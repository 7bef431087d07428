"""The simulated servo driver on a serial port (akarm.sim.uart), in lock step: it answers the manual's
example requests with the manual's bytes (AK manual §5.2.2), carries out its commands, and spoils its
replies as the line's faults say. The test plays the controller on the pseudo-terminal's other end."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from akarm import AkarmError, ConfigError
from akarm.buses.serialport import Port, open_serial
from akarm.config import RobotConfig
from akarm.protocol import uart
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot, faults
from akarm.sim.uart import UartServoDriver

from .conftest import ROBOTS


@pytest.fixture(scope="module")
def servo3() -> RobotConfig:
    return load_robot(ROBOTS / "servo3.yaml")


@pytest.fixture
def line(servo3: RobotConfig, channel: str) -> Iterator[tuple[SimulatedRobot, Port]]:
    """servo3 in lock step, pan's driver on a pty pair; the controller's end of it, opened raw."""
    with SimulatedRobot(servo3.with_bus(interface="virtual", channel=channel), realtime=False,
                        serial={"pan": "pty"}, log_frames=True) as sim:
        port = open_serial(sim.serial_ports["pan"])
        try:
            yield sim, port
        finally:
            port.close()


def exchange(sim: SimulatedRobot, port: Port, request: str, seconds: float = 0.001) -> bytes:
    port.write(bytes.fromhex(request))
    sim.run_for(seconds)
    return port.read()


def test_the_driver_is_on_the_serial_port_and_the_config_says_where(line) -> None:
    sim, port = line
    pan = sim.joint("pan")
    assert isinstance(pan, UartServoDriver) and not isinstance(sim.joint("elbow"), UartServoDriver)
    assert sim.config.buses["uart-pan"].interface == "akarm_uart"
    assert sim.config.buses["uart-pan"].channel == sim.serial_ports["pan"]
    assert sim.config.joint("pan").bus == "uart-pan" and sim.config.joint("elbow").bus == "arm"
    sim.run_for(0.05)
    assert port.read() == b""  # nothing unasked: no status frames over UART


def test_it_answers_the_manuals_temperature_request_with_the_manuals_reply(line) -> None:
    sim, port = line
    sim.joint("pan").temperature = 12.9
    assert exchange(sim, port, "02 05 32 00 00 00 01 58 4C 03") == bytes.fromhex("02 03 32 00 81 2A 6C 03")


def test_after_set_detect_it_reports_the_position_every_10_ms_as_the_manual_prints(line) -> None:
    sim, port = line
    sim.joint("pan").origin = -math.radians(1750.628)  # the manual's example position (1 750 628 thousandths)
    got = exchange(sim, port, "02 02 0B 04 9C 7E 03", 0.035)
    assert got == bytes.fromhex("02 05 16 00 1A B6 64 D5 F4 03") * 3


def test_get_values_reports_the_plant(line) -> None:
    sim, port = line
    sim.set_state([0.5, 0.0, 0.0])
    values = uart.decode_get_values(uart.decode_frame(exchange(sim, port, "02 01 04 40 84 03")))
    assert values.position_deg == pytest.approx(math.degrees(0.5), abs=1e-6)
    assert values.controller_id == 1 and values.fault == 0 and values.input_voltage == 24.0


def test_the_manuals_commands_are_carried_out(line) -> None:
    sim, port = line
    pan = sim.joint("pan")
    exchange(sim, port, "02 0D 5B 00 02 BF 20 00 00 13 88 00 00 75 30 A5 AC 03")  # 180°, 5000 ERPM, 30000 ERPM/s
    assert pan.control == "position" and pan.profile.target == pytest.approx(math.pi)
    exchange(sim, port, "02 05 5D 00 00 00 00 34 48 03")
    assert pan.position_mode == "single"
    exchange(sim, port, "02 05 5C 00 00 00 00 9E 19 03")
    assert pan.position_mode == "multi"
    sim.set_state([0.3, 0.0, 0.0])
    exchange(sim, port, "02 02 5F 01 0E A0 03")  # origin here, kept (mode 1)
    assert pan.origin == pytest.approx(0.3) and pan.permanent_origin == pytest.approx(0.3)
    exchange(sim, port, uart.encode_current(0.0).hex(" "))
    assert pan.control is None  # zero current: released


def test_the_manuals_misprinted_set_pos_is_ignored_and_the_corrected_one_taken(line) -> None:
    sim, port = line
    pan = sim.joint("pan")
    exchange(sim, port, "02 05 09 0A BA 95 00 1E E7 03")  # as printed: its CRC is wrong
    assert pan.control is None and pan.frame_errors == 1
    exchange(sim, port, "02 05 09 0A BA 95 00 1E F7 03")
    assert pan.control == "position" and pan.profile.target == pytest.approx(math.pi)


POLL = "02 01 04 40 84 03"


@pytest.mark.parametrize("fault", [faults.BadCrc(), faults.PartialFrame(), faults.CorruptBytes(seed=4),
                                   faults.SilentPort(), faults.Unplugged()], ids=repr)
def test_the_lines_faults_spoil_the_replies_as_they_say(line, fault: faults.Fault) -> None:
    sim, port = line
    good = exchange(sim, port, POLL)
    assert uart.decode_frame(good)
    sim.inject("pan", fault)
    got = exchange(sim, port, POLL)
    decoder = uart.FrameDecoder()
    found = decoder.feed(got) + decoder.flush()
    assert found == []  # no good frame in it, whatever the fault
    if isinstance(fault, faults.BadCrc):
        assert len(got) == len(good) and got[:-3] == good[:-3] and decoder.crc_errors == 1
    elif isinstance(fault, faults.PartialFrame):
        assert got == good[:len(good) // 2]
    elif isinstance(fault, faults.CorruptBytes):
        assert len(got) == len(good) and got != good
    else:
        assert got == b""
    exchange(sim, port, "02 05 06 00 00 13 88 8B 25 03")  # 5 A
    assert (sim.joint("pan").control == "current") is not isinstance(fault, faults.Unplugged)  # silent still hears
    sim.clear_faults("pan")
    assert uart.decode_frame(exchange(sim, port, POLL))


def test_line_faults_are_refused_on_a_can_driver_and_second_nodes_on_a_serial_one(line) -> None:
    sim, _ = line
    with pytest.raises(AkarmError, match="BadCrc is a fault of a serial port") as e:
        sim.inject("elbow", faults.BadCrc())
    assert e.value.joint == "elbow" and "--serial elbow=pty" in e.value.fix
    with pytest.raises(AkarmError, match="another node"):
        sim.inject("pan", faults.ForgedReply(1.0))
    sim.inject("pan", faults.RogueExit(on_bus=False))


def test_a_joint_on_a_serial_port_needs_one_and_mit_joints_have_none(servo3: RobotConfig, channel: str) -> None:
    from akarm.buses.uart import serial_config

    on_uart = serial_config(servo3.with_bus(interface="virtual", channel=channel), {"pan": "/dev/ttyUSB0"})
    with pytest.raises(ConfigError, match="joint 'pan' is on serial port bus 'uart-pan'"):
        SimulatedRobot(on_uart, realtime=False)
    planar2 = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with pytest.raises(ConfigError, match="MIT mode, which has no serial protocol"):
        SimulatedRobot(planar2, realtime=False, serial={"elbow": "pty"})
