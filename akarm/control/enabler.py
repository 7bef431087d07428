"""Enabling without a kick: listen, make contact, settle, then ramp the gains up.

1. **Listen.** Before anything is sent, frames another node sent our joints in the last
   :data:`FOREIGN_RECENT` s refuse the enable (:meth:`Enabler.refuse_foreign`): another controller
   must not lose its arm to us. The controller listens :data:`LISTEN` s after opening the buses.
2. **Contact** (:meth:`Enabler.step`, every cycle): ENTER, then a zero-gain, zero-torque command
   each cycle, until every joint gave :data:`CONTACT_REPLIES` consecutive replies that agree (the
   gate in :mod:`akarm.control.joints`; when the replies after the first one all disagree with it,
   the first one was the odd one out and contact starts over from the next, or from the second of two
   that agree with each other: :attr:`Joint.adopting`), and, for joints that
   answer every frame, a first reply within the joint's feedback timeout of the first frame: a
   constant delay is visible only here, where the stream of replies starts.
3. **Settle**: damping (kp = 0, the joint's damping, gravity feed-forward at the measured pose)
   until every joint is slower than the settle speed; then the arm is at rest and is held there.
   A real unit whose motor gives less than its model says (0.5-1 N·m per N·m reported), or whose
   links are heavier, is not carried by the model's gravity: damped, it falls (a weak arm6 fell 1.9 rad
   in 3 s and was refused with NotSettled, disabled). Each joint's gravity feed-forward is therefore
   scaled by a factor that rises while the joint moves the way gravity pulls it and falls while it
   moves against it (:data:`CATCH_RATE` per s at the settle speed and beyond, within 1 and
   :data:`CATCH_MAX`): the arm is caught where it is, and a hand that moves it is not resisted more than
   by the damping and that share of its weight.
4. **Ramp** (:class:`GainRamp`): kp rises from zero over the enable ramp once the arm is held.

Contact, and the first cycle that carries the arm after it, run at ``contact_period`` (a timing profile's
``contact_rate_hz``) where the loop's own period is longer, for at most :data:`CONTACT_BURST` s
(:meth:`Enabler.hurry`: extra cycles between the loop's): until contact is made the drivers are limp, and
an arm carrying weight falls with the square of that time. At 25 Hz (the ``slow`` profile) contact took
three cycles, 120 ms; at 500 Hz 6 ms.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from akarm.buses.bus import no_answer_hint, polled
from akarm.config import BusConfig
from akarm.control.joints import Joint
from akarm.control.safety import Supervisor, contact_delay
from akarm.errors import (
    AkarmError,
    DuplicateCanId,
    FeedbackTimeout,
    ForeignTraffic,
    ModeMismatch,
    NotSettled,
    StaleFeedback,
    StatusRateLow,
    WiringError,
)

if TYPE_CHECKING:
    import can
    import numpy as np

__all__ = ["AT_REST", "CATCH_MAX", "CATCH_RATE", "CONTACT_BURST", "CONTACT_REPLIES", "FOREIGN_RECENT", "LISTEN",
           "Enabler", "GainRamp", "Refusal"]

CONTACT_REPLIES = 2  #: consistent replies in a row that establish contact with a joint
LISTEN = 0.02  #: s the loop listens to a bus before the first enable (a controller at 50 Hz or more shows)
FOREIGN_RECENT = 0.5  #: s: foreign frames this recent refuse an enable
AT_REST: Final = "at rest"  #: what :meth:`Enabler.step` returns once the arm is at rest: hold it
#: s from an enable's first frames during which its cycles may come at the contact period (:meth:`Enabler.hurry`):
#: contact takes about 6 ms there; a joint that answers later is waited for at the loop's own
#: period (a slow machine's CPU is not spent on more cycles than that)
CONTACT_BURST = 0.2
#: per s: how fast a joint's gravity factor rises while settling, moving the way gravity pulls it at the
#: settle speed or faster (slower: in proportion), and falls while it moves against gravity
CATCH_RATE = 2.0
#: the largest gravity factor while settling (a unit giving 0.5 N·m per N·m reported, its links 20 %
#: heavier, needs 2.4 times the model's gravity torque)
CATCH_MAX = 2.5


@dataclass(frozen=True)
class Refusal:
    """An enable that failed: why, and whether exit frames must go out (something was sent)."""

    error: AkarmError
    release: bool = True


@dataclass
class _Attempt:
    """Where one enable is."""

    t0: float
    timeout: list[float]  # s per joint to make contact
    received0: list[int]  # frames_received per joint when the enable began
    sent0: list[int]  # frames_sent per joint when the enable began
    rejected0: list[int]  # replies rejected (implausible) per joint when the enable began
    first_reply: list[float | None]
    entered: bool = False
    first_sent: float = 0.0  # when the first frames (ENTER) went out
    second: float | None = None  # when the cycle after it ran (a reply to them is read there at the soonest)
    settling_since: float | None = None  # contact made with every joint; damping since
    catch: list[float] | None = None  # per joint, the factor on its gravity feed-forward while settling


class Enabler:
    """Steps 1 to 3 of the module's docstring, one cycle at a time.

    Args:
        joints: the joints, config order.
        buses: the robot's buses by name (for the hint when a joint does not answer).
        send: ``send(joint, frame)``: the bus set's.
        supervisor: its checks run while settling; it is armed when contact begins.
        gravity: ``gravity(q)``: each joint's gravity torque at ``q``, N·m, clamped to its limit.
        commanded: ``commanded(now, q, tau)``: what the arm was told this cycle (damped at ``q``
            with ``tau`` feed-forward), for telemetry and a stop's fade.
        damping: N·m·s/rad per joint while settling. timeouts: s per joint, its feedback timeout.
        period: s, the loop's. settle_speed: rad/s. settle_timeout: s.
        lag: s a reading may trail on this machine (the timing profile's).
        at_contact: ``at_contact(now)`` once every joint answered, before anything with gains or
            torque is sent: the error refusing the enable, or ``None`` (the turn check).
        contact_period: s between the cycles of contact (at most :data:`CONTACT_BURST` s of
            them) where it is shorter than ``period``: the loop runs extra cycles (:meth:`hurry`).
    """

    def __init__(self, joints: Sequence[Joint], buses: Mapping[str, BusConfig],
                 send: Callable[[Joint, can.Message], object], supervisor: Supervisor,
                 gravity: Callable[[Sequence[float]], np.ndarray],
                 commanded: Callable[[float, Sequence[float], list[float]], None], *,
                 damping: Sequence[float], timeouts: Sequence[float], period: float, settle_speed: float,
                 settle_timeout: float, at_contact: Callable[[float], AkarmError | None] | None = None,
                 lag: float = 0.0, contact_period: float | None = None) -> None:
        self.joints = list(joints)
        self.n = len(self.joints)
        self._buses = buses
        self._send = send
        self._supervisor = supervisor
        self._gravity = gravity
        self._commanded = commanded
        self._damping = list(damping)
        self.timeouts = list(timeouts)
        self.period = period
        self.settle_speed = settle_speed
        self.settle_timeout = settle_timeout
        self._attempt: _Attempt | None = None
        self._at_contact = at_contact
        self.lag = lag
        self.contact_period = contact_period if contact_period is not None and contact_period < period else None

    @property
    def under_way(self) -> bool:
        return self._attempt is not None

    def refuse_foreign(self, now: float, since: float) -> ForeignTraffic | None:
        """The error refusing an enable when another node sent our joints frames since ``since`` (s)."""
        other = self._supervisor.foreign_since(since)
        if other is None:
            return None
        j, kind = other
        error = ForeignTraffic(f"another program sent it a frame ({kind}) {max(0.0, now - j.foreign_at):.2f} s ago: "
                               "two controllers on one bus; nothing was enabled", kind=kind, joint=j.name,
                               fix="stop the other controller (or akarm serve) first, or use it instead")
        error.at = now
        return error

    def begin(self, now: float, timeout: float) -> float:
        """Start an enable at ``now``: ``timeout`` s for each joint's replies (servo joints: at least
        their status frames' time). Returns the longest time contact may take, s."""
        for j in self.joints:
            j.begin_contact()
        contact = []
        for j in self.joints:
            t = timeout
            if not j.answers_commands and j.config.status_rate_hz > 0:  # status frames at their own rate
                t = max(t, (CONTACT_REPLIES + 0.5) / j.config.status_rate_hz)
            contact.append(t)
        for j in self.joints:
            j.mode_seen = None
        self._attempt = _Attempt(now, contact, [j.frames_received for j in self.joints],
                                 [j.frames_sent for j in self.joints], [j.rejected for j in self.joints],
                                 [None] * self.n)
        self._supervisor.arm(now)
        return max(contact)

    def hurry(self, now: float) -> float | None:
        """s to the next cycle the enable under way wants (sooner than the loop's period: the contact
        period, within :data:`CONTACT_BURST` s of its first frames, or before them), or ``None`` (the
        loop's own). Contact, and the first cycle after it, which carries the arm: settling goes on at the
        loop's period (the supervisor's checks count commands, and a watchdog of K commands must not
        shrink to K contact periods)."""
        en = self._attempt
        if en is None or self.contact_period is None or (en.entered and now - en.first_sent >= CONTACT_BURST):
            return None
        if en.settling_since is not None and en.settling_since < now:
            return None
        return self.contact_period

    def abandon(self) -> None:
        """Forget the enable under way (a stop took over)."""
        self._attempt = None
        self._contact_made()

    def step(self, now: float) -> Refusal | str | None:
        """One cycle of the enable: ``None`` while under way, :data:`AT_REST` once the arm is at rest
        (hold it), or the :class:`Refusal` that ends it."""
        en = self._attempt
        if en is None:
            return None
        out = self._contact(en, now) if en.settling_since is None else self._settle(en, now)
        if out is not None:
            self._attempt = None
            self._contact_made()
        return out

    def _contact_made(self) -> None:
        """Contact is over (made, or the enable ended): a reply that disagrees with the reference is
        implausible from now on, never a new reference (:attr:`Joint.adopting`)."""
        for j in self.joints:
            j.adopting = False

    def _settle(self, en: _Attempt, now: float) -> Refusal | str | None:
        assert en.settling_since is not None
        js = self.joints
        stop = self._supervisor.check(now)
        if stop is not None:
            return Refusal(stop)
        q = [j.state.position for j in js]
        g = self._gravity(q).tolist()
        catch = en.catch
        if catch is None:
            catch = en.catch = [1.0] * self.n
        step = CATCH_RATE * self.period
        for i, j in enumerate(js):  # (see the module's docstring: a weak unit falls on the model's gravity)
            falling = -j.state.velocity if g[i] > 0.0 else j.state.velocity  # > 0: the way gravity pulls it
            share = max(-1.0, min(1.0, falling / self.settle_speed))
            catch[i] = max(1.0, min(CATCH_MAX, catch[i] + step * share))
            g[i] *= catch[i]
        for i, j in enumerate(js):
            self._send(j, j.damp(self._damping[i], g[i]))
        self._commanded(now, q, g)
        fastest = max(range(self.n), key=lambda i: abs(js[i].state.velocity))
        speed = abs(js[fastest].state.velocity)
        if speed < self.settle_speed:  # at rest (with gravity carried, a swing only decays): hold here
            return AT_REST
        if now - en.settling_since > self.settle_timeout:
            stop = NotSettled(f"still moving at {speed:.2f} rad/s after {self.settle_timeout:.1f} s of damping (it "
                              f"must come below {self.settle_speed:.2f} rad/s before it is held); nothing was held, "
                              "the arm was disabled", speed=speed, limit=self.settle_speed, joint=js[fastest].name,
                              fix="let the arm come to rest (support it) and enable again; raise settle_timeout "
                                  "for an arm that swings for long")
            stop.at = now
            return Refusal(stop)
        return None

    def _contact(self, en: _Attempt, now: float) -> Refusal | None:
        refused = self.refuse_foreign(now, en.t0 - FOREIGN_RECENT)
        if refused is not None:  # before anything is sent: another controller must not lose its arm to us
            return Refusal(refused, release=en.entered)
        miswired = self._miswired(en, now)
        if miswired is not None:
            return miswired
        self._send_contact_frames(en, now)
        ready = True
        late: list[Joint] = []
        for i, j in enumerate(self.joints):
            stale = self._note_first_reply(en, i, j, now)
            if stale is not None:
                return stale
            if j.rejected_run >= 2:  # the reference disagrees with every reply since: it was the odd one
                j.rebase()
            if j.accepted_run < CONTACT_REPLIES or j.state.stamp <= j.adopted_at:  # (see Joint.adopted_at)
                ready = False
                if now - en.t0 > en.timeout[i]:
                    late.append(j)
            elif not self._heard_long_enough(en, i, j, now):
                ready = False
        if late:
            return self._silent(en, late, now)
        if ready:
            wrong = self._at_contact(now) if self._at_contact is not None else None
            if wrong is not None:  # only zero-gain, zero-torque commands were sent: nothing moved
                return Refusal(wrong)
            en.settling_since = now
            self._contact_made()
        return None

    def _miswired(self, en: _Attempt, now: float) -> Refusal | None:
        """A wiring mistake what came in so far shows (:func:`wiring_error`), before anything with
        gains or torque was sent; counted from the first frame sent."""
        if not en.entered:
            return None
        for i, j in enumerate(self.joints):
            first = en.first_reply[i]
            plausible = j.frames_received - en.received0[i] - (j.rejected - en.rejected0[i])
            error = wiring_error(j, plausible, j.frames_sent - en.sent0[i], None if first is None else now - first,
                                 self.lag, polled=polled(self._buses[j.bus]))
            if error is not None:
                error.at = now
                return Refusal(error, release=en.entered)
        return None

    @staticmethod
    def _heard_long_enough(en: _Attempt, i: int, j: Joint, now: float) -> bool:
        """Servo joints are listened to for two status periods from their first frame, so that their
        frames can be counted (:func:`wiring_error`: a second motor, a low rate)."""
        rate = j.config.status_rate_hz
        first = en.first_reply[i]
        return j.answers_commands or rate <= 0 or (first is not None and now - first >= 2.0 / rate - 1e-9)

    def _send_contact_frames(self, en: _Attempt, now: float) -> None:
        """ENTER once, then every cycle a zero-gain, zero-torque command: it overrides the command the
        driver remembers and asks for a reply."""
        if en.entered and en.second is None:
            en.second = now
        if not en.entered:  # count from here: what came before cannot answer our frames
            en.received0 = [j.frames_received for j in self.joints]
            en.rejected0 = [j.rejected for j in self.joints]
            en.sent0 = [j.frames_sent for j in self.joints]
            for j in self.joints:
                for f in j.enter_frames():
                    self._send(j, f)
                if not polled(self._buses[j.bus]):  # (a serial port carries one servo motor, no MIT)
                    for f in j.mode_query_frames():
                        self._send(j, f)
            en.entered = True
            en.first_sent = now
        for j in self.joints:
            msg = j.neutral()
            if msg is not None:
                self._send(j, msg)

    def _note_first_reply(self, en: _Attempt, i: int, j: Joint, now: float) -> Refusal | None:
        """Note when joint ``i`` first answered; a first answer later than its feedback timeout is stale."""
        if en.first_reply[i] is not None or j.frames_received <= en.received0[i]:
            return None
        en.first_reply[i] = now
        # (the loop's own part: to the cycle after the first frames, the soonest a reply to them is read)
        own = self.period if en.second is None else en.second - en.first_sent
        delay = contact_delay(en.first_sent, now, own)
        if not (j.answers_commands and delay > self.timeouts[i]):
            return None
        stop = StaleFeedback(
            f"its first reply came {delay * 1e3:.0f} ms after the first frame (limit "
            f"{self.timeouts[i] * 1e3:.0f} ms): replies arrive late; nothing was enabled",
            age=delay, limit=self.timeouts[i], joint=j.name,
            fix="a CAN adapter or bus that queues frames (check the bus load with akarm check, the "
                "adapter's latency, other traffic); raise feedback_timeout only if the delay is known "
                "and harmless")
        stop.at = now
        return Refusal(stop)

    def _silent(self, en: _Attempt, late: list[Joint], now: float) -> Refusal:
        """The joints that gave no (or too few consistent) replies within their timeout."""
        limit = en.timeout[late[0].index]
        for j in late:  # answers at two positions, one of them rejected each time: two motors on one ID
            i = j.index
            replies, sent = j.frames_received - en.received0[i], j.frames_sent - en.sent0[i]
            if j.answers_commands and sent >= 4 and replies >= 1.5 * sent:
                c = j.config
                twin = DuplicateCanId(f"{replies} replies to {sent} frames on CAN ID {c.can_id} on bus {c.bus!r}, at "
                                      "two positions: two motors answer on this ID; nothing was enabled",
                                      can_id=c.can_id, joint=j.name,
                                      fix="give each motor its own CAN ID (akarm scan lists them), then enable again")
                twin.at = now
                return Refusal(twin)
        heard = [j for j in late if j.frames_received > en.received0[j.index]]
        names = ", ".join(j.name for j in late)
        if heard:
            what = f"no {CONTACT_REPLIES} consistent replies within {limit * 1e3:.0f} ms from: {names}"
        else:
            what = f"no answer within {limit * 1e3:.0f} ms from: {names}"
        silent = FeedbackTimeout(f"{what}; nothing was enabled", age=now - en.t0, limit=limit,
                                 joint=late[0].name, fix=no_answer_hint(self._buses[late[0].bus]))
        silent.at = now
        return Refusal(silent)


def wiring_error(j: Joint, heard: int, sent: int, since_first: float | None, lag: float = 0.0, *,
                 polled: bool = False) -> WiringError | None:
    """What contact shows of a wiring mistake on joint ``j``: ``heard`` plausible frames from it (the
    gate's rejects are implausible traffic, the supervisor's) and ``sent`` to it since the enable
    began, the first heard ``since_first`` s ago (``None``: none yet).

    - MIT: servo status frames on its ID (:class:`~akarm.errors.ModeMismatch`); more replies than
      frames (every frame gets one reply from one motor: :class:`~akarm.errors.DuplicateCanId`).
    - Servo: MIT replies on its ID, answering the MIT query sent at contact
      (:class:`~akarm.errors.ModeMismatch`); more status frames than one motor sends at the configured
      rate (two motors), or, once
      two periods of the configured rate have passed, fewer than a third of them
      (:class:`~akarm.errors.StatusRateLow`, naming the measured rate). ``lag``: s a reading may
      trail on this machine (the timing profile's): frames that late may come in one burst.
    - ``polled``: a servo motor on a serial port (one per port), whose status frames answer our polls:
      their rate is the loop's, not the motor's, and no second motor can share the port: not judged.
    """
    c = j.config
    where = f"CAN ID {c.can_id} on bus {c.bus!r}"
    if j.answers_commands:
        if j.mode_seen is not None:
            return ModeMismatch(f"configured as a MIT joint, but {where} sends servo-mode status frames: its motor "
                                "is in servo mode; nothing was enabled", can_id=c.can_id, seen=j.mode_seen,
                                joint=j.name,
                                fix="switch the motor to MIT mode (CubeMars' upper-computer tool), or configure "
                                    "the joint as `mode: servo`")
        if heard > sent + 1:  # (one reply may answer a frame sent before the enable: a stop's exit)
            return DuplicateCanId(f"{heard} replies to {sent} frames on {where}: two motors answer on this ID; "
                                  "nothing was enabled", can_id=c.can_id, joint=j.name,
                                  fix="give each motor its own CAN ID (akarm scan lists them), then enable again")
        return None
    if j.mode_seen is not None:
        return ModeMismatch(f"configured as a servo joint, but {where} answers as a MIT motor (a state reply to "
                            "the MIT query sent at contact): its motor is in MIT mode; nothing was enabled",
                            can_id=c.can_id, seen=j.mode_seen, joint=j.name,
                            fix="switch the motor to servo mode (CubeMars' upper-computer tool), or configure the "
                                "joint as `mode: mit`")
    rate = float(c.status_rate_hz)
    if since_first is None or rate <= 0 or polled:
        return None
    expected = since_first * rate + 1  # frames one motor sends from its first one to now
    if heard > 1.5 * expected + 1 + lag * rate:
        return DuplicateCanId(f"{heard} status frames in {since_first * 1e3:.0f} ms on {where}, where one motor "
                              f"at {rate:g} Hz sends {expected:.0f}: two motors answer on this ID; nothing was "
                              "enabled", can_id=c.can_id, joint=j.name,
                              fix="give each motor its own CAN ID (akarm scan lists them), then enable again")
    if since_first >= 2.0 / rate and heard >= 2 and heard < expected / 3:
        measured = (heard - 1) / since_first
        return StatusRateLow(f"its status frames come at about {measured:.1f} Hz, not the {rate:g} Hz configured "
                             f"({heard} in {since_first * 1e3:.0f} ms); nothing was enabled", can_id=c.can_id,
                             measured=measured, configured=rate, joint=j.name,
                             fix=f"set the motor's status rate to {rate:g} Hz (CubeMars' upper-computer tool), "
                                 "or status_rate_hz to what it sends")
    return None


class GainRamp:
    """Step 4: the share of kp in force, rising from 0 to 1 over ``seconds`` from :meth:`start`
    (at once with ``seconds = 0``)."""

    __slots__ = ("_t0", "scale", "seconds")

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self.scale = 0.0
        self._t0 = math.inf

    @property
    def done(self) -> bool:
        return self.scale >= 1.0

    def start(self, now: float) -> None:
        self._t0 = now
        self.scale = 0.0 if self.seconds > 0 else 1.0

    def zero(self) -> None:
        """No gains (the arm is not held)."""
        self.scale = 0.0

    def update(self, now: float) -> float:
        """The share in force at ``now``."""
        if self.scale < 1.0:
            self.scale = min(1.0, (now - self._t0) / self.seconds) if self.seconds > 0 else 1.0
        return self.scale
