"""One command line: named-joint targets, names checked with a did-you-mean, output files checked
before anything moves, negative values without `--`, one word per meaning, `-i/-c/-b` everywhere."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from akarm.cli import main

from .conftest import ROOT
from .test_cli import HANGING, PLANAR2, bus, frames_received, relaxed, simulated  # noqa: F401 (relaxed: a fixture)

# ----------------------------------------------------------------------------- move targets


def test_move_named_joints_moves_those_and_keeps_the_others(channel: str, relaxed: str,  # noqa: F811
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["move", relaxed, *bus(channel), "elbow=-0.3", "--speed", "0.8"]) == 0
        q = sim.q.copy()
    assert q[1] == pytest.approx(-0.3, abs=0.02)  # measured while damped and disabled: a little sag
    assert q[0] == pytest.approx(HANGING[0], abs=0.05)  # the shoulder stayed where it hung
    out = capsys.readouterr().out
    assert "moving to elbow=-0.3 [" in out and "arrived" in out


@pytest.mark.parametrize(("words", "message"), [
    (["hme"], "no pose named 'hme' (did you mean 'home'?)"),
    (["elbw=0.2"], "no joint named 'elbw' (did you mean 'elbow'?)"),
    (["home", "--log", "run.txt"], "cannot save telemetry as 'run.txt': the name must end in .csv or .npz"),
    (["home", "--log", "robot.yaml/run.csv"], "cannot create directory robot.yaml: robot.yaml is not a directory"),
    (["elbow=3.0"], "target +3.0000 rad is outside"),
])
def test_bad_names_and_output_files_are_refused_before_anything_moves(
        words: list[str], message: str, channel: str, relaxed: str,  # noqa: F811
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "robot.yaml").write_text("a file, not a folder")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["move", relaxed, *bus(channel), *words]) == 1
        assert frames_received(sim) == 0  # not a frame sent
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_replay_checks_its_log_file_first(channel: str, relaxed: str, tmp_path: Path,  # noqa: F811
                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "k.yaml"
    path.write_text("robot: planar2\njoints: [shoulder, elbow]\nkeyframes:\n  - {q: [0.1, 0.1]}\n")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["replay", relaxed, *bus(channel), str(path), "--log", str(tmp_path / "x.png")]) == 1
        assert frames_received(sim) == 0
    assert "cannot save telemetry as" in capsys.readouterr().err


# ----------------------------------------------------------------------------- option names


def test_bench_runs_on_the_bus_it_is_given(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", PLANAR2, "--seconds", "1", "--in-process", "-i", "virtual", "-c", channel]) == 0
    assert "moves in" in capsys.readouterr().out


# ----------------------------------------------------------------------------- the checkout


def test_the_demo_plot_is_not_left_in_a_clean_checkout() -> None:
    """`akarm demo` writes akarm-demo.png into the current folder (the README's quick start: the clone)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    r = subprocess.run(["git", "check-ignore", "-q", "akarm-demo.png"], cwd=ROOT)
    assert r.returncode == 0, "akarm-demo.png is not ignored by git"
    r = subprocess.run(["git", "check-ignore", "-q", "docs/demo.png"], cwd=ROOT)
    assert r.returncode == 1  # the README's image itself stays tracked
