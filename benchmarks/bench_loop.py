"""Control-loop benchmark: timing against the simulator, and per-cycle cost versus joint count.

    .venv/bin/python benchmarks/bench_loop.py                 # 10 s per rate and wait mode, then 1..12 joints
    .venv/bin/python benchmarks/bench_loop.py --seconds 60 --rates 500 --realtime-priority

Part 1 runs robots/arm6.yaml (6 MIT joints) in real time, moving between poses: the simulator in a
process of its own (``akarm sim``, as a real arm's drivers are hardware of their own) on the
``akarm_local`` bus, the Arm's loop in this one (with ``busy``, pinned to the last CPU and the
simulator to the others). For each rate and each way of waiting between cycles (``sleep``: sleep, then spin the last
200 µs, the default; ``busy``: ``Arm(busy_wait=True)``) it prints the achieved rate, lateness
percentiles, missed slots, compute time per cycle and per stage, and the CPU use of both processes.
``--sim thread`` runs the old arrangement instead: the simulator in this process, on python-can's
``virtual`` bus, sharing the interpreter lock.
(1000 Hz is over the 80 % bus-load budget of a real 1 Mbit/s bus for six MIT joints; the simulated
bus has no bit timing, so it is measured anyway.)

Part 2 measures the per-cycle compute of the loop alone (lock step with the simulator, whose time
is not counted) for generated chain arms of 1 to 12 joints, to show how the cost grows.
"""

from __future__ import annotations

import argparse
import contextlib
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
from akarm.sim.process import SimulatorProcess  # noqa: E402

ARM6 = ROOT / "robots" / "arm6.yaml"


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def moves(arm: akarm.Arm, seconds: float) -> None:
    poses = [p for p in ("ready", "reach", "home") if p in arm.config.poses]
    wall0 = time.perf_counter()
    k = 0
    while time.perf_counter() - wall0 < seconds:
        arm.move_to(poses[k % len(poses)], speed=0.7)
        k += 1


def realtime_run(rate: float, seconds: float, rt: bool, busy: bool, sim: str) -> dict:
    channel = f"bench-{os.getpid()}-{rate:.0f}-{int(busy)}"
    ncpu = os.cpu_count() or 1
    # a busy loop gets the last CPU to itself (the simulator is kept off it); a sleeping one is left
    # to the scheduler, as a CPU of its own would be idle, and so cold, when each cycle starts
    loop_cpu = ncpu - 1 if ncpu > 1 and busy else None
    interface = "akarm_local" if sim == "process" else "virtual"
    cfg = replace(akarm.load_robot(ARM6).with_bus(interface=interface, channel=channel), rate_hz=rate)
    with contextlib.ExitStack() as stack:
        if sim == "process":
            proc = stack.enter_context(SimulatorProcess(ARM6, channel=channel,
                                                        cpus=range(ncpu - 1) if loop_cpu else None))
            sim_cpu_seconds, options = proc.cpu_seconds, {}
        else:
            stack.enter_context(SimulatedRobot(cfg, realtime=True))
            # the simulator shares this process and its interpreter lock: a stall of it is not a motor
            # going silent, so the watchdog gets 100 ms here instead of the default 20 ms
            sim_cpu_seconds, options = (lambda: float("nan")), {"feedback_timeout": 0.1}
        arm = stack.enter_context(akarm.Arm(cfg, realtime_priority=rt, busy_wait=busy, loop_cpu=loop_cpu,
                                                  remember_positions=False, **options))
        arm.enable()
        arm.reset_stats()  # measure the steady state, not the enable
        wall0, cpu0, sim0 = time.perf_counter(), cpu_seconds(), sim_cpu_seconds()
        moves(arm, seconds)
        wall = time.perf_counter() - wall0
        cpu, sim_cpu = cpu_seconds() - cpu0, sim_cpu_seconds() - sim0
        s, report = arm.stats(), arm.realtime_report
    return {"rate": rate, "mode": "busy" if busy else "sleep", "stats": s, "cpu": cpu / wall,
            "sim_cpu": sim_cpu / wall, "rt": report}


#: One link of the generated chains: 0.1 m and 0.1 kg, so that even twelve of them stay within an AK80-9's
#: 18 N·m at the first joint (0.2 m and 0.6 kg links needed more than that from five joints on: the
#: feed-forward saturated and the lock-step run stopped with a TrackingError).
CHAIN_LINK = """
  <link name="l{i}">
    <inertial><origin xyz="0 0 0.05"/><mass value="0.1"/>
      <inertia ixx="0.0001" iyy="0.0001" izz="0.00005" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="j{i}" type="revolute"><parent link="l{p}"/><child link="l{i}"/>
    <origin xyz="0 0 0.1"/><axis xyz="{axis}"/><limit lower="-2" upper="2" effort="18" velocity="5"/>
  </joint>"""


def chain_config(n: int, folder: Path, channel: str) -> RobotConfig:
    links = "".join(CHAIN_LINK.format(i=i, p=i - 1, axis="0 1 0" if i % 2 else "0 0 1") for i in range(1, n + 1))
    urdf = folder / f"chain{n}.urdf"
    urdf.write_text(f'<robot name="chain{n}"><link name="l0"/>{links}\n</robot>\n')
    buses = {"a": BusConfig("a", "akarm_local", f"{channel}-a"), "b": BusConfig("b", "akarm_local", f"{channel}-b")}
    motor = akarm.protocol.motors.get("AK80-9")
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
                # every other pair of joints turns the other way: the chain zigzags instead of curling up,
                # which would ask its first joints for more than their 18 N·m (a TrackingError)
                for target in (0.8, -0.8, 0.0):
                    arm.move_to(target * (-1.0) ** (np.arange(n) // 2))
                rows.append((n, arm.stats()))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="length of each real-time run, s")
    ap.add_argument("--rates", type=float, nargs="+", default=[250.0, 500.0, 1000.0])
    ap.add_argument("--modes", nargs="+", choices=("sleep", "busy"), default=["sleep", "busy"],
                    help="how the loop waits between cycles")
    ap.add_argument("--sim", choices=("process", "thread"), default="process",
                    help="the simulator in its own process on akarm_local (default), or in this one on virtual")
    ap.add_argument("--max-joints", type=int, default=12, help="part 2 up to this many joints (0: skip part 2)")
    ap.add_argument("--realtime-priority", action="store_true", help="ask for SCHED_FIFO and mlockall")
    args = ap.parse_args()

    print(f"akarm {akarm.__version__} loop benchmark, {os.cpu_count()} CPUs, Python {sys.version.split()[0]}")
    where = ("the simulator in its own process, akarm_local bus" if args.sim == "process"
             else "the simulator in this process, python-can virtual bus")
    print(f"\nPart 1: robots/arm6.yaml (6 MIT joints) in real time, {args.seconds:g} s per run; {where}")
    us = 1e6
    print(f"{'rate Hz':>8} {'wait':>6} {'achieved':>9} {'late p50':>9} {'late p99':>9} {'late max':>9} {'missed':>7} "
          f"{'miss %':>7} {'compute':>8} {'cmp p99':>8} {'CPU %':>6} {'sim CPU %':>9}   (times in µs)")
    runs = []
    for rate in args.rates:
        for mode in args.modes:
            run = realtime_run(rate, args.seconds, args.realtime_priority, mode == "busy", args.sim)
            runs.append(run)
            s = run["stats"]
            slots = s.cycles + s.missed
            print(f"{run['rate']:8.0f} {run['mode']:>6} {s.rate:9.1f} {s.late_p50 * us:9.1f} {s.late_p99 * us:9.1f} "
                  f"{s.late_max * us:9.0f} {s.missed:7d} {100 * s.missed / max(slots, 1):7.3f} "
                  f"{s.compute_mean * us:8.1f} {s.compute_p99 * us:8.1f} {100 * run['cpu']:6.0f} "
                  f"{100 * run['sim_cpu']:9.0f}", flush=True)
    print(f"real-time priority: {runs[0]['rt']}")
    print("\ncompute per stage (mean µs):")
    stages = list(runs[0]["stats"].stage_mean)
    print(f"{'rate Hz':>8} {'wait':>6} " + " ".join(f"{s:>11}" for s in stages))
    for run in runs:
        print(f"{run['rate']:8.0f} {run['mode']:>6} "
              + " ".join(f"{run['stats'].stage_mean[s] * us:11.1f}" for s in stages))

    if args.max_joints > 0:
        print("\nPart 2: per-cycle compute vs joint count (lock step, akarm_local; simulator time excluded), µs")
        print(f"{'joints':>6} {'mean':>8} {'p99':>8} {'per joint':>10}   " + " ".join(f"{s:>11}" for s in stages))
        for n, s in compute_per_joint_count(args.max_joints):
            print(f"{n:6d} {s.compute_mean * us:8.1f} {s.compute_p99 * us:8.1f} {s.compute_mean * us / n:10.1f}   "
                  + " ".join(f"{s.stage_mean[k] * us:11.1f}" for k in stages), flush=True)


if __name__ == "__main__":
    main()
