"""akarm.telemetry.plot.plot_log on small synthetic telemetry logs: a real PNG of the right size, drawn from
the data, written atomically, and clear errors for what cannot be plotted."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from akarm.errors import RecordingError
from akarm.telemetry.log import TelemetryLog
from akarm.telemetry.plot import plot_log

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _log(n_joints: int = 2, seconds: float = 1.0, error_rad: float = 0.002) -> TelemetryLog:
    """A log at 500 Hz: desired sine per joint, measured lagging by ``error_rad`` (rad)."""
    t = 10.0 + np.arange(0.0, seconds, 0.002)  # a clock that does not start at 0
    phase = np.arange(n_joints)[None, :]
    q_des = 0.5 * np.sin(2 * np.pi * t[:, None] + phase)
    q = q_des - error_rad * np.cos(2 * np.pi * t[:, None] + phase)
    dq = np.gradient(q_des, t, axis=0)
    tau_ff = 1.5 * np.cos(t[:, None] + phase)
    names = tuple(f"joint{k}" for k in range(n_joints))
    return TelemetryLog(names, t, q_des, dq, q, dq, tau_ff + 0.05, tau_ff)


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def _pixels(path: Path) -> np.ndarray:
    import matplotlib.image as mpimg

    return (mpimg.imread(path)[:, :, :3] * 255).round().astype(int)


def _has_colour(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 12) -> int:
    return int(np.sum(np.all(np.abs(img - np.array(rgb)) <= tol, axis=2)))


def test_writes_a_png_whose_height_grows_with_the_joints(tmp_path: Path) -> None:
    two = plot_log(_log(2), tmp_path / "two.png")
    six = plot_log(_log(6), tmp_path / "sub" / "six.png")  # parent folders are created
    assert two == tmp_path / "two.png" and six.exists()
    (w2, h2), (w6, h6) = _png_size(two), _png_size(six)
    assert w2 == w6 == 1400
    assert h6 > h2 + 4 * 150  # four more rows of plots
    assert two.stat().st_size > 20_000
    assert not [p for p in tmp_path.rglob("*.tmp")]  # the temporary file was renamed away


def test_draws_the_data_lines_in_their_colours(tmp_path: Path) -> None:
    img = _pixels(plot_log(_log(2), tmp_path / "a.png"))
    assert _has_colour(img, (31, 119, 180)) > 100  # desired position (tab:blue)
    assert _has_colour(img, (214, 39, 40)) > 150  # tracking error (tab:red)
    assert _has_colour(img, (44, 160, 44)) > 150  # measured torque (tab:green)


def test_the_picture_depends_on_the_data(tmp_path: Path) -> None:
    a = _pixels(plot_log(_log(2, error_rad=0.002), tmp_path / "a.png"))
    b = _pixels(plot_log(_log(2, error_rad=0.02), tmp_path / "b.png"))
    assert a.shape == b.shape
    assert np.mean(np.any(a != b, axis=2)) > 0.001


def test_overwrites_an_existing_file(tmp_path: Path) -> None:
    target = tmp_path / "run.png"
    target.write_bytes(b"old")
    plot_log(_log(1), target)
    assert target.read_bytes()[:8] == PNG_SIGNATURE


def test_an_empty_log_is_a_clear_error(tmp_path: Path) -> None:
    empty = TelemetryLog(("a",), np.zeros(0), *(np.zeros((0, 1)) for _ in range(6)))
    with pytest.raises(RecordingError, match="no cycles"):
        plot_log(empty, tmp_path / "e.png")
    assert not (tmp_path / "e.png").exists()


def test_only_png_is_written(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="only PNG") as e:
        plot_log(_log(1), tmp_path / "run.pdf")
    assert ".png" in e.value.fix


def test_missing_matplotlib_is_an_akarm_error_naming_the_extra(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    # a None entry in sys.modules makes `import` raise ImportError, as if matplotlib were absent
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backends.backend_agg", None)
    with pytest.raises(RecordingError, match="matplotlib") as e:
        plot_log(_log(1), tmp_path / "m.png")
    assert "akarm[plot]" in e.value.fix
    assert not (tmp_path / "m.png").exists()


def test_events_are_marked_and_make_room_for_their_labels(tmp_path: Path) -> None:
    log = _log(2, seconds=2.0)
    plain = plot_log(log, tmp_path / "plain.png")
    marked = plot_log(log, tmp_path / "marked.png", events=[(log.t[0] + 0.5, "start"), (log.t[0] + 1.5, "replay")])
    (w0, h0), (w1, h1) = _png_size(plain), _png_size(marked)
    assert w0 == w1 and h1 > h0  # room above the first row for the labels
    img = _pixels(marked)
    # the dotted event lines are grey (0.45) and cross every row: a grey column in the bottom row too
    bottom = img[int(h1 * 0.8):int(h1 * 0.9)]
    assert _has_colour(bottom, (115, 115, 115), tol=20) > 20
    assert _has_colour(_pixels(plain)[int(h0 * 0.8):int(h0 * 0.9)], (115, 115, 115), tol=20) < \
        _has_colour(bottom, (115, 115, 115), tol=20)
