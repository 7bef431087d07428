"""The gripper's cost per control cycle, and the arm's cycle with and without one.

    .venv/bin/python benchmarks/bench_gripper.py              # 4 s of simulated time per case
    .venv/bin/python benchmarks/bench_gripper.py --seconds 10

In lock step against the simulator (no wall clock in the way), arm6g's arm holds still while:

- ``arm6g, no gripper``: the same robot without its `gripper:` entry (six motors);
- ``arm6g, gripper holding``: the gripper has grasped a 30 mm object and holds it (seven motors);
- ``arm6g, gripper moving``: the jaws open and close the whole time.

Printed per case: the loop's compute per cycle (median and p99, the controller's stages only: the
simulator's time is not in them) and each stage's median, of the fastest of ``--repeat`` runs:
medians and the fastest run, because a shared machine preempts some cycles and slows some runs.
Then the gripper's own law alone, ``GripperDrive.command``, its frame (``Joint.track_frame``) and
its per-cycle record, back to back: its cost per cycle.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import akarm  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402


def run_case(case: str, seconds: float) -> tuple[float, float, dict[str, float]]:
    """Per-cycle compute of the controller's stages: median and p99 (µs), and each stage's median."""
    config = akarm.load_robot(ROOT / "robots" / "arm6g.yaml").with_bus(interface="virtual",
                                                                         channel=f"bench-grip-{os.getpid()}-{case}")
    if case == "no gripper":
        config = replace(config, gripper=None)
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        g = arm.gripper
        if g is not None and case == "gripper holding":
            sim.place_object(0.03)
            g.close(force=20.0)
        arm.sleep(0.2)
        arm.reset_stats()
        end = arm.clock.now() + seconds
        while arm.clock.now() < end:
            if g is not None and case == "gripper moving" and not g.state().moving:
                g.move_to(0.07 if g.state().width < 0.04 else 0.01, wait=False)
            arm.sleep(0.1)  # (the same waiting in every case: the caller's work between cycles cools the caches)
        stats = arm.observe.loop.stats
        rows = stats.stage[:min(stats.cycles, stats.capacity)] * 1e6
        arm.disable()
    total = rows.sum(axis=1)
    return (float(np.median(total)), float(np.percentile(total, 99)),
            {name: float(np.median(rows[:, k])) for k, name in enumerate(stats.stages)})


def drive_alone(batches: int = 40, n: int = 5000) -> float:
    """µs per cycle of the gripper's law, frame and record, back to back (the fastest of ``batches`` batches)."""
    config = akarm.load_robot(ROOT / "robots" / "arm6g.yaml").with_bus(interface="virtual",
                                                                         channel=f"bench-drive-{os.getpid()}")
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        sim.place_object(0.03)
        assert arm.gripper is not None
        arm.gripper.close(force=20.0)
        drive = arm.observe.gripper
        assert drive is not None
        j = drive.joint
        best = float("inf")
        for _ in range(batches):
            t0 = time.perf_counter()
            for k in range(n):
                j.track_frame(*drive.command(k * 0.0025))
                drive.record(k * 0.0025)
            best = min(best, time.perf_counter() - t0)
        arm.disable()
    return best / n * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per case")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each case (the fastest is printed)")
    args = parser.parse_args()
    kind = "pure Python" if os.environ.get("AKARM_PURE") else "compiled where built"
    print(f"arm6g at 400 Hz, lock step, {args.seconds:g} s per case, the fastest of {args.repeat} runs ({kind})")
    cases = ("no gripper", "gripper holding", "gripper moving")
    best: dict[str, tuple[float, float, dict[str, float]]] = {}
    for _ in range(args.repeat):  # interleaved, the fastest run of each kept: a shared machine slows some runs
        for case in cases:
            r = run_case(case, args.seconds)
            if case not in best or r[0] < best[case][0]:
                best[case] = r
    base = best["no gripper"][0]
    for case in cases:
        p50, p99, stages = best[case]
        each = ", ".join(f"{k} {v:.1f}" for k, v in stages.items())
        print(f"  arm6g, {case:<16} cycle compute p50 {p50:6.1f} µs  p99 {p99:7.1f} µs  (p50 {p50 - base:+5.1f} µs)"
              f"   stages p50 µs: {each}")
    print(f"  the gripper's law, frame and record alone: {drive_alone():.2f} µs per cycle")


if __name__ == "__main__":
    main()
