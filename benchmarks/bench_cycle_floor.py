"""The floor under the cycle's compute: what the library calls alone that akarm's cycle cannot
avoid cost in a loop that sleeps between cycles, against the same calls run back to back.

    .venv/bin/python benchmarks/bench_cycle_floor.py                # 10 s per case
    .venv/bin/python benchmarks/bench_cycle_floor.py --hold-idle    # CPUs held out of deep idle (root)

A thread at 480 Hz (arm6's rate), sleeping to absolute deadlines as a plain loop does, runs each
cycle one of:

- ``ruckig``: sampling a 6-joint jerk-limited trajectory (``Trajectory.at_time``);
- ``libraries``: that, and the four Pinocchio passes at the sampled state: the collision observer's
  three (Coriolis matrix, gravity, RNEA at zero velocity) and the feed-forward's RNEA, with their
  numpy conversions;
- ``+ codec``: that, and encoding six MIT commands with akarm's codec.

Printed per case: the compute per cycle (mean, p50, p99), the process CPU per cycle, and the same
work back to back (warm: its median). This is how much of the cycle's budget is spent before any
of akarm's own supervision runs: on a core that sleeps between cycles, every cycle starts cold.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import ruckig  # noqa: E402
from bench_cpu_peer import hold_idle  # noqa: E402 (this folder: the same request, the same refusal)

import akarm  # noqa: E402
from akarm.dynamics.model import RobotModel  # noqa: E402
from akarm.protocol.mit import MitCodec  # noqa: E402

RATE = 480.0
CASES = ("ruckig", "libraries", "+ codec")


def make_cycle(case: str):
    cfg = akarm.load_robot(ROOT / "robots" / "arm6.yaml")
    model = RobotModel(cfg)
    pm, pd = model.pin_model, model.pin_data
    n = len(cfg.joints)
    inp = ruckig.InputParameter(n)
    inp.current_position = [0.0] * n
    inp.target_position = [0.8, -0.5, 0.6, 0.3, -0.4, 0.5][:n]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [2.0] * n, [6.0] * n, [40.0] * n
    traj = ruckig.Trajectory(n)
    ruckig.Ruckig(n).calculate(inp, traj)
    duration = traj.duration
    zero = np.zeros(n)
    codecs = [MitCodec(j.motor) for j in cfg.joints]

    def cycle(t: float) -> None:
        p, v, a = traj.at_time(t % duration)
        if case == "ruckig":
            return
        q, dq = np.array(p), np.array(v)
        pin.computeCoriolisMatrix(pm, pd, q, dq).tolist()
        pin.computeGeneralizedGravity(pm, pd, q).tolist()
        pin.rnea(pm, pd, q, zero, dq).tolist()
        pin.rnea(pm, pd, q, dq, np.array(a)).tolist()
        if case == "libraries":
            return
        for c, x, y in zip(codecs, p, v, strict=True):
            c.encode_command(x, y, 30.0, 1.0, 0.5)

    return cycle


def run(case: str, seconds: float) -> dict[str, float]:
    cycle = make_cycle(case)
    period, pc = 1.0 / RATE, time.perf_counter
    compute: list[float] = []
    cpu0 = time.process_time()
    t0 = pc()
    deadline = t0 + period
    while True:
        now = pc()
        if now < deadline:
            time.sleep(deadline - now)
        start = pc()
        if start - t0 > seconds:
            break
        cycle(start - t0)
        compute.append(pc() - start)
        deadline += period
        if pc() > deadline:  # a slot gone by: skip it
            deadline += period * int((pc() - deadline) / period + 1)
    cpu = (time.process_time() - cpu0) / len(compute)
    warm = []
    for k in range(2000):
        start = pc()
        cycle(k * period)
        warm.append(pc() - start)
    compute.sort()
    warm.sort()
    return {"mean": sum(compute) / len(compute), "p50": compute[len(compute) // 2],
            "p99": compute[int(0.99 * (len(compute) - 1))], "cpu": cpu, "warm": warm[len(warm) // 2]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="length of each case's run, s")
    ap.add_argument("--hold-idle", action="store_true", help="hold every CPU out of deep idle states (needs root)")
    args = ap.parse_args()
    hold = hold_idle() if args.hold_idle else None
    print(f"arm6, 6 joints, {RATE:g} Hz, sleeping loop, {args.seconds:g} s per case"
          + ("; CPU idle latency held at 0 µs" if hold is not None else ""))
    print(f"{'case':>10} {'mean':>7} {'p50':>7} {'p99':>7} {'CPU/c':>7} {'warm':>7}   (µs)")
    us = 1e6
    for case in CASES:
        r = run(case, args.seconds)
        print(f"{case:>10} {r['mean'] * us:7.1f} {r['p50'] * us:7.1f} {r['p99'] * us:7.1f} {r['cpu'] * us:7.1f} "
              f"{r['warm'] * us:7.1f}", flush=True)
    if hold is not None:
        hold.release()


if __name__ == "__main__":
    main()
