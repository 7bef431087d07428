"""Servo mode over UART: every example frame of the manual, its two errata, framing, the stream decoder."""

from __future__ import annotations

import binascii
import math
import struct
from collections.abc import Callable
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akarm import FrameError, ProtocolError
from akarm.protocol import uart
from akarm.protocol.uart import (
    FaultCode,
    FirmwareVersion,
    FrameDecoder,
    GetValues,
    RotorPosition,
    UartCommand,
    UartPacket,
    ValueField,
)

P = UartPacket

# Commands the controller sends, as printed in the manual (§5.2.2), with the value each carries.
# (frame as printed, encoder, its arguments, the command decoded back)
MANUAL_COMMANDS: list[tuple[str, Callable[..., bytes], tuple[float, ...], UartCommand]] = [
    ("02 01 04 40 84 03", uart.encode_get_values, (), UartCommand(P.GET_VALUES, ())),
    ("02 02 0B 04 9C 7E 03", uart.encode_detect, (4,), UartCommand(P.SET_DETECT, (4.0,))),
    ("02 05 32 00 00 00 01 58 4C 03", uart.encode_get_values_setup, (ValueField.MOSFET_TEMPERATURE,),
     UartCommand(P.GET_VALUES_SETUP, (1.0,))),
    ("02 05 05 00 00 4E 20 29 F6 03", uart.encode_duty, (0.2,), UartCommand(P.SET_DUTY, (0.2,))),
    ("02 05 05 FF FF B1 E0 77 85 03", uart.encode_duty, (-0.2,), UartCommand(P.SET_DUTY, (-0.2,))),
    ("02 05 06 00 00 13 88 8B 25 03", uart.encode_current, (5.0,), UartCommand(P.SET_CURRENT, (5.0,))),
    ("02 05 06 FF FF EC 78 E3 05 03", uart.encode_current, (-5.0,), UartCommand(P.SET_CURRENT, (-5.0,))),
    ("02 05 07 00 00 13 88 21 74 03", uart.encode_current_brake, (5.0,), UartCommand(P.SET_CURRENT_BRAKE, (5.0,))),
    ("02 05 07 FF FF EC 78 49 54 03", uart.encode_current_brake, (-5.0,),
     UartCommand(P.SET_CURRENT_BRAKE, (-5.0,))),
    ("02 05 08 00 00 03 E8 2B 58 03", uart.encode_rpm, (1000.0,), UartCommand(P.SET_RPM, (1000.0,))),
    ("02 05 08 FF FF FC 18 43 78 03", uart.encode_rpm, (-1000.0,), UartCommand(P.SET_RPM, (-1000.0,))),
    # 180° as printed has CRC 1EE7, an erratum: the corrected frame (1EF7) is here, the printed one below
    ("02 05 09 0A BA 95 00 1E F7 03", uart.encode_position, (180.0,), UartCommand(P.SET_POS, (180.0,))),
    ("02 05 09 05 5D 4A 80 7B 29 03", uart.encode_position, (90.0,), UartCommand(P.SET_POS, (90.0,))),
    ("02 05 0A 00 00 13 88 00 0E 03", uart.encode_handbrake, (5.0,), UartCommand(P.SET_HANDBRAKE, (5.0,))),
    # printed with the comment "5A": the bytes say -5 A
    ("02 05 0A FF FF EC 78 68 2E 03", uart.encode_handbrake, (-5.0,), UartCommand(P.SET_HANDBRAKE, (-5.0,))),
    ("02 0D 5B 00 02 BF 20 00 00 13 88 00 00 75 30 A5 AC 03", uart.encode_position_speed, (180.0, 5000.0, 30000.0),
     UartCommand(P.SET_POS_SPD, (180.0, 5000.0, 30000.0))),
    ("02 05 5C 00 00 00 00 9E 19 03", uart.encode_multi_turn, (), UartCommand(P.SET_POS_MULTI, (0.0,))),
    ("02 05 5D 00 00 00 00 34 48 03", uart.encode_single_turn, (), UartCommand(P.SET_POS_SINGLE, (0.0,))),
    ("02 02 5F 01 0E A0 03", uart.encode_origin, (1,), UartCommand(P.SET_POS_ORIGIN, (1.0,))),
]


@pytest.mark.parametrize(("frame", "encode", "args", "command"), MANUAL_COMMANDS)
def test_manual_command_frames_encode_and_decode(frame: str, encode: Callable[..., bytes], args: tuple[float, ...],
                                                 command: UartCommand) -> None:
    raw = bytes.fromhex(frame)
    assert encode(*args) == raw
    payload = uart.decode_frame(raw)
    assert uart.decode_command(payload) == command
    dec = FrameDecoder()
    assert dec.feed(raw) == [payload] and not dec.errors


ROTOR_FRAMES = [
    ("02 05 16 00 1A B6 64 D5 F4 03", 1750.628),  # the SET_DETECT example's reply
    ("02 05 16 00 1A B6 03 C9 B5 03", 1750.531),  # printed right after the broken GET_VALUES reply
]


@pytest.mark.parametrize(("frame", "degrees"), ROTOR_FRAMES)
def test_manual_rotor_position_frames(frame: str, degrees: float) -> None:
    raw = bytes.fromhex(frame)
    assert uart.encode_rotor_position(degrees) == raw
    payload = uart.decode_frame(raw)
    assert uart.decode_rotor_position(payload) == degrees
    assert uart.decode_payload(payload) == RotorPosition(degrees)


def test_manual_get_values_setup_reply_is_the_mosfet_temperature() -> None:
    # "02 03 32 00 81 2A 6C 03 // Feedback motor temperature" answers the bit-1 request above it: bit 1
    # is the MOSFET temperature, int16 / 10, so 0x0081 = 12.9 °C. It is a reply (3 bytes), not a request
    # (5 bytes): it only decodes given the requested field set.
    raw = bytes.fromhex("02 03 32 00 81 2A 6C 03")
    payload = uart.decode_frame(raw)
    fields = ValueField.MOSFET_TEMPERATURE
    assert uart.decode_get_values_setup(payload, fields) == {ValueField.MOSFET_TEMPERATURE: 12.9}
    assert uart.decode_payload(payload, setup_fields=fields) == {ValueField.MOSFET_TEMPERATURE: 12.9}
    assert uart.encode_get_values_setup_reply({ValueField.MOSFET_TEMPERATURE: 12.9}) == raw
    with pytest.raises(ProtocolError, match="knowing the fields requested"):
        uart.decode_payload(payload)
    with pytest.raises(FrameError, match="MOTOR_TEMPERATURE, OUTPUT_CURRENT has 7 payload bytes, this one 3"):
        uart.decode_get_values_setup(payload, ValueField.OUTPUT_CURRENT | ValueField.MOTOR_TEMPERATURE)
    with pytest.raises(FrameError, match="GET_VALUES_SETUP payload has 3 bytes, not 5"):
        uart.decode_command(payload)


# ---- the two errata ------------------------------------------------------------------------------------

PRINTED_SET_POS_180 = bytes.fromhex("02 05 09 0A BA 95 00 1E E7 03")
PRINTED_GET_VALUES = bytes.fromhex(
    "02 49 04 01 66 FC D0 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 FF FF FF F3 00 F6 00 00 00 00 00"
    " 00 00 00 00 00 00 00 00 00 00 00 FF FF FF FF 00 16 D7 AD 00 0A 6F 19 40 7E 00 00 00 00 00 00 00 00 00 00 00"
    " 00 04 4D 53 03")
ROTOR_AFTER = bytes.fromhex("02 05 16 00 1A B6 03 C9 B5 03")


def test_printed_set_pos_180_has_a_bad_crc_and_is_rejected() -> None:
    with pytest.raises(FrameError, match="CRC mismatch: the frame says 1EE7, the payload's CRC-16/XMODEM is 1EF7"):
        uart.decode_frame(PRINTED_SET_POS_180)
    dec = FrameDecoder()
    assert dec.feed(PRINTED_SET_POS_180) == [] and dec.flush() == []
    assert dec.error_count >= 1 and "CRC mismatch" in str(dec.errors[0])
    corrected = uart.encode_position(180.0)
    assert corrected == PRINTED_SET_POS_180[:8] + bytes.fromhex("F7 03")
    assert uart.decode_command(uart.decode_frame(corrected)) == UartCommand(P.SET_POS, (180.0,))


def test_printed_get_values_reply_is_one_byte_short_and_rejected() -> None:
    assert len(PRINTED_GET_VALUES) == 77 and PRINTED_GET_VALUES[1] == 73
    with pytest.raises(FrameError, match="says 73 payload bytes but it carries 72"):
        uart.decode_frame(PRINTED_GET_VALUES)
    with pytest.raises(FrameError, match="GET_VALUES reply has 73 payload bytes, this one 72"):
        uart.decode_get_values(PRINTED_GET_VALUES[2:-3])


@pytest.mark.parametrize("chunk", [1, 2, 7, 1000])
def test_rotor_position_after_the_broken_reply_still_comes_out(chunk: int) -> None:
    stream = PRINTED_GET_VALUES + ROTOR_AFTER
    dec = FrameDecoder()
    out: list[bytes] = []
    for i in range(0, len(stream), chunk):
        out += dec.feed(stream[i:i + chunk])
    # no flush needed: the bound on the length field (517 > 512) stops the decoder waiting on "03 02 05"
    assert out == [ROTOR_AFTER[2:7]]
    assert uart.decode_payload(out[0]) == RotorPosition(1750.531)
    assert dec.error_count >= 1 and dec.buffered == 0
    assert any("ends with 02, not 03" in str(e) for e in dec.errors)


def test_whole_manual_stream_yields_every_valid_frame_in_order() -> None:
    frames = [bytes.fromhex(f) for f, *_ in MANUAL_COMMANDS] + [bytes.fromhex(f) for f, _ in ROTOR_FRAMES]
    stream = b"".join(frames[:5]) + PRINTED_SET_POS_180 + b"".join(frames[5:]) + PRINTED_GET_VALUES + ROTOR_AFTER
    dec = FrameDecoder()
    out = [p for i in range(0, len(stream), 3) for p in dec.feed(stream[i:i + 3])] + dec.flush()
    assert out == [f[2:-3] for f in frames] + [ROTOR_AFTER[2:-3]]


# ---- framing ------------------------------------------------------------------------------------------


def test_crc16_is_xmodem() -> None:
    assert uart.crc16(b"123456789") == 0x31C3  # the CRC-16/XMODEM check value
    assert uart.crc16(b"") == 0


def test_short_and_long_frames() -> None:
    p255 = bytes([4]) + bytes(range(254))
    f = uart.encode_frame(p255)
    assert f[:2] == b"\x02\xff" and len(f) == 255 + 5 and f[-1] == 3
    # a 256-byte payload cannot be a short frame (LEN is one byte): it is a long one
    p256 = p255 + b"\x99"
    f = uart.encode_frame(p256)
    assert f[:3] == b"\x03\x01\x00" and len(f) == 256 + 6
    assert f[-3:-1] == uart.crc16(p256).to_bytes(2, "big")
    for payload in (p255, p256, bytes(600)):
        frame = uart.encode_frame(payload)
        assert uart.decode_frame(frame) == payload
    dec = FrameDecoder(max_payload=1000)
    assert dec.feed(uart.encode_frame(p255) + uart.encode_frame(p256) + uart.encode_frame(bytes(600))) == [
        p255, p256, bytes(600)]


def test_long_frame_with_a_small_payload_is_accepted() -> None:
    payload = b"\x16\x00\x1a\xb6\x64"
    frame = b"\x03\x00\x05" + payload + uart.crc16(payload).to_bytes(2, "big") + b"\x03"
    assert uart.decode_frame(frame) == payload
    assert FrameDecoder().feed(frame) == [payload]


def test_encode_frame_limits() -> None:
    with pytest.raises(ProtocolError, match="1 to 65535 bytes, this one 0"):
        uart.encode_frame(b"")
    with pytest.raises(ProtocolError, match="this one 65536"):
        uart.encode_frame(bytes(65536))


@pytest.mark.parametrize(("frame", "message"), [
    ("02 00 40 84 03 03", "LEN 0"),
    ("03 00 00 40 84 03", "length 0"),
    ("05 01 04 40 84 03", "starts with 02 or 03, this one with 05"),
    ("02 01 04 40 84 02", "ends with 03, this one with 02"),
    ("02 01 04 40 85 03", "CRC mismatch"),
    ("02 02 04 40 84 03", "says 2 payload bytes but it carries 1"),
    ("02 01 04 40 84", "at least 6 bytes"),
])
def test_decode_frame_errors(frame: str, message: str) -> None:
    with pytest.raises(FrameError, match=message):
        uart.decode_frame(bytes.fromhex(frame))


# ---- stream decoder ----------------------------------------------------------------------------------


def test_decoder_byte_by_byte_and_garbage() -> None:
    a, b = uart.encode_get_values(), uart.encode_rpm(-1000)
    stream = b"\xff\x00\x55" + a + b"\x10\x20" + b
    dec = FrameDecoder()
    out = [p for byte in stream for p in dec.feed(bytes([byte]))]
    assert out == [a[2:-3], b[2:-3]]
    assert dec.discarded == 5 and dec.error_count == 0 and dec.frames == 2


def test_valid_frame_inside_a_bad_one_is_found() -> None:
    good = uart.encode_current(5.0)
    # a start byte and a length that swallow the good frame: only the start byte is skipped on failure
    stream = b"\x02\x0c" + good + bytes(5)
    errors: list[FrameError] = []
    dec = FrameDecoder(on_error=errors.append)
    assert dec.feed(stream) == [good[2:-3]]
    assert errors and all(isinstance(e, FrameError) for e in errors) and list(dec.errors) == errors


def test_truncated_frame_then_valid_frame() -> None:
    good = uart.encode_duty(0.5)
    stream = uart.encode_position_speed(10, 1000, 1000)[:9] + good
    dec = FrameDecoder()
    out = dec.feed(stream)
    out += dec.flush()  # the truncated frame's length runs past the end: only the end of stream settles it
    assert out == [good[2:-3]]
    assert any("truncated" in str(e) or "ends with" in str(e) or "CRC" in str(e) for e in dec.errors)
    assert dec.buffered == 0


def test_garbage_length_does_not_stall_beyond_max_payload() -> None:
    good = uart.encode_get_values()
    dec = FrameDecoder(max_payload=512)
    assert dec.feed(b"\x03\xff\xff" + good) == [good[2:-3]]
    assert "frame length 65535 is outside 1..512" in str(dec.errors[0])
    # a plausible length holds frames back until enough bytes arrive (or flush), and then finds them
    dec = FrameDecoder()
    assert dec.feed(b"\x02\x40" + good) == []
    assert dec.buffered == 2 + len(good)
    assert dec.flush() == [good[2:-3]]


def test_non_bytes_input_is_a_protocol_error() -> None:
    frame = uart.encode_get_values()
    assert FrameDecoder().feed(list(frame)) == [b"\x04"]
    assert uart.decode_frame(bytearray(frame)) == b"\x04"
    for bad in (None, "02 01 04 40 84 03", 5):
        with pytest.raises(FrameError, match="expected bytes"):
            FrameDecoder().feed(bad)  # type: ignore[arg-type]
        with pytest.raises(FrameError, match="expected bytes"):
            uart.decode_payload(bad)  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="expected bytes"):
        uart.encode_frame(5)  # type: ignore[arg-type]


def test_decoder_rejects_bad_max_payload() -> None:
    with pytest.raises(ProtocolError):
        FrameDecoder(max_payload=0)


def test_errors_log_is_bounded_but_counted() -> None:
    dec = FrameDecoder(max_errors=3)
    dec.feed(b"\x02\x00" * 10)
    dec.flush()
    assert len(dec.errors) == 3 and dec.error_count >= 10
    dec.reset()
    assert dec.buffered == 0


def is_subsequence(needles: list[bytes], haystack: list[bytes]) -> bool:
    it = iter(haystack)
    return all(any(n == h for h in it) for n in needles)


GARBAGE = st.lists(st.one_of(st.sampled_from([0x02, 0x03, 0x00, 0xFF, 0x01]), st.integers(0, 255)),
                   max_size=30).map(bytes)
PAYLOAD = st.one_of(st.binary(min_size=1, max_size=40), st.binary(min_size=250, max_size=300))


@st.composite
def item(draw: st.DrawFn) -> tuple[str, bytes]:
    kind = draw(st.sampled_from(["garbage", "frame", "frame", "truncated"]))
    if kind == "garbage":
        return kind, draw(GARBAGE)
    payload = draw(PAYLOAD)
    if kind == "frame":
        return kind, payload
    frame = uart.encode_frame(payload)
    return kind, frame[:draw(st.integers(1, len(frame) - 1))]


@settings(max_examples=250, deadline=None)
@given(items=st.lists(item(), max_size=10), cuts=st.lists(st.integers(0, 10_000), max_size=12))
def test_fuzz_stream_decoder_never_raises_and_never_loses_a_valid_frame(items: list[tuple[str, bytes]],
                                                                        cuts: list[int]) -> None:
    stream = b"".join(uart.encode_frame(x) if kind == "frame" else x for kind, x in items)
    expected = [x for kind, x in items if kind == "frame"]
    points = [*sorted({c % (len(stream) + 1) for c in cuts}), len(stream)]
    dec = FrameDecoder()
    out: list[bytes] = []
    prev = 0
    for p in points:
        out += dec.feed(stream[prev:p])
        prev = p
    out += dec.flush()
    assert is_subsequence(expected, out), (expected, out)
    assert dec.buffered == 0 and all(isinstance(e, FrameError) for e in dec.errors)
    assert dec.frames == len(out)


def decode_in_chunks(data: bytes, chunk: int) -> tuple[list[bytes], FrameDecoder]:
    """Feed ``data`` to a new decoder ``chunk`` bytes at a time, then flush: the payloads and the decoder."""
    dec = FrameDecoder()
    out = [p for i in range(0, len(data), chunk) for p in dec.feed(data[i:i + chunk])] + dec.flush()
    return out, dec


def framed_in(payload: bytes, data: bytes) -> bool:
    """True when ``payload`` is in ``data`` as a whole frame, short (02 LEN) or long (03 LEN_HI LEN_LO)."""
    n, crc = len(payload), binascii.crc_hqx(payload, 0).to_bytes(2, "big")
    heads = [b"\x03" + n.to_bytes(2, "big"), *([bytes((2, n))] if n <= 255 else [])]
    return any(head + payload + crc + b"\x03" in data for head in heads)


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=600), chunk=st.integers(1, 64))
def test_fuzz_random_bytes_are_reported_not_raised(data: bytes, chunk: int) -> None:
    out, dec = decode_in_chunks(data, chunk)
    # only whole frames that are in the stream come out; the rest is counted or reported, never raised
    assert all(framed_in(payload, data) for payload in out), out
    assert dec.frames == len(out) and dec.buffered == 0
    assert all(isinstance(e, FrameError) for e in dec.errors)
    # and how the bytes arrive changes nothing: all at once gives the same payloads
    assert decode_in_chunks(data, max(len(data), 1))[0] == out


@settings(max_examples=100, deadline=None)
@given(before=st.binary(max_size=300), payload=PAYLOAD, after=st.binary(max_size=300), chunk=st.integers(1, 64))
def test_fuzz_a_frame_among_random_bytes_is_found(before: bytes, payload: bytes, after: bytes, chunk: int) -> None:
    data = before + uart.encode_frame(payload) + after
    out, _ = decode_in_chunks(data, chunk)
    assert payload in out, (len(before), out)


# ---- commands: ranges and motor-side decoding -----------------------------------------------------------


@pytest.mark.parametrize(("call", "message"), [
    (lambda: uart.encode_duty(1.5), r"duty 1.5 is outside the range -1 \.\. 1"),
    (lambda: uart.encode_current(-60.5), r"current -60.5 A is outside the range -60 \.\. 60 A"),
    (lambda: uart.encode_current_brake(61), r"brake current 61 A is outside"),
    (lambda: uart.encode_rpm(-100_001), r"-100000 \.\. 100000 ERPM"),
    (lambda: uart.encode_position(2148.0), r"position 2148.0 deg is outside the range -2147.48 \.\. 2147.48 deg"),
    (lambda: uart.encode_handbrake(math.nan), r"handbrake current nan A is outside"),
    (lambda: uart.encode_detect(256), r"detect mode 256 is outside"),
    (lambda: uart.encode_detect(1.5), r"detect mode must be an integer"),  # type: ignore[arg-type]
    (lambda: uart.encode_origin(3), r"origin mode 3 is outside the range 0 \.\. 2"),
    (lambda: uart.encode_position_speed(36_001, 0, 0), r"position 36001 deg"),
    (lambda: uart.encode_position_speed(0, 0, -1), r"acceleration -1 ERPM/s is outside"),
    (lambda: uart.encode_get_values_setup(0), r"asks for no field"),
    (lambda: uart.encode_get_values_setup(1 << 9), r"reserved bits \(0x200\)"),
    (lambda: uart.encode_get_values_setup(1 << 18), r"reserved bits"),
    (lambda: uart.encode_current("5"), r"current must be a number"),  # type: ignore[arg-type]
])
def test_command_values_out_of_range_raise(call: Callable[[], object], message: str) -> None:
    with pytest.raises(ProtocolError, match=message):
        call()


def test_other_commands_encode_and_decode() -> None:
    assert uart.encode_fw_version() == uart.encode_frame(b"\x00")
    assert uart.decode_command(b"\x00") == UartCommand(P.FW_VERSION, ())
    assert uart.encode_unlimited() == uart.encode_frame(b"\x5e")
    assert uart.decode_command(b"\x5e") == UartCommand(P.SET_POS_UNLIMITED, ())
    mask = ValueField.MOTOR_TEMPERATURE | ValueField.SPEED | ValueField.ERROR | ValueField.MOTOR_ID
    assert uart.decode_frame(uart.encode_get_values_setup(mask)) == bytes.fromhex("32 00 02 80 82")
    assert uart.decode_command(bytes.fromhex("32 00 02 80 82")).values == (float(mask),)


@pytest.mark.parametrize(("payload", "message"), [
    ("", "empty UART payload"),
    ("63", "unknown UART command 99"),
    ("16 00 1A B6 64", "ROTOR_POSITION is sent by the motor, not a command"),
    ("05 00 00 4E", "SET_DUTY payload has 4 bytes, not 5"),
    ("04 00", "GET_VALUES payload has 2 bytes, not 1"),
    ("5F 03", r"origin mode 3 is outside"),
    ("05 00 01 86 A1", r"duty 1.00001 is outside"),
    ("32 00 00 02 00", "reserved bits 0x200"),
])
def test_decode_command_refuses_malformed_payloads(payload: str, message: str) -> None:
    with pytest.raises(FrameError, match=message):
        uart.decode_command(bytes.fromhex(payload))


# ---- replies --------------------------------------------------------------------------------------------

SAMPLE = GetValues(mosfet_temperature=35.8, motor_temperature=-8.0, output_current=-0.13, input_current=2.46,
                   id_current=0.0, iq_current=-12.34, duty=-0.5, speed_erpm=-1500.0, input_voltage=24.1,
                   fault=int(FaultCode.OVER_TEMP_FET), position_deg=-123.456789, controller_id=104,
                   vd=1.234, vq=-22.5)


def test_get_values_field_offsets() -> None:
    # lay the payload out by hand, field by field, to pin every offset
    payload = bytearray(73)
    payload[0] = 4
    struct.pack_into(">hh", payload, 1, 358, -80)              # MOSFET 35.8 °C, motor -8.0 °C
    struct.pack_into(">iiii", payload, 5, -13, 246, 0, -1234)  # output, input, Id, Iq currents / 100
    struct.pack_into(">h", payload, 21, -500)                  # duty / 1000
    struct.pack_into(">i", payload, 23, -1500)                 # speed ERPM
    struct.pack_into(">h", payload, 27, 241)                   # input voltage / 10
    payload[29:53] = b"\xee" * 24                              # 24 reserved bytes, ignored
    payload[53] = 5                                            # status: OVER_TEMP_FET
    struct.pack_into(">i", payload, 54, -123_456_789)          # position / 1e6 degrees
    payload[58] = 104                                          # controller id
    payload[59:65] = b"\xee" * 6                               # 6 reserved bytes
    struct.pack_into(">ii", payload, 65, 1234, -22_500)        # Vd, Vq / 1000
    v = uart.decode_get_values(payload)
    assert v == SAMPLE
    assert v.fault_code is FaultCode.OVER_TEMP_FET
    assert uart.decode_payload(bytes(payload)) == SAMPLE
    frame = uart.encode_get_values_reply(SAMPLE)
    assert frame[:2] == b"\x02\x49" and len(frame) == 78
    assert uart.decode_get_values(uart.decode_frame(frame)) == SAMPLE


def test_get_values_unknown_fault_is_kept() -> None:
    frame = uart.encode_get_values_reply(replace(SAMPLE, fault=77))
    v = uart.decode_get_values(uart.decode_frame(frame))
    assert v.fault == 77 and v.fault_code is None


def test_get_values_wrong_command_or_length() -> None:
    with pytest.raises(FrameError, match="not a GET_VALUES reply"):
        uart.decode_get_values(b"\x05" + bytes(72))
    with pytest.raises(FrameError, match="73 payload bytes, this one 74"):
        uart.decode_get_values(b"\x04" + bytes(73))
    with pytest.raises(ProtocolError, match="does not fit"):
        uart.encode_get_values_reply(GetValues(*[1e12] * 14))  # type: ignore[arg-type]


def test_get_values_setup_several_fields_in_bit_order() -> None:
    mask = ValueField.MOTOR_ID | ValueField.SPEED | ValueField.MOTOR_TEMPERATURE | ValueField.ERROR | \
        ValueField.POSITION
    # motor temp 41.5 °C (int16 415), speed -2000 ERPM (int32), error 0, position 90° (int32 90e6), id 104
    payload = bytes.fromhex("32" "01 9F" "FF FF F8 30" "00" "05 5D 4A 80" "68")
    got = uart.decode_get_values_setup(payload, mask)
    assert list(got) == [ValueField.MOTOR_TEMPERATURE, ValueField.SPEED, ValueField.ERROR, ValueField.POSITION,
                         ValueField.MOTOR_ID]
    assert list(got.values()) == [41.5, -2000.0, 0, 90.0, 104]
    assert uart.encode_get_values_setup_reply(got) == uart.encode_frame(payload)
    with pytest.raises(FrameError, match="this one 12"):
        uart.decode_get_values_setup(payload[:-1], mask)
    with pytest.raises(FrameError, match="not a GET_VALUES_SETUP reply"):
        uart.decode_get_values_setup(b"\x04" + payload[1:], mask)
    with pytest.raises(ProtocolError, match="reserved bits"):
        uart.decode_get_values_setup(payload, 1 << 12)
    with pytest.raises(ProtocolError, match="not a single GET_VALUES_SETUP field"):
        uart.encode_get_values_setup_reply({ValueField.SPEED | ValueField.DUTY: 1.0})


def test_every_setup_field_round_trips() -> None:
    values = {ValueField.MOSFET_TEMPERATURE: 30.5, ValueField.MOTOR_TEMPERATURE: 41.2, ValueField.OUTPUT_CURRENT: -1.5,
              ValueField.INPUT_CURRENT: 0.75, ValueField.ID_CURRENT: 0.01, ValueField.IQ_CURRENT: -3.33,
              ValueField.DUTY: 0.125, ValueField.SPEED: 12345.0, ValueField.INPUT_VOLTAGE: 48.1,
              ValueField.ERROR: 3, ValueField.POSITION: -1.5, ValueField.MOTOR_ID: 7}
    mask = 0
    for f in values:
        mask |= f
    payload = uart.decode_frame(uart.encode_get_values_setup_reply(values))
    assert len(payload) == 1 + 2 + 2 + 4 * 4 + 2 + 4 + 2 + 1 + 4 + 1
    assert uart.decode_get_values_setup(payload, mask) == values


def test_fw_version_and_unknown_replies() -> None:
    assert uart.decode_payload(b"\x00\x05\x02AK80\x00") == FirmwareVersion(5, 2, b"AK80\x00")
    with pytest.raises(FrameError, match="not a FW_VERSION reply"):
        uart.decode_fw_version(b"\x00\x05")
    with pytest.raises(FrameError, match="not a reply the motor sends"):
        uart.decode_payload(b"\x05\x00\x00\x00\x00")
    with pytest.raises(FrameError, match="empty"):
        uart.decode_payload(b"")
    with pytest.raises(FrameError, match="not a 5-byte ROTOR_POSITION payload"):
        uart.decode_rotor_position(b"\x16\x00")


def test_fault_codes() -> None:
    assert [int(c) for c in FaultCode] == list(range(19))
    assert FaultCode(0) is FaultCode.NONE and FaultCode(18) is FaultCode.UNBALANCED_CURRENTS
    assert FaultCode(6) is FaultCode.OVER_TEMP_MOTOR and FaultCode(10) is FaultCode.BOOTING_FROM_WATCHDOG_RESET
    assert FaultCode(15).name == "HIGH_OFFSET_CURRENT_SENSOR_1"


def test_packet_numbers() -> None:
    assert (P.SET_POS_MULTI, P.SET_POS_SINGLE, P.SET_POS_UNLIMITED, P.SET_POS_ORIGIN) == (92, 93, 94, 95)
    assert (P.ROTOR_POSITION, P.GET_VALUES_SETUP, P.SET_POS_SPD) == (22, 50, 91)
    assert (ValueField.ERROR, ValueField.POSITION, ValueField.MOTOR_ID) == (1 << 15, 1 << 16, 1 << 17)
