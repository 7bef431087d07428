"""Servo mode over UART (the R-link serial port, 921 600 baud): VESC-style framed packets (AK manual §5.2.2).

Framing::

    02 LEN PAYLOAD CRC_HI CRC_LO 03                payload of 1-255 bytes ("short" frame)
    03 LEN_HI LEN_LO PAYLOAD CRC_HI CRC_LO 03      payload of 256 bytes and more ("long" frame)

The CRC is CRC-16/XMODEM (poly 0x1021, init 0) over the payload only, sent big-endian. The first
payload byte is the command (:class:`UartPacket`).

The short frame's LEN is one byte, so a 256-byte payload cannot be a short frame, whatever the
manual's ``len <= 256`` test says (it would send LEN 0): :func:`encode_frame` uses the short form up
to 255 bytes and the long form from 256 on. The decoders accept a long frame of any length from 1 (as
VESC does) and refuse a short frame with LEN 0 (an empty payload has no command byte).

Controller side: one encoder per command (each returns the whole frame, ready to write), decoders
for the replies (:func:`decode_get_values`, :func:`decode_get_values_setup`,
:func:`decode_rotor_position`, :func:`decode_fw_version`, or :func:`decode_payload` to dispatch on
the command byte) and :class:`FrameDecoder`, which finds payloads in a byte stream and resynchronises
after garbage. Motor side: :func:`decode_command` and the reply encoders.

Scales are those of the protocol notes' UART table (``shared/docs/ak-protocol.md`` §3); note that
SET_POS here is degrees × 1 000 000 (CAN uses × 10 000), so it only reaches ±2147.48°, and
SET_POS_SPD's position is degrees × 1000. Values outside the documented (or, where nothing is
documented, the field's) range raise :class:`~akarm.ProtocolError`, and are rounded to the nearest
wire step.
"""

from __future__ import annotations

import binascii
import operator
import struct
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import NamedTuple

from ..errors import FrameError, ProtocolError
from ._fields import Field, as_number, checked, fmt

__all__ = [
    "DEFAULT_MAX_PAYLOAD",
    "FaultCode",
    "FirmwareVersion",
    "FrameDecoder",
    "GetValues",
    "RotorPosition",
    "UartCommand",
    "UartPacket",
    "ValueField",
    "crc16",
    "decode_command",
    "decode_frame",
    "decode_fw_version",
    "decode_get_values",
    "decode_get_values_setup",
    "decode_payload",
    "decode_rotor_position",
    "encode_current",
    "encode_current_brake",
    "encode_detect",
    "encode_duty",
    "encode_frame",
    "encode_fw_version",
    "encode_get_values",
    "encode_get_values_reply",
    "encode_get_values_setup",
    "encode_get_values_setup_reply",
    "encode_handbrake",
    "encode_multi_turn",
    "encode_origin",
    "encode_position",
    "encode_position_speed",
    "encode_rotor_position",
    "encode_rpm",
    "encode_single_turn",
    "encode_unlimited",
]

#: Largest payload :class:`FrameDecoder` waits for by default, bytes (VESC's PACKET_MAX_PL_LEN).
DEFAULT_MAX_PAYLOAD = 512
_SHORT_MAX = 255
_LONG_MAX = 0xFFFF

_I32_MIN, _I32_MAX = -(1 << 31), (1 << 31) - 1


class UartPacket(IntEnum):
    """Command bytes (the first payload byte) of the serial protocol."""

    FW_VERSION = 0
    GET_VALUES = 4
    SET_DUTY = 5
    SET_CURRENT = 6
    SET_CURRENT_BRAKE = 7
    SET_RPM = 8
    SET_POS = 9
    SET_HANDBRAKE = 10
    SET_DETECT = 11
    ROTOR_POSITION = 22
    GET_VALUES_SETUP = 50
    SET_POS_SPD = 91
    SET_POS_MULTI = 92
    """Multi-turn position mode, ±100 turns (the manual's enum comments swap 92 and 93)."""
    SET_POS_SINGLE = 93
    """Single-turn position mode, 0-360°."""
    SET_POS_UNLIMITED = 94
    SET_POS_ORIGIN = 95


class FaultCode(IntEnum):
    """VESC ``mc_fault_code``: the status byte of a GET_VALUES reply."""

    NONE = 0
    OVER_VOLTAGE = 1
    UNDER_VOLTAGE = 2
    DRV = 3
    ABS_OVER_CURRENT = 4
    OVER_TEMP_FET = 5
    OVER_TEMP_MOTOR = 6
    GATE_DRIVER_OVER_VOLTAGE = 7
    GATE_DRIVER_UNDER_VOLTAGE = 8
    MCU_UNDER_VOLTAGE = 9
    BOOTING_FROM_WATCHDOG_RESET = 10
    ENCODER_SPI = 11
    ENCODER_SINCOS_BELOW_MIN_AMPLITUDE = 12
    ENCODER_SINCOS_ABOVE_MAX_AMPLITUDE = 13
    FLASH_CORRUPTION = 14
    HIGH_OFFSET_CURRENT_SENSOR_1 = 15
    HIGH_OFFSET_CURRENT_SENSOR_2 = 16
    HIGH_OFFSET_CURRENT_SENSOR_3 = 17
    UNBALANCED_CURRENTS = 18


class ValueField(IntFlag):
    """The GET_VALUES_SETUP field mask. The manual numbers bits from 1 (bit 1 = least significant).

    A reply carries exactly the requested fields, in bit order. Bits 10-15 and 19-32 are reserved
    (their sizes are not documented), so they cannot be requested.
    """

    MOSFET_TEMPERATURE = 1 << 0
    """bit 1: int16 / 10 → °C"""
    MOTOR_TEMPERATURE = 1 << 1
    """bit 2: int16 / 10 → °C"""
    OUTPUT_CURRENT = 1 << 2
    """bit 3: int32 / 100 → A"""
    INPUT_CURRENT = 1 << 3
    """bit 4: int32 / 100 → A"""
    ID_CURRENT = 1 << 4
    """bit 5: int32 / 100 → A"""
    IQ_CURRENT = 1 << 5
    """bit 6: int32 / 100 → A"""
    DUTY = 1 << 6
    """bit 7: int16 / 1000 → fraction"""
    SPEED = 1 << 7
    """bit 8: int32 → ERPM"""
    INPUT_VOLTAGE = 1 << 8
    """bit 9: int16 / 10 → V"""
    ERROR = 1 << 15
    """bit 16: uint8 fault code (:class:`FaultCode`)"""
    POSITION = 1 << 16
    """bit 17: int32 / 1 000 000 → degrees"""
    MOTOR_ID = 1 << 17
    """bit 18: uint8"""


# field -> (struct format, divisor); divisor None = an integer field returned as int
_SETUP_FIELDS: tuple[tuple[ValueField, struct.Struct, float | None], ...] = (
    (ValueField.MOSFET_TEMPERATURE, struct.Struct(">h"), 10.0),
    (ValueField.MOTOR_TEMPERATURE, struct.Struct(">h"), 10.0),
    (ValueField.OUTPUT_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.INPUT_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.ID_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.IQ_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.DUTY, struct.Struct(">h"), 1000.0),
    (ValueField.SPEED, struct.Struct(">i"), 1.0),
    (ValueField.INPUT_VOLTAGE, struct.Struct(">h"), 10.0),
    (ValueField.ERROR, struct.Struct(">B"), None),
    (ValueField.POSITION, struct.Struct(">i"), 1_000_000.0),
    (ValueField.MOTOR_ID, struct.Struct(">B"), None),
)
_SETUP_KNOWN = 0
for _field, *_ in _SETUP_FIELDS:
    _SETUP_KNOWN |= int(_field)


# ---- framing -------------------------------------------------------------------------------


def _as_bytes(data: object, error: type[ProtocolError] = FrameError) -> bytes:
    """``data`` as bytes when it is bytes-like or an iterable of 0-255 ints, else ``error``."""
    if isinstance(data, bytes):
        return data
    if not isinstance(data, str | int) and data is not None:
        try:
            return bytes(data)  # type: ignore[call-overload]
        except (TypeError, ValueError):
            pass
    raise error(f"expected bytes, got {type(data).__name__}")


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/XMODEM (poly 0x1021, init 0, no reflection, no final XOR) of ``data``."""
    return binascii.crc_hqx(data, 0)


def encode_frame(payload: bytes | bytearray) -> bytes:
    """Wrap ``payload`` (1-65 535 bytes, command byte first) in a frame: start, length, payload, CRC, 03.

    Payloads up to 255 bytes get a short frame (``02 LEN``), longer ones a long frame (``03 LEN_HI LEN_LO``).

    Raises:
        ProtocolError: an empty payload or one longer than 65 535 bytes.
    """
    payload = _as_bytes(payload, ProtocolError)
    n = len(payload)
    crc = binascii.crc_hqx(payload, 0)
    if 0 < n <= _SHORT_MAX:
        return b"".join((bytes((2, n)), payload, bytes((crc >> 8, crc & 0xFF, 3))))
    if _SHORT_MAX < n <= _LONG_MAX:
        return b"".join((bytes((3, n >> 8, n & 0xFF)), payload, bytes((crc >> 8, crc & 0xFF, 3))))
    raise ProtocolError(f"a UART payload has 1 to {_LONG_MAX} bytes, this one {n}",
                        fix="every payload starts with a command byte")


def decode_frame(frame: bytes | bytearray) -> bytes:
    """The payload of exactly one complete frame, checked strictly.

    Raises:
        FrameError: a bad start byte, a length byte that disagrees with the frame's size (e.g. the
            manual's GET_VALUES example, which says 73 payload bytes and carries 72), a bad end byte,
            or a CRC mismatch (e.g. the manual's SET_POS 180° example, printed with CRC 1EE7).
    """
    frame = _as_bytes(frame)
    n = len(frame)
    if n < 6:
        raise FrameError(f"a UART frame has at least 6 bytes, this one {n}", data=frame)
    start = frame[0]
    if start == 2:
        hdr, length = 2, frame[1]
        if length == 0:
            raise FrameError("short frame with LEN 0: a payload needs at least a command byte", data=frame)
    elif start == 3:
        hdr, length = 3, (frame[1] << 8) | frame[2]
        if length == 0:
            raise FrameError("long frame with length 0: a payload needs at least a command byte", data=frame)
    else:
        raise FrameError(f"a UART frame starts with 02 or 03, this one with {start:02X}", data=frame)
    carried = n - hdr - 3
    if carried != length:
        raise FrameError(f"the frame's length field says {length} payload bytes but it carries {carried} "
                         f"(a frame of {n} bytes, {hdr + length + 3} expected): bytes lost or added",
                         data=frame)
    if frame[-1] != 3:
        raise FrameError(f"a UART frame ends with 03, this one with {frame[-1]:02X}", data=frame)
    payload = frame[hdr:hdr + length]
    got = (frame[-3] << 8) | frame[-2]
    want = binascii.crc_hqx(payload, 0)
    if got != want:
        raise FrameError(f"CRC mismatch: the frame says {got:04X}, the payload's CRC-16/XMODEM is {want:04X}",
                         data=frame)
    return payload


class FrameDecoder:
    """Finds frames in a serial byte stream, whatever is around them.

    ``feed(data)`` appends bytes and returns the payloads of the frames completed so far, in order.
    Bytes that cannot start a frame are skipped (counted in :attr:`discarded`). A candidate frame
    that turns out bad (a length of 0 or above ``max_payload``, a wrong end byte, a CRC mismatch) is
    reported as a :class:`~akarm.FrameError`, appended to :attr:`errors` and passed to ``on_error``,
    never raised; then only its start byte is dropped and scanning resumes at the next byte, so a
    valid frame that begins inside the bad one, or right after garbage, is still found.

    A candidate whose length runs past the bytes received so far is kept until more bytes come:
    :meth:`flush` (at the end of a stream) gives up on it and rescans what is left. ``max_payload``
    bounds that wait, so a garbage length field cannot stall the decoder for long.

    The end byte 03 is also a long frame's start byte, so a frame that lost only its end byte looks
    complete when a long frame follows, and would swallow that frame's start. After every good
    frame, its end byte is therefore also tried, silently, as the start of a long frame of 256-511
    bytes (what normally follows, ``02 LEN`` or ``03 LEN_HI``, reads as 512 or more and is dropped at
    once, so this never delays normal traffic). A long frame of 512 bytes or more that follows a frame
    missing its end byte is still lost.

    Attributes:
        errors: the most recent reports (up to ``max_errors``), oldest first.
        error_count: how many bad frames were reported in all.
        discarded: how many bytes were skipped outside any candidate frame.
        frames: how many payloads were returned in all.
    """

    def __init__(self, *, max_payload: int = DEFAULT_MAX_PAYLOAD,
                 on_error: Callable[[FrameError], object] | None = None, max_errors: int = 100) -> None:
        if not 1 <= max_payload <= _LONG_MAX:
            raise ProtocolError(f"max_payload must be 1..{_LONG_MAX}, got {max_payload}")
        self.max_payload = max_payload
        self.on_error = on_error
        self.errors: deque[FrameError] = deque(maxlen=max_errors)
        self.error_count = 0
        self.discarded = 0
        self.frames = 0
        self._buf = bytearray()
        self._spec = False  # the buffer starts with the end byte of a good frame (see _scan)

    def __repr__(self) -> str:
        return (f"FrameDecoder(buffered={len(self._buf)}, frames={self.frames}, errors={self.error_count}, "
                f"discarded={self.discarded})")

    @property
    def buffered(self) -> int:
        """Bytes held back waiting for the rest of a frame (not counting a decoded frame's end byte)."""
        return len(self._buf) - self._spec

    def feed(self, data: bytes | bytearray | memoryview | Iterable[int]) -> list[bytes]:
        """Add received bytes; return the payloads of every frame completed so far (possibly none)."""
        self._buf += data if isinstance(data, bytes | bytearray | memoryview) else _as_bytes(data)
        return self._scan(final=False)

    def flush(self) -> list[bytes]:
        """End of stream: treat any incomplete candidate as truncated, rescan the rest, empty the buffer."""
        return self._scan(final=True)

    def reset(self) -> None:
        """Drop buffered bytes (the counters and error log stay)."""
        self._buf.clear()
        self._spec = False

    def _report(self, what: str, data: bytes | bytearray) -> None:
        err = FrameError(what, data=bytes(data))
        self.errors.append(err)
        self.error_count += 1
        if self.on_error is not None:
            self.on_error(err)

    def _scan(self, *, final: bool) -> list[bytes]:
        buf = self._buf
        n = len(buf)
        out: list[bytes] = []
        i = 0
        maxp = self.max_payload
        # The end byte 03 is also a long frame's start byte. After a good frame its end byte is tried
        # (silently) as the start of a long frame, in case that frame had lost its own end byte and the
        # 03 belongs to the next one. Only lengths 256-511 are tried, so the frames that normally follow
        # (02 LEN ... or 03 LEN_HI ..., i.e. lengths of 512 and more) never make the decoder wait.
        spec = 0 if self._spec else -1
        while i < n:
            start = buf[i]
            if i == spec:
                if i + 1 < n and buf[i + 1] != 1:
                    i += 1
                    continue
                if i + 3 > n:
                    if final:
                        i += 1
                        continue
                    break
                length = 256 | buf[i + 2]
                end = i + 3 + length + 3
                if length > maxp:
                    i += 1
                    continue
                if end > n:
                    if final:
                        i += 1
                        continue
                    break
                payload = bytes(buf[i + 3:end - 3])
                if buf[end - 1] == 3 and binascii.crc_hqx(payload, 0) == (buf[end - 3] << 8) | buf[end - 2]:
                    out.append(payload)
                    i = spec = end - 1
                else:
                    i += 1
                continue
            if start != 2 and start != 3:
                j2 = buf.find(2, i)
                j3 = buf.find(3, i)
                j = n if j2 < 0 and j3 < 0 else j3 if j2 < 0 else j2 if j3 < 0 else min(j2, j3)
                self.discarded += j - i
                i = j
                continue
            hdr = 2 if start == 2 else 3
            if i + hdr > n:
                if not final:
                    break
                self._report("stream ended inside a frame header (truncated frame)", buf[i:])
                i += 1
                continue
            length = buf[i + 1] if hdr == 2 else (buf[i + 1] << 8) | buf[i + 2]
            if length == 0 or length > maxp:
                self._report(f"frame length {length} is outside 1..{maxp}", buf[i:i + hdr])
                i += 1
                continue
            end = i + hdr + length + 3
            if end > n:
                if not final:
                    break
                self._report(f"truncated frame: length {length} needs {end - i} bytes, the stream ended "
                             f"after {n - i}", buf[i:])
                i += 1
                continue
            if buf[end - 1] != 3:
                self._report(f"frame of length {length} ends with {buf[end - 1]:02X}, not 03", buf[i:end])
                i += 1
                continue
            payload = bytes(buf[i + hdr:end - 3])
            got = (buf[end - 3] << 8) | buf[end - 2]
            want = binascii.crc_hqx(payload, 0)
            if got != want:
                self._report(f"CRC mismatch in a frame of length {length}: frame says {got:04X}, "
                             f"payload gives {want:04X}", buf[i:end])
                i += 1
                continue
            out.append(payload)
            i = spec = end - 1
        if final:
            i = n
        self._spec = i == spec and i < n
        del buf[:i]
        self.frames += len(out)
        return out


# ---- commands (controller → motor) ------------------------------------------------------------


_I32 = struct.Struct(">i")
_U8 = struct.Struct(">B")
_U32 = struct.Struct(">I")
_3I32 = struct.Struct(">iii")
_NONE = struct.Struct(">")

_COMMANDS: dict[UartPacket, tuple[struct.Struct, tuple[Field, ...]]] = {
    UartPacket.FW_VERSION: (_NONE, ()),
    UartPacket.GET_VALUES: (_NONE, ()),
    UartPacket.SET_DUTY: (_I32, (Field("duty", "", 100_000.0, -1.0, 1.0),)),
    UartPacket.SET_CURRENT: (_I32, (Field("current", "A", 1000.0, -60.0, 60.0),)),
    UartPacket.SET_CURRENT_BRAKE: (_I32, (Field("brake current", "A", 1000.0, -60.0, 60.0),)),
    UartPacket.SET_RPM: (_I32, (Field("speed", "ERPM", 1.0, -100_000.0, 100_000.0),)),
    UartPacket.SET_POS: (_I32, (Field("position", "deg", 1_000_000.0, _I32_MIN / 1e6, _I32_MAX / 1e6),)),
    UartPacket.SET_HANDBRAKE: (_I32, (Field("handbrake current", "A", 1000.0, -60.0, 60.0),)),
    UartPacket.SET_DETECT: (_U8, (Field("detect mode", "", 1.0, 0.0, 255.0),)),
    UartPacket.GET_VALUES_SETUP: (_U32, (Field("field mask", "", 1.0, 1.0, float(_SETUP_KNOWN)),)),
    UartPacket.SET_POS_SPD: (_3I32, (
        Field("position", "deg", 1000.0, -36_000.0, 36_000.0),
        Field("speed", "ERPM", 1.0, -100_000.0, 100_000.0),
        Field("acceleration", "ERPM/s", 1.0, 0.0, float(_I32_MAX)),
    )),
    UartPacket.SET_POS_MULTI: (_I32, (Field("argument", "", 1.0, _I32_MIN, _I32_MAX),)),
    UartPacket.SET_POS_SINGLE: (_I32, (Field("argument", "", 1.0, _I32_MIN, _I32_MAX),)),
    UartPacket.SET_POS_UNLIMITED: (_NONE, ()),
    UartPacket.SET_POS_ORIGIN: (_U8, (Field("origin mode", "", 1.0, 0.0, 2.0),)),
}


def _integer(name: str, value: int) -> int:
    try:
        return operator.index(value)
    except TypeError:
        raise ProtocolError(f"{name} must be an integer, got {value!r}") from None


def _setup_mask(fields: ValueField | int) -> int:
    mask = _integer("field mask", fields)
    if mask <= 0 or mask & ~_SETUP_KNOWN:
        raise ProtocolError(f"field mask 0x{mask:X} asks for no field or for reserved bits "
                            f"(0x{mask & ~_SETUP_KNOWN:X})",
                            fix="combine ValueField members only")
    return mask


def _command(packet: UartPacket, *values: float) -> bytes:
    st, args = _COMMANDS[packet]
    ints = [round(checked(a, v) * a.scale) for a, v in zip(args, values, strict=True)]
    for a, k in zip(args, ints, strict=True):  # rounding can step just past the field's edge
        if not _I32_MIN <= k <= _I32_MAX:
            raise ProtocolError(f"{a.name} does not fit the wire field after scaling")
    return encode_frame(bytes((packet,)) + st.pack(*ints))


def encode_fw_version() -> bytes:
    """FW_VERSION request frame (reply: :func:`decode_fw_version`)."""
    return _command(UartPacket.FW_VERSION)


def encode_get_values() -> bytes:
    """GET_VALUES request frame ``02 01 04 40 84 03`` (reply: :func:`decode_get_values`)."""
    return _command(UartPacket.GET_VALUES)


def encode_duty(duty: float) -> bytes:
    """SET_DUTY frame: ``duty`` as a fraction of the supply voltage, -1 .. 1 (int32 × 100 000)."""
    return _command(UartPacket.SET_DUTY, duty)


def encode_current(amps: float) -> bytes:
    """SET_CURRENT frame: Iq in A, -60 .. 60 (int32 mA)."""
    return _command(UartPacket.SET_CURRENT, amps)


def encode_current_brake(amps: float) -> bytes:
    """SET_CURRENT_BRAKE frame: brake current in A, -60 .. 60 (int32 mA).

    Negative values are accepted here because the manual's serial example sends -5 A (the CAN
    encoder, following the notes, refuses them).
    """
    return _command(UartPacket.SET_CURRENT_BRAKE, amps)


def encode_rpm(erpm: float) -> bytes:
    """SET_RPM frame: speed in electrical RPM, -100 000 .. 100 000 (int32)."""
    return _command(UartPacket.SET_RPM, erpm)


def encode_position(degrees: float) -> bytes:
    """SET_POS frame: position in degrees (int32 × 1 000 000, so only ±2147.483647° fit)."""
    return _command(UartPacket.SET_POS, degrees)


def encode_handbrake(amps: float) -> bytes:
    """SET_HANDBRAKE frame: handbrake current in A, -60 .. 60 (int32 mA)."""
    return _command(UartPacket.SET_HANDBRAKE, amps)


def encode_detect(mode: int = 4) -> bytes:
    """SET_DETECT frame (uint8 mode, 0-255; the manual's example uses 4): the motor then sends
    ROTOR_POSITION every 10 ms.
    """
    return _command(UartPacket.SET_DETECT, _integer("detect mode", mode))


def encode_get_values_setup(fields: ValueField | int) -> bytes:
    """GET_VALUES_SETUP request frame asking for ``fields`` (a :class:`ValueField` combination; uint32).

    Raises:
        ProtocolError: no field, or a reserved bit (10-15, 19-32 in the manual's numbering).
    """
    return _command(UartPacket.GET_VALUES_SETUP, _setup_mask(fields))


def encode_position_speed(degrees: float, erpm: float, erpm_per_s: float) -> bytes:
    """SET_POS_SPD frame: go to ``degrees`` (±36 000, int32 × 1000) at up to ``erpm`` (±100 000 ERPM,
    int32) with acceleration ``erpm_per_s`` (≥ 0 ERPM/s, int32).
    """
    return _command(UartPacket.SET_POS_SPD, degrees, erpm, erpm_per_s)


def encode_multi_turn() -> bytes:
    """SET_POS_MULTI frame (0x5C, int32 0): position loop in multi-turn mode, ±100 turns."""
    return _command(UartPacket.SET_POS_MULTI, 0)


def encode_single_turn() -> bytes:
    """SET_POS_SINGLE frame (0x5D, int32 0): position loop in single-turn mode, 0-360°."""
    return _command(UartPacket.SET_POS_SINGLE, 0)


def encode_unlimited() -> bytes:
    """SET_POS_UNLIMITED frame (0x5E, no argument)."""
    return _command(UartPacket.SET_POS_UNLIMITED)


def encode_origin(mode: int = 1) -> bytes:
    """SET_POS_ORIGIN frame: make the current position the origin (uint8 mode 0-2, as CAN's SET_ORIGIN_HERE;
    the manual's example sends 1).
    """
    return _command(UartPacket.SET_POS_ORIGIN, _integer("origin mode", mode))


class UartCommand(NamedTuple):
    """A decoded command payload (motor side), values in the units the encoders take.

    ``values`` is empty for FW_VERSION, GET_VALUES and SET_POS_UNLIMITED; ``(duty,)``, ``(amps,)``,
    ``(erpm,)``, ``(degrees,)``, ``(mode,)``, ``(field_mask,)``, ``(degrees, erpm, erpm_per_s)`` or
    ``(argument,)`` otherwise.
    """

    packet: UartPacket
    values: tuple[float, ...]


def decode_command(payload: bytes | bytearray) -> UartCommand:
    """Motor side: decode a command payload (controller → motor), as built by the ``encode_*`` functions.

    Raises:
        FrameError: empty, an unknown or reply-only command byte, a length that does not fit the
            command, or a value outside its range.
    """
    payload = _as_bytes(payload)
    if not payload:
        raise FrameError("empty UART payload")
    try:
        packet = UartPacket(payload[0])
    except ValueError:
        raise FrameError(f"unknown UART command {payload[0]}", data=payload) from None
    spec = _COMMANDS.get(packet)
    if spec is None:
        raise FrameError(f"{packet.name} is sent by the motor, not a command", data=payload)
    st, args = spec
    if len(payload) != 1 + st.size:
        raise FrameError(f"{packet.name} payload has {len(payload)} bytes, not {1 + st.size}", data=payload)
    values = []
    for a, k in zip(args, st.unpack(payload[1:]), strict=True):
        x = k / a.scale if a.scale != 1.0 else float(k)
        if not a.lo <= x <= a.hi:
            raise FrameError(f"{packet.name}: {a.name} {x:g} is outside {fmt(a.lo)} .. {fmt(a.hi)}", data=payload)
        values.append(x)
    if packet is UartPacket.GET_VALUES_SETUP and int(values[0]) & ~_SETUP_KNOWN:
        raise FrameError(f"GET_VALUES_SETUP asks for reserved bits 0x{int(values[0]) & ~_SETUP_KNOWN:X}",
                         data=payload)
    return UartCommand(packet, tuple(values))


# ---- replies (motor → controller) -------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class GetValues:
    """A GET_VALUES reply.

    Attributes:
        mosfet_temperature: °C. motor_temperature: °C.
        output_current, input_current, id_current, iq_current: A.
        duty: fraction of the supply voltage (-1 .. 1).
        speed_erpm: electrical RPM.
        input_voltage: V.
        fault: status byte, a :class:`FaultCode` value (kept as int when unknown).
        position_deg: degrees.
        controller_id: the motor's ID.
        vd, vq: V.
    """

    mosfet_temperature: float
    motor_temperature: float
    output_current: float
    input_current: float
    id_current: float
    iq_current: float
    duty: float
    speed_erpm: float
    input_voltage: float
    fault: int
    position_deg: float
    controller_id: int
    vd: float
    vq: float

    @property
    def fault_code(self) -> FaultCode | None:
        """:attr:`fault` as a :class:`FaultCode`, or None when the firmware sent an unknown code."""
        try:
            return FaultCode(self.fault)
        except ValueError:
            return None


# cmd, mos T, motor T, out I, in I, Id, Iq, duty, speed, Vin, 24 reserved, status, pos, id, 6 reserved, Vd, Vq
_GET_VALUES = struct.Struct(">BhhiiiihihxxxxxxxxxxxxxxxxxxxxxxxxBiBxxxxxxii")
assert _GET_VALUES.size == 73


def decode_get_values(payload: bytes | bytearray) -> GetValues:
    """Decode a GET_VALUES reply payload (73 bytes, command 4) into a :class:`GetValues`.

    Raises:
        FrameError: not command 4, or not 73 bytes (the manual's printed example carries 72).
    """
    payload = _as_bytes(payload)
    if not payload or payload[0] != UartPacket.GET_VALUES:
        raise FrameError("not a GET_VALUES reply (command 4)", data=payload)
    if len(payload) != _GET_VALUES.size:
        raise FrameError(f"a GET_VALUES reply has {_GET_VALUES.size} payload bytes, this one {len(payload)}",
                         data=payload)
    (_, mos, mot, iout, iin, i_d, i_q, duty, speed, vin, status, pos, cid, vd, vq) = _GET_VALUES.unpack(payload)
    return GetValues(mos / 10, mot / 10, iout / 100, iin / 100, i_d / 100, i_q / 100, duty / 1000, float(speed),
                     vin / 10, status, pos / 1e6, cid, vd / 1000, vq / 1000)


def _to_int(name: str, value: float, scale: float, lo: int, hi: int) -> int:
    x = as_number(name, value)
    k = round(x * scale) if x == x and abs(x) != float("inf") else None
    if k is None or not lo <= k <= hi:
        raise ProtocolError(f"{name} {value!r} does not fit its field ({lo / scale:g} .. {hi / scale:g})")
    return k


def encode_get_values_reply(values: GetValues) -> bytes:
    """Motor side: a GET_VALUES reply frame (units as :class:`GetValues`; reserved bytes zero).

    Raises:
        ProtocolError: a value that does not fit its field.
    """
    i16, i32 = (-(1 << 15), (1 << 15) - 1), (_I32_MIN, _I32_MAX)
    v = values
    payload = _GET_VALUES.pack(
        UartPacket.GET_VALUES,
        _to_int("mosfet_temperature", v.mosfet_temperature, 10, *i16),
        _to_int("motor_temperature", v.motor_temperature, 10, *i16),
        _to_int("output_current", v.output_current, 100, *i32),
        _to_int("input_current", v.input_current, 100, *i32),
        _to_int("id_current", v.id_current, 100, *i32),
        _to_int("iq_current", v.iq_current, 100, *i32),
        _to_int("duty", v.duty, 1000, *i16),
        _to_int("speed_erpm", v.speed_erpm, 1, *i32),
        _to_int("input_voltage", v.input_voltage, 10, *i16),
        _to_int("fault", v.fault, 1, 0, 255),
        _to_int("position_deg", v.position_deg, 1_000_000, *i32),
        _to_int("controller_id", v.controller_id, 1, 0, 255),
        _to_int("vd", v.vd, 1000, *i32),
        _to_int("vq", v.vq, 1000, *i32),
    )
    return encode_frame(payload)


def decode_get_values_setup(payload: bytes | bytearray, fields: ValueField | int) -> dict[ValueField, float]:
    """Decode a GET_VALUES_SETUP reply, given the ``fields`` that were requested.

    The reply is the command byte (50) followed by exactly the requested fields, in bit order; the
    result maps each requested :class:`ValueField` to its value in bit order (°C, A, fraction, ERPM,
    V, degrees; the error flag and motor id as ints). The manual's ``02 03 32 00 81 2A 6C 03`` is the
    reply to its bit-1 request: MOSFET temperature 12.9 °C.

    Raises:
        ProtocolError: ``fields`` empty or with reserved bits.
        FrameError: not command 50, or a length that does not match the requested fields.
    """
    mask = _setup_mask(fields)
    payload = _as_bytes(payload)
    if not payload or payload[0] != UartPacket.GET_VALUES_SETUP:
        raise FrameError("not a GET_VALUES_SETUP reply (command 50)", data=payload)
    wanted = [(f, st, div) for f, st, div in _SETUP_FIELDS if mask & f]
    size = 1 + sum(st.size for _, st, _ in wanted)
    if len(payload) != size:
        names = ", ".join(f.name or "" for f, _, _ in wanted)
        raise FrameError(f"a GET_VALUES_SETUP reply with {names} has {size} payload bytes, this one {len(payload)}",
                         data=payload, fix="decode with the field set that was requested")
    out: dict[ValueField, float] = {}
    i = 1
    for f, st, div in wanted:
        (k,) = st.unpack_from(payload, i)
        i += st.size
        out[f] = k if div is None else (k / div if div != 1.0 else float(k))
    return out


def encode_get_values_setup_reply(values: Mapping[ValueField, float]) -> bytes:
    """Motor side: a GET_VALUES_SETUP reply frame carrying ``values`` (fields in bit order, units as decoded).

    Raises:
        ProtocolError: no field, a combined or unknown flag as a key, or a value that does not fit.
    """
    if not values:
        raise ProtocolError("a GET_VALUES_SETUP reply needs at least one field")
    known = {f for f, _, _ in _SETUP_FIELDS}
    for key in values:
        if key not in known:
            raise ProtocolError(f"{key!r} is not a single GET_VALUES_SETUP field")
    parts = [bytes((UartPacket.GET_VALUES_SETUP,))]
    for f, st, div in _SETUP_FIELDS:
        if f in values:
            lo, hi = {1: (0, 255), 2: (-(1 << 15), (1 << 15) - 1), 4: (_I32_MIN, _I32_MAX)}[st.size]
            parts.append(st.pack(_to_int(f.name or "", values[f], div or 1.0, lo, hi)))
    return encode_frame(b"".join(parts))


class RotorPosition(NamedTuple):
    """A ROTOR_POSITION report (streamed every 10 ms after SET_DETECT). ``degrees``: int32 / 1000."""

    degrees: float


_ROTOR = struct.Struct(">Bi")


def decode_rotor_position(payload: bytes | bytearray) -> float:
    """Decode a ROTOR_POSITION payload (command 22, int32 / 1000) into degrees.

    Raises:
        FrameError: not command 22 or not 5 bytes.
    """
    payload = _as_bytes(payload)
    if len(payload) != _ROTOR.size or payload[0] != UartPacket.ROTOR_POSITION:
        raise FrameError(f"not a 5-byte ROTOR_POSITION payload (command 22): {payload.hex(' ')}", data=payload)
    return _ROTOR.unpack(payload)[1] / 1000


def encode_rotor_position(degrees: float) -> bytes:
    """Motor side: a ROTOR_POSITION frame (degrees, int32 × 1000)."""
    return encode_frame(_ROTOR.pack(UartPacket.ROTOR_POSITION,
                                    _to_int("rotor position", degrees, 1000, _I32_MIN, _I32_MAX)))


class FirmwareVersion(NamedTuple):
    """A FW_VERSION reply: ``major``, ``minor`` and whatever the firmware appends (hardware name, UUID ...)."""

    major: int
    minor: int
    extra: bytes


def decode_fw_version(payload: bytes | bytearray) -> FirmwareVersion:
    """Decode a FW_VERSION reply: command 0, major, minor, then firmware-specific bytes kept raw.

    Raises:
        FrameError: not command 0 or shorter than 3 bytes.
    """
    payload = _as_bytes(payload)
    if len(payload) < 3 or payload[0] != UartPacket.FW_VERSION:
        raise FrameError("not a FW_VERSION reply (command 0, major, minor, ...)", data=payload)
    return FirmwareVersion(payload[1], payload[2], payload[3:])


Reply = GetValues | dict[ValueField, float] | RotorPosition | FirmwareVersion


def decode_payload(payload: bytes | bytearray, *, setup_fields: ValueField | int | None = None) -> Reply:
    """Decode a reply payload (motor → controller) by its command byte.

    GET_VALUES → :class:`GetValues`; GET_VALUES_SETUP → ``dict`` (needs ``setup_fields``, the
    fields that were requested, since the reply does not say); ROTOR_POSITION → :class:`RotorPosition`;
    FW_VERSION → :class:`FirmwareVersion`.

    Raises:
        ProtocolError: a GET_VALUES_SETUP reply without ``setup_fields``.
        FrameError: an empty payload, a command the motor does not send, or a malformed reply.
    """
    payload = _as_bytes(payload)
    if not payload:
        raise FrameError("empty UART payload")
    cmd = payload[0]
    if cmd == UartPacket.GET_VALUES:
        return decode_get_values(payload)
    if cmd == UartPacket.ROTOR_POSITION:
        return RotorPosition(decode_rotor_position(payload))
    if cmd == UartPacket.GET_VALUES_SETUP:
        if setup_fields is None:
            raise ProtocolError("a GET_VALUES_SETUP reply can only be decoded knowing the fields requested",
                                fix="pass setup_fields=the ValueField mask sent with encode_get_values_setup")
        return decode_get_values_setup(payload, setup_fields)
    if cmd == UartPacket.FW_VERSION:
        return decode_fw_version(payload)
    raise FrameError(f"command {cmd} is not a reply the motor sends", data=payload)
