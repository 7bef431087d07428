"""Plots of telemetry: what the arm was asked to do against what it did.

::

    from akarm.telemetry.plot import plot_log
    plot_log(arm.telemetry(), "run.png")        # or akarm.telemetry.log.load("run.csv")

One row per joint, three columns sharing the time axis (s from the log's first cycle):

- position: desired and measured, rad;
- tracking error ``q_des - q``, mrad, with its RMS in the title;
- torque: measured and feed-forward, N·m.

Drawn with matplotlib's Agg canvas (no screen, no global backend switch) and written atomically
(temporary file, then rename), so a crash never leaves half a PNG. matplotlib comes with the
``plot`` extra: ``pip install "akarm[plot]"``.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from akarm.errors import RecordingError
from akarm.files import atomic_write
from akarm.telemetry.log import MAX_TELEMETRY_JOINTS, TelemetryLog

__all__ = ["plot_log"]

_ROW_HEIGHT = 1.9  # inches per joint row
_WIDTH = 14.0  # inches
_DPI = 100
_TOP = 0.7  # inches above the first row (the figure's title)
_BOTTOM = 0.6  # inches below the last row (the time axis)
_EVENT_LABELS = 0.6  # inches more at the top for event labels

if TYPE_CHECKING:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure


def figure_classes() -> tuple[type[Figure], type[FigureCanvasAgg]]:
    """matplotlib's Figure and Agg canvas, or a RecordingError that says how to install them."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise RecordingError("plotting needs matplotlib, which is not installed",
                             fix='pip install "akarm[plot]" (or pip install matplotlib)') from None
    return Figure, FigureCanvasAgg


def plot_log(log: TelemetryLog, path: str | os.PathLike[str], *, title: str | None = None,
             events: Sequence[tuple[float, str]] = ()) -> Path:
    """Draw ``log`` as a PNG at ``path``: per joint, position (desired vs measured, rad), tracking
    error (mrad) and torque (measured and feed-forward, N·m) against time (s).

    Args:
        log: a telemetry log (``arm.telemetry()`` or :func:`akarm.telemetry.log.load`).
        path: the PNG to write (parent folders are created); written atomically.
        title: the figure's title; default: the number of cycles and the duration.
        events: ``(time, label)`` pairs marked as vertical lines on every plot, labelled above the
            first row (e.g. the steps of a session); time in s on the log's clock (like ``log.t``).

    Returns:
        The path written.

    Raises:
        RecordingError: matplotlib is missing, the log has no cycles, or ``path`` is not a ``.png``.
    """
    target = Path(path)
    if target.suffix.lower() != ".png":
        raise RecordingError(f"cannot plot to {target.name!r}: only PNG is written", fix="use a .png file name")
    if len(log) == 0:
        raise RecordingError("the telemetry log has no cycles: nothing to plot",
                             fix="record some motion first (the arm records every cycle while open)")
    if not 0 < len(log.joint_names) <= MAX_TELEMETRY_JOINTS:
        raise RecordingError(f"the telemetry log has {len(log.joint_names)} joints: a plot draws 1 to "
                             f"{MAX_TELEMETRY_JOINTS} (MAX_TELEMETRY_JOINTS)", fix="plot a log of one arm's joints")
    Figure, FigureCanvasAgg = figure_classes()

    names = log.joint_names
    n = len(names)
    t = log.t - log.t[0]
    err_mrad = log.tracking_error() * 1e3
    rms_mrad = log.rms_error() * 1e3
    with np.errstate(invalid="ignore"):
        max_mrad = np.nanmax(np.abs(err_mrad), axis=0) if np.any(np.isfinite(err_mrad)) else np.zeros(n)

    top = _TOP + (_EVENT_LABELS if events else 0.0)
    height = top + _BOTTOM + _ROW_HEIGHT * n
    fig = Figure(figsize=(_WIDTH, height), dpi=_DPI)
    FigureCanvasAgg(fig)
    # fixed margins in inches: much faster than a constrained layout, and the rows stay the same size
    axes = fig.subplots(n, 3, sharex=True, squeeze=False,
                        gridspec_kw={"left": 0.07, "right": 0.99, "top": 1 - top / height, "bottom": _BOTTOM / height,
                                     "wspace": 0.22, "hspace": 0.45})
    for k, name in enumerate(names):
        ax_q, ax_e, ax_tau = axes[k]
        ax_q.plot(t, log.q_des[:, k], color="tab:blue", lw=1.6, label="desired")
        ax_q.plot(t, log.q[:, k], color="tab:orange", lw=1.0, ls="--", label="measured")
        ax_q.set_ylabel(f"{name}\nposition, rad")

        ax_e.plot(t, err_mrad[:, k], color="tab:red", lw=0.9)
        ax_e.axhline(0.0, color="0.6", lw=0.6)
        ax_e.set_ylabel("error, mrad")
        ax_e.set_title(f"{name}: RMS {rms_mrad[k]:.2f} mrad, max {max_mrad[k]:.2f} mrad", fontsize=9)

        ax_tau.plot(t, log.tau[:, k], color="tab:green", lw=0.9, label="measured")
        ax_tau.plot(t, log.tau_ff[:, k], color="tab:purple", lw=1.2, ls="--", label="feed-forward")
        ax_tau.set_ylabel("torque, N·m")
        for ax in (ax_q, ax_e, ax_tau):
            ax.grid(True, lw=0.4, alpha=0.6)
        if k == 0:
            ax_q.legend(loc="upper right", fontsize=8)
            ax_tau.legend(loc="upper right", fontsize=8)
    for t_event, label in events:
        x = t_event - log.t[0]
        for ax in axes.flat:
            ax.axvline(x, color="0.45", lw=0.6, ls=":")
        for ax in axes[0][::2]:  # position and torque columns: the error column has its title there
            ax.annotate(label, (x, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 2),
                        textcoords="offset points", fontsize=7, color="0.3", rotation=90, ha="center", va="bottom")
    for ax in axes[-1]:
        ax.set_xlabel("time, s")
    duration = float(t[-1]) if len(t) else 0.0
    fig.suptitle(title if title is not None else f"akarm telemetry: {len(log)} cycles, {duration:.2f} s")

    def write(f: io.BufferedWriter) -> None:
        fig.savefig(f, format="png", dpi=_DPI)

    return atomic_write(target, write)
