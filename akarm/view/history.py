"""The last seconds of snapshots, as the plots draw them.

:class:`History` keeps what a live source gave (one row per snapshot, in a preallocated ring);
:meth:`History.window` returns a :class:`Window`: times relative to the newest snapshot and, per
joint, the commanded and measured positions, the tracking error and the torque. A recording builds
its windows straight from the file (:meth:`akarm.view.recorded.RecordedSource.window`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from akarm.server.snapshot import Snapshot

__all__ = ["History", "Window", "decimate"]

#: the most points a plot gets per series (more are thinned evenly)
MAX_POINTS = 600


@dataclass(frozen=True)
class Window:
    """Plot data: ``t`` (k,) s relative to the window's end (≤ 0); each other field (k, joints)."""

    t: np.ndarray
    q_des: np.ndarray
    q: np.ndarray
    error: np.ndarray
    tau: np.ndarray

    def joint(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Joint ``k``'s series: t, q_des, q, error, tau."""
        return self.t, self.q_des[:, k], self.q[:, k], self.error[:, k], self.tau[:, k]


def decimate(n: int, most: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``most`` of ``n`` rows, evenly spread, the last always included."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, most).round().astype(np.intp))


class History:
    """The snapshots of the last ``seconds`` (at most ``capacity`` of them) of a live source.

    A snapshot older than the newest one (a restarted server, a new clock) starts the history over.
    """

    def __init__(self, joints: int, seconds: float = 10.0, capacity: int = 2048) -> None:
        self.seconds = seconds
        self.capacity = capacity
        self._t = np.zeros(capacity)
        self._rows = np.zeros((capacity, 4, joints))  # q_des, q, error, tau
        self._count = 0

    def __len__(self) -> int:
        return min(self._count, self.capacity)

    def clear(self) -> None:
        self._count = 0

    def add(self, snap: Snapshot) -> None:
        if self._count and snap.t < self._t[(self._count - 1) % self.capacity]:
            self.clear()
        i = self._count % self.capacity
        self._t[i] = snap.t
        self._rows[i] = (snap.q_des, snap.q, snap.error, snap.tau)
        self._count += 1

    def window(self, seconds: float | None = None) -> Window:
        """The last ``seconds`` (default :attr:`seconds`), oldest first, thinned to :data:`MAX_POINTS`."""
        n = len(self)
        idx = np.arange(self._count - n, self._count) % self.capacity
        t = self._t[idx]
        if n:
            keep = t >= t[-1] - (self.seconds if seconds is None else seconds)
            idx, t = idx[keep], t[keep]
        pick = decimate(len(idx))
        idx, t = idx[pick], t[pick]
        rows = self._rows[idx]
        end = t[-1] if len(t) else 0.0
        return Window(t - end, rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3])
