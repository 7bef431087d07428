"""``akarm demo``: the scripted session runs in lock step, prints its statistics, writes its plot and
telemetry; bad outputs and a missing robot are refused before anything runs; the bundled
recording replays at speed 1 within arm6's limits."""

from __future__ import annotations

import contextlib
import io
import re
import struct
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.arm import Arm
from akarm.cli import demo, main
from akarm.motion import recording
from akarm.telemetry import log as tel

from .conftest import ROBOTS

ARM6 = ("shoulder_pan", "shoulder_lift", "elbow", "forearm_roll", "wrist_pitch", "wrist_roll")


@dataclass
class DemoRun:
    code: int
    out: str
    err: str
    png: Path
    log: Path
    seconds: float


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> DemoRun:
    """One `akarm demo --fast` session, shared by the tests that read its results."""
    d = tmp_path_factory.mktemp("demo")
    png, log = d / "out" / "demo.png", d / "demo.csv"
    out, err = io.StringIO(), io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["demo", "--fast", "-o", str(png), "--log", str(log)])
    return DemoRun(code, out.getvalue(), err.getvalue(), png, log, time.perf_counter() - start)


def _tracking_rows(out: str) -> dict[str, tuple[float, float]]:
    rows = {}
    for name in ARM6:
        m = re.search(rf"^\s+{name}\s+([0-9.]+)\s+([0-9.]+)\s*$", out, re.M)
        assert m, f"no tracking row for {name} in:\n{out}"
        rows[name] = (float(m.group(1)), float(m.group(2)))
    return rows


def test_the_demo_succeeds_and_prints_every_step(run: DemoRun) -> None:
    assert run.code == 0, run.err
    assert run.err == ""
    for k, what in enumerate(["enable", "move_to('home')", "move_to('ready')", "move_to('left')", "move_to('reach')",
                              "move_to('home')", "move_through(5 waypoints", "replay('demo_path.csv')", "disable"],
                             start=1):
        assert re.search(rf"^\s+{k}\. {re.escape(what)}", run.out, re.M), (k, what, run.out)
    assert "lock step (--fast)" in run.out


def test_tracking_statistics_are_printed_per_joint_and_plausible(run: DemoRun) -> None:
    rows = _tracking_rows(run.out)
    for name, (rms, peak) in rows.items():
        # the arm moved (a one-period-old measurement alone gives mrad of error at speed) and tracked well
        assert 0.1 < rms < 8.0, (name, rms)
        assert rms <= peak < 25.0, (name, peak)


def test_printed_statistics_match_the_saved_telemetry(run: DemoRun) -> None:
    log = tel.load(run.log)
    assert log.joint_names == ARM6
    assert 12.0 < log.t[-1] - log.t[0] < 20.0  # the whole session, enable to disable, at arm6's 480 Hz
    # one period apart, to the CSV's resolution (9 significant digits: 1e-7 s at t = 15 s)
    assert np.allclose(np.diff(log.t), 1 / 480, rtol=0, atol=1.5e-7)
    rows = _tracking_rows(run.out)
    rms = log.rms_error() * 1e3
    peak = np.abs(log.tracking_error()).max(axis=0) * 1e3
    for k, name in enumerate(ARM6):
        assert rows[name][0] == pytest.approx(rms[k], abs=1.5e-3)
        assert rows[name][1] == pytest.approx(peak[k], abs=1.5e-3)
    # the session visited the poses: the replayed figure eight swings the base ±0.55 rad
    assert log.q_des[:, 0].max() > 1.1  # `left`
    assert log.q_des[:, 1].max() > 1.25  # `reach`


def test_loop_statistics_in_lock_step(run: DemoRun) -> None:
    m = re.search(r"rate ([0-9.]+) Hz \(target 480\), (\d+) cycles, missed slots (\d+), lateness p99 (\d+) µs",
                  run.out)
    assert m, run.out
    assert float(m.group(1)) == pytest.approx(480.0, abs=0.1)
    assert int(m.group(2)) > 6000
    assert int(m.group(3)) == 0 and int(m.group(4)) == 0  # simulated time: never late


def test_the_plot_is_a_png_with_a_row_per_joint(run: DemoRun) -> None:
    data = run.png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 100_000
    width, height = struct.unpack(">II", data[16:24])
    assert width == 1400 and height > 6 * 180
    assert f"plot: {run.png}" in run.out


def test_the_fast_demo_is_fast(run: DemoRun) -> None:
    assert run.seconds < 45.0  # ~6 s on an idle machine; generous for a loaded CI runner


def test_a_log_with_an_unknown_suffix_is_refused_before_anything_runs(capsys: pytest.CaptureFixture[str],
                                                                       tmp_path: Path) -> None:
    start = time.perf_counter()
    assert main(["demo", "--fast", "--no-plot", "--log", str(tmp_path / "run.txt")]) == 1
    err = capsys.readouterr().err
    assert "cannot save telemetry as" in err and ".csv or .npz" in err
    assert time.perf_counter() - start < 2.0


def test_a_plot_that_is_not_png_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["demo", "--fast", "-o", str(tmp_path / "x.jpg")]) == 1
    assert "only PNG" in capsys.readouterr().err


def test_without_matplotlib_the_demo_says_which_extra_to_install(capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch,
                                                                 tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backends.backend_agg", None)
    assert main(["demo", "--fast", "-o", str(tmp_path / "d.png")]) == 1
    assert 'akarm[plot]' in capsys.readouterr().err
    assert not (tmp_path / "d.png").exists()


def test_without_the_robots_folder_the_demo_says_where_to_get_it(capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch,
                                                                 tmp_path: Path) -> None:
    monkeypatch.setattr(demo, "robots_dir", lambda: tmp_path / "robots")
    assert main(["demo", "--fast", "--no-plot"]) == 1
    err = capsys.readouterr().err
    assert str(tmp_path / "robots" / "arm6.yaml") in err
    assert "source repository" in err and "pip install -e" in err


def test_the_demo_finds_the_repository_robots() -> None:
    assert demo.robots_dir() == ROBOTS
    assert (demo.robots_dir() / "arm6.yaml").is_file()


def test_the_bundled_recording_replays_at_speed_1_within_arm6_limits() -> None:
    config = akarm.load_robot(ROBOTS / "arm6.yaml")
    rec = recording.load(demo.DEMO_PATH, config.joint_names)
    assert isinstance(rec, recording.PathRecording)
    assert np.allclose(np.diff(rec.t), 0.01)  # 100 Hz
    limits = Arm(config).limits
    recording.check_path(recording.PathPlan(rec, 0.0, 1.0), limits)  # raises LimitError if not
    ready = np.array(config.pose("ready"))
    assert np.allclose(rec.q[0], ready) and np.allclose(rec.q[-1], ready)  # a closed figure, at rest
    assert np.allclose(rec.q[1], rec.q[0], atol=1e-5)
    with pytest.raises(akarm.LimitError, match="--speed"):  # and it does use the limits: twice as fast fails
        recording.check_path(recording.PathPlan(rec, 0.0, 2.0), limits)
