"""How the cycle's compute grows with the number of joints: arm6 driving its first 1, 2, ... 6 joints.

    .venv/bin/python benchmarks/bench_joint_growth.py              # 3 rounds, 6 s of moves each
    .venv/bin/python benchmarks/bench_joint_growth.py --rounds 1 --seconds 3
    .venv/bin/python benchmarks/bench_joint_growth.py --interface akarm_local

For k = 1..6, a robot file that is robots/arm6.yaml with only its first k joints (the others
``locked:`` at zero), its named poses cut to k values, run in lock step against the simulator in
this process on python-can's ``virtual`` bus, or with ``--interface akarm_local`` on that (the
loop's clock is the simulator's: the compute is the controller's own, nothing else running
meanwhile), moving between the poses at full speed,
every check and the collision reflex on. Per k: the compute per cycle (mean and p99) and each
stage's mean, µs; then the least-squares growth per joint of the mean compute and of each stage
(µs per joint), with the rounds' spread. (Receive and send include the bus's own cost: on ``virtual``
a deep copy of every message and a queue per receiver, more than a SocketCAN frame costs; on
``akarm_local`` a slot of shared memory, which the loop reads and writes by a frame's fields.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402

ARM6 = ROOT / "robots" / "arm6.yaml"
POSES = ("ready", "left", "home", "reach", "home")


def first_joints(k: int, directory: Path) -> Path:
    """arm6's robot file driving its first ``k`` joints only."""
    doc = yaml.safe_load(ARM6.read_text())
    doc["name"] = f"arm6_first{k}"
    doc["urdf"] = str(ARM6.parent / doc["urdf"])
    doc["locked"] = {j["name"]: 0.0 for j in doc["joints"][k:]}
    doc["joints"] = doc["joints"][:k]
    doc["poses"] = {name: q[:k] for name, q in doc["poses"].items()}
    path = directory / f"arm6_first{k}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def measure(robot: Path, seconds: float, interface: str) -> tuple[float, float, dict[str, float]]:
    config = akarm.load_robot(robot).with_bus(interface=interface, channel=f"growth-{robot.stem}")
    with SimulatedRobot(config, realtime=False, q0=config.pose("home")) as sim, \
            akarm.Arm(config, clock=sim.clock, remember_positions=False) as arm:
        arm.enable()
        arm.move_to("ready")
        arm.reset_stats()
        t0, k = arm.clock.now(), 0
        while arm.clock.now() - t0 < seconds:
            arm.move_to(POSES[k % len(POSES)])
            k += 1
        s = arm.stats()
        arm.disable()
    return s.compute_mean * 1e6, s.compute_p99 * 1e6, {name: v * 1e6 for name, v in s.stage_mean.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=6.0, help="simulated seconds of moves per robot and round")
    ap.add_argument("--interface", choices=("virtual", "akarm_local"), default="virtual")
    args = ap.parse_args()
    directory = Path(tempfile.mkdtemp(prefix="joint-growth-"))
    robots = {k: first_joints(k, directory) for k in range(1, 7)}
    print(f"akarm {akarm.__version__}: compute per cycle against the number of joints (arm6's first k), lock step, "
          f"{args.rounds} rounds of {args.seconds:g} s, on {args.interface}")
    slopes: dict[str, list[float]] = {}
    for r in range(args.rounds):
        rows = {k: measure(robot, args.seconds, args.interface) for k, robot in robots.items()}
        stages = list(next(iter(rows.values()))[2])
        print(f"\nround {r + 1}\n{'joints':>6} {'compute':>8} {'p99':>7}   " + " ".join(f"{s:>11}" for s in stages))
        for k, (mean, p99, stage) in rows.items():
            print(f"{k:6d} {mean:8.1f} {p99:7.1f}   " + " ".join(f"{stage[s]:11.1f}" for s in stages))
        ks = np.array(list(rows), dtype=float)
        for what, ys in [("compute", [rows[k][0] for k in rows])] + [(s, [rows[k][2][s] for k in rows])
                                                                     for s in stages]:
            slopes.setdefault(what, []).append(float(np.polyfit(ks, np.array(ys), 1)[0]))
    print("\ngrowth per joint, µs (least squares over k = 1..6; mean ± spread across rounds):")
    for what, values in slopes.items():
        v = np.array(values)
        print(f"  {what:12s} {v.mean():6.1f} ± {v.std():4.1f}")


if __name__ == "__main__":
    main()
