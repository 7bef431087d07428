"""The wait between cycles: CPU per cycle and lateness of the fixed and the adaptive spin.

    .venv/bin/python benchmarks/bench_wait.py              # 480 Hz, 4 s per run, 3 rounds

A loop at 480 Hz does ~0.1 ms of pure-Python work per cycle and waits for its next deadline with
``RealClock(adaptive=False)`` (sleep, then spin the last 200 µs: the old default) or ``RealClock()``
(spin only as long as the tracked wake-up lateness needs: :class:`akarm.clock.WakeLateness`), or
``RealClock(spin=0, adaptive=False)`` (``sleep only``: no spin, every cycle as late as the sleep
wakes). Printed: the loop thread's CPU per cycle (``time.thread_time``), its lateness p50 and p99,
and the spin the adaptive clock settled on; first, the work alone, back to back, with no wait.
``sleep only`` less the work is what sleeping costs: the sleep call itself (on a virtual machine
the core's halt and wake-up; a bare 2 ms ``time.sleep`` takes 24-39 µs of CPU here) and the work's
cold start after it. The adaptive row less ``sleep only`` is what its spin costs. Say the machine's
load with the numbers: the spin follows it.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from akarm.clock import RealClock


def work() -> int:
    """The cycle's work: ~0.1 ms of pure Python."""
    x = 0
    for i in range(2000):
        x += i
    return x


def work_alone(n: int = 2000) -> float:
    """The work's CPU, s, back to back (no wait between)."""
    c0 = time.thread_time()
    for _ in range(n):
        work()
    return (time.thread_time() - c0) / n


def run(clock: RealClock, seconds: float, rate: float) -> tuple[float, float, float, float]:
    pc, period = time.perf_counter, 1.0 / rate
    n = int(seconds * rate)
    late = []
    t = pc() + period
    c0 = time.thread_time()
    for _ in range(n):
        clock.sleep_until(t)
        late.append(pc() - t)
        t += period
        work()
    cpu = (time.thread_time() - c0) / n
    late.sort()
    spin = clock.wake.spin() if clock.wake is not None else clock.spin
    return cpu, late[n // 2], late[int(0.99 * n)], spin


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--rate", type=float, default=480.0)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    us = 1e6
    print(f"{args.rate:g} Hz, {args.seconds:g} s per run, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}")
    print(f"{'wait':>10} {'CPU/cycle':>10} {'late p50':>9} {'late p99':>9} {'spin':>6}   (µs)")
    for _ in range(args.rounds):
        print(f"{'work':>10} {work_alone() * us:10.0f}", flush=True)
        for name, clock in (("fixed", RealClock(adaptive=False)), ("adaptive", RealClock()),
                            ("sleep only", RealClock(spin=0.0, adaptive=False))):
            cpu, p50, p99, spin = run(clock, args.seconds, args.rate)
            print(f"{name:>10} {cpu * us:10.0f} {p50 * us:9.0f} {p99 * us:9.0f} {spin * us:6.0f}", flush=True)


if __name__ == "__main__":
    main()
