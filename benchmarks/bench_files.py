"""Files that try to hurt, and files at the limits: what reading them costs.

    .venv/bin/python benchmarks/bench_files.py [--repeat R] [--quick]

1. The issue's hostile cases on the command line, each in a process of its own (best of R for time;
   CPU time from ``os.wait4``, peak memory the process's own VmHWM, Linux): a URDF of 2000 chained
   joints (``akarm check`` and ``akarm init``), a keyframe file with a YAML alias bomb, a path with
   two samples 1e9 s apart, a path of 1e7 samples (``akarm replay``), and 100 000 valid keyframes;
   with ``akarm check`` of planar2 for the cost of starting the command at all.
2. Valid files up to the limits, each read in a fresh process: CPU time of the read alone and the
   process's peak memory, at three sizes up to the limit, to show the cost grows in proportion:
   keyframe files (``load``, and ``Arm.check_replay``'s planning at the smaller sizes), path
   recordings, URDF chains (``read_urdf`` and ``load_robot`` with one joint driven), telemetry CSVs.

``--quick`` skips the largest sizes. Other processes only ever make a run slower: best of R.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.system.test_hostile_files import measured, path_of_samples  # noqa: E402
from tests.unit.test_files import billion_laughs  # noqa: E402
from tests.unit.test_hostile_files import chain_robot, keyframe_text  # noqa: E402

PLANAR2 = ROOT / "robots" / "planar2.yaml"


def hostile(d: Path, repeat: int) -> None:
    (d / "bomb.yaml").write_text("joints: [shoulder, elbow]\n" + billion_laughs() + "keyframes:\n  - {q: *a8}\n")
    (d / "gap.csv").write_text("t [s],shoulder [rad],elbow [rad]\n0.0,0.0,0.0\n1000000000.0,0.1,0.1\n")
    (d / "k100k.yaml").write_text(keyframe_text(100_000))
    path_of_samples(d / "samples.csv", 10_000_000)
    robot = chain_robot(d, 2000)
    cases = [("akarm check planar2.yaml (start-up, for reference)", ["check", PLANAR2]),
             ("URDF of 2000 chained joints: akarm check", ["check", robot]),
             ("URDF of 2000 chained joints: akarm init", ["init", d / "chain.urdf", "-o", d / "out.yaml"]),
             ("keyframes with an alias bomb: akarm replay", ["replay", PLANAR2, d / "bomb.yaml"]),
             ("path, two samples 1e9 s apart: akarm replay", ["replay", PLANAR2, d / "gap.csv"]),
             ("path of 1e7 samples (150 MB): akarm replay", ["replay", PLANAR2, d / "samples.csv"]),
             ("100 000 valid keyframes: akarm replay", ["replay", PLANAR2, d / "k100k.yaml"])]
    print(f"{'hostile case':<54} {'exit':>4} {'wall s':>7} {'CPU s':>6} {'peak MB':>8}  error")
    for label, args in cases:
        runs = [measured(*args) for _ in range(repeat)]
        best = min(runs, key=lambda r: r.cpu)
        at = best.err.find("(MAX_")
        limit = best.err[at:best.err.find(")", at) + 1] if at >= 0 else ""
        print(f"{label:<54} {best.code:>4} {min(r.wall for r in runs):>7.2f} {best.cpu:>6.2f} "
              f"{max(r.rss for r in runs):>8.0f}  {limit}")


# ---- valid files at the limits, one read per process ---------------------------------------------
def make(kind: str, size: int, d: Path) -> Path:
    if kind in ("keyframes", "check_replay"):
        import random

        from akarm.motion.recording import Keyframe, Keyframes

        rng = random.Random(1)
        frames = tuple(Keyframe(tuple(rng.uniform(-1.0, 1.0) for _ in range(2))) for _ in range(size))
        return Keyframes(("shoulder", "elbow"), frames, "planar2").save(d / f"k{size}.yaml")
    if kind == "path":
        return path_of_samples(d / f"p{size}.csv", size)
    if kind == "urdf":
        folder = d / f"u{size}"
        folder.mkdir()
        return chain_robot(folder, size)
    if kind == "telemetry":
        import numpy as np

        from akarm.telemetry.log import FIELDS, TelemetryLog

        rng = np.random.default_rng(1)
        log = TelemetryLog(("shoulder", "elbow"), np.arange(size) * 0.002,
                           *(rng.normal(size=(size, 2)) for _ in FIELDS))
        return log.save(d / f"t{size}.csv")
    raise ValueError(kind)


def read_one(kind: str, path: Path) -> float:
    """CPU seconds to read (or check) one file, in this process."""
    warnings.simplefilter("ignore")
    if kind in ("keyframes", "check_replay"):
        from akarm.motion.recording import load

        if kind == "check_replay":
            import akarm
            from akarm.arm import Arm

            arm = Arm(akarm.load_robot(PLANAR2, interface="virtual", channel="bench"))
            rec = load(path, arm.names)
            t0 = time.process_time()
            arm.check_replay(rec)
            return time.process_time() - t0
        t0 = time.process_time()
        load(path, ("shoulder", "elbow"))
        return time.process_time() - t0
    if kind == "path":
        from akarm.motion.recording import load

        t0 = time.process_time()
        load(path, ("shoulder", "elbow"))
        return time.process_time() - t0
    if kind == "urdf":
        from akarm.config.urdf import read_urdf
        from akarm.robotfile.load import load_robot

        t0 = time.process_time()
        urdf, _ = read_urdf(path.with_suffix(".urdf"))
        assert urdf is not None
        urdf.chain_order()
        load_robot(path)
        return time.process_time() - t0
    from akarm.telemetry.log import load as load_telemetry

    t0 = time.process_time()
    load_telemetry(path)
    return time.process_time() - t0


def in_process(kind: str, path: Path) -> tuple[float, float]:
    """(CPU s of the read alone, peak MB of the whole process) in a fresh process."""
    r = subprocess.run([sys.executable, __file__, "--one", kind, str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{kind} {path}: exit {r.returncode}\n{r.stderr}")
    cpu, peak = r.stdout.split()
    return float(cpu), float(peak) / 1024.0


def at_the_limits(d: Path, repeat: int, quick: bool) -> None:
    from akarm.config.urdf import MAX_URDF_LINKS
    from akarm.motion.bounds import MAX_KEYFRAMES, MAX_PATH_SAMPLES

    sizes = {"keyframes": [1000, 5000, MAX_KEYFRAMES], "check_replay": [250, 1000, 4000],
             "path": [200_000, 1_000_000, MAX_PATH_SAMPLES], "urdf": [100, 500, MAX_URDF_LINKS - 1],
             "telemetry": [50_000, 100_000, 200_000]}
    units = {"keyframes": "keyframes", "check_replay": "keyframes", "path": "samples", "urdf": "joints",
             "telemetry": "cycles (2 joints, 15 values each)"}
    print(f"\n{'valid file (planar2 joints)':<30} {'size':>10} {'CPU s':>7} {'µs each':>8} {'peak MB':>8}")
    for kind, values in sizes.items():
        for size in values[:2] if quick else values:
            path = make(kind, size, d)
            runs = [in_process(kind, path) for _ in range(repeat)]
            cpu = min(r[0] for r in runs)
            print(f"{kind:<30} {size:>10} {cpu:>7.3f} {1e6 * cpu / size:>8.2f} {max(r[1] for r in runs):>8.0f}")
        print(f"{'':<30} ({units[kind]})")


def main() -> None:
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        cpu = read_one(sys.argv[2], Path(sys.argv[3]))
        with open("/proc/self/status") as f:  # the process's own peak (VmHWM, kB)
            print(cpu, next(line for line in f if line.startswith("VmHWM:")).split()[1])
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="skip the largest sizes")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs\n")
    with tempfile.TemporaryDirectory() as tmp:
        hostile(Path(tmp), args.repeat)
        at_the_limits(Path(tmp), args.repeat, args.quick)


if __name__ == "__main__":
    main()
