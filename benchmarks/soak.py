"""Soak: arm6 moving without a break in real time, the supervisor at its defaults; how many stops?

    .venv/bin/python benchmarks/soak.py                 # 10 minutes
    .venv/bin/python benchmarks/soak.py --seconds 60
    .venv/bin/python benchmarks/soak.py --lockstep      # the same workload in lock step, simulated time

The simulator runs in a process of its own (``akarm sim`` on ``akarm_local``), as a real arm's
drivers are hardware of their own; the Arm is built with every default (20 ms feedback timeout,
derived following-error limits, settle guard ...). It works as an arm at a cell does, until the time
is up: moves to random targets in its workspace (a random blend of its named poses home, ready and
left, home weighing most, plus up to ±0.15 rad per joint; seeded) at random speeds from 0.5 to 1.0,
with a full-speed move to a named pose every fourth move (reach, its furthest, every sixteenth) and
a short pause at each target. (arm6 holds ready and left at its shoulder's rated torque and reach at
1.7 times it: a cycle that dwells out there heats that motor past 80 °C within minutes, in the
simulator as in the motor, and the soak would measure the thermal model instead of the controller.) A safety stop
is counted, reported and the arm enabled again: the goal is zero. Printed every minute and at the
end: moves, stops, the loop's missed slots and late cycles, the largest following error per joint
(and its limit), the largest feedback age, the hottest motor, and the process's resident memory.

``--lockstep`` runs the same workload against an in-process simulator in lock step: the supervisor's
checks without the machine's timing (a loaded machine can delay the simulator's replies past the
20 ms feedback timeout; real drivers answer within a millisecond).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402

ARM6 = ROOT / "robots" / "arm6.yaml"


def rss_mb() -> float:
    """Resident memory of this process, MB (Linux; NaN elsewhere)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


# C901 14 > 12, left as it was: a benchmark's main: options, the run and its report
def process_cpu() -> float:
    """This process's CPU time so far, all threads, s."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> int:  # noqa: C901
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0, help="how long to move (default 600)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--channel", default=f"soak-{os.getpid()}")
    ap.add_argument("--lockstep", action="store_true", help="simulated time, simulator in this process")
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    config = akarm.load_robot(ARM6).with_bus(interface="virtual" if args.lockstep else "akarm_local",
                                             channel=args.channel)
    poses = [np.array(config.pose(p)) for p in ("home", "ready", "left")]
    weights = np.array([3.0, 1.0, 1.0])
    reach = np.array(config.pose("reach"))
    load0 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    how = "simulated (lock step)" if args.lockstep else "real time"
    print(f"akarm {akarm.__version__} soak: arm6, {args.seconds:.0f} s {how}, {os.cpu_count()} CPUs, load {load0:.2f}",
          flush=True)
    with contextlib.ExitStack() as stack:
        if args.lockstep:
            sim = stack.enter_context(SimulatedRobot(config, realtime=False, q0=config.pose("home")))
            arm = stack.enter_context(akarm.Arm(config, clock=sim.clock, remember_positions=False))
            clock = arm.clock.now
        else:
            sim = stack.enter_context(SimulatorProcess(ARM6, channel=args.channel, pose="home"))
            arm = stack.enter_context(akarm.Arm(config, remember_positions=False))
            clock = time.monotonic
        lo = arm.limits.lower + 0.05
        hi = arm.limits.upper - 0.05
        limits = np.array([g.following_error for g in arm.observe.guards])
        arm.enable()
        rss0 = rss_mb()
        cycles0, cpu0 = arm.stats().cycles, process_cpu()
        stops: list[str] = []
        n_moves = 0
        worst = np.zeros(arm.n)
        worst_age = 0.0
        max_temp = 0.0
        t0 = clock()
        last_report = t0
        since = arm.clock.now()
        while clock() - t0 < args.seconds:
            if n_moves % 16 == 15:
                target, speed = reach, 1.0
            elif n_moves % 4 == 3:
                target, speed = poses[rng.integers(len(poses))], 1.0
            else:
                w = rng.dirichlet(weights)
                target = np.clip(sum(wk * p for wk, p in zip(w, poses, strict=True)) + rng.uniform(-0.15, 0.15, arm.n),
                                 lo, hi)
                speed = float(rng.uniform(0.5, 1.0))
            try:
                motion = arm.move_to(target, speed=speed, wait=False)
                while not motion.done:
                    arm.sleep(0.05)
                    state = arm.state()
                    worst_age = max(worst_age, max(j.age for j in state.joints))
                    max_temp = max(max_temp, max(j.temperature or 0.0 for j in state.joints))
                motion.wait()
                n_moves += 1
                arm.sleep(0.2)
            except akarm.SafetyStop as e:
                stops.append(f"{clock() - t0:7.1f} s: {type(e).__name__}: {e}")
                print("STOP " + stops[-1], flush=True)
                while True:
                    try:
                        arm.enable()
                        break
                    except akarm.SafetyStop as again:  # e.g. still too hot: wait (simulated time goes on)
                        print(f"  enable refused: {again}", flush=True)
                        if args.lockstep:
                            sim.run_for(5.0)
                        else:
                            time.sleep(5.0)
                since = arm.clock.now()  # the stop's damping is not following: leave it out
                continue
            log = arm.telemetry(since=since)
            if len(log):
                worst = np.maximum(worst, np.nanmax(np.abs(log.q_des - log.q), axis=0))
                since = float(log.t[-1])
            if clock() - last_report >= 60.0 or clock() - t0 >= args.seconds:
                last_report = clock()
                st = arm.stats()
                print(f"{last_report - t0:6.0f} s: {n_moves} moves, {len(stops)} stops, missed slots {st.missed}, "
                      f"late max {st.late_max * 1e3:.2f} ms, largest following error "
                      f"{worst.max() * 1e3:.1f} mrad, RSS {rss_mb():.1f} MB", flush=True)
        st = arm.stats()
        cpu_per_cycle = (process_cpu() - cpu0) / max(st.cycles - cycles0, 1)
        rss1 = rss_mb()
        sim_cpu = sim.cpu_seconds() if hasattr(sim, "cpu_seconds") else float("nan")
        elapsed = clock() - t0
    load1 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nsoak over {elapsed:.0f} s: {n_moves} moves, {len(stops)} safety stops")
    print(f"loop: {st.cycles} cycles at {st.rate:.1f} Hz, missed slots {st.missed}, late p99 "
          f"{st.late_p99 * 1e6:.0f} µs, late max {st.late_max * 1e3:.2f} ms")
    print(f"process CPU per cycle (all threads: the loop, planning, this script) {cpu_per_cycle * 1e6:.0f} µs; "
          f"compute mean {st.compute_mean * 1e6:.0f} µs, p99 {st.compute_p99 * 1e6:.0f} µs")
    print(f"largest feedback age seen {worst_age * 1e3:.1f} ms (limit 20 ms)")
    print("largest following error per joint (limit):")
    for name, w, lim in zip(config.joint_names, worst, limits, strict=True):
        print(f"  {name:<14} {w * 1e3:7.1f} mrad ({lim * 1e3:.0f} mrad)")
    temps = f"hottest motor {max_temp:.0f} °C"
    print(f"RSS {rss0:.1f} MB at start, {rss1:.1f} MB at end; simulator CPU {sim_cpu:.0f} s; {temps}; load "
          f"{load0:.2f} → {load1:.2f}")
    for s in stops:
        print("  " + s)
    return 1 if stops else 0


if __name__ == "__main__":
    sys.exit(main())
