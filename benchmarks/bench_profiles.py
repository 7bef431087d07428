"""What loop rate, watchdog and simulator rate a machine keeps: the numbers behind akarm.timing's profiles.

An Arm in this process against ``akarm sim`` in a process of its own, in real time, moving between the
robot's poses for a while, per (loop rate, simulator rate). Printed per run: how long enable took,
the age of the joints' feedback as the loop saw it (sampled every 50 ms: p50, p99, max), missed
loop slots, how far the simulator fell behind the wall clock, the largest error when a motion ended
and how long after that every joint was within 30 mrad, and the CPU of both processes.

Run it where the profile is for, e.g. inside the emulated SocketCAN machine::

    ../shared/tools/vcan-vm -- .venv/bin/python benchmarks/bench_profiles.py -i socketcan 50:250 25:250
    .venv/bin/python benchmarks/bench_profiles.py 500:2000 50:250         # this machine, akarm_local

The watchdog is set out of reach (10 s) so a run measures instead of stopping.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from akarm.sim.process import stat_cpu_seconds
from akarm.testing.rig import SimulatedArm
from akarm.timing import PROFILES

SETTLED = 0.03  # rad


def run(robot: str, interface: str, loop_hz: float, sim_hz: float, seconds: float) -> None:
    profile = replace(PROFILES["slow"], name=f"bench-{loop_hz:g}-{sim_hz:g}", max_rate_hz=loop_hz,
                      feedback_timeout=10.0, min_feedback_timeout=10.0, enable_timeout=30.0, sim_rate_hz=sim_hz)
    with SimulatedArm.start(robot, interface, timing=profile, pose=None) as rig:
        poses = list(rig.config.poses)
        sim_cpu0 = stat_cpu_seconds(f"/proc/{rig.process.pid}/stat")  # type: ignore[attr-defined]
        cpu0, wall0 = time.process_time(), time.monotonic()
        with rig.arm() as arm:
            t0 = time.monotonic()
            arm.enable()
            enable = time.monotonic() - t0
            ages: list[float] = []
            end_errors, settle = [], []
            end = time.monotonic() + seconds
            k = 0
            while time.monotonic() < end:
                target = np.array(rig.config.pose(poses[k % len(poses)]))
                k += 1
                motion = arm.move_to(target, wait=False)
                while not motion.done:
                    ages.append(max(j.age for j in arm.state().joints))
                    arm.sleep(0.05)
                motion.wait()
                t_end = time.monotonic()
                end_errors.append(np.abs(arm.state().q - target).max())
                while np.abs(arm.state().q - target).max() > SETTLED and time.monotonic() - t_end < 10.0:
                    ages.append(max(j.age for j in arm.state().joints))
                    arm.sleep(0.05)
                settle.append(time.monotonic() - t_end)
            stats = arm.stats()
        wall = time.monotonic() - wall0
        cpu = time.process_time() - cpu0
        sim_cpu = stat_cpu_seconds(f"/proc/{rig.process.pid}/stat") - sim_cpu0  # type: ignore[attr-defined]
        slip = rig.process.control.request(cmd="state")["slip"]  # type: ignore[attr-defined]
    a = np.array(ages) * 1e3
    print(f"loop {loop_hz:g} Hz, simulator {sim_hz:g} Hz: enable {enable:.2f} s; {k} moves; feedback age "
          f"p50 {np.percentile(a, 50):.0f} ms, p99 {np.percentile(a, 99):.0f} ms, max {a.max():.0f} ms; "
          f"missed slots {stats.missed} of {stats.cycles + stats.missed}; simulator behind by {slip:.2f} s; "
          f"error at a motion's end max {max(end_errors) * 1e3:.0f} mrad, within {SETTLED * 1e3:.0f} mrad "
          f"after {np.median(settle):.2f} s (median), {max(settle):.2f} s (max); "
          f"CPU: arm {100 * cpu / wall:.0f} %, simulator {100 * sim_cpu / wall:.0f} %", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="LOOP:SIM", help="loop rate and simulator rate, Hz")
    parser.add_argument("--robot", default="robots/arm6.yaml")
    parser.add_argument("-i", "--interface", default="akarm_local", choices=["akarm_local", "socketcan"])
    parser.add_argument("--seconds", type=float, default=30.0, help="per run (default 30)")
    args = parser.parse_args()
    for spec in args.runs:
        loop_hz, sim_hz = (float(x) for x in spec.split(":"))
        run(args.robot, args.interface, loop_hz, sim_hz, args.seconds)


if __name__ == "__main__":
    main()
