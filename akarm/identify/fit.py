"""Identification, the arithmetic: the excitation, the fit of each joint's friction and torque
offset and of the payload, and the collision thresholds they suggest. Pure: arrays and the arm's
model in, results out; :mod:`akarm.identify.procedure` drives an arm through it.

**Excitation** (:func:`excitation`): every joint follows, around a centre pose, two sines of its
own frequencies (``0.6·sin(ωt) + 0.4·sin(2.63·ωt + φ)``) under a smooth envelope that starts and
ends at rest. The amplitude is clipped to stay within each joint's range, the frequency chosen so
the sines use at most 80 % of the joint's velocity, acceleration and jerk limits at ``speed = 1``;
the envelope's ramps add their own derivatives to that, so where they would take a joint over
80 % (large amplitudes: the ramp's velocity alone is about amplitude × 1.1 /s), its amplitude is
reduced until the whole motion, ramps included, stays within 80 %.
It is an ordinary recorded path (:class:`~akarm.motion.recording.PathRecording`): replayed, after a soft
start, and checked against every limit before anything moves, like any replay.

**Fit** (:func:`fit`): from the measured positions and torques (the telemetry of the excitation),
smoothed and differentiated by a Savitzky-Golay filter, per sample and joint::

    τ_measured - ID(q, q̇, q̈) = Y_payload(q, q̇, q̈)·π + c·tanh(q̇/0.02) + b·q̇ + offset

``ID`` is the arm's inverse dynamics without a payload (links and motor rotors as the URDF and
catalogue give them), ``Y_payload`` Pinocchio's joint torque regressor (``computeJointTorqueRegressor``)
for the ten inertial parameters ``π`` of the body that carries the tool frame, to which a payload
adds; friction ``c`` (Coulomb), ``b`` (viscous) and an optional ``offset`` per joint. One weighted
least-squares solve (each joint's rows weighted by the inverse of its residual in a first solve)
gives them all; the payload's mass is ``π[0]`` and its centre of mass ``π[1:4] / π[0]``, moved into
the tool frame. The RMS residual per joint says how well the model fits.

**Thresholds**: the collision observer (:mod:`akarm.control.collision`) is run over the same data with the
identified values; its largest output per joint while nothing touched the arm, times
:data:`THRESHOLD_MARGIN` (the arm's other motions are faster than the excitation, and the
estimate's error grows with acceleration), and at least :data:`MIN_SHARE` of the joint's torque
limit and :data:`STEP_MARGIN` times the estimate's jump for one step of the velocity feedback
(``K·M·step``, with the joint's largest inertia ``M`` over its range: where the arm does not track
its command closely, as with a gravity-only feed-forward, the estimate sees those steps), is the
suggested ``collision: {threshold: ...}``.

:func:`estimate_payload_at_rest` fits mass and centre of mass alone from the torques held at rest in
several poses (gravity only: four parameters); :func:`payload_poses` chooses the poses.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akarm.config import Friction, Payload
from akarm.control.collision import MomentumObserver
from akarm.dynamics.gravity import sample_box
from akarm.dynamics.model import ArrayLike, RobotModel
from akarm.errors import LimitError, StateError, finite_number
from akarm.motion.recording import PathRecording
from akarm.motion.trajectory import JointLimits
from akarm.robotfile.save import JointValues, flow_collision, flow_friction, flow_payload, save_values
from akarm.telemetry.log import TelemetryLog

__all__ = [
    "MIN_SHARE",
    "STEP_MARGIN",
    "THRESHOLD_MARGIN",
    "TORQUE_SHARE",
    "Identification",
    "JointFit",
    "PayloadFit",
    "check_excitation",
    "estimate_payload_at_rest",
    "excitation",
    "fit",
    "largest_inertia",
    "payload_poses",
    "suggest_thresholds",
    "torque_speed",
    "yaml_payload",
]

#: The threshold suggested is this many times the largest estimate seen without contact ...
THRESHOLD_MARGIN = 3.0
#: ... and at least this share of the joint's torque limit ...
MIN_SHARE = 0.06
#: ... and this many times the estimate's jump for one step of the velocity feedback.
STEP_MARGIN = 1.5
_SMOOTHING = 0.02  # rad/s: tanh smoothing of the Coulomb term (the feed-forward's and the observer's)
_HARMONIC = 2.63
_WEIGHTS = (0.6, 0.4)
_RAMP = 2.0  # s of envelope at each end
#: the excitation's torque (the model's) stays within this share of each joint's torque limit,
#: leaving the rest for a payload not yet known and for the feedback
TORQUE_SHARE = 0.5


@dataclass(frozen=True)
class JointFit:
    """One joint's identified friction (N·m, N·m·s/rad), offset (N·m), the fit's RMS residual (N·m),
    the suggested collision threshold (N·m, ``None`` if not computed), the excitation amplitude (rad)."""

    name: str
    coulomb: float
    viscous: float
    offset: float
    rms: float
    threshold: float | None = None
    amplitude: float = math.nan
    #: N·m the joint gets per N·m the motor reports (1: not fitted)
    torque_scale: float = 1.0
    #: Coulomb friction's load-dependent part, N·m per N·m of the motor's torque
    load: float = 0.0

    def friction(self, offset: bool = True) -> Friction:
        """The identified friction (with its offset, or without: 0), as a robot file takes it: a Coulomb
        or viscous term the fit's noise made slightly negative is 0 (the file, and ``set_friction``,
        refuse a negative one: ``akarm identify --save`` failed at its very end)."""
        return Friction(max(0.0, self.coulomb), max(0.0, self.viscous), self.offset if offset else 0.0,
                        min(1.0, max(0.0, self.load)), min(2.0, max(0.2, self.torque_scale)))


@dataclass(frozen=True)
class PayloadFit:
    """A payload: mass (kg), centre of mass in the tool frame (m), RMS torque residual per joint (N·m),
    and which centre-of-mass components the data determined (the others are 0)."""

    mass: float
    com: tuple[float, float, float]
    rms: tuple[float, ...] = ()
    determined: tuple[bool, bool, bool] = (True, True, True)

    def as_payload(self) -> Payload:
        """The payload as the robot file's ``payload:`` has it."""
        return Payload(self.mass, self.com)


@dataclass(frozen=True)
class Identification:
    """What :func:`akarm.identify.identify` found (see the module's docstring)."""

    joints: tuple[JointFit, ...]
    payload: PayloadFit | None
    samples: int
    duration: float
    offsets: bool = True
    notes: tuple[str, ...] = field(default=())
    speed: float = 1.0

    def table(self) -> str:
        """A table per joint: friction, offset, RMS residual, suggested threshold, torque scale, load share."""
        rows = [f"{'joint':<16}{'coulomb Nm':>11}{'viscous Nms':>12}{'offset Nm':>10}{'RMS Nm':>8}"
                f"{'threshold Nm':>13}{'torque x':>9}{'load':>6}"]
        for j in self.joints:
            th = f"{j.threshold:13.2f}" if j.threshold is not None else f"{'-':>13}"
            rows.append(f"{j.name:<16}{j.coulomb:11.3f}{j.viscous:12.4f}{j.offset:10.3f}{j.rms:8.3f}{th}"
                        f"{j.torque_scale:9.3f}{j.load:6.3f}")
        if self.payload is not None:
            p = self.payload
            rows.append(f"payload: {p.mass:.3f} kg, centre of mass ({p.com[0]:+.4f}, {p.com[1]:+.4f}, "
                        f"{p.com[2]:+.4f}) m in the tool frame")
        return "\n".join(rows)

    def fragment(self) -> str:
        """The results as robot YAML: ``payload:`` and, per joint, ``friction:`` and ``collision:``."""
        lines = ["# identified by akarm identify: merge into the robot file (or run it with --save)"]
        if self.payload is not None:
            lines.append(yaml_payload(self.payload))
        lines.append("joints:")
        for j in self.joints:
            lines.append(f"  - name: {j.name}")
            lines.append(f"    friction: {flow_friction(j.friction(self.offsets))}")
            if j.threshold is not None:
                lines.append(f"    collision: {flow_collision(j.threshold)}")
        return "\n".join(lines) + "\n"

    def joint_values(self) -> dict[str, JointValues]:
        """What to write into the robot file per joint (friction, suggested threshold)."""
        return {j.name: JointValues(j.friction(self.offsets), j.threshold) for j in self.joints}

    def save(self, path: str | Path, *, check: Callable[[Path], object] | None = None) -> tuple[Path, Path]:
        """Write the results into the robot file at ``path``, in place, with a backup
        (:func:`akarm.robotfile.save.save_values`); returns (the file, its backup).

        Raises:
            ConfigError: the file cannot be read, has no such joints, or would not load after the edit.
        """
        return save_values(path, payload=None if self.payload is None else self.payload.as_payload(),
                           joints=self.joint_values(), check=check)


def yaml_payload(p: PayloadFit) -> str:
    """``payload: {mass: ..., com: [...]}``: the payload as a line of robot YAML."""
    return f"payload: {flow_payload(p.as_payload())}"


# ----------------------------------------------------------------------------------------------
# excitation
# ----------------------------------------------------------------------------------------------
_SMOOTHSTEP = np.array([0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0])  # x⁴(35 - 84x + 70x² - 20x³)


def _envelope(t: np.ndarray, duration: float, derivative: int = 0) -> np.ndarray:
    """0 → 1 → 0 with zero velocity, acceleration and jerk at both ends (7th-order smoothstep ramps);
    or its ``derivative``-th time derivative."""
    ramp = min(_RAMP, duration / 4)
    rising = t < duration - t
    x = np.clip(np.minimum(t, duration - t) / ramp, 0.0, 1.0)
    poly = np.polynomial.polynomial
    value = poly.polyval(x, poly.polyder(_SMOOTHSTEP, derivative) if derivative else _SMOOTHSTEP)
    if derivative:  # dx/dt: 1/ramp rising, -1/ramp falling, 0 at full envelope
        slope = np.where(x >= 1.0, 0.0, np.where(rising, 1.0, -1.0) / ramp)
        value = value * slope**derivative
    return value


def check_excitation(amplitude: float, duration: float, *,
                     names: tuple[str, str] = ("amplitude", "duration")) -> tuple[float, float]:
    """``(amplitude, duration)`` as floats when an excitation can have them: an amplitude in (0, π] rad,
    a duration of 8-600 s (what :func:`excitation` takes; ``akarm identify`` checks its options with it,
    under their ``names``, before the arm is enabled).

    Raises:
        ArgumentError: either is not a finite number in its range (names it).
    """
    return (finite_number(amplitude, names[0], above=0.0, at_most=math.pi, unit="rad", fix="e.g. 0.5 rad"),
            finite_number(duration, names[1], at_least=8.0, at_most=600.0, unit="s", fix="e.g. 30 s"))


def excitation(limits: JointLimits, center: ArrayLike, *, amplitude: float = 0.5, duration: float = 30.0,
               rate_hz: float = 500.0) -> PathRecording:
    """The excitation path around ``center`` (rad): see the module's docstring.

    Raises:
        LimitError: the centre is outside a joint's range.
        ArgumentError: an amplitude or duration out of range.
    """
    amplitude, duration = check_excitation(amplitude, duration)
    c = np.asarray(center, dtype=float)
    limits.check_position(c, what="the excitation's centre")
    margin = 0.05
    room = np.minimum(c - limits.lower, limits.upper - c) - margin
    amp = np.clip(np.minimum(amplitude, room), 0.0, None)
    sum_v = _WEIGHTS[0] + _WEIGHTS[1] * _HARMONIC
    sum_a = _WEIGHTS[0] + _WEIGHTS[1] * _HARMONIC**2
    sum_j = _WEIGHTS[0] + _WEIGHTS[1] * _HARMONIC**3
    safe = np.maximum(amp, 1e-9)
    omega = np.minimum.reduce([0.8 * limits.velocity / (safe * sum_v),
                               np.sqrt(0.8 * limits.acceleration / (safe * sum_a)),
                               np.cbrt(0.8 * limits.jerk / (safe * sum_j)), np.full(len(c), 2 * math.pi * 0.5)])
    omega *= 1.0 - 0.061 * np.arange(len(c))  # a frequency of its own per joint: the columns stay apart
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate_hz)
    phase = np.linspace(0.3, 2.5, len(c))
    w = omega[None, :] * t[:, None]

    def wave(k: int) -> np.ndarray:  # the k-th time derivative of the two sines
        turn = k * math.pi / 2
        return (_WEIGHTS[0] * omega**k * np.sin(w + turn)
                + _WEIGHTS[1] * (_HARMONIC * omega)**k * np.sin(_HARMONIC * w + phase[None, :] + turn))

    env = [_envelope(t, duration, k)[:, None] for k in range(4)]
    # the sines at full envelope use at most 80 %; during the ramps the envelope's derivatives add
    # to that (amplitude × E'·sines ...): where they take a joint over 80 %, its amplitude is reduced
    used = np.zeros(len(c))
    for k, lim in ((1, limits.velocity), (2, limits.acceleration), (3, limits.jerk)):
        dk = sum(math.comb(k, i) * env[i] * wave(k - i) for i in range(k + 1))
        used = np.maximum(used, amp * np.max(np.abs(dk), axis=0) / lim)
    amp = np.where(used > 0.8, amp * 0.8 / np.maximum(used, 1e-300), amp)
    q = c[None, :] + env[0] * amp[None, :] * wave(0)
    return PathRecording(limits.names, t, q)


def torque_speed(model: RobotModel, path: PathRecording, torque_limit: Sequence[float],
                 share: float = TORQUE_SHARE) -> tuple[float, int, float]:
    """The fastest time scaling (≤ 1) of ``path`` whose inverse-dynamics torque stays within ``share``
    of each joint's torque limit: velocities scale by ``s`` and accelerations by ``s²``, so the
    torque is ``g(q) + s²·(the rest)``. Returns (s, the joint that sets it, its peak torque at s = 1, N·m).

    Raises:
        LimitError: gravity alone needs more than ``share`` of a joint's limit somewhere on the path.
    """
    lim = share * np.asarray(torque_limit, dtype=float)
    step = max(1, len(path.t) // 2000)
    dq = np.gradient(path.q, path.t, axis=0)
    ddq = np.gradient(dq, path.t, axis=0)
    best, joint, peak = 1.0, -1, 0.0
    for k in range(0, len(path.t), step):
        g = model.gravity(path.q[k])
        rest = model.inverse_dynamics(path.q[k], dq[k], ddq[k]) - g
        for i in range(model.n):
            if abs(g[i]) >= lim[i]:
                raise LimitError(f"gravity alone needs {abs(g[i]):.1f} N·m at {path.q[k]}, over {share:.0%} of the "
                                 f"joint's {lim[i] / share:.0f} N·m", joint=model.joint_names[i],
                                 fix="excite around a pose where the arm's weight loads the joints less (center=)")
            if abs(rest[i]) > 1e-12:
                s2 = (lim[i] - abs(g[i])) / abs(rest[i])
                if s2 < best * best:
                    best, joint, peak = math.sqrt(s2), i, abs(g[i]) + abs(rest[i])
    return best, joint, peak


# ----------------------------------------------------------------------------------------------
# fit
# ----------------------------------------------------------------------------------------------
def _savgol(x: np.ndarray, dt: float, window: float, order: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky-Golay smoothing of the columns of ``x`` sampled every ``dt``: value, first and second
    derivative at each sample (zero phase; the ends, where the window does not fit, are NaN)."""
    half = max(order, round(window / dt / 2))
    if len(x) < 2 * half + 1:
        raise StateError(f"{len(x)} samples are too few: the {window:g} s smoothing window alone takes {2 * half + 1}",
                         fix="excite for longer")
    k = np.arange(-half, half + 1) * dt
    V = np.vander(k, order + 1, increasing=True)  # columns 1, k, k², k³
    P = np.linalg.pinv(V)  # rows: coefficients of 1, k, k²: value, slope, curvature/2
    out = []
    for row, factor in ((0, 1.0), (1, 1.0), (2, 2.0)):
        kernel = P[row][::-1] * factor
        y = np.full_like(x, np.nan)
        for j in range(x.shape[1]):
            y[half:-half, j] = np.convolve(x[:, j], kernel, mode="valid")
        out.append(y)
    return out[0], out[1], out[2]


# C901 13 > 12, left as it was: one least-squares fit, a branch per optional term (offsets, payload, window)
#: the torque scales a real unit has (Variation's 0.49-1.3, with a margin): outside, a fit found the
#: degenerate solution of a friction-dominated joint (0.01-0.08 on roll joints, 0.30 on a wrist)
_SCALE_RANGE = (0.45, 1.6)


def fit(model: RobotModel, log: TelemetryLog, *, kp: np.ndarray | None = None, kd: np.ndarray | None = None,  # noqa: C901
        payload: bool = True, offsets: bool = True, use: np.ndarray | None = None, window: float = 0.1,
        decimate: int = 1, torque_scale: bool = False) -> tuple[list[JointFit], PayloadFit | None, np.ndarray]:
    """Friction (and offsets, and the payload) from an excitation's telemetry (module's docstring).

    ``kp``, ``kd``: the MIT gains in force for each sample's torque (samples × joints, or one row for
    all; 0 for servo joints). A reply carries the torque of the command just received; the PD torque
    then changes, by about ``-(kp·q̇ + kd·q̈)`` per second, until the next command: the samples are
    biased by ``λp·kp·q̇ + λd·kd·q̈``, with "lags" ``λ`` of about half a period that depend on the
    driver and the joint. When the gains vary (:func:`identify` alternates full and half gains), the
    lags are fitted too (two columns per joint); else half a period is taken. ``use``: which samples
    to fit (e.g. not those just after a change of gains).

    ``torque_scale``: fit per joint also the torque the joint gets per N·m reported (``s``) and Coulomb
    friction's load-dependent part (``μ``, per N·m of the motor's torque): the model is then
    ``s·(τ - lags) = ID + Y·π + (c + μ·|τ|)·tanh(q̇/0.02) + b·q̇ + offset``, linear in ``s``, ``s·λ``,
    ``π``, ``c``, ``μ``, ``b`` and the offset (the target is ``ID``; a real unit's torque constant and
    gearbox make ``s`` 0.5-1.3).

    With ``payload``, ``model`` must carry none (else its payload is taken as known). Returns the
    per-joint fits (threshold unset), the payload (``None`` unless ``payload``), and the lags (joints × 2, s).

    Raises:
        StateError: too little data.
    """
    if payload and model.payload is not None:
        raise StateError("identifying the payload needs the model without one", fix="model.clear_payload() first")
    n = model.n
    if len(log.t) < 2:
        raise StateError(f"{len(log.t)} samples are too few to identify {n} joints", fix="excite for longer")
    period = float(np.median(np.diff(log.t)))
    dt = period
    q, dq, ddq = _savgol(log.q, dt, window)
    kp_t = np.broadcast_to(np.zeros(n) if kp is None else np.asarray(kp, dtype=float), log.q.shape)
    kd_t = np.broadcast_to(np.zeros(n) if kd is None else np.asarray(kd, dtype=float), log.q.shape)
    varying = bool(np.any(np.ptp(kp_t, axis=0) > 0))
    # the torque after each sample acts over the period that follows: the motion's state mid-period
    tau = log.tau[:-1]
    q, dq, ddq = (0.5 * (x[:-1] + x[1:]) for x in (q, dq, ddq))
    kp_t, kd_t = kp_t[:-1], kd_t[:-1]
    ok = np.all(np.isfinite(q), axis=1) & (np.ones(len(q), bool) if use is None else np.asarray(use)[:-1])
    idx = np.nonzero(ok)[0][::decimate]
    if len(idx) < 20 * n:
        raise StateError(f"{len(idx)} samples are too few to identify {n} joints", fix="excite for longer")
    lag = np.full((n, 2), period / 2)
    if not varying:
        tau = tau - 0.5 * period * (kp_t * dq + kd_t * ddq)
    n_pay = 10 if payload else 0
    names = (["coulomb", "viscous"] + (["offset"] if offsets else []) + (["lag_p", "lag_d"] if varying else [])
             + (["scale", "load"] if torque_scale else []))
    per_joint = len(names)
    cols = n_pay + per_joint * n
    Y = np.empty(len(idx) * n)
    A = np.zeros((len(idx) * n, cols))
    for r, k in enumerate(idx):
        rows = slice(r * n, (r + 1) * n)
        if torque_scale:  # ID = s·τ - s·λ·(kp·q̇, kd·q̈) - Y·π - friction: the signs of every column turn
            Y[rows] = -model.inverse_dynamics(q[k], dq[k], ddq[k])
        else:
            Y[rows] = tau[k] - model.inverse_dynamics(q[k], dq[k], ddq[k])
        if payload:
            A[rows, :10] = model.payload_regressor(q[k], dq[k], ddq[k])
        for i in range(n):
            base = n_pay + per_joint * i
            v = dq[k, i]
            th = math.tanh(v / _SMOOTHING)
            A[r * n + i, base:base + 2] = (th, v)
            col = base + 2
            if offsets:
                A[r * n + i, col] = 1.0
                col += 1
            if varying:
                A[r * n + i, col:col + 2] = (kp_t[k, i] * v, kd_t[k, i] * ddq[k, i])
                col += 2
            if torque_scale:
                t = tau[k, i]
                A[r * n + i, col:col + 2] = (-t, abs(t) * th)
    joint_of_row = np.tile(np.arange(n), len(idx))
    weights = np.ones(len(Y))
    fixed: set[int] = set()  # joints whose torque scale the motion does not determine: 1, as catalogued
    for step in range(3):  # weighted by each joint's residual: a noisy joint does not drown the others
        x, *_ = np.linalg.lstsq(A * weights[:, None], Y * weights, rcond=None)
        res = Y - A @ x
        rms = np.array([math.sqrt(float(np.mean(res[joint_of_row == i] ** 2))) for i in range(n)])
        weights = 1.0 / np.maximum(rms, 1e-4)[joint_of_row]
        if torque_scale and step < 2:  # (the last solve has them all)
            # Where a joint's torque is mostly its own friction (a roll joint: little inertia, no gravity),
            # s·τ = friction has a second solution, everything near 0: a scale outside what a real unit
            # has (_SCALE_RANGE) is that one. It keeps the catalogue's (1) and no load share (|τ| is its friction
            # then: the two columns cannot be told apart), and its friction is fitted so.
            for i in range(n):
                col = n_pay + per_joint * i + names.index("scale")
                if i not in fixed and not _SCALE_RANGE[0] <= x[col] <= _SCALE_RANGE[1]:
                    fixed.add(i)
                    rows = joint_of_row == i
                    Y[rows] -= A[rows, col]  # (the column is -τ: s = 1 moves it into the target)
                    A[rows, col] = 0.0
                    A[rows, col + 1] = 0.0  # (and |τ|·tanh is its Coulomb friction again: no load share)
    fits = []
    for i, name in enumerate(model.joint_names):
        v = dict(zip(names, x[n_pay + per_joint * i:n_pay + per_joint * (i + 1)], strict=True))
        scale = 1.0 if i in fixed else float(v.get("scale", 1.0))
        if torque_scale:  # (the rows solved s·λ, and the residual is in N·m of the model: per N·m reported, /s)
            rms[i] /= max(scale, 1e-3)
        fits.append(JointFit(name, float(v["coulomb"]), float(v["viscous"]), float(v.get("offset", 0.0)),
                             float(rms[i]), torque_scale=scale, load=float(v.get("load", 0.0))))
        if varying:
            lag[i] = (v["lag_p"] / scale, v["lag_d"] / scale) if torque_scale else (v["lag_p"], v["lag_d"])
    pay = _payload_from(model, x[:4], rms) if payload else None
    return fits, pay, lag


def _payload_from(model: RobotModel, first: np.ndarray, rms: np.ndarray,
                  determined: tuple[bool, bool, bool] = (True, True, True)) -> PayloadFit:
    """(m, m·c) in the carrying body's frame → a payload with its centre of mass in the tool frame."""
    m = float(first[0])
    if m <= 1e-3:
        return PayloadFit(max(m, 0.0), (0.0, 0.0, 0.0), tuple(float(r) for r in rms), determined)
    c_body = np.asarray(first[1:4]) / m
    P = model.payload_placement
    c_tool = P[:3, :3].T @ (c_body - P[:3, 3])
    c_tool = np.where(determined, c_tool, 0.0)
    return PayloadFit(m, (float(c_tool[0]), float(c_tool[1]), float(c_tool[2])), tuple(float(r) for r in rms),
                      determined)


def estimate_payload_at_rest(model: RobotModel, poses: Sequence[Sequence[float]],
                             torques: Sequence[Sequence[float]],
                             offsets: Sequence[float] | None = None) -> PayloadFit:
    """Mass and centre of mass from the torques held at rest (N·m) in ``poses`` (rad): gravity only.

    The model carries no payload. A centre-of-mass component the poses cannot tell (gravity never
    acts across it in the tool frame, as for a planar arm) is reported as 0 and not determined.

    Raises:
        StateError: fewer than two poses, or the data cannot tell the mass.
    """
    if model.payload is not None:
        raise StateError("the payload estimate needs the model without its payload", fix="model.clear_payload()")
    if len(poses) < 2:
        raise StateError("estimating a payload needs at least two poses")
    n = model.n
    off = np.zeros(n) if offsets is None else np.asarray(offsets, dtype=float)
    zero = np.zeros(n)
    A = np.vstack([model.payload_regressor(q, zero, zero)[:, :4] for q in poses])
    Y = np.concatenate([np.asarray(tau, dtype=float) - model.gravity(q) - off
                        for q, tau in zip(poses, torques, strict=True)])
    # the directions of (m, m·c) the data does not see (the least-squares solution leaves them at 0)
    _, s, vt = np.linalg.svd(A, full_matrices=False)
    null = vt[s <= 1e-6 * s[0]] if s[0] > 0 else np.eye(4)
    if np.any(np.abs(null[:, 0]) > 1e-3):
        raise StateError("the poses cannot tell the payload's mass", fix="use poses where gravity loads the joints")
    x, *_ = np.linalg.lstsq(A, Y, rcond=1e-6)
    determined = _determined(model, null)
    res = Y - A @ x
    rms = np.sqrt(np.mean(res.reshape(len(poses), n) ** 2, axis=0))
    return _payload_from(model, x, rms, determined)


def _determined(model: RobotModel, null: np.ndarray) -> tuple[bool, bool, bool]:
    """Which tool-frame axes of the centre of mass the data determines (none of the null directions
    moves the centre of mass along them)."""
    if null.shape[0] == 0:
        return (True, True, True)
    R = model.payload_placement[:3, :3]
    moves = np.abs(null[:, 1:4] @ R)  # each null direction's m·c change, in tool axes
    return tuple(bool(np.all(moves[:, a] < 1e-6)) for a in range(3))  # type: ignore[return-value]


def suggest_thresholds(model: RobotModel, log: TelemetryLog, fits: Sequence[JointFit],
                       deadband: Sequence[float], gain: float, torque_limit: Sequence[float],
                       kp: np.ndarray | None = None, kd: np.ndarray | None = None,
                       use: np.ndarray | None = None) -> list[float]:
    """Run the collision observer over ``log`` with the identified friction and ``model`` (its
    payload set; ``kp``, ``kd`` as for :func:`fit`; ``use``: the samples judged): the largest
    estimate per joint times :data:`THRESHOLD_MARGIN`, at least :data:`MIN_SHARE` of
    ``torque_limit`` (N·m per joint) and :data:`STEP_MARGIN` times ``K·M·step`` (``deadband`` is the
    step), rounded up to 0.05 N·m."""
    obs = MomentumObserver(model, [f.coulomb for f in fits], [f.viscous for f in fits], [f.offset for f in fits],
                           gain, deadband, [j.motor.t_max for j in model.config.joints])
    obs.set_torque_scale([f.torque_scale for f in fits])
    peak = np.zeros(model.n)
    kp_t = np.broadcast_to(np.zeros(model.n) if kp is None else np.asarray(kp, dtype=float), log.q.shape)
    kd_t = np.broadcast_to(np.zeros(model.n) if kd is None else np.asarray(kd, dtype=float), log.q.shape)
    settle = 5.0 / gain  # the observer's start-up
    for k in range(len(log.t)):
        q, dq, tau = log.q[k], log.dq[k], log.tau[k]
        if k == 0:
            obs.reset(q, dq, tau)
            continue
        # each row's feedback answers the command of the row before: its velocity refines the estimate
        r = obs.update(q, dq, tau, float(log.t[k] - log.t[k - 1]), kp_t[k - 1], kd_t[k - 1], log.dq_des[k - 1])
        if log.t[k] - log.t[0] > settle and (use is None or use[k]):
            np.maximum(peak, np.abs(r), out=peak)
    inertia = largest_inertia(model)
    return [math.ceil(max(THRESHOLD_MARGIN * p, MIN_SHARE * lim, STEP_MARGIN * gain * m * step) / 0.05 - 1e-9) * 0.05
            for p, lim, m, step in zip(peak, torque_limit, inertia, deadband, strict=True)]


def largest_inertia(model: RobotModel, samples: int = 64) -> np.ndarray:
    """Each joint's largest inertia (the mass matrix's diagonal, kg·m²) over the joint ranges, sampled."""
    lim = [j.limits for j in model.config.joints]
    qs = sample_box([x.lower for x in lim], [x.upper for x in lim], samples, seed=2)
    return np.max([np.diag(model.mass_matrix(q)) for q in qs], axis=0)


def payload_poses(limits: JointLimits, center: ArrayLike, step: float = 0.9) -> list[np.ndarray]:
    """Poses for :func:`estimate_payload`: ``q0``; each of the three joints nearest the tool moved by
    ±``step``, and the one before them by ±``step``/2 (clipped 0.05 rad inside the ranges): gravity
    then acts on the payload from several sides, and at several distances from the joints, so its
    mass and where it sits along the tool are told apart."""
    q0 = np.asarray(center, dtype=float)
    lo, hi = limits.lower + 0.05, limits.upper - 0.05
    n = len(q0)
    poses = [q0.copy()]
    for i in range(max(0, n - 4), n):
        size = step if i >= n - 3 else step / 2
        for sign in (1.0, -1.0):
            q = q0.copy()
            q[i] = float(np.clip(q0[i] + sign * size, lo[i], hi[i]))
            if abs(q[i] - q0[i]) > 0.05:
                poses.append(q)
    return poses


# ----------------------------------------------------------------------------------------------
# torque scale with a known weight
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Run:
    """One excitation's telemetry for :func:`fit_runs`: ``kp``, ``kd`` the MIT gains in force for each
    sample's torque (as for :func:`fit`), ``use`` the samples to fit, ``weight`` the known mass (kg) and
    centre of mass (m, tool frame) at the tool during it, or ``None``."""

    log: TelemetryLog
    kp: np.ndarray
    kd: np.ndarray
    use: np.ndarray | None = None
    weight: tuple[float, tuple[float, float, float]] | None = None
    #: the joints whose fit takes this run (``None``: all): a run where only these moved
    joints: tuple[int, ...] | None = None


def fit_runs(model: RobotModel, runs: Sequence[Run], *, offsets: bool = True, window: float = 0.1,
             decimate: int = 4) -> list[JointFit]:
    """Each joint's torque scale and friction (Coulomb with its load share, viscous, offset) from
    excitations with and without a known weight at the tool, the links' inertial parameters free.

    Per joint ``i``, over the samples of all runs (``k = 1/s``: N·m reported per N·m at the joint)::

        τ_i = k·τ_weight,i + Y_links,i·φ_i + k·(c + μ·|τ_i|)·tanh(q̇/0.02) + k·b·q̇ + k·offset + J·q̈ + lags

    ``τ_weight`` is the known weight's torque (the model's inverse dynamics with it minus without it; 0
    in a run without it), ``Y_links·φ`` every link's ten inertial parameters (Pinocchio's regressor)
    as this joint sees them, in N·m reported: the URDF's masses and centres of mass are not trusted
    (a real arm's are ±20 % off), ``J`` the rotor's inertia. Without the weight, a stronger motor and
    lighter links are the same data; the weight's torque, known in N·m, tells them apart. The measured
    torque is the fit's target (a fit with it among the columns shrinks the scale of a joint whose
    torque is mostly friction: the part of the torque the friction law does not explain counts as noise
    in the column). ``|τ_i|`` in the load share's column is the torque the fit says (:func:`_fit_joint`).
    A run with ``joints`` (a joint excited alone: identify_unit's runs for a vertical axis) informs
    only those joints' fits, and for them the encoder's play is fitted too (:func:`_play_columns`).
    Returns the per-joint fits (threshold unset).

    A joint whose torque the weight hardly changes (shoulder_pan: its axis is vertical, the weight only
    loads it through inertia) may get a scale outside what a real unit has (:data:`_SCALE_RANGE`): it
    keeps the catalogue's 1, and its friction is fitted so.

    Raises:
        StateError: too little data, or a model with a payload.
    """
    if model.payload is not None:
        raise StateError("fit_runs needs the model without a payload", fix="model.clear_payload() first")
    n = model.n
    nb = model.link_regressor(np.zeros(n), np.zeros(n), np.zeros(n)).shape[1]
    t_max = np.array([j.motor.t_max for j in model.config.joints])
    alone = {i for run in runs if run.joints is not None for i in run.joints}  # joints with runs of their own
    parts: list[tuple[np.ndarray, ...]] = []
    for run in runs:
        log = run.log
        if len(log.t) < 2:
            raise StateError(f"{len(log.t)} samples are too few to identify {n} joints", fix="excite for longer")
        dt = float(np.median(np.diff(log.t)))
        q, dq, ddq = _savgol(log.q, dt, window)
        kp_t = np.broadcast_to(np.asarray(run.kp, dtype=float), log.q.shape)[:-1]
        kd_t = np.broadcast_to(np.asarray(run.kd, dtype=float), log.q.shape)[:-1]
        tau = log.tau[:-1]
        # the torque after each sample acts over the period that follows: the motion's state mid-period
        q, dq, ddq = (0.5 * (x[:-1] + x[1:]) for x in (q, dq, ddq))
        ok = np.all(np.isfinite(q), axis=1) & (np.ones(len(q), bool) if run.use is None else np.asarray(run.use)[:-1])
        idx = np.nonzero(ok)[0][::decimate]
        links = np.empty((len(idx), n, nb))
        weight = np.zeros((len(idx), n))
        for r, k in enumerate(idx):
            links[r] = model.link_regressor(q[k], dq[k], ddq[k])
        if run.weight is not None:
            bare = np.array([model.inverse_dynamics(q[k], dq[k], ddq[k]) for k in idx])
            model.set_payload(run.weight[0], run.weight[1])
        try:
            if run.weight is not None:
                weight = np.array([model.inverse_dynamics(q[k], dq[k], ddq[k]) for k in idx]) - bare
            inertia = np.array([np.diag(model.mass_matrix(q[k])) for k in idx])  # (the weight's included)
        finally:
            model.clear_payload()
        play = _play_columns(log.tau, dt, window, t_max)[:, :, idx].transpose(2, 0, 1) * inertia[:, None, :]
        informs = np.zeros((len(idx), n), bool)
        informs[:, list(range(n)) if run.joints is None else list(run.joints)] = True
        parts.append((tau[idx], dq[idx], ddq[idx], kp_t[idx], kd_t[idx], links, weight, informs, play))
    tau, dq, ddq, kp_t, kd_t, links, weight, informs, play = (np.concatenate(x) for x in zip(*parts, strict=True))
    if len(tau) < 40:
        raise StateError(f"{len(tau)} samples are too few to identify {n} joints", fix="excite for longer")
    fits = []
    undetermined: set[int] = set()
    for i, name in enumerate(model.joint_names):
        mine = informs[:, i]
        v, a, t = dq[mine, i], ddq[mine, i], tau[mine, i]
        th = np.tanh(v / _SMOOTHING)
        friction = [th, v] + ([np.ones(len(t))] if offsets else [])
        common = [a, kp_t[mine, i] * v, kd_t[mine, i] * a]
        Yl = links[mine, i, :]
        Yl = Yl[:, np.any(Yl != 0.0, axis=0)]
        # Friction's load share from the whole torque (see _fit_joint) where the joint brakes often enough
        # to tell it from the scale, or was excited alone to; and there the encoder's play too (one column
        # per width in _PLAY_WIDTHS, the one that fits best)
        braking = float(np.mean((t * v < 0) & (np.abs(v) > 2 * _SMOOTHING)))
        whole = i in alone or braking >= _BRAKING
        tries = [None, *range(len(_PLAY_WIDTHS))] if i in alone else [None]
        best: tuple[np.ndarray, float, float, bool] | None = None
        for k in tries:
            extra = common if k is None else [*common, play[mine, k, i]]
            got = _fit_joint(t, weight[mine, i], friction, extra, Yl, th, whole=whole)
            if best is None or got[1] < best[1]:
                best = got
        assert best is not None
        x, rms, scale, determined = best
        nfric = len(friction)
        if not determined:
            undetermined.add(i)
        x = x[1:] / x[0]  # N·m at the joint
        load = x[nfric]
        c, b = x[0], x[1]
        off = x[2] if offsets else 0.0
        fits.append(JointFit(name, float(c), float(b), float(off), float(rms), torque_scale=float(scale),
                             load=float(load)))
    return fits


#: fit_runs takes friction's load share from the whole torque for a joint whose torque opposes its motion
#: (braking) in at least this share of its samples: with less, its data cannot tell the load share from the
#: scale (wrist_roll with a weight lighter than its friction: 1 % of its samples; +17 % off that way)
_BRAKING = 0.1

#: the encoder's play as a function of the motor's torque, ``tanh(τ / (w·t_max))``, for these widths ``w``
#: (fit_runs: a joint with runs of its own takes the one that fits best, or none)
_PLAY_WIDTHS = (0.01, 0.02, 0.05, 0.1)


def _play_columns(tau: np.ndarray, dt: float, window: float, t_max: np.ndarray) -> np.ndarray:
    """Backlash: a gearbox's play puts the motor's encoder ahead of the link by an amount that turns with
    the torque (about ``±play/2·tanh(τ/width)``), so the acceleration read from the encoder is the link's
    plus that amount's second derivative, and a fit of inertia on it is off (5 mrad of play took 2-3 %
    off shoulder_pan's scale). Per width of :data:`_PLAY_WIDTHS` (widths × joints × samples - 1, mid-period
    like the fit's states): the second derivative (Savitzky-Golay, as the positions) of
    ``tanh(τ / (width·t_max))``; times the joint's inertia, its coefficient is the play the fit removes."""
    out = np.empty((len(_PLAY_WIDTHS), tau.shape[1], len(tau) - 1))
    for w, width in enumerate(_PLAY_WIDTHS):
        second = _savgol(np.tanh(tau / (width * t_max)), dt, window)[2]
        second = 0.5 * (second[:-1] + second[1:])
        out[w] = np.where(np.isfinite(second), second, 0.0).T
    return out


def _fit_joint(t: np.ndarray, weight: np.ndarray, friction: list[np.ndarray], common: list[np.ndarray],
               links: np.ndarray, th: np.ndarray, *, whole: bool) -> tuple[np.ndarray, float, float, bool]:
    """One joint's solve for :func:`fit_runs`: the coefficients (the weight's first: 1/scale), the RMS
    residual, the scale, and whether the weight determined it (else 1, friction as reported).

    Friction's load-dependent part grows with the motor's torque but its friction; a column of the
    measured |τ| would be nearly the Coulomb column where the torque is mostly friction (a roll joint),
    and let the fit trade the scale for friction. So: the scale and friction without it, then twice with
    |the torque this fit says is not friction| as its column. ``whole``: with |the whole torque the fit
    says| from the second solve on (what the motor's current is, and what the friction grows with): a joint
    excited alone at its full acceleration brakes, its torque against its motion, and that tells the
    load share from the scale; where it only turned against its friction, |the torque not friction|
    took the load share for a weaker motor (shoulder_pan: 0.903 - 0.046 = 0.857, fitted 0.854; wrist_roll
    -5.0 %). Only where the joint brakes often enough (:data:`_BRAKING`): without braking both are the same
    data, and the whole torque lets the load share run off with the scale."""
    load_col = np.zeros(len(t))
    determined = True
    nfric = len(friction)
    for step in range(3):
        A = np.column_stack([weight, *friction, load_col, *common, links])
        if determined:
            x, rms = _solve(A, t)
            scale = 1.0 / x[0] if x[0] > 0 else math.inf
            if not _SCALE_RANGE[0] <= scale <= _SCALE_RANGE[1]:
                determined = False  # the weight does not tell it: the catalogue's 1, friction as reported
        if not determined:
            scale = 1.0
            x, rms = _solve(A[:, 1:], t - weight)
            x = np.concatenate([[1.0], x])
        if whole and step > 0:
            load_col = np.abs(A @ x) * th
        else:  # the motor's torque that is not friction (N·m reported): the weight's, the links', the rotor's
            load_col = np.abs(A[:, :1] @ x[:1] + A[:, 2 + nfric:] @ x[2 + nfric:]) * th
    return x, rms, scale, determined


def _solve(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares with the columns normalized (rank-deficient ones get the least-norm answer):
    the coefficients and the RMS residual."""
    norm = np.linalg.norm(A, axis=0)
    norm[norm == 0] = 1.0
    x, *_ = np.linalg.lstsq(A / norm, y, rcond=1e-8)
    x = x / norm
    return x, math.sqrt(float(np.mean((y - A @ x) ** 2)))
