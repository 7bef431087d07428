"""Cost of the rigid-body model calls the control loop and the simulator make, per robot.

    .venv/bin/python benchmarks/bench_model.py [--calls N] [--repeat R]

For each robot in ``robots/`` it times N calls of each :class:`akarm.dynamics.model.RobotModel` method at a
pose of the robot (best of R runs, since other processes only ever make a run slower) and prints
µs per call: ``gravity`` (the loop's gravity-only feed-forward, and teach mode), ``inverse_dynamics``
(RNEA, the default feed-forward), ``forward_dynamics`` (ABA, the simulator's plant) and
``mass_matrix`` (CRBA). The whole control cycle is ``bench_loop.py``'s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm import load_robot  # noqa: E402
from akarm.dynamics.model import RobotModel  # noqa: E402


def per_call(fn, fn_args: tuple, calls: int, repeat: int) -> float:
    fn(*fn_args)
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn(*fn_args)
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"model calls, µs per call (best of {args.repeat} x {args.calls})")
    print(f"{'robot':>8} {'joints':>6} {'gravity':>9} {'inv.dyn.':>9} {'fwd.dyn.':>9} {'mass mat.':>9}")
    for yaml in sorted((ROOT / "robots").glob("*.yaml")):
        config = load_robot(yaml)
        model = RobotModel(config)
        pose = next(iter(config.poses), None)
        q = np.array(config.pose(pose)) if pose else np.zeros(len(config.joints))
        v, a = np.full_like(q, 0.5), np.full_like(q, 1.0)
        cols = [per_call(f, f_args, args.calls, args.repeat) * 1e6 for f, f_args in (
            (model.gravity, (q,)), (model.inverse_dynamics, (q, v, a)),
            (model.forward_dynamics, (q, v, a)), (model.mass_matrix, (q,)))]
        print(f"{config.name:>8} {len(config.joints):>6} " + " ".join(f"{c:9.1f}" for c in cols))


if __name__ == "__main__":
    main()
