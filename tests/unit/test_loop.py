"""The control loop's timing: skipped slots on a stepped clock, the busy-waiting real clock, and
what asking for real-time conditions does to the process."""

from __future__ import annotations

import pytest

from akarm import clock as clock_mod
from akarm.clock import RealClock, SteppedClock
from akarm.control.loop import ControlLoop, LoopStats
from akarm.errors import ArgumentError


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


def test_a_cycle_may_ask_for_extra_cycles_between_the_slots_which_stay_on_the_grid():
    clock = SteppedClock()
    starts: list[float] = []

    def cycle(now: float, slot: int) -> None:
        starts.append(now)
        if 0.04 - 1e-9 <= now < 0.05:  # from the first slot, extra cycles every 2 ms for 10 ms
            loop.soon = 0.002

    loop = ControlLoop(25.0, clock, cycle)
    loop.step(9)
    assert starts == pytest.approx([0.04, 0.042, 0.044, 0.046, 0.048, 0.050, 0.08, 0.12, 0.16])
    # the statistics are the slots' (25 Hz), the extra cycles only counted
    s = loop.stats.summary()
    assert s.missed == 0 and s.cycles == 4 and loop.stats.extra == 5
    assert s.rate == pytest.approx(25.0) and s.period_p50 == pytest.approx(0.04) and s.late_max == 0.0


def test_hasten_brings_the_next_cycle_forward_once(monkeypatch):
    clock = SteppedClock()
    starts: list[float] = []
    loop = ControlLoop(25.0, clock, lambda now, slot: starts.append(now))
    loop.start()
    clock.sleep_until(0.05)                  # the slot at 0.04 ran; the next is at 0.08
    loop.hasten(0.052)
    assert loop.due() == pytest.approx(0.052)
    clock.sleep_until(0.1)
    assert starts == pytest.approx([0.04, 0.052, 0.08])
    loop.stop()


def test_a_slow_loop_on_a_real_clock_is_woken_from_its_wait_by_hasten():
    """With a real clock, a 25 Hz loop waits for its next slot on an event (an enable need not wait up
    to 40 ms for its first contact). A clock that only moves when told: the wait is the event's."""
    import threading

    class Manual:
        stepped = False
        def __init__(self) -> None:
            self.t = 0.0
            self.slept: list[float] = []

        def now(self) -> float:
            return self.t

        def sleep_until(self, t: float) -> None:
            self.slept.append(t)
            self.t = max(self.t, t)

    clock = Manual()
    starts: list[float] = []
    loop = ControlLoop(25.0, clock, lambda now, slot: starts.append(now))  # type: ignore[arg-type]
    loop.step()                               # the slot at 0.04
    clock.t = -60.0                           # (the next slot is a minute away: only hasten ends the wait)

    def enable() -> None:
        while loop.due() is not None:  # (None while it is in _one: waiting for its cycle)
            threading.Event().wait(0.001)
        clock.t = 0.049
        loop.hasten(0.05)

    helper = threading.Thread(target=enable)
    helper.start()
    loop.step()
    helper.join()
    assert starts == pytest.approx([0.04, 0.05]) and clock.slept[-1] == pytest.approx(0.05)


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


def test_a_cycles_stage_row_is_its_own_and_starts_at_zero():
    stats = LoopStats(("a", "b"), capacity=2)
    for now, writes in ((0.0, (1e-4, 2e-4)), (0.01, (3e-4,))):  # the second cycle writes its first stage only
        row = stats.row(stats.begin(now, 0.0))
        for k, x in enumerate(writes):
            row[k] = x
    assert stats.stage.tolist() == [[1e-4, 2e-4], [3e-4, 0.0]]
    assert stats.summary().stage_mean == pytest.approx({"a": 2e-4, "b": 1e-4})
    stats.begin(0.02, 5e-5)  # the ring wraps: slot 0 again, zeroed for its cycle
    assert stats.stage.tolist() == [[0.0, 0.0], [3e-4, 0.0]]
    assert stats.late.tolist() == [5e-5, 0.0] and stats.period.tolist() == pytest.approx([0.01, 0.01])


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


def test_loops_sharing_a_stepped_clock_each_keep_their_own_grid_whoever_advances_it():
    clock = SteppedClock()
    seen: dict[str, list[float]] = {"a": [], "b": []}
    a = ControlLoop(500.0, clock, lambda now, slot: seen["a"].append(now))
    b = ControlLoop(400.0, clock, lambda now, slot: seen["b"].append(now))
    a.start()
    b.start()
    a.step(5)                # only a is stepped: b runs its own cycles on the way, at 2.5 ms, 5 ms, 7.5 ms
    assert seen["a"] == pytest.approx([0.002, 0.004, 0.006, 0.008, 0.010])
    assert seen["b"] == pytest.approx([0.0025, 0.005, 0.0075, 0.010])
    clock.sleep_until(0.015)  # someone else (a test, a simulator) advances it: both loops keep cycling
    assert seen["a"][5:] == pytest.approx([0.012, 0.014])
    assert seen["b"][4:] == pytest.approx([0.0125, 0.015])
    assert a.stats.missed == b.stats.missed == 0
    b.stop()                 # a stopped loop leaves the clock
    a.step(2)
    assert len(seen["b"]) == 6 and seen["a"][-1] == pytest.approx(0.018)


def test_no_collection_while_any_thread_plans_and_the_setting_comes_back() -> None:
    import gc

    from akarm.control.loop import collector_paused

    assert gc.isenabled()
    with collector_paused():
        assert not gc.isenabled()
        with collector_paused():  # a second planner meanwhile
            assert not gc.isenabled()
        assert not gc.isenabled()  # the first one still plans
    assert gc.isenabled()
    gc.disable()
    try:
        with collector_paused():
            pass
        assert not gc.isenabled()  # off before: left off
    finally:
        gc.enable()


@pytest.mark.parametrize("rate", [0.0, 1e-300, 5.0, 1e9, float("nan"), float("inf"), "500", True])
def test_a_loop_rate_outside_what_akarm_runs_is_an_argument_error(rate: object) -> None:
    """(a config made in code skips the robot file's check: the loop checks its rate itself)"""
    with pytest.raises(ArgumentError, match="the loop rate must be a number of Hz from 10 to 10000"):
        ControlLoop(rate, SteppedClock(), lambda now, slot: None)  # type: ignore[arg-type]
