"""Planning while streaming: how late and how long the loop's cycles are while a big plan is made.

planar2 at 500 Hz in real time against ``akarm sim`` in another process (akarm_local), holding; then,
each in the caller's thread while the loop streams: a 5000-keyframe replay, a one-hour recorded path
(500 Hz, 1.8 million samples) replayed, and a 100 000-point trajectory (refused by
akarm.motion.bounds before planning). For each: the time to plan (or refuse), and over that time the
loop's cycles: the longest compute, the latest start, the longest period and the slots missed. The
plans are stopped as soon as they are in (only the planning is measured).

    .venv/bin/python benchmarks/bench_planning.py [--repeat N]

Real time on a shared machine: the load average is printed with the numbers.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.motion import recording as rec  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402

PLANAR2 = ROOT / "robots" / "planar2.yaml"


def keyframes(names: tuple[str, ...], n: int) -> rec.Keyframes:
    return rec.Keyframes(names, tuple(rec.Keyframe((-1.0 + 0.3 * math.sin(k / 9.0), 0.3 * math.cos(k / 7.0)))
                                      for k in range(n)))


def hour_path(names: tuple[str, ...], rate: float = 500.0) -> rec.PathRecording:
    t = np.arange(int(3600 * rate)) / rate
    q = np.column_stack([-1.0 + 0.3 * np.sin(t / 5.0), 0.3 * np.sin(t / 7.0)])
    return rec.PathRecording(names, t, q)


def measure(arm: akarm.Arm, what: str, start) -> None:
    try:
        _measure(arm, what, start)
    except akarm.SafetyStop as e:  # real time on a loaded machine: said, and the arm enabled again
        print(f"{what:28s} STOPPED: {type(e).__name__}: {str(e)[:160]}", flush=True)
        arm.enable()


def _measure(arm: akarm.Arm, what: str, start) -> None:
    arm.sleep(0.3)
    arm.reset_stats()
    began = time.perf_counter()
    outcome = "planned"
    try:
        start()
    except (akarm.ArgumentError, akarm.RecordingError) as e:
        outcome = f"refused ({type(e).__name__}: {str(e)[:70]}...)"
    took = time.perf_counter() - began
    s = arm.stats()
    if arm.moving:
        arm.stop()
    print(f"{what:28s} {outcome[:90]}\n{'':28s} {took * 1e3:8.1f} ms to plan; during it {s.cycles} cycles: compute max "
          f"{s.compute_max * 1e3:.2f} ms, p99 {s.compute_p99 * 1e3:.2f} ms; late max {s.late_max * 1e3:.2f} ms; "
          f"period max {s.period_max * 1e3:.2f} ms; missed {s.missed}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    channel = f"bench-planning-{os.getpid()}"
    config = akarm.load_robot(PLANAR2).with_bus(interface="akarm_local", channel=channel)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    path_rec = hour_path(tuple(config.joint_names))
    with SimulatorProcess(PLANAR2, channel=channel, pose="down"), \
            akarm.Arm(config, feedback_timeout=0.5, remember_positions=False) as arm:  # a fresh simulator
        arm.enable()
        names = tuple(arm.names)
        arm.move_to(path_rec.q[0])
        n = 100_000
        for _ in range(args.repeat):
            measure(arm, "5000-keyframe replay", lambda: arm.replay(keyframes(names, 5000), wait=False))
            measure(arm, "move to the path's start", lambda: arm.move_to(path_rec.q[0], wait=True))
            measure(arm, "one-hour path replay", lambda: arm.replay(path_rec, wait=False))
            measure(arm, "100 000-point trajectory", lambda: arm.follow([0.01 * (k + 1) for k in range(n)],
                                                                        [list(path_rec.q[0])] * n, wait=False))
    print(f"load average {os.getloadavg()[0]:.1f} at the end", flush=True)


if __name__ == "__main__":
    main()
