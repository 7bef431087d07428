"""Soak of `akarm serve` under load: moves every few seconds, a second process burning a core.

    .venv/bin/python benchmarks/soak_serve.py                   # 10 minutes, arm6, one core burnt
    .venv/bin/python benchmarks/soak_serve.py --seconds 60 --burn 0

Three processes, as a cell runs them: the simulator (``akarm sim`` on ``akarm_local``, the arm's
drivers), ``akarm serve`` at the default profile (every supervisor default: 20 ms feedback timeout,
0.2 s stall limit) and this script, a client sending a served move over the control socket every
``--every`` seconds (to home, ready and left in turn, at speeds from 0.5 to 1.0) and waiting for it;
``--burn N`` more processes spin (``while True: pass``) the whole time. A safety stop is counted,
printed and acknowledged with an enable (the goal is zero). At the end: moves, stops, the loop's rate
and missed slots, late and compute p99 (the server's own statistics), and the largest feedback age
seen (the server's status, asked 10 times a second: the oldest joint's reading at that moment).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm.buses.ownership import find_server  # noqa: E402
from akarm.errors import AkarmError  # noqa: E402
from akarm.robotfile.load import load_robot  # noqa: E402
from akarm.server.socket import SocketClient  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402

POSES = ["home", "ready", "home", "left"]


def start_server(robot: Path, channel: str, lines: list[str]) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, "-m", "akarm", "serve", str(robot), "-i", "akarm_local", "-c", channel,
                             "--no-ros"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    started = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip())
            if line.startswith("serving"):
                started.set()
        started.set()

    threading.Thread(target=read, daemon=True).start()
    if not started.wait(120) or proc.poll() is not None:
        proc.kill()
        raise SystemExit("akarm serve did not start:\n" + "\n".join(lines))
    return proc


def watch(path: str, stop: threading.Event, seen: dict[str, Any]) -> None:
    """Ask the server's status 10 times a second; keep the largest feedback age and the last statistics."""
    with SocketClient(path, timeout=30) as c:
        while not stop.wait(0.1):
            with contextlib.suppress(AkarmError, OSError):
                s = c.call("status")
                seen["age_ms"] = max(seen.get("age_ms", 0.0), float(s.get("feedback_age_max_ms") or 0.0))
                seen["last"] = s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--every", type=float, default=3.0, help="s from one move's start to the next's")
    ap.add_argument("--burn", type=int, default=1, help="processes spinning meanwhile (default 1: a core)")
    ap.add_argument("--robot", default=str(ROOT / "robots" / "arm6.yaml"))
    ap.add_argument("--save-stops", metavar="DIR",
                    help="at each stop, save the server's telemetry (the external torque estimate included) here")
    args = ap.parse_args()
    robot = Path(args.robot)
    channel = f"soak-serve-{os.getpid()}"
    config = load_robot(robot).with_bus(interface="akarm_local", channel=channel)
    lines: list[str] = []
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.burn)]
    moves, stops = 0, []
    seen: dict[str, Any] = {}
    try:
        with SimulatorProcess(robot, channel=channel, pose="home"):
            server = start_server(robot, channel, lines)
            try:
                info = find_server(config)
                assert info is not None
                path = str(info["socket"])
                done = threading.Event()
                watcher = threading.Thread(target=watch, args=(path, done, seen), daemon=True)
                watcher.start()
                load0 = os.getloadavg()[0]
                end = time.monotonic() + args.seconds
                with SocketClient(path, timeout=120) as c:
                    k = 0
                    while time.monotonic() < end:
                        began = time.monotonic()
                        pose, speed = POSES[k % len(POSES)], 0.5 + 0.5 * ((k * 7) % 11) / 10
                        k += 1
                        try:
                            motion = c.call("move", target=pose, speed=speed)
                            c.call("wait", id=motion["id"])
                            moves += 1
                        except AkarmError as e:
                            stops.append(f"{time.strftime('%H:%M:%S')} {type(e).__name__}: {e}")
                            print(f"  stop: {stops[-1]}", flush=True)
                            if args.save_stops:
                                saved = Path(args.save_stops) / f"stop-{len(stops)}.npz"
                                saved.parent.mkdir(parents=True, exist_ok=True)
                                with contextlib.suppress(AkarmError):
                                    print(f"  telemetry: {c.call('telemetry', since=0.0, save=str(saved))['path']}")
                            with contextlib.suppress(AkarmError):
                                c.call("enable")  # acknowledge, and go on
                        time.sleep(max(0.0, args.every - (time.monotonic() - began)))
                load1 = os.getloadavg()[0]
                done.set()
                watcher.join(5)
            finally:
                server.terminate()
                server.wait(60)
    finally:
        for b in burners:
            b.kill()
    last = seen.get("last", {})
    print(f"akarm serve, {config.name} at {config.rate_hz:g} Hz, {args.seconds:.0f} s, {args.burn} core(s) burnt; "
          f"load average {load0:.1f} -> {load1:.1f}")
    print(f"  moves {moves}, stops {len(stops)}")
    for s in stops:
        print(f"    {s}")
    print(f"  loop {last.get('loop_rate_hz', float('nan'))} Hz, missed slots {last.get('missed_slots', '?')}, "
          f"late p99 {last.get('late_p99_us', '?')} us, compute p99 {last.get('compute_p99_us', '?')} us "
          "(the server's statistics, at the end)")
    print(f"  largest feedback age seen {seen.get('age_ms', float('nan')):.1f} ms (status asked at 10 Hz)")
    server_stops = [line for line in lines if "safety stop" in line]
    if server_stops:
        print("  the server said:")
        for line in server_stops:
            print(f"    {line}")


if __name__ == "__main__":
    main()
