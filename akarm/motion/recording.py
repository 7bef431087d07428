"""Teach-and-replay recordings: plain files a person can read and edit.

Two kinds, both in joint space (rad, config order), written atomically (temporary file, then
rename) so a crash never leaves half a file:

- **keyframes** (``.yaml``): named or unnamed poses, replayed as one smooth move through them::

      robot: arm6
      joints: [shoulder_pan, shoulder_lift, ...]
      units: rad
      keyframes:
        - {name: pick, q: [0.1, -0.4, ...]}
        - {q: [0.3, -0.2, ...]}

- **paths** (``.csv``): a continuously recorded motion, replayed at its recorded timing (scaled by a
  speed factor). Header ``t [s],<joint> [rad],...``, one row per sample.

Before replay a path is smoothed (zero-phase moving average over ``smoothing`` s, which removes the
encoder quantisation that would otherwise look like enormous jerk) and checked against every joint's
position, velocity, acceleration and jerk limits after time scaling; a violation names the joint,
the time, and the largest speed factor that would pass.
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
import yaml

from akarm.errors import ArgumentError, LimitError, RecordingError, num
from akarm.files import FileProblem, YamlLimits, atomic_write, load_yaml, over, read_csv_table
from akarm.motion.bounds import MAX_DURATION, MAX_KEYFRAMES, MAX_PATH_SAMPLES
from akarm.motion.trajectory import JointLimits, Timed
from akarm.robotfile.nodes import MAX_JOINTS

__all__ = ["KEYFRAME_FILE_LIMITS", "MAX_KEYFRAME_FILE_BYTES", "MAX_KEYFRAME_FILE_NODES", "MAX_PATH_FILE_BYTES",
           "Keyframe", "Keyframes", "PathPlan", "PathRecording", "check_path", "load", "load_keyframes", "load_path"]


#: Bytes of a keyframe file (10 000 keyframes of 32 joints take about 4 MB).
MAX_KEYFRAME_FILE_BYTES = 16 << 20
#: Values in a keyframe file, aliases counted at their full size: 10 000 keyframes of 32 joints and their names.
MAX_KEYFRAME_FILE_NODES = MAX_KEYFRAMES * (MAX_JOINTS + 8)
#: How a keyframe file is read: at most :data:`~akarm.motion.bounds.MAX_KEYFRAMES` entries in a list.
KEYFRAME_FILE_LIMITS = YamlLimits("keyframe file", MAX_KEYFRAME_FILE_BYTES, "MAX_KEYFRAME_FILE_BYTES",
                                  MAX_KEYFRAME_FILE_NODES, "MAX_KEYFRAME_FILE_NODES", max_items=MAX_KEYFRAMES,
                                  items="keyframes", items_name="MAX_KEYFRAMES")
#: Bytes of a path recording (an hour at 500 Hz of 6 joints, as akarm writes it, is 140 MB).
MAX_PATH_FILE_BYTES = 512 << 20


@dataclass(frozen=True)
class Keyframe:
    """One taught pose: joint positions (rad, config order) and an optional name."""

    q: tuple[float, ...]
    name: str | None = None


@dataclass(frozen=True)
class Keyframes:
    """A keyframe recording."""

    joint_names: tuple[str, ...]
    frames: tuple[Keyframe, ...]
    robot: str = ""

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write as YAML, atomically."""
        doc = {"robot": self.robot, "joints": list(self.joint_names), "units": "rad",
               "keyframes": [({"name": f.name} if f.name else {}) | {"q": [round(x, 6) for x in f.q]}
                             for f in self.frames]}
        text = "# akarm keyframes: joint positions in rad, in the order of `joints`\n"
        text += yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
        return atomic_write(path, lambda f: f.write(text.encode()))


@dataclass(frozen=True)
class PathRecording:
    """A continuously recorded path: times ``t`` (s, from 0) and positions ``q`` (n × joints, rad)."""

    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray

    @property
    def duration(self) -> float:
        """Length of the recording, s."""
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write as CSV with a header naming joints and units, atomically."""

        def write(f: io.BufferedWriter) -> None:
            text = io.TextIOWrapper(f, encoding="utf-8", newline="")
            w = csv.writer(text)
            w.writerow(["t [s]", *(f"{n} [rad]" for n in self.joint_names)])
            for ti, qi in zip(self.t, self.q, strict=True):
                w.writerow([f"{ti:.6f}", *(f"{x:.6f}" for x in qi)])
            text.flush()
            text.detach()

        return atomic_write(path, write)


def _bad(path: Path, what: str, fix: str) -> RecordingError:
    return RecordingError(f"{path}: {what}", fix=fix)


def load_keyframes(path: str | os.PathLike[str], joint_names: Sequence[str] | None = None) -> Keyframes:
    """Read a keyframe YAML within :data:`KEYFRAME_FILE_LIMITS`; check it has one finite value per
    joint (and the right joints, if given).

    Raises:
        RecordingError: the file is missing, past a limit (named), not YAML, truncated or
            inconsistent; says where.
    """
    p = Path(path)
    try:
        doc = load_yaml(p, KEYFRAME_FILE_LIMITS)
    except FileProblem as e:
        raise _bad(p, e.what if e.line is None else f"line {e.line}: {e.what}", e.fix) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("keyframes"), list) or not isinstance(doc.get("joints"),
                                                                                                   list):
        raise _bad(p, "not an akarm keyframe file (needs `joints:` and `keyframes:` lists)",
                   "record one with `akarm teach` or see akarm.motion.recording's docstring")
    names = tuple(str(n) for n in doc["joints"])
    if joint_names is not None and names != tuple(joint_names):
        raise _bad(p, f"recorded for joints {list(names)}, the arm has {list(joint_names)}",
                   "replay it on the robot it was taught on")
    frames = []
    for k, item in enumerate(doc["keyframes"]):
        q = item.get("q") if isinstance(item, dict) else None
        if not isinstance(q, list) or len(q) != len(names) or not all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in q):
            raise _bad(p, f"keyframe {k} needs `q:` with {len(names)} finite numbers (rad)", "fix that keyframe")
        name = item.get("name")
        frames.append(Keyframe(tuple(float(x) for x in q), None if name is None else str(name)))
    if not frames:
        raise _bad(p, "has no keyframes", "teach at least one pose")
    return Keyframes(names, tuple(frames), str(doc.get("robot", "")))


def load_path(path: str | os.PathLike[str], joint_names: Sequence[str] | None = None) -> PathRecording:
    """Read a path CSV within its limits (:data:`MAX_PATH_FILE_BYTES`, :data:`~akarm.motion.bounds.MAX_PATH_SAMPLES`
    samples, counted before any is kept, and :data:`~akarm.motion.bounds.MAX_DURATION`); check the
    header, every row, and that time increases.

    Raises:
        RecordingError: missing, past a limit (named), truncated or malformed file; says which row.
    """
    p = Path(path)

    def check(header: list[str]) -> None:
        if not header or header[0] != "t [s]":
            raise FileProblem("not an akarm path recording (the header must start with 't [s]')",
                              "record one with `akarm teach --continuous`")
        names = tuple(h.rsplit(" [", 1)[0] for h in header[1:])
        if joint_names is not None and names != tuple(joint_names):
            raise FileProblem(f"recorded for joints {list(names)}, the arm has {list(joint_names)}",
                              "replay it on the robot it was taught on")

    try:
        header, arr = read_csv_table(p, what="path recording", max_bytes=MAX_PATH_FILE_BYTES,
                                     bytes_name="MAX_PATH_FILE_BYTES", max_rows=MAX_PATH_SAMPLES,
                                     rows_name="MAX_PATH_SAMPLES", rows="samples", check_header=check)
    except FileProblem as e:
        raise _bad(p, e.what, e.fix) from None
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise _bad(p, f"row {int(np.argmax(bad)) + 2} has a value that is not finite", "fix that row")
    if len(arr) < 2:
        raise _bad(p, "has fewer than two samples", "record for longer")
    t = arr[:, 0] - arr[0, 0]
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0)) + 3
        raise _bad(p, f"time does not increase at row {k}", "rows must be in time order")
    if not t[-1] <= MAX_DURATION:
        k = int(np.argmax(t > MAX_DURATION)) + 2
        gap = f" (row {k} comes {t[k - 2] - t[k - 3]:.6g} s after row {k - 1})" if k > 2 else ""
        raise _bad(p, over(f"the path lasts {t[-1]:.6g} s{gap}", MAX_DURATION, "s", "MAX_DURATION"),
                   "is it the right file? cut it into recordings of at most "
                   f"{MAX_DURATION / 3600:g} h, or fix the times in column 't [s]'")
    names = tuple(h.rsplit(" [", 1)[0] for h in header[1:])
    return PathRecording(names, t, arr[:, 1:])


def load(path: str | os.PathLike[str], joint_names: Sequence[str] | None = None) -> Keyframes | PathRecording:
    """A keyframe (``.yaml``/``.yml``) or path (``.csv``) recording, by suffix."""
    p = Path(path)
    if p.suffix in (".yaml", ".yml"):
        return load_keyframes(p, joint_names)
    if p.suffix == ".csv":
        return load_path(p, joint_names)
    raise _bad(p, f"unknown recording type {p.suffix!r}", "use .yaml (keyframes) or .csv (paths)")


def _smooth(t: np.ndarray, q: np.ndarray, window: float, dt: float) -> tuple[np.ndarray, int]:
    """Resample at ``dt``, pad with rest at both ends, apply a zero-phase moving average over ``window`` s.

    Returns the smoothed samples and the number of padding samples before the recording's first
    one. The padding (one filter length of the first and last pose) makes the smoothed path start
    and end exactly at rest on the recorded end points, so replay joins the soft start smoothly.
    """
    tt = np.arange(0.0, t[-1] + 1e-12, dt)
    qq = np.column_stack([np.interp(tt, t, q[:, k]) for k in range(q.shape[1])])
    n = max(1, round(window / dt))
    if n == 1:
        return qq, 0
    lead = 2 * n  # two passes of an n-sample box: a triangle 2n samples wide
    qq = np.vstack([np.repeat(qq[:1], lead, axis=0), qq, np.repeat(qq[-1:], lead, axis=0)])
    kernel = np.ones(n) / n
    for _ in range(2):  # forward, then backward: zero phase
        pad = np.vstack([np.repeat(qq[:1], n, axis=0), qq, np.repeat(qq[-1:], n, axis=0)])
        qq = np.column_stack([np.convolve(pad[:, k], kernel, mode="same") for k in range(q.shape[1])])[n:-n]
        qq = qq[::-1]
    return qq, lead


class PathPlan(Timed):
    """A recorded path made ready for replay: smoothed, time-scaled, with derivatives.

    Has the same sampling interface as :class:`akarm.motion.trajectory.Plan` (``t0``, ``t_end``,
    ``duration``, ``sample(t)``, ``done(t)``), so the control loop follows it the same way.
    """

    def __init__(self, path: PathRecording, t0: float, speed: float = 1.0, smoothing: float = 0.05,
                 dt: float = 0.002) -> None:
        if not speed > 0:
            raise ArgumentError(f"speed must be positive, got {speed}", fix="pass e.g. --speed 0.5")
        self.speed = speed
        qq, lead = _smooth(path.t, path.q, smoothing, dt)
        self.dt_rec = dt
        self.t_rec = np.arange(len(qq)) * dt - lead * dt  # recording time of each sample (0 = first recorded)
        #: replay time (s) before the recording's first sample: the rest padding that smoothing needs
        self.lead_in = lead * dt / speed
        self.q = qq
        with np.errstate(invalid="ignore", over="ignore"):  # a sample that is not finite: check_path says which
            self.dq = np.gradient(qq, dt, axis=0) * speed
            self.ddq = np.gradient(self.dq, dt, axis=0) * speed
            self.jerk = np.gradient(self.ddq, dt, axis=0) * speed
        self.t0 = t0
        self.t_end = t0 + (len(qq) - 1) * dt / speed
        self.segments = ()

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, dq, ddq) at absolute time ``t``, linearly interpolated between samples."""
        x = (t - self.t0) * self.speed / self.dt_rec
        if x <= 0:
            i, f = 0, 0.0
        elif x >= len(self.t_rec) - 1:
            i, f = len(self.t_rec) - 2, 1.0
        else:
            i = int(x)
            f = x - i
        g = 1.0 - f
        return (self.q[i] * g + self.q[i + 1] * f, self.dq[i] * g + self.dq[i + 1] * f,
                self.ddq[i] * g + self.ddq[i + 1] * f)


def check_path(plan: PathPlan, limits: JointLimits) -> None:
    """Raise :class:`LimitError` if the replayed path breaks any limit of any joint.

    The error names the joint, the time (s into the replay) and the largest speed factor that
    would pass (velocity scales with the speed factor s, acceleration with s², jerk with s³).

    Raises:
        RecordingError: the path has a value that is not finite (NaN or infinite): no limit can be
            checked against it, and the arm must not be sent there.
        LimitError: a limit is broken.
    """
    s = plan.speed
    if plan.q.ndim != 2 or plan.q.shape[1] != len(limits.names):
        raise RecordingError(f"the path has {plan.q.shape[1] if plan.q.ndim == 2 else 0} values per sample, the arm "
                             f"{len(limits.names)} joints ({', '.join(limits.names)})",
                             fix="replay a recording of this arm's joints, one value per joint")
    for arr, what in ((plan.q, "position"), (plan.dq, "velocity"), (plan.ddq, "acceleration"), (plan.jerk, "jerk")):
        bad_rows = ~np.isfinite(arr).all(axis=1)
        if bad_rows.any():
            i = int(np.argmax(bad_rows))
            k = int(np.argmax(~np.isfinite(arr[i])))
            name = limits.names[k] if k < len(limits.names) else None
            raise RecordingError(f"the path's {what} is {arr[i, k]} at t = {plan.t_rec[i] / s:.2f} s: not a number "
                                 "a joint can be sent to", joint=name,
                                 fix="the recording is damaged: record it again, or edit out the samples that are "
                                     "not finite")
    for k, name in enumerate(limits.names):
        q = plan.q[:, k]
        bad = np.nonzero((q < limits.lower[k] - 1e-9) | (q > limits.upper[k] + 1e-9))[0]
        if bad.size:
            i = int(bad[0])
            raise LimitError(f"the path reaches {num(q[i])} rad at t = {plan.t_rec[i] / s:.2f} s, outside "
                             f"[{num(limits.lower[k])}, {num(limits.upper[k])}] rad", joint=name,
                             fix="no speed factor helps: edit the recording or the joint limits")
    worst: tuple[float, str, float, str] | None = None  # (speed factor that passes, joint, time, what)
    for k, name in enumerate(limits.names):
        for arr, lim, power, what in ((plan.dq, limits.velocity, 1, "velocity"),
                                      (plan.ddq, limits.acceleration, 2, "acceleration"),
                                      (plan.jerk, limits.jerk, 3, "jerk")):
            peak_i = int(np.argmax(np.abs(arr[:, k])))
            peak = abs(arr[peak_i, k])
            if peak > lim[k] * (1 + 1e-9):
                passing = s * (lim[k] / peak) ** (1.0 / power)
                if worst is None or passing < worst[0]:
                    worst = (passing, name, plan.t_rec[peak_i] / s, f"{what} {peak:.3g} > limit {lim[k]:.3g}")
    if worst is not None:
        factor = math.floor(worst[0] * 0.98 * 100) / 100
        raise LimitError(f"at speed {s:g} the path's {worst[3]} at t = {worst[2]:.2f} s", joint=worst[1],
                         fix=f"replay with --speed {max(factor, 0.01):g} or lower")
