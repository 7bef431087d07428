"""The safety supervisor: every cycle, decide from the joints' feedback whether the arm must stop.

The control loop asks :meth:`Supervisor.check` once per cycle while the arm is powered; a
:class:`~akarm.SafetyStop` comes back when something is wrong, and the loop then damps and
disables the arm. The supervisor only reads: the joints' latest accepted feedback and counters
(:class:`akarm.control.joints.Joint`), and the commanded positions. It needs no bus and no clock of its
own, so every check is tested by feeding it joint states.

Checks, per joint, in order (the first that fires is the stop):

1. **Foreign traffic**: another node sent one of our joints a command, ENTER, EXIT or ZERO since the
   arm was enabled (a second controller, a forgotten script, the upper computer), or a joint answers
   more frames than it was sent (a second motor with the same CAN ID, a forger). →
   :class:`~akarm.ForeignTraffic`.
2. **Motor error code** reported by the driver. → :class:`~akarm.MotorFault`.
3. **Implausible feedback**: the joint rejects a reply whose position it cannot have reached since
   the last good one (the gate in :mod:`akarm.control.joints`); ``implausible_limit`` in a row stop the
   arm, and so do :data:`IMPLAUSIBLE_PER_WINDOW` in one :data:`REPLY_WINDOW` between good ones (CAN's
   own CRC makes a corrupt frame rare: these come from another node). →
   :class:`~akarm.ImplausibleFeedback`.
4. **Feedback age** over the joint's feedback timeout. → :class:`~akarm.FeedbackTimeout`.
5. **Temperature** over ``max_temperature``. → :class:`~akarm.OverTemperature`.
6. **Following error** (only joints that track a position: MIT with kp > 0, servo): the commanded
   minus the measured position over the joint's limit for three cycles in a row; or a command
   saturated at the motor's torque range for :data:`SATURATION_TIME` while the joint is more than
   ``stuck_travel`` from it (an undersized motor: it cannot hold the arm, whatever the error); or a
   reading that repeats while the command has moved on by more than ``stuck_travel``, is more than
   that from the reading, and the motor is not saturated (a frozen encoder or a blocked joint: a
   moving joint's reading changes every step of its 16-bit field; a joint turning round more slowly
   than its command repeats its reading but stays near it; a motor at its limit is the saturation
   check's). →
   :class:`~akarm.TrackingError`.

A constant reply delay cannot be seen in feedback age (every cycle brings a reply, just an old one).
It is measured where the stream of replies starts: at enable, from the first frame sent to the
first reply (:func:`contact_delay`); a delay that starts later shows as a gap as long as itself,
which feedback age catches.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from akarm.config import JointConfig
from akarm.control.joints import Joint
from akarm.errors import (
    FeedbackTimeout,
    ForeignTraffic,
    ImplausibleFeedback,
    MotorFault,
    OverTemperature,
    SafetyStop,
    TrackingError,
)
from akarm.protocol.servo import ServoErrorCode, describe_error

__all__ = ["Guard", "Supervisor", "default_following_error", "default_stuck_travel"]

#: Cycles in a row over the following-error limit that stop the arm (a lone sample never does).
FOLLOWING_CYCLES = 3
#: s between the comparisons of replies received with frames sent (the duplicate-responder check).
REPLY_WINDOW = 1.0
#: Rejected replies of one joint within a REPLY_WINDOW that stop the arm, even between good ones.
IMPLAUSIBLE_PER_WINDOW = 10
#: s a joint's command may stay at the motor's torque range while the joint is off its target (a move
#: that asks a little too much saturates for part of its acceleration; a motor that cannot hold, for good).
SATURATION_TIME = 0.5
_KNOWN_ERRORS = frozenset(int(c) for c in ServoErrorCode)  # the codes the manual lists (0-7)

_FIX_FOREIGN = ("stop the other program (akarm disable or akarm status from another terminal count too), or give "
                "each motor its own CAN ID; then enable again")


def default_following_error(joint: JointConfig, kp: float) -> float:
    """The following-error limit of a joint (rad) when its YAML gives none.

    MIT joints: the error at which the PD alone commands the joint's whole torque limit, ``torque /
    kp`` (``inf`` with kp = 0: the joint is not held at a position). Servo joints: the firmware's
    position profile chases each new target as if it were the last, so it trails a moving target by
    its braking distance ``v² / 2a`` at the joint's limits; add what three status periods cover at
    ``v`` and 0.1 rad.
    """
    if joint.following_error is not None:
        return joint.following_error
    if joint.mode == "servo":
        v, a = joint.limits.velocity, joint.limits.acceleration
        return v * v / (2.0 * a) + v * 3.0 / joint.status_rate_hz + 0.1
    return joint.limits.torque / kp if kp > 0 else math.inf


def default_stuck_travel(joint: JointConfig, kp: float, following_error: float) -> float:
    """How far (rad) the command may move while the joint's reading repeats, before the arm stops.

    Three times what friction alone could hold back with the PD (``3 · coulomb / kp``), at least
    0.05 rad (a loaded joint turning round behind a command that reverses fast reads the same step of
    its field for tens of milliseconds, 20-30 mrad behind), at most the following-error limit. Servo
    joints: a tenth of the following-error limit (their reading updates only with status frames).
    """
    if joint.stuck_travel is not None:
        return joint.stuck_travel
    if joint.mode == "servo":
        return following_error / 10.0
    if not kp > 0:
        return math.inf
    return min(following_error, max(0.05, 3.0 * joint.friction_model().coulomb / kp))


@dataclass(frozen=True)
class Guard:
    """One joint's safety limits.

    Attributes:
        feedback_timeout: s. max_temperature: °C.
        following_error: rad (``inf``: not checked). stuck_travel: rad (``inf``: not checked).
    """

    feedback_timeout: float
    max_temperature: float
    following_error: float = math.inf
    stuck_travel: float = math.inf


class Supervisor:
    """Decides, every cycle, whether the arm must stop (see the module's docstring for the checks).

    Args:
        joints: the controller's joints, in config order.
        guards: one :class:`Guard` per joint.
        implausible_limit: rejected replies in a row that stop the arm.

    Attributes:
        armed_at: clock time (s) from which foreign frames stop the arm (:meth:`arm`).
    """

    def __init__(self, joints: Sequence[Joint], guards: Sequence[Guard], *, implausible_limit: int = 3) -> None:
        if len(joints) != len(guards):
            raise ValueError("one guard per joint")
        if implausible_limit < 1:
            raise ValueError("implausible_limit must be at least 1")
        self.joints = list(joints)
        self.guards = list(guards)
        self.implausible_limit = implausible_limit
        n = len(self.joints)
        self.armed_at = math.inf
        self._answering = [i for i, j in enumerate(self.joints) if j.answers_commands]
        self._over = [0] * n
        self._saturated_since = [math.inf] * n
        self._tracked = [False] * n
        self._last_stamp = [-math.inf] * n
        self._last_value = [math.nan] * n
        self._des_at_value = [0.0] * n
        self._window_end = math.inf
        self._window_start: list[tuple[int, int]] = []
        self._rejected_start = [0] * n
        self._refresh()

    def _refresh(self) -> None:
        g = self.guards
        self._timeouts = [x.feedback_timeout for x in g]
        self._max_temp = [x.max_temperature for x in g]
        self._following = [x.following_error for x in g]
        self._stuck = [x.stuck_travel for x in g]

    def set_guards(self, guards: Sequence[Guard]) -> None:
        """Replace the limits (e.g. after the gains, and so the default following errors, changed)."""
        self.guards = list(guards)
        self._refresh()

    def arm(self, now: float) -> None:
        """From ``now`` on, a foreign frame to any joint stops the arm; the per-joint histories start over."""
        self.armed_at = now
        n = len(self.joints)
        self._over = [0] * n
        self._saturated_since = [math.inf] * n
        self._tracked = [False] * n
        self._window_end = now + REPLY_WINDOW
        self._window_start = [(self.joints[i].frames_received, self.joints[i].frames_sent) for i in self._answering]
        self._rejected_start = [j.rejected for j in self.joints]

    def disarm(self) -> None:
        """The arm is no longer powered: nothing is checked until :meth:`arm`."""
        self.armed_at = math.inf
        self._window_end = math.inf

    def foreign_since(self, since: float) -> tuple[Joint, str] | None:
        """The first joint another node sent a frame to at or after ``since`` (s), with its kind, or ``None``."""
        for j in self.joints:
            if j.foreign is not None and j.foreign_at >= since:
                return j, j.foreign
        return None

    # ------------------------------------------------------------------------------------------
    def check(self, now: float, q_des: Sequence[float] | None = None, tracking: Sequence[bool] | None = None,
              saturated: Sequence[bool] | None = None) -> SafetyStop | None:
        """The stop the arm needs now, or ``None``.

        Args:
            now: clock time, s.
            q_des: the commanded positions this cycle (rad, config order); ``None`` skips the
                following-error checks (teach mode, enabling).
            tracking: per joint, whether it is held at ``q_des`` (MIT with kp > 0, servo).
            saturated: per joint, whether its last command asked for the motor's whole torque range
                (stiffness, damping and feed-forward together); ``None``: unknown.
        """
        stop = self._check_joints(now)
        if stop is None and q_des is not None and tracking is not None:
            stop = self._check_following(now, q_des, tracking, saturated)
        if stop is None and now >= self._window_end:
            stop = self._check_replies(now)
        if stop is not None:
            stop.at = now
        return stop

    def _check_joints(self, now: float) -> SafetyStop | None:
        armed = self.armed_at
        limit = self.implausible_limit
        for j, timeout, max_temp in zip(self.joints, self._timeouts, self._max_temp, strict=True):
            if j.foreign_at >= armed:
                return self.foreign_stop(j, j.foreign or "command")
            s = j.state
            if s.error:
                if s.error not in _KNOWN_ERRORS:  # no driver sends it: forged or corrupt replies
                    return ImplausibleFeedback(
                        f"a reply carries error code {s.error}, which no AK driver reports: implausible traffic "
                        "(replies forged by another node, or corrupt), not a motor fault; the arm was damped and "
                        "disabled", value=s.position, limit=j.max_speed, count=1, joint=j.name,
                        fix="look for another node sending in this motor's name (candump), and check the CAN "
                            "wiring and termination")
                desc, remedy = describe_error(s.error)
                return MotorFault(f"motor reports error {s.error} ({desc}); the arm was damped and disabled",
                                  code=s.error, joint=j.name, fix=remedy)
            run = j.rejected_peak
            j.rejected_peak = j.rejected_run
            if run >= limit:
                step = abs(j.last_rejected - s.position)
                return ImplausibleFeedback(
                    f"{run} replies in a row claimed positions it cannot have reached (the last "
                    f"{j.last_rejected:+.4f} rad, {step:.3f} rad from the last good reading {s.position:+.4f} rad; "
                    f"at most {j.max_speed:.1f} rad/s is possible); the arm was damped and disabled",
                    value=j.last_rejected, limit=j.max_speed, count=run, joint=j.name,
                    fix="check the CAN wiring and termination (corrupt frames), and that no other node sends "
                        "replies with this driver ID")
            age = now - s.stamp
            if age > timeout:
                return FeedbackTimeout(
                    f"no feedback for {age * 1e3:.0f} ms (limit {timeout * 1e3:.0f} ms); the arm was damped and "
                    "disabled", age=age, limit=timeout, joint=j.name,
                    fix="check the motor's power and CAN wiring, its CAN ID, the bit rate, and the bus load")
            if s.temperature is not None and s.temperature > max_temp:
                return OverTemperature(
                    f"temperature {s.temperature:.0f} °C is above the limit {max_temp:.0f} °C; the arm was damped "
                    "and disabled", temperature=s.temperature, limit=max_temp, joint=j.name,
                    fix="let the motor cool; lower duty, speed or payload; check max_temperature in the YAML")
        return None

    def _check_following(self, now: float, q_des: Sequence[float], tracking: Sequence[bool],
                         saturated: Sequence[bool] | None) -> SafetyStop | None:
        over, tracked, sat_since = self._over, self._tracked, self._saturated_since
        last_stamp, last_value, des_at = self._last_stamp, self._last_value, self._des_at_value
        for i, j in enumerate(self.joints):
            qd = q_des[i]
            if not tracking[i]:
                tracked[i] = False
                over[i] = 0
                sat_since[i] = math.inf
                continue
            s = j.state
            q = s.position
            if not tracked[i]:  # tracking starts (again): the reading's history starts here
                tracked[i] = True
                last_stamp[i], last_value[i], des_at[i] = s.stamp, q, qd
            e = qd - q
            limit = self._following[i]
            if e > limit or e < -limit:
                over[i] += 1
                if over[i] >= FOLLOWING_CYCLES:
                    return TrackingError(
                        f"following error {e * 1e3:+.0f} mrad (commanded {qd:+.4f} rad, measured {q:+.4f} rad) is "
                        f"over its limit {limit * 1e3:.0f} mrad; the arm was damped and disabled",
                        error=e, limit=limit, joint=j.name,
                        fix="the motor cannot follow: a blocked or overloaded joint, a motor another program "
                            "disabled, a payload the motors cannot hold (akarm check), or gains too low; raise "
                            "following_error in the YAML only if the arm is sound")
            else:
                over[i] = 0
            sat = saturated is not None and saturated[i]
            if sat and (e > self._stuck[i] or e < -self._stuck[i]):
                if sat_since[i] == math.inf:
                    sat_since[i] = now
                elif now - sat_since[i] >= SATURATION_TIME:
                    return TrackingError(
                        f"its motor has been at the end of its torque range for {(now - sat_since[i]) * 1e3:.0f} ms "
                        f"and the joint is {e * 1e3:+.0f} mrad from its command (limit {self._stuck[i] * 1e3:.0f} "
                        "mrad): the motor cannot hold or move the arm; the arm was damped and disabled",
                        error=e, limit=self._stuck[i], joint=j.name,
                        fix="a motor too small for the load (akarm check shows the gravity torque per joint), a "
                            "payload heavier than configured, or a joint pressing on an obstacle")
            else:
                sat_since[i] = math.inf
            if s.stamp != last_stamp[i]:  # a new reading
                last_stamp[i] = s.stamp
                if q != last_value[i] or sat:
                    last_value[i], des_at[i] = q, qd
                else:
                    # the command moved on, and is that far from the reading now: a joint that only turns
                    # round slower than its command (readings repeat within one step of the field) is not
                    travel, lim = qd - des_at[i], self._stuck[i]
                    if (travel > lim or travel < -lim) and (e > lim or e < -lim):
                        return TrackingError(
                            f"its reading stays at {q:+.4f} rad while the command moved {travel * 1e3:+.0f} mrad "
                            f"(limit {self._stuck[i] * 1e3:.0f} mrad): a frozen encoder or a blocked joint; the arm "
                            "was damped and disabled", error=travel, limit=self._stuck[i], joint=j.name,
                            fix="check the joint moves freely and the encoder (power-cycle the driver); raise "
                                "stuck_travel only if the joint is sound")
        return None

    def _check_replies(self, now: float) -> SafetyStop | None:
        """Every REPLY_WINDOW s: a joint that answered more frames than it was sent is not alone on its ID,
        and one that rejected many replies hears another node."""
        for j, r0 in zip(self.joints, self._rejected_start, strict=True):
            if j.rejected - r0 >= IMPLAUSIBLE_PER_WINDOW:
                return ImplausibleFeedback(
                    f"{j.rejected - r0} replies in {REPLY_WINDOW:g} s claimed positions it cannot have reached (the "
                    f"last {j.last_rejected:+.4f} rad; the arm was at {j.state.position:+.4f} rad); the arm was damped "
                    "and disabled", value=j.last_rejected, limit=j.max_speed, count=j.rejected - r0, joint=j.name,
                    fix="another node sends replies with this driver ID: find it (candump), or give the motors "
                        "distinct IDs")
        for k, i in enumerate(self._answering):
            j = self.joints[i]
            r0, s0 = self._window_start[k]
            replies, sent = j.frames_received - r0, j.frames_sent - s0
            if replies > sent + max(3, sent // 20):
                return self.foreign_stop(j, "replies", f"{replies} replies to {sent} frames in {REPLY_WINDOW:g} s")
        self._window_end = now + REPLY_WINDOW
        self._window_start = [(self.joints[i].frames_received, self.joints[i].frames_sent) for i in self._answering]
        self._rejected_start = [j.rejected for j in self.joints]
        return None

    @staticmethod
    def foreign_stop(j: Joint, kind: str, detail: str = "") -> ForeignTraffic:
        """The stop for a frame of ``kind`` another node sent to ``j`` (``"replies"``: surplus replies, as
        ``detail`` counts them)."""
        what = {
            "exit": "another program sent it EXIT (disabled it)",
            "enter": "another program sent it ENTER",
            "zero": "another program sent it ZERO (moved its zero)",
            "command": "another program is sending it commands (a second controller on the bus)",
            "replies": f"it answers more frames than it was sent ({detail}): a second motor with the same CAN ID, "
                       "or another node sending replies as it",
        }[kind]
        return ForeignTraffic(f"{what}; the arm was damped and disabled", kind=kind, joint=j.name, fix=_FIX_FOREIGN)


def contact_delay(first_sent: float, first_reply: float, period: float) -> float:
    """The delay between a joint's first command and its first reply, s, as the loop sees it: the
    reply to a frame sent in one cycle is read at the start of a later one, so one period is the
    loop's own and not counted."""
    return max(0.0, first_reply - first_sent - period)
