"""What the arm is commanded to follow: the plan in force and the :class:`Motion` its caller holds,
or the pose it holds; and the path recorder of teach mode.

:class:`Motions` is the controller's: a request puts a plan in (superseding the one in force, whose
:class:`Motion` then reports ``superseded``), planned outside the controller's lock from a
:class:`Ticket`; the loop samples it every cycle and, at its end, holds where it ended. A
:class:`Motion` is the caller's read-only view of one plan: whether it ended, how, and a way to wait
for that. Only :class:`Motions` ends one.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from akarm.errors import AkarmError
from akarm.motion.trajectory import Timed

__all__ = ["Motion", "Motions", "PathRecorder", "Ticket", "WaitFor"]


class WaitFor(Protocol):
    """The controller's wait (running cycles in lock step; raising its fault): until ``done()``,
    woken by ``wake`` (:meth:`akarm.control.controller.Controller.wait_for`)."""

    def __call__(self, done: Callable[[], bool], timeout: float, what: str, *,
                 wake: threading.Event | None = None) -> None: ...


#: (q, dq, ddq): a commanded state, rad, rad/s, rad/s²
State = tuple[np.ndarray, np.ndarray, np.ndarray]


class _Outcome:
    """How a motion ended, set once by :class:`Motions`."""

    __slots__ = ("error", "event", "superseded")

    def __init__(self) -> None:
        self.event = threading.Event()
        self.superseded = False
        self.error: AkarmError | None = None

    def end(self, superseded: bool, error: AkarmError | None) -> None:
        self.superseded = superseded
        self.error = error
        self.event.set()


class Motion:
    """A motion the arm is executing (returned by :meth:`Arm.move_to` and friends).

    Attributes:
        plan: the planned trajectory. duration: its length, s.
    """

    def __init__(self, plan: Timed, outcome: _Outcome, wait_for: WaitFor) -> None:
        self.plan = plan
        self.duration = plan.duration
        self._outcome = outcome
        self._wait_for = wait_for

    @property
    def done(self) -> bool:
        """True once the motion has ended (or was replaced by another, or the arm stopped)."""
        return self._outcome.event.is_set()

    @property
    def superseded(self) -> bool:
        """True when another motion (or a stop) replaced it before its end."""
        return self._outcome.superseded

    @property
    def error(self) -> AkarmError | None:
        """What cut it short without a safety stop (a collision with the "hold" reaction), or ``None``."""
        return self._outcome.error

    def wait(self, timeout: float | None = None) -> Motion:
        """Block until the motion has ended; raise the arm's :class:`~akarm.SafetyStop` if it stopped.

        ``timeout`` is in s of the arm's clock; ``None`` waits for the motion's duration plus a margin.
        """
        limit = self.duration + 5.0 if timeout is None else timeout
        event = self._outcome.event
        self._wait_for(event.is_set, limit, f"the motion ({self.duration:.2f} s) to end", wake=event)
        if self._outcome.error is not None:  # cut short without a safety stop (a collision, the arm holding)
            raise self._outcome.error
        return self


@dataclass(frozen=True)
class Ticket:
    """What a plan must start from to take over (:meth:`Motions.ticket`): the commanded state ``state``
    at plan time ``t`` (s), as it was when the ticket was taken (``generation``), and ``static_from``:
    the plan time from which that state no longer changes (``-inf``: the arm holds; ``inf``: it moves
    on), so that a plan from it may start any time after that."""

    generation: int
    t: float
    state: State
    static_from: float


class _Next:
    """A plan waiting to take over at plan time ``at`` (s), with its caller's outcome."""

    __slots__ = ("at", "outcome", "plan")

    def __init__(self, at: float, plan: Timed, outcome: _Outcome) -> None:
        self.at, self.plan, self.outcome = at, plan, outcome


class Motions:
    """The commanded trajectory: the plan being followed (and its :class:`Motion`), else the pose held,
    and the plans waiting to take over from it.

    Times are the controller's *plan time* (s): its clock, less the slots its loop missed (a stalled
    loop resumes where its plan was, rather than jumping ahead).

    A new plan is made in two steps, so that planning never holds up the loop: :meth:`ticket` says
    what it must start from (the commanded state at a plan time not yet sampled), the caller plans
    from that without any lock, and :meth:`take` puts the plan in, to take over at exactly that time,
    if nothing changed meanwhile (the same ticket ``generation``) and the loop has not yet gone past it;
    a plan from a state of rest may take over later (it is shifted in time). Else :meth:`take` returns
    ``None`` and the caller plans again, further ahead.

    Requests (:meth:`ticket`, :meth:`take`, :meth:`cancel`, :meth:`replace`, :meth:`hold_at`) come under
    the controller's lock; the loop calls :meth:`sample` once per cycle.

    Attributes:
        plan: the plan followed now (``None``: holding :attr:`hold`). hold: the pose held, rad.
        generation: counts the requests that changed what is commanded. sampled: the plan time of
            the last sample (``-inf`` before the first).
    """

    def __init__(self, n: int, wait_for: WaitFor) -> None:
        self.n = n
        self.plan: Timed | None = None
        self.hold = np.zeros(n)
        self.generation = 0
        self.sampled = -math.inf
        self._outcome: _Outcome | None = None
        self._queue: list[_Next] = []
        self._wait_for = wait_for

    @property
    def moving(self) -> bool:
        """True while a plan is followed (or waits to take over)."""
        return self.plan is not None or bool(self._queue)

    def running_at(self, t: float) -> bool:
        """True while a plan is followed (or waits) and not yet at its end at plan time ``t``."""
        if self._queue:
            return True
        plan = self.plan
        return plan is not None and not plan.done(t)

    def _source(self, t: float) -> Timed | None:
        """The plan in force at plan time ``t`` (``None``: the hold)."""
        plan = self.plan
        for nxt in self._queue:
            if t >= nxt.at:
                plan = nxt.plan
        return plan

    def desired(self, t: float) -> State:
        """The commanded (q, dq, ddq) at plan time ``t`` (copies)."""
        plan = self._source(t)
        if plan is not None:
            q, dq, ddq = plan.sample(t)
            return np.array(q, dtype=float), np.array(dq, dtype=float), np.array(ddq, dtype=float)
        return self.hold.copy(), np.zeros(self.n), np.zeros(self.n)

    def ticket(self, t: float) -> Ticket:
        """What a plan must start from to take over at plan time ``t`` (at least the last sample's)."""
        t = max(t, self.sampled)
        last = self._queue[-1].plan if self._queue else self.plan
        if last is None:
            static_from = -math.inf
        else:
            end = last.sample(last.t_end)
            at_rest = not (np.any(np.abs(end[1]) > 1e-9) or np.any(np.abs(end[2]) > 1e-9))
            static_from = last.t_end if at_rest else math.inf
        return Ticket(self.generation, t, self.desired(t), static_from)

    def take(self, ticket: Ticket, plan: Timed) -> Motion | None:
        """Put ``plan`` (planned from ``ticket``) in; ``None`` if it can no longer start where it was planned
        from (another request came between, or the loop went past ``ticket.t`` while the arm moved)."""
        if ticket.generation != self.generation:
            return None
        at = ticket.t
        if ticket.static_from <= at:  # from a state of rest: it may start at any time after that began
            at = max(ticket.static_from, self.sampled)
            if at == -math.inf:  # nothing sampled yet, and holding
                at = ticket.t
            plan = plan.shifted(at - ticket.t)
        elif self.sampled > at:
            return None
        self.generation += 1
        self._end(superseded=True)  # the motion in force (it is followed until `at`, no longer waited for)
        for nxt in self._queue:
            if nxt.at >= at:
                nxt.outcome.end(True, None)
        self._queue = [nxt for nxt in self._queue if nxt.at < at]
        outcome = _Outcome()
        self._queue.append(_Next(at, plan, outcome))
        return Motion(plan, outcome, self._wait_for)

    def sample(self, t: float) -> State:
        """The commanded state at plan time ``t`` (this cycle's); at the end of the plan its motion ends
        and its last point is held; a plan waiting for ``t`` takes over."""
        self.sampled = t
        queue = self._queue
        while queue and t >= queue[0].at:
            nxt = queue.pop(0)
            self._end(superseded=True)  # (a plan that took over before it, and waited for by its caller)
            self.plan, self._outcome = nxt.plan, nxt.outcome
        plan = self.plan
        if plan is None:
            return self.hold, np.zeros(self.n), np.zeros(self.n)
        q_d, dq_d, ddq_d = plan.sample(t)
        if plan.done(t):
            self.hold = np.array(q_d, dtype=float)
            self.plan = None
            self._end()
        return q_d, dq_d, ddq_d

    def cancel(self) -> None:
        """Follow nothing (a stop, teach mode): the motions in force or waiting are superseded."""
        self._drop()
        self.plan = None

    def replace(self, plan: Timed, error: AkarmError | None) -> None:
        """Follow ``plan`` from now, which no caller waits for (the collision reflex's stop; a guarded
        move's, ``error`` None): the motion in force ends with ``error``, those waiting are superseded."""
        self._end(superseded=True, error=error)
        self._drop()
        self.plan = plan

    def hold_at(self, q: np.ndarray) -> None:
        """Hold ``q`` (rad) from now on (no motion is in force: an enable, the end of teach mode)."""
        self._drop()
        self.hold = q
        self.plan = None

    def _drop(self) -> None:
        """Whatever is in force or waits is superseded; tickets taken so far are void."""
        self.generation += 1
        self._end(superseded=True)
        for nxt in self._queue:
            nxt.outcome.end(True, None)
        self._queue = []

    def _end(self, superseded: bool = False, error: AkarmError | None = None) -> None:
        outcome, self._outcome = self._outcome, None
        if outcome is not None:
            outcome.end(superseded, error)


class PathRecorder:
    """The samples of :meth:`Arm.start_recording`, taken by the loop on a grid of ``1 / rate`` s
    from the first one; a stall skips the grid points it missed (no burst of samples after it), and
    with a duration, no sample is taken more than half a grid step past its end."""

    __slots__ = ("_last", "_next", "duration", "positions", "rate", "times")

    def __init__(self, rate: float, duration: float | None) -> None:
        self.rate, self.duration = rate, duration
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self._next = -math.inf
        self._last = math.inf

    @property
    def finished(self) -> bool:
        return self._next > self._last

    def sample(self, now: float, q: np.ndarray) -> None:
        if now < self._next - 1e-9 or self.finished:  # a nanosecond's slack: clocks sum periods
            return
        if now > self._last + 0.5 / self.rate:  # a stall across the end: that grid point is lost too
            self._next = math.inf
            return
        if not self.times:
            self._next = now
            if self.duration is not None:  # the last grid point within the duration (slack for rounding)
                self._last = now + math.floor(self.duration * self.rate + 1e-9) / self.rate + 1e-9
        self.times.append(now)
        self.positions.append(q)
        self._next += (max(0, math.floor((now - self._next) * self.rate)) + 1) / self.rate
