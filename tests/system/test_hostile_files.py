"""The issue's hostile files on the command line, each in a process of its own whose CPU time (os.wait4)
and peak memory (its VmHWM) are measured: refused with an akarm error naming the limit, no traceback, within
2 s of CPU and 300 MB. Generous where load matters (wall time); the numbers themselves:
benchmarks/bench_files.py. The readers alone: tests/unit/test_hostile_files.py."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from ..unit.test_files import billion_laughs
from ..unit.test_hostile_files import chain_robot, keyframe_text
from .conftest import ROBOTS

#: the issue's bounds on each hostile case
CPU_S, RSS_MB = 2.0, 300.0


@dataclass(frozen=True)
class Run:
    """One measured ``akarm`` process."""

    code: int
    out: str
    err: str
    wall: float  # s
    cpu: float  # s, user + system
    rss: float  # MB, peak resident


#: ``python -m akarm``, writing the process's peak resident memory (VmHWM, kB) to $AKARM_PEAK at exit. Its
#: own: ru_maxrss would include the parent's memory at the fork (Linux keeps the high-water mark across exec).
_AKARM_MEASURING = """
import atexit, os, runpy, sys
def peak():
    with open("/proc/self/status") as f, open(os.environ["AKARM_PEAK"], "w") as out:
        out.write(next(line for line in f if line.startswith("VmHWM:")).split()[1])
atexit.register(peak)
sys.argv[0] = "akarm"
runpy.run_module("akarm", run_name="__main__", alter_sys=True)
"""


def measured(*args: str | Path, timeout: float = 60.0) -> Run:
    """``python -m akarm ARGS`` in its own process: exit code, output, wall and CPU time, peak memory (Linux)."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err, tempfile.NamedTemporaryFile() as peak:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-c", _AKARM_MEASURING, *map(str, args)], stdout=out, stderr=err,
                                env={**os.environ, "AKARM_PEAK": peak.name})
        while True:  # os.wait4: this child's own CPU time (RUSAGE_CHILDREN would add earlier children's)
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout:
                proc.kill()
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        rss = float(Path(peak.name).read_text() or "nan") / 1024.0
        return Run(proc.returncode, out.read().decode(), err.read().decode(), wall, usage.ru_utime + usage.ru_stime,
                   rss)


def path_of_samples(path: Path, samples: int, joints: int = 2) -> Path:
    """A path recording of ``samples`` rows 1 ms apart (``NNNNNNNe-3,0,...``), written in blocks with NumPy."""
    tail = np.frombuffer(("e-3" + ",0" * joints + "\n").encode(), dtype=np.uint8)
    with path.open("wb") as f:
        f.write(("t [s]," + ",".join(["shoulder [rad]", "elbow [rad]"][:joints]) + "\n").encode())
        for start in range(0, samples, 1_000_000):
            k = np.arange(start, min(samples, start + 1_000_000))
            digits = (k[:, None] // 10 ** np.arange(7)[::-1]) % 10 + ord("0")
            f.write(np.hstack([digits.astype(np.uint8), np.tile(tail, (len(k), 1))]).tobytes())
    return path


pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="peak memory is read from /proc")


@pytest.fixture(scope="module")
def hostile(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The issue's hostile files (and 100 000 valid keyframes), for planar2 (shoulder, elbow)."""
    d = tmp_path_factory.mktemp("hostile")
    (d / "bomb.yaml").write_text("joints: [shoulder, elbow]\n" + billion_laughs() + "keyframes:\n  - {q: *a8}\n")
    (d / "gap.csv").write_text("t [s],shoulder [rad],elbow [rad]\n0.0,0.0,0.0\n1000000000.0,0.1,0.1\n")
    (d / "k100k.yaml").write_text(keyframe_text(100_000))
    return {"robot": chain_robot(d, 2000), "urdf": d / "chain.urdf", "bomb": d / "bomb.yaml", "gap": d / "gap.csv",
            "samples": path_of_samples(d / "samples.csv", 10_000_000), "k100k": d / "k100k.yaml", "dir": d}


def refused(run: Run, limit: str, cpu: float = CPU_S) -> None:
    assert run.code == 1, run.out + run.err
    assert f"({limit})" in run.err and "Traceback" not in run.err, run.err
    assert run.cpu < cpu and run.rss < RSS_MB and run.wall < 10 * cpu, run


@pytest.mark.parametrize(("case", "verb", "limit"), [
    ("robot", "check", "MAX_URDF_LINKS"),
    ("urdf", "init", "MAX_URDF_LINKS"),
    ("bomb", "replay", "MAX_KEYFRAME_FILE_NODES"),
    ("gap", "replay", "MAX_DURATION"),
    ("samples", "replay", "MAX_PATH_SAMPLES"),
])
def test_each_hostile_case_ends_quickly_and_small_naming_its_limit(hostile: dict[str, Path], case: str, verb: str,
                                                                    limit: str) -> None:
    if verb == "check":
        run = measured("check", hostile[case])
    elif verb == "init":
        run = measured("init", hostile[case], "-o", hostile["dir"] / "out.yaml")
        assert not (hostile["dir"] / "out.yaml").exists()
    else:
        run = measured("replay", ROBOTS / "planar2.yaml", hostile[case])
    refused(run, limit)


def test_100_000_keyframes_are_refused_by_the_documented_limit_quickly(hostile: dict[str, Path]) -> None:
    refused(measured("replay", ROBOTS / "planar2.yaml", hostile["k100k"]), "MAX_KEYFRAMES", cpu=2 * CPU_S)
