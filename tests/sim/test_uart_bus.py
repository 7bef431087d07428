"""akarm_uart, the servo motors' serial port as a python-can bus, on a pseudo-terminal pair: the bytes it
writes (the manual's example frames, AK manual §5.2.2), the status frames it makes of the replies, the
polls, and what it does with a line that carries no good reply.

The test plays the motor on the pair's other end (``open_pty``'s port); no simulator here
(tests/sim/test_uart_sim.py has the simulated motor, tests/sim/test_uart_arm.py an Arm on both).
"""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest

from akarm import ArgumentError, BusError, UartBadCrc, UartNoise, UartPartialFrame, UartSilent
from akarm.buses.serialport import Port, open_pty
from akarm.buses.uart import STATUS_FIELDS, UartBus, serial_config
from akarm.protocol import servo, uart
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS

V = uart.ValueField


def manual(text: str) -> bytes:
    return bytes.fromhex(text)


@pytest.fixture
def line() -> Iterator[tuple[Port, str]]:
    port, path = open_pty()
    try:
        yield port, path
    finally:
        port.close()


def frame(packet_frame: tuple[int, bytes]) -> can.Message:
    return can.Message(arbitration_id=packet_frame[0], data=packet_frame[1], is_extended_id=True)


def reply(motor_id: int = 3, position: float = 12.3456, speed: float = 1000.0, iq: float = 1.25, mosfet: float = 30.0,
          motor: float = 35.5, fault: int = 0) -> bytes:
    return uart.encode_get_values_setup_reply({V.MOSFET_TEMPERATURE: mosfet, V.MOTOR_TEMPERATURE: motor,
                                               V.IQ_CURRENT: iq, V.SPEED: speed, V.ERROR: fault,
                                               V.POSITION: position, V.MOTOR_ID: motor_id})


# ------------------------------------------------------------------------------------------------
# bytes out: the manual's examples
# ------------------------------------------------------------------------------------------------
# (what the controller sends on CAN, the manual's frame for it); the 180° SET_POS is printed with CRC 1E E7,
# which is wrong (docs ak-protocol.md §3 errata): its right CRC is 1E F7
EXAMPLES = [
    (servo.encode_duty(1, 0.20), "02 05 05 00 00 4E 20 29 F6 03"),
    (servo.encode_duty(1, -0.20), "02 05 05 FF FF B1 E0 77 85 03"),
    (servo.encode_current(1, 5.0), "02 05 06 00 00 13 88 8B 25 03"),
    (servo.encode_current(1, -5.0), "02 05 06 FF FF EC 78 E3 05 03"),
    (servo.encode_current_brake(1, 5.0), "02 05 07 00 00 13 88 21 74 03"),
    (servo.encode_rpm(1, 1000.0), "02 05 08 00 00 03 E8 2B 58 03"),
    (servo.encode_rpm(1, -1000.0), "02 05 08 FF FF FC 18 43 78 03"),
    (servo.encode_position(1, 90.0), "02 05 09 05 5D 4A 80 7B 29 03"),
    (servo.encode_position(1, 180.0), "02 05 09 0A BA 95 00 1E F7 03"),
    (servo.encode_position_speed(1, 180.0, 5000.0, 30000.0), "02 0D 5B 00 02 BF 20 00 00 13 88 00 00 75 30 A5 AC 03"),
    (servo.encode_origin(1, servo.OriginMode.PERMANENT), "02 02 5F 01 0E A0 03"),
]


def test_opening_puts_the_position_loop_in_multi_turn_mode_with_the_manuals_frame(line) -> None:
    motor, path = line
    with UartBus(path) as bus:
        assert motor.read() == manual("02 05 5C 00 00 00 00 9E 19 03")
        bus.recv(0.0)  # the first window: a poll
        assert motor.read() == uart.encode_get_values_setup(STATUS_FIELDS)
    with UartBus(path, multi_turn=False, poll="values") as bus:
        assert motor.read() == b""
        bus.recv(0.0)
        assert motor.read() == manual("02 01 04 40 84 03")  # GET_VALUES, as the manual prints it


@pytest.mark.parametrize(("command", "wire"), EXAMPLES, ids=[w for _, w in EXAMPLES])
def test_each_servo_command_goes_out_as_the_manuals_frame(line, command: tuple[int, bytes], wire: str) -> None:
    motor, path = line
    with UartBus(path, multi_turn=False) as bus:
        bus.send(frame(command))
        assert motor.read() == manual(wire)


def test_units_differ_between_can_and_uart_and_the_bus_converts_them(line) -> None:
    motor, path = line
    with UartBus(path, multi_turn=False) as bus:
        # CAN: degrees x 10 000, speed in tens of ERPM; UART: degrees x 1000, whole ERPM
        bus.send(frame(servo.encode_position_speed(1, -1234.5678, 12340.0, 50000.0)))
        cmd = uart.decode_command(uart.decode_frame(motor.read()))
        assert cmd == uart.UartCommand(uart.UartPacket.SET_POS_SPD, (-1234.568, 12340.0, 50000.0))
        with pytest.raises(can.CanOperationError, match="position"):  # SET_POS: only ±2147.48° fit the UART field
            bus.send(frame(servo.encode_position(1, 3000.0)))
        assert motor.read() == b""


def test_frames_that_are_no_servo_command_for_this_motor_go_nowhere(line) -> None:
    motor, path = line
    with UartBus(path, multi_turn=False) as bus:
        bus.send(can.Message(arbitration_id=1, data=bytes(8), is_extended_id=False))       # a MIT frame
        bus.send(can.Message(arbitration_id=0x2903, data=bytes(8), is_extended_id=True))   # a status frame
        assert bus.unsent == 2 and motor.read() == b""
        bus.recv(0.0)
        motor.read()
        motor.write(reply(motor_id=3))
        assert bus.recv(0.0) is not None and bus.motor_id == 3
        bus.send(frame(servo.encode_current(2, 1.0)))  # another motor's: none on this port
        assert bus.foreign == 1 and motor.read() == b""
        bus.send(frame(servo.encode_current(3, 1.0)))
        assert motor.read() == uart.encode_current(1.0)


# ------------------------------------------------------------------------------------------------
# bytes in: status frames
# ------------------------------------------------------------------------------------------------
def test_a_reply_becomes_the_status_frame_the_motor_sends_on_can(line) -> None:
    motor, path = line
    with UartBus(path) as bus:
        assert bus.recv(0.0) is None
        motor.write(reply(position=-12.3456, speed=-1000.0, iq=1.25, mosfet=30.0, motor=35.5))
        msg = bus.recv(0.0)
        assert msg is not None and msg.is_extended_id and msg.arbitration_id == 0x2903
        assert bytes(msg.data) == servo.encode_status(3, -12.3, -1000.0, 1.25, 36.0)[1]  # the hotter temperature
        motor.write(reply(fault=uart.FaultCode.OVER_TEMP_MOTOR) + reply(fault=uart.FaultCode.DRV))
        codes = [servo.decode_status(m.arbitration_id, m.data).error for m in (bus.recv(0.0), bus.recv(0.0))]
        assert codes == [1, 0x83]  # motor over-temperature as on CAN; DRV, which CAN lacks, as 0x80 + 3
        assert "gate driver" in servo.describe_error(0x83)[0]
        assert bus.replies == 3


def test_get_values_replies_work_too_and_the_manuals_misprinted_one_is_no_status(line) -> None:
    motor, path = line
    values = uart.GetValues(30.0, 31.0, 2.0, 0.5, 0.1, 1.5, 0.1, 2000.0, 24.0, 0, 45.0, 3, 0.0, 0.0)
    with UartBus(path, poll="values") as bus:
        motor.write(uart.encode_get_values_reply(values))
        msg = bus.recv(0.0)
        assert servo.decode_status(msg.arbitration_id, msg.data) == servo.ServoStatus(3, 45.0, 2000.0, 1.5, 31.0, 0)
        # the manual's GET_VALUES reply says 73 payload bytes and carries 72, then a ROTOR_POSITION frame
        motor.write(manual("02 49 04 01 66 FC D0 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 FF FF FF F3 "
                           "00 F6 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 FF FF FF FF 00 16 D7 AD 00 0A 6F "
                           "19 40 7E 00 00 00 00 00 00 00 00 00 00 00 00 04 4D 53 03 02 05 16 00 1A B6 03 C9 B5 03"))
        assert bus.recv(0.0) is None
        assert bus.replies == 1 and bus.other == 1  # no status made of it; the ROTOR_POSITION is no status either


def test_one_poll_per_window_and_a_waiting_caller_polls_on_its_own(line) -> None:
    motor, path = line
    with UartBus(path, multi_turn=False, poll_interval=0.002) as bus:
        for _ in range(3):
            assert bus.recv(0.0) is None
        assert bus.polls == 3 and motor.read() == uart.encode_get_values_setup(STATUS_FIELDS) * 3
        assert bus.recv(0.02) is None  # waiting: a poll every 2 ms meanwhile
        assert bus.polls >= 5


def test_a_caller_that_waits_a_little_at_a_time_still_gets_its_polls(line) -> None:
    import time

    motor, path = line
    with UartBus(path, multi_turn=False, poll_interval=0.002) as bus:
        end = time.monotonic() + 0.03
        while time.monotonic() < end:  # as akarm status goes round several buses, 1 ms each
            assert bus.recv(0.0005) is None
        assert bus.polls >= 2 and motor.read() == uart.encode_get_values_setup(STATUS_FIELDS) * bus.polls


# ------------------------------------------------------------------------------------------------
# faults on the wire
# ------------------------------------------------------------------------------------------------
def spoil_crc(data: bytes) -> bytes:
    return data[:-2] + bytes((data[-2] ^ 0xFF, data[-1]))


FAULTS = [
    ("crc", lambda r: spoil_crc(r), UartBadCrc, "bad CRC"),
    ("partial", lambda r: r[:12], UartPartialFrame, "cut short"),
    ("noise", lambda r: bytes((b * 37 + 11) % 256 | 0x80 for b in r), UartNoise, "none forms a frame"),
    ("silent", lambda r: b"", UartSilent, "no byte came back"),
]


def commanded(bus: UartBus) -> None:
    bus.send(frame(servo.encode_position_speed(3, 10.0, 1000.0, 10000.0)))


@pytest.mark.parametrize(("kind", "spoil", "error", "says"), FAULTS, ids=[f[0] for f in FAULTS])
def test_a_line_without_good_replies_raises_its_named_error_while_commanded(line, kind, spoil, error, says) -> None:
    motor, path = line
    with UartBus(path) as bus:
        bus.recv(0.0)
        motor.write(reply())
        assert bus.recv(0.0) is not None and bus.recv(0.0) is None
        commanded(bus)
        motor.write(spoil(reply()))
        assert bus.recv(0.0) is None  # one bad window: one status frame missing, nothing more
        assert bus.bad_in_row == 1 and getattr(bus, {"crc": "bad_crc"}.get(kind, kind)) == 1
        motor.write(spoil(reply()))
        with pytest.raises(error, match=says) as e:
            bus.recv(0.0)
        assert e.value.port == path and e.value.polls == 2 and e.value.kind == kind


def test_a_bad_window_between_good_ones_is_counted_not_raised(line) -> None:
    motor, path = line
    with UartBus(path) as bus:
        bus.recv(0.0)
        for k in range(6):
            commanded(bus)
            motor.write(reply() if k % 2 else spoil_crc(reply()))
            while bus.recv(0.0) is not None:
                pass
        assert bus.bad_crc == 3 and bus.replies == 3 and bus.bad_in_row == 0


def test_a_reply_cut_short_does_not_hold_back_the_good_ones_behind_it(line) -> None:
    motor, path = line
    with UartBus(path) as bus:
        bus.recv(0.0)
        motor.write(reply()[:12])  # a header with a length that waits for bytes that never come
        assert bus.recv(0.0) is None
        motor.write(b"\x02\x30")   # noise that looks like one more header, then a good reply
        motor.write(reply())
        got = [m for m in iter(lambda: bus.recv(0.0), None)]
        assert len(got) == 1 and bus.motor_id == 3


def test_nothing_is_raised_while_the_motor_is_not_commanded_and_the_hint_says_what_came(line) -> None:
    from akarm.buses.bus import no_answer_hint

    motor, path = line
    config = serial_config(load_robot(ROBOTS / "servo3.yaml"), {"pan": path})
    with UartBus(path) as bus:
        for _ in range(5):
            assert bus.recv(0.0) is None  # silent: counted only
        assert bus.silent == 4
        assert "nothing came back on serial port" in no_answer_hint(config.buses["uart-pan"])
        motor.write(b"\x55\xaa" * 20)
        bus.recv(0.0)
        assert "no frame: check the baud rate" in no_answer_hint(config.buses["uart-pan"])
        commanded(bus)
        bus.send(frame(servo.encode_current(3, 0.0)))  # a release commands nothing, but the arming lasts
        with pytest.raises(UartSilent):
            for _ in range(3):
                bus.recv(0.0)


def test_a_port_whose_other_end_closes_is_a_bus_error(line) -> None:
    motor, path = line
    bus = UartBus(path)
    try:
        motor.close()
        with pytest.raises(BusError, match="unplugged or closed"):
            for _ in range(3):
                bus.recv(0.0)
    finally:
        bus.shutdown()


def test_bad_arguments_and_missing_ports_are_clear_errors(tmp_path, line) -> None:
    with pytest.raises(BusError, match=r"there is no .*nowhere"):
        UartBus(str(tmp_path / "nowhere"))
    with pytest.raises(ArgumentError, match="poll"):
        UartBus(line[1], poll="sometimes")
    with pytest.raises(ArgumentError, match="errors_in_row"):
        UartBus(line[1], errors_in_row=0)
    with UartBus(line[1]), pytest.raises(BusError, match="another program has the port open"):
        UartBus(line[1])


def test_python_can_opens_it_by_its_interface_name(line) -> None:
    with can.Bus(interface="akarm_uart", channel=line[1], baudrate=921600) as bus:
        assert isinstance(bus, UartBus)
    assert "akarm_uart" in can.VALID_INTERFACES and "serial" in can.VALID_INTERFACES  # python-can's own, another
