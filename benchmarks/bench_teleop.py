"""Teleoperation: how closely and how late the follower copies a hand-guided leader.

    .venv/bin/python benchmarks/bench_teleop.py [--robot planar2] [--seconds 6] [--mode both]

Two simulated arms of one robot, the leader in teach mode pushed by a hand: a spring and damper
pulling it along ``q0 + A·(1 − cos 2πft)/2`` (f = 0.4 Hz) through the simulator's external torque.

- **lock step** (``--mode lockstep``): both simulators and both loops on one stepped clock in this
  process (deterministic; the figures do not depend on the machine's load). Per swing amplitude: the
  leader's peak speed, the follower's largest and RMS distance from the leader's pose once engaged,
  the lag (the delay that best lays the follower's path on the leader's) and CPU per simulated second.
- **real time** (``--mode realtime``): each simulator in a process of its own (``akarm sim`` on
  akarm_local, as drivers are hardware of their own), both Arms' loops and the session in this one;
  the hand pushes through the simulator's control channel every 10 ms. The latency (the leader's
  feedback to the follower's command using it: p50, p99, max), steps a second, the same tracking
  figures, and this process's CPU time. Real time on a shared machine is noisy: the load average is
  printed with it.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm import Arm, SafetyStop, load_robot  # noqa: E402
from akarm.clock import SteppedClock  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402
from akarm.teleop import Step, Teleop  # noqa: E402

FREQ = 0.4
START = {"planar2": [-0.5, 0.3], "arm6": [0.0, -0.15, 0.6, 0.0, 0.9, 0.0]}
SHAPE = {"planar2": [1.0, -0.5], "arm6": [1.0, 0.4, -0.6, 1.0, 0.6, 1.0]}
HAND = {"planar2": (60.0, 4.0), "arm6": (15.0, 0.3)}  # spring N·m/rad and damper N·m·s/rad, stable at 2 kHz


def path(q0: np.ndarray, amp: np.ndarray, t: float) -> np.ndarray:
    return q0 + amp * 0.5 * (1.0 - np.cos(2.0 * np.pi * FREQ * max(0.0, t)))


def lag_of(t: np.ndarray, leader: np.ndarray, follower: np.ndarray, longest: float = 0.25) -> float:
    """The delay (s) that best lays ``follower`` on ``leader``, both resampled on a 1 ms grid."""
    grid = np.arange(t[0], t[-1], 0.001)
    a, b = np.interp(grid, t, leader), np.interp(grid, t, follower)
    rms = [np.sqrt(np.mean((b[s:] - a[:len(a) - s]) ** 2)) for s in range(int(longest / 0.001))]
    return 0.001 * int(np.argmin(rms))


def tracking(steps: list[Step], names: tuple[str, ...]) -> str:
    following = [s for s in steps if s.phase == "following"]
    if len(following) < 50:
        return "never followed"
    err = np.array([s.follower_q - s.command for s in following])
    speed = np.abs(np.array([s.leader_dq for s in following])).max(axis=0)
    t = np.array([s.t for s in following])
    lines = []
    for j, name in enumerate(names):
        lag = lag_of(t, np.array([s.command[j] for s in following]), np.array([s.follower_q[j] for s in following]))
        rms = np.sqrt(np.mean(err[:, j] ** 2))
        lines.append(f"    {name:<15} leader up to {speed[j]:5.2f} rad/s   follower - leader: max "
                     f"{np.abs(err[:, j]).max() * 1e3:6.2f} mrad, RMS {rms * 1e3:5.2f} mrad   lag {lag * 1e3:5.1f} ms")
    return "\n".join(lines)


def lockstep(robot: str, seconds: float) -> None:
    config = load_robot(ROOT / "robots" / f"{robot}.yaml")
    q0, shape = np.array(START[robot]), np.array(SHAPE[robot])
    k, d = HAND[robot]
    print(f"lock step, {robot}: both arms on one stepped clock; a hand swings the leader at {FREQ} Hz")
    for amplitude in (0.2, 0.4, 0.6):
        clock = SteppedClock()
        lc = config.with_bus(interface="virtual", channel=f"bench-lead-{os.getpid()}")
        fc = config.with_bus(interface="virtual", channel=f"bench-foll-{os.getpid()}")
        with SimulatedRobot(lc, realtime=False, clock=clock, q0=q0) as ls, \
                SimulatedRobot(fc, realtime=False, clock=clock, q0=q0), \
                Arm(lc, clock=clock) as leader, Arm(fc, clock=clock) as follower:
            leader.enable()
            follower.enable()
            steps = []
            cpu = time.process_time()
            with Teleop(leader, follower) as tele:
                while tele.step().phase != "following":  # (the follower sagged while the leader enabled)
                    ls.set_external_torque(k * (q0 - ls.q) - d * ls.dq)
                t0 = clock.now()
                while clock.now() - t0 < seconds:
                    ls.set_external_torque(k * (path(q0, amplitude * shape, clock.now() - t0 - 0.2) - ls.q)
                                           - d * ls.dq)
                    steps.append(tele.step())
            cpu = (time.process_time() - cpu) / seconds
        print(f"  swing {amplitude:.1f} rad (× {shape.tolist()}), {cpu:.2f} s CPU per simulated s, latency "
              f"{tele.summary().latency_p50 * 1e3:.1f} ms (one follower period)")
        print(tracking(steps, tuple(follower.names)))


def realtime(robot: str, seconds: float, watchdog: float) -> None:
    import yaml

    from akarm.sim.process import SimulatorProcess

    folder = Path(tempfile.mkdtemp(prefix="akarm-bench-teleop-"))
    doc = yaml.safe_load((ROOT / "robots" / f"{robot}.yaml").read_text())
    doc["urdf"] = str(ROOT / "robots" / doc["urdf"])
    # a loaded machine's processes pause: the watchdog relaxed, and a reading may trail its command
    doc.setdefault("defaults", {}).update(feedback_timeout=watchdog, stuck_travel=3.0, following_error=3.0)
    yaml_path = folder / f"{robot}.yaml"
    yaml_path.write_text(yaml.safe_dump(doc))
    config = load_robot(yaml_path)
    q0, shape = np.array(START[robot]), np.array(SHAPE[robot])
    k, d = 8.0, 0.2  # softer than in lock step: the push is refreshed every 10 ms, not every 0.5 ms
    tag = f"{os.getpid()}"
    load = "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    print(f"real time, {robot}: simulators in processes of their own; watchdog {watchdog * 1e3:.0f} ms; "
          f"{os.cpu_count()} CPUs, {load} at start")
    with SimulatorProcess(yaml_path, channel=f"lead-{tag}", control=True) as ls, \
            SimulatorProcess(yaml_path, channel=f"foll-{tag}", control=True) as fs:
        leader = Arm(config.with_bus(interface="akarm_local", channel=f"lead-{tag}"), remember_positions=False)
        follower = Arm(config.with_bus(interface="akarm_local", channel=f"foll-{tag}"), remember_positions=False)
        with leader, follower:
            leader.enable()
            follower.enable()
            with Teleop(leader, follower) as tele:
                s = tele.step()
                q0 = s.leader_q.copy()             # the hand holds the leader where it is until engaged
                while s.phase != "following":
                    ls.control.push((k * (q0 - s.leader_q) - d * s.leader_dq).tolist())
                    s = tele.step()
                steps: list[Step] = []
                t0 = time.perf_counter()
                pushed = 0.0
                cpu = time.process_time()
                while time.perf_counter() - t0 < seconds:
                    now = time.perf_counter() - t0
                    s = tele.step()
                    steps.append(s)
                    if now - pushed >= 0.01:
                        pushed = now
                        target = path(q0, 0.3 * shape, now - 0.2)
                        ls.control.push((k * (target - s.leader_q) - d * s.leader_dq).tolist())
                cpu = time.process_time() - cpu
                ls.control.push(None)
                wall = time.perf_counter() - t0
            summary = tele.summary()
            stats = follower.stats()
        print(f"  {len(steps) / wall:.0f} steps/s (loop {follower.config.rate_hz:g} Hz, missed slots "
              f"{stats.missed}); this process {cpu / wall:.2f} s CPU per s (two loops, the session, the hand)")
        print(f"  latency, leader feedback → follower command: p50 {summary.latency_p50 * 1e3:.2f} ms, "
              f"p99 {summary.latency_p99 * 1e3:.2f} ms, max {summary.latency_max * 1e3:.2f} ms")
        print(tracking(steps, tuple(follower.names)))
        print(f"  simulators' CPU: leader {ls.cpu_seconds() / wall:.2f} s/s, "
              f"follower {fs.cpu_seconds() / wall:.2f} s/s")
    print("  load average {:.2f} {:.2f} {:.2f} at the end".format(*os.getloadavg()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default="planar2", choices=sorted(START))
    ap.add_argument("--seconds", type=float, default=6.0, help="of hand-guided motion per run")
    ap.add_argument("--mode", default="both", choices=["lockstep", "realtime", "both"])
    ap.add_argument("--watchdog", type=float, default=0.1,
                    help="real time: the feedback watchdog, s (default 0.1: the robot file's 20 ms stops the arms on "
                         "a machine loaded enough to pause a simulator's process that long)")
    args = ap.parse_args()
    if args.mode in ("lockstep", "both"):
        lockstep(args.robot, args.seconds)
    if args.mode in ("realtime", "both"):
        try:
            realtime(args.robot, args.seconds, args.watchdog)
        except SafetyStop as e:  # the machine's load paused a process past the relaxed limits
            sys.exit(f"  real time: the arms stopped ({e}); load average {os.getloadavg()[0]:.2f}: rerun on a "
                     "quieter machine or with a larger --watchdog")


if __name__ == "__main__":
    main()
