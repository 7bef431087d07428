"""The safety supervisor: every cycle, decide from the joints' feedback whether the arm must stop.

The control loop asks :meth:`Supervisor.check` once per cycle while the arm is powered; a
:class:`~akarm.SafetyStop` comes back when something is wrong, and the loop then damps and
disables the arm. The supervisor only reads: the joints' latest accepted feedback and counters
(:class:`akarm.control.joints.Joint`), and the commanded positions. It needs no bus and no clock of its
own, so every check is tested by feeding it joint states.

Checks, per joint, in order (the first that fires is the stop):

1. **Foreign traffic**: another node sent one of our joints a command, ENTER, EXIT or ZERO since the
   arm was enabled (a second controller, a forgotten script, the upper computer), or a joint answers
   more frames than it was sent (a second motor with the same CAN ID, a forger): in a
   :data:`REPLY_WINDOW`, more plausible replies (those the gate passed; its rejects are check 3's) than
   the commands sent in it plus those still owed at its start (a driver that fell behind answers them
   late, in a burst), with a margin of 5 %. →
   :class:`~akarm.ForeignTraffic`.
2. **Motor error code** reported by the driver. → :class:`~akarm.MotorFault`.
3. **Implausible feedback**: the joint rejects a reply whose position it cannot have reached since
   the last good one (the gate in :mod:`akarm.control.joints`); ``implausible_limit`` in a row stop the
   arm, and so do :data:`IMPLAUSIBLE_PER_WINDOW` within any :data:`REPLY_WINDOW` (sliding: the stop comes
   with the tenth) between good ones (CAN's own CRC makes a corrupt frame rare: these come from another
   node), under every timing profile. →
   :class:`~akarm.ImplausibleFeedback`.
4. **A silent joint**, judged on what it was actually sent, never on the clock alone: a MIT joint
   that answered none of its last ``K`` commands (``K`` = its feedback timeout in loop periods, 10
   at 500 Hz with the default 20 ms), a servo joint that sent no status frame during its feedback
   timeout *of loop time* (the time the loop ran, a period per cycle at most). A gap in which the
   loop itself did not run (this process stopped or starved) sends no command and counts no time:
   it is the controller's own (:class:`~akarm.LoopStall`, decided by the controller), not the
   joint's. → :class:`~akarm.FeedbackTimeout`, naming the likelier cause first: the joint (its
   power, cable, ID) when others on its bus answer, the bus or the motors' supply when none does.
5. **A driver reset** (a brown-out): a MIT driver that answers, but reports less than a quarter of
   the torque the law it was sent asks for, where that is at least a tenth of the joint's torque
   limit, :data:`RESET_REPLIES` replies in a row (a driver out of motor mode reports no torque). →
   :class:`~akarm.DriverReset`. Where replies trail the commands (a busy machine's simulator, a
   timing profile's ``lag``), a reply is judged against every law it may answer: the commands still
   in flight (sent and not answered), at least the last ``ceil(lag / period) + 1``; it counts only if
   it fits none of them. Under a timing profile with a lag (``slow``) the replies without torque must
   also go on for :data:`RESET_LAG_TIME` s (a simulator working through a backlog, in vcan-vm, reported
   no torque where every law in flight asked for some, for moments): a driver that rebooted is a named
   stop under every profile.
6. **Temperature** over ``max_temperature``. → :class:`~akarm.OverTemperature`.
7. **Following error** (only joints that track a position: MIT with kp > 0, servo): the commanded
   minus the measured position over the joint's limit for three cycles in a row (a MIT joint: at three
   replies in a row; one that stopped answering is the watchdog's, whose stop names the silence, not
   the tracking its old reading would show); or a command
   saturated at the motor's torque range for :data:`SATURATION_TIME` while the joint is more than
   ``stuck_travel`` from it (an undersized motor: it cannot hold the arm, whatever the error); or a
   reading that repeats while the command has moved on by more than ``stuck_travel``, is more than
   that from the reading, and the motor is not saturated (a frozen encoder or a blocked joint: a
   moving joint's reading changes every step of its 16-bit field; a joint turning round more slowly
   than its command repeats its reading but stays near it; a motor at its limit is the saturation
   check's). Under a timing profile with a lag, the following-error limit grows by how far the command
   moved within the lag (a reading that trails by the lag is that far behind), nothing more: a joint
   that fell while the arm holds still is caught as on any machine; so does the stuck travel, until the
   reading has repeated for :data:`DEAD_STOP_TIME` on new replies: from then on the stuck travel grows
   only by how far the command moved within the replies the joint owes (a plant trails its commands
   only as far as its replies do; one that answers on time and repeats its reading for that long does
   not move: a frozen encoder or a blocked joint). →
   :class:`~akarm.TrackingError`.

A constant reply delay cannot be seen in feedback age (every cycle brings a reply, just an old one).
It is measured where the stream of replies starts: at enable, from the first frame sent to the
first reply (:func:`contact_delay`); a delay that starts later shows as a gap as long as itself,
which feedback age catches.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from akarm.config import JointConfig
from akarm.control.joints import Joint
from akarm.errors import (
    DriverReset,
    FeedbackTimeout,
    ForeignTraffic,
    ImplausibleFeedback,
    MotorFault,
    OverTemperature,
    SafetyStop,
    TrackingError,
)
from akarm.protocol.servo import ServoErrorCode, describe_error

if TYPE_CHECKING:
    import numpy as np

__all__ = ["Guard", "Supervisor", "default_following_error", "default_stuck_travel"]

#: Cycles in a row over the following-error limit that stop the arm (a lone sample never does).
FOLLOWING_CYCLES = 3
#: s between the comparisons of replies received with frames sent (the duplicate-responder check).
REPLY_WINDOW = 1.0
#: s of commands whose replies may still be on their way when a REPLY_WINDOW starts (at least the
#: watchdog's limit): a driver or simulator that fell behind answers them in the next window.
REPLIES_IN_FLIGHT = 0.1
#: Rejected replies of one joint within a REPLY_WINDOW that stop the arm, even between good ones.
IMPLAUSIBLE_PER_WINDOW = 10
#: s a joint's command may stay at the motor's torque range while the joint is off its target (a move
#: that asks a little too much saturates for part of its acceleration; a motor that cannot hold, for good).
SATURATION_TIME = 0.5
#: Replies in a row reporting no torque where the law asks for some that stop the arm (a driver reset).
RESET_REPLIES = 3
#: s the replies without torque must go on (besides :data:`RESET_REPLIES` of them) under a timing profile
#: whose readings lag (``slow``): longer than the oldest feedback measured there at 25 Hz (177 ms, see
#: :mod:`akarm.timing`), short enough that a driver reset stops the arm within 1 s of its power loss.
RESET_LAG_TIME = 0.3
#: s a reading must repeat on new replies, under a timing profile whose readings lag, before the stuck
#: travel stops allowing for the whole lag: longer than the oldest feedback measured there at 25 Hz
#: (177 ms; a simulator working through a backlog answers several frames with one state, in a burst),
#: short enough that a frozen encoder stops a move within 0.3 s as on a normal machine.
DEAD_STOP_TIME = 0.2
#: The share of a joint's torque limit the law must ask for before a reply without it counts.
RESET_ASK = 0.1
#: A reply "has no torque" when it reports less than this share of the motor's torque range (a driver
#: out of motor mode reports its current sensor's offset: a few tenths of a percent; the simulator 0)
#: and less than :data:`RESET_SHARE` of what the law asks for.
RESET_NONE = 0.005
#: See :data:`RESET_NONE`.
RESET_SHARE = 0.25
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
        torque_slack: rad per N·m of feed-forward the following-error limit grows by: what the PD must
            make up where the model's torque is off by its uncertainty (a real unit's torque constant,
            masses: ``uncertainty / kp``; 0: the model is taken as exact).
    """

    feedback_timeout: float
    max_temperature: float
    following_error: float = math.inf
    stuck_travel: float = math.inf
    torque_slack: float = 0.0


class Supervisor:
    """Decides, every cycle, whether the arm must stop (see the module's docstring for the checks).

    Args:
        joints: the controller's joints, in config order.
        guards: one :class:`Guard` per joint.
        implausible_limit: rejected replies in a row that stop the arm.
        period: s, the loop's period.
        lag: s a reply may trail the commands (the timing profile's ``lag``; 0: a reply answers the
            last command sent).
        driver_resets: whether to judge replies for a driver reset (check 5); the controller turns
            it off under a timing profile for machines that cannot keep time (see the check).

    Attributes:
        armed_at: clock time (s) from which foreign frames stop the arm (:meth:`arm`).
    """

    def __init__(self, joints: Sequence[Joint], guards: Sequence[Guard], *, period: float,
                 implausible_limit: int = 3, lag: float = 0.0, driver_resets: bool = True) -> None:
        if len(joints) != len(guards):
            raise ValueError("one guard per joint")
        if implausible_limit < 1:
            raise ValueError("implausible_limit must be at least 1")
        if not period > 0:
            raise ValueError("period must be positive")
        if not lag >= 0.0:
            raise ValueError("lag must be at least 0")
        self.joints = list(joints)
        self.guards = list(guards)
        #: ``(bus, silent_for) -> (cause, fix)`` when the bus is simulated and its simulator has not read
        #: it for ``silent_for`` s (it did not run in time), else None: a silent joint's stop then says so
        #: rather than blame the cables (the controller sets it)
        self.simulator_late: Callable[[str, float], tuple[str, str] | None] | None = None
        self.implausible_limit = implausible_limit
        self.period = period
        n = len(self.joints)
        self.armed_at = math.inf
        self._answering = [i for i, j in enumerate(self.joints) if j.answers_commands]
        self._mit = [j.answers_commands for j in self.joints]
        # the watchdog: per joint the frames received when last seen, and then the frames sent (MIT) or
        # the loop time (servo); the loop time counts a period per check at most (a stall is not a joint's)
        self._received = [0] * n
        self._sent_then = [0] * n
        self._ran = 0.0
        self._ran_then = [0.0] * n
        self._last_check = math.inf
        # the brown-out check: the torque a law must ask for before a reply without it counts, N·m
        self._ask = [RESET_ASK * j.config.limits.torque if driver_resets else math.inf for j in self.joints]
        # the MIT joints whose laws are kept for it (none while the check is off: nothing would read them)
        self._keeps_laws = [m and driver_resets for m in self._mit]
        self._t_max = [j.motor.t_max for j in self.joints]
        self._none = [RESET_NONE * j.motor.t_max for j in self.joints]
        self._no_torque = [0] * n
        self._no_torque_since = [0.0] * n
        self._asked = [0.0] * n  # N·m the law asked of the last reply without torque
        # a lagging machine's replies may answer laws older than those kept for a while (a simulator
        # working through a backlog): there the replies without torque must go on this long too
        self._reset_time = min(lag, RESET_LAG_TIME) if lag > 0.0 else 0.0
        self._reset: DriverReset | None = None
        # the laws a reply may answer (it trails the commands on a slow or busy machine): per MIT joint
        # the last ones sent (position, velocity, kp, kd, torque), newest last, and the frames sent
        # when the newest was taken; a reply is judged against as many as are in flight, at least the
        # profile's lag in commands
        self._lag_laws = math.ceil(lag / period - 1e-9) + 1 if lag > 0.0 else 1
        # the following-error limit under a lag grows by how far the command moved within the lag (a
        # reading that trails by the lag is that far behind): the commands of the last lag s
        self.lag = lag
        self._q_des_past: deque[list[float]] = deque(maxlen=self._lag_laws if lag > 0.0 else 1)
        self._laws: list[list[tuple[float, float, float, float, float]]] = [[] for _ in range(n)]
        self._laws_sent = [-1] * n
        self._over = [0] * n
        self._saturated_since = [math.inf] * n
        self._tracked = [False] * n
        self._last_stamp = [-math.inf] * n
        self._last_value = [math.nan] * n
        self._des_at_value = [0.0] * n
        # (under a lag) when each joint's reading last changed, and its command then
        self._changed_at = [math.inf] * n
        self._des_changed = [0.0] * n
        self._window_end = math.inf
        self._window_start: list[tuple[int, int, int]] = []
        self._rejected_start = [0] * n
        # the gate's rejects per joint: the count last seen, and when each of the last REPLY_WINDOW s came
        self._rejected_seen = [j.rejected for j in self.joints]
        self._rejected_at: list[deque[float]] = [deque() for _ in range(n)]
        self._refresh()

    def _refresh(self) -> None:
        g = self.guards
        self._timeouts = [x.feedback_timeout for x in g]
        # MIT: the commands a joint may leave unanswered, its timeout in loop periods (at least 2)
        self._unanswered = [max(2, round(x.feedback_timeout / self.period)) for x in g]
        # the laws kept per MIT joint: as many replies as may be in flight, at least the lag's
        self._laws_kept = [max(self._lag_laws, u + 1) for u in self._unanswered]
        self._max_temp = [x.max_temperature for x in g]
        self._following = [x.following_error for x in g]
        self._torque_slack = [x.torque_slack for x in g]
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
        self._q_des_past.clear()
        self._received = [j.frames_received for j in self.joints]
        self._sent_then = [j.frames_sent for j in self.joints]
        self._start_window(now)
        self._ran = 0.0
        self._ran_then = [0.0] * n
        self._last_check = now
        self._no_torque = [0] * n
        self._rejected_seen = [j.rejected for j in self.joints]
        for d in self._rejected_at:
            d.clear()

    def unanswered(self, index: int) -> int:
        """Commands sent to joint ``index`` since the last check at which it had answered (MIT; 0 for servo)."""
        j = self.joints[index]
        return j.frames_sent - self._sent_then[index] if j.answers_commands else 0

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
              saturated: Sequence[bool] | None = None,
              feedforward: Sequence[float] | np.ndarray | None = None) -> SafetyStop | None:
        """The stop the arm needs now, or ``None``.

        Args:
            now: clock time, s.
            q_des: the commanded positions this cycle (rad, config order); ``None`` skips the
                following-error checks (teach mode, enabling).
            tracking: per joint, whether it is held at ``q_des`` (MIT with kp > 0, servo).
            saturated: per joint, whether its last command asked for the motor's whole torque range
                (stiffness, damping and feed-forward together); ``None``: unknown.
            feedforward: the feed-forward torque of the last command per joint, N·m: the following-error
                limit grows by :attr:`Guard.torque_slack` times it; ``None``: not at all.
        """
        stop = self._check_joints(now)
        if stop is None and q_des is not None and tracking is not None:
            stop = self._check_following(now, q_des, tracking, saturated, feedforward)
            if isinstance(stop, TrackingError):  # off its command, and no torque where the law asks: a reset
                stop = self._reset_behind(stop) or stop
        if stop is None and self._reset is not None:
            stop = self._reset
        if stop is None and now >= self._window_end:
            stop = self._check_replies(now)
        if stop is not None:
            stop.at = now
        return stop

    def _check_joints(self, now: float) -> SafetyStop | None:  # noqa: C901 (one pass over the joints: the hot path)
        armed = self.armed_at
        limit = self.implausible_limit
        # the loop time since the last check: a period at most (a longer gap is a stall of the loop)
        dt = now - self._last_check
        self._last_check = now
        ran = self._ran = self._ran + (dt if 0.0 < dt < self.period else self.period if dt > 0.0 else 0.0)
        received, sent_then, ran_then, no_torque = self._received, self._sent_then, self._ran_then, self._no_torque
        reset: DriverReset | None = None  # decided last: a joint with a frozen reading is the following checks'
        for i, j in enumerate(self.joints):
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
            if j.rejected != self._rejected_seen[i]:
                between = self._rejected_between(i, j, now)
                if between is not None:
                    return between
            if self._keeps_laws[i] and j.frames_sent != self._laws_sent[i]:
                self._keep_law(i, j)
            r = j.frames_received
            if r != received[i]:  # it answered since the last check
                received[i] = r
                sent_then[i] = j.frames_sent
                ran_then[i] = ran
                if self._mit[i]:
                    # the reply answers the last command: a driver in motor mode reports the torque its law
                    # asks for at the state it reports; one out of it (reset by a brown-out) reports none
                    tau = j.cmd_kd * (j.cmd_velocity - s.velocity) + j.cmd_torque
                    kp = j.cmd_kp
                    if kp:
                        tau += kp * (j.cmd_position - s.position)
                    t_max = self._t_max[i]
                    tau = t_max if tau > t_max else -t_max if tau < -t_max else tau
                    mag = tau if tau >= 0.0 else -tau
                    got = s.torque if s.torque >= 0.0 else -s.torque
                    if mag >= self._ask[i] and not (got >= RESET_SHARE * mag or got > self._none[i]) and (
                            self._fits_no_older_law(i, s.position, s.velocity, got)):
                        no_torque[i] += 1
                        self._asked[i] = tau
                        if no_torque[i] == 1:
                            self._no_torque_since[i] = now
                        if no_torque[i] >= RESET_REPLIES and reset is None and (
                                now - self._no_torque_since[i] >= self._reset_time - 1e-9):
                            reset = self._reset_stop(j, tau, s.torque)
                    else:
                        no_torque[i] = 0
            elif self._mit[i]:
                if j.frames_sent - sent_then[i] >= self._unanswered[i]:
                    return self._silent_stop(i, now)
            elif ran - ran_then[i] > self._timeouts[i]:
                return self._silent_stop(i, now)
            if s.temperature is not None and s.temperature > self._max_temp[i]:
                max_temp = self._max_temp[i]
                return OverTemperature(
                    f"temperature {s.temperature:.0f} °C is above the limit {max_temp:.0f} °C; the arm was damped "
                    "and disabled", temperature=s.temperature, limit=max_temp, joint=j.name,
                    fix="let the motor cool; lower duty, speed or payload; check max_temperature in the YAML")
        self._reset = reset
        return None

    def _rejected_between(self, i: int, j: Joint, now: float) -> ImplausibleFeedback | None:
        """Joint ``i`` rejected replies since the last check: the stop once :data:`IMPLAUSIBLE_PER_WINDOW` came
        within the last :data:`REPLY_WINDOW` s, a sliding window (one that starts every second may split
        a dozen forged replies in two halves neither of which stops the arm), or ``None``."""
        times = self._rejected_at[i]
        times.extend([now] * min(j.rejected - self._rejected_seen[i], IMPLAUSIBLE_PER_WINDOW))
        self._rejected_seen[i] = j.rejected
        while times and times[0] <= now - REPLY_WINDOW:
            times.popleft()
        if len(times) < IMPLAUSIBLE_PER_WINDOW:
            return None
        return ImplausibleFeedback(
            f"{len(times)} replies within {REPLY_WINDOW:g} s claimed positions it cannot have reached "
            f"(the last {j.last_rejected:+.4f} rad; the arm was at {j.state.position:+.4f} rad); the arm was damped "
            "and disabled", value=j.last_rejected, limit=j.max_speed, count=len(times), joint=j.name,
            fix="another node sends replies with this driver ID: find it (candump), or give the motors distinct IDs")

    def _keep_law(self, i: int, j: Joint) -> None:
        """Keep joint ``i``'s last law sent (a lagging machine's replies may answer it later)."""
        self._laws_sent[i] = j.frames_sent
        laws = self._laws[i]
        laws.append((j.cmd_position, j.cmd_velocity, j.cmd_kp, j.cmd_kd, j.cmd_torque))
        if len(laws) > self._laws_kept[i]:
            del laws[0]

    def _fits_no_older_law(self, i: int, position: float, velocity: float, got: float) -> bool:
        """Whether a reply of torque magnitude ``got`` at ``position``, ``velocity`` fits none of the
        laws joint ``i`` was sent lately, those still in flight (each asks for torque it lacks): a
        reply that trails the commands answers one of them, not necessarily the last."""
        t_max, ask, none = self._t_max[i], self._ask[i], self._none[i]
        laws = self._laws[i]
        k = max(self._lag_laws, self._in_flight(i) + 1)
        for p, v, kp, kd, t in laws[-k:] if k < len(laws) else laws:
            tau = kd * (v - velocity) + t
            if kp:
                tau += kp * (p - position)
            mag = min(abs(tau), t_max)
            if mag < ask or got >= RESET_SHARE * mag or got > none:
                return False
        return True

    def _silent_stop(self, i: int, now: float) -> FeedbackTimeout:
        """The stop for joint ``i``, silent: the likelier cause first (the motor when others on its bus
        answer, the bus or the motors' supply when none does)."""
        j = self.joints[i]
        timeout = self._timeouts[i]
        age = now - j.state.stamp
        if self._mit[i]:
            k = j.frames_sent - self._sent_then[i]
            silent_for = k * self.period
            what = (f"no reply to its last {k} commands ({k * self.period * 1e3:.0f} ms of loop time; limit "
                    f"{timeout * 1e3:.0f} ms)")
        else:
            silent_for = self._ran - self._ran_then[i]
            what = (f"no status frame for {(self._ran - self._ran_then[i]) * 1e3:.0f} ms of loop time (limit "
                    f"{timeout * 1e3:.0f} ms)")
        others = [k for k, o in enumerate(self.joints) if o.bus == j.bus and k != i]
        answering = [self.joints[k].name for k in others if self._answers(k)]
        late = self.simulator_late(j.bus, silent_for) if self.simulator_late is not None else None
        if late is not None:
            cause, fix = late
        elif answering:
            cause = (f"while {', '.join(answering)} on bus {j.bus!r} answer: the likelier cause is this motor: its "
                     "power, its CAN cable or connector, its CAN ID")
            fix = ("check this motor's power and CAN connector and its CAN ID (akarm scan); if it answers again, "
                   "enable the arm")
        elif others:
            cause = (f"and no joint on bus {j.bus!r} answers: the likelier cause is the bus (the adapter, the cable "
                     "to the chain, its termination) or the motors' power supply")
            fix = "check the motors' power supply, the CAN adapter (ip link, akarm scan), the cable and termination"
        else:
            cause = (f"(the only joint on bus {j.bus!r}): the likelier cause is its power, the CAN adapter or the "
                     "cable")
            fix = "check the motor's power, the CAN adapter (ip link, akarm scan), the cable, termination and CAN ID"
        return FeedbackTimeout(f"{what}, {cause}; the arm was damped and disabled", age=age, limit=timeout,
                               joint=j.name, fix=fix)

    def _answers(self, k: int) -> bool:
        """Whether joint ``k`` answers now (at most two commands, or two periods of loop time, unanswered)."""
        j = self.joints[k]
        if self._mit[k]:
            return j.frames_sent - self._sent_then[k] <= 2
        return self._ran - self._ran_then[k] <= max(2.0 * self.period, self._timeouts[k] / 3.0)

    def _reset_behind(self, stop: TrackingError) -> DriverReset | None:
        """The :class:`DriverReset` behind a following error: its joint's last :data:`RESET_REPLIES` replies
        or more reported no torque where the law asked for some (before :data:`RESET_LAG_TIME` passed: the
        joint fell off its command meanwhile), or ``None``."""
        for i, j in enumerate(self.joints):
            if j.name == stop.joint and self._no_torque[i] >= RESET_REPLIES:
                return self._reset_stop(j, self._asked[i], j.state.torque)
        return None

    def _reset_stop(self, j: Joint, expected: float, reported: float) -> DriverReset:
        return DriverReset(
            f"its driver answers but reports {reported:+.2f} N·m where the law it was sent asks for {expected:+.2f} "
            f"N·m, {RESET_REPLIES} replies in a row: it is out of motor mode, the likelier cause a reset (a brown-out: "
            "a dip in its supply voltage, a loose power connector), else another program that made it leave without a "
            "frame on this bus; the arm was damped and disabled", expected=expected, reported=reported, joint=j.name,
            fix="check the motor's power supply and connector (its voltage under load); enable the arm again once "
                "it is sound (a driver that was reset may have lost its turn count: check the joint's position)")

    def lag_slack(self, q_des: Sequence[float]) -> list[float] | None:
        """(Under a lag) per joint, how far (rad) ``q_des`` lies from the commands of the last lag s, which
        a reading that trails by the lag may still follow; ``None`` without a lag."""
        if self.lag <= 0.0:
            return None
        past = self._q_des_past
        qd = list(q_des)
        past.append(qd)
        return [max(abs(x - p[i]) for p in past) for i, x in enumerate(qd)]

    def _check_following(self, now: float, q_des: Sequence[float], tracking: Sequence[bool],  # noqa: C901
                         saturated: Sequence[bool] | None,
                         feedforward: Sequence[float] | np.ndarray | None = None) -> SafetyStop | None:
        slack = self.lag_slack(q_des)
        over, tracked, sat_since = self._over, self._tracked, self._saturated_since
        last_stamp, last_value, des_at = self._last_stamp, self._last_value, self._des_at_value
        mit = self._mit
        for i, j in enumerate(self.joints):
            qd = q_des[i]
            if not tracking[i]:
                tracked[i] = False
                over[i] = 0
                sat_since[i] = math.inf
                continue
            s = j.state
            q = s.position
            new = s.stamp != last_stamp[i] or not mit[i]  # (MIT: a reply to the last command)
            if not tracked[i]:  # tracking starts (again): the reading's history starts here
                tracked[i] = True
                new = True
                last_stamp[i], last_value[i], des_at[i] = s.stamp, q, qd
                self._changed_at[i], self._des_changed[i] = now, qd
            e = qd - q
            limit = self._following[i] if slack is None else self._following[i] + slack[i]
            if feedforward is not None:  # the model's torque may be off by its uncertainty: the PD makes it up
                limit += self._torque_slack[i] * abs(feedforward[i])
            if e > limit or e < -limit:
                if not new:  # no reply to the last command: the watchdog's to judge
                    continue
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
            stuck = self._stuck[i] if slack is None else self._stuck[i] + slack[i]
            if sat and (e > stuck or e < -stuck):
                if sat_since[i] == math.inf:
                    sat_since[i] = now
                elif now - sat_since[i] >= SATURATION_TIME:
                    return TrackingError(
                        f"its motor has been at the end of its torque range for {(now - sat_since[i]) * 1e3:.0f} ms "
                        f"and the joint is {e * 1e3:+.0f} mrad from its command (limit {stuck * 1e3:.0f} "
                        "mrad): the motor cannot hold or move the arm; the arm was damped and disabled",
                        error=e, limit=stuck, joint=j.name,
                        fix="a motor too small for the load (akarm check shows the gravity torque per joint), a "
                            "payload heavier than configured, or a joint pressing on an obstacle")
            else:
                sat_since[i] = math.inf
            if s.stamp != last_stamp[i]:  # a new reading
                last_stamp[i] = s.stamp
                if q != last_value[i]:
                    self._changed_at[i], self._des_changed[i] = now, qd
                # under a lag, a reading repeated on new replies for DEAD_STOP_TIME stopped dead: only the
                # replies the joint owes explain how far it trails, and a saturated command is no excuse
                dead = slack is not None and now - self._changed_at[i] >= DEAD_STOP_TIME
                if q != last_value[i] or (sat and not dead):
                    last_value[i], des_at[i] = q, qd
                else:
                    # the command moved on, and is that far from the reading now: a joint that only turns
                    # round slower than its command (readings repeat within one step of the field) is not
                    travel, lim = qd - des_at[i], stuck
                    if dead:
                        travel, lim = qd - self._des_changed[i], self._stuck[i] + self._owed_slack(i, qd)
                    if (travel > lim or travel < -lim) and (e > lim or e < -lim):
                        return TrackingError(
                            f"its reading stays at {q:+.4f} rad while the command moved {travel * 1e3:+.0f} mrad "
                            f"(limit {lim * 1e3:.0f} mrad): a frozen encoder or a blocked joint; the arm "
                            "was damped and disabled", error=travel, limit=lim, joint=j.name,
                            fix="check the joint moves freely and the encoder (power-cycle the driver); raise "
                                "stuck_travel only if the joint is sound")
        return None

    def _owed_slack(self, i: int, qd: float) -> float:
        """(Under a lag) how far (rad) joint ``i``'s command ``qd`` lies from the commands its owed replies
        (and the last one) answer: as far as a plant whose replies trail that much may trail."""
        k = self._in_flight(i) + 2
        past = self._q_des_past
        return max(abs(qd - p[i]) for p in itertools.islice(past, max(0, len(past) - k), None))

    def _check_replies(self, now: float) -> SafetyStop | None:
        """Every REPLY_WINDOW s: a joint that answered more plausible frames than it was sent is not alone on
        its ID (its implausible ones are :meth:`_rejected_between`'s)."""
        for k, i in enumerate(self._answering):
            j = self.joints[i]
            r0, s0, owed = self._window_start[k]
            # the plausible replies: the gate's rejects are judged above, as implausible traffic (at 25 Hz a
            # dozen forged replies outnumber the margin and were named a second motor)
            replies = j.frames_received - r0 - (j.rejected - self._rejected_start[i])
            sent = j.frames_sent - s0
            if replies > sent + owed + max(3, sent // 20):
                return self.foreign_stop(j, "replies", f"{replies} replies to {sent} frames in {REPLY_WINDOW:g} s"
                                         + (f" and {owed} unanswered before" if owed else ""))
        self._start_window(now)
        return None

    def _in_flight(self, i: int) -> int:
        """The replies joint ``i`` may still owe: the commands sent to it that no reply answered yet (one
        reply a command), at most :data:`REPLIES_IN_FLIGHT` s of commands or its watchdog's limit, and
        the timing profile's lag on top (its replies may trail the commands by that much more: a
        simulator that fell behind answers slower than the commands come while its replies keep the
        watchdog fed, then catches up in a burst); the replies that never came, lost on the bus over
        hours, cannot hide a second motor."""
        j = self.joints[i]
        owed = j.frames_sent - j.frames_received
        cap = max(self._unanswered[i], round(REPLIES_IN_FLIGHT / self.period)) + self._lag_laws - 1
        return 0 if owed < 0 else cap if owed > cap else owed

    def _start_window(self, now: float) -> None:
        """The counts a REPLY_WINDOW starts from: per answering joint, the replies and commands so far and the
        replies still owed (they may come in this window: a driver or simulator that fell behind or paused,
        then answers what it was sent meanwhile, replies that trail the commands on a slow machine)."""
        self._window_end = now + REPLY_WINDOW
        self._window_start = [(self.joints[i].frames_received, self.joints[i].frames_sent, self._in_flight(i))
                              for i in self._answering]
        self._rejected_start = [j.rejected for j in self.joints]

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
