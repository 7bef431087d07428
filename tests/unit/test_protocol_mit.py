"""MIT-mode codec: exact frames, the errata (byte 6, 2^bits - 1), clamping, round trips over every model."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akarm import FrameError, ProtocolError, UnknownMotorError
from akarm.protocol import mit, motors
from akarm.protocol.mit import MitCodec, MitCommand, MitReply

MODELS = motors.names()
FIELDS = ("position", "velocity", "kp", "kd", "torque")


def limits(model: motors.MotorModel) -> MitCommand:
    """Upper end of each command field (the lower ends are -max, -max, 0, 0, -max)."""
    return MitCommand(model.p_max, model.v_max, model.kp_max, model.kd_max, model.t_max)


def lower(model: motors.MotorModel) -> MitCommand:
    return MitCommand(-model.p_max, -model.v_max, 0.0, 0.0, -model.t_max)


def fields_of(frame: bytes) -> tuple[int, int, int, int, int]:
    """(p, v, kp, kd, t) integers of a V2 command, read with the notes' corrected layout byte by byte."""
    b = frame
    return ((b[0] << 8) | b[1], (b[2] << 4) | (b[3] >> 4), ((b[3] & 0xF) << 8) | b[4],
            (b[5] << 4) | (b[6] >> 4), ((b[6] & 0xF) << 8) | b[7])


# ---- hand-computed frames ------------------------------------------------------------------
#
# AK80-9: P ±12.5 rad, V ±50 rad/s, T ±18 N·m, Kp 0..500, Kd 0..5; u = (x - min)·(2^bits - 1)/span,
# rounded to nearest (an exact tie to the lower code).
#
# 1. all zero: p = 12.5·65535/25 = 32767.5 (tie) → 0x7FFF; v = 50·4095/100 = 2047.5 (tie) → 0x7FF;
#    kp = kd = 0 → 0; t = 18·4095/36 = 2047.5 (tie) → 0x7FF.
#    → 7F FF | 7F | F0 (v low nibble F, kp high nibble 0) | 00 | 00 | 07 (kd low nibble 0, t high 7) | FF
# 2. every field at its extreme: p = +12.5 → 0xFFFF, v = -50 → 0x000, kp = 500 → 0xFFF, kd = 5 → 0xFFF,
#    t = +18 → 0xFFF → FF FF | 00 | 0F | FF | FF | FF | FF
# 3. p = 1 rad: 13.5·65535/25 = 35388.9 → 35389 = 0x8A3D; v = 10: 60·4095/100 = 2457 = 0x999;
#    kp = 100: 100·4095/500 = 819 = 0x333; kd = 1: 1·4095/5 = 819 = 0x333; t = -3: 15·4095/36 = 1706.25
#    → 1706 = 0x6AA → 8A 3D | 99 | 93 | 33 | 33 | 36 | AA
# 4. AK10-9 (T ±65): p = -12.5 → 0x0000, v = 0 → 0x7FF, kp = kd = 0, t = +65 → 0xFFF
#    → 00 00 | 7F | F0 | 00 | 00 | 0F | FF
HAND_FRAMES = [
    ("AK80-9", (0.0, 0.0, 0.0, 0.0, 0.0), "7F FF 7F F0 00 00 07 FF"),
    ("AK80-9", (12.5, -50.0, 500.0, 5.0, 18.0), "FF FF 00 0F FF FF FF FF"),
    ("AK80-9", (1.0, 10.0, 100.0, 1.0, -3.0), "8A 3D 99 93 33 33 36 AA"),
    ("AK10-9", (-12.5, 0.0, 0.0, 0.0, 65.0), "00 00 7F F0 00 00 0F FF"),
]


@pytest.mark.parametrize(("model", "values", "frame"), HAND_FRAMES)
def test_hand_computed_command_frames(model: str, values: tuple[float, ...], frame: str) -> None:
    assert mit.encode_command(model, *values) == bytes.fromhex(frame)
    assert mit.codec(model).encode_command(*values) == bytes.fromhex(frame)


def test_special_frames_are_the_documented_bytes() -> None:
    assert bytes.fromhex("FF FF FF FF FF FF FF FC") == mit.ENTER
    assert bytes.fromhex("FF FF FF FF FF FF FF FD") == mit.EXIT
    assert bytes.fromhex("FF FF FF FF FF FF FF FE") == mit.ZERO
    assert mit.special_frame(mit.ENTER) == "enter"
    assert mit.special_frame(bytearray(mit.EXIT)) == "exit"
    assert mit.special_frame(mit.ZERO) == "zero"
    assert mit.special_frame(bytes.fromhex("FF FF FF FF FF FF FF FB")) is None
    assert mit.special_frame(mit.ENTER[:7]) is None
    assert mit.special_frame(mit.encode_command("AK80-9", 0, 0, 0, 0, 0)) is None


def test_decode_command_refuses_a_special_frame() -> None:
    with pytest.raises(ProtocolError, match="'enter' special frame"):
        mit.decode_command("AK80-9", mit.ENTER)


# ---- the errata: byte 6 and the (2^bits - 1) scale ------------------------------------------------


@pytest.mark.parametrize("name", MODELS)
def test_values_at_the_range_ends_do_not_wrap_or_spill(name: str) -> None:
    m = motors.get(name)
    hi = mit.encode_command(m, *limits(m))
    assert hi == bytes.fromhex("FF FF FF FF FF FF FF FF")
    assert fields_of(hi) == (0xFFFF, 0xFFF, 0xFFF, 0xFFF, 0xFFF)
    lo = mit.encode_command(m, *lower(m))
    assert lo == bytes(8)
    # p = +p_max alone is 0xFFFF (the manual's 2^16/span formula gives 0x10000, i.e. -p_max)
    assert mit.encode_command(m, m.p_max, 0, 0, 0, 0)[:2] == b"\xff\xff"
    # a 12-bit field at its maximum leaves its neighbours' nibbles alone
    frame = mit.encode_command(m, -m.p_max, -m.v_max, m.kp_max, 0, -m.t_max)
    assert frame == bytes.fromhex("00 00 00 0F FF 00 00 00")


@pytest.mark.parametrize("name", MODELS)
def test_byte6_carries_kd_low_nibble_and_torque_high_nibble(name: str) -> None:
    m = motors.get(name)
    # kd = max (0xFFF), t = -max (0x000): byte5 = FF, byte6 = F0, byte7 = 00
    f = mit.encode_command(m, 0, 0, 0, m.kd_max, -m.t_max)
    assert (f[5], f[6], f[7]) == (0xFF, 0xF0, 0x00)
    # kd = 0, t = +max: byte6 = 0F; kp at its max must not appear in byte 6 (the manual's erratum put it there)
    f = mit.encode_command(m, 0, 0, m.kp_max, 0, m.t_max)
    assert (f[3] & 0x0F, f[4], f[5], f[6], f[7]) == (0x0F, 0xFF, 0x00, 0x0F, 0xFF)
    # kd = 1/15 of its range: 0x111 → byte5 = 11, byte6 high nibble = 1
    f = mit.encode_command(m, 0, 0, 0, m.kd_max * 0x111 / 0xFFF, -m.t_max)
    assert (f[5], f[6]) == (0x11, 0x10)


@pytest.mark.parametrize("name", MODELS)
def test_out_of_range_values_clamp(name: str) -> None:
    m = motors.get(name)
    c = mit.codec(m)
    assert c.encode_command(*(2 * x + 1 for x in limits(m))) == c.encode_command(*limits(m))
    assert c.encode_command(*(math.inf,) * 5) == c.encode_command(*limits(m))
    assert c.encode_command(-1e9, -1e9, -1.0, -1.0, -1e9) == c.encode_command(*lower(m))
    assert c.encode_command(-math.inf, -math.inf, -math.inf, -math.inf, -math.inf) == bytes(8)
    assert c.encode_reply(1, 100.0, 1e6, -1e6)[1:6] == bytes.fromhex("FF FF FF F0 00")


@pytest.mark.parametrize("field", FIELDS)
def test_nan_raises_naming_the_field(field: str) -> None:
    values = dict.fromkeys(FIELDS, 0.0)
    values[field] = math.nan
    with pytest.raises(ProtocolError, match=rf"MIT {field} is NaN"):
        mit.encode_command("AK80-9", *values.values())
    with pytest.raises(ProtocolError, match=rf"MIT {field} is NaN"):
        mit.encode_command("AK80-9", *values.values(), firmware="v3")


def test_non_numbers_raise_protocol_error() -> None:
    with pytest.raises(ProtocolError, match="kd must be a real number"):
        mit.encode_command("AK80-9", 0.0, 0.0, 1.0, "fast", 0.0)  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="NaN"):
        mit.encode_reply("AK80-9", 1, math.nan, 0.0, 0.0)
    with pytest.raises(ProtocolError, match="temperature is NaN"):
        mit.encode_reply("AK80-9", 1, 0.0, 0.0, 0.0, temperature=math.nan)


def test_zero_is_a_tie_that_goes_to_the_lower_code_for_every_model() -> None:
    for name in MODELS:
        p, v, _kp, _kd, t = fields_of(mit.encode_command(name, 0.0, 0.0, 0.0, 0.0, 0.0))
        assert (p, v, t) == (0x7FFF, 0x7FF, 0x7FF), name
        # just above zero rounds up to the upper neighbour
        c = mit.codec(name)
        assert fields_of(c.encode_command(c.steps.position * 0.01, 0, 0, 0, 0))[0] == 0x8000, name


def test_firmware_must_be_known() -> None:
    with pytest.raises(ProtocolError, match="unknown MIT firmware 'v4'"):
        mit.encode_command("AK80-9", 0, 0, 0, 0, 0, firmware="v4")  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="unknown MIT firmware"):
        mit.command_arbitration_id(1, "v1")  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="unknown MIT firmware"):
        mit.decode_command("AK80-9", bytes(8), firmware="x")  # type: ignore[arg-type]


# ---- round trips over every catalogue model ---------------------------------------------------------


@st.composite
def command(draw: st.DrawFn) -> tuple[str, MitCommand]:
    name = draw(st.sampled_from(MODELS))
    m = motors.get(name)
    vals = [draw(st.floats(lo, hi, allow_nan=False)) for lo, hi in zip(lower(m), limits(m), strict=True)]
    return name, MitCommand(*vals)


@settings(max_examples=250, deadline=None)
@given(cmd=command(), firmware=st.sampled_from(["v2", "v3"]))
def test_command_round_trip_within_half_a_step(cmd: tuple[str, MitCommand], firmware: str) -> None:
    name, x = cmd
    c = mit.codec(name)
    frame = mit.encode_command(name, *x, firmware=firmware)  # type: ignore[arg-type]
    assert len(frame) == 8
    back = mit.decode_command(name, frame, firmware=firmware)  # type: ignore[arg-type]
    for f, want, got, step in zip(FIELDS, x, back, c.steps, strict=True):
        assert abs(got - want) <= step / 2 * (1 + 1e-9), (f, want, got, step)
    # re-encoding the decoded command gives the same bytes: decoding lands on the code's own value
    assert c.encode_command(*back, firmware=firmware) == frame  # type: ignore[arg-type]


@settings(max_examples=250, deadline=None)
@given(cmd=command(), driver=st.integers(0, 255), temp=st.integers(-20, 120), err=st.integers(0, 7),
       offset=st.sampled_from([0.0, 40.0]))
def test_reply_round_trip_within_half_a_step(cmd: tuple[str, MitCommand], driver: int, temp: int, err: int,
                                             offset: float) -> None:
    name, x = cmd
    m = replace(motors.get(name), mit_temp_offset=offset)
    c = MitCodec(m)
    data = c.encode_reply(driver, x.position, x.velocity, x.torque, temp, err)
    r = mit.decode_reply(m, data)
    assert r.driver_id == driver and r.error == err
    assert r.temperature == (max(0, temp + offset) - offset)
    for want, got, step in ((x.position, r.position, c.steps.position), (x.velocity, r.velocity, c.steps.velocity),
                            (x.torque, r.torque, c.steps.torque)):
        assert abs(got - want) <= step / 2 * (1 + 1e-9)
    short = mit.decode_reply(m, c.encode_reply(driver, x.position, x.velocity, x.torque, length=6))
    assert short[:4] == r[:4] and short.temperature is None and short.error is None


# ---- replies --------------------------------------------------------------------------------------------


def test_decode_eight_byte_reply() -> None:
    # id 5, p = 0xFFFF (+12.5), v = 0x000 (-50), i = 0xFFF (+18), temperature byte 30, error 2
    r = mit.decode_reply("AK80-9", bytes.fromhex("05 FF FF 00 0F FF 1E 02"))
    assert r == MitReply(5, 12.5, -50.0, 18.0, 30.0, 2)
    assert isinstance(r, MitReply) and r.temperature == 30.0
    # p = 0x0000, v = 0xFFF, i = 0x000; a bytearray (what python-can hands out) works as well
    r = mit.decode_reply("AK80-9", bytearray.fromhex("01 00 00 FF F0 00 28 00"))
    assert (r.driver_id, r.position, r.velocity, r.torque, r.temperature, r.error) == (1, -12.5, 50.0, -18.0, 40.0, 0)


def test_decode_six_byte_reply_has_no_temperature_or_error() -> None:
    r = mit.decode_reply("AK80-9", bytes.fromhex("05 FF FF 00 0F FF"))
    assert r == MitReply(5, 12.5, -50.0, 18.0, None, None)


def test_temperature_offset_is_subtracted() -> None:
    m = replace(motors.get("AK80-9"), name="AK80-9-hot", mit_temp_offset=40)
    assert mit.decode_reply(m, bytes.fromhex("05 FF FF 00 0F FF 1E 02")).temperature == -10.0
    assert mit.encode_reply(m, 5, 12.5, -50, 18, temperature=-10, error=2) == bytes.fromhex("05 FF FF 00 0F FF 1E 02")


def test_encode_reply_temperature_byte_is_rounded_and_clamped() -> None:
    assert mit.encode_reply("AK80-9", 1, 0, 0, 0, temperature=36.6)[6] == 37
    assert mit.encode_reply("AK80-9", 1, 0, 0, 0, temperature=-30)[6] == 0
    assert mit.encode_reply("AK80-9", 1, 0, 0, 0, temperature=300)[6] == 255
    with pytest.raises(ProtocolError, match="driver id 256"):
        mit.encode_reply("AK80-9", 256, 0, 0, 0)
    with pytest.raises(ProtocolError, match="error code -1"):
        mit.encode_reply("AK80-9", 1, 0, 0, 0, error=-1)
    with pytest.raises(ProtocolError, match="6 or 8 bytes"):
        mit.encode_reply("AK80-9", 1, 0, 0, 0, length=7)


@pytest.mark.parametrize("n", [0, 1, 5, 7, 9, 16])
def test_reply_of_wrong_length_is_a_frame_error(n: int) -> None:
    with pytest.raises(FrameError, match=f"6 or 8 data bytes, this one {n}"):
        mit.decode_reply("AK80-9", bytes(n))


@pytest.mark.parametrize("n", [0, 6, 7, 9])
def test_command_of_wrong_length_is_a_frame_error(n: int) -> None:
    with pytest.raises(FrameError, match="8 data bytes"):
        mit.decode_command("AK80-9", bytes(n))


def test_decode_takes_any_bytes_like_and_rejects_the_rest_with_a_frame_error() -> None:
    want = MitReply(5, 12.5, -50.0, 18.0, 30.0, 2)
    raw = bytes.fromhex("05 FF FF 00 0F FF 1E 02")
    assert mit.decode_reply("AK80-9", memoryview(raw)) == want
    assert mit.decode_reply("AK80-9", list(raw)) == want  # type: ignore[arg-type]
    for bad in (None, [1, 2, 300, 4, 5, 6, 7, 8], "05FFFF000FFF1E02"):
        with pytest.raises(FrameError):
            mit.decode_reply("AK80-9", bad)  # type: ignore[arg-type]


# ---- V3 boards ----------------------------------------------------------------------------------------


def test_arbitration_ids() -> None:
    assert mit.command_arbitration_id(1) == (1, False)
    assert mit.command_arbitration_id(0x7F, "v2") == (0x7F, False)
    assert mit.command_arbitration_id(1, "v3") == (0x801, True)
    assert mit.command_arbitration_id(0xFF, "v3") == (0x8FF, True)
    for bad in (-1, 256):
        with pytest.raises(ProtocolError, match="motor id"):
            mit.command_arbitration_id(bad)


def test_v3_command_layout_puts_kp_first() -> None:
    # AK70-9 (V3): P ±12.5, V ±30, T ±32. kp = 500 → FFF, kd = 0 → 000, p = 0 → 7FFF, v = +30 → FFF, t = -32 → 000
    # [kp11:4][kp3:0|kd11:8][kd7:0][p15:8][p7:0][v11:4][v3:0|t11:8][t7:0] = FF F0 00 7F FF FF F0 00
    frame = mit.encode_command("AK70-9", 0.0, 30.0, 500.0, 0.0, -32.0, firmware="v3")
    assert frame == bytes.fromhex("FF F0 00 7F FF FF F0 00")
    # the same command in the V2 layout: 7F FF | FF | FF (v low F, kp high F) | FF | 00 | 00 | 00
    assert mit.encode_command("AK70-9", 0.0, 30.0, 500.0, 0.0, -32.0) == bytes.fromhex("7F FF FF FF FF 00 00 00")
    # kd = 5 (FFF) and t = +32 (FFF), the rest at the bottom: 00 0F FF 00 00 00 0F FF
    frame = mit.encode_command("AK70-9", -12.5, -30.0, 0.0, 5.0, 32.0, firmware="v3")
    assert frame == bytes.fromhex("00 0F FF 00 00 00 0F FF")
    assert mit.decode_command("AK70-9", frame, firmware="v3") == MitCommand(-12.5, -30.0, 0.0, 5.0, 32.0)


def test_v3_reply_is_a_status_frame_converted_to_si() -> None:
    m = motors.get("AK70-9")  # 14 pole pairs, 9:1, kt 0.13 N·m/A, position at the output
    # position 900 (90.0°), speed 100 (1000 ERPM), current 250 (2.5 A), 30 °C, error 0
    r = mit.decode_reply_v3(m, 0x2905, bytes.fromhex("03 84 00 64 00 FA 1E 00"))
    assert r.driver_id == 5 and r.temperature == 30.0 and r.error == 0
    assert r.position == pytest.approx(math.pi / 2)
    assert r.velocity == pytest.approx(1000 * 2 * math.pi / (60 * 14 * 9))
    assert r.torque == pytest.approx(2.5 * 0.13 * 9)
    # negative values, and a model whose servo position is measured at the rotor
    rotor = replace(m, name="AK70-9-rotor", servo_position="rotor")
    r = mit.decode_reply_v3(rotor, 0x2901, bytes.fromhex("FC 7C FF 9C FF 06 EC 01"))
    assert r.position == pytest.approx(-math.radians(90.0) / 9)
    assert r.velocity == pytest.approx(-1000 * 2 * math.pi / (60 * 14 * 9))
    assert r.torque == pytest.approx(-2.5 * 0.13 * 9)
    assert (r.temperature, r.error) == (-20.0, 1)


@pytest.mark.parametrize(("aid", "ext", "n"), [(0x0805, True, 8), (0x12905, True, 8), (0x2905, False, 8),
                                                (0x2905, True, 6)])
def test_v3_reply_refuses_anything_but_an_8_byte_29xx_extended_frame(aid: int, ext: bool, n: int) -> None:
    with pytest.raises(FrameError):
        mit.decode_reply_v3("AK70-9", aid, bytes(n), is_extended=ext)


# ---- codec cache ----------------------------------------------------------------------------------------


def test_codec_is_cached_per_model_and_name() -> None:
    m = motors.get("AK80-9")
    assert mit.codec("AK80-9") is mit.codec("ak80-9") is mit.codec(m)
    assert mit.codec("AK80-9") is not mit.codec("AK10-9")
    assert repr(mit.codec(m)) == "MitCodec('AK80-9')"
    other = replace(m, name="AK80-9-slow", v_max=25.0)
    assert mit.codec(other).model is other
    # a model with the same name but other ranges gets its own codec, not the cached one
    assert mit.encode_command(other, 0, 25.0, 0, 0, 0) != mit.encode_command(m, 0, 25.0, 0, 0, 0)


def test_unknown_model_name_is_an_akarm_error() -> None:
    with pytest.raises(UnknownMotorError):
        mit.encode_command("AK99-1", 0, 0, 0, 0, 0)
