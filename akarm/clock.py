"""Clocks: the wall clock for hardware, and a stepped clock for lock-step simulation.

The control loop never calls ``time`` directly; it asks its :class:`Clock` for ``now()`` and to
``sleep_until(deadline)``. With a :class:`RealClock` that sleeps (then spins the last stretch). With
a :class:`SteppedClock` sleeping *is* simulating: every participant attached to the clock (the
simulator) is advanced to the deadline first, so the controller and the simulated arm run in lock
step, as fast as the CPU allows, and identically on a loaded machine.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Protocol

__all__ = ["Clock", "RealClock", "SteppedClock", "SteppedLoop", "WakeLateness"]

_yield = getattr(os, "sched_yield", lambda: time.sleep(0))  # (Windows has no sched_yield)
_NAP_SHARE = 0.1  # of the wait between cycles, slept by a busy real-time loop (throttling needs > 5 %)


def _realtime_thread() -> bool:
    """True when the calling thread runs under a real-time policy (SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)  # type: ignore[attr-defined,unused-ignore]
    except (AttributeError, OSError):
        return False


class Clock(Protocol):
    """What the control loop needs of time. Seconds, monotonic."""

    #: True when time only advances through :meth:`sleep_until` (lock-step simulation).
    stepped: bool

    def now(self) -> float:
        """The current time, s."""
        ...

    def sleep_until(self, t: float) -> None:
        """Return at (or just after) time ``t``, s. Returns at once if ``t`` has passed."""
        ...


class WakeLateness:
    """How late ``time.sleep`` wakes, tracked, and so how long a sleeping loop must spin before its
    deadline: the spin covers the lateness of half the wake-ups (its median, tracked), never more
    than ``max_spin``, and none at all once wake-ups come later than ``give_up``: a machine that
    wakes a sleeper that late cannot keep the spin either (the cycle is late anyway and the spin
    would only burn the CPU the loop is short of).

    The median, not a high percentile: the other half of the wake-ups start their cycle late by
    what they exceed it by, a few tens of µs, while a spin long enough for the tail is paid every
    cycle. For arm6 at 480 Hz here (the loop thread with 1 µs of timer slack) the 95th percentile
    cost 26-32 µs more CPU per cycle than the median, for a lateness p99 of 40-57 µs instead of
    48-83 µs (a period is 2083 µs).

    The estimate moves by ``step`` per wake-up: up by ``QUANTILE`` of it when a wake-up came later
    than the estimate, down by the rest when not (a stochastic quantile: it settles where a share
    ``1 - QUANTILE`` of wake-ups are later), so it follows a change of load within a few hundred cycles.
    """

    QUANTILE = 0.5

    def __init__(self, max_spin: float = 200e-6, give_up: float = 1e-3, step: float = 4e-6) -> None:
        self.max_spin = max_spin
        self.give_up = give_up
        self.step = step
        #: the tracked median (:attr:`QUANTILE`) of how late a sleep woke, s (from the old fixed spin)
        self.estimate = max_spin

    def spin(self) -> float:
        """s to spin before a deadline (the sleep ends that long before it)."""
        e = self.estimate
        if e > self.give_up:
            return 0.0
        return e if e < self.max_spin else self.max_spin

    def woke(self, late: float) -> None:
        """A sleep woke ``late`` s after it should have."""
        if late > self.estimate:
            self.estimate += self.QUANTILE * self.step
        elif self.estimate > 0.0:
            self.estimate -= (1.0 - self.QUANTILE) * self.step


class RealClock:
    """Wall-clock time (``perf_counter``): sleeps to a little before a deadline, then spins.

    Sleeping to an absolute deadline does not drift; the final spin removes the timer slack of
    ``time.sleep`` (about 0.06-0.1 ms on Linux) at the cost of that much CPU per cycle. With
    ``adaptive`` (the default) the spin is only as long as the measured wake-up lateness needs
    (:class:`WakeLateness`: at most ``spin``, none on a machine that wakes sleepers later than 1 ms);
    without, always ``spin``.

    ``busy=True`` hardly sleeps: between cycles the thread keeps its core, yielding it (and the
    interpreter lock) to the process's other threads at every turn until the last ``spin`` seconds.
    A thread with real-time priority first naps for a tenth of the wait, which keeps it clear of the
    kernel's real-time throttling and lets lower-priority threads of its core run. It costs most of
    a core, and buys a loop whose caches stay warm: a core that sleeps between cycles starts each
    one cold (and on a virtual machine may have been given away meanwhile), which on our 2-core
    machines makes the cycle's work about 1.5 times slower.

    Attributes:
        wake: the wake-up lateness tracked (``None`` unless adaptive and sleeping).
    """

    stepped = False

    def __init__(self, spin: float = 200e-6, busy: bool = False, adaptive: bool = True) -> None:
        self.spin = spin
        self.busy = busy
        self.wake = WakeLateness(spin) if adaptive and not busy else None

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        pc = time.perf_counter
        remaining = t - pc()
        if self.busy:
            yield_until = t - self.spin
            if _realtime_thread() and remaining > 0.0:
                # a real-time thread that never sleeps is stopped by the kernel's RT throttling (for
                # 50 ms a second by default) and starves the other threads of its core: nap for a
                # tenth of the wait first, right after the cycle, when the next one is furthest away
                time.sleep(_NAP_SHARE * remaining)
            while pc() < yield_until:
                _yield()  # releases the interpreter lock: the process's other threads run
        else:
            wake = self.wake
            spin = self.spin if wake is None else wake.spin()
            if remaining > spin:
                time.sleep(remaining - spin)
                if wake is not None:
                    wake.woke(pc() - (t - spin))
        while pc() < t:
            pass


class SteppedLoop(Protocol):
    """A control loop that runs on a :class:`SteppedClock` beside others (:meth:`SteppedClock.join`)."""

    def due(self) -> float | None:
        """The time of its next cycle, or ``None`` while it has none to run (or is running one now)."""
        ...

    def run_due(self, now: float) -> None:
        """Run its cycle if one is due at ``now`` (the clock's time already is ``now``)."""
        ...


class SteppedClock:
    """Simulated time that advances only when someone sleeps.

    ``sleep_until(t)`` first calls every attached stepper with ``t`` (each advances its own state to
    time ``t``: the simulator integrates its plant and answers the frames it has received), then
    sets the time to ``t``.

    Several simulators and several control loops may share one clock (two arms in one process, a
    leader and a follower): every simulator is a stepper, and every control loop *joins* the clock
    (:meth:`join`). Whoever sleeps, time then stops at each joined loop's next cycle on the way to
    ``t``, and that loop runs its cycle there: each loop keeps its own grid, whichever of them (or
    the test) advances the clock, as loops in threads of their own would on a real clock.
    """

    stepped = True

    def __init__(self, start: float = 0.0) -> None:
        self._t = start
        self._steppers: list[Callable[[float], None]] = []
        self._loops: list[SteppedLoop] = []

    def attach(self, stepper: Callable[[float], None]) -> None:
        """Call ``stepper(t)`` whenever the clock advances to ``t``."""
        self._steppers.append(stepper)

    def detach(self, stepper: Callable[[float], None]) -> None:
        """Stop calling ``stepper``."""
        if stepper in self._steppers:
            self._steppers.remove(stepper)

    def join(self, loop: SteppedLoop) -> None:
        """Run ``loop``'s cycles whenever they come due, whoever advances the clock."""
        if loop not in self._loops:
            self._loops.append(loop)

    def leave(self, loop: SteppedLoop) -> None:
        """Stop running ``loop``'s cycles (it stopped)."""
        if loop in self._loops:
            self._loops.remove(loop)

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> None:
        while t > self._t:
            step = t
            for loop in self._loops:  # the next cycle of another loop on the way: stop there first
                due = loop.due()
                if due is not None and self._t < due < step:
                    step = due
            for stepper in list(self._steppers):
                stepper(step)
            self._t = step
            for loop in list(self._loops):
                loop.run_due(step)

    def sleep(self, dt: float) -> None:
        """Advance by ``dt`` seconds."""
        self.sleep_until(self._t + dt)

    def stall(self, dt: float) -> None:
        """Advance by ``dt`` seconds with no joined loop running a cycle on the way (the simulators
        step): the controlling process stopped, as a long GC, SIGSTOP or a loaded machine stops it.
        The loops resume at the next advance, late, as they would on a real clock."""
        t = self._t + dt
        for stepper in list(self._steppers):
            stepper(t)
        self._t = t
