"""Controller side of each joint: frames out, feedback in, and the joint ⇄ motor conversion.

``joint = direction * motor + offset`` for positions (rad); velocities and torques scale by
``direction``. Everything a :class:`Joint` returns or accepts is joint-side SI; motor units (the
codecs' integers, degrees, ERPM, amps) stay in here and in :mod:`akarm.protocol.units`.

Every joint, MIT or servo, offers the same typed interface (:class:`Joint`): the frames that put
it in motor mode, track a target, carry a torque without stiffness, damp it, and release it, and
:meth:`Joint.take` for the frames it is sent back. Callers never ask which kind a joint is.

Feedback is **gated**: a reply whose position is further from the last accepted one than the motor
could have turned since (:attr:`Joint.max_speed`) is discarded and counted
(:attr:`Joint.rejected_run`), so a corrupt or forged frame never reaches the commands, nor the
turn counting of MIT replies across their ±P_MAX wrap. The supervisor (:mod:`akarm.control.safety`) stops
the arm when several come in a row. While an enable makes contact (:attr:`Joint.adopting`), the first
reply is the reference only until two replies in a row disagree with it and agree with each other: then
it was the odd one (a forged reply just before contact) and the later of them is the reference instead
(:meth:`Joint.rebase`), in the same pass over the replies.

Replies are routed per bus by :class:`Router`: MIT (V1/V2 firmware) replies are standard frames
whose byte 0 is the driver ID (the arbitration ID differs between units and is not used); servo
status and V3 replies are extended ``0x29xx`` frames matched on the whole ID. A frame on one of our
joints' *command* IDs was sent by another node (we do not hear our own): the Router records it on
the joint (:attr:`Joint.foreign`) for the supervisor.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Iterable
from dataclasses import dataclass

import can

from akarm.buses.frames import Frame, message
from akarm.config import JointConfig
from akarm.errors import ProtocolError
from akarm.protocol import mit, servo, units

__all__ = ["Joint", "JointState", "MitJoint", "Router", "ServoJoint", "make_joint"]

_SPEED_FIELD_MAX = 32767 * 10  # int16 in units of 10 ERPM (and 10 ERPM/s)
_SERVO_COMMAND_PACKETS = tuple(p for p in servo.ServoPacket if p is not servo.ServoPacket.STATUS)


@dataclass(slots=True)
class JointState:
    """The latest accepted feedback of one joint, joint side.

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


class Joint(abc.ABC):
    """One configured joint as the controller sees it: the contract every joint kind implements.

    Attributes:
        index, config, name, bus, motor, direction, offset: from the configuration.
        state: the latest accepted feedback (:class:`JointState`).
        answers_commands: True when the driver answers every frame it is sent (MIT); False when it
            sends status frames on its own (servo).
        frames_received: feedback frames taken (accepted or rejected).
        frames_sent: frames sent to it that it answers (counted by the sender, :meth:`sent`).
        max_speed: rad/s at the output; feedback implying a faster motion since the last accepted
            one is rejected (``inf``: no gate; the Arm sets the motor's speed range).
        min_interval: s; two replies are taken to be at least this far apart in time (the loop
            period: the replies drained in one cycle share one time stamp).
        rejected, rejected_run: feedback frames rejected in all, and in a row since the last
            accepted one. rejected_peak: the longest such run since the supervisor last looked
            (frames drained together can hold a run and the good frame after it).
        accepted_run: accepted in a row since the last rejected one (or :meth:`begin_contact`).
        last_rejected: the position the last rejected one claimed (rad, joint side).
        adopting: while an enable makes contact (from :meth:`begin_contact` until the enabler has made it):
            a second rejected reply in a row that agrees with the first is taken as the new reference.
        adopted_at: when that last happened (clock time, s; ``-inf``: not since :meth:`begin_contact`).
            The enabler makes contact only on a reply from a later cycle: a burst of forged replies
            drained together never makes contact by itself.
        foreign, foreign_at: the kind of the last frame another node sent to this joint's command
            IDs (``"exit"``, ``"enter"``, ``"zero"``, ``"command"``), and when (clock time, s).
        cmd_position, cmd_velocity, cmd_kp, cmd_kd, cmd_torque: MIT joints: the law of the last
            command sent (rad, rad/s, N·m/rad, N·m·s/rad, N·m; position NaN: none); servo joints: unused.
    """

    mode: str = ""
    answers_commands: bool = False

    def __init__(self, index: int, config: JointConfig) -> None:
        self.index = index
        self.config = config
        self.name = config.name
        self.bus = config.bus
        self.can_id = config.can_id
        self.motor = config.motor
        self.direction = float(config.direction)
        self.offset = config.offset
        self.state = JointState()
        self.frames_received = 0
        self.frames_sent = 0
        self.max_speed = math.inf
        self.min_interval = 0.0
        self._slack = 0.0  # rad: what the position field's resolution adds to a step
        self.rejected = 0
        self.rejected_run = 0
        self.rejected_peak = 0
        self.accepted_run = 0
        self.last_rejected = math.nan
        self._rejected_at = -math.inf
        self.adopting = False
        self.adopted_at = -math.inf
        self.foreign: str | None = None
        self.foreign_at = -math.inf
        # MIT: the law of the last command (joint side): the driver applies kp·(position - q) + kd·(velocity
        # - v) + torque until the next one; the supervisor judges the torque the replies report against it
        self.cmd_position = math.nan
        self.cmd_velocity = 0.0
        self.cmd_kp = 0.0
        self.cmd_kd = 0.0
        self.cmd_torque = 0.0
        # "servo": status frames on this MIT joint's ID; "mit": MIT replies on this servo joint's (the Router)
        self.mode_seen: str | None = None

    # -- conversions --------------------------------------------------------------------------
    def joint_position(self, motor_position: float) -> float:
        """Motor-side angle (rad at the output) → joint angle (rad)."""
        return self.direction * motor_position + self.offset

    def motor_position(self, joint_position: float) -> float:
        """Joint angle (rad) → motor-side angle (rad at the output)."""
        return (joint_position - self.offset) * self.direction

    # -- frames out (joint side, SI) ------------------------------------------------------------
    @abc.abstractmethod
    def enter_frames(self) -> list[can.Message]:
        """Frames that put the driver in motor mode (none where the driver has no such mode)."""

    def mode_query_frames(self) -> list[can.Message]:
        """Frames that make a motor in the other mode than this joint's answer on its ID, leaving it
        limp (:attr:`mode_seen` says so once it does): a servo joint asks as a MIT motor is asked. None
        by default."""
        return []

    @abc.abstractmethod
    def neutral(self) -> can.Message | None:
        """A frame that commands nothing (no stiffness, no torque) but asks for feedback, or ``None``."""

    def track(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> can.Message:
        """Hold or follow ``position`` (rad) at ``velocity`` (rad/s): MIT with gains ``kp``, ``kd`` and
        feed-forward ``torque`` (N·m); servo through the firmware's own position loop (gains and
        torque unused)."""
        arbitration_id, extended, data = self.track_frame(position, velocity, kp, kd, torque)
        return message(arbitration_id, data, extended)

    @abc.abstractmethod
    def track_frame(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> Frame:
        """:meth:`track`'s frame by its fields, ``(arbitration_id, is_extended_id, data)``: what the control
        loop sends every cycle (:meth:`akarm.control.busset.BusSet.send_frames`), without a message."""

    @abc.abstractmethod
    def carry(self, damping: float, torque: float) -> can.Message:
        """No stiffness: apply ``torque`` (N·m, e.g. the arm's weight) with ``damping`` (N·m·s/rad; MIT)."""

    @abc.abstractmethod
    def damp(self, damping: float, torque: float) -> can.Message:
        """Resist motion without a position target: MIT damping ``damping`` with ``torque``;
        servo a braking current."""

    @abc.abstractmethod
    def release_frames(self) -> list[can.Message]:
        """Frames that make the output limp and leave the driver so (MIT: a zero-gain, zero-torque
        command, so the next enable cannot kick, then EXIT; servo: zero current)."""

    @abc.abstractmethod
    def query_frames(self) -> list[can.Message]:
        """Frames that make a silent driver report its state without commanding it (MIT: EXIT, which
        leaves it disabled); none for drivers that report on their own."""

    @abc.abstractmethod
    def zero_frames(self, permanent: bool = False) -> list[can.Message]:
        """Frames that make the motor's current position its zero (none where the firmware has none)."""

    def rezeroed(self) -> None:
        """Forget what depends on the motor's zero (called after :meth:`zero_frames` were sent)."""
        self.begin_contact()

    # -- routing --------------------------------------------------------------------------------
    @abc.abstractmethod
    def feedback_route(self) -> tuple[str, int]:
        """How the Router finds this joint's feedback: ``("byte0", driver id)`` for standard-frame
        replies, ``("id", arbitration id)`` for extended status frames."""

    @abc.abstractmethod
    def command_ids(self) -> list[tuple[int, bool]]:
        """The ``(arbitration id, extended)`` pairs frames *to* this joint are sent on."""

    @abc.abstractmethod
    def take(self, arbitration_id: int, data: bytes | bytearray, now: float) -> None:
        """A feedback frame for this joint arrived at ``now`` (s): decode, gate, update :attr:`state`.

        Raises:
            ProtocolError: a corrupt frame (the Router counts it).
        """

    def sent(self, frames: int = 1) -> None:
        """Count ``frames`` sent to this joint that it will answer (nothing for drivers that do not)."""
        if self.answers_commands:
            self.frames_sent += frames

    def note_foreign(self, kind: str, now: float) -> None:
        """Another node sent this joint a frame of ``kind`` at ``now``."""
        self.foreign = kind
        self.foreign_at = now

    def begin_contact(self) -> None:
        """Start over (at enable): the next frame is accepted as it comes, and is the reference the
        ones after it are gated against. :meth:`rebase` returns here."""
        self._restart()
        self.adopted_at = -math.inf

    def _restart(self) -> None:
        self.state.stamp = -math.inf
        self.rejected_run = 0
        self.rejected_peak = 0  # replies refused before (while disabled, or an odd reference) do not count
        self.accepted_run = 0
        self.adopting = True

    def rebase(self) -> None:
        """Drop the reference taken since :meth:`begin_contact` (it was the odd one out: the replies
        after it all disagreed with it) and start over from the same point."""
        self._restart()

    def _odd_reference(self, claimed: float, now: float) -> bool:
        """(A reply claiming ``claimed`` rad at ``now`` was just rejected.) True when, during contact, it is
        the second rejected in a row and agrees with the first: the reference was the odd one. Notes it as
        the last rejected either way."""
        prev, at = self.last_rejected, self._rejected_at
        self.last_rejected = claimed
        self._rejected_at = now
        if not (self.adopting and self.rejected_run >= 2):
            return False
        dt = max(now - at, self.min_interval)
        if abs(claimed - prev) > self.max_speed * dt + self._slack:
            return False
        self.adopted_at = now
        return True

    def set_gate(self, max_speed: float, min_interval: float) -> None:
        """Gate feedback: reject positions implying more than ``max_speed`` rad/s since the last
        accepted one, taking replies to be at least ``min_interval`` s apart."""
        self.max_speed = max_speed
        self.min_interval = min_interval

    def _gate(self, step: float, now: float, claimed: float) -> bool:
        """True to accept a position ``step`` (rad, motor side) from the last accepted feedback."""
        s = self.state
        if s.stamp == -math.inf:
            return True
        dt = now - s.stamp
        if dt < self.min_interval:
            dt = self.min_interval
        if step <= self.max_speed * dt + self._slack or step != step:
            return True
        self.rejected += 1
        self.rejected_run += 1
        if self.rejected_run > self.rejected_peak:
            self.rejected_peak = self.rejected_run
        self.accepted_run = 0
        if self._odd_reference(claimed, now):
            self.rebase()
            return True  # taken as the first reply after the checkpoint: the new reference
        return False

    def _update(self, p_motor: float, v_motor: float, t_motor: float, temperature: float | None,
                error: int | None, now: float) -> None:
        self.frames_received += 1
        s = self.state
        if s.stamp != -math.inf:
            d = self.direction
            claimed = d * p_motor + self.offset
            if not self._gate(abs(claimed - s.position), now, claimed):
                return
        self.rejected_run = 0
        self.accepted_run += 1
        s.position = self.direction * p_motor + self.offset
        s.velocity = self.direction * v_motor
        s.torque = self.direction * t_motor
        s.temperature = temperature
        s.error = error or 0
        s.stamp = now


class MitJoint(Joint):
    """A joint driven in MIT mode: (p, v, kp, kd, τ_ff) every cycle; a reply per frame."""

    mode = "mit"
    answers_commands = True

    def __init__(self, index: int, config: JointConfig) -> None:
        super().__init__(index, config)
        self.firmware = config.firmware
        self.codec = mit.codec(config.motor)
        arb, ext = mit.command_arbitration_id(config.can_id, config.firmware)
        self._arb, self._ext = arb, ext
        self._p_max = config.motor.p_max
        self._span = 2.0 * self._p_max
        self._slack = 4.0 * self._span / 65535.0  # four steps of the 16-bit position field
        self._last_raw: float | None = None
        self._turns = 0
        self._checkpoint: tuple[float | None, int] = (None, 0)

    # -- frames out ---------------------------------------------------------------------------
    def _msg(self, data: bytes) -> can.Message:
        return message(self._arb, data, self._ext)

    def enter_frames(self) -> list[can.Message]:
        """ENTER (none for V3 firmware, which has no such frame and applies its first command)."""
        return [] if self.firmware == "v3" else [self._msg(mit.ENTER)]

    def neutral(self) -> can.Message:
        """The zero-gain, zero-torque command: replaces the command the driver remembers, asks for a reply."""
        return self.command(math.nan, 0.0, 0.0, 0.0, 0.0)

    def track_frame(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> Frame:
        return self._arb, self._ext, self.command_data(position, velocity, kp, kd, torque)

    def carry(self, damping: float, torque: float) -> can.Message:
        return self.command(math.nan, 0.0, 0.0, damping, torque)

    def damp(self, damping: float, torque: float) -> can.Message:
        return self.command(math.nan, 0.0, 0.0, min(damping, self.motor.kd_max), torque)

    def exit_frames(self) -> list[can.Message]:
        """Frames that take the driver out of motor mode (V3: a zero-gain, zero-torque command)."""
        return [self.neutral()] if self.firmware == "v3" else [self._msg(mit.EXIT)]

    def release_frames(self) -> list[can.Message]:
        return [self.neutral(), *([] if self.firmware == "v3" else [self._msg(mit.EXIT)])]

    def query_frames(self) -> list[can.Message]:
        return self.exit_frames()

    def zero_frames(self, permanent: bool = False) -> list[can.Message]:
        """The frame that makes the motor's current position its zero (V1/V2 firmware; none on V3)."""
        return [] if self.firmware == "v3" else [self._msg(mit.ZERO)]

    def command(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> can.Message:
        """The MIT command for joint-side targets (rad, rad/s, N·m/rad, N·m·s/rad, N·m).

        A NaN position means "no position target" and is sent as the motor's current position
        (only meaningful with kp = 0). The law is kept as :attr:`cmd_position`, :attr:`cmd_velocity`,
        :attr:`cmd_kp`, :attr:`cmd_kd`, :attr:`cmd_torque` (what the driver applies until the next one).
        """
        return self._msg(self.command_data(position, velocity, kp, kd, torque))

    def command_data(self, position: float, velocity: float, kp: float, kd: float, torque: float) -> bytes:
        """:meth:`command`'s data bytes (its law kept as there)."""
        self.cmd_position = position
        self.cmd_velocity = velocity
        self.cmd_kp = kp
        self.cmd_kd = kd
        self.cmd_torque = torque
        if position != position:  # NaN
            p_motor = self.motor_position(self.state.position) if self.state.position == self.state.position else 0.0
            p_motor -= self._turns * self._span
        else:
            p_motor = (position - self.offset) * self.direction - self._turns * self._span
        d = self.direction
        return self.codec.encode_command(p_motor, velocity * d, kp, kd, torque * d, firmware=self.firmware)

    # -- routing and feedback -----------------------------------------------------------------
    def feedback_route(self) -> tuple[str, int]:
        if self.firmware == "v3":
            return "id", (servo.ServoPacket.STATUS << 8) | self.can_id
        return "byte0", self.can_id

    def command_ids(self) -> list[tuple[int, bool]]:
        return [(self._arb, self._ext)]

    def take(self, arbitration_id: int, data: bytes | bytearray, now: float) -> None:
        if self.firmware == "v3":
            r = self.codec.decode_reply_v3(arbitration_id, data)
            self._update(r.position, r.velocity, r.torque, r.temperature, r.error, now)
            return
        self.handle_reply(data, now)

    def handle_reply(self, data: bytes | bytearray, now: float) -> None:
        """Take a V1/V2 reply (6 or 8 bytes, standard frame)."""
        r = self.codec.decode_reply(data)
        self.frames_received += 1
        # Undo the reply's wrap at ±P_MAX by counting turns of the 2·P_MAX field: the step from the
        # last accepted reply is the wrapped difference, and a step the motor cannot have made is
        # rejected before it can touch the count. (Inlined: this runs for every joint every cycle.)
        raw = r[1]
        last = self._last_raw
        turns = self._turns
        s = self.state
        if last is not None:
            step = raw - last
            if step > self._p_max:
                step -= self._span
                turns -= 1
            elif step < -self._p_max:
                step += self._span
                turns += 1
            if s.stamp != -math.inf:
                dt = now - s.stamp
                if dt < self.min_interval:
                    dt = self.min_interval
                if abs(step) > self.max_speed * dt + self._slack:
                    self.rejected += 1
                    self.rejected_run += 1
                    if self.rejected_run > self.rejected_peak:
                        self.rejected_peak = self.rejected_run
                    self.accepted_run = 0
                    if not self._odd_reference(self.direction * (raw + turns * self._span) + self.offset, now):
                        return
                    # the reference was the odd one: from the checkpoint, this reply is the first again
                    self.rebase()
                    self.frames_received -= 1
                    self.handle_reply(data, now)
                    return
        self.rejected_run = 0
        self.accepted_run += 1
        self._last_raw = raw
        self._turns = turns
        d = self.direction
        s.position = d * (raw + turns * self._span) + self.offset
        s.velocity = d * r[2]
        s.torque = d * r[3]
        s.temperature = r[4]
        s.error = r[5] or 0
        s.stamp = now

    def begin_contact(self) -> None:
        super().begin_contact()
        self._checkpoint = (self._last_raw, self._turns)  # a forged first reply must not keep a turn

    def rebase(self) -> None:
        super().rebase()  # (not begin_contact: the checkpoint stays the one taken there)
        self._last_raw, self._turns = self._checkpoint

    def rezeroed(self) -> None:
        """Forget turn counting after the motor's zero was moved."""
        self._last_raw, self._turns = None, 0
        self.begin_contact()


class ServoJoint(Joint):
    """A joint driven in servo mode: a position-speed frame every cycle; periodic status frames."""

    mode = "servo"
    answers_commands = False

    def __init__(self, index: int, config: JointConfig) -> None:
        super().__init__(index, config)
        self._speed_cap = min(abs(units.rad_s_to_erpm(config.motor, config.limits.velocity)), _SPEED_FIELD_MAX)
        self._accel_cap = min(abs(units.rad_s_to_erpm(config.motor, config.limits.acceleration)), _SPEED_FIELD_MAX)
        self._slack = 4.0 * abs(units.servo_deg_to_rad(config.motor, 0.1))  # four 0.1° steps of the status field

    @staticmethod
    def _msg(frame: tuple[int, bytes]) -> can.Message:
        return message(frame[0], frame[1], True)

    def enter_frames(self) -> list[can.Message]:
        return []

    def mode_query_frames(self) -> list[can.Message]:
        """EXIT on its ID as a standard frame: a MIT motor answers it with a state reply and stays limp
        (the query ``akarm scan`` sends); a motor in servo mode ignores standard frames."""
        return [message(self.can_id, mit.EXIT, False)]

    def neutral(self) -> None:
        return None

    def track_frame(self, position: float, velocity: float = 0.0, kp: float = 0.0, kd: float = 0.0,
                    torque: float = 0.0) -> Frame:
        arbitration_id, data = self._position_speed(position, 1.0)
        return arbitration_id, True, data

    def carry(self, damping: float, torque: float) -> can.Message:
        return self.current(units.torque_to_amps(self.motor, torque * self.direction))

    def damp(self, damping: float, torque: float) -> can.Message:
        return self.brake(0.5 * (self.motor.rated_current or 2.0))

    def release_frames(self) -> list[can.Message]:
        return [self.release()]

    def query_frames(self) -> list[can.Message]:
        return []

    def zero_frames(self, permanent: bool = False) -> list[can.Message]:
        mode = servo.OriginMode.PERMANENT if permanent else servo.OriginMode.TEMPORARY
        return [self._msg(servo.encode_origin(self.can_id, mode))]

    def command(self, position: float, speed_fraction: float = 1.0) -> can.Message:
        """Position-speed frame: go to ``position`` (rad, joint side) within the joint's limits.

        ``speed_fraction`` scales the speed and acceleration caps (``speed=`` of a move).
        """
        return self._msg(self._position_speed(position, speed_fraction))

    def _position_speed(self, position: float, speed_fraction: float) -> tuple[int, bytes]:
        deg = units.rad_to_servo_deg(self.motor, self.motor_position(position))
        speed = max(10.0, self._speed_cap * speed_fraction)
        accel = max(10.0, self._accel_cap * speed_fraction * speed_fraction)
        return servo.encode_position_speed(self.can_id, deg, speed, accel)

    def current_frame(self, torque: float) -> Frame:
        """The current (SET_CURRENT) that gives ``torque`` N·m at the output, joint side, as the loop's
        frame fields (the gripper's force-limited law: the firmware's current loop, no position loop)."""
        aid, data = servo.encode_current(self.can_id, units.torque_to_amps(self.motor, torque * self.direction))
        return aid, True, data

    def brake(self, amps: float) -> can.Message:
        """Current-brake frame (A, ≥ 0): resists motion without a position target."""
        return self._msg(servo.encode_current_brake(self.can_id, amps))

    def release(self) -> can.Message:
        """Zero-current frame: the output goes limp."""
        return self._msg(servo.encode_current(self.can_id, 0.0))

    def current(self, amps: float) -> can.Message:
        """Current (torque) frame, A of Iq."""
        return self._msg(servo.encode_current(self.can_id, amps))

    def feedback_route(self) -> tuple[str, int]:
        return "id", (servo.ServoPacket.STATUS << 8) | self.can_id

    def command_ids(self) -> list[tuple[int, bool]]:
        return [((int(p) << 8) | self.can_id, True) for p in _SERVO_COMMAND_PACKETS]

    def take(self, arbitration_id: int, data: bytes | bytearray, now: float) -> None:
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
    frames are routed by their whole ID (``0x2900 | id`` for servo status and V3 replies). A frame
    on a joint's command ID is another node's (we never hear our own): it is noted on the joint
    (:meth:`Joint.note_foreign`), except a standard frame whose byte 0 is that joint's own ID,
    which is its reply (some units answer on their own ID). Frames for nobody, and corrupt frames,
    are counted, never raised.
    """

    def __init__(self, joints: list[Joint]) -> None:
        self.by_driver_id: dict[int, Joint] = {}
        self.by_status_id: dict[int, Joint] = {}
        self.by_command_id: dict[tuple[int, bool], Joint] = {}
        self.by_other_mode: dict[int, Joint] = {}  # servo status IDs of MIT V1/V2 joints: a motor in servo mode
        self.by_mit_of_servo: dict[int, Joint] = {}  # driver IDs of servo joints: MIT replies, a motor in MIT mode
        for j in joints:
            how, key = j.feedback_route()
            (self.by_driver_id if how == "byte0" else self.by_status_id)[key] = j
            if how == "byte0":
                self.by_other_mode[(servo.ServoPacket.STATUS << 8) | key] = j
            elif j.mode == "servo":
                self.by_mit_of_servo[j.can_id] = j
            for cid in j.command_ids():
                self.by_command_id[cid] = j
        # what route_frames takes straight to a joint: a standard 6- or 8-byte frame on an ID no joint
        # is commanded on is a V1/V2 reply, handed to the handler of the joint its byte 0 names
        self._reply_handlers = {key: j.handle_reply for key, j in self.by_driver_id.items() if isinstance(j, MitJoint)}
        self._standard_commands = frozenset(arb for arb, ext in self.by_command_id if not ext)
        self.unrouted = 0
        self.corrupt = 0

    def route_frames(self, frames: Iterable[tuple[int, bool, bool, int, bytes]], now: float) -> None:
        """:meth:`route_frame` for each of a bus's frames as :meth:`akarm.buses.localbus.LocalBus.drain`
        gives them: the loop's replies each go straight to their joint's decoder."""
        handlers, commands, route = self._reply_handlers, self._standard_commands, self.route_frame
        for frame in frames:
            arbitration_id, extended, plain, dlc, data = frame
            if not extended and plain and (dlc == 8 or dlc == 6) and arbitration_id not in commands:
                handle = handlers.get(data[0])
                if handle is not None:
                    try:
                        handle(data, now)
                    except ProtocolError:
                        self.corrupt += 1
                    continue
            route(arbitration_id, extended, plain, dlc, data, now)

    def route(self, msg: can.Message, now: float) -> Joint | None:
        """Hand ``msg`` to its joint; return that joint, or ``None``."""
        return self.route_frame(msg.arbitration_id, msg.is_extended_id,
                                not (msg.is_remote_frame or msg.is_error_frame), msg.dlc, msg.data, now)

    def route_frame(self, arbitration_id: int, extended: bool, plain: bool, dlc: int, data: bytes | bytearray,
                    now: float) -> Joint | None:
        """:meth:`route` for a frame given by its fields (``plain``: neither a remote nor an error frame)."""
        try:
            if extended:
                j = self.by_status_id.get(arbitration_id)
                if j is not None:
                    j.take(arbitration_id, data, now)
                    return j
                j = self.by_command_id.get((arbitration_id, True))
                if j is not None:
                    j.note_foreign("command", now)
                    return None
                j = self.by_other_mode.get(arbitration_id)
                if j is not None:
                    j.mode_seen = "servo"
            elif plain:
                jc = self.by_command_id.get((arbitration_id, False))
                if jc is not None and (dlc not in (6, 8) or data[0] != jc.can_id):
                    jc.note_foreign(mit.special_frame(data) or "command", now)
                    return None
                if dlc == 6 or dlc == 8:
                    mj = self.by_driver_id.get(data[0])
                    if mj is not None:
                        mj.take(arbitration_id, data, now)
                        return mj
                    sj = self.by_mit_of_servo.get(data[0])
                    if sj is not None:  # a MIT reply from a servo joint's ID: its motor is in MIT mode
                        sj.mode_seen = "mit"
                        return None
        except ProtocolError:
            self.corrupt += 1
            return None
        self.unrouted += 1
        return None
