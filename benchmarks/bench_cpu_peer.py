"""The cycle's CPU cost: akarm's whole supervised cycle against a bare peer loop, side by side.

    .venv/bin/python benchmarks/bench_cpu_peer.py                  # 3 rounds of 20 s per side
    .venv/bin/python benchmarks/bench_cpu_peer.py --rounds 1 --seconds 10

Both sides drive the 6 MIT joints of robots/arm6.yaml at 480 Hz against ``akarm sim`` in a process of
its own on the ``akarm_local`` bus, both loops sleeping between cycles, each side in a fresh process
of its own (so that its process CPU is its own alone), the sides alternating round by round:

- the peer: TMotorCANControl 1.2.6 (``pip install TMotorCANControl==1.2.6``; installed only for this
  benchmark, never a dependency of akarm): six ``TMotorManager_mit_can`` managers in impedance mode,
  a bare loop of ``set_output_angle_radians`` + ``update()`` per motor (no planning, dynamics or
  checks), its replies read by python-can's ``Notifier`` thread. Its CAN manager opens ``can0`` on
  socketcan (after ``sudo ip link``); here its one bus is an ``akarm_local`` bus instead, opened
  before the first manager, and nothing else of it is changed.
- akarm: as installed (its cycle compiled with mypyc where the install could: ``akarm --version``);
  where it is compiled, a third side, ``pure``, runs the same with ``AKARM_PURE=1``. Each:
  ``Arm(cfg)`` moving between the file's poses (planning included), with the supervisor, the
  collision reflex, the feed-forward and telemetry on, as shipped. A safety stop (on a loaded
  machine: the simulator's process starved past the 20 ms watchdog) is counted and the arm enabled
  again; the stops are printed.

``--hold-idle`` holds the CPUs out of deep idle states for the whole run, both sides alike
(:mod:`akarm.control.cpuidle`, needs root): what ``realtime_priority`` does for akarm's loop, and
what anyone tuning a machine for either loop would do (``cyclictest`` does it by default).

Printed per round and side: process CPU per cycle across all threads (getrusage), the loop's
lateness p99, and for akarm its per-stage compute (mean and p99, µs).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import resource
import subprocess
import sys
import time
import types
from dataclasses import replace
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

ARM6 = ROOT / "robots" / "arm6.yaml"
RATE = 480.0
MARK = "RESULT "


def cpu_seconds() -> float:
    """This process's CPU time, all threads, s."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def percentile(xs: list[float], p: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))] if s else float("nan")


def run_peer(channel: str, seconds: float) -> dict:
    import can
    from TMotorCANControl import mit_can  # the peer: installed only for this benchmark

    import akarm
    from akarm.sim.process import SimulatorProcess

    cfg = akarm.load_robot(ARM6)
    with SimulatorProcess(ARM6, channel=channel) as sim, contextlib.ExitStack() as stack:
        # the peer's CAN manager is a singleton that runs `sudo ip link` and opens socketcan can0 on
        # first use: its module gets an os without system() and a can whose Bus is akarm_local
        bus = can.Bus(interface="akarm_local", channel=channel)
        stack.callback(bus.shutdown)
        mit_can.os = types.SimpleNamespace(system=lambda command: 0)
        mit_can.can = types.SimpleNamespace(
            interface=types.SimpleNamespace(Bus=lambda channel, bustype: bus), Notifier=can.Notifier,
            Message=can.Message, CanError=can.CanError, BufferedReader=can.BufferedReader)
        motors = []
        with contextlib.redirect_stdout(sys.stderr):
            for j in cfg.joints:
                m = stack.enter_context(mit_can.TMotorManager_mit_can(motor_type=j.motor.name, motor_ID=j.can_id))
                m.set_impedance_gains_real_unit(K=j.gains.kp, B=j.gains.kd)
                motors.append(m)
        for m in motors:
            m.update()
        time.sleep(0.05)
        for m in motors:
            m.update()
        q0 = [m.position for m in motors]
        period = 1.0 / RATE
        late: list[float] = []
        compute: list[float] = []
        pc = time.perf_counter
        t_start = pc()
        deadline = t_start + period
        cycles = missed = 0
        cpu0, sim0 = cpu_seconds(), sim.cpu_seconds()
        while True:
            now = pc()
            if now < deadline:
                time.sleep(deadline - now)
                now = pc()
            late.append(now - deadline)
            t = now - t_start
            if t >= seconds:
                break
            for m, q in zip(motors, q0, strict=True):
                m.set_output_angle_radians(q + 0.2 * math.sin(2 * math.pi * 0.5 * t))
                m.update()
            compute.append(pc() - now)
            cycles += 1
            deadline += period
            behind = pc() - deadline
            if behind > period:  # slots gone by: skip them, as akarm's loop does
                skip = int(behind / period)
                missed += skip
                deadline += skip * period
        cpu, sim_cpu = cpu_seconds() - cpu0, sim.cpu_seconds() - sim0
        for m in motors:  # park: no stiffness
            m.set_impedance_gains_real_unit(K=0.0, B=0.0)
            m.update()
    return {"side": "peer", "cycles": cycles, "missed": missed, "cpu_per_cycle": cpu / cycles,
            "sim_cpu_per_cycle": sim_cpu / cycles,
            "late_p99": percentile(late, 99), "compute_mean": sum(compute) / len(compute),
            "compute_p99": percentile(compute, 99)}


def enable(arm: Any) -> None:
    """Enable, trying again after a stop (a starved simulator on a loaded machine), at most 5 times."""
    import akarm

    for attempt in range(5):
        try:
            arm.enable()
            return
        except akarm.SafetyStop as e:
            print(f"enable stopped: {e}", file=sys.stderr)
            if attempt == 4:
                raise
            time.sleep(0.5)


def run_akarm(channel: str, seconds: float, interface: str = "akarm_local") -> dict:
    """akarm's side: an Arm on ``interface`` (the simulator is on akarm_local ``channel``)."""
    import akarm
    from akarm.sim.process import SimulatorProcess

    cfg = replace(akarm.load_robot(ARM6).with_bus(interface=interface, channel=channel), rate_hz=RATE)
    poses = [p for p in ("ready", "reach", "home") if p in cfg.poses]
    with SimulatorProcess(ARM6, channel=channel) as sim, akarm.Arm(cfg, remember_positions=False) as arm:
        enable(arm)
        arm.reset_stats()
        wall0, cpu0, sim0 = time.perf_counter(), cpu_seconds(), sim.cpu_seconds()
        k = stops = 0
        while time.perf_counter() - wall0 < seconds:
            try:
                arm.move_to(poses[k % len(poses)], speed=0.7)
            except akarm.SafetyStop as e:  # a starved simulator on a loaded machine: counted, enabled again
                print(f"stop: {e}", file=sys.stderr)
                stops += 1
                enable(arm)
            k += 1
        cpu, sim_cpu = cpu_seconds() - cpu0, sim.cpu_seconds() - sim0
        s = arm.stats()
    return {"side": "akarm", "cycle": akarm.compiled.status(), "stops": stops, "cycles": s.cycles,
            "missed": s.missed, "cpu_per_cycle": cpu / s.cycles,
            "sim_cpu_per_cycle": sim_cpu / s.cycles, "late_p99": s.late_p99,
            "compute_mean": s.compute_mean, "compute_p99": s.compute_p99,
            "stage_mean": s.stage_mean, "stage_p99": s.stage_p99}


def child(side: str, seconds: float) -> None:
    channel = f"cpupeer-{os.getpid()}"
    result = run_peer(channel, seconds) if side == "peer" else run_akarm(channel, seconds)
    print(MARK + json.dumps(result), flush=True)


def spawn(side: str, seconds: float, script: str = __file__, pure: bool = False) -> dict:
    """``script --child side``'s result, run in a fresh process of its own (``pure``: with AKARM_PURE=1,
    akarm's cycle in pure Python though it is installed compiled)."""
    env = os.environ | {"AKARM_PURE": "1"} if pure else {k: v for k, v in os.environ.items() if k != "AKARM_PURE"}
    out = subprocess.run([sys.executable, script, "--child", side, "--seconds", str(seconds)],
                         capture_output=True, text=True, timeout=seconds + 180, env=env)
    for line in out.stdout.splitlines():
        if line.startswith(MARK):
            return json.loads(line[len(MARK):])
    raise SystemExit(f"the {side} run failed:\n{out.stdout[-2000:]}\n{out.stderr[-4000:]}")


def load() -> str:
    try:
        return Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "?"


def hold_idle() -> Any:
    """Every CPU held out of deep idle states until the process ends (akarm.control.cpuidle), or exit
    saying why not (it needs root)."""
    from akarm.control.cpuidle import IdleLatencyHold

    hold = IdleLatencyHold()
    report = hold.acquire()
    if not hold.held:
        raise SystemExit(report)
    return hold


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0, help="length of each side's run, s")
    ap.add_argument("--hold-idle", action="store_true",
                    help="hold every CPU out of deep idle states for the run, both sides (needs root)")
    ap.add_argument("--no-pure", action="store_true",
                    help="leave out the third side (akarm with AKARM_PURE=1) where akarm is installed compiled")
    ap.add_argument("--child", choices=("peer", "akarm"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.seconds)
        return
    hold = hold_idle() if args.hold_idle else None
    from akarm import compiled

    cycle = compiled.status()
    sides = ["peer", "akarm"] + ([] if args.no_pure or not compiled.compiled_modules() else ["pure"])
    us = 1e6
    print(f"arm6, 6 MIT joints, {RATE:g} Hz, akarm sim in its own process on akarm_local, both loops sleeping; "
          f"{args.seconds:g} s per side, {os.cpu_count()} CPUs, Python {sys.version.split()[0]}"
          + ("; CPU idle latency held at 0 µs" if hold is not None else "") + f"\nakarm's cycle: {cycle}"
          + ("; the side 'pure' is akarm with AKARM_PURE=1" if "pure" in sides else ""))
    print(f"{'round':>5} {'side':>6} {'load':>5} {'cycles':>7} {'missed':>6} {'CPU/cycle':>10} {'akarm/peer':>10} "
          f"{'compute':>8} {'cmp p99':>8} {'late p99':>9} {'sim CPU/c':>9}   (µs)")
    for r in range(1, args.rounds + 1):
        res = {}
        for side in sides:
            before = load()
            x = res[side] = spawn("peer" if side == "peer" else "akarm", args.seconds, pure=side == "pure")
            ratio = x["cpu_per_cycle"] / res["peer"]["cpu_per_cycle"]
            print(f"{r:5d} {side:>6} {before:>5} {x['cycles']:7d} {x['missed']:6d} {x['cpu_per_cycle'] * us:10.1f} "
                  f"{ratio:10.2f} {x['compute_mean'] * us:8.1f} {x['compute_p99'] * us:8.1f} "
                  f"{x['late_p99'] * us:9.1f} {x['sim_cpu_per_cycle'] * us:9.1f}", flush=True)
        for side in sides[1:]:
            a = res[side]
            print(f"      {side} per stage, µs: " + ", ".join(
                f"{k} {a['stage_mean'][k] * us:.1f} ({a['stage_p99'][k] * us:.0f})" for k in a["stage_mean"])
                + f"; whole compute {a['compute_mean'] * us:.1f} ({a['compute_p99'] * us:.0f}); "
                f"safety stops {a['stops']}", flush=True)


if __name__ == "__main__":
    main()
