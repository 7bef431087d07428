"""Servo mode over CAN: extended 29-bit frames, VESC-style packets (AK manual §5.1-5.2.1).

Controller side: one encoder per command, each returning ``(arbitration_id, data)`` for an
*extended* frame with ID ``(packet << 8) | motor_id``, and :func:`decode_status` for the periodic
``0x29xx`` status frames. Motor side (for the simulator): :func:`decode_command` and
:func:`encode_status`.

Units are the firmware's own, as the function and argument names say: degrees (at the output or at
the rotor, per the catalogue's ``servo_position``; :mod:`akarm.protocol.units` converts), electrical RPM
(ERPM = rotor RPM × pole pairs), ERPM/s, amps of Iq, duty as a fraction (0.2 = 20 %).

Scalings follow the protocol notes (``shared/docs/ak-protocol.md`` §2), which correct the seed manual:

==================  =====================================================  ==================
packet              payload (big-endian)                                   range accepted
==================  =====================================================  ==================
0 SET_DUTY          int32 duty × 100 000                                   -1 .. 1
1 SET_CURRENT       int32 mA                                               -60 .. 60 A
2 SET_CURRENT_BRAKE int32 mA                                               0 .. 60 A
3 SET_RPM           int32 ERPM                                             -100 000 .. 100 000
4 SET_POS           int32 degrees × 10 000 (not the seed's × 1 000 000)    -36 000 .. 36 000°
5 SET_ORIGIN_HERE   uint8 0 temporary, 1 permanent, 2 restore default      0, 1, 2
6 SET_POS_SPD       int32 deg × 10 000, int16 speed / 10 ERPM,             as SET_POS;
                    int16 accel / 10 ERPM/s (8 bytes)                      ±327 670 ERPM; 0 .. 327 670 ERPM/s
==================  =====================================================  ==================

A value outside its range raises :class:`~akarm.ProtocolError` naming the range: silently clamping a
servo command would move the motor somewhere else than asked. Values are rounded to the nearest
step of the wire unit (the seed's C code truncates, which turns 0.29 duty into 28 999).
"""

from __future__ import annotations

import math
import operator
import struct
from collections.abc import Callable
from enum import IntEnum
from typing import NamedTuple

from akarm.errors import FrameError, ProtocolError
from akarm.protocol._fields import Field, as_number, checked, fmt

__all__ = [
    "ACCEL_MAX_ERPM_S",
    "BRAKE_CURRENT_MAX_A",
    "CURRENT_MAX_A",
    "DUTY_MAX",
    "ENCODERS",
    "POSITION_MAX_DEG",
    "RPM_MAX",
    "SPEED_MAX_ERPM",
    "SPEED_MIN_ERPM",
    "OriginMode",
    "ServoCommand",
    "ServoErrorCode",
    "ServoPacket",
    "ServoStatus",
    "decode_command",
    "decode_status",
    "describe_error",
    "encode_current",
    "encode_current_brake",
    "encode_duty",
    "encode_origin",
    "encode_position",
    "encode_position_speed",
    "encode_rpm",
    "encode_status",
    "status_arbitration_id",
]

#: Largest |duty| accepted (fraction of the supply voltage).
DUTY_MAX = 1.0
#: Largest |Iq| accepted by SET_CURRENT, A.
CURRENT_MAX_A = 60.0
#: Largest brake current accepted by SET_CURRENT_BRAKE, A (negative is invalid).
BRAKE_CURRENT_MAX_A = 60.0
#: Largest |speed| accepted by SET_RPM, ERPM.
RPM_MAX = 100_000.0
#: Largest |position| accepted by SET_POS and SET_POS_SPD, degrees (±100 turns).
POSITION_MAX_DEG = 36_000.0
#: Speed range of SET_POS_SPD, ERPM (an int16 in units of 10 ERPM).
SPEED_MIN_ERPM = -32_768 * 10.0
SPEED_MAX_ERPM = 32_767 * 10.0
#: Acceleration range of SET_POS_SPD is 0 .. this, ERPM/s (an int16 in units of 10 ERPM/s).
ACCEL_MAX_ERPM_S = 32_767 * 10.0

_EXT_ID_MAX = 0x1FFF_FFFF


class ServoPacket(IntEnum):
    """The servo-mode CAN packet numbers (bits 8-15 of the extended ID)."""

    SET_DUTY = 0
    SET_CURRENT = 1
    SET_CURRENT_BRAKE = 2
    SET_RPM = 3
    SET_POS = 4
    SET_ORIGIN_HERE = 5
    SET_POS_SPD = 6
    STATUS = 0x29


class OriginMode(IntEnum):
    """Argument of SET_ORIGIN_HERE."""

    TEMPORARY = 0
    """Current position becomes the origin until power is lost."""
    PERMANENT = 1
    """Current position becomes the origin, saved in flash."""
    RESTORE_DEFAULT = 2
    """Back to the factory origin, saved in flash."""


_ERROR_TEXT: dict[int, tuple[str, str]] = {
    0: ("no fault", "nothing to do"),
    1: ("motor over-temperature", "let it cool; lower the duty or add cooling"),
    2: ("over-current", "lower the commanded current, gains or acceleration; check for a jam or a short"),
    3: ("supply over-voltage (often from braking energy fed back)",
        "decelerate more gently, lower the supply voltage or add a brake resistor"),
    4: ("supply under-voltage", "check the supply can deliver the peak current and its wiring is sound"),
    5: ("encoder fault", "check the encoder and its magnet, recalibrate, then power-cycle the driver"),
    6: ("MOSFET over-temperature (phase-current unbalance on V1.0.9 firmware)",
        "let the driver cool and improve its airflow; if it recurs cold, check the phase wiring"),
    7: ("motor stall", "remove the obstruction or lower the load and the commanded torque"),
}


class ServoErrorCode(IntEnum):
    """Error code in byte 7 of a status frame (also the MIT reply's error byte).

    Each member has a one-line :attr:`description` and :attr:`remedy`; :func:`describe_error`
    also handles codes that are not members.
    """

    NONE = 0
    MOTOR_OVER_TEMPERATURE = 1
    OVER_CURRENT = 2
    OVER_VOLTAGE = 3
    UNDER_VOLTAGE = 4
    ENCODER_FAULT = 5
    MOSFET_OVER_TEMPERATURE = 6
    MOTOR_STALL = 7

    @property
    def description(self) -> str:
        """What the code means, one line."""
        return _ERROR_TEXT[int(self)][0]

    @property
    def remedy(self) -> str:
        """What to do about it, one line."""
        return _ERROR_TEXT[int(self)][1]


def describe_error(code: int) -> tuple[str, str]:
    """``(description, remedy)`` for a servo/MIT error code, including codes no manual lists (and the
    serial port's faults that have no CAN code, passed on from 0x80 up by :mod:`akarm.buses.uart`)."""
    try:
        key = operator.index(code)
    except TypeError:
        key = None
    if key in _ERROR_TEXT:
        return _ERROR_TEXT[key]
    if key is not None:
        from akarm.protocol.uart.packets import describe_serial_fault

        serial = describe_serial_fault(key)
        if serial is not None:
            return serial
    return (f"unknown error code {code!r}",
            "look the code up for this firmware version; power-cycle the driver if it persists")


class ServoStatus(NamedTuple):
    """A decoded status frame, in the firmware's units.

    Attributes:
        motor_id: the sender's CAN ID (0-255).
        position_deg: degrees (resolution 0.1°), at the output or the rotor per ``servo_position``.
        speed_erpm: electrical RPM (resolution 10 ERPM).
        current_a: Iq in A (resolution 0.01 A).
        temperature_c: driver temperature in °C.
        error: error code (see :class:`ServoErrorCode`, :func:`describe_error`).
    """

    motor_id: int
    position_deg: float
    speed_erpm: float
    current_a: float
    temperature_c: float
    error: int


class ServoCommand(NamedTuple):
    """A decoded command (motor side), values in the units the encoders take.

    ``values`` is ``(duty,)``, ``(amps,)``, ``(amps,)``, ``(erpm,)``, ``(degrees,)``,
    ``(origin_mode,)`` or ``(degrees, erpm, erpm_per_s)`` for packets 0-6.
    """

    packet: ServoPacket
    motor_id: int
    values: tuple[float, ...]


def _motor_id(motor_id: int) -> int:
    try:
        mid = operator.index(motor_id)
    except TypeError:
        raise ProtocolError(f"motor id must be an integer, got {motor_id!r}", fix="use a CAN ID 0-255") from None
    if not 0 <= mid <= 255:
        raise ProtocolError(f"motor id {mid} is outside 0-255", fix="use the driver's CAN ID, 0-255")
    return mid


_I32 = struct.Struct(">i")
_U8 = struct.Struct(">B")
_POS_SPD = struct.Struct(">ihh")
_STATUS = struct.Struct(">hhhbB")

# packet -> (struct, fields)
_COMMANDS: dict[ServoPacket, tuple[struct.Struct, tuple[Field, ...]]] = {
    ServoPacket.SET_DUTY: (_I32, (Field("duty", "", 100_000.0, -DUTY_MAX, DUTY_MAX),)),
    ServoPacket.SET_CURRENT: (_I32, (Field("current", "A", 1000.0, -CURRENT_MAX_A, CURRENT_MAX_A),)),
    ServoPacket.SET_CURRENT_BRAKE: (_I32, (Field("brake current", "A", 1000.0, 0.0, BRAKE_CURRENT_MAX_A),)),
    ServoPacket.SET_RPM: (_I32, (Field("speed", "ERPM", 1.0, -RPM_MAX, RPM_MAX),)),
    ServoPacket.SET_POS: (_I32, (Field("position", "deg", 10_000.0, -POSITION_MAX_DEG, POSITION_MAX_DEG),)),
    ServoPacket.SET_ORIGIN_HERE: (_U8, (Field("origin mode", "", 1.0, 0.0, 2.0),)),
    ServoPacket.SET_POS_SPD: (_POS_SPD, (
        Field("position", "deg", 10_000.0, -POSITION_MAX_DEG, POSITION_MAX_DEG),
        Field("speed", "ERPM", 0.1, SPEED_MIN_ERPM, SPEED_MAX_ERPM),
        Field("acceleration", "ERPM/s", 0.1, 0.0, ACCEL_MAX_ERPM_S),
    )),
}


def _encode(packet: ServoPacket, motor_id: int, *values: float) -> tuple[int, bytes]:
    mid = _motor_id(motor_id)
    st, fields = _COMMANDS[packet]
    ints = [round(checked(f, v) * f.scale) for f, v in zip(fields, values, strict=True)]
    return (int(packet) << 8) | mid, st.pack(*ints)


def encode_duty(motor_id: int, duty: float) -> tuple[int, bytes]:
    """SET_DUTY: ``duty`` as a fraction of the supply voltage, -1 .. 1 (int32 × 100 000)."""
    return _encode(ServoPacket.SET_DUTY, motor_id, duty)


def encode_current(motor_id: int, amps: float) -> tuple[int, bytes]:
    """SET_CURRENT: Iq in A, -60 .. 60 (int32 mA). Output torque ≈ Iq · kt · gear ratio."""
    return _encode(ServoPacket.SET_CURRENT, motor_id, amps)


def encode_current_brake(motor_id: int, amps: float) -> tuple[int, bytes]:
    """SET_CURRENT_BRAKE: brake current in A, 0 .. 60 (int32 mA); negative raises ProtocolError."""
    return _encode(ServoPacket.SET_CURRENT_BRAKE, motor_id, amps)


def encode_rpm(motor_id: int, erpm: float) -> tuple[int, bytes]:
    """SET_RPM: speed in electrical RPM, -100 000 .. 100 000 (int32)."""
    return _encode(ServoPacket.SET_RPM, motor_id, erpm)


def encode_position(motor_id: int, degrees: float) -> tuple[int, bytes]:
    """SET_POS: position in degrees, -36 000 .. 36 000 (int32 × 10 000, resolution 0.0001°)."""
    return _encode(ServoPacket.SET_POS, motor_id, degrees)


def encode_origin(motor_id: int, mode: int | OriginMode = OriginMode.TEMPORARY) -> tuple[int, bytes]:
    """SET_ORIGIN_HERE: make the current position the origin; ``mode`` 0 temporary, 1 permanent, 2 default.

    One data byte.
    """
    try:
        m = operator.index(mode)
    except TypeError:
        raise ProtocolError(f"origin mode must be 0, 1 or 2, got {mode!r}") from None
    if m not in (0, 1, 2):
        raise ProtocolError(f"origin mode {m} is outside the range 0 .. 2",
                            fix="0 temporary, 1 permanent, 2 restore the default origin")
    return _encode(ServoPacket.SET_ORIGIN_HERE, motor_id, m)


def encode_position_speed(motor_id: int, degrees: float, erpm: float, erpm_per_s: float) -> tuple[int, bytes]:
    """SET_POS_SPD: go to ``degrees`` (±36 000) at up to ``erpm`` (±327 670 ERPM, step 10) with
    acceleration ``erpm_per_s`` (0 .. 327 670 ERPM/s, step 10). 8 bytes: int32, int16, int16.
    """
    return _encode(ServoPacket.SET_POS_SPD, motor_id, degrees, erpm, erpm_per_s)


def status_arbitration_id(motor_id: int) -> int:
    """The extended ID of ``motor_id``'s status frames: ``0x2900 | motor_id``."""
    return 0x2900 | _motor_id(motor_id)


def _as_bytes(data: object) -> bytes:
    try:
        if isinstance(data, str | int):
            raise TypeError
        return bytes(data)  # type: ignore[call-overload]
    except (TypeError, ValueError):
        raise FrameError(f"frame data must be bytes, got {type(data).__name__}") from None


def _check_id(arbitration_id: int, is_extended: bool) -> int:
    if not is_extended:
        raise FrameError(f"ID 0x{arbitration_id:X} is a standard frame; servo-mode frames are extended",
                         fix="pass is_extended=msg.is_extended_id and route standard frames to the MIT codec")
    if not 0 <= arbitration_id <= _EXT_ID_MAX:
        raise FrameError(f"arbitration ID {arbitration_id!r} is not a 29-bit CAN ID")
    return arbitration_id


def decode_status(arbitration_id: int, data: bytes | bytearray, *, is_extended: bool = True) -> ServoStatus:
    """Decode a status frame (extended ID ``0x2900 | motor_id``, 8 bytes).

    Fields: position int16 × 0.1°, speed int16 × 10 ERPM, current int16 × 0.01 A, temperature int8 °C,
    error uint8.

    Raises:
        FrameError: a standard frame, an ID that is not exactly ``0x29xx`` (bits 8-15 must be 0x29
            and every bit above them 0), or a length other than 8.
    """
    _check_id(arbitration_id, is_extended)
    if arbitration_id >> 8 != ServoPacket.STATUS:
        raise FrameError(f"ID 0x{arbitration_id:X} is not a servo status frame (0x2900 | motor id)")
    if not isinstance(data, bytes | bytearray):
        data = _as_bytes(data)
    if len(data) != 8:
        raise FrameError(f"servo status frame from motor {arbitration_id & 0xFF} has {len(data)} data bytes, not 8",
                         data=bytes(data))
    p, s, c, t, e = _STATUS.unpack(data)
    return ServoStatus(arbitration_id & 0xFF, p / 10, float(s * 10), c / 100, float(t), e)


def _saturate(name: str, value: float, scale: float, lo: int, hi: int) -> int:
    x = as_number(name, value)
    if math.isnan(x):
        raise ProtocolError(f"{name} is NaN", fix=f"report a finite {name}")
    x *= scale
    if x >= hi:
        return hi
    if x <= lo:
        return lo
    return round(x)


def encode_status(motor_id: int, position_deg: float, speed_erpm: float, current_a: float,
                  temperature_c: float, error: int = 0) -> tuple[int, bytes]:
    """Motor side: a status frame ``(0x2900 | motor_id, 8 bytes)``.

    ``position_deg`` in degrees (step 0.1°), ``speed_erpm`` in ERPM (step 10), ``current_a`` in A (step
    0.01), ``temperature_c`` in °C, ``error`` a code 0-255. Values past what an int16/int8 field holds
    saturate at the field's limit (±3276.7°, ±327 670 ERPM, ±327.67 A, -128 .. 127 °C), as a status
    report must still be sent; NaN raises ProtocolError.
    """
    aid = status_arbitration_id(motor_id)
    try:
        err = operator.index(error)
    except TypeError:
        raise ProtocolError(f"error code must be an integer, got {error!r}") from None
    if not 0 <= err <= 255:
        raise ProtocolError(f"error code {err} is outside 0-255")
    data = _STATUS.pack(
        _saturate("position", position_deg, 10.0, -32768, 32767),
        _saturate("speed", speed_erpm, 0.1, -32768, 32767),
        _saturate("current", current_a, 100.0, -32768, 32767),
        _saturate("temperature", temperature_c, 1.0, -128, 127),
        err,
    )
    return aid, data


_LENGTHS = {p: st.size for p, (st, _) in _COMMANDS.items()}


def decode_command(arbitration_id: int, data: bytes | bytearray, *, is_extended: bool = True) -> ServoCommand:
    """Motor side: decode a servo command frame into the units the encoders take.

    Raises:
        FrameError: a standard frame, an ID whose packet is not 0-6 or has bits above 15 set, a
            length that does not fit the packet (4 bytes for 0-4, 1 for 5, 8 for 6), or a value
            outside the packet's range (a negative brake current, origin mode 3, ...).
    """
    _check_id(arbitration_id, is_extended)
    try:
        packet = ServoPacket(arbitration_id >> 8)
    except ValueError:
        packet = None
    if packet is None or packet is ServoPacket.STATUS:
        raise FrameError(f"ID 0x{arbitration_id:X} is not a servo command (packet 0-6 in bits 8-15)")
    st, fields = _COMMANDS[packet]
    if not isinstance(data, bytes | bytearray):
        data = _as_bytes(data)
    if len(data) != st.size:
        raise FrameError(f"{packet.name} frame has {len(data)} data bytes, not {_LENGTHS[packet]}", data=bytes(data))
    values = []
    for f, n in zip(fields, st.unpack(data), strict=True):
        x = n / f.scale if f.scale != 1.0 else float(n)
        if not f.lo <= x <= f.hi:
            raise FrameError(f"{packet.name}: {f.name} {x:g} {f.unit} is outside {fmt(f.lo)} .. {fmt(f.hi)}",
                             data=bytes(data))
        values.append(x)
    return ServoCommand(packet, arbitration_id & 0xFF, tuple(values))


#: Encoder per command packet, for code that dispatches on :class:`ServoPacket`.
ENCODERS: dict[ServoPacket, Callable[..., tuple[int, bytes]]] = {
    ServoPacket.SET_DUTY: encode_duty,
    ServoPacket.SET_CURRENT: encode_current,
    ServoPacket.SET_CURRENT_BRAKE: encode_current_brake,
    ServoPacket.SET_RPM: encode_rpm,
    ServoPacket.SET_POS: encode_position,
    ServoPacket.SET_ORIGIN_HERE: encode_origin,
    ServoPacket.SET_POS_SPD: encode_position_speed,
}
