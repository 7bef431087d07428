"""MIT ("force control") mode: impedance commands and state replies (AK manual §5.3, with errata).

Controller side: :func:`encode_command` builds the 8-byte command, :func:`decode_reply` reads the
standard-frame reply (6 or 8 bytes), :func:`decode_reply_v3` the servo-style status frames V3 boards
answer with. Motor side (for the simulator): :func:`special_frame`, :func:`decode_command`,
:func:`encode_reply`. Everything is SI at the output shaft: rad, rad/s, N·m, N·m/rad, N·m·s/rad, °C.

Frame layout (V1/V2 firmware, standard ID = motor ID), a 64-bit big-endian word::

    p[15:0] v[11:0] kp[11:0] kd[11:0] t[11:0]
    byte6 = kd[3:0] << 4 | t[11:8]      (the seed manual's C code puts kp[11:8] there: an erratum)

V3 boards (``firmware="v3"``): extended ID ``(8 << 8) | motor_id`` and the fields reordered to
``kp kd p v t`` (same widths).

Quantisation. A value is first clamped to the model's range ``[x_min, x_max]`` (never wrapped), then
mapped to ``u = (x - x_min) · (2^bits - 1) / (x_max - x_min)`` (the notes' corrected formula: the
manual's ``2^bits / span`` turns +p_max into 0 and spills 12-bit fields into their neighbour) and
rounded to the *nearest* integer, so ``decode(encode(x))`` is within half a step of ``x``; the ends map
exactly to ``0`` and ``2^bits - 1``. An exact tie (only 0 in a symmetric range lands on one: ``u =
32767.5``) goes to the lower code, which is what the firmware's truncating C code sends, so a zero
command is ``7F FF 7F F0 00 00 07 FF`` as everywhere else. Decoding:
``x = u · (x_max - x_min) / (2^bits - 1) + x_min``. NaN cannot be clamped: it raises
:class:`~akarm.ProtocolError` naming the field.

Speed: :class:`MitCodec` computes every scale once per model; :func:`codec` caches one per model, and
the module-level functions use it.
"""

from __future__ import annotations

import math
import struct
from typing import Literal, NamedTuple

from akarm.errors import FrameError, ProtocolError
from akarm.protocol import motors, servo, units
from akarm.protocol.motors import MotorModel

__all__ = [
    "ENTER",
    "EXIT",
    "V3_COMMAND_PACKET",
    "ZERO",
    "Firmware",
    "MitCodec",
    "MitCommand",
    "MitReply",
    "codec",
    "command_arbitration_id",
    "decode_command",
    "decode_reply",
    "decode_reply_v3",
    "encode_command",
    "encode_reply",
    "special_frame",
]

Firmware = Literal["v2", "v3"]

#: Enter motor (MIT) mode. The firmware answers with a state reply, so this also reads the state.
ENTER: bytes = b"\xff" * 7 + b"\xfc"
#: Exit motor mode (the driver releases the output).
EXIT: bytes = b"\xff" * 7 + b"\xfd"
#: Make the current position zero (the motor is off-line for about 0.5-1.5 s afterwards).
ZERO: bytes = b"\xff" * 7 + b"\xfe"

#: Packet number of V3 MIT commands: extended ID ``(V3_COMMAND_PACKET << 8) | motor_id``.
V3_COMMAND_PACKET = 8

_SPECIAL: dict[bytes, Literal["enter", "exit", "zero"]] = {ENTER: "enter", EXIT: "exit", ZERO: "zero"}


class MitReply(NamedTuple):
    """A decoded state reply (SI, output shaft).

    Attributes:
        driver_id: CAN ID of the replying driver (byte 0; route replies by this, not by frame ID).
        position: rad, in [-p_max, p_max] (wraps there: track turns for longer travel).
        velocity: rad/s.
        torque: N·m (the 12-bit field drivers call "current").
        temperature: °C (``byte6 - mit_temp_offset``), or None in a 6-byte reply.
        error: error code (:func:`akarm.protocol.servo.describe_error`), or None in a 6-byte reply.
    """

    driver_id: int
    position: float
    velocity: float
    torque: float
    temperature: float | None
    error: int | None


class MitCommand(NamedTuple):
    """A decoded MIT command (SI, output shaft).

    Attributes:
        position: rad. velocity: rad/s. kp: N·m/rad. kd: N·m·s/rad. torque: feed-forward N·m.
    """

    position: float
    velocity: float
    kp: float
    kd: float
    torque: float


# NamedTuple's generated __new__ is a Python-level call; building the tuple directly halves the cost.
_new_reply = tuple.__new__
# Replies are unpacked with struct into small ints (id, p, three bytes holding v and i, temperature,
# error): measured 0.8 µs against 1.1 µs for int.from_bytes and shifts on a 64-bit int.
_REPLY8 = struct.Struct(">BHBBBBB").unpack
_REPLY6 = struct.Struct(">BHBBB").unpack


def _range(name: str, lo: float, hi: float, bits: int) -> tuple[float, float, float, float, float, int]:
    """(lo, hi, encode scale, encode constant, decode scale, max code) for one field.

    Encoding is ``u = m - int(c - x * s)``: with ``c = m + 0.5 + lo * s`` that is ``ceil(v - 0.5)`` for
    ``v = (x - lo) * s``, i.e. round to nearest with ties to the lower code, computed with one
    multiply and one subtract. For a symmetric range ``c`` is ``m/2 + 0.5`` exactly, so x = 0 is an
    exact tie whatever the model's range, and is always sent as the lower code.
    """
    lo, hi = float(lo), float(hi)
    if not lo < hi:
        raise ProtocolError(f"MIT {name} range {lo} .. {hi} is empty", fix=f"give the motor a positive {name} range")
    m = (1 << bits) - 1
    s = m / (hi - lo)
    c = m / 2 + 0.5 if lo == -hi else m + 0.5 + lo * s
    return lo, hi, s, c, (hi - lo) / m, m


def _nan(field: str) -> ProtocolError:
    return ProtocolError(f"MIT {field} is NaN; it cannot be clamped or sent", fix=f"pass a finite {field}")


def _not_number(field: str, value: object) -> ProtocolError:
    return ProtocolError(f"MIT {field} must be a real number, got {value!r}")


def _raw(data: object) -> bytes:
    """``data`` as bytes for an error report, or b"" when it is not bytes-like."""
    return bytes(data) if isinstance(data, bytes | bytearray | memoryview) else b""


def _byte(name: str, value: int) -> int:
    try:
        b = value.__index__()
    except (AttributeError, TypeError):
        raise ProtocolError(f"{name} must be an integer 0-255, got {value!r}") from None
    if not 0 <= b <= 255:
        raise ProtocolError(f"{name} {b} is outside 0-255")
    return b


class MitCodec:
    """The MIT codec of one motor model, with every scale computed once.

    Build one with :func:`codec` (cached) or ``MitCodec(model)``; ``model`` is a
    :class:`~akarm.protocol.motors.MotorModel` or a catalogue name.

    Attributes:
        model: the model whose ranges it uses.
        steps: one quantisation step of each command field (rad, rad/s, N·m/rad, N·m·s/rad, N·m);
            replies use the position, velocity and torque steps.
    """

    __slots__ = (
        "_kd_c", "_kd_d", "_kd_hi", "_kd_lo", "_kd_s",
        "_kp_c", "_kp_d", "_kp_hi", "_kp_lo", "_kp_s",
        "_p_c", "_p_d", "_p_hi", "_p_lo", "_p_s",
        "_t_c", "_t_d", "_t_hi", "_t_lo", "_t_s",
        "_temp_off",
        "_v_c", "_v_d", "_v_hi", "_v_lo", "_v_s",
        "model", "steps",
    )

    def __init__(self, model: MotorModel | str) -> None:
        m = motors.get(model)
        self.model = m
        self._p_lo, self._p_hi, self._p_s, self._p_c, self._p_d, _ = _range("position", -m.p_max, m.p_max, 16)
        self._v_lo, self._v_hi, self._v_s, self._v_c, self._v_d, _ = _range("velocity", -m.v_max, m.v_max, 12)
        self._kp_lo, self._kp_hi, self._kp_s, self._kp_c, self._kp_d, _ = _range("kp", 0.0, m.kp_max, 12)
        self._kd_lo, self._kd_hi, self._kd_s, self._kd_c, self._kd_d, _ = _range("kd", 0.0, m.kd_max, 12)
        self._t_lo, self._t_hi, self._t_s, self._t_c, self._t_d, _ = _range("torque", -m.t_max, m.t_max, 12)
        self._temp_off = float(m.mit_temp_offset)
        self.steps = MitCommand(self._p_d, self._v_d, self._kp_d, self._kd_d, self._t_d)

    def __repr__(self) -> str:
        return f"MitCodec({self.model.name!r})"

    # ---- controller side -------------------------------------------------------------------

    # C901 17 > 12, left as it was: the hot path: five inline clamps, no helper calls, by design
    def encode_command(self, position: float, velocity: float, kp: float, kd: float, torque: float,  # noqa: C901
                       *, firmware: Firmware = "v2") -> bytes:
        """The 8 data bytes of an MIT command.

        Args:
            position: target position, rad. velocity: target velocity, rad/s.
            kp: stiffness, N·m/rad (0 .. kp_max). kd: damping, N·m·s/rad (0 .. kd_max).
            torque: feed-forward torque, N·m.
            firmware: ``"v2"`` (seed layout, standard ID) or ``"v3"`` (kp kd p v t, extended ID).

        Values outside the model's ranges are clamped (never wrapped).

        Raises:
            ProtocolError: a NaN or non-numeric field (named), or an unknown firmware.
        """
        # NaN fails both comparisons of a clamp; int() then raises on it, and the except clause names it.
        try:
            if position > self._p_hi:
                position = self._p_hi
            elif position < self._p_lo:
                position = self._p_lo
            if velocity > self._v_hi:
                velocity = self._v_hi
            elif velocity < self._v_lo:
                velocity = self._v_lo
            if kp > self._kp_hi:
                kp = self._kp_hi
            elif kp < self._kp_lo:
                kp = self._kp_lo
            if kd > self._kd_hi:
                kd = self._kd_hi
            elif kd < self._kd_lo:
                kd = self._kd_lo
            if torque > self._t_hi:
                torque = self._t_hi
            elif torque < self._t_lo:
                torque = self._t_lo
            p = 0xFFFF - int(self._p_c - position * self._p_s)
            v = 0xFFF - int(self._v_c - velocity * self._v_s)
            ikp = 0xFFF - int(self._kp_c - kp * self._kp_s)
            ikd = 0xFFF - int(self._kd_c - kd * self._kd_s)
            t = 0xFFF - int(self._t_c - torque * self._t_s)
        except (TypeError, ValueError):  # NaN passes both clamps and stops at int(); or not a number
            named = (("position", position), ("velocity", velocity), ("kp", kp), ("kd", kd), ("torque", torque))
            for name, x in named:
                try:
                    nan = math.isnan(x)
                except (TypeError, ValueError):
                    raise _not_number(name, x) from None
                if nan:
                    raise _nan(name) from None
            raise _not_number("command", (position, velocity, kp, kd, torque)) from None
        if firmware == "v2":
            return ((p << 48) | (v << 36) | (ikp << 24) | (ikd << 12) | t).to_bytes(8, "big")
        if firmware == "v3":
            return ((ikp << 52) | (ikd << 40) | (p << 24) | (v << 12) | t).to_bytes(8, "big")
        raise _bad_firmware(firmware)

    def decode_reply(self, data: bytes | bytearray) -> MitReply:
        """Decode a V1/V2 state reply: 8 bytes, or 6 (no temperature, no error code) on some firmware.

        Returns SI values; temperature is ``byte6 - model.mit_temp_offset`` °C.

        Raises:
            FrameError: any other length.
        """
        try:
            n = len(data)
            if n == 8:
                did, p, b3, b4, b5, temp, err = _REPLY8(data)
                return _new_reply(MitReply, (did,
                                             p * self._p_d + self._p_lo,
                                             ((b3 << 4) | (b4 >> 4)) * self._v_d + self._v_lo,
                                             (((b4 & 0xF) << 8) | b5) * self._t_d + self._t_lo,
                                             temp - self._temp_off,
                                             err))
            if n == 6:
                did, p, b3, b4, b5 = _REPLY6(data)
                return _new_reply(MitReply, (did,
                                             p * self._p_d + self._p_lo,
                                             ((b3 << 4) | (b4 >> 4)) * self._v_d + self._v_lo,
                                             (((b4 & 0xF) << 8) | b5) * self._t_d + self._t_lo,
                                             None, None))
        except (TypeError, ValueError):  # not a bytes-like object: a list of ints, say
            try:
                raw = bytes(data)
            except (TypeError, ValueError):
                raise FrameError(f"an MIT reply must be bytes, got {type(data).__name__}") from None
            return self.decode_reply(raw)
        raise FrameError(f"an MIT reply has 6 or 8 data bytes, this one {n}", data=_raw(data))

    def decode_reply_v3(self, arbitration_id: int, data: bytes | bytearray, *, is_extended: bool = True) -> MitReply:
        """Decode a V3 board's reply, a servo-style status frame (extended ID ``0x2900 | driver id``).

        Position (0.1°) → rad at the output (:func:`akarm.protocol.units.servo_deg_to_rad`, honouring the model's
        ``servo_position``), speed (10 ERPM) → rad/s, current (0.01 A) → N·m through kt · gear ratio,
        temperature °C as sent, driver id from the ID's low byte.

        Raises:
            FrameError: not an 8-byte ``0x29xx`` extended frame.
            ConfigError: the model has no torque constant ``kt``.
        """
        st = servo.decode_status(arbitration_id, data, is_extended=is_extended)
        m = self.model
        return MitReply(st.motor_id, units.servo_deg_to_rad(m, st.position_deg), units.erpm_to_rad_s(m, st.speed_erpm),
                        units.amps_to_torque(m, st.current_a), st.temperature_c, st.error)

    # ---- motor side (simulator) ------------------------------------------------------------

    def decode_command(self, data: bytes | bytearray, *, firmware: Firmware = "v2") -> MitCommand:
        """Motor side: decode an 8-byte command into SI values (see :class:`MitCommand`).

        Raises:
            FrameError: not 8 bytes.
            ProtocolError: a V2 special frame (enter/exit/zero: check :func:`special_frame` first),
                or an unknown firmware.
        """
        try:
            n = len(data)
        except TypeError:
            raise FrameError(f"an MIT command must be bytes, got {type(data).__name__}") from None
        if n != 8:
            raise FrameError(f"an MIT command has 8 data bytes, this one {n}", data=_raw(data))
        try:
            w = int.from_bytes(data, "big")
            raw = bytes(data)
        except (TypeError, ValueError):
            raise FrameError(f"an MIT command must be bytes, got {type(data).__name__}") from None
        if firmware == "v2":
            special = _SPECIAL.get(raw)
            if special is not None:
                raise ProtocolError(f"this is the {special!r} special frame, not a command",
                                    fix="check special_frame(data) before decode_command")
            p, v, kp, kd, t = w >> 48, (w >> 36) & 0xFFF, (w >> 24) & 0xFFF, (w >> 12) & 0xFFF, w & 0xFFF
        elif firmware == "v3":
            kp, kd, p, v, t = w >> 52, (w >> 40) & 0xFFF, (w >> 24) & 0xFFFF, (w >> 12) & 0xFFF, w & 0xFFF
        else:
            raise _bad_firmware(firmware)
        return MitCommand(p * self._p_d + self._p_lo, v * self._v_d + self._v_lo, kp * self._kp_d + self._kp_lo,
                          kd * self._kd_d + self._kd_lo, t * self._t_d + self._t_lo)

    def encode_reply(self, driver_id: int, position: float, velocity: float, torque: float,
                     temperature: float = 25.0, error: int = 0, *, length: int = 8) -> bytes:
        """Motor side: a V1/V2 state reply.

        Args:
            driver_id: byte 0, 0-255.
            position: rad. velocity: rad/s. torque: N·m. All clamped to the model's ranges.
            temperature: °C; sent as ``round(temperature + mit_temp_offset)`` clamped to 0..255.
            error: error code 0-255.
            length: 8, or 6 for firmware that leaves out temperature and error.

        Raises:
            ProtocolError: NaN, a driver id or error outside 0-255, a length other than 6 or 8.
        """
        did = _byte("driver id", driver_id)
        err = _byte("error code", error)
        try:
            vals = []
            for name, x, lo, hi, s, c, m in (
                ("position", position, self._p_lo, self._p_hi, self._p_s, self._p_c, 0xFFFF),
                ("velocity", velocity, self._v_lo, self._v_hi, self._v_s, self._v_c, 0xFFF),
                ("torque", torque, self._t_lo, self._t_hi, self._t_s, self._t_c, 0xFFF),
            ):
                if x != x:
                    raise _nan(name)
                vals.append(m - int(c - min(max(float(x), lo), hi) * s))
            temp = float(temperature) + self._temp_off
            if temp != temp:
                raise _nan("temperature")
            tb = 0 if temp <= 0 else 255 if temp >= 255 else round(temp)
        except ProtocolError:
            raise
        except (TypeError, ValueError):
            raise _not_number("reply field", (position, velocity, torque, temperature)) from None
        p, v, t = vals
        w = (did << 56) | (p << 40) | (v << 28) | (t << 16) | (tb << 8) | err
        if length == 8:
            return w.to_bytes(8, "big")
        if length == 6:
            return (w >> 16).to_bytes(6, "big")
        raise ProtocolError(f"an MIT reply is 6 or 8 bytes long, not {length!r}")


def _bad_firmware(firmware: object) -> ProtocolError:
    return ProtocolError(f"unknown MIT firmware {firmware!r}", fix='use "v2" (V1/V2 boards) or "v3" (2024 V3 boards)')


_BY_MODEL: dict[int, tuple[MotorModel, MitCodec]] = {}
_BY_NAME: dict[str, tuple[motors.Catalogue, MitCodec]] = {}
_CACHE_MAX = 256


def codec(model: MotorModel | str) -> MitCodec:
    """The cached :class:`MitCodec` of ``model`` (a :class:`~akarm.protocol.motors.MotorModel` or catalogue name).

    A name is resolved in the current default catalogue: after :func:`akarm.protocol.motors.load` replaces it,
    the name's codec is rebuilt from the new entry.
    """
    if model.__class__ is str:
        cat = motors.default_catalogue()
        named = _BY_NAME.get(model)
        if named is not None and named[0] is cat:
            return named[1]
        c = codec(cat.get(model))
        if len(_BY_NAME) >= _CACHE_MAX:
            _BY_NAME.clear()
        _BY_NAME[model] = (cat, c)
        return c
    if not isinstance(model, MotorModel):
        model = motors.get(model)
    entry = _BY_MODEL.get(id(model))
    if entry is not None and entry[0] is model:
        return entry[1]
    if len(_BY_MODEL) >= _CACHE_MAX:  # many throw-away models (tests, per-joint overrides): start afresh
        _BY_MODEL.clear()
        _BY_NAME.clear()
    c = MitCodec(model)
    _BY_MODEL[id(model)] = (model, c)  # the entry keeps the model alive, so its id cannot be reused
    return c


def command_arbitration_id(motor_id: int, firmware: Firmware = "v2") -> tuple[int, bool]:
    """``(arbitration_id, is_extended)`` for MIT commands to ``motor_id`` (0-255).

    V2: ``(motor_id, False)``, a standard frame. V3: ``((8 << 8) | motor_id, True)``.
    """
    mid = _byte("motor id", motor_id)
    if firmware == "v2":
        return mid, False
    if firmware == "v3":
        return (V3_COMMAND_PACKET << 8) | mid, True
    raise _bad_firmware(firmware)


def encode_command(model: MotorModel | str, position: float, velocity: float, kp: float, kd: float, torque: float,
                   *, firmware: Firmware = "v2") -> bytes:
    """The 8 data bytes of an MIT command: rad, rad/s, N·m/rad, N·m·s/rad, N·m; clamped to ``model``'s ranges.

    See :meth:`MitCodec.encode_command`.
    """
    return codec(model).encode_command(position, velocity, kp, kd, torque, firmware=firmware)


def decode_reply(model: MotorModel | str, data: bytes | bytearray) -> MitReply:
    """Decode a V1/V2 state reply (6 or 8 bytes) into SI values. See :meth:`MitCodec.decode_reply`."""
    return codec(model).decode_reply(data)


def decode_reply_v3(model: MotorModel | str, arbitration_id: int, data: bytes | bytearray,
                    *, is_extended: bool = True) -> MitReply:
    """Decode a V3 reply (``0x29xx`` status frame) into SI values. See :meth:`MitCodec.decode_reply_v3`."""
    return codec(model).decode_reply_v3(arbitration_id, data, is_extended=is_extended)


def special_frame(data: bytes | bytearray) -> Literal["enter", "exit", "zero"] | None:
    """Motor side: ``"enter"``, ``"exit"`` or ``"zero"`` when ``data`` is that V1/V2 special frame, else None."""
    try:
        return _SPECIAL.get(bytes(data)) if len(data) == 8 else None
    except (TypeError, ValueError):
        return None


def decode_command(model: MotorModel | str, data: bytes | bytearray, *, firmware: Firmware = "v2") -> MitCommand:
    """Motor side: decode an 8-byte command into SI values. See :meth:`MitCodec.decode_command`."""
    return codec(model).decode_command(data, firmware=firmware)


def encode_reply(model: MotorModel | str, driver_id: int, position: float, velocity: float, torque: float,
                 temperature: float = 25.0, error: int = 0, *, length: int = 8) -> bytes:
    """Motor side: a V1/V2 state reply (rad, rad/s, N·m, °C; clamped). See :meth:`MitCodec.encode_reply`."""
    return codec(model).encode_reply(driver_id, position, velocity, torque, temperature, error, length=length)
