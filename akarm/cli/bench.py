"""``akarm bench ROBOT.yaml``: measure the control loop's timing against the simulator.

::

    akarm bench robots/arm6.yaml                    # 5 s at the file's rate_hz
    akarm bench robots/arm6.yaml --rate 1000 --seconds 10

Runs the arm on an in-process, real-time simulator on a private virtual bus (the file's buses are
not used: no hardware is touched), moving between the file's poses (or small moves about the
starting pose when it has none), then prints the loop's statistics (achieved rate, period and
lateness percentiles, missed slots, time per stage) and the CPU the process used. The simulator
shares the process and its CPU, so a real arm leaves the loop more room than this shows.

The feedback watchdog is relaxed to 0.5 s here (a busy machine would otherwise stop the run): this
measures timing, not safety.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    parser.add_argument("robot", metavar="ROBOT.yaml", help="the robot's YAML configuration")
    parser.add_argument("--seconds", type=float, default=5.0, metavar="S", help="how long to run (default 5)")
    parser.add_argument("--rate", type=float, metavar="HZ", help="loop rate (default: the file's rate_hz)")


def _thread_cpu() -> dict[str, float]:
    """CPU seconds per thread name (Linux /proc; empty elsewhere), summed over threads of the same name."""
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out: dict[str, float] = {}
    for th in threading.enumerate():
        tid = th.native_id
        try:
            stat = Path(f"/proc/self/task/{tid}/stat").read_text()
        except (OSError, TypeError):
            continue
        fields = stat.rsplit(")", 1)[1].split()
        out[th.name] = out.get(th.name, 0.0) + (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return out


def _group(cpu: dict[str, float]) -> tuple[float, float]:
    loop = sum(v for k, v in cpu.items() if k == "akarm-loop")
    sim = sum(v for k, v in cpu.items() if k.startswith("akarm-sim"))
    return loop, sim


def run(args: argparse.Namespace) -> int:
    """Run the arm against the simulator for ``--seconds``; print the loop statistics and CPU use."""
    from dataclasses import replace

    import numpy as np

    from ..arm import Arm
    from ..config_loader import load_robot
    from ..errors import AkarmError
    from ..sim import SimulatedRobot
    from .common import controlled

    if not args.seconds > 0:
        raise AkarmError(f"--seconds {args.seconds} must be positive")
    if args.rate is not None and not args.rate > 0:
        raise AkarmError(f"--rate {args.rate} must be positive", fix="e.g. --rate 500")
    config = load_robot(args.robot)
    config = config.with_bus(interface="virtual", channel=f"akarm-bench-{os.getpid()}-{time.monotonic_ns()}")
    config = replace(config, joints=tuple(replace(j, feedback_timeout=None) for j in config.joints))
    if args.rate is not None:
        config = replace(config, rate_hz=float(args.rate))
    lower = np.array([j.limits.lower for j in config.joints])
    upper = np.array([j.limits.upper for j in config.joints])
    if config.poses:
        targets = [np.array(q) for q in config.poses.values()]
    else:  # about the middle of the range: there and back, a fifth of the range each way
        mid, span = (lower + upper) / 2, (upper - lower) / 10
        targets = [mid + span, mid - span]
    start = np.clip(targets[0], lower, upper)
    print(f"bench: {config.name}, {len(config.joints)} joints at {config.rate_hz:g} Hz for {args.seconds:g} s "
          f"against the simulator (moving between {len(targets)} poses)", flush=True)
    moves = 0
    with SimulatedRobot(config, realtime=True, q0=start) as sim, \
            controlled(Arm(config, feedback_timeout=0.5)) as arm:
        arm.enable()
        cpu0, wall0, th0 = time.process_time(), time.monotonic(), _thread_cpu()
        end = wall0 + args.seconds
        k = 1 % len(targets)
        while time.monotonic() < end:
            motion = arm.move_to(targets[k], wait=False)
            moves += 1
            while not motion.done and time.monotonic() < end:
                arm.sleep(min(0.05, max(0.0, end - time.monotonic())))
            if motion.done:
                motion.wait()  # raises the arm's safety stop, if that is what ended it
            k = (k + 1) % len(targets)
        cpu1, wall1, th1 = time.process_time(), time.monotonic(), _thread_cpu()
        stats = arm.stats()
        arm.disable()
        slip = sim.slip
    wall = wall1 - wall0
    print(stats.table())
    line = f"CPU: {100 * (cpu1 - cpu0) / wall:.0f} % of one core for the whole process"
    if th0 and th1:
        loop0, sim0 = _group(th0)
        loop1, sim1 = _group(th1)
        line += f" (control loop {100 * (loop1 - loop0) / wall:.0f} %, simulator {100 * (sim1 - sim0) / wall:.0f} %)"
    print(line)
    print(f"{moves} moves in {wall:.2f} s" + (f"; the simulator fell {slip:.3f} s behind the wall clock" if slip > 0.001
                                               else ""))
    return 0
