"""``akarm_uart``: one servo-mode motor on a serial port (the R-link's UART side), as a python-can bus.

The controller drives servo joints with CAN frames (SET_POS_SPD, current, brake, origin ...) and
reads their ``0x29xx`` status frames. This bus carries the same frames over the motor's serial port
(AK manual §5.2.2, :mod:`akarm.protocol.uart`), so a servo joint whose bus is a serial port needs
nothing else::

    buses:
      pan: {interface: akarm_uart, channel: /dev/ttyUSB0, baudrate: 921600}

**Out.** Each servo command frame becomes the UART command that means the same, in the UART's own
units (SET_POS_SPD: degrees × 1000 and whole ERPM, where CAN has degrees × 10 000 and tens of ERPM;
SET_POS: degrees × 1 000 000, so only ±2147°; SET_ORIGIN_HERE: SET_POS_ORIGIN). Frames that are not
servo commands (MIT frames, another motor's ID) go nowhere, as on a CAN bus where no node takes
them; they are counted (:attr:`UartBus.unsent`, :attr:`UartBus.foreign`). On opening, the motor's
position loop is put in multi-turn mode (SET_POS_MULTI, ±100 turns), which is what servo mode over
CAN does; ``multi_turn=False`` leaves the motor's setting alone.

**In.** Over UART the motor reports nothing on its own but ROTOR_POSITION (every 10 ms after
SET_DETECT: a position alone, no speed, current, temperature or fault). So the bus polls: once per
*window*, it asks for position, speed, Iq, both temperatures, the fault code and the motor's ID
(GET_VALUES_SETUP, a 10-byte request and a 24-byte reply; ``poll="values"`` asks for the whole
GET_VALUES instead, 6 and 79 bytes), and turns each reply into the servo status frame the motor would
send on CAN (ID ``0x2900 |`` the ID the motor reports; the hotter of its two temperatures; its
serial fault code as the status frame's error code, :func:`akarm.protocol.uart.packets.status_code`).
A window ends each time a caller that does not wait (``recv(timeout=0)``, as the control loop's
drain each cycle) finds nothing more to read: one poll per control cycle, so status comes at the
loop's rate. A caller that waits gets a poll every ``poll_interval`` s.

**Faults on the wire.** Replies are found in the byte stream whatever is around them
(:class:`akarm.protocol.uart.FrameDecoder`). Every window without a good reply is classed: replies
with a bad CRC, replies cut short (a reply's header seen, its end never), bytes that form no frame
(noise, a wrong baud rate), or nothing at all. A lone bad window only costs one status frame. While
the motor is being commanded (a motion command in the last few windows), ``errors_in_row`` bad
windows in a row raise the class's named error from :meth:`UartBus.recv`: :class:`~akarm.UartBadCrc`,
:class:`~akarm.UartPartialFrame`, :class:`~akarm.UartNoise` or :class:`~akarm.UartSilent`. The
controller then loses the bus and stops the arm (:class:`~akarm.BusLost`, the error as its cause);
commands still go out (the stop's damping and release). While nothing is commanded (an arm open but
disabled, a motor not yet powered) nothing is raised, as on CAN: an enable that finds no status then
fails with :class:`~akarm.FeedbackTimeout`, whose fix says what the line carried
(:func:`diagnose`).

One motor per port: the serial protocol has no addresses.
"""

from __future__ import annotations

import binascii
import collections
import math
import struct
import threading
import time
import weakref
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import can

from akarm.buses.frames import message
from akarm.buses.serialport import DEFAULT_BAUDRATE, Port, open_serial
from akarm.errors import (
    AkarmError,
    ArgumentError,
    BusError,
    ProtocolError,
    UartBadCrc,
    UartError,
    UartNoise,
    UartPartialFrame,
    UartSilent,
)
from akarm.protocol import servo, uart
from akarm.protocol.uart.packets import SETUP_FIELDS, status_code

if TYPE_CHECKING:
    from akarm.config import RobotConfig

__all__ = ["DEFAULT_BAUDRATE", "ERRORS_IN_ROW", "INTERFACE", "STATUS_FIELDS", "UartBus", "diagnose",
           "position_speed", "serial_config", "setup_status", "to_uart"]

INTERFACE = "akarm_uart"
#: What a poll asks for (GET_VALUES_SETUP): all a servo status frame carries, and the motor's ID.
STATUS_FIELDS = (uart.ValueField.MOSFET_TEMPERATURE | uart.ValueField.MOTOR_TEMPERATURE | uart.ValueField.IQ_CURRENT
                 | uart.ValueField.SPEED | uart.ValueField.ERROR | uart.ValueField.POSITION | uart.ValueField.MOTOR_ID)
ERRORS_IN_ROW = 2  #: bad windows in a row that raise, while the motor is commanded
POLL_INTERVAL = 0.005  #: s between polls while a caller waits in recv
BACKLOG_LIMIT = 4096  #: bytes the port may leave unwritten before sends are refused
_ARMED_WINDOWS = 5  #: windows after a motion command during which bad windows raise
_MAX_REPLY = 128  #: the longest payload a reply may have (GET_VALUES: 73); longer headers are noise
_KEEP = 512  #: bytes of a window kept to look for a cut-short reply's header and to show in errors
_MIN_CURRENT = 0.05  #: A: a current below this releases the output (VESC), so it commands nothing
_MOTION = frozenset({servo.ServoPacket.SET_DUTY, servo.ServoPacket.SET_CURRENT, servo.ServoPacket.SET_CURRENT_BRAKE,
                     servo.ServoPacket.SET_RPM, servo.ServoPacket.SET_POS, servo.ServoPacket.SET_POS_SPD})

_SETUP_REPLY = 1 + sum(st.size for f, st, _ in SETUP_FIELDS if STATUS_FIELDS & f)  #: its payload's length: 19

_open: weakref.WeakValueDictionary[str, UartBus] = weakref.WeakValueDictionary()


# The hot path, every control cycle: SET_POS_SPD out, the status poll's reply in, as whole-struct work
# on the wire's integers (the generic codecs check each field: five times the cost, for frames whose
# fields are in range by construction). tests/unit/test_uart_transport.py checks both against the codecs.
_CAN_POS_SPD = struct.Struct(">ihh")  # degrees x 10 000, tens of ERPM, tens of ERPM/s
_UART_POS_SPD = struct.Struct(">Biii")  # command, degrees x 1000, ERPM, ERPM/s
_SETUP = struct.Struct(">BhhiiBiB")  # the poll's reply: 50, MOSFET and motor °C x 10, Iq A x 100, ERPM, fault,
#                                      degrees x 1e6, motor ID (ValueField bit order)
_STATUS = struct.Struct(">hhhbB")  # the servo status frame: 0.1°, 10 ERPM, 0.01 A, °C, error code
_STATUS_CODES = bytes(status_code(k) for k in range(256))


def _clamp(x: int, lo: int, hi: int) -> int:
    return lo if x < lo else hi if x > hi else x


def position_speed(data: bytes | bytearray) -> bytes:
    """The UART SET_POS_SPD frame for a CAN SET_POS_SPD frame's 8 data bytes (speed beyond the UART
    field's ±100 000 ERPM is limited to it)."""
    p, v, a = _CAN_POS_SPD.unpack(data)
    payload = _UART_POS_SPD.pack(uart.UartPacket.SET_POS_SPD, round(p / 10), _clamp(10 * v, -100_000, 100_000),
                                 max(0, 10 * a))
    crc = binascii.crc_hqx(payload, 0)
    return b"\x02\x0d" + payload + bytes((crc >> 8, crc & 0xFF, 3))


def setup_status(payload: bytes) -> tuple[int, bytes]:
    """The servo status frame ``(ID, 8 bytes)`` for a reply to the poll (:data:`STATUS_FIELDS`, 19 bytes)."""
    _, mos, mot, iq, erpm, fault, udeg, motor_id = _SETUP.unpack(payload)
    return (0x2900 | motor_id, _STATUS.pack(_clamp(round(udeg / 100_000), -32768, 32767),
                                            _clamp(round(erpm / 10), -32768, 32767), _clamp(iq, -32768, 32767),
                                            _clamp(round(max(mos, mot) / 10), -128, 127), _STATUS_CODES[fault]))


def to_uart(command: servo.ServoCommand) -> bytes:
    """The UART frame for a decoded servo CAN command (values in the units the servo codec uses).

    Raises:
        ProtocolError: a value the UART field cannot carry (SET_POS past ±2147.48°).
    """
    p, v = command.packet, command.values
    if p is servo.ServoPacket.SET_POS_SPD:
        return uart.encode_position_speed(v[0], v[1], v[2])
    if p is servo.ServoPacket.SET_CURRENT:
        return uart.encode_current(v[0])
    if p is servo.ServoPacket.SET_CURRENT_BRAKE:
        return uart.encode_current_brake(v[0])
    if p is servo.ServoPacket.SET_ORIGIN_HERE:
        return uart.encode_origin(int(v[0]))
    if p is servo.ServoPacket.SET_DUTY:
        return uart.encode_duty(v[0])
    if p is servo.ServoPacket.SET_RPM:
        return uart.encode_rpm(v[0])
    return uart.encode_position(v[0])  # SET_POS


class UartBus(can.BusABC):
    """A python-can bus on the serial port ``channel`` with one servo motor on it (see the module's docstring).

    Args:
        channel: the serial device (``/dev/ttyUSB0``, ``COM3``, ``/dev/pts/7``) or a pyserial URL.
        baudrate: bit/s (921 600 for AK drivers).
        poll: ``"setup"`` (GET_VALUES_SETUP, the fields a status frame needs) or ``"values"`` (GET_VALUES).
        errors_in_row: bad windows in a row that raise while the motor is commanded (at least 1).
        poll_interval: s between polls while a caller waits in :meth:`recv`.
        multi_turn: put the motor's position loop in multi-turn mode on opening (as servo mode over CAN).
        low_latency: ask the serial driver to pass bytes on at once (Linux).
        exclusive: lock the port against a second program (POSIX).
        bitrate, receive_own_messages and other python-can arguments: accepted and ignored
        (``can_filters`` works).

    Attributes:
        motor_id: the ID the motor reports (``None`` before its first reply).
        polls: polls sent. replies: good replies turned into status frames.
        bad_crc, partial, noise, silent: windows without a good reply, by what the line carried.
        bad_in_row: such windows in a row now.
        unsent: frames not carried (not servo commands). foreign: commands for another motor ID.
        other: frames from the motor that are no status (ROTOR_POSITION, FW_VERSION).

    Raises:
        BusError: the port will not open (the message says why and what to check), or a bad argument.
    """

    def __init__(self, channel: Any = None, baudrate: int = DEFAULT_BAUDRATE, poll: str = "setup",
                 errors_in_row: int = ERRORS_IN_ROW, poll_interval: float = POLL_INTERVAL, multi_turn: bool = True,
                 low_latency: bool = True, exclusive: bool = True, **kwargs: Any) -> None:
        if not channel:
            raise BusError("an akarm_uart bus needs a channel: the serial device",
                           fix="e.g. {interface: akarm_uart, channel: /dev/ttyUSB0, baudrate: 921600}")
        if poll not in ("setup", "values"):
            raise ArgumentError(f"poll {poll!r} is not 'setup' or 'values'",
                                fix="'setup' (GET_VALUES_SETUP, the default) or 'values' (GET_VALUES)")
        if isinstance(errors_in_row, bool) or not isinstance(errors_in_row, int) or errors_in_row < 1:
            raise ArgumentError(f"errors_in_row {errors_in_row!r} must be a whole number ≥ 1", fix="e.g. 2")
        if not isinstance(baudrate, int) or isinstance(baudrate, bool) or baudrate <= 0:
            raise ArgumentError(f"baudrate {baudrate!r} must be a positive whole number", fix="AK drivers use 921600")
        self.channel = str(channel)
        self.channel_info = f"akarm_uart port {self.channel!r}"
        self.baudrate = baudrate
        self.errors_in_row = errors_in_row
        self.poll_interval = float(poll_interval)
        self._setup = poll == "setup"
        self._request = uart.encode_get_values_setup(STATUS_FIELDS) if self._setup else uart.encode_get_values()
        self._headers = (bytes((2, _SETUP_REPLY, uart.UartPacket.GET_VALUES_SETUP)) if self._setup
                         else bytes((2, 73, uart.UartPacket.GET_VALUES)))  # a reply's first three bytes
        self._port: Port = open_serial(self.channel, baudrate, exclusive=exclusive, low_latency=low_latency)
        self._lock = threading.Lock()
        self._decoder = uart.FrameDecoder(max_payload=_MAX_REPLY)
        self._queue: collections.deque[can.Message] = collections.deque()
        self.motor_id: int | None = None
        self.polls = self.replies = self.unsent = self.foreign = self.other = 0
        self.bad_crc = self.partial = self.noise = self.silent = 0
        self.bad_in_row = 0
        self._last_bad = ""
        self._window = 0  # windows ended so far
        self._armed_until = -1  # bad windows raise while _window < this
        self._polled = False  # a poll went out when the current window began
        self._polled_at = -math.inf  # time.monotonic() of the last poll
        self._good = 0  # good replies in the current window
        self._bytes = 0  # bytes received in the current window
        self._crc0 = 0  # the decoder's CRC error count when the window began
        self._raw = bytearray()  # the current window's first bytes
        self._stale = False  # the decoder held part of a frame when the last window ended
        self._failed: BaseException | None = None
        try:
            self._port.discard_input()  # replies meant for a program that had the port before
            if multi_turn:
                self._write(uart.encode_multi_turn())
        except OSError as e:
            self._port.close()
            raise BusError(f"{self.channel_info}: cannot write to it: {e}",
                           fix="check the adapter and its cable") from None
        super().__init__(channel=self.channel, can_filters=kwargs.get("can_filters"))
        _open[self.channel] = self

    def __repr__(self) -> str:
        return (f"UartBus({self.channel!r}, motor_id={self.motor_id}, polls={self.polls}, replies={self.replies}, "
                f"bad_crc={self.bad_crc}, partial={self.partial}, noise={self.noise}, silent={self.silent})")

    # -- out -------------------------------------------------------------------------------------
    def _write(self, frame: bytes) -> None:
        with self._lock:
            self._port.write(frame)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Write the UART command for a servo command frame (other frames are counted, not carried).

        Raises:
            can.CanOperationError: the port failed, takes no more bytes, or the value does not fit
                the UART field.
        """
        if self._port.closed:
            raise can.CanOperationError(f"{self.channel_info} is shut down")
        if not msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            self.unsent += 1
            return
        aid, data = msg.arbitration_id, msg.data
        if aid >> 8 == servo.ServoPacket.SET_POS_SPD and len(data) == 8 and aid < 0x10000:  # every cycle
            if self.motor_id is not None and aid & 0xFF != self.motor_id:
                self.foreign += 1
                return
            frame = position_speed(data)
            packet = servo.ServoPacket.SET_POS_SPD
        else:
            try:
                command = servo.decode_command(aid, data)
            except ProtocolError:
                self.unsent += 1
                return
            if self.motor_id is not None and command.motor_id != self.motor_id:
                self.foreign += 1  # on CAN another motor would take it; there is none on this port
                return
            try:
                frame = to_uart(command)
            except ProtocolError as e:
                raise can.CanOperationError(f"{self.channel_info}: {e.what}") from None
            packet = command.packet
        try:
            self._write(frame)
        except OSError as e:
            raise can.CanOperationError(f"{self.channel_info}: cannot write: {e}") from None
        if self._port.backlog > BACKLOG_LIMIT:
            raise can.CanOperationError(f"{self.channel_info} takes no more bytes ({self._port.backlog} waiting): "
                                        "nothing reads the other end")
        if packet in _MOTION and (packet is not servo.ServoPacket.SET_CURRENT
                                  or abs(command.values[0]) >= _MIN_CURRENT):
            self._armed_until = self._window + _ARMED_WINDOWS

    # -- in --------------------------------------------------------------------------------------
    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next status frame, or ``None`` after ``timeout`` s (0: do not wait; ``None``: for ever).

        Raises:
            UartError: ``errors_in_row`` windows in a row without a good reply while the motor is
                commanded (:class:`~akarm.UartBadCrc`, :class:`~akarm.UartPartialFrame`,
                :class:`~akarm.UartNoise`, :class:`~akarm.UartSilent`).
            BusError: the port failed (unplugged; the other end closed).
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        # the window began with the last poll, whoever called then: callers that wait a little at a time
        # (a probe going round several buses 1 ms each) still get a poll every poll_interval
        window_end = self._polled_at + self.poll_interval
        while True:
            msg = self._next()
            if msg is not None:
                return msg
            if timeout == 0.0:
                if not self._flush_stale():
                    self._end_window()
                    return None
                continue
            now = time.monotonic()
            if now >= window_end:
                if not self._flush_stale():
                    self._end_window()
                window_end = self._polled_at + self.poll_interval
                continue
            if deadline is not None and now >= deadline:
                return None
            self._port.wait(min(window_end, deadline if deadline is not None else window_end) - now)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), False

    def _next(self) -> can.Message | None:
        """The next message that passes the filters, reading what has arrived first."""
        while True:
            if not self._queue:
                self._read()
                if not self._queue:
                    return None
            msg = self._queue.popleft()
            if self._filters is None or self._matches_filters(msg):
                return msg

    def _read(self, check: bool = False) -> None:
        if self._failed is not None:
            raise self._failed
        try:
            data = self._port.read(check)
        except OSError as e:
            self._failed = self._port_failed(e)
            raise self._failed from None
        if not data:
            return
        self._bytes += len(data)
        if len(self._raw) < _KEEP:
            self._raw += data[:_KEEP - len(self._raw)]
        self._take(self._decoder.feed(data))

    def _port_failed(self, error: OSError) -> BusError:
        return BusError(f"{self.channel_info} failed, unplugged or closed at its other end ({error})",
                        fix="check the adapter is plugged in (a simulator's end of the line: that it still runs); "
                            "then close the arm and open it again")

    def _take(self, payloads: list[bytes]) -> None:
        for payload in payloads:
            status = self._status(payload)
            if status is None:
                continue
            aid, data = status
            self._queue.append(message(aid, data, True, time.time(), channel=self.channel))
            self._good += 1
            self.replies += 1

    def _status(self, payload: bytes) -> tuple[int, bytes] | None:
        """The servo status frame for a reply payload, or ``None`` (not a status reply)."""
        if payload[0] == uart.UartPacket.GET_VALUES_SETUP and self._setup and len(payload) == _SETUP.size:
            aid, data = setup_status(payload)
            self.motor_id = aid & 0xFF
            return aid, data
        try:
            if payload[0] == uart.UartPacket.GET_VALUES:
                g = uart.decode_get_values(payload)
                fields = (g.controller_id, g.position_deg, g.speed_erpm, g.iq_current,
                          max(g.mosfet_temperature, g.motor_temperature), g.fault)
            else:
                self.other += 1
                return None
        except ProtocolError:
            self.other += 1
            return None
        motor_id, position, speed, current, temperature, fault = fields
        self.motor_id = motor_id
        return servo.encode_status(motor_id, position, speed, current, temperature, status_code(fault))

    def _flush_stale(self) -> bool:
        """When part of a frame has waited since the last window ended, give up on it and rescan
        what followed (a reply cut short must not hold back the good ones behind it). True when that
        found replies."""
        if not self._decoder.buffered:
            return False
        if not self._stale:
            return False
        self._stale = False
        before = len(self._queue)
        self._take(self._decoder.flush())
        return len(self._queue) > before

    def _end_window(self) -> None:
        """Judge the window that ends (if a poll began it), then poll: a new window begins."""
        if self._polled:
            if not self._good and not self._bytes:
                self._read(check=True)  # a silent port: hung up? (bytes just come are taken too)
            self._judge()
        self._stale = self._decoder.buffered > 0
        self._window += 1
        self._good = self._bytes = 0
        self._crc0 = self._decoder.crc_errors
        self._raw.clear()
        try:
            self._write(self._request)
        except OSError as e:
            self._polled = False
            self._failed = self._port_failed(e)
            raise self._failed from None
        self._polled = True
        self._polled_at = time.monotonic()
        self.polls += 1

    def _judge(self) -> None:
        if self._good:
            self.bad_in_row = 0
            return
        if self._decoder.crc_errors > self._crc0:
            kind, self.bad_crc = "crc", self.bad_crc + 1
        elif self._headers in self._raw:
            kind, self.partial = "partial", self.partial + 1
        elif self._bytes:
            kind, self.noise = "noise", self.noise + 1
        else:
            kind, self.silent = "silent", self.silent + 1
        self._last_bad = kind
        self.bad_in_row += 1
        if self.bad_in_row >= self.errors_in_row and self._window < self._armed_until:
            raise self._error(kind)

    def _error(self, kind: str) -> UartError:
        n, port, data = self.bad_in_row, self.channel, bytes(self._raw[:64])
        if kind == "crc":
            return UartBadCrc(f"{n} polls in a row got replies with a bad CRC on serial port {port}: bits are "
                              "flipped on the line", port=port, polls=n, data=data,
                              fix="check the cable (short, its ground wire beside the signals, away from the motor "
                                  "phases) and the ground connection between the adapter and the driver")
        if kind == "partial":
            return UartPartialFrame(f"{n} polls in a row got replies cut short on serial port {port}", port=port,
                                    polls=n, data=data,
                                    fix="a loose connector, or an adapter losing bytes: check the cable and "
                                        "connectors, and that the port runs at the driver's baud rate")
        if kind == "noise":
            return UartNoise(f"bytes arrive on serial port {port} but none forms a frame ({n} polls in a row)",
                             port=port, polls=n, data=data,
                             fix="a wrong baud rate (AK drivers: 921600, the bus's baudrate), line noise, or "
                                 "another device on the port")
        return UartSilent(f"no byte came back on serial port {port} for {n} polls in a row (the motor may still "
                          "hear commands)", port=port, polls=n,
                          fix="check the motor's power and the wiring (the adapter's RX to the motor's TX, and "
                              "GND); then close the arm and open it again")

    def diagnosis(self) -> str:
        """What the line carried since the port was opened, one sentence (for an error's fix)."""
        port = self.channel
        if self.replies:
            return (f"the motor on serial port {port} answers as CAN ID {self.motor_id}: check that the joint's "
                    f"can_id is {self.motor_id}")
        if not self._port.bytes_in:
            return (f"nothing came back on serial port {port} to {self.polls} polls: check that the motor is powered "
                    "and in servo mode, and the wiring (the R-link's serial side, or a USB-UART adapter: its RX to "
                    "the motor's TX, its TX to the motor's RX, GND to GND); for a simulator, that it runs with "
                    "--serial JOINT=pty and this is the path it printed")
        if self.bad_crc:
            return f"replies on serial port {port} fail their CRC: check the cable and its ground"
        if self.partial:
            return f"replies on serial port {port} are cut short: check the cable and connectors"
        return (f"{self._port.bytes_in} bytes came back on serial port {port} but no frame: check the baud rate "
                f"({self.baudrate} here; AK drivers use 921600)")

    # -- python-can's interface ------------------------------------------------------------------
    def fileno(self) -> int:
        fd = self._port.fileno()
        return -1 if fd is None else fd

    def shutdown(self) -> None:
        """Close the port (safe to call twice)."""
        if not self._port.closed:
            if _open.get(self.channel) is self:
                del _open[self.channel]
            with self._lock:
                self._port.close()
        super().shutdown()


def diagnose(channel: str) -> str | None:
    """What the open akarm_uart bus on ``channel`` saw on its line (:meth:`UartBus.diagnosis`), or ``None``."""
    bus = _open.get(channel)
    return None if bus is None else bus.diagnosis()


def serial_config(config: RobotConfig, ports: Mapping[str, str], baudrate: int = DEFAULT_BAUDRATE,
                  **options: Any) -> RobotConfig:
    """A copy of ``config`` with each joint of ``ports`` (joint name → serial device) on a serial port
    bus of its own: the bus the joint already has when it is an ``akarm_uart`` one (its channel
    changed), else a new bus named ``uart-JOINT``. Buses no joint uses any more are left out.
    ``options`` are more keyword arguments for those buses (``poll``, ``errors_in_row`` ...).

    Raises:
        ConfigError: no such joint. AkarmError: a joint that is not in servo mode (UART is servo mode's).
    """
    buses = dict(config.buses)
    joints = list(config.joints)
    for name, path in ports.items():
        j = config.joint(name)
        if j.mode != "servo":
            raise AkarmError(f"joint {name!r} is in MIT mode, which has no serial protocol",
                             fix="only servo-mode joints can run over UART (mode: servo)")
        old = buses.get(j.bus)
        if old is not None and old.interface == INTERFACE:
            bus_name = j.bus
            buses[bus_name] = replace(old, channel=str(path), options={**old.options, **options})
        else:
            from akarm.config import BusConfig

            bus_name = f"uart-{name}"
            buses[bus_name] = BusConfig(bus_name, INTERFACE, str(path), options={"baudrate": baudrate, **options})
        joints[joints.index(j)] = replace(j, bus=bus_name)
    used = {j.bus for j in joints}
    return replace(config, joints=tuple(joints), buses={k: b for k, b in buses.items() if k in used})
