"""The `akarm` verbs' refusals and the verbs that need no bus: help, bad joint names and files, plot
(every verb end to end: tests/system/test_cli.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from akarm.cli import VERBS, main
from akarm.telemetry.log import TelemetryLog

from .conftest import ROBOTS

PLANAR2 = str(ROBOTS / "planar2.yaml")

PNG = b"\x89PNG\r\n\x1a\n"


def test_help_lists_every_verb(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for verb in ("scan", "status", "enable", "disable", "zero", "move", "teach", "replay", "plot", "bench"):
        assert f"    {verb}" in out and VERBS[verb][1][:30] in out


def test_zero_an_unknown_joint_names_the_joints(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["zero", PLANAR2, "-i", "virtual", "-c", "unused", "wrist"]) == 1
    err = capsys.readouterr().err
    assert "no joint named 'wrist'" in err and "shoulder, elbow" in err


def test_teach_rejects_an_unknown_file_type(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["teach", PLANAR2, "-i", "virtual", "-c", "unused", "out.txt"]) == 1
    assert "unknown recording type '.txt'" in capsys.readouterr().err


def test_replay_a_corrupt_recording_is_one_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / "broken.csv"
    csv.write_text("t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n0.01,0.1\n")
    assert main(["replay", PLANAR2, "-i", "virtual", "-c", "unused", str(csv)]) == 1
    err = capsys.readouterr().err
    assert "row 3 has 2 values, expected 3" in err and len(err.strip().splitlines()) == 1
    yml = tmp_path / "broken.yaml"
    yml.write_text("joints: [shoulder, elbow]\nkeyframes:\n  - {q: [0.1, 0.2]\n")
    assert main(["replay", PLANAR2, "-i", "virtual", "-c", "unused", str(yml)]) == 1
    assert "not valid YAML" in capsys.readouterr().err


def test_plot_writes_a_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    t = np.arange(0.0, 1.0, 0.002)
    q_des = np.column_stack([np.sin(t), np.cos(t)])
    q = q_des - 0.001
    log = TelemetryLog(("shoulder", "elbow"), t, q_des, np.gradient(q_des, t, axis=0), q, np.zeros_like(q),
                       0.5 * q, 0.4 * q)
    src = log.save(tmp_path / "run.npz")
    assert main(["plot", str(src)]) == 0
    png = tmp_path / "run.png"
    data = png.read_bytes()
    assert data[:8] == PNG and len(data) > 20_000
    assert f"wrote {png}" in capsys.readouterr().out
    out = tmp_path / "sub" / "other.png"
    assert main(["plot", str(log.save(tmp_path / "run.csv")), "-o", str(out)]) == 0
    assert out.read_bytes()[:8] == PNG


def test_plot_a_bad_log_is_one_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("hello\n")
    assert main(["plot", str(bad)]) == 1
    assert "not an akarm telemetry CSV" in capsys.readouterr().err
    assert not (tmp_path / "bad.png").exists()
