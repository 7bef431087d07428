"""Control-loop benchmark: timing against the simulator, and per-cycle cost versus joint count.

    .venv/bin/python benchmarks/bench_loop.py                 # 10 s at 250, 500, 1000 Hz, then 1..12 joints
    .venv/bin/python benchmarks/bench_loop.py --seconds 60 --rates 500 --realtime-priority

Part 1 runs robots/arm6.yaml in real time: the simulator in its own thread on a python-can virtual
bus, the Arm's loop thread streaming MIT frames while moving between poses. It prints the achieved
rate, lateness percentiles, missed slots, compute time per stage and the process's CPU use (both
threads share the 2 cores and the GIL, as they would with the simulator on the same machine).
(1000 Hz is over the 80 % bus-load budget of a real 1 Mbit/s bus for six MIT joints; the virtual bus
has no bit timing, so it is measured anyway.)

Part 2 measures the per-cycle compute of the loop alone (lock step with the simulator, whose time
is not counted) for generated chain arms of 1 to 12 joints, to show how the cost grows.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.config import BusConfig, Gains, JointConfig, Limits, RobotConfig  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def realtime_run(rate: float, seconds: float, rt: bool) -> dict:
    cfg = akarm.load_robot(ROOT / "robots" / "arm6.yaml").with_bus(interface="virtual",
                                                                   channel=f"bench-{os.getpid()}-{rate}")
    cfg = replace(cfg, rate_hz=rate)
    poses = [p for p in ("ready", "reach", "home") if p in cfg.poses]
    # The simulator shares this process (and its GIL) with the loop: a stall of it is not a motor
    # going silent, so the watchdog gets 100 ms here instead of the default 20 ms.
    with SimulatedRobot(cfg, realtime=True) as _sim, \
            akarm.Arm(cfg, realtime_priority=rt, feedback_timeout=0.1) as arm:
        arm.enable()
        arm.reset_stats()  # measure the steady state, not the enable
        wall0, cpu0 = time.perf_counter(), cpu_seconds()
        k = 0
        while time.perf_counter() - wall0 < seconds:
            arm.move_to(poses[k % len(poses)], speed=0.7)
            k += 1
        wall, cpu = time.perf_counter() - wall0, cpu_seconds() - cpu0
        s = arm.stats()
        report = arm.realtime_report
    return {"rate": rate, "stats": s, "cpu": cpu / wall, "wall": wall, "rt": report}


CHAIN_LINK = """
  <link name="l{i}">
    <inertial><origin xyz="0 0 0.1"/><mass value="0.6"/>
      <inertia ixx="0.003" iyy="0.003" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="j{i}" type="revolute"><parent link="l{p}"/><child link="l{i}"/>
    <origin xyz="0 0 0.2"/><axis xyz="{axis}"/><limit lower="-2" upper="2" effort="18" velocity="5"/>
  </joint>"""


def chain_config(n: int, folder: Path, channel: str) -> RobotConfig:
    links = "".join(CHAIN_LINK.format(i=i, p=i - 1, axis="0 1 0" if i % 2 else "0 0 1") for i in range(1, n + 1))
    urdf = folder / f"chain{n}.urdf"
    urdf.write_text(f'<robot name="chain{n}"><link name="l0"/>{links}\n</robot>\n')
    buses = {"a": BusConfig("a", "virtual", f"{channel}-a"), "b": BusConfig("b", "virtual", f"{channel}-b")}
    motor = akarm.motors.get("AK80-9")
    joints = tuple(JointConfig(name=f"j{i}", bus="a" if i <= 6 else "b", can_id=i, motor=motor, mode="mit",
                               limits=Limits(-2, 2, 3.0, 15.0, 150.0, 18.0), gains=Gains(60.0, 2.0))
                   for i in range(1, n + 1))
    return RobotConfig(name=f"chain{n}", urdf=urdf, buses=buses, joints=joints, rate_hz=500.0)


def compute_per_joint_count(max_joints: int) -> list[tuple[int, object]]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for n in range(1, max_joints + 1):
            cfg = chain_config(n, Path(d), f"chain-{os.getpid()}-{n}")
            with SimulatedRobot(cfg, realtime=False) as sim, akarm.Arm(cfg, clock=sim.clock) as arm:
                arm.enable()
                arm.reset_stats()
                for target in (0.8, -0.8, 0.0):
                    arm.move_to(np.full(n, target))
                rows.append((n, arm.stats()))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="length of each real-time run, s")
    ap.add_argument("--rates", type=float, nargs="+", default=[250.0, 500.0, 1000.0])
    ap.add_argument("--max-joints", type=int, default=12)
    ap.add_argument("--realtime-priority", action="store_true", help="ask for SCHED_FIFO and mlockall")
    args = ap.parse_args()

    print(f"akarm {akarm.__version__} loop benchmark, {os.cpu_count()} CPUs, Python {sys.version.split()[0]}")
    print("\nPart 1: robots/arm6.yaml (6 MIT joints) against the real-time simulator, virtual bus")
    us = 1e6
    print(f"{'rate Hz':>8} {'achieved':>9} {'late p50':>9} {'late p99':>9} {'late max':>9} {'missed':>7} "
          f"{'miss %':>7} {'compute':>8} {'cmp p99':>8} {'CPU %':>6}   (times in µs)")
    runs = [realtime_run(r, args.seconds, args.realtime_priority) for r in args.rates]
    for run in runs:
        s = run["stats"]
        slots = s.cycles + s.missed
        print(f"{run['rate']:8.0f} {s.rate:9.1f} {s.late_p50 * us:9.1f} {s.late_p99 * us:9.1f} {s.late_max * us:9.0f} "
              f"{s.missed:7d} {100 * s.missed / max(slots, 1):7.3f} {s.compute_mean * us:8.1f} "
              f"{s.compute_p99 * us:8.1f} {100 * run['cpu']:6.0f}")
    print(f"real-time priority: {runs[0]['rt']}")
    print("\ncompute per stage at each rate (mean µs):")
    stages = list(runs[0]["stats"].stage_mean)
    print(f"{'rate Hz':>8} " + " ".join(f"{s:>11}" for s in stages))
    for run in runs:
        print(f"{run['rate']:8.0f} " + " ".join(f"{run['stats'].stage_mean[s] * us:11.1f}" for s in stages))

    print("\nPart 2: per-cycle compute vs joint count (lock step; simulator time excluded), µs")
    print(f"{'joints':>6} {'mean':>8} {'p99':>8} {'per joint':>10}   " + " ".join(f"{s:>11}" for s in stages))
    for n, s in compute_per_joint_count(args.max_joints):
        print(f"{n:6d} {s.compute_mean * us:8.1f} {s.compute_p99 * us:8.1f} {s.compute_mean * us / n:10.1f}   "
              + " ".join(f"{s.stage_mean[k] * us:11.1f}" for k in stages))


if __name__ == "__main__":
    main()
