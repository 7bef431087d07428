"""Servoing and impedance on the simulated arm6: their cost per cycle and the servo latency.

    .venv/bin/python benchmarks/bench_compliance.py [--cycles N]

Cost: the per-cycle work alone, on this thread (no loop, no bus): a ServoStream stepping a +z twist from
`ready` (plain; inside a workspace box; with self-collision), and an ImpedanceLaw from measured
states along a push. Self-collision: the supervisor's check of a measured pose, and the planner's
check of a planned move's path. Then the whole control cycle in lock step (compute per cycle, the loop's own
stage times) holding, servoing, and under impedance.

Latency: commands given at random moments between cycles in lock step; the time from the command to
the first cycle (the first frame sent) that used it, in plan time.
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
from akarm.arm import Arm  # noqa: E402
from akarm.config.workspace import Workspace  # noqa: E402
from akarm.control.impedance import ImpedanceLaw  # noqa: E402
from akarm.dynamics.model import RobotModel  # noqa: E402
from akarm.dynamics.selfcollision import SelfCollision  # noqa: E402
from akarm.motion.servo import ServoStream  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402

ARM6 = load_robot(ROOT / "robots" / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))


def us(samples: list[float]) -> str:
    a = np.array(samples) * 1e6
    return f"median {np.median(a):6.1f} µs, p99 {np.percentile(a, 99):6.1f} µs"


def stream_cost(cycles: int) -> None:
    arm = Arm(ARM6.with_bus(interface="virtual", channel="bench-compliance-limits"), remember_positions=False)
    top = RobotModel(ARM6).tool_pose(READY)[2, 3] + 0.5
    for label, walls, sc in (("servo step", None, None),
                             ("servo step, workspace box", Workspace.box([-1, -1, -0.5], [1, 1, top]), None),
                             ("servo step, self-collision", None, SelfCollision(ARM6, margin=0.01))):
        s = ServoStream(RobotModel(ARM6), arm.limits, walls, 1 / 480, 0.1, "base", 0.25, 1.0, sc)
        s.begin((READY, np.zeros(6), np.zeros(6)), 0.0)
        times = []
        for k in range(1, cycles + 1):
            s.command_twist(np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.0]), k / 480)
            t0 = time.perf_counter()
            s.sample(k / 480)
            times.append(time.perf_counter() - t0)
        print(f"  {label:<28} {us(times)}")
    model = RobotModel(ARM6, armature=True)
    torque_limit = [j.limits.torque for j in ARM6.joints]
    law = ImpedanceLaw(model, ARM6.joint_names, torque_limit, READY, np.array([500.0] * 3 + [30.0] * 3), None, 1.0,
                       (0.1, 0.5), [0.0] * 6, [0.0] * 6)
    rng = np.random.default_rng(3)
    times = []
    for k in range(cycles):
        q = READY + rng.normal(0.0, 0.01, 6)
        t0 = time.perf_counter()
        law.step(k / 480, q.tolist(), rng.normal(0.0, 0.05, 6).tolist())
        times.append(time.perf_counter() - t0)
    print(f"  {'impedance step (Cartesian)':<28} {us(times)}")


def self_collision_cost(cycles: int) -> None:
    """The supervisor's check of a measured pose (a check every 4th cycle at 480 Hz) and the planner's check of
    a planned move's path (every 10 ms of it)."""
    from akarm.control.selfcollision import SelfCollisionGuard
    from akarm.motion.trajectory import JointLimits, Planner
    from akarm.motion.walls import path_samples

    sc = SelfCollision(ARM6, margin=0.01)
    guard = SelfCollisionGuard(sc.copy(margin=0.0), ARM6.rate_hz, sc.margin)
    rng = np.random.default_rng(7)
    times, per_cycle = [], []
    for k in range(cycles):
        q = (READY + rng.normal(0.0, 0.01, 6)).tolist()
        t0 = time.perf_counter()
        guard.check.collides(q)
        times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        guard.step(k / 480, q, q)
        per_cycle.append(time.perf_counter() - t0)
    print(f"  {'supervisor: one check':<28} {us(times)} ({len(sc.pairs)} pairs)")
    print(f"  {'supervisor: per cycle':<28} mean {np.mean(per_cycle) * 1e6:6.1f} µs (a check every {guard.every})")
    lim = [j.limits for j in ARM6.joints]
    planner = Planner(JointLimits(ARM6.joint_names, np.array([x.lower for x in lim]), np.array([x.upper for x in lim]),
                                  np.array([x.velocity for x in lim]), np.array([x.acceleration for x in lim]),
                                  np.array([x.jerk for x in lim])), 0.05)
    zero = np.zeros(6)
    for a, b in (("ready", "home"), ("home", "reach"), ("ready", "left")):
        plan = planner.move_from((np.array(ARM6.pose(a)), zero, zero), np.array(ARM6.pose(b)), 0.0, 1.0)
        t0 = time.perf_counter()
        samples = path_samples(plan)
        sc.check_path(samples, False)
        dt = time.perf_counter() - t0
        print(f"  {'planned move ' + a + ' → ' + b:<28} {dt * 1e3:6.2f} ms for {plan.duration:.2f} s of path "
              f"({len(samples)} samples, {dt / len(samples) * 1e6:.0f} µs each)")


def cycle_cost(seconds: float) -> None:
    cfg = ARM6.with_bus(interface="virtual", channel="bench-compliance-cycle")
    with SimulatedRobot(cfg, realtime=False, q0=READY) as sim, Arm(cfg, clock=sim.clock,
                                                                      remember_positions=False) as arm:
        arm.enable()
        arm.reset_stats()
        arm.sleep(seconds)
        rows = [("holding", arm.stats())]
        arm.reset_stats()
        with arm.servo(timeout=0.1) as s:
            end = arm.clock.now() + seconds
            while arm.clock.now() < end:
                s.twist([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
                arm.sleep(0.01)
            rows.append(("servoing", arm.stats()))
        arm.reset_stats()
        with arm.impedance(stiffness=[500, 500, 500, 30, 30, 30]):
            arm.sleep(seconds)
            rows.append(("impedance", arm.stats()))
        for label, st in rows:
            stages = ", ".join(f"{k} {v * 1e6:.0f}" for k, v in st.stage_mean.items())
            print(f"  {label:<10} cycle compute mean {st.compute_mean * 1e6:5.0f} µs, "
                  f"p99 {st.compute_p99 * 1e6:5.0f} µs (stages, mean µs: {stages})")


def latency(commands: int) -> None:
    cfg = ARM6.with_bus(interface="virtual", channel="bench-compliance-latency")
    rng = np.random.default_rng(5)
    with SimulatedRobot(cfg, realtime=False, q0=READY) as sim, Arm(cfg, clock=sim.clock,
                                                                      remember_positions=False) as arm:
        arm.enable()
        period = 1.0 / arm.config.rate_hz
        found = []
        with arm.servo(timeout=0.5) as s:
            for _ in range(commands):
                sim.advance_to(sim.t + float(rng.uniform(0.0, period)))  # a moment between two cycles
                s.twist([0.0, 0.0, float(rng.uniform(-0.02, 0.02)), 0.0, 0.0, 0.0])
                stamp = s.stream.command.stamp if s.stream.command is not None else float("nan")
                arm.sleep(2 * period)
                if s.stream.first_step is not None:
                    found.append(s.stream.first_step - stamp)
        a = np.array(found) * 1e3
        print(f"  command → first frame: median {np.median(a):.2f} ms, max {a.max():.2f} ms over {len(a)} commands "
              f"(loop period {period * 1e3:.2f} ms)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=5000)
    args = parser.parse_args()
    print("per-cycle work alone:")
    stream_cost(args.cycles)
    print("self-collision (arm6's <collision> shapes, margin 10 mm):")
    self_collision_cost(args.cycles)
    print("the whole control cycle, lock step:")
    cycle_cost(3.0)
    print("servo latency, lock step:")
    latency(200)


if __name__ == "__main__":
    main()
