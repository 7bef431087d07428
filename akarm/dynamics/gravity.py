"""Will the motors hold the arm? The largest gravity torque of every joint over the joint ranges.

For each driven joint, :func:`gravity_peaks` finds the largest ``|g_i(q)|`` over the box of joint
ranges (the configured payload included, plus an optional extra mass) and where it is reached.

How: the gravity torque of a chain of revolute joints is, along any one joint angle ``q_k`` with the
others fixed, exactly ``a + b·cos q_k + c·sin q_k`` (every link's pose is a product of rotations, each
angle appearing once). So three evaluations give the whole curve along ``q_k``, and its largest
``|·|`` within ``[lower_k, upper_k]`` is at an end of the range or at one of the two turning points.
The search samples the box (a fixed pseudo-random set, so results are reproducible), then from the
best samples of each joint maximises one coordinate at a time, exactly, until no coordinate
improves. This finds the maxima of the shipped arms and of the URDF corpus of the tests (at or above
what 20 000 random samples find, and the same from other sample sets to 1e-7); it costs about a
thousand gravity evaluations, a few ms for six joints (``benchmarks/bench_model.py``). Results are
kept for the last few robots, by URDF file (name, size, time) and everything else they depend on.
"""

from __future__ import annotations

import math
import os
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from akarm.config import RobotConfig

__all__ = ["GravityPeak", "gravity_peaks", "peak_abs", "sample_box"]

#: phases of the three evaluations along one coordinate
_PHASES = np.array([0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0])
_COS, _SIN = np.cos(_PHASES), np.sin(_PHASES)


@dataclass(frozen=True)
class GravityPeak:
    """The largest gravity torque of one joint over the joint ranges.

    Attributes:
        joint: the joint's name.
        torque: the largest ``|g|``, N·m.
        q: a configuration (rad, config order) where it is reached.
    """

    joint: str
    torque: float
    q: tuple[float, ...]

    def pose(self) -> str:
        """``q`` as ``[+0.00, +1.57, ...]`` rad."""
        return "[" + ", ".join(f"{x:+.2f}" for x in self.q) + "] rad"


def peak_abs(gravity: Callable[[np.ndarray], np.ndarray], lower: Sequence[float], upper: Sequence[float], *,
             samples: int = 48, starts: int = 3, sweeps: int = 12, seed: int = 1) -> list[tuple[float, np.ndarray]]:
    """Per joint, the largest ``|gravity(q)[i]|`` over the box ``lower <= q <= upper`` and where.

    Args:
        gravity: joint torques at ``q`` (config order) for revolute or continuous joints.
        lower, upper: the box, rad.
        samples: random configurations to start from (plus the box's centre).
        starts: the best samples per joint that are refined.
        sweeps: at most this many passes over the coordinates per start.
        seed: of the sample set (fixed: the same file always gives the same answer).

    Returns:
        per joint ``(torque, q)``: the largest ``|g_i|`` (N·m) and a configuration where it is reached.
    """
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    n = lo.size
    pts = sample_box(lo, hi, samples, seed)
    values = np.array([gravity(q) for q in pts])
    scale = float(np.abs(values).max()) if values.size else 0.0
    out: list[tuple[float, np.ndarray]] = []
    for i in range(n):
        if not np.abs(values[:, i]).max() > 1e-12 * max(scale, 1.0):  # no gravity on it anywhere (a vertical axis)
            s = int(np.argmax(np.abs(values[:, i])))
            out.append((float(abs(values[s, i])), pts[s].copy()))
            continue
        best_t, best_q = -1.0, pts[0]
        for s in np.argsort(-np.abs(values[:, i]))[:starts]:
            t, q = _refine(gravity, i, pts[s].copy(), float(values[s, i]), lo, hi, sweeps)
            if t > best_t:
                best_t, best_q = t, q
        out.append(_tidy(gravity, i, best_t, best_q, lo, hi))
    return out


def _tidy(gravity: Callable[[np.ndarray], np.ndarray], i: int, torque: float, q: np.ndarray, lo: np.ndarray,
          hi: np.ndarray) -> tuple[float, np.ndarray]:
    """The same peak at a pose easier to read: each joint that does not matter to it put at 0 (within
    its range), e.g. the base's yaw for a shoulder's gravity torque."""
    for k in range(q.size):
        x = min(max(0.0, lo[k]), hi[k])
        if q[k] == x:
            continue
        trial = q.copy()
        trial[k] = x
        t = abs(float(gravity(trial)[i]))
        if t >= torque * (1 - 1e-12):
            q, torque = trial, t
    return torque, q


def sample_box(lower: Sequence[float] | np.ndarray, upper: Sequence[float] | np.ndarray, samples: int = 48,
               seed: int = 1) -> np.ndarray:
    """The box's centre and ``samples`` reproducible pseudo-random points in it, one per row."""
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    rng = np.random.default_rng(seed)
    return np.vstack([(lo + hi) / 2.0, lo + rng.random((samples, lo.size)) * (hi - lo)])


def _refine(gravity: Callable[[np.ndarray], np.ndarray], i: int, q: np.ndarray, g: float, lo: np.ndarray,
            hi: np.ndarray, sweeps: int) -> tuple[float, np.ndarray]:
    """Coordinate-wise exact ascent of ``|g_i|`` from ``q`` (where ``g_i = g``)."""
    best = abs(g)
    for _ in range(sweeps):
        improved = False
        for k in range(q.size):
            if not hi[k] > lo[k]:
                continue
            th0 = q[k]
            f = np.empty(3)
            f[0] = g
            for m in (1, 2):
                q[k] = th0 + _PHASES[m]
                f[m] = gravity(q)[i]
            q[k] = th0
            # f(th0 + phase) = a + b cos(th0 + phase) + c sin(th0 + phase): first in terms of the phase
            a = f.mean()
            bp = 2.0 / 3.0 * float(f @ _COS)
            cp = 2.0 / 3.0 * float(f @ _SIN)
            # rotate back to absolute angles: cos(th - th0), sin(th - th0)
            c0, s0 = math.cos(th0), math.sin(th0)
            b = bp * c0 - cp * s0
            c = bp * s0 + cp * c0
            phi = math.atan2(c, b)
            candidates = [lo[k], hi[k]]
            for turn in (phi, phi + math.pi):  # maximum and minimum of b cos + c sin
                j = math.ceil((lo[k] - turn) / (2 * math.pi))
                x = turn + 2 * math.pi * j
                while x <= hi[k]:
                    candidates.append(x)
                    x += 2 * math.pi
            vals = [a + b * math.cos(x) + c * math.sin(x) for x in candidates]
            m = max(range(len(vals)), key=lambda k2: abs(vals[k2]))
            if abs(vals[m]) > best * (1 + 1e-9) + 1e-12:
                q[k] = candidates[m]
                g = float(gravity(q)[i])  # exact, not the fit
                if abs(g) > best:
                    best = abs(g)
                    improved = True
                else:
                    q[k] = th0
                    g = float(gravity(q)[i])
        if not improved:
            break
    return best, q


#: recent results by what they depend on (the suite and long-lived programs load the same robots often)
_CACHE: OrderedDict[tuple[object, ...], list[GravityPeak]] = OrderedDict()
_CACHE_SIZE = 32


def clear_cache() -> None:
    """Forget every cached result of :func:`gravity_peaks` (benchmarks time a cold computation)."""
    _CACHE.clear()


def _key(config: RobotConfig, extra_payload: float) -> tuple[object, ...] | None:
    try:
        st = os.stat(config.urdf)
    except OSError:
        return None
    p = config.payload  # by value: a Payload built in code may hold a list (unhashable) as its com
    payload = None if p is None else (float(p.mass), tuple(float(c) for c in p.com))
    return (str(config.urdf), st.st_mtime_ns, st.st_size, tuple((j.name, j.limits.lower, j.limits.upper)
            for j in config.joints), tuple(sorted(config.locked.items())), payload, tuple(config.gravity),
            config.tool_frame, float(extra_payload))


def gravity_peaks(config: RobotConfig, *, extra_payload: float = 0.0) -> list[GravityPeak]:
    """The largest gravity torque of every joint of ``config`` over its position limits.

    Args:
        config: the robot; its payload (if any) is included.
        extra_payload: kg more at the payload's centre of mass (the tool frame's origin without a
            payload): a margin for what the gripper may carry.

    Raises:
        ModelError: the dynamics model cannot be built.
    """
    key = _key(config, extra_payload)
    if key is not None and key in _CACHE:
        _CACHE.move_to_end(key)
        return list(_CACHE[key])
    peaks = _gravity_peaks(config, extra_payload)
    if key is not None:
        _CACHE[key] = peaks
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    return list(peaks)


def _gravity_peaks(config: RobotConfig, extra_payload: float) -> list[GravityPeak]:
    import pinocchio as pin

    from akarm.dynamics.model import RobotModel

    model = RobotModel(config)
    if extra_payload:
        base = config.payload
        mass = (base.mass if base is not None else 0.0) + float(extra_payload)
        model.set_payload(mass, base.com if base is not None else (0.0, 0.0, 0.0))
    lower = [j.limits.lower for j in config.joints]
    upper = [j.limits.upper for j in config.joints]
    gravity: Callable[[np.ndarray], np.ndarray] = model.gravity
    pm, pd = model.pin_model, model.pin_data
    if model.identity_mapping:
        def gravity(q: np.ndarray) -> np.ndarray:  # config order is Pinocchio's: no mapping (3x faster)
            return pin.computeGeneralizedGravity(pm, pd, q)
    return [GravityPeak(j.name, t, tuple(float(x) for x in q))
            for j, (t, q) in zip(config.joints, peak_abs(gravity, lower, upper), strict=True)]
