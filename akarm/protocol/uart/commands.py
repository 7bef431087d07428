"""UART commands (controller → motor): one encoder per command, and the motor side's decoder."""

from __future__ import annotations

import struct
from typing import NamedTuple

from akarm.errors import FrameError, ProtocolError
from akarm.protocol._fields import Field, checked, fmt
from akarm.protocol.uart.framing import as_bytes, encode_frame
from akarm.protocol.uart.packets import (
    I32_MAX,
    I32_MIN,
    SETUP_KNOWN,
    UartPacket,
    ValueField,
    integer_argument,
    setup_mask,
)

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
    UartPacket.SET_POS: (_I32, (Field("position", "deg", 1_000_000.0, I32_MIN / 1e6, I32_MAX / 1e6),)),
    UartPacket.SET_HANDBRAKE: (_I32, (Field("handbrake current", "A", 1000.0, -60.0, 60.0),)),
    UartPacket.SET_DETECT: (_U8, (Field("detect mode", "", 1.0, 0.0, 255.0),)),
    UartPacket.GET_VALUES_SETUP: (_U32, (Field("field mask", "", 1.0, 1.0, float(SETUP_KNOWN)),)),
    UartPacket.SET_POS_SPD: (_3I32, (
        Field("position", "deg", 1000.0, -36_000.0, 36_000.0),
        Field("speed", "ERPM", 1.0, -100_000.0, 100_000.0),
        Field("acceleration", "ERPM/s", 1.0, 0.0, float(I32_MAX)),
    )),
    UartPacket.SET_POS_MULTI: (_I32, (Field("argument", "", 1.0, I32_MIN, I32_MAX),)),
    UartPacket.SET_POS_SINGLE: (_I32, (Field("argument", "", 1.0, I32_MIN, I32_MAX),)),
    UartPacket.SET_POS_UNLIMITED: (_NONE, ()),
    UartPacket.SET_POS_ORIGIN: (_U8, (Field("origin mode", "", 1.0, 0.0, 2.0),)),
}




def _command(packet: UartPacket, *values: float) -> bytes:
    st, args = _COMMANDS[packet]
    ints = [round(checked(a, v) * a.scale) for a, v in zip(args, values, strict=True)]
    for a, k in zip(args, ints, strict=True):  # rounding can step just past the field's edge
        if not I32_MIN <= k <= I32_MAX:
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
    return _command(UartPacket.SET_DETECT, integer_argument("detect mode", mode))


def encode_get_values_setup(fields: ValueField | int) -> bytes:
    """GET_VALUES_SETUP request frame asking for ``fields`` (a :class:`ValueField` combination; uint32).

    Raises:
        ProtocolError: no field, or a reserved bit (10-15, 19-32 in the manual's numbering).
    """
    return _command(UartPacket.GET_VALUES_SETUP, setup_mask(fields))


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
    return _command(UartPacket.SET_POS_ORIGIN, integer_argument("origin mode", mode))


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
    payload = as_bytes(payload)
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
    if packet is UartPacket.GET_VALUES_SETUP and int(values[0]) & ~SETUP_KNOWN:
        raise FrameError(f"GET_VALUES_SETUP asks for reserved bits 0x{int(values[0]) & ~SETUP_KNOWN:X}",
                         data=payload)
    return UartCommand(packet, tuple(values))


