"""The fixed-rate control loop: absolute deadlines, skipped slots, statistics.

One cycle function is called once per period. With a real clock it runs in its own thread, sleeping
to absolute deadlines and spinning the last stretch (:class:`~akarm.clock.RealClock`); a cycle that
starts late skips the slots it missed instead of bursting frames, and counts them. With a stepped
clock there is no thread: the caller runs cycles with :meth:`ControlLoop.step`, each of which
advances simulated time to the next deadline (the simulator runs up to that instant) first. A
started loop joins its stepped clock (:meth:`~akarm.clock.SteppedClock.join`), so that several
loops on one clock (two arms in one process) each run their cycles whoever advances it.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import logging
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from akarm.clock import Clock, SteppedClock
from akarm.config import MAX_RATE_HZ, MIN_RATE_HZ
from akarm.control.cpuidle import IdleLatencyHold
from akarm.errors import ArgumentError

__all__ = ["TIMER_SLACK", "ControlLoop", "LoopStats", "StatsSummary", "collector_paused", "keep_from_collections",
           "pin_thread", "request_realtime", "set_timer_slack", "timer_slack"]

log = logging.getLogger(__name__)


def _libc() -> ctypes.CDLL:
    """The C library, for the calls Python's os module lacks (mlockall, prctl). Raises OSError (or
    TypeError where there is no C library to find)."""
    return ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)


def request_realtime(priority: int = 80, lock_memory: bool = True, switch_interval: float | None = None) -> str:
    """Ask for SCHED_FIFO for the calling thread, lock the process's memory, and keep Python's own
    pauses short: the garbage collector stops re-scanning the objects that exist now (``gc.freeze``:
    a full collection of a process with Pinocchio and numpy loaded takes milliseconds), and, if
    ``switch_interval`` (s) is given, another thread holding the interpreter lock is made to hand it
    over within that time instead of Python's default 5 ms (``sys.setswitchinterval``).

    Returns a one-line report of what was granted. Never raises: a refusal is reported (and
    logged) with what would allow it (root, or ``ulimit -r``/RLIMIT_RTPRIO and ``ulimit -l``).
    """
    parts = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))  # type: ignore[attr-defined,unused-ignore]
        parts.append(f"SCHED_FIFO priority {priority} granted")
    except (AttributeError, PermissionError, OSError) as e:
        parts.append(f"real-time priority refused ({e.__class__.__name__}: {e}); run as root or raise "
                     f"RLIMIT_RTPRIO (ulimit -r {priority}) to get it")
    if lock_memory:
        try:
            if _libc().mlockall(3) != 0:  # MCL_CURRENT | MCL_FUTURE
                raise OSError(ctypes.get_errno(), os.strerror(ctypes.get_errno()))
            parts.append("memory locked")
        except (OSError, AttributeError, TypeError) as e:
            parts.append(f"mlockall refused ({e}); raise RLIMIT_MEMLOCK (ulimit -l unlimited) to get it")
    gc.collect()
    gc.freeze()
    parts.append("garbage collector frozen")
    if switch_interval is not None and switch_interval < sys.getswitchinterval():
        sys.setswitchinterval(switch_interval)
        parts.append(f"switch interval {switch_interval * 1e6:.0f} µs")
    report = "; ".join(parts)
    log.info("control loop: %s", report)
    return report


_collector_lock = threading.Lock()
_collector_paused = [0, True]  # the threads inside collector_paused(), and whether collection was on before


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """No garbage collection while inside (in any thread: several may be inside at once).

    A full collection runs in whichever thread allocates when it is due and holds the interpreter
    lock throughout: over a 5000-keyframe plan's objects it took 33 ms here, and the control loop's
    thread waited for it (30 slots missed). Objects are still freed by their reference counts; the
    collection that was due runs after. See :func:`keep_from_collections` for a big plan.
    """
    with _collector_lock:
        if _collector_paused[0] == 0:
            _collector_paused[1] = gc.isenabled()
            gc.disable()
        _collector_paused[0] += 1
    try:
        yield
    finally:
        with _collector_lock:
            _collector_paused[0] -= 1
            if _collector_paused[0] == 0 and _collector_paused[1]:
                gc.enable()


def keep_from_collections() -> None:
    """Leave what exists now out of later collections (``gc.freeze``) until the loop stops
    (:meth:`ControlLoop.stop` unfreezes): for a big plan, which lives as long as its motion and which
    each full collection would otherwise scan again. Any garbage cycle that exists at this moment is
    kept until then too, so it is called for big plans only (rare), never for every move."""
    gc.freeze()


_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30  # prctl(2) options (Linux)
#: ns: the timer slack of the loop's thread. Linux lets a normal thread's sleep end up to 50 µs late
#: (its default slack), and the loop spins before each deadline to cover how late sleeps end: on our
#: machines 1 µs of slack made them end about 50 µs sooner (the median from 113 to 60 µs late), and
#: so shortened the spin. (A thread with real-time priority has no slack.)
TIMER_SLACK = 1000
#: s: a loop whose period is at least this long (a slow profile's 25 Hz) sleeps towards its next cycle
#: on an event that :meth:`ControlLoop.hasten` sets, up to :data:`HASTEN_MARGIN` before it, then as
#: its clock sleeps: an enable's first cycle need not wait for the next slot (the normal profile's
#: loops, at 100 Hz and faster, sleep as they did)
HASTEN_PERIOD = 0.01
#: s before a cycle's time its loop stops waiting on the event (the clock's own sleep does the rest)
HASTEN_MARGIN = 0.002


def _prctl(option: int, value: int = 0) -> int | None:
    """prctl(2) for the calling thread (Linux); ``None`` where there is none or it fails."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        result = int(_libc().prctl(option, value, 0, 0, 0))
    except (OSError, AttributeError, TypeError):
        return None
    return None if result < 0 else result


def set_timer_slack(ns: int = TIMER_SLACK) -> bool:
    """Let the calling thread's sleeps end at most ``ns`` late (Linux); whether it was granted."""
    return _prctl(_PR_SET_TIMERSLACK, ns) == 0


def timer_slack() -> int | None:
    """The calling thread's timer slack, ns (``None`` where unknown: not Linux)."""
    return _prctl(_PR_GET_TIMERSLACK)


def pin_thread(cpu: int) -> str:
    """Run the calling thread on CPU ``cpu`` only (Linux). Returns a report; never raises."""
    try:
        os.sched_setaffinity(0, {cpu})  # type: ignore[attr-defined,unused-ignore]
    except (AttributeError, OSError, ValueError) as e:
        return f"pinning to CPU {cpu} refused ({e})"
    return f"pinned to CPU {cpu}"


@dataclass(frozen=True)
class StatsSummary:
    """What the loop measured (times in s).

    Attributes:
        cycles: cycles run. missed: slots skipped because a cycle started late.
        rate: achieved cycles per second of clock time.
        period_p50, period_p99, period_max: time between cycle starts.
        late_p50, late_p99, late_max: how long after its deadline a cycle started.
        stage_mean, stage_p99: compute time per stage (name → s).
        compute_mean, compute_p99, compute_max: whole cycle compute time.
    """

    cycles: int
    missed: int
    rate: float
    period_p50: float
    period_p99: float
    period_max: float
    late_p50: float
    late_p99: float
    late_max: float
    stage_mean: dict[str, float]
    stage_p99: dict[str, float]
    compute_mean: float
    compute_p99: float
    compute_max: float

    def table(self) -> str:
        """A human-readable table (µs)."""
        us = 1e6
        lines = [f"cycles {self.cycles}, missed slots {self.missed}, rate {self.rate:.1f} Hz",
                 f"period  p50 {self.period_p50 * us:8.1f} µs  p99 {self.period_p99 * us:8.1f} µs  "
                 f"max {self.period_max * us:8.1f} µs",
                 f"late    p50 {self.late_p50 * us:8.1f} µs  p99 {self.late_p99 * us:8.1f} µs  "
                 f"max {self.late_max * us:8.1f} µs",
                 f"compute mean {self.compute_mean * us:7.1f} µs  p99 {self.compute_p99 * us:8.1f} µs  "
                 f"max {self.compute_max * us:8.1f} µs"]
        for name in self.stage_mean:
            lines.append(f"  {name:<10} mean {self.stage_mean[name] * us:7.1f} µs  "
                         f"p99 {self.stage_p99[name] * us:7.1f} µs")
        return "\n".join(lines)


class LoopStats:
    """Ring buffers of per-cycle timings (the last ``capacity`` cycles) and counters.

    Extra cycles between the loop's slots (:attr:`ControlLoop.soon`) are counted in :attr:`extra` and
    not measured: the rate, periods and lateness are the slots'."""

    def __init__(self, stages: Sequence[str], capacity: int = 1 << 16) -> None:
        self.stages = tuple(stages)
        self.capacity = capacity
        self.period = np.zeros(capacity)
        self.late = np.zeros(capacity)
        self.stage = np.zeros((capacity, len(self.stages)))
        # the loop writes through views of the same buffers: a memoryview's item is set by a few
        # instructions, a numpy array's by its indexing machinery, whose code starts cold in a loop
        # that sleeps between cycles (ten such writes a cycle)
        self._period = self.period.data.cast("B").cast("d")
        self._late = self.late.data.cast("B").cast("d")
        self._stage = self.stage.data.cast("B").cast("d")
        self._stage_bytes = self.stage.data.cast("B")
        self._row_zero = bytes(8 * len(self.stages))
        self._extra_row = np.zeros(len(self.stages)).data.cast("B").cast("d")  # an extra cycle's, never summarised
        self.cycles = 0
        self.missed = 0
        self.extra = 0
        self.first_start: float | None = None
        self.last_start: float | None = None

    def reset(self) -> None:
        """Forget everything measured so far."""
        self.period[:] = 0
        self.late[:] = 0
        self.stage[:] = 0
        self.cycles = self.missed = self.extra = 0
        self.first_start = self.last_start = None

    def begin_extra(self) -> int:
        """Count an extra cycle between the slots; return its index for :meth:`row` (-1: a row of its own,
        never summarised)."""
        self.extra += 1
        return -1

    def begin(self, now: float, lateness: float) -> int:
        """Record a cycle start; return its ring index."""
        i = self.cycles % self.capacity
        self._period[i] = now - self.last_start if self.last_start is not None else 0.0
        self._late[i] = lateness
        size = len(self._row_zero)
        self._stage_bytes[i * size:(i + 1) * size] = self._row_zero
        if self.first_start is None:
            self.first_start = now
        self.last_start = now
        self.cycles += 1
        return i

    def row(self, i: int) -> memoryview[float]:
        """Cycle ``i``'s stage times (s, :attr:`stages` order) to write: a view of its row of :attr:`stage`
        (``-1``, an extra cycle's: a row of its own, never summarised)."""
        if i < 0:
            return self._extra_row
        k = len(self.stages)
        return self._stage[i * k:(i + 1) * k]

    def summary(self) -> StatsSummary:
        """Percentiles over the cycles in the ring."""
        n = min(self.cycles, self.capacity)
        if n == 0:
            zero = {s: 0.0 for s in self.stages}
            return StatsSummary(0, self.missed, 0.0, 0, 0, 0, 0, 0, 0, zero, dict(zero), 0, 0, 0)
        period = self.period[:n]
        periods = period[period > 0] if np.any(period > 0) else np.zeros(1)
        late = self.late[:n]
        stage = self.stage[:n]
        compute = stage.sum(axis=1)
        span = (self.last_start or 0.0) - (self.first_start or 0.0)
        rate = (self.cycles - 1) / span if span > 0 else 0.0
        return StatsSummary(
            cycles=self.cycles, missed=self.missed, rate=rate,
            period_p50=float(np.percentile(periods, 50)), period_p99=float(np.percentile(periods, 99)),
            period_max=float(periods.max()),
            late_p50=float(np.percentile(late, 50)), late_p99=float(np.percentile(late, 99)),
            late_max=float(late.max()),
            stage_mean={s: float(stage[:, k].mean()) for k, s in enumerate(self.stages)},
            stage_p99={s: float(np.percentile(stage[:, k], 99)) for k, s in enumerate(self.stages)},
            compute_mean=float(compute.mean()), compute_p99=float(np.percentile(compute, 99)),
            compute_max=float(compute.max()),
        )


class _SwitchInterval:
    """The process's thread switch interval, shared by the loops running in it: while any runs it is
    the smallest they asked for (never raised above what it was); the last to stop restores it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._wanted: dict[int, float] = {}
        self._before = 0.0

    def want(self, key: int, interval: float) -> None:
        with self._lock:
            if not self._wanted:
                self._before = sys.getswitchinterval()
            self._wanted[key] = interval
            sys.setswitchinterval(min([self._before, *self._wanted.values()]))

    def release(self, key: int) -> None:
        with self._lock:
            if self._wanted.pop(key, None) is None:
                return
            sys.setswitchinterval(min([self._before, *self._wanted.values()]))


_switch_interval = _SwitchInterval()


class ControlLoop:
    """Calls ``cycle(now, slot)`` at ``rate_hz`` on ``clock``.

    With a real clock, a running loop lowers the process's thread switch interval to a twentieth of
    the period (``sys.setswitchinterval``; restored when the last loop stops): otherwise any thread
    that computes in Python holds the interpreter lock for up to 5 ms when the loop wakes.

    ``cycle`` receives the clock time at which it started and the ring index for its stage timings
    (``loop.stats.row(slot)[k]``, s); while it runs, :attr:`deadline`, :attr:`skipped` and
    :attr:`gap` describe its slot, and it may set :attr:`soon` to have the next cycle sooner than the
    next slot (an extra cycle between the slots, which stay where they were). It must not raise; if it
    does, the loop stops and calls ``on_crash(exception)`` (the Arm uses that to send exit frames).
    """

    def __init__(self, rate_hz: object, clock: Clock, cycle: Callable[[float, int], None], *,
                 stages: Sequence[str] = ("cycle",), realtime_priority: bool = False, cpu: int | None = None,
                 on_crash: Callable[[BaseException], None] | None = None) -> None:
        # (``object``: compiled, an annotation is checked at the call, and a wrong type would be a
        # TypeError there, not this ArgumentError)
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or \
                not MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ:
            raise ArgumentError(f"the loop rate must be a number of Hz from {MIN_RATE_HZ:g} to {MAX_RATE_HZ:g}, "
                                f"not {rate_hz!r}", fix="give the robot's rate_hz within that range, e.g. 500")
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz
        self.clock = clock
        self.cycle = cycle
        self.stats = LoopStats(stages)
        self.realtime_priority = realtime_priority
        self.cpu = cpu
        self.realtime_report = "not requested"
        self.on_crash = on_crash
        self.crashed: BaseException | None = None
        #: the slot of the cycle running (or last run): its time on the loop's grid of periods, s
        self.deadline = 0.0
        #: slots skipped just before that cycle (it started that many periods late, or more)
        self.skipped = 0
        #: s from the start of the cycle before to this one's (0 for the first): one period, give or
        #: take the jitter, while the loop keeps time; more where it did not run (a stall)
        self.gap = 0.0
        #: s: set by a cycle, the next one runs this long after this one's time, when that comes before
        #: the next slot of the grid (an extra cycle: an enable's contact on a slow profile); read once
        self.soon: float | None = None
        self._next: float | None = None
        self._slot = 0.0  # the next slot of the grid of periods (the extra cycles leave it where it is)
        self._early: float | None = None  # an extra cycle's time asked for from outside (:meth:`hasten`)
        self._hastened = threading.Event()
        self._in_cycle = False  # (stepped) this loop's own cycle is under way: the clock must not start another
        self._worker: threading.Thread | None = None  # (not `_thread`: compiled, that is C's `__thread`)
        self._running = threading.Event()
        self.cycled = threading.Condition()

    @property
    def stepped(self) -> bool:
        """True when the clock is stepped: cycles run only through :meth:`step`."""
        return self.clock.stepped

    @property
    def running(self) -> bool:
        """True while the real-time thread runs."""
        return self._running.is_set()

    # -- one cycle ----------------------------------------------------------------------------
    def _one(self) -> None:
        if self._next is None:
            self._next = self._slot = self.clock.now() + self.period
        deadline = self._take_early(self._next)
        self._in_cycle = True
        try:
            if not self.clock.stepped and self.period >= HASTEN_PERIOD:
                while True:  # until shortly before the cycle, a hasten() may bring it forward
                    lead = deadline - self.clock.now() - HASTEN_MARGIN
                    if lead <= 0.0 or not self._hastened.wait(lead):
                        break
                    self._hastened.clear()
                    deadline = self._take_early(deadline)
            self.clock.sleep_until(deadline)
            now = self.clock.now()
            if deadline < self._slot <= now + 1e-12:  # an extra cycle that came as late as the slot: the slot's
                deadline = self._slot
            late = now - deadline
            skipped = 0
            if late >= self.period:  # skip the slots we missed rather than burst
                skipped = int(late // self.period)
                self.stats.missed += skipped
                deadline += skipped * self.period
                late = now - deadline
            last = self.stats.last_start
            self.gap = now - last if last is not None else 0.0
            self.deadline = deadline
            self.skipped = skipped
            # (an extra cycle between the slots is counted, not measured: the statistics are the slots')
            slot = self.stats.begin(now, late) if deadline >= self._slot - 1e-12 else self.stats.begin_extra()
            self.soon = None
            self.cycle(now, slot)
            if deadline >= self._slot - 1e-12:  # (not an extra cycle)
                self._slot = deadline + self.period
            soon = self._asked_soon()
            self._next = self._slot if soon is None or deadline + soon >= self._slot else deadline + soon
        finally:
            self._in_cycle = False

    def _asked_soon(self) -> float | None:
        # (a method: mypy and mypyc, having seen it set to None before the cycle, would take the
        # attribute for None there, while the cycle sets it)
        return self.soon

    def hasten(self, t: float) -> None:
        """Run an extra cycle at clock time ``t`` (at once if past) when the next one would come later
        (an enable's first contact on a slow profile); the grid's slots stay where they were. With a real
        clock, a loop whose period is shorter than :data:`HASTEN_PERIOD` is not woken early."""
        self._early = t
        self._hastened.set()

    def _take_early(self, deadline: float) -> float:
        """``deadline``, or the :meth:`hasten` time asked for if sooner (then forgotten)."""
        early = self._early
        if early is None:
            return deadline
        self._early = None
        return early if early < deadline else deadline

    def _due(self) -> float | None:
        nxt, early = self._next, self._early
        return nxt if nxt is None or early is None or early >= nxt else early

    # -- on a stepped clock shared with other loops (akarm.clock.SteppedLoop) -----------------
    def due(self) -> float | None:
        """The time of the next cycle, while started on a stepped clock and not in a cycle now."""
        return None if self._in_cycle else self._due()

    def run_due(self, now: float) -> None:
        """Run the cycle due at ``now``, if one is (another loop or a test advanced the shared clock)."""
        due = self._due()
        if not self._in_cycle and due is not None and due <= now + 1e-12:
            self._one()

    def step(self, cycles: int = 1) -> None:
        """Run ``cycles`` cycles now (stepped clocks; also usable before :meth:`start`)."""
        for _ in range(cycles):
            self._one()

    # -- the real-time thread -----------------------------------------------------------------
    def start(self) -> None:
        """Start the loop afresh (its statistics and any crash forgotten), in a thread of its own with
        a real clock (a stepped loop runs through :meth:`step`). Nothing if it runs already."""
        if self._worker is not None:
            return
        self.stats.reset()
        self.crashed = None
        self.realtime_report = "not requested"
        if self.stepped:
            if isinstance(self.clock, SteppedClock):  # its cycles run whoever advances the clock
                self._next = self._slot = self.clock.now() + self.period
                self.clock.join(self)
            return
        self._running.set()
        self._worker = threading.Thread(target=self._run, name="akarm-loop", daemon=True)
        self._worker.start()

    def _run(self) -> None:
        # a thread of the process holding the interpreter lock must give it up within a twentieth of
        # a period, not Python's default 5 ms (which would cost 2 cycles at 500 Hz)
        switch = max(20e-6, self.period / 20)
        _switch_interval.want(id(self), switch)
        set_timer_slack()  # sleeps that end sooner: a shorter spin before each deadline
        reports = []
        if self.cpu is not None:
            reports.append(pin_thread(self.cpu))
        idle = IdleLatencyHold()
        if self.realtime_priority:
            reports.append(request_realtime())
            reports.append(f"switch interval {sys.getswitchinterval() * 1e6:.0f} µs")
            reports.append(idle.acquire())  # cycles that start warm and on time (akarm.control.cpuidle)
        else:
            # what exists now (the model, numpy, the modules) lives as long as the loop: later full
            # collections need not scan it again (one took 33-61 ms here, and the loop waited for it)
            gc.collect()
            keep_from_collections()
        if reports:
            self.realtime_report = "; ".join(reports)
        self._next = self._early = None
        try:
            while self._running.is_set():
                self._one()
                with self.cycled:
                    self.cycled.notify_all()
        except BaseException as e:  # a bug in a cycle: stop the loop, let the owner make it safe
            self.crashed = e
            self._running.clear()
            log.exception("control loop crashed")
            if self.on_crash is not None:
                self.on_crash(e)
            with self.cycled:
                self.cycled.notify_all()
        finally:
            idle.release()
            _switch_interval.release(id(self))

    @property
    def thread(self) -> threading.Thread | None:
        """The loop's thread while it runs (``None`` in lock step: cycles run in the caller's thread)."""
        return self._worker

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the loop thread (after its current cycle); a stepped loop leaves its clock."""
        if isinstance(self.clock, SteppedClock):
            self.clock.leave(self)
        self._running.clear()
        t = self._worker
        if t is not None and t is not threading.current_thread():
            t.join(timeout)
        if t is not None:
            gc.unfreeze()  # what request_realtime or keep_from_collections froze may be collected again
        self._worker = None
        self._next = self._early = None

    def wait_cycle(self, timeout: float) -> None:
        """Block until the next cycle has run (real clocks), or run one (stepped clocks)."""
        if self.stepped:
            self.step()
            return
        with self.cycled:
            self.cycled.wait(timeout)

