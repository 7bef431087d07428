"""Servo mode over CAN: IDs, scalings (the notes', not the seed's), range errors, status frames."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akarm import FrameError, ProtocolError
from akarm.protocol import servo
from akarm.protocol.servo import OriginMode, ServoCommand, ServoErrorCode, ServoPacket, ServoStatus

# (encoder, motor id, arguments, expected extended ID, expected data, decoded values)
# Worked by hand: 0.2 duty × 100 000 = 20 000 = 0x4E20; 5 A = 5000 mA = 0x1388; 1000 ERPM = 0x3E8;
# 180° × 10 000 = 1 800 000 = 0x1B7740 (the seed's × 1 000 000 would be 0x0ABA9500);
# -90° × 10 000 = -900 000 = 0xFFF24460; SET_POS_SPD speed 5000 ERPM / 10 = 500 = 0x01F4,
# acceleration 30 000 ERPM/s / 10 = 3000 = 0x0BB8.
COMMANDS: list[tuple[Callable[..., tuple[int, bytes]], int, tuple[float, ...], int, str, tuple[float, ...]]] = [
    (servo.encode_duty, 1, (0.2,), 0x001, "00 00 4E 20", (0.2,)),
    (servo.encode_duty, 1, (-0.2,), 0x001, "FF FF B1 E0", (-0.2,)),
    (servo.encode_duty, 0x68, (1.0,), 0x068, "00 01 86 A0", (1.0,)),
    (servo.encode_current, 2, (5.0,), 0x102, "00 00 13 88", (5.0,)),
    (servo.encode_current, 2, (-5.0,), 0x102, "FF FF EC 78", (-5.0,)),
    (servo.encode_current, 2, (-60.0,), 0x102, "FF FF 15 A0", (-60.0,)),
    (servo.encode_current_brake, 3, (5.0,), 0x203, "00 00 13 88", (5.0,)),
    (servo.encode_current_brake, 3, (0.0,), 0x203, "00 00 00 00", (0.0,)),
    (servo.encode_rpm, 4, (1000.0,), 0x304, "00 00 03 E8", (1000.0,)),
    (servo.encode_rpm, 4, (-1000.0,), 0x304, "FF FF FC 18", (-1000.0,)),
    (servo.encode_position, 5, (180.0,), 0x405, "00 1B 77 40", (180.0,)),
    (servo.encode_position, 5, (-90.0,), 0x405, "FF F2 44 60", (-90.0,)),
    (servo.encode_position, 5, (36000.0,), 0x405, "15 75 2A 00", (36000.0,)),
    (servo.encode_origin, 6, (0,), 0x506, "00", (0.0,)),
    (servo.encode_origin, 6, (1,), 0x506, "01", (1.0,)),
    (servo.encode_origin, 6, (OriginMode.RESTORE_DEFAULT,), 0x506, "02", (2.0,)),
    (servo.encode_position_speed, 7, (180.0, 5000.0, 30000.0), 0x607, "00 1B 77 40 01 F4 0B B8",
     (180.0, 5000.0, 30000.0)),
    (servo.encode_position_speed, 0xFF, (-90.0, -1000.0, 0.0), 0x6FF, "FF F2 44 60 FF 9C 00 00",
     (-90.0, -1000.0, 0.0)),
]


@pytest.mark.parametrize(("encode", "motor", "args", "aid", "data", "values"), COMMANDS)
def test_command_ids_and_exact_bytes(encode: Callable[..., tuple[int, bytes]], motor: int, args: tuple[float, ...],
                                     aid: int, data: str, values: tuple[float, ...]) -> None:
    assert encode(motor, *args) == (aid, bytes.fromhex(data))
    cmd = servo.decode_command(aid, bytes.fromhex(data))
    assert cmd == ServoCommand(ServoPacket(aid >> 8), motor, values)


def test_packet_numbers() -> None:
    assert [int(p) for p in ServoPacket] == [0, 1, 2, 3, 4, 5, 6, 0x29]
    assert ServoPacket.SET_POS_SPD == 6 and ServoPacket.STATUS == 0x29
    assert set(servo.ENCODERS) == set(ServoPacket) - {ServoPacket.STATUS}


def test_values_round_to_the_nearest_step_not_down() -> None:
    # 0.29 × 100 000 is 28 999.999... in binary: truncating (the seed's C cast) would send 28 999
    assert servo.encode_duty(1, 0.29)[1] == (29_000).to_bytes(4, "big")
    assert servo.encode_position(1, 0.00006)[1] == (1).to_bytes(4, "big")
    assert servo.encode_position_speed(1, 0, 1234.0, 16.0)[1][4:] == bytes.fromhex("00 7B 00 02")


@pytest.mark.parametrize(("call", "message"), [
    (lambda: servo.encode_duty(1, 1.01), r"duty 1.01 +is outside the range -1 \.\. 1"),
    (lambda: servo.encode_current(1, 60.5), r"current 60.5 A is outside the range -60 \.\. 60 A"),
    (lambda: servo.encode_current(1, -61), r"-60 \.\. 60 A"),
    (lambda: servo.encode_current_brake(1, -0.1), r"brake current -0.1 A is outside the range 0 \.\. 60 A"),
    (lambda: servo.encode_current_brake(1, 61), r"0 \.\. 60 A"),
    (lambda: servo.encode_rpm(1, 100_001), r"speed 100001 ERPM is outside the range -100000 \.\. 100000 ERPM"),
    (lambda: servo.encode_position(1, 36_000.5), r"position 36000.5 deg is outside the range -36000 \.\. 36000"),
    (lambda: servo.encode_position(1, -36_001), r"-36000 \.\. 36000 deg"),
    (lambda: servo.encode_origin(1, 3), r"origin mode 3 is outside the range 0 \.\. 2"),
    (lambda: servo.encode_origin(1, 1.5), r"origin mode must be 0, 1 or 2"),
    (lambda: servo.encode_position_speed(1, 0, 400_000, 0), r"speed 400000 ERPM is outside .*-327680 \.\. 327670"),
    (lambda: servo.encode_position_speed(1, 0, 1000, -10), r"acceleration -10 ERPM/s is outside .*0 \.\. 327670"),
    (lambda: servo.encode_position_speed(1, 40_000, 1000, 10), r"position 40000 deg"),
    (lambda: servo.encode_position(1, math.nan), r"position nan deg is outside"),
    (lambda: servo.encode_rpm(1, math.inf), r"speed inf ERPM is outside"),
    (lambda: servo.encode_current(1, "5"), r"current must be a number"),
    (lambda: servo.encode_duty(256, 0.1), r"motor id 256 is outside 0-255"),
    (lambda: servo.encode_duty(-1, 0.1), r"motor id -1 is outside 0-255"),
    (lambda: servo.encode_duty(1.0, 0.1), r"motor id must be an integer"),
])
def test_out_of_range_values_raise_naming_the_range(call: Callable[[], object], message: str) -> None:
    with pytest.raises(ProtocolError, match=message):
        call()


# ---- status frames -------------------------------------------------------------------------------------


def test_decode_status_positive() -> None:
    # 900 → 90.0°, 100 → 1000 ERPM, 250 → 2.5 A, 30 °C, error 0
    st_ = servo.decode_status(0x2905, bytes.fromhex("03 84 00 64 00 FA 1E 00"))
    assert st_ == ServoStatus(5, 90.0, 1000.0, 2.5, 30.0, 0)


def test_decode_status_negative_fields() -> None:
    # -1234 → -123.4°, -50 → -500 ERPM, -250 → -2.5 A, -20 °C, error 2 (over-current)
    st_ = servo.decode_status(0x29FF, bytearray.fromhex("FB 2E FF CE FF 06 EC 02"))
    assert st_ == ServoStatus(0xFF, -123.4, -500.0, -2.5, -20.0, 2)
    # extremes of the int16 / int8 fields
    st_ = servo.decode_status(0x2900, bytes.fromhex("80 00 7F FF 80 00 80 FF"))
    assert st_ == ServoStatus(0, -3276.8, 327670.0, -327.68, -128.0, 255)


@pytest.mark.parametrize(("aid", "ext"), [
    (0x0901, True),     # packet 9: not a status frame, though its low byte is a motor id
    (0x0101, True),     # a SET_CURRENT command
    (0x2801, True),
    (0x2A01, True),
    (0x12901, True),    # 0x29 in bits 8-15 but bits above set
    (0x1FF2901, True),
    (0x29, True),       # 0x29 in the low byte only
    (0x2901, False),    # a standard frame cannot be a servo status frame
    (0x701, False),
    (-1, True),
    (0x2000_0000, True),  # wider than 29 bits
])
def test_decode_status_refuses_other_ids(aid: int, ext: bool) -> None:
    with pytest.raises(FrameError):
        servo.decode_status(aid, bytes(8), is_extended=ext)


def test_decode_takes_any_bytes_like_and_rejects_the_rest() -> None:
    raw = bytes.fromhex("03 84 00 64 00 FA 1E 00")
    assert servo.decode_status(0x2905, list(raw)) == servo.decode_status(0x2905, memoryview(raw))  # type: ignore[arg-type]
    for bad in (None, 8, "0384006400FA1E00", [0, 0, 0, 0, 0, 0, 0, 256]):
        with pytest.raises(FrameError, match="must be bytes"):
            servo.decode_status(0x2905, bad)  # type: ignore[arg-type]
        with pytest.raises(FrameError, match="must be bytes"):
            servo.decode_command(0x105, bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("n", [0, 6, 7, 9])
def test_decode_status_refuses_wrong_length(n: int) -> None:
    with pytest.raises(FrameError, match=f"{n} data bytes, not 8"):
        servo.decode_status(0x2901, bytes(n))


def test_encode_status_exact_and_round_trip() -> None:
    aid, data = servo.encode_status(0xFF, -123.4, -500.0, -2.5, -20.0, 2)
    assert (aid, data) == (0x29FF, bytes.fromhex("FB 2E FF CE FF 06 EC 02"))
    assert servo.status_arbitration_id(7) == 0x2907


def test_encode_status_saturates_and_refuses_nan() -> None:
    _, data = servo.encode_status(1, 1e6, -1e9, 1000.0, 500.0, 0)
    assert data == bytes.fromhex("7F FF 80 00 7F FF 7F 00")
    with pytest.raises(ProtocolError, match="position is NaN"):
        servo.encode_status(1, math.nan, 0, 0, 25)
    with pytest.raises(ProtocolError, match="error code 300"):
        servo.encode_status(1, 0, 0, 0, 25, 300)


@settings(max_examples=200, deadline=None)
@given(motor=st.integers(0, 255), pos=st.floats(-3276.8, 3276.7), speed=st.floats(-327_680, 327_670),
       amps=st.floats(-327.68, 327.67), temp=st.integers(-128, 127), err=st.integers(0, 255))
def test_status_round_trip(motor: int, pos: float, speed: float, amps: float, temp: int, err: int) -> None:
    s = servo.decode_status(*servo.encode_status(motor, pos, speed, amps, temp, err))
    assert s.motor_id == motor and s.temperature_c == temp and s.error == err
    assert abs(s.position_deg - pos) <= 0.05 + 1e-9
    assert abs(s.speed_erpm - speed) <= 5 + 1e-6
    assert abs(s.current_a - amps) <= 0.005 + 1e-9


@settings(max_examples=200, deadline=None)
@given(motor=st.integers(0, 255), deg=st.floats(-36_000, 36_000), erpm=st.floats(-327_680, 327_670),
       acc=st.floats(0, 327_670))
def test_position_speed_round_trip(motor: int, deg: float, erpm: float, acc: float) -> None:
    cmd = servo.decode_command(*servo.encode_position_speed(motor, deg, erpm, acc))
    assert cmd.packet is ServoPacket.SET_POS_SPD and cmd.motor_id == motor
    d, e, a = cmd.values
    assert abs(d - deg) <= 0.5e-4 + 1e-9 and abs(e - erpm) <= 5 + 1e-6 and abs(a - acc) <= 5 + 1e-6


# ---- motor side: malformed commands ----------------------------------------------------------------------


@pytest.mark.parametrize(("aid", "data", "ext", "message"), [
    (0x601, "00 1B 77 40", True, "SET_POS_SPD frame has 4 data bytes, not 8"),  # the seed's 4-byte send
    (0x401, "00 1B 77 40 00", True, "SET_POS frame has 5 data bytes, not 4"),
    (0x501, "", True, "SET_ORIGIN_HERE frame has 0 data bytes, not 1"),
    (0x501, "03", True, r"origin mode 3 .*outside"),
    (0x201, "FF FF EC 78", True, r"brake current -5 A is outside"),
    (0x001, "00 01 86 A1", True, r"duty 1.00001 .*outside"),
    (0x701, "00 00 00 00", True, "not a servo command"),
    (0x2901, "00" * 8, True, "not a servo command"),
    (0x10101, "00 00 00 00", True, "not a servo command"),
    (0x101, "00 00 13 88", False, "standard frame"),
])
def test_decode_command_refuses_malformed_frames(aid: int, data: str, ext: bool, message: str) -> None:
    with pytest.raises(FrameError, match=message):
        servo.decode_command(aid, bytes.fromhex(data), is_extended=ext)


# ---- error codes ----------------------------------------------------------------------------------------


def test_error_codes_have_description_and_remedy() -> None:
    assert [int(c) for c in ServoErrorCode] == list(range(8))
    for code in ServoErrorCode:
        assert code.description and code.remedy and "\n" not in code.description + code.remedy
        assert servo.describe_error(int(code)) == (code.description, code.remedy)
    assert ServoErrorCode.MOTOR_OVER_TEMPERATURE.remedy == "let it cool; lower the duty or add cooling"
    assert ServoErrorCode(2) is ServoErrorCode.OVER_CURRENT
    assert "MOSFET" in ServoErrorCode.MOSFET_OVER_TEMPERATURE.description
    assert ServoErrorCode.MOTOR_STALL.description == "motor stall"


def test_unknown_error_codes_are_still_described() -> None:
    desc, remedy = servo.describe_error(42)
    assert desc == "unknown error code 42" and remedy
    desc, _ = servo.describe_error("x")  # type: ignore[arg-type]
    assert desc == "unknown error code 'x'"
    assert servo.describe_error(ServoErrorCode.OVER_VOLTAGE)[0].startswith("supply over-voltage")
