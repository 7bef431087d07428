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
import struct
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeAlias

import numpy as np

from akarm.errors import RecordingError
from akarm.files import FileProblem, atomic_write, number, over, read_csv_table

Values: TypeAlias = Sequence[float] | np.ndarray  # (an alias: still a type where numpy's are missing)

__all__ = ["FIELDS", "MAX_TELEMETRY_BYTES", "MAX_TELEMETRY_JOINTS", "MAX_TELEMETRY_VALUES", "Telemetry", "TelemetryLog",
           "check_joints", "load", "load_mcap"]

#: Bytes of a telemetry file: a CSV's, or an NPZ's arrays uncompressed.
MAX_TELEMETRY_BYTES = 512 << 20
#: Numbers in a telemetry file, cycles × (1 + 7 × joints): 25 minutes of 6 joints at 500 Hz (256 MB).
MAX_TELEMETRY_VALUES = 32_000_000
#: Joints of one arm in a telemetry file (a plot draws three panels a joint).
MAX_TELEMETRY_JOINTS = 64

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
    """Read a telemetry file written by :meth:`TelemetryLog.save`, within :data:`MAX_TELEMETRY_BYTES`
    and :data:`MAX_TELEMETRY_VALUES` (refused before its arrays are allocated).

    An ``.mcap`` file must hold one arm (:func:`load_mcap` reads several).

    Raises:
        RecordingError: the file is missing, past a limit (named), truncated or not a telemetry log.
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
            return _load_npz(p)
        header, data = read_csv_table(p, what="telemetry file", max_bytes=MAX_TELEMETRY_BYTES,
                                      bytes_name="MAX_TELEMETRY_BYTES", max_rows=MAX_TELEMETRY_VALUES,
                                      rows_name="MAX_TELEMETRY_VALUES", rows="cycles", max_values=MAX_TELEMETRY_VALUES,
                                      values_name="MAX_TELEMETRY_VALUES", check_header=_check_header)
    except FileProblem as e:
        raise RecordingError(f"{p}: {e.what}", fix=e.fix) from None
    fields = len(FIELDS) if header[-1].startswith("tau_ext.") else len(FIELDS) - 1  # older logs: no tau_ext
    per_field = (len(header) - 1) // fields
    names = tuple(h.split(".", 1)[1].rsplit(" [", 1)[0] for h in header[1:1 + per_field])
    cols = [data[:, 1 + k * per_field:1 + (k + 1) * per_field] for k in range(fields)]
    return TelemetryLog(names, data[:, 0], *cols)


def check_joints(count: int) -> None:
    """Refuse (:class:`~akarm.files.FileProblem`) a telemetry file of no joint, or of more than
    :data:`MAX_TELEMETRY_JOINTS`."""
    if count == 0:
        raise FileProblem("the telemetry file has no joints", "pass a file written by Arm.telemetry().save()")
    if count > MAX_TELEMETRY_JOINTS:
        raise FileProblem(over(f"the telemetry file has {number(count)} joints", MAX_TELEMETRY_JOINTS, "joints",
                               "MAX_TELEMETRY_JOINTS"), "is it the right file?")


def _check_header(header: list[str]) -> None:
    if not header or header[0] != "t [s]":
        raise FileProblem("not an akarm telemetry CSV (no 't [s]' header)",
                          "pass a file written by Arm.telemetry().save()")
    fields = len(FIELDS) if header[-1].startswith("tau_ext.") else len(FIELDS) - 1
    if (len(header) - 1) % fields or not all("." in h for h in header[1:]):
        raise FileProblem(f"not an akarm telemetry CSV (its {len(header)} columns are not 't [s]' and "
                          f"{fields} fields per joint)", "pass a file written by Arm.telemetry().save()")
    check_joints((len(header) - 1) // fields)


def _load_npz(p: Path) -> TelemetryLog:
    """An ``.npz`` log: every array's size read from its header (and checked against the bytes the
    archive holds for it) before any is loaded."""
    try:
        with zipfile.ZipFile(p) as z:
            sizes = {info.filename.removesuffix(".npy"): _npy_size(z, info) for info in z.infolist()}
            size, values = sum(b for b, _ in sizes.values()), sum(v for _, v in sizes.values())
            if size > MAX_TELEMETRY_BYTES:
                raise FileProblem(over(f"the telemetry file's arrays hold {number(size)} bytes", MAX_TELEMETRY_BYTES,
                                       "bytes", "MAX_TELEMETRY_BYTES"), "is it the right file?")
            if values > MAX_TELEMETRY_VALUES:
                raise FileProblem(over(f"the telemetry file holds {number(values)} values", MAX_TELEMETRY_VALUES,
                                       "values", "MAX_TELEMETRY_VALUES"), "is it the right file?")
        with np.load(p) as z:
            names = tuple(str(n) for n in z["joint_names"])
            known = [f for f, _ in FIELDS if f != "tau_ext" or f in z.files]  # older logs: no tau_ext
            t = z["t"]
            arrays = [z[f] for f in known]
    except FileNotFoundError:
        raise FileProblem("telemetry file not found", "check the path") from None
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise FileProblem(f"cannot read the telemetry file: {e}", "pass a .csv or .npz written by akarm") from None
    if t.ndim != 1 or any(a.shape != (len(t), len(names)) for a in arrays):
        raise FileProblem("its arrays do not fit together (t: one value a cycle; every field: one a cycle and joint)",
                          "pass a .npz written by akarm")
    check_joints(len(names))
    return TelemetryLog(names, t, *arrays)


def _npy_size(z: zipfile.ZipFile, info: zipfile.ZipInfo) -> tuple[int, int]:
    """Bytes and values of one array of an ``.npz``, from its header (no array is read)."""
    with z.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
    count = math.prod(shape)
    if dtype.hasobject or count * dtype.itemsize > info.file_size:
        raise FileProblem(f"its array {info.filename!r} is not what its header says",
                          "pass a .npz written by akarm")
    return count * dtype.itemsize, count


def load_mcap(path: str | os.PathLike[str]) -> dict[str, TelemetryLog]:
    """Every arm's telemetry in an MCAP file (:mod:`akarm.telemetry.mcap`): ``{arm name: log}``, ``""``
    for a file of one unnamed arm (what ``Arm.telemetry().save("run.mcap")`` writes)."""
    from akarm.telemetry.mcap import read_mcap

    arms = read_mcap(path)
    for arm, a in arms.items():
        try:
            check_joints(len(a.joint_names))
        except FileProblem as e:
            raise RecordingError(f"{path}{f' (arm {arm})' if arm else ''}: {e.what}", fix=e.fix) from None
    return {arm: TelemetryLog(a.joint_names, a.t, *(a.fields[f] for f, _ in FIELDS)) for arm, a in arms.items()}


_STAMP = struct.Struct("=d")
#: Records :meth:`Telemetry.snapshot` copies at a time (arm6: 330 kB, tens of µs).
SNAPSHOT_CHUNK = 1024


class Telemetry:
    """Ring buffer of the last ``capacity`` cycles (preallocated: recording allocates nothing)."""

    def __init__(self, joint_names: Sequence[str], capacity: int) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self.capacity = capacity
        self.t = np.zeros(capacity)
        self.rows = np.zeros((capacity, len(FIELDS) * n))  # one row per cycle: the fields side by side
        # written through views: a struct packs a row straight into the buffer (a numpy assignment of a
        # list costs the loop, whose core sleeps between cycles, several µs more: its code starts cold)
        self._t_view = self.t.data.cast("B")
        self._rows_view = self.rows.data.cast("B")
        self._row = struct.Struct(f"={len(FIELDS) * n}d")
        self._nan = [math.nan] * n
        self.count = 0
        self.writing = 0  # records begun: count, or one more while one is being written

    def record(self, t: float, q_des: Values, dq_des: Values, q: Values, dq: Values, tau: Values, tau_ff: Values,
               tau_ext: Values | None = None) -> None:
        """Record one cycle (sequences of joint values, SI; ``tau_ext`` ``None``: not known, NaN)."""
        count = self.count
        self.writing = count + 1  # (what a snapshot taken meanwhile must leave out: see snapshot)
        i = count % self.capacity
        ext = self._nan if tau_ext is None else tau_ext
        row = self._row
        row.pack_into(self._rows_view, i * row.size, *q_des, *dq_des, *q, *dq, *tau, *tau_ff, *ext)
        _STAMP.pack_into(self._t_view, 8 * i, t)
        self.count = count + 1

    def clear(self) -> None:
        """Forget every record."""
        self.count = 0
        self.writing = 0

    def snapshot(self, since: float | None = None) -> TelemetryLog:
        """The recorded cycles, oldest first (optionally only those at or after time ``since``).

        Safe while the control loop records, and it takes no lock the loop needs: the rows are copied
        :data:`SNAPSHOT_CHUNK` at a time (the loop may run between two chunks), and the rows the loop
        overwrote meanwhile, the oldest, are left out. (Copying a full ring of arm6 under the loop's
        lock held the loop for 24-62 ms, a hundred cycles.)"""
        for _ in range(3):
            first = self.count
            lo = max(0, first - self.capacity)
            if since is not None:
                lo = self._first_at(since, lo, first)
            t, rows = self._copy(lo, first)
            last = self.writing  # the records begun so far: those the ring no longer holds are left out
            if last < first:  # cleared meanwhile: read again
                continue
            skip = max(lo, last - self.capacity) - lo
            if since is not None:  # (what is left rises: exact even if the search above met a row overwritten)
                skip += int(np.searchsorted(t[skip:], since, side="left"))
            t, rows = t[skip:], rows[skip:]
            fields = rows.reshape(len(t), len(FIELDS), len(self.joint_names))
            return TelemetryLog(self.joint_names, t, *(fields[:, k].copy() for k in range(len(FIELDS))))
        return TelemetryLog(self.joint_names, np.zeros(0), *(np.zeros((0, len(self.joint_names))) for _ in FIELDS))

    def _first_at(self, since: float, lo: int, hi: int) -> int:
        """The first record in ``[lo, hi)`` (counted from the first ever) stamped at or after ``since``
        (stamps rise record by record); ``hi`` if none is."""
        cap, t = self.capacity, self.t
        while lo < hi:
            mid = (lo + hi) // 2
            if t[mid % cap] < since:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def _copy(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """Copies of the stamps and rows of records ``[lo, hi)``, a chunk at a time."""
        cap = self.capacity
        t = np.empty(hi - lo)
        rows = np.empty((hi - lo, self.rows.shape[1]))
        k = lo
        while k < hi:
            at = k % cap
            m = min(hi - k, cap - at, SNAPSHOT_CHUNK)
            t[k - lo:k - lo + m] = self.t[at:at + m]
            rows[k - lo:k - lo + m] = self.rows[at:at + m]
            k += m
        return t, rows
