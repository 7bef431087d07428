"""Two buses of three MIT joints at 1 kHz, in real time: can this machine keep it?

    .venv/bin/python benchmarks/two_buses_1khz.py                 # 60 s
    .venv/bin/python benchmarks/two_buses_1khz.py --seconds 20 --no-realtime-priority

arm6 with its joints split over two 1 Mbit/s buses (shoulder_pan, shoulder_lift and elbow on ``a``;
the wrist's three on ``b``) and its loop at 1000 Hz: three MIT joints a bus at 1 kHz use about 48 % of
each bus, where six on one bus would need 128 %. The simulator runs in a process of its own (``akarm
sim`` on ``akarm_local``, one channel per bus, integrating at 2 kHz), the Arm's loop in this one,
with ``realtime_priority`` where the machine grants it (SCHED_FIFO and locked memory; said when it
does not), every other setting at its default (the 20 ms watchdog, the collision reflex with arm6's
thresholds). It moves between arm6's named poses at random speeds for the whole run, and prints the
achieved rate, the missed slots, lateness, compute per cycle, process CPU per cycle and safety stops.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402

ARM6 = ROOT / "robots" / "arm6.yaml"
RATE_HZ = 1000.0
BUS_A = ("shoulder_pan", "shoulder_lift", "elbow")


def two_bus_robot(directory: Path) -> Path:
    """arm6 on two buses at 1 kHz, written in ``directory``."""
    doc = yaml.safe_load(ARM6.read_text())
    doc["name"] = "arm6_two_buses"
    doc["urdf"] = str(ARM6.parent / doc["urdf"])
    doc["rate_hz"] = RATE_HZ
    bus = doc["buses"]["arm"]
    doc["buses"] = {"a": dict(bus, channel="can0"), "b": dict(bus, channel="can1")}
    doc["defaults"].pop("bus", None)
    for joint in doc["joints"]:
        joint["bus"] = "a" if joint["name"] in BUS_A else "b"
    path = directory / "arm6_two_buses.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="how long to move (default 60)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-realtime-priority", action="store_true", help="run the loop at normal priority")
    args = ap.parse_args()

    robot = two_bus_robot(Path(tempfile.mkdtemp(prefix="two-buses-")))
    channel = f"two-buses-{os.getpid()}"
    config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
    load0 = os.getloadavg()[0]
    print(f"akarm {akarm.__version__}: arm6 on 2 buses x 3 MIT joints at {RATE_HZ:g} Hz, {args.seconds:.0f} s real "
          f"time, {os.cpu_count()} CPUs, load average {load0:.2f}", flush=True)
    print("  buses: " + "; ".join(f"{b}: {', '.join(j.name for j in config.joints if j.bus == b)}"
                                   for b in config.buses), flush=True)
    rng = np.random.default_rng(args.seed)
    poses = ("home", "ready", "left", "home")
    rt = not args.no_realtime_priority
    stops: list[str] = []
    moves = 0
    with SimulatorProcess(robot, channel=channel, pose="home"):
        try:
            arm = akarm.Arm(config, realtime_priority=rt, remember_positions=False)
        except akarm.AkarmError as e:
            if not rt:
                raise
            print(f"  realtime_priority refused here ({e}); at normal priority", flush=True)
            rt = False
            arm = akarm.Arm(config, remember_positions=False)
        with arm:
            arm.enable()
            print(f"  loop thread: {arm.realtime_report}", flush=True)
            arm.move_to("home", speed=0.5)
            arm.reset_stats()
            cpu0, wall0 = time.process_time(), time.perf_counter()
            while time.perf_counter() - wall0 < args.seconds:
                pose = poses[moves % len(poses)]
                try:
                    arm.move_to(pose, speed=float(rng.uniform(0.5, 1.0)))
                    moves += 1
                except akarm.SafetyStop as e:
                    stops.append(f"{time.perf_counter() - wall0:6.1f} s: {type(e).__name__}: {e}")
                    print("STOP " + stops[-1], flush=True)
                    time.sleep(1.0)
                    arm.enable()
            wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
            st = arm.stats()
            arm.disable()
    print(f"\n{moves} moves in {wall:.0f} s, {len(stops)} safety stops; load average {os.getloadavg()[0]:.2f} "
          "at the end")
    print(f"loop: {st.cycles} cycles at {st.rate:.1f} Hz (target {RATE_HZ:g}), missed slots {st.missed} "
          f"({100.0 * st.missed / max(st.cycles, 1):.2f} %), lateness p99 {st.late_p99 * 1e6:.0f} µs, "
          f"max {st.late_max * 1e3:.2f} ms")
    print(f"compute per cycle: mean {st.compute_mean * 1e6:.0f} µs, p99 {st.compute_p99 * 1e6:.0f} µs; "
          f"process CPU per cycle (all threads) {cpu / max(st.cycles, 1) * 1e6:.0f} µs ({100.0 * cpu / wall:.0f} % "
          f"of a CPU)")
    for s in stops:
        print("  " + s)
    return 1 if stops else 0


if __name__ == "__main__":
    sys.exit(main())
