"""UART replies (motor → controller): decoders, and the motor side's encoders."""

from __future__ import annotations

import functools
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

from akarm.errors import FrameError, ProtocolError
from akarm.protocol._fields import as_number
from akarm.protocol.uart.framing import as_bytes, encode_frame
from akarm.protocol.uart.packets import I32_MAX, I32_MIN, SETUP_FIELDS, FaultCode, UartPacket, ValueField, setup_mask

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
    payload = as_bytes(payload)
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
    i16, i32 = (-(1 << 15), (1 << 15) - 1), (I32_MIN, I32_MAX)
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
    st, wanted = _setup_layout(setup_mask(fields))
    payload = as_bytes(payload)
    if not payload or payload[0] != UartPacket.GET_VALUES_SETUP:
        raise FrameError("not a GET_VALUES_SETUP reply (command 50)", data=payload)
    if len(payload) != st.size:
        names = ", ".join(f.name or "" for f, _ in wanted)
        raise FrameError(f"a GET_VALUES_SETUP reply with {names} has {st.size} payload bytes, this one "
                         f"{len(payload)}", data=payload, fix="decode with the field set that was requested")
    return {f: k if div is None else (k / div if div != 1.0 else float(k))
            for (f, div), k in zip(wanted, st.unpack(payload)[1:], strict=True)}


@functools.lru_cache(maxsize=64)
def _setup_layout(mask: int) -> tuple[struct.Struct, tuple[tuple[ValueField, float | None], ...]]:
    """The reply to a GET_VALUES_SETUP for ``mask`` (an int): its whole payload's struct (the command
    byte first), and each field with its divisor, in bit order (worked out once per mask: polls repeat)."""
    wanted = [(f, st, div) for f, st, div in SETUP_FIELDS if mask & int(f)]
    layout = struct.Struct(">B" + "".join(st.format.lstrip(">") for _, st, _ in wanted))
    return layout, tuple((f, div) for f, _, div in wanted)


def encode_get_values_setup_reply(values: Mapping[ValueField, float]) -> bytes:
    """Motor side: a GET_VALUES_SETUP reply frame carrying ``values`` (fields in bit order, units as decoded).

    Raises:
        ProtocolError: no field, a combined or unknown flag as a key, or a value that does not fit.
    """
    if not values:
        raise ProtocolError("a GET_VALUES_SETUP reply needs at least one field")
    known = {f for f, _, _ in SETUP_FIELDS}
    for key in values:
        if key not in known:
            raise ProtocolError(f"{key!r} is not a single GET_VALUES_SETUP field")
    parts = [bytes((UartPacket.GET_VALUES_SETUP,))]
    for f, st, div in SETUP_FIELDS:
        if f in values:
            lo, hi = {1: (0, 255), 2: (-(1 << 15), (1 << 15) - 1), 4: (I32_MIN, I32_MAX)}[st.size]
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
    payload = as_bytes(payload)
    if len(payload) != _ROTOR.size or payload[0] != UartPacket.ROTOR_POSITION:
        raise FrameError(f"not a 5-byte ROTOR_POSITION payload (command 22): {payload.hex(' ')}", data=payload)
    return _ROTOR.unpack(payload)[1] / 1000


def encode_rotor_position(degrees: float) -> bytes:
    """Motor side: a ROTOR_POSITION frame (degrees, int32 × 1000)."""
    return encode_frame(_ROTOR.pack(UartPacket.ROTOR_POSITION,
                                    _to_int("rotor position", degrees, 1000, I32_MIN, I32_MAX)))


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
    payload = as_bytes(payload)
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
    payload = as_bytes(payload)
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
