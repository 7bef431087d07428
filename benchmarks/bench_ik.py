"""Inverse kinematics and straight-line planning: solve times, accuracy, and pin-pink for comparison.

    .venv/bin/python benchmarks/bench_ik.py [--targets N]

Targets are the tool poses of random joint positions of arm6 (away from singularities), solved
from the `home` pose: median and p99 solve time of :class:`akarm.dynamics.ik.IKSolver`, how many needed the
other starts, the worst pose error; then the planning time of 20 straight lines (`plan_linear`).

If ``pin-pink`` (PyPI) and a QP back-end (``daqp``) are installed in the same environment (they
are no dependency of akarm), the same targets are solved with pink's differential IK, iterated
until converged, for comparison: ``pip install pin-pink daqp``.
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
from akarm.dynamics.ik import IKSolver, pose_error  # noqa: E402
from akarm.dynamics.model import RobotModel  # noqa: E402
from akarm.errors import LimitError  # noqa: E402
from akarm.motion.cartesian import plan_linear  # noqa: E402
from akarm.motion.trajectory import JointLimits  # noqa: E402


def stats(ms: list[float]) -> str:
    a = np.array(ms)
    return f"median {np.median(a):.2f} ms, p99 {np.percentile(a, 99):.2f} ms, max {a.max():.2f} ms"


def pink_solver(model: RobotModel, seed: np.ndarray):  # pragma: no cover - optional
    """pink's differential IK iterated to a pose (None when pink is not installed)."""
    try:
        import pink
        from pink.tasks import FrameTask
    except ImportError:
        return None
    import pinocchio as pin

    task = FrameTask(model.tool_frame, position_cost=1.0, orientation_cost=0.1)
    pm = model.pin_model

    def solve(target: np.ndarray) -> tuple[np.ndarray, int]:
        config = pink.Configuration(pm, pm.createData(), model.to_pin_q(seed))
        task.set_target(pin.SE3(target[:3, :3], target[:3, 3]))
        dt = 0.02
        for k in range(3000):
            err = task.compute_error(config)
            if np.linalg.norm(err[:3]) < 1e-6 and np.linalg.norm(err[3:]) < 1e-5:
                return model.from_pin_q(config.q), k
            try:
                v = pink.solve_ik(config, [task], dt, solver="daqp")
            except Exception:  # pink.exceptions.NoSolutionFound: the QP is infeasible here
                return model.from_pin_q(config.q), -1
            config.integrate_inplace(v, dt)
        return model.from_pin_q(config.q), -1

    return solve


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", type=int, default=300)
    args = ap.parse_args()
    cfg = load_robot(ROOT / "robots" / "arm6.yaml")
    lim = [j.limits for j in cfg.joints]
    limits = JointLimits(cfg.joint_names, *(np.array([getattr(x, k) for x in lim])
                                            for k in ("lower", "upper", "velocity", "acceleration", "jerk")))
    ik = IKSolver(RobotModel(cfg), limits.lower, limits.upper)
    seed = np.array(cfg.pose("home"))
    rng = np.random.default_rng(3)
    targets = []
    while len(targets) < args.targets:
        q = limits.lower + rng.random(6) * (limits.upper - limits.lower)
        if ik.sigma_min(q, False) > 0.01:
            targets.append(ik.model.tool_pose(q))
    times, worst, restarts = [], (0.0, 0.0), 0
    for T in targets:
        t0 = time.perf_counter()
        q = ik.solve(T, seed)
        times.append((time.perf_counter() - t0) * 1e3)
        restarts += not ik.iterate(seed, T, False)[2]
        dp, dr = pose_error(ik.model.tool_pose(q), T)
        worst = (max(worst[0], dp), max(worst[1], dr))
    print(f"akarm IKSolver, arm6, {len(targets)} random reachable poses from 'home' (damped least squares):")
    print(f"  {stats(times)}; {restarts} needed other starts; worst error {worst[0] * 1e6:.2f} µm, "
          f"{worst[1] * 1e6:.2f} µrad")

    line_times, durations, refused = [], [], 0
    q_line = np.array([0.2, 0.5, 1.2, 0.3, 0.9, 0.1])  # in front, wrist bent: room all round
    for _ in range(20):
        target = ik.model.tool_pose(q_line)
        target[:3, 3] += rng.uniform(-0.1, 0.1, 3)
        t0 = time.perf_counter()
        try:
            plan = plan_linear(ik, limits, q_line, target)
        except LimitError:
            refused += 1
            continue
        line_times.append((time.perf_counter() - t0) * 1e3)
        durations.append(plan.duration)
    print(f"plan_linear, {len(line_times)} lines of up to 17 cm ({refused} refused): {stats(line_times)} "
          f"(motions of {np.median(durations):.2f} s median)")

    solve = pink_solver(ik.model, seed)
    if solve is None:
        print("pin-pink: not installed here (pip install pin-pink daqp to compare)")
        return
    p_times, fails = [], 0
    for T in targets[:50]:
        t0 = time.perf_counter()
        q, k = solve(T)
        p_times.append((time.perf_counter() - t0) * 1e3)
        fails += k < 0
    print(f"pin-pink (differential IK, daqp, iterated to 1 µm), first 50 poses: {stats(p_times)}; {fails} did not "
          "converge in 3000 steps (or its QP found no solution)")


if __name__ == "__main__":
    main()
