"""Controller side of each joint: frames out, feedback in, and the joint ⇄ motor conversion.

``joint = direction * motor + offset`` for positions (rad); velocities and torques scale by
``direction``. Everything a :class:`Joint` returns or accepts is joint-side SI; motor units (the
codecs' integers, degrees, ERPM, amps) stay in here and in :mod:`akarm.units`.

Replies are routed per bus by :class:`Router`: MIT (V1/V2 firmware) replies are standard frames
whose byte 0 is the driver ID (the arbitration ID differs between units and is not used); servo
status and V3 replies are extended ``0x29xx`` frames matched on the whole ID.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import can

from . import units
from .config import JointConfig
from .errors import ProtocolError
from .frames import message
from .protocol import mit, servo

__all__ = ["Joint", "JointState", "MitJoint", "Router", "ServoJoint", "make_joint"]

_SPEED_FIELD_MAX = 32767 * 10  # int16 in units of 10 ERPM (and 10 ERPM/s)


@dataclass(slots=True)
class JointState:
    """The latest feedback of one joint, joint side.

    Attributes:
        position: rad. velocity: rad/s. torque: N·m (as the motor reports it).
        temperature: °C, or ``None`` if the motor does not report it.
        error: the motor's error code (0 = none).
        stamp: clock time of the feedback, s (``-inf`` before the first one).
    """

    position: float = math.nan
    velocity: float = math.nan
    torque: float = math.nan
    temperature: float | None = None
    error: int = 0
    stamp: float = -math.inf

    def age(self, now: float) -> float:
        """Seconds since this feedback arrived (``inf`` if none has)."""
        return now - self.stamp


class Joint:
    """One configured joint as the controller sees it."""

    mode: str = ""

    def __init__(self, index: int, config: JointConfig) -> None:
        self.index = index
        self.config = config
        self.name = config.name
        self.bus = config.bus
        self.motor = config.motor
        self.direction = float(config.direction)
        self.offset = config.offset
        self.state = JointState()
        self.frames_received = 0

    def joint_position(self, motor_position: float) -> float:
        """Motor-side angle (rad at the output) → joint angle (rad)."""
        return self.direction * motor_position + self.offset

    def motor_position(self, joint_position: float) -> float:
        """Joint angle (rad) → motor-side angle (rad at the output)."""
        return (joint_position - self.offset) * self.direction

    def _update(self, p_motor: float, v_motor: float, t_motor: float, temperature: float | None,
                error: int | None, now: float) -> None:
        s = self.state
        s.position = self.direction * p_motor + self.offset
        s.velocity = self.direction * v_motor
        s.torque = self.direction * t_motor
        s.temperature = temperature
        s.error = error or 0
        s.stamp = now
        self.frames_received += 1


class MitJoint(Joint):
    """A joint driven in MIT mode: (p, v, kp, kd, τ_ff) every cycle; a reply per frame."""

    mode = "mit"

    def __init__(self, index: int, config: JointConfig) -> None:
        super().__init__(index, config)
        self.firmware = config.firmware
        self.codec = mit.codec(config.motor)
        arb, ext = mit.command_arbitration_id(config.can_id, config.firmware)
        self._arb, self._ext = arb, ext
        self._p_max = config.motor.p_max
        self._last_raw: float | None = None
        self._turns = 0

    # -- frames out ---------------------------------------------------------------------------
    def _msg(self, data: bytes) -> can.Message:
        return message(self._arb, data, self._ext)

    def enter_frames(self) -> list[can.Message]:
        """Frames that put the driver in motor mode (none for V3 firmware, which has no such frame)."""
        return [] if self.firmware == "v3" else [self._msg(mit.ENTER)]

    def zero_frames(self) -> list[can.Message]:
        """The frame that makes the motor's current position its zero (V1/V2 firmware; none on V3)."""
        return [] if self.firmware == "v3" else [self._msg(mit.ZERO)]

    def exit_frames(self) -> list[can.Message]:
        """Frames that take the driver out of motor mode (V3: a zero-gain, zero-torque command)."""
        return [self.command(math.nan, 0.0, 0.0, 0.0, 0.0)] if self.firmware == "v3" else [self._msg(mit.EXIT)]

    def command(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> can.Message:
        """The MIT command for joint-side targets (rad, rad/s, N·m/rad, N·m·s/rad, N·m).

        A NaN position means "no position target" and is sent as the motor's current position
        (only meaningful with kp = 0).
        """
        if position != position:  # NaN
            p_motor = self.motor_position(self.state.position) if self.state.position == self.state.position else 0.0
        else:
            p_motor = (position - self.offset) * self.direction - self._turns * 2.0 * self._p_max
        d = self.direction
        data = self.codec.encode_command(p_motor, velocity * d, kp, kd, torque * d, firmware=self.firmware)
        return self._msg(data)

    # -- feedback in --------------------------------------------------------------------------
    def handle_reply(self, data: bytes, now: float) -> None:
        """Take a V1/V2 reply (6 or 8 bytes, standard frame)."""
        r = self.codec.decode_reply(data)
        # _update inlined (this runs for every joint every cycle), after undoing the reply's wrap at
        # ±P_MAX by counting turns of the 2·P_MAX field
        raw = r[1]
        last = self._last_raw
        if last is not None:
            if raw - last > self._p_max:
                self._turns -= 1
            elif last - raw > self._p_max:
                self._turns += 1
        self._last_raw = raw
        d, s = self.direction, self.state
        s.position = d * (raw + self._turns * 2.0 * self._p_max) + self.offset
        s.velocity = d * r[2]
        s.torque = d * r[3]
        s.temperature = r[4]
        s.error = r[5] or 0
        s.stamp = now
        self.frames_received += 1

    def handle_status(self, arbitration_id: int, data: bytes, now: float) -> None:
        """Take a V3 reply (a 0x29xx status frame)."""
        r = self.codec.decode_reply_v3(arbitration_id, data)
        self._update(r.position, r.velocity, r.torque, r.temperature, r.error, now)

    def rezeroed(self) -> None:
        """Forget turn counting after the motor's zero was moved."""
        self._last_raw = None
        self._turns = 0


class ServoJoint(Joint):
    """A joint driven in servo mode: a position-speed frame every cycle; periodic status frames."""

    mode = "servo"

    def __init__(self, index: int, config: JointConfig) -> None:
        super().__init__(index, config)
        self.can_id = config.can_id
        self._speed_cap = min(abs(units.rad_s_to_erpm(config.motor, config.limits.velocity)), _SPEED_FIELD_MAX)
        self._accel_cap = min(abs(units.rad_s_to_erpm(config.motor, config.limits.acceleration)), _SPEED_FIELD_MAX)

    @staticmethod
    def _msg(frame: tuple[int, bytes]) -> can.Message:
        return message(frame[0], frame[1], True)

    def command(self, position: float, speed_fraction: float = 1.0) -> can.Message:
        """Position-speed frame: go to ``position`` (rad, joint side) within the joint's limits.

        ``speed_fraction`` scales the speed and acceleration caps (``speed=`` of a move).
        """
        deg = units.rad_to_servo_deg(self.motor, self.motor_position(position))
        speed = max(10.0, self._speed_cap * speed_fraction)
        accel = max(10.0, self._accel_cap * speed_fraction * speed_fraction)
        return self._msg(servo.encode_position_speed(self.can_id, deg, speed, accel))

    def brake(self, amps: float) -> can.Message:
        """Current-brake frame (A, ≥ 0): resists motion without a position target."""
        return self._msg(servo.encode_current_brake(self.can_id, amps))

    def release(self) -> can.Message:
        """Zero-current frame: the output goes limp."""
        return self._msg(servo.encode_current(self.can_id, 0.0))

    def current(self, amps: float) -> can.Message:
        """Current (torque) frame, A of Iq."""
        return self._msg(servo.encode_current(self.can_id, amps))

    def handle_status(self, arbitration_id: int, data: bytes, now: float) -> None:
        """Take a 0x29xx status frame."""
        s = servo.decode_status(arbitration_id, data)
        m = self.motor
        torque = units.amps_to_torque(m, s.current_a) if m.kt is not None else math.nan
        self._update(units.servo_deg_to_rad(m, s.position_deg), units.erpm_to_rad_s(m, s.speed_erpm), torque,
                     float(s.temperature_c), s.error, now)


def make_joint(index: int, config: JointConfig) -> Joint:
    """The controller-side joint for ``config`` (MIT or servo)."""
    return MitJoint(index, config) if config.mode == "mit" else ServoJoint(index, config)


class Router:
    """Routes the frames received on one bus to its joints.

    Standard frames of 6 or 8 bytes are MIT replies, routed by byte 0 (the driver ID). Extended
    frames are routed by their whole ID (``0x2900 | id`` for servo status and V3 replies).
    Frames for nobody, and corrupt frames, are counted, never raised.
    """

    def __init__(self, joints: list[Joint]) -> None:
        self.by_driver_id: dict[int, MitJoint] = {}
        self.by_status_id: dict[int, Joint] = {}
        for j in joints:
            if isinstance(j, MitJoint) and j.firmware != "v3":
                self.by_driver_id[j.config.can_id] = j
            else:
                self.by_status_id[(servo.ServoPacket.STATUS << 8) | j.config.can_id] = j
        self.unrouted = 0
        self.corrupt = 0

    def route(self, msg: can.Message, now: float) -> Joint | None:
        """Hand ``msg`` to its joint; return that joint, or ``None``."""
        data = msg.data
        try:
            if msg.is_extended_id:
                j = self.by_status_id.get(msg.arbitration_id)
                if j is not None:
                    j.handle_status(msg.arbitration_id, data, now)  # type: ignore[attr-defined]
                    return j
            elif msg.dlc in (6, 8) and not msg.is_remote_frame:
                mj = self.by_driver_id.get(data[0])
                if mj is not None:
                    mj.handle_reply(data, now)
                    return mj
        except ProtocolError:
            self.corrupt += 1
            return None
        self.unrouted += 1
        return None
