"""The control loop's real clock and real-time requests, on real threads and the wall clock (the
stepped clock: tests/unit/test_loop.py)."""

from __future__ import annotations

import gc
import sys
import threading

import pytest

from akarm.clock import RealClock
from akarm.control.loop import ControlLoop, request_realtime


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
