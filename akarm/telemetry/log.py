"""Per-cycle telemetry: a ring buffer of desired and measured joint states, saved atomically.

Each control cycle records its time, the desired q/dq (the trajectory), the measured q/dq/τ (the
joints' latest feedback), the feed-forward torque and the collision reflex's estimate of the
external torque (:mod:`akarm.control.collision`), all joint side in SI. Save to CSV (a header
naming joints and units), NumPy ``.npz`` or MCAP (``.mcap``: ROS 2 JointState messages that Foxglove
and ``ros2 bag`` open, :mod:`akarm.telemetry.mcap`); the file is written to a temporary name and
renamed, so a crash never leaves half a file. :func:`load` reads each back.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akarm.errors import RecordingError
from akarm.files import atomic_write

Values = Sequence[float] | np.ndarray

__all__ = ["FIELDS", "Telemetry", "TelemetryLog", "load", "load_mcap"]

#: The per-joint fields of a record, with their units.
FIELDS = (("q_des", "rad"), ("dq_des", "rad/s"), ("q", "rad"), ("dq", "rad/s"), ("tau", "N·m"),
          ("tau_ff", "N·m"), ("tau_ext", "N·m"))


@dataclass(frozen=True)
class TelemetryLog:
    """Recorded cycles as arrays: ``t`` (n,), and each of :data:`FIELDS` as (n, joints).

    ``tau_ext`` (the external torque estimate) is NaN where it was not recorded (logs written
    before akarm had it, or built without it)."""

    joint_names: tuple[str, ...]
    t: np.ndarray
    q_des: np.ndarray
    dq_des: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    tau_ff: np.ndarray
    tau_ext: np.ndarray = None  # type: ignore[assignment]  # None: not recorded, NaN (see __post_init__)

    def __post_init__(self) -> None:
        if self.tau_ext is None:
            object.__setattr__(self, "tau_ext", np.full(np.shape(self.q), np.nan))

    def __len__(self) -> int:
        return len(self.t)

    def tracking_error(self) -> np.ndarray:
        """``q_des - q`` per cycle and joint, rad."""
        return self.q_des - self.q

    def rms_error(self) -> np.ndarray:
        """RMS tracking error per joint, rad."""
        e = self.tracking_error()
        return np.sqrt(np.nanmean(e * e, axis=0)) if len(e) else np.zeros(len(self.joint_names))

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Save as ``.csv``, ``.npz`` or ``.mcap`` (by suffix), atomically."""
        p = Path(path)
        if p.suffix == ".mcap":
            from akarm.telemetry.mcap import save_mcap

            return save_mcap(p, self)
        if p.suffix == ".npz":
            arrays = {k: getattr(self, k) for k in ("t", *(f for f, _ in FIELDS))}
            return atomic_write(p, lambda f: np.savez(f, joint_names=np.array(self.joint_names), **arrays))
        if p.suffix != ".csv":
            raise RecordingError(f"cannot save telemetry as {p.suffix!r}", fix="use a .csv, .npz or .mcap file name")

        def write(f: io.BufferedWriter) -> None:
            text = io.TextIOWrapper(f, encoding="utf-8", newline="")
            w = csv.writer(text)
            w.writerow(["t [s]", *(f"{field}.{j} [{unit}]" for field, unit in FIELDS for j in self.joint_names)])
            data = np.column_stack([self.t, *(getattr(self, field) for field, _ in FIELDS)])
            for row in data:
                w.writerow([f"{x:.9g}" for x in row])
            text.flush()
            text.detach()

        return atomic_write(p, write)


def load(path: str | os.PathLike[str]) -> TelemetryLog:
    """Read a telemetry file written by :meth:`TelemetryLog.save`.

    An ``.mcap`` file must hold one arm (:func:`load_mcap` reads several).

    Raises:
        RecordingError: the file is missing, truncated or not a telemetry log.
    """
    p = Path(path)
    if p.suffix == ".mcap":
        arms = load_mcap(p)
        if len(arms) != 1:
            raise RecordingError(f"{p} holds the telemetry of {len(arms)} arms ({', '.join(arms)})",
                                 fix="read it with akarm.telemetry.log.load_mcap (akarm plot draws each)")
        return next(iter(arms.values()))
    try:
        if p.suffix == ".npz":
            with np.load(p) as z:
                names = tuple(str(n) for n in z["joint_names"])
                known = [f for f, _ in FIELDS if f != "tau_ext" or f in z.files]  # older logs: no tau_ext
                return TelemetryLog(names, z["t"], *(z[f] for f in known))
        with p.open(newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, KeyError, ValueError) as e:
        raise RecordingError(f"cannot read telemetry {p}: {e}", fix="pass a .csv or .npz written by akarm") from None
    if not rows or not rows[0] or rows[0][0] != "t [s]":
        raise RecordingError(f"{p} is not an akarm telemetry CSV (no 't [s]' header)",
                             fix="pass a file written by Arm.telemetry().save()")
    header = rows[0]
    fields = len(FIELDS) if header[-1].startswith("tau_ext.") else len(FIELDS) - 1  # older logs: no tau_ext
    per_field = (len(header) - 1) // fields
    names = tuple(h.split(".", 1)[1].rsplit(" [", 1)[0] for h in header[1:1 + per_field])
    try:
        data = np.array([[float(x) for x in r] for r in rows[1:]], dtype=float).reshape(-1, len(header))
    except ValueError:
        raise RecordingError(f"{p} has a malformed or truncated row", fix="re-record the log") from None
    cols = [data[:, 1 + k * per_field:1 + (k + 1) * per_field] for k in range(fields)]
    return TelemetryLog(names, data[:, 0], *cols)


def load_mcap(path: str | os.PathLike[str]) -> dict[str, TelemetryLog]:
    """Every arm's telemetry in an MCAP file (:mod:`akarm.telemetry.mcap`): ``{arm name: log}``, ``""``
    for a file of one unnamed arm (what ``Arm.telemetry().save("run.mcap")`` writes)."""
    from akarm.telemetry.mcap import read_mcap

    return {arm: TelemetryLog(a.joint_names, a.t, *(a.fields[f] for f, _ in FIELDS))
            for arm, a in read_mcap(path).items()}


class Telemetry:
    """Ring buffer of the last ``capacity`` cycles (preallocated: recording allocates nothing)."""

    def __init__(self, joint_names: Sequence[str], capacity: int) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self.capacity = capacity
        self.t = np.zeros(capacity)
        self.rows = np.zeros((capacity, len(FIELDS) * n))  # one row per cycle: the fields side by side
        self._nan = [math.nan] * n
        self.count = 0

    def record(self, t: float, q_des: Values, dq_des: Values, q: Values, dq: Values, tau: Values, tau_ff: Values,
               tau_ext: Values | None = None) -> None:
        """Record one cycle (sequences of joint values, SI; ``tau_ext`` ``None``: not known, NaN)."""
        i = self.count % self.capacity
        self.t[i] = t
        ext = self._nan if tau_ext is None else tau_ext
        self.rows[i] = [*q_des, *dq_des, *q, *dq, *tau, *tau_ff, *ext]  # one conversion for the whole record
        self.count += 1

    def clear(self) -> None:
        """Forget every record."""
        self.count = 0

    def snapshot(self, since: float | None = None) -> TelemetryLog:
        """The recorded cycles, oldest first (optionally only those at or after time ``since``)."""
        n = min(self.count, self.capacity)
        if self.count <= self.capacity:
            idx = np.arange(n)
        else:
            start = self.count % self.capacity
            idx = np.concatenate([np.arange(start, self.capacity), np.arange(0, start)])
        t = self.t[idx]
        if since is not None:
            keep = t >= since
            idx, t = idx[keep], t[keep]
        fields = self.rows[idx].reshape(len(idx), len(FIELDS), len(self.joint_names))
        return TelemetryLog(self.joint_names, t.copy(), *(fields[:, k].copy() for k in range(len(FIELDS))))
