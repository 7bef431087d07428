"""Servo joints over UART against CAN: tracking error and CPU time of one program, both ways.

servo3 runs one program (enable; moves through its poses; a replayed path: a 4 s sweep of every
joint; disable) three times: every joint over CAN, every joint over UART (a serial port each, the
simulated drivers on pseudo-terminal pairs: ``akarm_uart``), and pan alone over UART with the other
two on CAN. Printed per run and joint: the RMS and largest tracking error (commanded minus measured)
while the arm moves, the largest error 0.5 s after each move ends, and the CPU time per control
cycle of this process (controller and simulator together).

Lock step by default (``SimulatedRobot(realtime=False)``): the numbers depend on nothing but the code.
``--realtime`` runs the simulator in a process of its own (``akarm sim --serial JOINT=pty``) and the
loop in real time instead, where the machine's load shows (the watchdogs are relaxed to 0.5 s, the
following error to 3 rad and the serial line's to 100 bad polls, so that a loaded machine's pauses
measure rather than stop)::

    .venv/bin/python benchmarks/bench_uart.py
    .venv/bin/python benchmarks/bench_uart.py --realtime
"""

from __future__ import annotations

import argparse
import itertools
import os
import time
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

import akarm
from akarm.motion.recording import PathRecording
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot
from akarm.testing.rig import SimulatedArm
from akarm.timing import PROFILES

ROBOT = Path(__file__).resolve().parent.parent / "robots" / "servo3.yaml"
RUNS = {"CAN": (), "UART (all)": ("pan", "shoulder", "elbow"), "UART (pan) + CAN": ("pan",)}
_channels = itertools.count()


def sweep(arm: akarm.Arm, seconds: float = 4.0) -> PathRecording:
    """A path from the middle of every joint's range, one, two and three periods, starting and ending at rest
    (position, speed and acceleration continuous)."""
    t = np.arange(0.0, seconds + 0.01, 0.02)
    lo, hi = np.array(arm.limits.lower), np.array(arm.limits.upper)
    mid, amp = (lo + hi) / 2, np.minimum((hi - lo) / 4, 0.5)
    q = mid + amp * ((1 - np.cos(2 * np.pi * np.outer(t, [1.0, 2.0, 3.0]) / seconds)) / 2) ** 2
    return PathRecording(arm.names, t, q)


def program(arm: akarm.Arm, settle: float = 0.5) -> dict[str, Any]:
    """The program; what it measured."""
    cpu0, cycles0 = time.process_time(), arm.stats().cycles
    arm.enable()
    t_start = arm.state().time
    moving: list[tuple[float, float]] = []
    after: list[np.ndarray] = []
    for pose in [*arm.config.poses, *list(arm.config.poses)[:1]]:
        t0 = arm.state().time
        arm.move_to(pose)
        moving.append((t0, arm.state().time))
        arm.sleep(settle)
        after.append(np.abs(arm.state().q - np.array(arm.config.pose(pose))))
    t0 = arm.state().time
    arm.replay(sweep(arm))
    moving.append((t0, arm.state().time))
    arm.sleep(settle)
    arm.disable()
    log = arm.telemetry(since=t_start)
    inside = np.zeros(len(log.t), bool)
    for a, b in moving:
        inside |= (log.t >= a) & (log.t <= b)
    e = log.tracking_error()[inside]
    return {"rms": np.sqrt(np.mean(e * e, axis=0)), "max": np.abs(e).max(axis=0), "after": np.max(after, axis=0),
            "cpu_per_cycle": (time.process_time() - cpu0) / max(1, arm.stats().cycles - cycles0)}


def lockstep(serial: Sequence[str]) -> dict[str, Any]:
    config = load_robot(ROBOT).with_bus(interface="virtual", channel=f"bench-uart-{os.getpid()}-{next(_channels)}")
    with SimulatedRobot(config, realtime=False, serial=dict.fromkeys(serial, "pty")) as sim, \
            akarm.Arm(sim.config, clock=sim.clock, telemetry_seconds=60.0) as arm:
        return program(arm)


def realtime(serial: Sequence[str]) -> dict[str, Any]:
    """The simulator in its own process; the watchdogs relaxed (a loaded machine pauses either process)."""
    profile = replace(PROFILES["normal"], name="bench-uart", feedback_timeout=0.5, min_feedback_timeout=0.5)
    with ExitStack() as stack:
        rig = stack.enter_context(SimulatedArm.start(ROBOT, "akarm_local", serial=serial, timing=profile))
        config = replace(rig.config, buses={k: replace(b, options={**b.options, "errors_in_row": 100})
                                            if b.interface == "akarm_uart" else b for k, b in rig.config.buses.items()},
                         joints=tuple(replace(j, following_error=3.0, stuck_travel=3.0) for j in rig.config.joints))
        arm = stack.enter_context(akarm.Arm(config, timing=profile, telemetry_seconds=60.0,
                                                  remember_positions=False))
        return program(arm)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realtime", action="store_true", help="the simulator in its own process, in real time")
    args = parser.parse_args(argv)
    how = "real time, akarm sim in its own process" if args.realtime else "lock step, in process"
    print(f"servo3, {how}; load average {', '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} CPUs")
    print("tracking error while moving (mrad): RMS and max per joint (pan, shoulder, elbow); 0.5 s after each move: "
          "max; CPU per cycle (this process)")
    for name, serial in RUNS.items():
        r = realtime(serial) if args.realtime else lockstep(serial)
        fmt = "/".join(f"{1e3 * x:5.1f}" for x in r["rms"])
        print(f"  {name:18s} rms {fmt}   max {'/'.join(f'{1e3 * x:5.1f}' for x in r['max'])}   "
              f"after {'/'.join(f'{1e3 * x:4.2f}' for x in r['after'])}   cpu {1e6 * r['cpu_per_cycle']:6.0f} µs")


if __name__ == "__main__":
    main()
