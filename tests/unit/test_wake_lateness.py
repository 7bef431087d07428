"""The adaptive spin of a sleeping real-time loop (akarm.clock.WakeLateness), on given wake-ups."""

from __future__ import annotations

import random

import pytest

from akarm.clock import RealClock, WakeLateness


def feed(w: WakeLateness, lateness_us: list[int], times: int) -> None:
    order = random.Random(1)
    xs = list(lateness_us)
    for _ in range(times):
        order.shuffle(xs)
        for x in xs:
            w.woke(x * 1e-6)


def test_the_spin_settles_at_the_median_of_wake_up_lateness() -> None:
    w = WakeLateness(max_spin=200e-6)
    lateness = list(range(30, 130))  # µs, uniform: the median ≈ 80 µs
    feed(w, lateness, 300)
    assert w.spin() == pytest.approx(80e-6, abs=8e-6)
    late_after = sum(x * 1e-6 > w.spin() for x in lateness) / len(lateness)
    assert 0.4 <= late_after <= 0.6  # half the wake-ups still come after the spin began: that is the trade
    tail = [60] * 90 + [190] * 10  # µs: a few very late wake-ups do not lengthen every cycle's spin
    feed(w, tail, 300)
    assert w.spin() == pytest.approx(60e-6, abs=8e-6)


def test_the_spin_never_exceeds_its_maximum() -> None:
    w = WakeLateness(max_spin=200e-6, give_up=1e-3)
    feed(w, [500], 2000)  # every sleep wakes 0.5 ms late: the spin covers what it may
    assert w.spin() == 200e-6


def test_no_spin_on_a_machine_that_wakes_sleepers_too_late_and_back_when_it_recovers() -> None:
    w = WakeLateness(max_spin=200e-6, give_up=1e-3)
    feed(w, [3000], 2000)  # 3 ms late every time: spinning would not make the cycle on time
    assert w.spin() == 0.0
    feed(w, [50], 20000)  # quiet again
    assert 40e-6 < w.spin() < 60e-6


def test_a_busy_or_fixed_clock_keeps_its_fixed_spin() -> None:
    assert RealClock(busy=True).wake is None
    assert RealClock(adaptive=False).wake is None
    assert RealClock().wake is not None
    assert RealClock(spin=100e-6).wake.max_spin == 100e-6  # type: ignore[union-attr]
