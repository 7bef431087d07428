"""What the arm is commanded to follow: the plan in force and the :class:`Motion` its caller holds,
or the pose it holds; and the path recorder of teach mode.

:class:`Motions` is the controller's: a request starts a plan (superseding the one in force, whose
:class:`Motion` then reports ``superseded``), the loop samples it every cycle and, at its end, holds
where it ended. A :class:`Motion` is the caller's read-only view of one plan: whether it ended, how,
and a way to wait for that. Only :class:`Motions` ends one.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from akarm.errors import AkarmError

if TYPE_CHECKING:
    from akarm.motion.trajectory import Timed

__all__ = ["Motion", "Motions", "PathRecorder", "WaitFor"]

#: ``wait_for(done, timeout, what)``: the controller's wait (running cycles in lock step; raising its fault)
WaitFor = Callable[[Callable[[], bool], float, str], None]
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
        self._wait_for(self._outcome.event.is_set, limit, f"the motion ({self.duration:.2f} s) to end")
        if self._outcome.error is not None:  # cut short without a safety stop (a collision, the arm holding)
            raise self._outcome.error
        return self


class Motions:
    """The commanded trajectory: the plan being followed (and its :class:`Motion`), else the pose held.

    Requests (:meth:`start`, :meth:`cancel`, :meth:`replace`, :meth:`hold_at`) come under the
    controller's lock; the loop calls :meth:`sample` once per cycle.
    """

    def __init__(self, n: int, wait_for: WaitFor) -> None:
        self.n = n
        self.plan: Timed | None = None
        self.hold = np.zeros(n)
        self._outcome: _Outcome | None = None
        self._wait_for = wait_for

    @property
    def moving(self) -> bool:
        """True while a plan is followed."""
        return self.plan is not None

    def running_at(self, now: float) -> bool:
        """True while a plan is followed and not yet at its end at ``now``."""
        plan = self.plan
        return plan is not None and not plan.done(now)

    def desired(self, now: float) -> State:
        """The commanded (q, dq, ddq) at ``now`` (copies)."""
        if self.plan is not None:
            return self.plan.sample(now)
        return self.hold.copy(), np.zeros(self.n), np.zeros(self.n)

    def start(self, make_plan: Callable[[State, float], Timed], now: float) -> Motion:
        """Plan from the commanded state at ``now`` (``make_plan(start, now)``) and follow it; the
        motion in force is superseded. Whatever ``make_plan`` raises leaves everything as it was."""
        plan = make_plan(self.desired(now), now)
        outcome = _Outcome()
        self._end(superseded=True)
        self.plan, self._outcome = plan, outcome
        return Motion(plan, outcome, self._wait_for)

    def sample(self, now: float) -> State:
        """The commanded state this cycle; at the end of the plan its motion ends and its last point is held."""
        plan = self.plan
        if plan is None:
            return self.hold, np.zeros(self.n), np.zeros(self.n)
        q_d, dq_d, ddq_d = plan.sample(now)
        if plan.done(now):
            self.hold = q_d.copy()
            self.plan = None
            self._end()
        return q_d, dq_d, ddq_d

    def cancel(self) -> None:
        """Follow nothing (a stop, teach mode): the motion in force is superseded."""
        self._end(superseded=True)
        self.plan = None

    def replace(self, plan: Timed, error: AkarmError) -> None:
        """Follow ``plan``, which no caller waits for (the collision reflex's stop): the motion in force
        ends with ``error``."""
        self._end(superseded=True, error=error)
        self.plan = plan

    def hold_at(self, q: np.ndarray) -> None:
        """Hold ``q`` (rad) from now on (no motion is in force: an enable, the end of teach mode)."""
        self.hold = q
        self.plan = None

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
