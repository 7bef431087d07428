"""Simulated AK drivers: the motor side of the wire protocols, with the firmware's own loops.

One driver per configured joint. A driver receives the frames addressed to it, answers as the
firmware does (through the project's codecs, motor side), and every plant step returns the torque
its firmware would apply. Drivers work in motor units: motor position ``p = (joint - offset) ·
direction`` (rad at the output shaft, before the driver's own zero), joint torque = direction · motor
torque. Motor-side units (servo degrees, ERPM, amps) appear only here, through :mod:`akarm.protocol.units`.

:class:`MitDriver` (MIT mode, V1/V2 frames or V3 boards) and :class:`ServoDriver` (servo mode over
CAN) share :class:`SimulatedDriver`: faults, temperature, the output gate.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Protocol

from akarm.config import JointConfig
from akarm.errors import AkarmError, ProtocolError
from akarm.protocol import mit, servo, units
from akarm.sim import faults as _f
from akarm.sim.params import MotorSimParams

__all__ = ["MitDriver", "ServoDriver", "SimulatedDriver", "TrapezoidProfile", "make_driver"]

_INF = math.inf
#: A, servo mode: a current or brake current command below this releases the output, as VESC's firmware
#: does below its ``cc_min_current`` (0.05 A by default): zero current is how a controller lets go.
MIN_CURRENT = 0.05


class DriverHost(Protocol):
    """What a driver needs of the simulator around it."""

    def now(self) -> float:
        """The simulated time, s."""
        ...

    def transmit(self, bus: str, arbitration_id: int, data: bytes, is_extended: bool, due: float) -> None:
        """Send a frame on ``bus`` at time ``due`` (s; now or later)."""
        ...

    def set_blocked(self, name: str, blocked: bool) -> None:
        """Hold joint ``name`` where it is (mechanically blocked), or let it move again."""
        ...


#: (motor position before the driver's zero, rad; motor velocity, rad/s): the plant's true state.
StateGetter = Callable[[], tuple[float, float]]


class SimulatedDriver:
    """What every simulated driver has: identity, faults, temperature, the frames-out gate.

    Attributes:
        joint: the joint's configuration. name: its name. motor: its catalogue model.
        params: physical constants (friction, resistance, thermal).
        temperature: winding temperature, °C (the plant's thermal model updates it).
        torque: the torque the firmware applies now, N·m at the output, motor side.
        frames_received: frames addressed to this driver that it took in.
        frames_sent: frames it handed to the bus (after drops; delayed ones count when due).
    """

    mode = ""

    def __init__(self, joint: JointConfig, params: MotorSimParams, host: DriverHost, state: StateGetter,
                 dt: float) -> None:
        self.joint = joint
        self.name = joint.name
        self.motor = joint.motor
        self.params = params
        self.can_id = joint.can_id
        self.bus = joint.bus
        self.dt = dt
        self._host = host
        self._state = state
        m = joint.motor
        # Output torque per amp of Iq (kt · GR); a motor without kt uses t_max / peak current.
        if m.kt is not None:
            self.kt_out = m.kt * m.gear_ratio
        elif m.peak_current:
            self.kt_out = m.t_max / m.peak_current
        else:
            self.kt_out = m.t_max / 20.0
        self.peak_current = m.peak_current if m.peak_current else m.t_max / self.kt_out
        self.temperature = params.ambient
        self.torque = 0.0
        self.frames_received = 0
        self.frames_sent = 0
        self._faults: list[_f.Fault] = []
        self._drop = 0.0
        self._rng = random.Random(0)
        self._delay = 0.0
        self._jitter = params.reply_jitter
        self._jitter_rng = random.Random(f"{joint.name}:{params.reply_jitter!r}")
        self._unplugged = False
        self._miss = 0  # frames addressed to it still to be missed (MissedFrames)
        self._powered = True
        self._error = 0
        # the supply is off (a Brownout, a PowerCycle): (time back on, the reading's shift then (rad), the fault's type)
        self._off: tuple[float, float, type[_f.Fault]] | None = None
        self._twin: float | None = None  # a Twin's motor position: a second motor answers on this ID
        self._forged_error = 0  # the error code forged replies carry
        self._fault_after: list[tuple[float, int]] = []
        self._forged: list[tuple[float, float]] = []  # (due time, motor position) of replies another node forges
        self._frozen: tuple[float, float] | None = None  # (reported position, motor side raw), when frozen
        self._frozen_control = False
        self._next_timer = _INF

    # ------------------------------------------------------------------ faults

    @property
    def faults(self) -> tuple[_f.Fault, ...]:
        """The faults in force, in the order injected."""
        return tuple(self._faults)

    @property
    def error(self) -> int:
        """The error code the driver reports now (0 = none)."""
        return self._error

    @property
    def powered(self) -> bool:
        """False while an :class:`~akarm.sim.faults.Unplugged` fault with ``power_lost`` is in force."""
        return self._powered

    def inject(self, fault: _f.Fault) -> None:
        """Start ``fault`` now (simulated time). Faults add up; :meth:`clear_faults` ends them all."""
        t = self._host.now()
        if isinstance(fault, _f.DropReplies):
            self._drop = fault.fraction
            self._rng = random.Random(fault.seed)
        elif isinstance(fault, _f.DelayReplies):
            self._delay = fault.delay
        elif isinstance(fault, _f.MissedFrames):
            self._miss += fault.count
        elif isinstance(fault, _f.Unplugged):
            self._unplugged = True
            if fault.power_lost:
                self._powered = False
                self._power_off()
        elif isinstance(fault, _f.Twin):
            self._twin = float(fault.position)
        elif isinstance(fault, _f.ErrorCode):
            self._error = int(fault.code)
        elif isinstance(fault, _f.FrozenEncoder):
            p_raw, _ = self._state()
            self._frozen = (self._reported_position(p_raw), p_raw)
            self._frozen_control = fault.affects_control
        elif isinstance(fault, _f.Blocked):
            self._host.set_blocked(self.name, True)
        elif isinstance(fault, _f.SERIAL):
            self._serial_fault(fault)
        elif not self._start_timed(fault, t):
            raise AkarmError(f"unknown fault {fault!r}", joint=self.name,
                             fix="use one of akarm.sim.faults: DropReplies, DelayReplies, MissedFrames, Unplugged, "
                                 "ErrorCode, FrozenEncoder, FaultAfter, ForgedReply, RogueExit, Blocked, Brownout, "
                                 "PowerCycle, Twin; on a serial port CorruptBytes, PartialFrame, BadCrc, SilentPort")
        self._faults.append(fault)

    def _start_timed(self, fault: _f.Fault, t: float) -> bool:
        """Start a fault that acts at times of its own (from ``t``); False: ``fault`` is not one."""
        if isinstance(fault, _f.FaultAfter):
            self._fault_after.append((t + fault.after, int(fault.code)))
            self._reschedule(t)
        elif isinstance(fault, _f.ForgedReply):
            self._forged_error = int(fault.error) & 0xFF
            self._forged.extend((t + k * fault.interval, float(fault.position)) for k in range(int(fault.count)))
            self._forged.sort()
            self._timers(t)
            self._reschedule(t)
        elif isinstance(fault, _f.RogueExit):
            self._rogue_exit(t, fault.on_bus)
        elif isinstance(fault, _f.Brownout):
            self._supply_off(t, fault.seconds, 0.0, _f.Brownout)
        elif isinstance(fault, _f.PowerCycle):
            self._supply_off(t, fault.seconds, fault.turns * 2.0 * math.pi / self.motor.gear_ratio, _f.PowerCycle)
        else:
            return False
        return True

    def _serial_fault(self, fault: _f.Fault) -> None:
        """Start a fault of the serial line (:data:`akarm.sim.faults.SERIAL`): only a driver on a serial
        port has one."""
        raise AkarmError(f"{type(fault).__name__} is a fault of a serial port, and this driver is on CAN bus "
                         f"{self.bus!r}", joint=self.name,
                         fix=f"give the joint a serial port (akarm sim --serial {self.name}=pty, or "
                             f"SimulatedRobot(..., serial={{{self.name!r}: 'pty'}}))")

    def clear_faults(self) -> None:
        """End every fault. A motor whose power was lost starts again as after power-up."""
        was_off = not self._powered
        self._off = None
        self._faults.clear()
        self._drop = 0.0
        self._delay = 0.0
        self._unplugged = False
        self._miss = 0
        self._powered = True
        self._error = 0
        self._fault_after.clear()
        self._forged.clear()
        self._twin = None
        self._frozen = None
        self._frozen_control = False
        self._host.set_blocked(self.name, False)
        if was_off:
            self._power_on()
        self._reschedule(self._host.now())

    # ------------------------------------------------------------------ frames

    def receive(self, arbitration_id: int, is_extended: bool, data: bytes, t: float) -> None:
        """A frame addressed to this driver arrived at time ``t`` (s). An unplugged driver never sees it."""
        if self._unplugged:
            return
        if self._miss:
            self._miss -= 1
            return
        self.frames_received += 1
        self._handle(arbitration_id, is_extended, data, t)

    def _send(self, arbitration_id: int, data: bytes, is_extended: bool, t: float) -> None:
        """Hand a frame to the bus, through the faults (unplugged, drops, delay)."""
        if self._unplugged:
            return
        if self._drop and self._rng.random() < self._drop:
            return
        self.frames_sent += 1
        delay = self._delay
        if self._jitter:  # a real unit's replies do not all take the same time
            delay += self._jitter_rng.random() * self._jitter
        self._host.transmit(self.bus, arbitration_id, data, is_extended, t + delay)
        if self._twin is not None:  # the second motor on this ID answers too (its own frame, its position)
            aid, twin, ext = self._forged_frame(self._twin)
            self._host.transmit(self.bus, aid, twin, ext, t + self._delay)

    # ------------------------------------------------------------------ the plant's side

    def output(self, t: float, p_raw: float, v: float) -> tuple[float, float, float]:
        """The firmware's torque at time ``t`` for motor position ``p_raw`` (rad) and velocity ``v`` (rad/s).

        Returns ``(torque N·m, stiffness N·m/rad, damping N·m·s/rad)``: the torque and its negated
        derivatives with respect to position and velocity (the plant integrates those implicitly).
        """
        raise NotImplementedError

    # ------------------------------------------------------------------ helpers for subclasses

    def _measured(self, p_raw: float, v: float) -> tuple[float, float]:
        """What the encoder says: (raw position, velocity); frozen while a FrozenEncoder is in force."""
        fr = self._frozen
        if fr is None:
            return p_raw, v
        return fr[1], 0.0

    def _reported_position(self, p_raw: float) -> float:
        raise NotImplementedError

    def _timers(self, t: float) -> None:
        """Run whatever is due at time ``t`` (s); subclasses extend and call this."""
        if self._off is not None and t + 1e-9 >= self._off[0]:
            self._supply_on()
        if self._fault_after:
            due = [c for (ta, c) in self._fault_after if ta <= t]
            if due:
                self._error = due[-1]
                self._fault_after = [(ta, c) for (ta, c) in self._fault_after if ta > t]
        while self._forged and self._forged[0][0] <= t + 1e-9:
            _, position = self._forged.pop(0)
            aid, data, ext = self._forged_frame(position)
            self._host.transmit(self.bus, aid, data, ext, t)  # another node's frame: no drops, no delay

    def _timer_deadlines(self) -> list[float]:
        off = [self._off[0]] if self._off is not None else []
        return [ta for ta, _ in self._fault_after] + [ta for ta, _ in self._forged[:1]] + off

    def _supply_off(self, t: float, seconds: float, shift: float, kind: type[_f.Fault]) -> None:
        """The supply dips (:class:`~akarm.sim.faults.Brownout`, :class:`~akarm.sim.faults.PowerCycle`): off
        (limp, deaf and mute) from ``t`` for ``seconds``, then as after power-up (out of motor mode), its
        reading ``shift`` rad off (a power cycle loses the multi-turn count; a brown-out, 0)."""
        self._unplugged = True
        self._powered = False
        self._power_off()
        self._off = (t + seconds, shift, kind)
        self._reschedule(t)

    def _supply_on(self) -> None:
        """The supply is back: the driver starts as after power-up and answers again."""
        assert self._off is not None
        _, shift, kind = self._off
        self._off = None
        self._unplugged = False
        self._powered = True
        self._faults = [f for f in self._faults if not isinstance(f, kind)]
        self._power_on()
        if shift:
            self._lose_turns(shift)

    def _forged_frame(self, position: float) -> tuple[int, bytes, bool]:
        """A reply (or status frame) in this driver's name at motor ``position`` (rad): (ID, data, extended)."""
        aid, data = servo.encode_status(self.can_id, units.rad_to_servo_deg(self.motor, position), 0.0, 0.0,
                                        self.temperature, self._forged_error)
        return aid, data, True

    def _rogue_exit(self, t: float, on_bus: bool) -> None:
        """Another program makes the output limp now (see :class:`~akarm.sim.faults.RogueExit`)."""
        raise NotImplementedError

    def _reschedule(self, t: float) -> None:
        self._next_timer = min(self._timer_deadlines(), default=_INF)

    @property
    def next_timer(self) -> float:
        """Simulated time, s, of the driver's next timer (a status frame, a timeout, a fault's step;
        ``inf``: none): :meth:`tick` before it has nothing to do."""
        return self._next_timer

    def tick(self, t: float) -> None:
        """Run the driver's timers due at time ``t`` (s): status frames, timeouts, delayed faults."""
        if t + 1e-9 >= self._next_timer:
            self._timers(t)
            self._reschedule(t)

    def output_off(self) -> None:
        """Take the output off now, as EXIT (MIT) or a zero current (servo) would: it goes limp; the
        driver stays powered and on the bus."""
        self._power_off()

    def _power_off(self) -> None:
        """Power lost: the output goes limp."""

    def _power_on(self) -> None:
        """Power back: the driver's state as after power-up."""

    def _lose_turns(self, shift: float) -> None:
        """From now on report the position ``shift`` rad (motor side) higher: the multi-turn count is lost."""
        raise NotImplementedError

    def _handle(self, arbitration_id: int, is_extended: bool, data: bytes, t: float) -> None:
        raise NotImplementedError

    def routes(self) -> list[tuple[int, bool]]:
        """The ``(arbitration_id, is_extended)`` pairs this driver listens to."""
        raise NotImplementedError


def _wrap(p: float, p_max: float) -> float:
    """``p`` wrapped into [-p_max, p_max), as the firmware's reply does."""
    span = 2.0 * p_max
    return (p + p_max) % span - p_max


class MitDriver(SimulatedDriver):
    """An AK driver in MIT mode.

    V1/V2 firmware (``joint.firmware == "v2"``): standard frames to the motor's ID; commands are
    ignored until ENTER; every frame is answered (special frames and ignored commands too) on
    ``joint.reply_id``; EXIT makes the output limp; ZERO makes the current position zero and takes
    the driver off-line (no replies, frames ignored) for :attr:`zero_silence` seconds. V3 boards
    (``"v3"``): commands on extended ID ``(8 << 8) | id`` in the V3 layout, applied from the first
    one (there is no enter/exit); each is answered with a ``0x2900 | id`` status frame. A V2 special
    frame sent to a V3 board is not a command it knows: it is answered but not applied.

    The last command applied persists across EXIT/ENTER (:attr:`stored_command`): entering motor
    mode applies it again at once, the "kick on enable" of the real firmware. A ZERO while enabled
    leaves the output on: the stored command's position then counts from the new zero.

    Attributes:
        enabled: motor mode is on (the command is applied).
        zero_silence: s off-line after ZERO (default 1.0; 0.5-1.5 on real units).
        reply_length: 8 (default) or 6 bytes, as some firmware sends.
    """

    mode = "mit"

    def __init__(self, joint: JointConfig, params: MotorSimParams, host: DriverHost, state: StateGetter,
                 dt: float, *, zero_silence: float = 1.0) -> None:
        super().__init__(joint, params, host, state, dt)
        m = joint.motor
        self._codec = mit.codec(m)
        self.v3 = joint.firmware == "v3"
        self.zero_silence = zero_silence
        self.reply_length = 8
        self.enabled = False
        self._cmd = mit.MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)
        self._zero = 0.0          # raw motor position that reads 0
        self._silent_until = -_INF
        self._last_rx = host.now()
        self.can_timeout = float(joint.can_timeout)
        self._t_max = m.t_max
        self._p_max = m.p_max
        self._reply_id = joint.reply_id
        self._cmd_id, self._cmd_ext = mit.command_arbitration_id(joint.can_id, joint.firmware)
        self._reschedule(host.now())

    def routes(self) -> list[tuple[int, bool]]:
        return [(self._cmd_id, self._cmd_ext)]

    @property
    def stored_command(self) -> mit.MitCommand:
        """The last command applied (SI, motor side); applied again on ENTER. Settable, for tests."""
        return self._cmd

    @stored_command.setter
    def stored_command(self, cmd: mit.MitCommand | tuple[float, float, float, float, float]) -> None:
        self._cmd = mit.MitCommand(*(float(x) for x in cmd))

    @property
    def silent(self) -> bool:
        """True while the driver is off-line after a ZERO."""
        return self._host.now() < self._silent_until

    @property
    def zero(self) -> float:
        """The raw motor position (rad, before the driver's zero) that the driver reports as 0."""
        return self._zero

    # -- frames

    def _handle(self, arbitration_id: int, is_extended: bool, data: bytes, t: float) -> None:
        if t < self._silent_until or not self._powered:
            return
        self._last_rx = t
        try:
            self._handle_frame(data, t)
        finally:
            if self.can_timeout > 0:
                self._reschedule(t)

    def _handle_frame(self, data: bytes, t: float) -> None:
        special = mit.special_frame(data)
        if self.v3:
            if special is None:
                try:
                    self._cmd = self._codec.decode_command(data, firmware="v3")
                except ProtocolError:
                    return
                self.enabled = True
            self._reply(t)
            return
        if special == "enter":
            self.enabled = True
        elif special == "exit":
            self.enabled = False
        elif special == "zero":
            p_raw, _ = self._state()
            self._zero = p_raw
            self._silent_until = t + self.zero_silence
            return
        else:
            try:
                cmd = self._codec.decode_command(data, firmware="v2")
            except ProtocolError:
                return  # not an 8-byte command: the firmware drops it
            if self.enabled:
                self._cmd = cmd
        self._reply(t)

    def _reply(self, t: float) -> None:
        p_raw, v = self._state()
        tau = self._law(p_raw, v)
        mp, mv = self._measured(p_raw, v)
        pos = self._reported_position(mp) if self._frozen is None else self._frozen[0]
        if self.v3:
            m = self.motor
            aid, data = servo.encode_status(
                self.can_id, units.rad_to_servo_deg(m, pos), units.rad_s_to_erpm(m, mv), tau / self.kt_out,
                self.temperature, self._error)
            self._send(aid, data, True, t)
        else:
            data = self._codec.encode_reply(self.can_id, pos, mv, tau, self.temperature, self._error,
                                            length=self.reply_length)
            self._send(self._reply_id, data, False, t)

    def _reported_position(self, p_raw: float) -> float:
        return _wrap(p_raw - self._zero, self._p_max)

    def _forged_frame(self, position: float) -> tuple[int, bytes, bool]:
        if self.v3:
            return super()._forged_frame(position)
        return 0, self._codec.encode_reply(self.can_id, position, 0.0, 0.0, self.temperature, self._forged_error), False

    def _rogue_exit(self, t: float, on_bus: bool) -> None:
        if self.v3:  # no EXIT frame: another controller's zero-gain command
            frame = self._codec.encode_command(0.0, 0.0, 0.0, 0.0, 0.0, firmware="v3")
        else:
            frame = mit.EXIT
        if on_bus:
            self._host.transmit(self.bus, self._cmd_id, frame, self._cmd_ext, t)
            self.receive(self._cmd_id, self._cmd_ext, frame, t)  # it reaches this driver too (and is answered)
        elif self.v3:
            self._cmd = mit.MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)
        else:
            self.enabled = False

    # -- control

    def _law(self, p_raw: float, v: float) -> float:
        """The torque the firmware applies at this state, N·m (0 when not enabled), clamped to ±t_max."""
        if not self.enabled or not self._powered:
            return 0.0
        if self._frozen_control:
            p_raw, v = self._measured(p_raw, v)
        c = self._cmd
        tau = c.kp * (c.position - (p_raw - self._zero)) + c.kd * (c.velocity - v) + c.torque
        tm = self._t_max
        return tm if tau > tm else -tm if tau < -tm else tau

    def output(self, t: float, p_raw: float, v: float) -> tuple[float, float, float]:
        if t + 1e-9 >= self._next_timer:
            self.tick(t)
        if not self.enabled or not self._powered:
            return 0.0, 0.0, 0.0
        if self._frozen_control:
            p_raw, v = self._measured(p_raw, v)
            c = self._cmd
            tau = c.kp * (c.position - (p_raw - self._zero)) + c.kd * (c.velocity - v) + c.torque
            k = d = 0.0  # the loop does not see the motion
        else:
            c = self._cmd
            tau = c.kp * (c.position - (p_raw - self._zero)) + c.kd * (c.velocity - v) + c.torque
            k, d = c.kp, c.kd
        tm = self._t_max
        if tau > tm:
            return tm, 0.0, 0.0
        if tau < -tm:
            return -tm, 0.0, 0.0
        return tau, k, d

    # -- timers

    def _timer_deadlines(self) -> list[float]:
        out = super()._timer_deadlines()
        if self.can_timeout > 0 and self.enabled:
            out.append(self._last_rx + self.can_timeout)
        return out

    def _timers(self, t: float) -> None:
        super()._timers(t)
        if self.can_timeout > 0 and self.enabled and t - self._last_rx >= self.can_timeout:
            self.enabled = False  # the firmware's CAN timeout: back to rest mode, output limp

    def _power_off(self) -> None:
        self.enabled = False

    def _power_on(self) -> None:
        self.enabled = False
        self._cmd = mit.MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)
        self._silent_until = -_INF
        self._last_rx = self._host.now()

    def _lose_turns(self, shift: float) -> None:
        self._zero -= shift


class TrapezoidProfile:
    """A position reference moving to a target with bounded speed and acceleration, one step at a time.

    Each :meth:`step` moves the reference by one sample of a time-optimal trapezoidal (or triangular)
    velocity profile from its current position and velocity, braking in time to stop on the target:
    the speed allowed at distance ``d`` is the largest the discrete deceleration can still stop from.

    Attributes:
        position: rad. velocity: rad/s. acceleration: rad/s² of the last step.
        target: rad. max_velocity: rad/s (> 0). max_acceleration: rad/s² (> 0).
    """

    __slots__ = ("acceleration", "max_acceleration", "max_velocity", "position", "target", "velocity")

    def __init__(self, position: float, velocity: float = 0.0) -> None:
        self.position = position
        self.velocity = velocity
        self.acceleration = 0.0
        self.target = position
        self.max_velocity = 1.0
        self.max_acceleration = 1.0

    @property
    def done(self) -> bool:
        """True when the reference rests on the target."""
        return self.position == self.target and self.velocity == 0.0

    def step(self, dt: float) -> None:
        """Advance the reference by ``dt`` seconds."""
        d = self.target - self.position
        v = self.velocity
        if d == 0.0 and v == 0.0:
            self.acceleration = 0.0
            return
        s = 1.0 if d > 0 or (d == 0.0 and v < 0) else -1.0
        vs = v * s                      # speed towards the target
        a = self.max_acceleration
        adt = a * dt
        # n steps of braking from n·a·dt cover a·dt²·n(n+1)/2: the largest n that still fits in |d|
        n = math.sqrt(0.25 + 2.0 * abs(d) / (adt * dt)) - 0.5
        goal = min(self.max_velocity, n * adt)
        new = goal if vs - adt <= goal <= vs + adt else (vs - adt if goal < vs else vs + adt)
        self.acceleration = (new - vs) * s / dt
        self.velocity = new * s
        self.position += self.velocity * dt
        rest = self.target - self.position
        if (rest == 0.0 or (rest > 0) != (s > 0) or abs(rest) < 1e-12) and abs(new) <= adt * 1.0000001:
            self.position = self.target  # the last braking step lands on the target
            self.velocity = 0.0


class ServoDriver(SimulatedDriver):
    """An AK driver in servo mode over CAN (VESC-derived firmware).

    Commands (extended ID ``(packet << 8) | id``): duty (a DC motor: supply voltage, winding
    resistance, back-EMF from kt), current (τ = I·kt·GR, limited to the peak current), brake current
    (resists motion up to that current), speed (a PI loop on the speed error, ERPM), position (a trapezoidal move at
    :attr:`position_speed_erpm` and :attr:`position_accel_erpm_s`), position-speed (a trapezoidal
    move at the commanded speed and acceleration) and origin (0 temporary, 1 permanent, 2 restore
    default). Position moves are tracked by a stiff PID position loop with acceleration feed-forward.
    A current or brake command below :data:`MIN_CURRENT` releases the output (zero current is how
    the protocol lets go). Servo commands get no reply: the driver sends ``0x2900 | id`` status frames at
    ``joint.status_rate_hz`` instead, whatever its state, and releases the output (limp)
    :attr:`release_after` seconds after the last command.

    The loops' gains are set for :attr:`load_inertia` (kg·m² at the output: the arm's inertia about
    this joint, which the firmware's tuning assumes): speed loop bandwidth :attr:`speed_bandwidth`
    rad/s, position loop :attr:`position_bandwidth` rad/s, critically damped.

    Attributes:
        control: ``None`` (released), ``"duty"``, ``"current"``, ``"brake"``, ``"speed"`` or ``"position"``.
        release_after: s (default 1.0).
        position_speed_erpm, position_accel_erpm_s: speed (12 000 ERPM) and acceleration
            (40 000 ERPM/s) of SET_POS moves.
        origin: raw motor position (rad) of the current origin; permanent_origin: the one kept in flash.
        profile: the position reference (raw motor rad) while ``control == "position"``.
    """

    mode = "servo"

    def __init__(self, joint: JointConfig, params: MotorSimParams, host: DriverHost, state: StateGetter,
                 dt: float, *, load_inertia: float | None = None, release_after: float = 1.0) -> None:
        super().__init__(joint, params, host, state, dt)
        m = joint.motor
        self.release_after = release_after
        self.position_speed_erpm = 12_000.0
        self.position_accel_erpm_s = 40_000.0
        self.speed_bandwidth = 150.0
        self.position_bandwidth = 150.0
        self.load_inertia = load_inertia if load_inertia and load_inertia > 0 else max(m.reflected_inertia, 1e-4)
        self.control: str | None = None
        self.origin = 0.0
        self.permanent_origin = 0.0
        self.profile = TrapezoidProfile(0.0)
        self._duty = 0.0
        self._amps = 0.0
        self._speed = 0.0       # rad/s target of the speed loop
        self._integral = 0.0    # N·m, the active loop's integral term
        self._last_cmd = -_INF
        self._tau_cap = min(self.peak_current * self.kt_out, m.t_max)
        # DC model of the duty mode (rotor side): I = (duty·V - kt·ω_rotor) / R
        self._kt = self.kt_out / m.gear_ratio
        self._gr = m.gear_ratio
        rate = float(joint.status_rate_hz)
        self.status_period = 1.0 / rate if rate > 0 else _INF
        t0 = host.now()
        self._status_epoch, self._status_n = t0, 1   # status frame n is due at epoch + n·period
        self._next_status = t0 + self.status_period
        self.tune()
        self._reschedule(t0)

    def tune(self, load_inertia: float | None = None) -> None:
        """Set the loop gains for ``load_inertia`` (kg·m², default :attr:`load_inertia`) and the bandwidths."""
        if load_inertia is not None:
            self.load_inertia = load_inertia
        j = self.load_inertia
        ws, wp = self.speed_bandwidth, self.position_bandwidth
        self.speed_kp = j * ws              # N·m per rad/s
        self.speed_ki = self.speed_kp * ws / 4.0
        self.pos_kp = j * wp * wp           # N·m/rad
        self.pos_kd = 2.0 * j * wp          # N·m·s/rad
        self.pos_ki = self.pos_kp * wp / 8.0

    def routes(self) -> list[tuple[int, bool]]:
        return [((int(p) << 8) | self.can_id, True) for p in servo.ENCODERS]

    @property
    def enabled(self) -> bool:
        """True while a control mode drives the output (not released)."""
        return self.control is not None and self._powered

    def _reported_position(self, p_raw: float) -> float:
        return p_raw - self.origin

    # -- frames

    def _handle(self, arbitration_id: int, is_extended: bool, data: bytes, t: float) -> None:
        if not self._powered:
            return
        try:
            cmd = servo.decode_command(arbitration_id, data, is_extended=is_extended)
        except ProtocolError:
            return  # malformed or out-of-range: the firmware ignores it
        self.apply(cmd.packet, cmd.values, t)

    # C901 15 > 12, left as it was: a branch per servo command the simulated driver carries out
    def apply(self, packet: servo.ServoPacket, values: tuple[float, ...], t: float) -> None:  # noqa: C901
        """Carry out a servo command at time ``t`` (s), whichever port it came by: ``values`` in the
        servo codec's units (:class:`~akarm.protocol.servo.ServoCommand`)."""
        m = self.motor
        pk = packet
        p_raw, v = self._measured(*self._state())
        previous = self.control
        if pk is servo.ServoPacket.SET_ORIGIN_HERE:
            mode = int(values[0])
            if mode == 2:
                self.origin = self.permanent_origin = 0.0
            else:
                self.origin = p_raw
                if mode == 1:
                    self.permanent_origin = p_raw
            if previous is not None:
                self._last_cmd = t
            self._reschedule(t)
            return
        self._last_cmd = t
        if pk is servo.ServoPacket.SET_DUTY:
            self.control, self._duty = "duty", values[0]
        elif pk is servo.ServoPacket.SET_CURRENT:
            # below the firmware's minimum current (VESC: cc_min_current) the output is released
            self.control, self._amps = "current" if abs(values[0]) >= MIN_CURRENT else None, values[0]
        elif pk is servo.ServoPacket.SET_CURRENT_BRAKE:
            self.control, self._amps = "brake" if abs(values[0]) >= MIN_CURRENT else None, abs(values[0])
        elif pk is servo.ServoPacket.SET_RPM:
            if previous != "speed":
                self._integral = 0.0
            self.control, self._speed = "speed", units.erpm_to_rad_s(m, values[0])
        else:  # SET_POS, SET_POS_SPD
            if pk is servo.ServoPacket.SET_POS:
                deg, erpm, accel = values[0], self.position_speed_erpm, self.position_accel_erpm_s
            else:
                deg, erpm, accel = values
                if accel <= 0:
                    accel = self.position_accel_erpm_s  # 0 leaves the acceleration to the firmware default
            prof = self.profile
            if previous != "position":
                prof.position, prof.velocity, prof.acceleration = p_raw, v, 0.0
                self._integral = 0.0
            prof.target = self.origin + units.servo_deg_to_rad(m, deg)
            prof.max_velocity = abs(units.erpm_to_rad_s(m, erpm))
            prof.max_acceleration = units.erpm_to_rad_s(m, accel)
            if prof.max_velocity == 0.0:
                prof.target = prof.position  # speed 0: the reference stays where it is
                prof.max_velocity = 1e-9
            self.control = "position"
        self._reschedule(t)

    def _rogue_exit(self, t: float, on_bus: bool) -> None:
        aid, data = servo.encode_current(self.can_id, 0.0)  # another program's "limp": zero current
        if on_bus:
            self._host.transmit(self.bus, aid, data, True, t)
            self.receive(aid, True, data, t)
        else:
            self.control = None

    def _status(self, t: float) -> None:
        p_raw, v = self._state()
        mp, mv = self._measured(p_raw, v)
        pos = self._reported_position(mp)
        m = self.motor
        aid, data = servo.encode_status(self.can_id, units.rad_to_servo_deg(m, pos), units.rad_s_to_erpm(m, mv),
                                        self.torque / self.kt_out, self.temperature, self._error)
        self._send(aid, data, True, t)

    # -- control

    # C901 13 > 12, left as it was: the simulated driver's output, a branch per control mode and fault
    def output(self, t: float, p_raw: float, v: float) -> tuple[float, float, float]:  # noqa: C901
        if t + 1e-9 >= self._next_timer:
            self.tick(t)
        ctl = self.control
        if ctl is None or not self._powered:
            return 0.0, 0.0, 0.0
        if self._frozen is not None:
            mp, mv = self._measured(p_raw, v)
            if self._frozen_control:
                p_raw, v = mp, mv
        cap = self._tau_cap
        dt = self.dt
        if ctl == "position":
            prof = self.profile
            prof.step(dt)
            e = prof.position - p_raw
            integral = self._integral + self.pos_ki * e * dt
            tau = (self.pos_kp * e + self.pos_kd * (prof.velocity - v) + integral
                   + self.load_inertia * prof.acceleration)
            k, d = self.pos_kp, self.pos_kd
            if -cap < tau < cap:
                self._integral = integral  # integrate only when not saturated (anti-windup)
        elif ctl == "current":
            tau, k, d = self._amps * self.kt_out, 0.0, 0.0
            cap = min(cap, self.peak_current * self.kt_out)
        elif ctl == "speed":
            e = self._speed - v
            integral = self._integral + self.speed_ki * e * dt
            tau = self.speed_kp * e + integral
            k, d = 0.0, self.speed_kp
            if -cap < tau < cap:
                self._integral = integral
        elif ctl == "brake":
            # Resists motion up to the brake current's torque: limit·tanh(v/ε), ε = 1 mm/s-like 1e-3 rad/s.
            # Its damping is the secant τ/v, so the implicit step slows the joint to rest but never
            # past it (the tangent would let a saturated brake flip the speed's sign every step).
            limit = min(self._amps, self.peak_current) * self.kt_out
            x = v * 1000.0
            th = math.tanh(x)
            return -limit * th, 0.0, (limit * 1000.0 if -1e-9 < x < 1e-9 else limit * th / v)
        else:  # duty: a DC motor on duty·V_bus, with back-EMF kt·ω at the rotor
            r = self.params.resistance
            w_rotor = v * self._gr
            amps = (self._duty * self.params.bus_voltage - self._kt * w_rotor) / r
            tau = amps * self.kt_out
            k, d = 0.0, self.kt_out * self._kt * self._gr / r
        if tau >= cap:
            return cap, 0.0, 0.0
        if tau <= -cap:
            return -cap, 0.0, 0.0
        return tau, k, d

    # -- timers

    def _timer_deadlines(self) -> list[float]:
        out = super()._timer_deadlines()
        out.append(self._next_status)
        if self.control is not None:
            out.append(self._last_cmd + self.release_after)
        return out

    def _timers(self, t: float) -> None:
        super()._timers(t)
        if self.control is not None and t - self._last_cmd >= self.release_after:
            self.control = None  # the firmware's timeout: output released
        if t + 1e-9 >= self._next_status:
            self._status(t)
            self._status_n += 1
            self._next_status = self._status_epoch + self._status_n * self.status_period
            if self._next_status <= t:  # fell behind (a long step): skip, do not burst
                self._status_epoch, self._status_n = t, 1
                self._next_status = t + self.status_period

    def _power_off(self) -> None:
        self.control = None

    def _power_on(self) -> None:
        self.control = None
        self.origin = self.permanent_origin  # a temporary origin does not survive power loss
        self._status_epoch, self._status_n = self._host.now(), 1
        self._next_status = self._status_epoch + self.status_period

    def _lose_turns(self, shift: float) -> None:
        self.origin -= shift


def make_driver(joint: JointConfig, params: MotorSimParams, host: DriverHost, state: StateGetter, dt: float, *,
                load_inertia: float | None = None, zero_silence: float = 1.0,
                servo_release: float = 1.0) -> SimulatedDriver:
    """The driver for ``joint``.s mode: :class:`MitDriver` (``"mit"``) or :class:`ServoDriver` (``"servo"``)."""
    if joint.mode == "servo":
        return ServoDriver(joint, params, host, state, dt, load_inertia=load_inertia, release_after=servo_release)
    return MitDriver(joint, params, host, state, dt, zero_silence=zero_silence)
