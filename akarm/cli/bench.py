"""``akarm bench ROBOT.yaml``: measure the control loop's timing against the simulator.

::

    akarm bench robots/arm6.yaml                    # 5 s at the file's rate_hz
    akarm bench robots/arm6.yaml --loop-rate 1000 --seconds 10 --busy-wait --realtime-priority
    akarm bench robots/arm6.yaml -i socketcan -c vcan0     # the simulator on SocketCAN vcan0 instead

Runs the arm against a real-time simulator in a process of its own (``akarm sim``) on a private
``akarm_local`` channel (the file's buses are not used: no hardware is touched; ``-i/-c/-b`` put the
simulator and the arm on another bus, e.g. SocketCAN ``vcan0``), moving between the
file's poses (or small moves about the starting pose when it has none), then prints the loop's
statistics (achieved rate, period and lateness percentiles, missed slots, time per stage) and the
CPU used by the control loop, the rest of this process and the simulator. ``--in-process`` puts the
simulator in this process instead (python-can ``virtual`` bus), where it competes with the loop for
the interpreter lock: slower, and what a notebook running both sees.

The feedback watchdog is relaxed to 0.5 s here (a busy machine would otherwise stop the run): this
measures timing, not safety.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import threading
import time

from akarm import compiled
from akarm.cli.common import add_profile_argument, loop_options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.common import add_robot_arguments
    from akarm.cli.options import duration, renamed

    add_robot_arguments(parser)
    parser.add_argument("--seconds", type=duration, default=5.0, metavar="S", help="how long to run (default 5)")
    parser.add_argument("--loop-rate", type=float, metavar="HZ", help="loop rate (default: the file's rate_hz)")
    renamed(parser, "--rate", "--loop-rate")
    parser.add_argument("--busy-wait", action="store_true",
                        help="the loop keeps its core between cycles: faster cycles for a whole core")
    parser.add_argument("--realtime-priority", action="store_true",
                        help="ask for SCHED_FIFO, locked memory and the CPUs held out of deep idle states")
    parser.add_argument("--in-process", action="store_true",
                        help="run the simulator in this process, on a virtual bus, instead of in its own")
    add_profile_argument(parser)


def _thread_cpu() -> dict[str, float]:
    """CPU seconds per thread name (Linux /proc; empty elsewhere), summed over threads of the same name."""
    from akarm.sim.process import stat_cpu_seconds

    out: dict[str, float] = {}
    for th in threading.enumerate():
        seconds = stat_cpu_seconds(f"/proc/self/task/{th.native_id}/stat")
        if seconds == seconds:  # not NaN
            out[th.name] = out.get(th.name, 0.0) + seconds
    return out


def _group(cpu: dict[str, float]) -> tuple[float, float]:
    loop = sum(v for k, v in cpu.items() if k == "akarm-loop")
    sim = sum(v for k, v in cpu.items() if k.startswith("akarm-sim"))
    return loop, sim


# C901 15 > 12, left as it was: the bench verb runs and reports in one pass, a branch per option
def run(args: argparse.Namespace) -> int:  # noqa: C901
    """Run the arm against the simulator for ``--seconds``; print the loop statistics and CPU use."""
    from dataclasses import replace

    import numpy as np

    from akarm.arm import Arm
    from akarm.cli.common import controlled
    from akarm.config import parse_channel
    from akarm.errors import ArgumentError
    from akarm.robotfile.load import load_robot
    from akarm.sim import SimulatedRobot
    from akarm.sim.process import SimulatorProcess
    from akarm.timing import get_profile

    if not args.seconds > 0:
        raise ArgumentError(f"--seconds {args.seconds} must be positive")
    if args.loop_rate is not None and not args.loop_rate > 0:
        raise ArgumentError(f"--loop-rate {args.loop_rate} must be positive", fix="e.g. --loop-rate 500")
    config = load_robot(args.robot)
    interface = args.interface or ("virtual" if args.in_process else "akarm_local")
    channel = args.channel or f"akarm-bench-{os.getpid()}-{time.monotonic_ns()}"
    config = config.with_bus(interface=interface, channel=parse_channel(channel), bitrate=args.bitrate,
                             options=args.bus_kwargs or None)
    config = replace(config, joints=tuple(replace(j, feedback_timeout=None) for j in config.joints))
    if args.loop_rate is not None:
        config = replace(config, rate_hz=float(args.loop_rate))
    config = get_profile(args.profile).apply(config)
    lower = np.array([j.limits.lower for j in config.joints])
    upper = np.array([j.limits.upper for j in config.joints])
    if config.poses:
        targets = [np.array(q) for q in config.poses.values()]
    else:  # about the middle of the range: there and back, a fifth of the range each way
        mid, span = (lower + upper) / 2, (upper - lower) / 10
        targets = [mid + span, mid - span]
    start = np.clip(targets[0], lower, upper)
    where = "in this process" if args.in_process else "in its own process"
    print(f"bench: {config.name}, {len(config.joints)} joints at {config.rate_hz:g} Hz for {args.seconds:g} s "
          f"against the simulator {where} (moving between {len(targets)} poses); the control cycle: "
          f"{compiled.status()}", flush=True)
    with contextlib.ExitStack() as stack:
        sim: SimulatedRobot | SimulatorProcess
        if args.in_process:
            sim = stack.enter_context(SimulatedRobot(config, realtime=True, q0=start, timing=args.profile))
        else:
            first = next(iter(config.poses), None)
            more = ["-b", str(args.bitrate)] if args.bitrate is not None else []
            if args.bus_kwargs:
                more += ["--bus-kwargs", *(f"{k}={v}" for k, v in args.bus_kwargs.items())]
            sim = stack.enter_context(SimulatorProcess(args.robot, interface=interface, channel=channel, pose=first,
                                                       args=more, timing=args.profile))
        arm = stack.enter_context(controlled(Arm(config, feedback_timeout=0.5, busy_wait=args.busy_wait,
                                                 realtime_priority=args.realtime_priority,
                                                 **loop_options(args))))
        arm.enable()
        cpu0, wall0, th0 = time.process_time(), time.monotonic(), _thread_cpu()
        sim0 = sim.cpu_seconds() if isinstance(sim, SimulatorProcess) else 0.0
        end = wall0 + args.seconds
        k = 1 % len(targets)
        moves = 0
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
        report = arm.realtime_report
        arm.disable()
        if isinstance(sim, SimulatorProcess):
            sim_cpu, slip = sim.cpu_seconds() - sim0, 0.0
        else:
            sim_cpu, slip = math.nan, sim.slip
    wall = wall1 - wall0
    print(stats.table())
    line = f"CPU: {100 * (cpu1 - cpu0) / wall:.0f} % of one core for this process"
    if th0 and th1:
        loop0, thread_sim0 = _group(th0)
        loop1, thread_sim1 = _group(th1)
        line += f" (control loop {100 * (loop1 - loop0) / wall:.0f} %)"
        if args.in_process:
            sim_cpu = thread_sim1 - thread_sim0
    if sim_cpu == sim_cpu:
        line += f"; simulator {100 * sim_cpu / wall:.0f} %"
    print(line)
    if args.busy_wait or args.realtime_priority:
        print(f"real time: {report}")
    print(f"{moves} moves in {wall:.2f} s" + (f"; the simulator fell {slip:.3f} s behind the wall clock" if slip > 0.001
                                               else ""))
    return 0
