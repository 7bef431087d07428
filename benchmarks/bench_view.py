"""Does a live view disturb the control loop? Missed slots and compute per cycle, view open against closed.

    .venv/bin/python benchmarks/bench_view.py                   # 4 rounds of 10 s each way
    .venv/bin/python benchmarks/bench_view.py --rounds 6 --seconds 20

robots/arm6.yaml at its 500 Hz in real time: the simulator in a process of its own (``akarm sim``, on
the ``akarm_local`` bus), the Arm's loop in this one, moving between poses the whole time. The
rounds alternate, in one run: **closed** (no view at all) and **open** (a
:class:`~akarm.view.process.ViewProcess`, as ``akarm serve --view``, ``akarm sim --view`` and
``akarm demo --view`` run it: the page drawn by a child process that asks this one for ~30 snapshots
a second), with a headless Chromium, in a process of its own, showing the page. ``--in-process``
adds a third way, **in-proc**: a :class:`~akarm.view.ViewServer` drawing in this process, its threads
sharing this interpreter with the loop (how ``--view`` ran before). Each round starts from fresh loop
statistics once the browser has loaded the page. For each round it prints the achieved rate, missed
slots, lateness and compute per cycle, and this process's CPU use (with ``open``, the view's process
is not counted: it is reported apart); then the mean of each way with its spread across rounds (the
noise), and the view's own numbers (snapshots a second, time spent taking each).

Needs the ``view-test`` extra and Chromium (see tests/system/test_view.py); without them only the
closed rounds run.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.sim.process import SimulatorProcess, stat_cpu_seconds  # noqa: E402
from akarm.view import browser  # noqa: E402

ARM6 = ROOT / "robots" / "arm6.yaml"

#: the browser's process: shows the page until its standard input closes
BROWSER = textwrap.dedent("""
    import sys
    from akarm.view.browser import headless_page
    with headless_page(sys.argv[1]) as page:
        print("shown", flush=True)
        sys.stdin.read()
""")


def relaxed(robot: Path) -> Path:
    """``robot`` with a watchdog of 1 s, generous tracking limits and no collision thresholds (a late
    reply reads as a push), written beside the system tests' copies."""
    import yaml

    doc = yaml.safe_load(robot.read_text())
    doc["urdf"] = str(robot.parent / doc["urdf"])
    doc.setdefault("defaults", {}).update(feedback_timeout=1.0, stuck_travel=3.0, following_error=3.0)
    for joint in doc["joints"]:
        joint.pop("collision", None)
    path = Path(tempfile.mkdtemp(prefix="bench-view-")) / robot.name
    path.write_text(yaml.safe_dump(doc))
    return path


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def moves(arm: akarm.Arm, seconds: float) -> None:
    poses = ("ready", "reach", "home")
    wall0, k = time.perf_counter(), 0
    while time.perf_counter() - wall0 < seconds:
        arm.move_to(poses[k % len(poses)], speed=0.7)
        k += 1


def measure(arm: akarm.Arm, seconds: float) -> dict[str, float]:
    arm.reset_stats()
    wall0, cpu0 = time.perf_counter(), cpu_seconds()
    stops = 0
    while (left := seconds - (time.perf_counter() - wall0)) > 0.5:
        try:
            moves(arm, left)
        except akarm.AkarmError as e:  # the supervisor stopped the arm (a starved machine): counted, enabled again
            print(f"      stopped: {e}", flush=True)
            stops += 1
            for attempt in range(5):
                try:
                    arm.enable()
                    break
                except akarm.AkarmError:
                    if attempt == 4:
                        raise
                    time.sleep(1.0)
    wall, cpu = time.perf_counter() - wall0, cpu_seconds() - cpu0
    s = arm.stats()
    return {"rate": s.rate, "cycles": s.cycles, "missed": s.missed, "missed_pct": 100.0 * s.missed / max(1, s.cycles),
            "late_p99": s.late_p99 * 1e6, "compute_mean": s.compute_mean * 1e6, "compute_p99": s.compute_p99 * 1e6,
            "cpu": 100.0 * cpu / wall, "stops": stops}


def pin(pid: int, cpus: set[int] | None) -> None:
    """Every thread of process ``pid`` on ``cpus`` (threads started later inherit it)."""
    if not cpus:
        return
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            os.sched_setaffinity(int(task.name), cpus)


def open_round(arm: akarm.Arm, seconds: float, nice: int = 0, in_process: bool = False,
               cpus: set[int] | None = None) -> tuple[dict[str, float], dict[str, float]]:
    from akarm.view import ArmSource, ViewServer
    from akarm.view.process import ViewProcess

    view: ViewServer | ViewProcess
    if in_process:
        view = ViewServer(arm.config, ArmSource(arm), port=0, log=lambda text: None)
    else:
        view = ViewProcess(arm.config, ArmSource(arm), port=0)
    with view:
        if isinstance(view, ViewProcess) and view.pid is not None:
            pin(view.pid, cpus)
        # nice: the browser (Chromium, drawing WebGL in software) yields the CPU to everything else, as a
        # browser on another computer, the way a user watches, takes none of this one's
        def prepare() -> None:
            if nice:
                os.nice(nice)
            if cpus:
                os.sched_setaffinity(0, cpus)

        shown = subprocess.Popen([sys.executable, "-c", BROWSER, view.url], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True, preexec_fn=prepare)
        try:
            assert shown.stdout is not None
            if shown.stdout.readline().strip() != "shown":
                raise RuntimeError("the headless browser did not show the page")
            def count() -> int:
                return view.draws if isinstance(view, ViewServer) else view.snapshots

            pid = None if isinstance(view, ViewServer) else view.pid
            took0, draws0, child0 = view.snapshot_seconds, count(), stat_cpu_seconds(f"/proc/{pid}/stat")
            t0 = time.perf_counter()
            row = measure(arm, seconds)
            wall = time.perf_counter() - t0
            extra = {"draws_hz": (count() - draws0) / wall,
                     "snapshot_ms": 1e3 * (view.snapshot_seconds - took0) / max(1, count() - draws0),
                     "child_cpu": 100.0 * (stat_cpu_seconds(f"/proc/{pid}/stat") - child0) / wall}
        finally:
            if shown.stdin is not None:
                shown.stdin.close()
            shown.wait(60)
    return row, extra


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=4, help="rounds each way, alternating (closed first)")
    ap.add_argument("--seconds", type=float, default=10.0, help="length of each round, s")
    ap.add_argument("--strict", action="store_true",
                    help="arm6's own supervisor (default: a relaxed one, as the system tests use: on a shared, "
                         "loaded machine the simulator's process is starved at times, and a stop ends the run)")
    ap.add_argument("--browser-nice", type=int, default=0, metavar="N",
                    help="run the browser at this niceness (19: it takes only CPU nothing else wants, as a "
                         "browser on another computer takes none of this one's)")
    ap.add_argument("--split-cpus", action="store_true",
                    help="the loop's process and the simulator on the first CPU, the view's process and the browser "
                         "on the last, in both ways (as a browser on another computer, and a view on a core the "
                         "loop does not use)")
    ap.add_argument("--in-process", action="store_true",
                    help="also rounds with the view drawing in this process (in-proc), as --view ran before")
    args = ap.parse_args()

    why_not = browser.unavailable()
    print(f"akarm {akarm.__version__} view benchmark: arm6 at 500 Hz in real time, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f} at the start"
          + (f"; the browser at niceness {args.browser_nice}" if args.browser_nice else ""))
    if why_not:
        print(f"!!! {why_not}: only the closed rounds run")
    channel = f"bench-view-{os.getpid()}"
    config = akarm.load_robot(ARM6 if args.strict else relaxed(ARM6)).with_bus(interface="akarm_local",
                                                                              channel=channel)
    ways = ("closed", "open", "in-proc") if args.in_process else ("closed", "open")
    rows: dict[str, list[dict[str, float]]] = {way: [] for way in ways}
    extras: list[dict[str, float]] = []
    head = (f"{'round':>5} {'view':>6} {'rate Hz':>8} {'cycles':>7} {'missed':>7} {'late p99':>9} "
            f"{'compute':>8} {'c. p99':>8} {'CPU %':>6} {'stops':>5}   view: snapshots/s, ms each, its process's CPU")
    loop_cpus = view_cpus = None
    if args.split_cpus:
        last = max(os.sched_getaffinity(0))
        loop_cpus, view_cpus = set(os.sched_getaffinity(0)) - {last}, {last}
        os.sched_setaffinity(0, loop_cpus)  # the loop's thread, started below, inherits it
        print(f"the loop's process and the simulator on CPU {sorted(loop_cpus)}, the view and the browser on {last}")
    with SimulatorProcess(ARM6, channel=channel, cpus=loop_cpus), \
            akarm.Arm(config, remember_positions=False) as arm:
        arm.enable()
        moves(arm, 2.0)  # warm up
        print(head)
        for k in range(args.rounds):
            for way in ways:
                if way != "closed" and why_not:
                    continue
                if way == "closed":
                    row, note = measure(arm, args.seconds), ""
                else:
                    row, extra = open_round(arm, args.seconds, args.browser_nice, in_process=way == "in-proc",
                                            cpus=view_cpus)
                    extras.append(extra)
                    note = f"{extra['draws_hz']:.1f}/s, {extra['snapshot_ms']:.2f} ms" + \
                        (f", {extra['child_cpu']:.1f} %" if way == "open" else "")
                rows[way].append(row)
                print(f"{k + 1:5d} {way:>6} {row['rate']:8.1f} {row['cycles']:7.0f} {row['missed']:7.0f} "
                      f"{row['late_p99']:9.0f} {row['compute_mean']:8.1f} {row['compute_p99']:8.1f} "
                      f"{row['cpu']:6.1f} {row['stops']:5.0f}   {note}", flush=True)
    print(f"\nmean ± spread (standard deviation across rounds); µs; load average {os.getloadavg()[0]:.1f} at the end")
    for key, label in (("missed_pct", "missed slots, % of cycles"), ("late_p99", "lateness p99, µs"),
                       ("compute_mean", "compute per cycle, mean, µs"), ("compute_p99", "compute per cycle, p99, µs"),
                       ("cpu", "this process's CPU, %")):
        cells = []
        for way in ways:
            values = np.array([r[key] for r in rows[way]])
            cells.append(f"{way} {values.mean():8.2f} ± {values.std():6.2f}" if len(values) else f"{way}: not run")
        print(f"  {label:30s} " + "   ".join(cells))


if __name__ == "__main__":
    main()
