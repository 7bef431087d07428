"""The collision reflex on the simulated arm6, in lock step: detection latency and false stops.

    .venv/bin/python benchmarks/bench_collision.py [--pulses N] [--minutes M] [--retarget-minutes R]

Latency: during fast moves between random poses (full speed), a push of twice a joint's threshold
(robots/arm6.yaml's, what `akarm identify` suggests for the simulator) starts at a random moment on
one joint; the time from the push to the `CollisionError` is measured, per joint.

False stops: the `akarm demo` session, then M minutes of moves between random poses at random
speeds, through waypoints and along straight lines, with pauses, all with the reflex armed; every
`CollisionError` is counted (and the session goes on after re-enabling). The largest estimate per
joint is printed as a share of its threshold.

Retargets: R minutes of random targets over the joints' whole ranges, each given before the last
move ends (after a random share of it) at a random speed factor, then R minutes of ``stream_to``
every 10-50 ms towards a noisy sweep (a joystick); stops, refused targets, and how far the
commands went past a range or a velocity limit.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm import AkarmError, CollisionError, LimitError, load_robot  # noqa: E402
from akarm.arm import Arm  # noqa: E402
from akarm.cli.demo import session_steps  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402

ARM6 = load_robot(ROOT / "robots" / "arm6.yaml")
LO = np.array([-1.5, -0.3, -0.5, -1.5, -1.2, -2.0])  # a box the shoulder holds for minutes
HI = np.array([1.5, 0.3, 1.0, 1.5, 1.4, 2.0])


def latencies(pulses: int) -> None:
    thresholds = [j.collision_threshold for j in ARM6.joints]
    rng = np.random.default_rng(11)
    for joint in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_pitch"):
        k = ARM6.joint_names.index(joint)
        found, missed = [], 0
        for trial in range(pulses):
            cfg = ARM6.with_bus(interface="virtual", channel=f"bench-collision-{joint}-{trial}")
            with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home")) as sim, Arm(cfg, clock=sim.clock) as arm:
                arm.enable()
                motion = arm.move_to(LO + rng.random(6) * (HI - LO), wait=False)
                arm.sleep(float(rng.uniform(0.1, 0.9)) * motion.duration)
                push = np.zeros(6)
                push[k] = 2.0 * thresholds[k] * rng.choice([-1.0, 1.0])
                t0 = sim.t
                sim.set_external_torque(push)
                try:
                    arm.sleep(0.2)
                    missed += 1
                except CollisionError as e:
                    found.append((e.at - t0) * 1e3)
                    if e.joint != joint:
                        missed += 1
        a = np.array(found)
        print(f"  {joint:<14} push {2 * thresholds[k]:.2f} N·m: latency median {np.median(a):.0f} ms, "
              f"max {a.max():.0f} ms over {len(a)} pushes; {missed} missed or on another joint")


def false_stops(minutes: float) -> None:
    cfg = ARM6.with_bus(interface="virtual", channel="bench-collision-run")
    thresholds = np.array([j.collision_threshold for j in ARM6.joints])
    rng = np.random.default_rng(12)
    stops: list[str] = []
    with SimulatedRobot(cfg, realtime=False) as sim, Arm(cfg, clock=sim.clock, telemetry_seconds=10) as arm:
        for _label, _short, action in session_steps(arm):
            try:
                action()
            except CollisionError as e:
                stops.append(f"demo: {e}")
                arm.enable()
        demo_peak = arm.collision_peak / thresholds
        arm.reset_collision_peak()
        t0, moves = arm.clock.now(), 0
        while arm.clock.now() - t0 < 60.0 * minutes:
            speed = float(rng.uniform(0.3, 1.0))
            try:
                if moves % 4 == 3:
                    pose = arm.tool_pose()
                    pose[:3, 3] += rng.uniform(-0.08, 0.08, 3)
                    with contextlib.suppress(LimitError):  # a line the arm refuses: not moved
                        arm.move_linear(pose, speed=speed)
                elif moves % 4 == 2:
                    arm.move_through([LO + rng.random(6) * (HI - LO) for _ in range(3)], speed=speed)
                else:
                    arm.move_to(LO + rng.random(6) * (HI - LO), speed=speed)
                arm.sleep(float(rng.uniform(0.2, 1.2)))
            except CollisionError as e:
                stops.append(f"run: {e}")
                arm.enable()
            except AkarmError as e:  # another safety stop (overheating, ...): say so, go on
                print(f"  (not a collision: {type(e).__name__}: {e})")
                arm.enable()
            moves += 1
        run_peak = arm.collision_peak / thresholds
    print(f"  demo session: largest estimate {np.round(demo_peak, 2).tolist()} of the thresholds")
    print(f"  {minutes:g} min, {moves} motions: largest estimate {np.round(run_peak, 2).tolist()} of the thresholds")
    print(f"  false stops: {len(stops)}")
    for s in stops:
        print(f"    {s}")


def retargets(minutes: float) -> None:
    thresholds = np.array([j.collision_threshold for j in ARM6.joints])
    rng = np.random.default_rng(13)
    for kind in ("move_to, retargeted", "stream_to"):
        cfg = ARM6.with_bus(interface="virtual", channel=f"bench-collision-{kind[:6]}")
        stops, refused, sent, beyond, faster, ended = 0, 0, 0, -np.inf, 0.0, ""
        with SimulatedRobot(cfg, realtime=False, q0=ARM6.pose("home")) as sim, \
                Arm(cfg, clock=sim.clock, telemetry_seconds=20) as arm:
            arm.enable()
            arm.reset_collision_peak()
            lo, hi = arm.limits.lower, arm.limits.upper
            freq, phase = rng.uniform(0.1, 0.6, 6), rng.uniform(0.0, 2 * np.pi, 6)
            t0 = last = sim.t
            while sim.t - t0 < 60.0 * minutes:
                try:
                    if kind == "stream_to":
                        stick = (lo + hi) / 2 + 0.49 * (hi - lo) * np.sin(2 * np.pi * freq * (sim.t - t0) + phase)
                        arm.stream_to(np.clip(stick + rng.normal(0.0, 0.05, 6), lo, hi),
                                      speed=float(rng.choice([0.3, 0.6, 1.0])))
                        sent += 1
                        arm.sleep(0.01 * int(rng.integers(1, 6)))
                    else:
                        motion = arm.move_to(rng.uniform(lo + 0.02, hi - 0.02), speed=float(rng.uniform(0.3, 1.0)),
                                             wait=False)
                        sent += 1
                        arm.sleep(float(rng.uniform(0.1, 0.8)) * motion.duration)
                except LimitError:
                    refused += 1
                except CollisionError:
                    stops += 1
                    arm.enable()
                except AkarmError as e:  # another safety stop (overheating, ...): the run ends here
                    ended = f"; ended after {sim.t - t0:.0f} s by {type(e).__name__}: {e}"
                    break
                if sim.t - last > 15.0 or sim.t - t0 >= 60.0 * minutes:  # the telemetry ring keeps 20 s
                    log = arm.telemetry(since=last)
                    last = sim.t
                    beyond = max(beyond, float(np.max(np.maximum(lo - log.q_des, log.q_des - hi))))
                    faster = max(faster, float(np.max(np.abs(log.dq_des) / arm.limits.velocity)))
            peak = arm.collision_peak / thresholds
        print(f"  {kind}: {sent} targets, {refused} refused, {stops} collision stops; commands at most "
              f"{beyond * 1e3:+.1f} mrad past a range, {faster:.2f} of a velocity limit; largest estimate "
              f"{peak.max():.2f} of a threshold{ended}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pulses", type=int, default=10, help="pushes per joint (default 10)")
    ap.add_argument("--minutes", type=float, default=5.0, help="length of the continuous run (default 5)")
    ap.add_argument("--retarget-minutes", type=float, default=2.0,
                    help="length of each retargeting run (default 2)")
    args = ap.parse_args()
    print(f"thresholds (robots/arm6.yaml), N·m: {[j.collision_threshold for j in ARM6.joints]}")
    print("detection latency, a push of twice the threshold during a full-speed move:")
    latencies(args.pulses)
    print("false stops with the reflex armed:")
    false_stops(args.minutes)
    print("retargets over the whole range, with the reflex armed:")
    retargets(args.retarget_minutes)


if __name__ == "__main__":
    main()
