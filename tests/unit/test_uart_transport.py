"""akarm.buses.uart's pure parts: the hot path's translations agree with the codecs, the serial fault codes
map onto status error codes, serial_config and the robot file's serial-port rules, with_bus leaving
serial ports alone, the line faults' command-line form. (The bus itself: tests/sim/test_uart_bus.py.)"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akarm import AkarmError, ConfigError
from akarm.buses.uart import INTERFACE, STATUS_FIELDS, position_speed, serial_config, setup_status, to_uart
from akarm.protocol import servo, uart
from akarm.protocol.uart.packets import FaultCode, fault_code, status_code
from akarm.robotfile.load import load_robot
from akarm.sim import faults

from .conftest import ROBOTS

V = uart.ValueField


@given(st.integers(-360_000_000, 360_000_000), st.integers(-10_000, 10_000), st.integers(1, 32767))
def test_the_fast_position_speed_frame_is_the_codecs(p: int, v: int, a: int) -> None:
    aid, data = servo.encode_position_speed(7, p / 10_000, v * 10.0, a * 10.0)
    fast = position_speed(data)
    payload = uart.decode_frame(fast)
    cmd = uart.decode_command(payload)
    assert cmd.packet is uart.UartPacket.SET_POS_SPD
    assert cmd.values[0] == pytest.approx(p / 10_000, abs=0.0005 + 1e-9)  # UART: 0.001° steps
    assert cmd.values[1:] == (v * 10.0, a * 10.0)
    if p % 10 == 0:  # no rounding: the generic path's bytes exactly
        assert fast == to_uart(servo.decode_command(aid, data))


def test_a_speed_the_uart_field_cannot_hold_is_limited_to_it() -> None:
    _, data = servo.encode_position_speed(1, 10.0, 300_000.0, 1000.0)
    assert uart.decode_command(uart.decode_frame(position_speed(data))).values[1] == 100_000.0


@given(st.integers(-2_000_000_000, 2_000_000_000), st.integers(-400_000, 400_000), st.integers(-40_000, 40_000),
       st.integers(-2000, 2000), st.integers(-2000, 2000), st.integers(0, 30), st.integers(1, 127))
def test_the_fast_status_frame_is_the_codecs(udeg: int, erpm: int, iq: int, mos: int, mot: int, fault: int,
                                             motor_id: int) -> None:
    frame = uart.encode_get_values_setup_reply({V.MOSFET_TEMPERATURE: mos / 10, V.MOTOR_TEMPERATURE: mot / 10,
                                                V.IQ_CURRENT: iq / 100, V.SPEED: erpm, V.ERROR: fault,
                                                V.POSITION: udeg / 1e6, V.MOTOR_ID: motor_id})
    payload = uart.decode_frame(frame)
    aid, data = setup_status(payload)
    f = uart.decode_get_values_setup(payload, STATUS_FIELDS)
    want_aid, want = servo.encode_status(motor_id, f[V.POSITION], f[V.SPEED], f[V.IQ_CURRENT],
                                         max(f[V.MOSFET_TEMPERATURE], f[V.MOTOR_TEMPERATURE]), status_code(fault))
    assert aid == want_aid
    got, expected = servo.decode_status(aid, data), servo.decode_status(aid, want)
    # the same but where a value lies on a rounding tie (the codec's float steps can fall either side)
    assert got.motor_id == expected.motor_id and got.error == expected.error
    for x, y, step in zip(got[1:5], expected[1:5], (0.1, 10.0, 0.01, 1.0), strict=True):
        assert abs(x - y) <= step * 1.0001


def test_serial_faults_map_onto_status_codes_and_back() -> None:
    assert [status_code(f) for f in (FaultCode.NONE, FaultCode.OVER_TEMP_MOTOR, FaultCode.ABS_OVER_CURRENT,
                                     FaultCode.OVER_VOLTAGE, FaultCode.UNDER_VOLTAGE, FaultCode.ENCODER_SPI,
                                     FaultCode.OVER_TEMP_FET)] == [0, 1, 2, 3, 4, 5, 6]
    assert status_code(FaultCode.FLASH_CORRUPTION) == 0x80 + 14
    assert "flash corruption" in servo.describe_error(0x8E)[0]
    assert servo.describe_error(200)[0] == "unknown error code 200"  # not every high code is a serial one
    for code in range(7):
        assert status_code(fault_code(code)) == code
    assert fault_code(7) == FaultCode.DRV  # motor stall: no serial code of its own
    assert fault_code(0x80 + 14) == FaultCode.FLASH_CORRUPTION


def test_to_uart_refuses_a_set_pos_the_uart_field_cannot_hold() -> None:
    with pytest.raises(AkarmError, match="position"):
        to_uart(servo.decode_command(*servo.encode_position(1, 2500.0)))


def test_serial_config_moves_joints_onto_ports_of_their_own() -> None:
    servo3 = load_robot(ROBOTS / "servo3.yaml")
    one = serial_config(servo3, {"pan": "/dev/ttyUSB0"}, errors_in_row=4)
    assert one.joint("pan").bus == "uart-pan" and one.joint("elbow").bus == "arm"
    bus = one.buses["uart-pan"]
    assert (bus.interface, bus.channel, bus.options) == (INTERFACE, "/dev/ttyUSB0",
                                                         {"baudrate": 921_600, "errors_in_row": 4})
    every = serial_config(one, {"pan": "/dev/ttyUSB1", "shoulder": "/dev/ttyUSB2", "elbow": "/dev/ttyUSB3"})
    assert set(every.buses) == {"uart-pan", "uart-shoulder", "uart-elbow"}  # "arm" carries nothing any more
    assert every.buses["uart-pan"].channel == "/dev/ttyUSB1"
    with pytest.raises(AkarmError, match="MIT mode"):
        serial_config(load_robot(ROBOTS / "planar2.yaml"), {"elbow": "/dev/ttyUSB0"})


def test_bus_overrides_leave_serial_ports_alone_unless_named() -> None:
    one = serial_config(load_robot(ROBOTS / "servo3.yaml"), {"pan": "/dev/ttyUSB0"})
    moved = one.with_bus(interface="akarm_local", channel="x")
    assert moved.buses["uart-pan"] == one.buses["uart-pan"] and moved.buses["arm"].interface == "akarm_local"
    named = one.with_bus(interface="akarm_local", channel={"uart-pan": "/dev/pts/9"})
    assert (named.buses["uart-pan"].interface, named.buses["uart-pan"].channel) == (INTERFACE, "/dev/pts/9")


def write_robot(tmp_path: Path, buses: str, joints: str) -> Path:
    (tmp_path / "servo3.urdf").write_text((ROBOTS / "servo3.urdf").read_text())
    path = tmp_path / "robot.yaml"
    path.write_text("urdf: servo3.urdf\nrate_hz: 200\nbuses:\n" + textwrap.indent(textwrap.dedent(buses), "  ")
                    + "defaults: {mode: servo, status_rate_hz: 200, limits: {velocity: 2.0, acceleration: 10.0, "
                      "jerk: 100.0}}\njoints:\n" + textwrap.indent(joints, "  "))
    return path


JOINTS = """\
- {name: pan, can_id: 1, motor: AK70-10, bus: pan}
- {name: shoulder, can_id: 2, motor: AK70-10, bus: shoulder}
- {name: elbow, can_id: 3, motor: AK60-6, bus: elbow}
"""


def test_a_robot_file_puts_servo_joints_on_serial_ports(tmp_path: Path) -> None:
    config = load_robot(write_robot(tmp_path, """\
        pan: {interface: akarm_uart, channel: /dev/ttyUSB0, baudrate: 921600}
        shoulder: {interface: akarm_uart, channel: /dev/ttyUSB1, baudrate: 115200, errors_in_row: 3}
        elbow: {channel: can0}
        """, JOINTS))
    assert config.buses["pan"].options == {"baudrate": 921600}
    assert config.buses["shoulder"].options == {"baudrate": 115200, "errors_in_row": 3}


@pytest.mark.parametrize(("buses", "joints", "says"), [
    ("pan: {interface: akarm_uart, channel: /dev/ttyUSB0}\nshoulder: can0\nelbow: can1\n",
     JOINTS.replace("bus: shoulder", "bus: pan"),
     "joints pan, shoulder are on it: the serial protocol has no addresses"),
    ("pan: {interface: akarm_uart, channel: /dev/ttyUSB0}\nshoulder: can0\nelbow: can1\n",
     JOINTS.replace("bus: pan}", "bus: pan, mode: mit, gains: {kp: 10, kd: 1}}"), "MIT mode on serial port bus 'pan'"),
    ("pan: {interface: akarm_uart, channel: /dev/ttyUSB0, baudrate: fast}\nshoulder: can0\nelbow: can1\n",
     JOINTS, "baudrate"),
    ("pan: {interface: akarm_uart, channel: /dev/ttyUSB0}\nshoulder: can0\nelbow: can1\n",  # fine on CAN (±57 rad)
     JOINTS.replace("bus: pan}", "bus: pan, offset: -40.0}"),
     "outside the ±37.4807 rad a UART reply's position carries"),
])
def test_the_robot_file_refuses_what_a_serial_port_cannot_carry(tmp_path: Path, buses: str, joints: str,
                                                                says: str) -> None:
    with pytest.raises(ConfigError, match=says):
        load_robot(write_robot(tmp_path, buses, joints))


@pytest.mark.parametrize(("spec", "fault"), [
    ("pan:corrupt", faults.CorruptBytes()), ("pan:corrupt:0.5,3", faults.CorruptBytes(0.5, 3)),
    ("pan:partial:0.25", faults.PartialFrame(0.25)), ("pan:bad-crc", faults.BadCrc()),
    ("pan:bad_crc:1,9", faults.BadCrc(1.0, 9)), ("pan:silent", faults.SilentPort()),
])
def test_the_line_faults_command_line_form(spec: str, fault: faults.Fault) -> None:
    assert faults.parse(spec) == ("pan", fault)


@pytest.mark.parametrize(("spec", "says"), [("pan:silent:1", "silent takes no argument"),
                                            ("pan:partial:2", "outside 0..1"),
                                            ("pan:corrupt:1,2,3", "at most a fraction and a seed")])
def test_bad_line_fault_specs_are_clear_errors(spec: str, says: str) -> None:
    with pytest.raises(AkarmError, match=says):
        faults.parse(spec)
