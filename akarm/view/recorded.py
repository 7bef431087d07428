"""A recorded run played back: a telemetry file read into a :class:`~akarm.telemetry.log.TelemetryLog`,
shown at any instant of it (the view's time slider).

Files are read by suffix through :data:`READERS`, which another format joins with
:func:`register_reader` (a function from a path to a ``TelemetryLog``): ``.csv`` and ``.npz`` are
akarm's own (:func:`akarm.telemetry.log.load`); ``.mcap`` is read by ``akarm.telemetry.mcap.load``
when this akarm has that module.
"""

from __future__ import annotations

import importlib
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from akarm.errors import RecordingError
from akarm.server.snapshot import Snapshot
from akarm.telemetry.log import TelemetryLog
from akarm.view.history import Window, decimate

if TYPE_CHECKING:
    from akarm.view.sources import Controls

__all__ = ["READERS", "RecordedSource", "read_telemetry", "register_reader"]

Reader = Callable[[Path], TelemetryLog]


def _akarm_log(path: Path) -> TelemetryLog:
    from akarm.telemetry.log import load

    return load(path)


def _mcap(path: Path) -> TelemetryLog:
    try:
        module = importlib.import_module("akarm.telemetry.mcap")
    except ImportError as e:
        raise RecordingError(f"cannot read {path}: this akarm reads no MCAP telemetry ({e})",
                             fix="save the run as .csv or .npz (Arm.telemetry().save), or update akarm") from None
    load = getattr(module, "load", None)
    if not callable(load):
        raise RecordingError(f"cannot read {path}: akarm.telemetry.mcap has no load(path)",
                             fix="save the run as .csv or .npz")
    log = load(path)
    if not isinstance(log, TelemetryLog):
        raise RecordingError(f"akarm.telemetry.mcap.load({path}) did not give a TelemetryLog",
                             fix="save the run as .csv or .npz")
    return log


#: suffix (lower case, with the dot) → reader
READERS: dict[str, Reader] = {".csv": _akarm_log, ".npz": _akarm_log, ".mcap": _mcap}


def register_reader(suffix: str, reader: Reader) -> None:
    """Read telemetry files ending in ``suffix`` (``".bag"``) with ``reader(path) -> TelemetryLog``."""
    if not suffix.startswith(".") or len(suffix) < 2:
        raise ValueError(f"a suffix starts with a dot, not {suffix!r}")
    READERS[suffix.lower()] = reader


def read_telemetry(path: str | os.PathLike[str]) -> TelemetryLog:
    """The telemetry in ``path``, read by its suffix.

    Raises:
        RecordingError: an unknown suffix, a missing or unreadable file, or one with no cycles.
    """
    p = Path(path)
    reader = READERS.get(p.suffix.lower())
    if reader is None:
        raise RecordingError(f"cannot play back {p}: no reader for {p.suffix or 'files without a suffix'}",
                             fix="telemetry files are " + ", ".join(sorted(READERS)))
    if not p.is_file():
        raise RecordingError(f"cannot play back {p}: no such file", fix="check the path")
    log = reader(p)
    if len(log) == 0:
        raise RecordingError(f"{p} holds no cycles", fix="record a run first (akarm demo --log run.csv)")
    return log


class RecordedSource:
    """Plays ``log`` back: :meth:`at` is the arm at a time of the recording (s from its start);
    :meth:`snapshot` at :attr:`position`, which the view moves (its time slider and play button).

    Args:
        log: the recording. names: its joints must be these (the robot's), in any order.
        title: what the view says it shows.
    """

    controls: Controls | None = None

    def __init__(self, log: TelemetryLog, names: tuple[str, ...], title: str = "") -> None:
        missing = [n for n in names if n not in log.joint_names]
        if missing:
            raise RecordingError(f"the recording has no joint {', '.join(missing)} (it has "
                                 f"{', '.join(log.joint_names)})", fix="play it back with the robot it was recorded on")
        order = [log.joint_names.index(n) for n in names]
        self.names = names
        self.title = title or "recording"
        self.t = np.asarray(log.t, dtype=float) - float(log.t[0])
        self._q_des = np.asarray(log.q_des, dtype=float)[:, order]
        self._q = np.asarray(log.q, dtype=float)[:, order]
        self._tau = np.asarray(log.tau, dtype=float)[:, order]
        self._tau_ff = np.asarray(log.tau_ff, dtype=float)[:, order]
        self.duration = float(self.t[-1])
        span = self.duration / (len(self.t) - 1) if len(self.t) > 1 else 0.0
        self.rate_hz = 1.0 / span if span > 0 else 0.0
        self.position = 0.0

    def index(self, t: float) -> int:
        """The last recorded cycle at or before ``t`` (clamped to the recording)."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))

    def at(self, t: float) -> Snapshot:
        """The arm as recorded at ``t`` s from the start (temperatures, ages and the loop's counters
        are not recorded: NaN and 0)."""
        i = self.index(t)
        n = len(self.names)
        q, q_des = tuple(self._q[i].tolist()), tuple(self._q_des[i].tolist())
        return Snapshot(t=float(self.t[i]), names=self.names, q=q, q_des=q_des,
                        error=tuple(d - m for d, m in zip(q_des, q, strict=True)), tau=tuple(self._tau[i].tolist()),
                        tau_ff=tuple(self._tau_ff[i].tolist()), temperature=(math.nan,) * n, age=(math.nan,) * n,
                        fault=(0,) * n, mode="recorded", enabled=False, moving=False, stop="",
                        rate_hz=self.rate_hz, loop_rate_hz=0.0, cycles=i + 1, missed_slots=0)

    def snapshot(self) -> Snapshot:
        return self.at(self.position)

    def window(self, end: float, seconds: float = 10.0) -> Window:
        """The ``seconds`` of the recording before ``end`` (s from its start), thinned for a plot."""
        lo, hi = int(np.searchsorted(self.t, end - seconds, side="left")), self.index(end) + 1
        idx = np.arange(lo, hi)[decimate(hi - lo)]
        q_des, q = self._q_des[idx], self._q[idx]
        return Window(self.t[idx] - end, q_des, q, q_des - q, self._tau[idx])

    def close(self) -> None:
        pass
