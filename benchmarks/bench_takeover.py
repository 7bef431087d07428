"""How far an arm sags when an enable takes it over from a controller that died holding it.

In lock step: the simulated drivers are left in motor mode holding the robot's pose with its gains (a
controller that died without its exit frames: the drivers keep applying its last command), the arm
comes to rest there; then an :class:`~akarm.Arm` enables it. Until contact is made the enable commands
the drivers limp (their stored command is not ours to keep), and the arm falls meanwhile. Printed per
robot and timing profile: the largest sag during the enable and the ramp after it (mrad, the joint), and
how far from where it was the arm is held.

    .venv/bin/python benchmarks/bench_takeover.py                 # planar2 and arm6, normal and slow

docs/turn-counts.md quotes its numbers.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

from akarm import Arm, load_robot
from akarm.sim import SimulatedRobot

ROBOTS = Path(__file__).resolve().parent.parent / "robots"
HOLD = {"planar2": "home", "arm6": "reach"}  # poses held against gravity (as the fault matrix's)


def run(robot: str, timing: str) -> tuple[float, str, float]:
    """The largest sag during the enable and 0.5 s after it (rad), its joint, and the held offset (rad)."""
    config = load_robot(ROBOTS / f"{robot}.yaml").with_bus(interface="virtual", channel=f"takeover-{robot}-{timing}")
    pose = np.array(config.pose(HOLD[robot]))
    with SimulatedRobot(config, realtime=False, q0=pose, timing=timing) as sim:
        for j, d, q in zip(config.joints, sim.drivers, pose, strict=True):  # the dead controller's last command
            d.stored_command = ((q - j.offset) * j.direction, 0.0, j.gains.kp, j.gains.kd, 0.0)
            d.enabled = True
        sim.run_for(1.0)  # at rest under it
        before = sim.q.copy()
        worst = np.zeros(len(before))

        def watch(_t: float) -> None:
            np.maximum(worst, np.abs(sim.q - before), out=worst)

        with tempfile.TemporaryDirectory() as state, \
                Arm(config, clock=sim.clock, timing=timing, remember_positions=Path(state) / "p.json") as arm:
            sim.clock.attach(watch)
            arm.enable(accept_position=True)
            arm.sleep(0.5)
            held = float(np.max(np.abs(arm.state().q_des - before)))
            sim.clock.detach(watch)
        k = int(np.argmax(worst))
        return float(worst[k]), config.joints[k].name, held


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=["planar2", "arm6"])
    ap.add_argument("--timings", nargs="+", default=["normal", "slow"])
    args = ap.parse_args()
    print(f"{'robot':8} {'timing':7} {'sag max (mrad)':>15} {'joint':14} {'held off (mrad)':>16}")
    for robot in args.robots:
        for timing in args.timings:
            sag, joint, held = run(robot, timing)
            assert math.isfinite(sag)
            print(f"{robot:8} {timing:7} {sag * 1e3:15.2f} {joint:14} {held * 1e3:16.2f}")


if __name__ == "__main__":
    main()
