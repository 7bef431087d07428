"""Simulator benchmark: real-time factor (simulated seconds per wall second) in lock step.

    .venv/bin/python benchmarks/bench_sim.py                    # arm6 at 2 kHz, 10 simulated seconds each
    .venv/bin/python benchmarks/bench_sim.py --robot planar2 --rates 1000 2000 4000 --seconds 5

For each plant rate it measures, on a python-can virtual bus in lock step (no threads):

- ``plant only``: the arm with no controller (limp, falling under gravity onto its hard stops);
- ``+ MIT 500 Hz``: a test bus sends one MIT command per joint every 2 ms (a hold at the start pose,
  after ENTER), the simulator decodes each, answers with a state reply, and the test side drains
  the replies: the cost of the wire protocol at a controller's rate, without the controller.

Real-time factor = simulated seconds / wall seconds (above 1: faster than real time). Per-step cost
= wall time / plant steps.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import can  # noqa: E402

from akarm.protocol import mit  # noqa: E402
from akarm.robotfile.load import load_robot  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402


def run(robot: str, rate: float, seconds: float, with_commands: bool, channel: str) -> tuple[float, float, int]:
    """(real-time factor, µs per plant step, frames answered) for one configuration."""
    config = load_robot(ROOT / "robots" / f"{robot}.yaml")
    start_pose = config.pose("home") if "home" in config.poses else None
    with SimulatedRobot(config, "virtual", channel, realtime=False, dt=1.0 / rate, q0=start_pose) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        mit_joints = [j for j in config.joints if j.mode == "mit" and j.firmware == "v2"]
        commands = [can.Message(arbitration_id=j.can_id, is_extended_id=False,
                                data=mit.encode_command(j.motor, (sim.q[i] - j.offset) * j.direction, 0.0,
                                                        j.gains.kp, j.gains.kd, 0.0))
                    for i, j in enumerate(config.joints) if j in mit_joints]
        if with_commands:
            for j in mit_joints:
                bus.send(can.Message(arbitration_id=j.can_id, data=mit.ENTER, is_extended_id=False))
        period = 0.002
        answered = 0
        steps0 = sim.plant.steps
        t0 = time.perf_counter()
        t = 0.0
        while t < seconds - 1e-9:
            if with_commands:
                for msg in commands:
                    bus.send(msg)
            t += period
            sim.clock.sleep_until(t)
            if with_commands:
                while bus.recv(timeout=0.0) is not None:
                    answered += 1
        wall = time.perf_counter() - t0
        steps = sim.plant.steps - steps0
    return seconds / wall, wall / steps * 1e6, answered


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="arm6", help="robot under robots/ (default arm6)")
    parser.add_argument("--rates", type=float, nargs="+", default=[2000.0], help="plant rates, Hz (default 2000)")
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run (default 10)")
    args = parser.parse_args()
    print(f"akarm simulator, {args.robot}, lock step on a virtual bus, {args.seconds:g} simulated s per run")
    print(f"{'plant rate':>10}  {'load':<16} {'real-time factor':>16}  {'µs/step':>8}  {'replies':>8}")
    for rate in args.rates:
        for with_commands in (False, True):
            rtf, per_step, answered = run(args.robot, rate, args.seconds, with_commands,
                                          f"bench-sim-{rate:g}-{with_commands}")
            load = "+ MIT 500 Hz" if with_commands else "plant only"
            print(f"{rate:>8g} Hz  {load:<16} {rtf:>15.1f}x  {per_step:>8.1f}  {answered:>8d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
