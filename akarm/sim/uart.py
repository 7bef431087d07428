"""A simulated servo-mode driver on a serial port: the motor side of the UART protocol (AK manual §5.2.2).

:class:`UartServoDriver` is a :class:`~akarm.sim.drivers.ServoDriver` (the same position, speed,
current, brake and duty loops, origin, release timeout) that takes its commands as UART frames and
answers on the line instead of sending CAN status frames:

- SET_DUTY, SET_CURRENT, SET_CURRENT_BRAKE, SET_RPM, SET_POS, SET_POS_SPD and SET_POS_ORIGIN do what
  their CAN counterparts do; SET_HANDBRAKE brakes like SET_CURRENT_BRAKE.
- GET_VALUES and GET_VALUES_SETUP are answered at once (the reply leaves when its last byte would
  have, at the port's baud rate): position, speed, Iq, temperature (the same value as MOSFET and
  motor temperature), the fault code (:func:`akarm.protocol.uart.packets.fault_code` of the error
  the driver reports), the motor's ID (its ``can_id``), the supply voltage.
- SET_DETECT starts a ROTOR_POSITION report every 10 ms (the position GET_VALUES reports, in the
  report's thousandths of a degree: the manual's example, 1750.628°, is no angle within one turn).
- SET_POS_MULTI, SET_POS_SINGLE and SET_POS_UNLIMITED set :attr:`UartServoDriver.position_mode`; in
  single-turn mode reported positions are wrapped into 0-360°.
- FW_VERSION is answered with version 1.0 and the name ``akarm-sim``.

Nothing is sent unasked but ROTOR_POSITION. Faults: those of every driver, except the two that need
a second node on the line (:class:`~akarm.sim.faults.ForgedReply`, a
:class:`~akarm.sim.faults.RogueExit` seen on the bus), plus the line's own
(:data:`akarm.sim.faults.SERIAL`): replies as noise, cut short, with a bad CRC, or none at all.
"""

from __future__ import annotations

import math
import random
from typing import Protocol

from akarm.buses.serialport import DEFAULT_BAUDRATE
from akarm.config import JointConfig
from akarm.errors import AkarmError, ProtocolError
from akarm.protocol import servo, uart, units
from akarm.protocol.uart.packets import fault_code
from akarm.sim import faults as _f
from akarm.sim.drivers import DriverHost, ServoDriver, StateGetter
from akarm.sim.params import MotorSimParams

__all__ = ["DETECT_PERIOD", "SerialHost", "UartServoDriver"]

DETECT_PERIOD = 0.01  #: s between ROTOR_POSITION reports after SET_DETECT (the manual's 10 ms)
_INF = math.inf
_I32_DEG = 2147.483647  # the widest position a UART reply carries (int32 / 1e6)
_SERVO = {
    uart.UartPacket.SET_DUTY: servo.ServoPacket.SET_DUTY,
    uart.UartPacket.SET_CURRENT: servo.ServoPacket.SET_CURRENT,
    uart.UartPacket.SET_CURRENT_BRAKE: servo.ServoPacket.SET_CURRENT_BRAKE,
    uart.UartPacket.SET_HANDBRAKE: servo.ServoPacket.SET_CURRENT_BRAKE,
    uart.UartPacket.SET_RPM: servo.ServoPacket.SET_RPM,
    uart.UartPacket.SET_POS: servo.ServoPacket.SET_POS,
    uart.UartPacket.SET_POS_SPD: servo.ServoPacket.SET_POS_SPD,
    uart.UartPacket.SET_POS_ORIGIN: servo.ServoPacket.SET_ORIGIN_HERE,
}
_MODES = {uart.UartPacket.SET_POS_MULTI: "multi", uart.UartPacket.SET_POS_SINGLE: "single",
          uart.UartPacket.SET_POS_UNLIMITED: "unlimited"}


class SerialHost(DriverHost, Protocol):
    """What a driver on a serial port needs of the simulator around it."""

    def transmit_serial(self, joint: str, data: bytes, due: float) -> None:
        """Write ``data`` on joint ``joint``'s serial port at time ``due`` (s; now or later)."""
        ...


class UartServoDriver(ServoDriver):
    """A servo-mode driver on a serial port (see the module's docstring).

    Attributes:
        baudrate: bit/s of its port (the time a reply takes to leave).
        position_mode: ``"multi"`` (±100 turns; the default here), ``"single"`` or ``"unlimited"``.
        detect: True after SET_DETECT (ROTOR_POSITION every :data:`DETECT_PERIOD`).
        frame_errors: frames received that were corrupt (the decoder skipped them).
    """

    detect = False
    _next_detect = _INF

    def __init__(self, joint: JointConfig, params: MotorSimParams, host: SerialHost, state: StateGetter,
                 dt: float, *, load_inertia: float | None = None, release_after: float = 1.0,
                 baudrate: int = DEFAULT_BAUDRATE) -> None:
        self._serial_host = host
        super().__init__(joint, params, host, state, dt, load_inertia=load_inertia, release_after=release_after)
        self.baudrate = baudrate
        self.position_mode = "multi"
        self.detect = False
        self._next_detect = _INF
        self._decoder = uart.FrameDecoder()
        self._wire: dict[type[_f.Fault], _f.Fault] = {}
        self._wire_rng = random.Random(0)
        # no status frames of its own: over UART the motor answers polls
        self.status_period = _INF
        self._next_status = _INF
        self._reschedule(host.now())

    @property
    def frame_errors(self) -> int:
        return self._decoder.error_count

    def routes(self) -> list[tuple[int, bool]]:
        return []  # on no CAN bus

    # -- faults ----------------------------------------------------------------------------------
    def inject(self, fault: _f.Fault) -> None:
        if isinstance(fault, _f.ForgedReply) or (isinstance(fault, _f.RogueExit) and fault.on_bus):
            raise AkarmError(f"{type(fault).__name__} needs another node on the bus; a serial port links one "
                             "controller to one motor", joint=self.name,
                             fix="use RogueExit(on_bus=False) for a driver that leaves motor mode unseen")
        super().inject(fault)

    def _serial_fault(self, fault: _f.Fault) -> None:
        self._wire[type(fault)] = fault
        seed = getattr(fault, "seed", None)
        if seed is not None:
            self._wire_rng = random.Random(seed)

    def clear_faults(self) -> None:
        self._wire.clear()
        super().clear_faults()

    # -- bytes in --------------------------------------------------------------------------------
    def receive_bytes(self, data: bytes, t: float) -> list[bytes]:
        """Bytes from the line at time ``t`` (s); the payloads of the frames they completed (whatever
        their command), which the driver then carried out. An unplugged driver takes nothing."""
        if self._unplugged:
            return []
        payloads = self._decoder.feed(data)
        for payload in payloads:
            self.frames_received += 1
            if self._powered:
                self._command(payload, t)
        return payloads

    def _command(self, payload: bytes, t: float) -> None:
        try:
            cmd = uart.decode_command(payload)
        except ProtocolError:
            return  # malformed or out of range: the firmware ignores it
        pk = cmd.packet
        if pk in _SERVO:
            self.apply(_SERVO[pk], cmd.values, t)
        elif pk is uart.UartPacket.GET_VALUES:
            self._reply(uart.encode_get_values_reply(self._values()), t)
        elif pk is uart.UartPacket.GET_VALUES_SETUP:
            v = self._values()
            every = {uart.ValueField.MOSFET_TEMPERATURE: v.mosfet_temperature,
                     uart.ValueField.MOTOR_TEMPERATURE: v.motor_temperature,
                     uart.ValueField.OUTPUT_CURRENT: v.output_current, uart.ValueField.INPUT_CURRENT: v.input_current,
                     uart.ValueField.ID_CURRENT: v.id_current, uart.ValueField.IQ_CURRENT: v.iq_current,
                     uart.ValueField.DUTY: v.duty, uart.ValueField.SPEED: v.speed_erpm,
                     uart.ValueField.INPUT_VOLTAGE: v.input_voltage, uart.ValueField.ERROR: v.fault,
                     uart.ValueField.POSITION: v.position_deg, uart.ValueField.MOTOR_ID: v.controller_id}
            mask = int(cmd.values[0])
            self._reply(uart.encode_get_values_setup_reply({f: x for f, x in every.items() if mask & int(f)}), t)
        elif pk is uart.UartPacket.SET_DETECT:
            self.detect = True
            self._next_detect = t + DETECT_PERIOD
            self._reschedule(t)
        elif pk in _MODES:
            self.position_mode = _MODES[pk]
        elif pk is uart.UartPacket.FW_VERSION:
            self._reply(uart.encode_frame(bytes((uart.UartPacket.FW_VERSION, 1, 0)) + b"akarm-sim"), t)

    def _position_deg(self, p_raw: float) -> float:
        """The position the driver reports for raw motor position ``p_raw`` (rad), in its degrees."""
        deg = units.rad_to_servo_deg(self.motor, self._reported_position(p_raw))
        if self.position_mode == "single":
            deg %= 360.0
        return min(max(deg, -_I32_DEG), _I32_DEG)  # what an int32 of millionths of a degree holds

    def _values(self) -> uart.GetValues:
        """What GET_VALUES reports now."""
        p_raw, v = self._state()
        mp, mv = self._measured(p_raw, v)
        m = self.motor
        deg = self._position_deg(mp)
        amps = self.torque / self.kt_out
        temperature = round(self.temperature, 1)
        return uart.GetValues(temperature, temperature, amps, 0.0, 0.0, amps, 0.0, units.rad_s_to_erpm(m, mv),
                              self.params.bus_voltage, fault_code(self._error), deg, self.can_id, 0.0, 0.0)

    # -- bytes out -------------------------------------------------------------------------------
    def _reply(self, frame: bytes, t: float) -> None:
        """Send a frame, through the faults; it leaves when its last byte would have (10 bits a byte)."""
        if self._unplugged or _f.SilentPort in self._wire:
            return
        if self._drop and self._rng.random() < self._drop:
            return
        frame = self._spoil(frame)
        self.frames_sent += 1
        self._serial_host.transmit_serial(self.name, frame, t + self._delay + 10.0 * len(frame) / self.baudrate)

    def _spoil(self, frame: bytes) -> bytes:
        """The frame as the line's faults leave it."""
        rng = self._wire_rng
        if self._hits(_f.CorruptBytes):
            return bytes(rng.getrandbits(8) for _ in frame)
        if self._hits(_f.PartialFrame):
            return frame[:len(frame) // 2]
        if self._hits(_f.BadCrc):
            return frame[:-2] + bytes((frame[-2] ^ 0xFF, frame[-1]))
        return frame

    def _hits(self, kind: type[_f.CorruptBytes | _f.PartialFrame | _f.BadCrc]) -> bool:
        fault = self._wire.get(kind)
        return isinstance(fault, kind) and self._wire_rng.random() < fault.fraction

    def _status(self, t: float) -> None:
        """No CAN status frames over UART."""

    def _forged_frame(self, position: float) -> tuple[int, bytes, bool]:
        raise AkarmError("a serial port has no other node to forge replies", joint=self.name)

    # -- timers ----------------------------------------------------------------------------------
    def _timer_deadlines(self) -> list[float]:
        out = super()._timer_deadlines()
        if self.detect:
            out.append(self._next_detect)
        return out

    def _timers(self, t: float) -> None:
        super()._timers(t)
        if self.detect and t + 1e-9 >= self._next_detect:
            p_raw, _ = self._state()
            self._reply(uart.encode_rotor_position(self._position_deg(self._measured(p_raw, 0.0)[0])), t)
            self._next_detect += DETECT_PERIOD
            if self._next_detect <= t:
                self._next_detect = t + DETECT_PERIOD

    def _power_on(self) -> None:
        super()._power_on()
        self.status_period = _INF
        self._next_status = _INF
        self.detect = False
        self._next_detect = _INF
        self._decoder.reset()
