"""The control loop's timing: skipped slots on a stepped clock, the busy-waiting real clock, and
what asking for real-time conditions does to the process."""

from __future__ import annotations

import gc
import sys
import threading

import pytest

from akarm import clock as clock_mod
from akarm.clock import RealClock, SteppedClock
from akarm.control.loop import ControlLoop, request_realtime


def test_a_late_cycle_skips_the_slots_it_missed_and_keeps_the_grid():
    clock = SteppedClock()
    starts: list[float] = []

    def cycle(now: float, slot: int) -> None:
        starts.append(now)
        if len(starts) == 3:
            clock.sleep_until(now + 0.0075)  # this cycle overruns by 3.75 periods

    loop = ControlLoop(500.0, clock, cycle)
    loop.step(6)
    assert starts[:3] == pytest.approx([0.002, 0.004, 0.006])
    # the slots at 0.008 and 0.010 were missed and are skipped; the cycle runs at once in the 0.012
    # slot, late by 1.5 ms, and the next ones are back on the grid: no burst of catch-up cycles
    assert starts[3] == pytest.approx(0.0135)
    assert starts[4:] == pytest.approx([0.014, 0.016])
    s = loop.stats.summary()
    assert s.missed == 2 and s.cycles == 6
    assert s.late_max == pytest.approx(0.0015)


def test_stats_summarise_stage_times():
    clock = SteppedClock()
    loop = ControlLoop(100.0, clock, lambda now, slot: loop.stats.stage[slot].__setitem__(0, 1e-4 * (slot + 1)),
                       stages=("work",))
    loop.step(100)
    s = loop.stats.summary()
    assert s.stage_mean["work"] == pytest.approx(1e-4 * 50.5)
    assert s.compute_max == pytest.approx(1e-2)
    assert s.rate == pytest.approx(100.0)
    assert "work" in s.table()


@pytest.fixture
def default_switch_interval():
    """Python's default switch interval, 5 ms, for the test (``request_realtime`` lowers it for
    good); the process's own is restored after."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(0.005)
    yield
    sys.setswitchinterval(before)


@pytest.mark.parametrize("busy", [False, True])
def test_real_clock_wakes_at_the_deadline_and_lets_other_threads_run(busy, default_switch_interval):
    # (a thread that only computes keeps the interpreter lock for the switch interval, 5 ms by
    # default: the control loop shortens it, as here)
    sys.setswitchinterval(1e-4)
    c = RealClock(busy=busy)
    counted = [0]
    stop = threading.Event()

    def count() -> None:
        while not stop.is_set():
            counted[0] += 1

    th = threading.Thread(target=count)
    th.start()
    try:
        late = []
        for _ in range(20):
            t = c.now() + 0.005
            c.sleep_until(t)
            late.append(c.now() - t)
    finally:
        stop.set()
        th.join()
    assert min(late) >= 0.0
    assert counted[0] > 1000  # the other thread got the interpreter while the clock waited
    # the median wake-up is not a whole 5 ms switch interval late; bound generously, as a loaded
    # machine takes the core away for a time slice (~3 ms); the real numbers are bench_loop's
    assert sorted(late)[10] < 0.02


class _FakeTime:
    """``perf_counter`` and ``sleep`` for :class:`RealClock` alone: a microsecond passes per read."""

    def __init__(self) -> None:
        self.t = 100.0
        self.naps: list[float] = []

    def perf_counter(self) -> float:
        self.t += 1e-6
        return self.t

    def sleep(self, s: float) -> None:
        self.naps.append(s)
        self.t += s


def test_a_busy_real_time_loop_naps_a_tenth_of_each_wait(monkeypatch):
    fake = _FakeTime()
    monkeypatch.setattr(clock_mod, "time", fake)
    monkeypatch.setattr(clock_mod, "_yield", lambda: None)
    monkeypatch.setattr(clock_mod, "_realtime_thread", lambda: True)
    c = RealClock(busy=True)
    t = c.now() + 0.010
    c.sleep_until(t)
    assert fake.t >= t
    assert len(fake.naps) == 1 and fake.naps[0] == pytest.approx(0.001, abs=1e-6)
    monkeypatch.setattr(clock_mod, "_realtime_thread", lambda: False)
    c.sleep_until(fake.t + 0.010)
    assert len(fake.naps) == 1  # not a real-time thread: no nap, it only yields


def test_request_realtime_never_raises_and_keeps_python_pauses_short(default_switch_interval):
    report: list[str] = []
    th = threading.Thread(target=lambda: report.append(request_realtime(lock_memory=False, switch_interval=1e-4)))
    try:
        th.start()
        th.join()
        assert "SCHED_FIFO priority 80 granted" in report[0] or "real-time priority refused" in report[0]
        assert "garbage collector frozen" in report[0] and gc.get_freeze_count() > 0
        assert sys.getswitchinterval() == pytest.approx(1e-4, abs=2e-6)
        assert "switch interval 100 µs" in report[0]
    finally:
        gc.unfreeze()


def test_a_running_loop_makes_other_threads_hand_over_the_interpreter_quickly(default_switch_interval):
    ran = threading.Event()
    loop = ControlLoop(500.0, RealClock(), lambda now, slot: ran.set())
    try:
        loop.start()
        assert ran.wait(5.0)
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)  # a twentieth of the 2 ms period
        slower = ControlLoop(100.0, RealClock(), lambda now, slot: None)  # two loops: the smaller interval
        slower.start()
        slower.wait_cycle(5.0)
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)
        slower.stop()
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)  # the faster one still runs
    finally:
        loop.stop()
    assert sys.getswitchinterval() == 0.005  # the last loop stopped: Python's own again
