"""The collision reflex: an estimate of the external torque on every joint, and a stop when one is too large.

**Estimate: a generalized-momentum observer** (De Luca et al., 2003), not a filtered residual of
inverse dynamics: it needs no joint acceleration (which would have to be differentiated from the
motors' quantised velocity), and its output is a first-order filter of the true external torque,
``ṙ = K·(τ_ext - r)``, whatever the controller does. With the arm's momentum ``p = M(q)·q̇``::

    ṗ = τ_m + C(q, q̇)ᵀ·q̇ - g(q) - τ_f(q̇) + τ_ext
    r = K·(p - p(0) - ∫ (τ_m + Cᵀq̇ - g - τ_f + r) dt)

``τ_m`` is the torque the motors report, ``τ_f = c·tanh(q̇/0.02) + b·q̇ + offset`` the joint's
friction (its ``friction:`` in the YAML: identified, or the catalogue's typical values), ``M``,
``C``, ``g`` the arm's model with the payload it is told about (:meth:`akarm.Arm.set_payload`), so
a payload that is set or identified is not a collision. ``K`` (1/s) sets the time constant: with
the default 50/s a step of external torque shows 63 % of itself after 20 ms; a larger ``K`` reacts
sooner and passes on more of the velocity quantisation (``K·M·Δq̇``).

**Model error is not a collision.** A real arm is not its model: an unknown tool or payload, URDF
masses 20 % off, a torque constant 30 % off, twice the catalogue's friction put a slow, pose-dependent
error of several N·m into ``r``. :class:`ModelResidual` separates it from a contact: the reflex judges
how much ``r`` rose over the last :data:`WINDOW` (60 ms), not its level, and each threshold grows by
what the model's uncertainty (:class:`Uncertainty`: wide for a joint the robot file has no identified
values for, narrow after ``akarm identify --save``) lets the error change in that time: a share of the
change of the model's and the motors' torque (an acceleration, a move's start and end) and of the
friction model's (a start from rest). A contact is a step: it shows whole within the window. A push
that builds up over more than the window is not judged; after a fresh start (enable, a new payload
or friction) nothing is judged for :data:`LEARN_TIME` while the estimate settles. After a stop the
window's start is held: the reflex re-arms once the contact has ended.

**Reflex.** A joint whose judged part of ``r`` passes its threshold (YAML ``collision: {threshold: N·m}``;
``akarm identify`` suggests one from the residual's noise) stops the arm with a
:class:`~akarm.CollisionError` naming the joint and the torque: damped and disabled (the default),
or, with ``reaction="hold"``, brought to rest jerk-limited and held. Joints without a threshold
are not checked. Teach mode is never checked (the hand is an expected external torque); after
teach mode, and after a stop-and-hold, the reflex re-arms once every joint's estimate is back
under half its threshold (the hand let go, the contact ended).
"""

from __future__ import annotations

import collections
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from akarm.config import JointConfig, RobotConfig
from akarm.dynamics.model import ArrayLike, RobotModel
from akarm.errors import ArgumentError, CollisionError
from akarm.protocol import mit
from akarm.protocol.units import erpm_to_rad_s

__all__ = ["DEFAULT_GAIN", "LEARN_TIME", "WINDOW", "CollisionReflex", "ModelResidual", "MomentumObserver",
           "Reaction", "Uncertainty", "friction_torque", "reflex_for", "uncertainty_for", "velocity_resolution"]

Reaction = Literal["disable", "hold"]
#: 1/s: the observer's default bandwidth (time constant 20 ms).
DEFAULT_GAIN = 50.0
#: rad/s: the Coulomb friction model's smoothing speed (the same as the feed-forward's and the simulator's).
FRICTION_SMOOTHING = 0.02
_LAG_SMOOTHING = 0.02  # s: low-pass of the measured velocity's difference to the command (see velocity())
#: loop periods between two complete sets of feedback after which the observer starts over rather
#: than integrate across the gap (a stall of the loop or of the drivers, a mode without it)
RESET_GAP = 3.5
_POSITION_STEP = 1e-3  # rad: twice the MIT position field's step (0.38 mrad), the travel a timing check trusts
#: s: how long a contact stays "sudden". The reflex judges how much the estimate rose over this window, not its
#: level: a model error (a payload it was not told, masses, a real unit's torque constant, friction) changes with
#: the pose and the motion, smoothly; a contact is a step. A step shows 95 % of itself after 60 ms (the observer's
#: 20 ms lag), so the reflex has the window to decide; a push that builds up more slowly is not a collision to it.
WINDOW = 0.06
#: s the reflex judges nothing after a fresh start (enable, a new payload or friction), while the estimate rises
#: from 0 to the model's error (a step to it, as the window would see it).
LEARN_TIME = 0.3
#: How much of a change of the motors' reported torque (not only the model's) the thresholds grow with: a torque
#: scale error is a share of what the motors deliver, the PD's part too; a contact's own PD reaction, which comes
#: after the contact, should not hide it (half).
REPORTED_SHARE = 0.5
#: The same for the whole estimate (the slow contact's check), of the motors' reported torque now: a unit whose
#: motor gives less per N·m reported, with heavier links, reports that much more than the model asks, and the
#: estimate is that difference, a share of what it reports: seed 3's elbow (0.68 N·m per N·m reported, its links
#: 8 % heavier) lagging its command at full speed reported 13.0 N·m with 5.0 N·m of model error, over
#: 1.10 + 0.6 · max(5.5, 0.5 · 13.0) N·m. A joint blocked while its command moves on still builds up past it:
#: its motor's torque grows until the estimate passes th + 0.45·τ (before the motor's own limit).
LEVEL_REPORTED_SHARE = 0.75
#: s of motion the learnt share of the model's error (:attr:`ModelResidual.follow`) remembers: a share learnt
#: over the last few moves, which a new payload or the next unit's pose range changes within a few more.
FOLLOW_MEMORY = 5.0
#: (N·m)²: how much change of the model's torque it takes before the learnt share counts fully (a share learnt
#: from a few small changes stays near 0: the thresholds' margin alone covers the error then).
FOLLOW_PRIOR = 20.0
#: N·m: a change of the model's torque over the window smaller than this teaches nothing (noise, a joint at rest).
FOLLOW_MIN = 0.05


def friction_torque(v: np.ndarray, coulomb: np.ndarray, viscous: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Joint friction (N·m) at velocities ``v`` (rad/s): ``c·tanh(v/0.02) + b·v + offset``."""
    return coulomb * np.tanh(v / FRICTION_SMOOTHING) + viscous * v + offset


def velocity_resolution(joint: JointConfig) -> float:
    """The step of a joint's velocity feedback, rad/s: the 12-bit MIT field over ±v_max (it has no
    zero: a joint at rest reads ±half a step), or 10 ERPM in servo status frames (V3 MIT replies too)."""
    if joint.mode == "servo" or joint.firmware == "v3":
        return erpm_to_rad_s(joint.motor, 10.0)
    return float(mit.codec(joint.motor).steps.velocity)


def _floats(x: ArrayLike) -> list[float]:
    """``x`` as a new list of Python numbers (the observer's per-joint arithmetic is scalar: on a few
    joints a pass of float operations costs a fraction of numpy's per-call overhead). A list, which
    the controller passes, is copied as it is: converting its items again cost a third of a
    microsecond per call, a dozen calls a cycle."""
    if type(x) is list:
        return x[:]
    return x.tolist() if isinstance(x, np.ndarray) else [float(v) for v in x]


class MomentumObserver:
    """The generalized-momentum observer of the module's docstring (config joint order, SI).

    Args:
        model: the arm's model (the payload included); used from one thread only.
        coulomb, viscous, offset: per joint friction, N·m, N·m·s/rad, N·m.
        gain: K, 1/s.
        deadband: rad/s per joint: a measured speed this small is a joint at rest as far as the
            Coulomb friction goes (one step of the velocity feedback: :func:`velocity_resolution`;
            at rest a joint's friction is anywhere within ±coulomb, and the smooth model says 0).
        saturation: N·m per joint, the motors' torque range (a torque there does not decay).

    Its arithmetic per joint is done in scalar passes over lists of floats (the momentum and the
    model's terms come from the model as arrays): for six joints that is about a third of the cost
    of the same steps as numpy calls on six-element arrays, with the same operations in the same
    order.
    """

    def __init__(self, model: RobotModel, coulomb: Sequence[float], viscous: Sequence[float],
                 offset: Sequence[float], gain: float = DEFAULT_GAIN, deadband: Sequence[float] | None = None,
                 saturation: Sequence[float] | None = None) -> None:
        if not (gain > 0 and math.isfinite(gain)):
            raise ArgumentError(f"the collision observer's gain must be a positive number (1/s), got {gain!r}")
        self.model = model
        self.gain = float(gain)
        n = len(coulomb)
        self.n = n
        self.set_friction(coulomb, viscous, offset)
        self._scale = [1.0] * n  # N·m each joint gets per N·m its motor reports (set_torque_scale)
        self.deadband = np.zeros(n) if deadband is None else np.asarray(deadband, dtype=float)
        self._deadband = self.deadband.tolist()
        self._half_deadband = (0.5 * self.deadband).tolist()
        #: N·m per joint: a reported torque this large is the motor at its limit
        self.saturation = np.full(n, np.inf) if saturation is None else 0.999 * np.asarray(saturation, dtype=float)
        self._saturation = self.saturation.tolist()
        self._saturation_min = min(self._saturation, default=math.inf)
        self._lag: list[float] | None = None
        self._r = [0.0] * n  # the estimate, N·m (:attr:`estimate`)
        self._p0 = [0.0] * n
        self._integral = [0.0] * n
        self._last: tuple[list[float], list[float], list[float]] = ([0.0] * n, [0.0] * n, [0.0] * n)
        #: the model's ``g - Cᵀq̇`` per joint at the last step, N·m (the gravity torque, at low speed)
        self.beta = [0.0] * n
        self.started = False

    def set_friction(self, coulomb: ArrayLike, viscous: ArrayLike, offset: ArrayLike) -> None:
        """New friction per joint (N·m, N·m·s/rad, N·m), e.g. identified ones (restart the estimate after)."""
        self.coulomb = np.array(coulomb, dtype=float)
        self.viscous = np.array(viscous, dtype=float)
        self.offset = np.array(offset, dtype=float)
        self._friction = list(zip(self.coulomb.tolist(), self.viscous.tolist(), self.offset.tolist(), strict=True))

    def set_torque_scale(self, scale: Sequence[float]) -> None:
        """N·m each joint gets per N·m its motor reports (a real unit's, identified): the motors' torque
        counts times it (restart the estimate after)."""
        self._scale = [float(x) for x in scale]

    def at_limit(self, tau: Sequence[float]) -> bool:
        """Whether a reported torque (N·m per joint) is at its motor's limit (:attr:`saturation`)."""
        if max(map(abs, tau), default=0.0) < self._saturation_min:  # (the usual case, in one pass)
            return False
        return any(t >= sat or t <= -sat for t, sat in zip(tau, self._saturation, strict=True))

    def velocity(self, dq: ArrayLike, v_des: ArrayLike | None, dt: float = 0.0) -> list[float]:
        """The velocity the observer works with: the measured one, or, when the arm tracks a command,
        the command plus its (low-passed, 20 ms) difference to the measurement, kept within the
        measurement's quantisation step (the feedback rounds to the nearest step, so the truth is
        within half a step of it). That is smooth where the feedback jumps by whole steps, and each
        jump would pass ``K·M·step`` into the estimate."""
        d = _floats(dq)
        if v_des is None:
            self._lag = None
            return d
        vd = _floats(v_des)
        lag = self._lag
        if lag is None:  # from the command: the first reading is off by up to half a step
            lag = self._lag = [0.0] * len(d)
        a = min(1.0, dt / _LAG_SMOOTHING)
        out = []
        for i, (x, c, h) in enumerate(zip(d, vd, self._half_deadband, strict=True)):
            li = lag[i] + a * ((x - c) - lag[i])
            lag[i] = li
            out.append(min(max(c + li, x - h), x + h))
        return out

    def _smooth(self, beta: list[float], dq: list[float], v_des: list[float] | None) -> list[float]:
        """``τ_f - Cᵀq̇ + g`` at (q, v), given ``beta = g - Cᵀq̇`` there
        (:meth:`~akarm.dynamics.model.RobotModel.momentum`): what the model and friction take
        from the momentum's rate of change. The friction's speed: the commanded one where the joint
        tracks it (within two steps of the feedback: slow motions, whose feedback flips between "at
        rest" and "moving", follow the smooth command, as the feed-forward does), unless the command
        is at rest and the joint moves by more than a step (it creeps, or slides back after it stopped:
        it rubs); else the measured one, a speed within one step of it counting as at rest for the
        Coulomb friction (at rest it is anywhere within ±coulomb, and the smooth model says 0).
        (:func:`friction_torque`, per joint.)"""
        return [self._smooth_one(i, dq[i], None if v_des is None else v_des[i], beta[i]) for i in range(self.n)]

    def _smooth_one(self, i: int, x: float, c: float | None, be: float) -> float:
        """:meth:`_smooth` for joint ``i``: measured speed ``x``, commanded ``c`` (``None``: not tracking)."""
        db = self._deadband[i]
        co, b, o = self._friction[i]
        v_f = x
        if c is not None and abs(c - x) <= 2.0 * db and not (abs(c) <= db < abs(x)):  # tracks the command
            v_f = c
        elif abs(x) <= db:  # at rest as far as the Coulomb friction goes
            co = 0.0
        return co * math.tanh(v_f / FRICTION_SMOOTHING) + b * v_f + o + be

    def reset(self, q: ArrayLike, dq: ArrayLike, tau: ArrayLike, v_des: ArrayLike | None = None,
              estimate: Sequence[float] | None = None) -> None:
        """Start over at (q, q̇, τ): the estimate is ``estimate`` (N·m per joint; default 0) and moves
        towards the external torque from there."""
        self._lag = None
        d = _floats(dq)
        vd = None if v_des is None else _floats(v_des)
        v = self.velocity(d, vd)
        p, beta = self.model.momentum(q, v)
        r0 = [0.0] * self.n if estimate is None else [float(x) for x in estimate]
        k = self.gain
        self._p0 = [pi - ri / k for pi, ri in zip(p, r0, strict=True)]  # r = K·(p - p0) at the start
        self._integral = [0.0] * self.n
        self._last = (_floats(tau), v, self._smooth(beta, d, vd))
        self._r = r0
        self.beta = beta
        self.started = True

    @property
    def estimate(self) -> np.ndarray:
        """The external torque estimate per joint, N·m (a new array; zeros before the first step)."""
        return np.array(self._r)

    def update(self, q: ArrayLike, dq: ArrayLike, tau: ArrayLike, dt: float,
               kp: ArrayLike | None = None, kd: ArrayLike | None = None,
               v_des: ArrayLike | None = None) -> np.ndarray:
        """:meth:`advance`, and the new :attr:`estimate`."""
        self.advance(q, dq, tau, dt, kp, kd, v_des)
        return self.estimate

    def advance(self, q: ArrayLike, dq: ArrayLike, tau: ArrayLike, dt: float,
                kp: ArrayLike | None = None, kd: ArrayLike | None = None,
                v_des: ArrayLike | None = None) -> None:
        """One step: positions (rad), velocities (rad/s), motor torques (N·m) measured now, ``dt`` s
        since the last step; ``kp``, ``kd``: the MIT gains in force (N·m/rad, N·m·s/rad; 0 for servo
        joints); ``v_des``: the velocity commanded when the feedback was taken (see :meth:`velocity`).
        The estimate is then :attr:`estimate` (:attr:`estimate_list` as floats).

        The torque between two samples: an MIT command is held for a whole period, and the reply
        carries the torque of the command just received, so the PD part decays from the sample by
        ``kp·q̇ + kd·q̈`` per second until the next command: over the period it averages the last
        sample less half that decay. Gravity, Coriolis and friction change smoothly: trapezoidal.
        (The rectangle rule's error ``K·Δβ·dt/2`` would follow the arm's gravity torque.)

        After the model's momentum, everything per joint is one scalar pass over floats (friction,
        the torque's decay, the integral, the estimate), no numpy operation: in the control loop, whose
        core sleeps between cycles, every separate pass and numpy call starts cold."""
        tau_prev, v_prev, smooth_prev = self._last
        d = _floats(dq)
        vd = None if v_des is None else _floats(v_des)
        v = self.velocity(d, vd, dt)
        p, beta = self.model.momentum(q, v)
        n = self.n
        if kp is not None:
            kpl, kdl = _floats(kp), ([0.0] * n if kd is None else _floats(kd))
        smooth_one, saturation = self._smooth_one, self._saturation
        integral, p0, r_prev, k, scale = self._integral, self._p0, self._r, self.gain, self._scale
        smooth = [0.0] * n
        r = [0.0] * n
        for i in range(n):
            sm = smooth_one(i, d[i], None if vd is None else vd[i], beta[i])
            smooth[i] = sm
            t = tau_prev[i]
            if kp is not None and abs(t) < saturation[i]:  # (a saturated motor holds its limit: no decay)
                vp = v_prev[i]
                t = t - 0.5 * (kpl[i] * vp * dt + kdl[i] * (v[i] - vp))
            t *= scale[i]
            g = integral[i] + (t - 0.5 * (sm + smooth_prev[i]) + r_prev[i]) * dt
            integral[i] = g
            r[i] = k * (p[i] - p0[i] - g)
        self._last = (_floats(tau), v, smooth)
        self._r = r
        self.beta = beta

    @property
    def estimate_list(self) -> list[float]:
        """:attr:`estimate` as a list of floats (read-only: a copy)."""
        return self._r[:]


@dataclass(frozen=True)
class Uncertainty:
    """How wrong the model of one joint may be, as shares: ``torque`` of the motor's torque (its torque
    constant, the gearbox, the link masses, an unknown payload), ``friction`` of its Coulomb and viscous
    friction, ``friction_load``: N·m of Coulomb friction per N·m of the motor's torque that the model does
    not have (friction's load-dependent part, which the observer does not model). Unidentified: 0.6, 1.0
    and 0.06 (real units: torque constants ±30 %, true/reported 0.7-1.0, URDF masses ±20 %; friction
    0.5-2× the catalogue's, and up to 6 % of the load: an AK80-9 with a load cell, 0.049 N·m per A of its
    0.82 N·m/A); identified (``akarm identify``): 0.15, 0.3 and 1.3 times the fitted load share."""

    torque: float = 0.6
    friction: float = 1.0
    friction_load: float = 0.06


#: Uncertainty of a joint the robot file gives identified values for (its load share: the fit's, x 1.3).
IDENTIFIED = Uncertainty(0.15, 0.3, 0.0)


def uncertainty_for(joint: JointConfig) -> Uncertainty:
    """How wrong ``joint``'s model may be: :data:`IDENTIFIED` (with 1.3 times its fitted load share) where
    the robot file gives its identified friction (``akarm identify --save``), else the default
    :class:`Uncertainty`."""
    if joint.friction is None:
        return Uncertainty()
    return Uncertainty(IDENTIFIED.torque, IDENTIFIED.friction, (1.0 + IDENTIFIED.friction) * joint.friction.load)


class ModelResidual:
    """Separates the slow, pose-dependent part of the external torque estimate (the model's error: a
    payload it was not told, link masses, the torque constant, friction) from the sudden part (a
    contact), and says how far the sudden part may still be the model's error.

    The slow part is the estimate :data:`WINDOW` ago; the reflex judges the rise since. A model error
    changes in that time only as much as what it is proportional to: ``δ·τ`` for a torque scale or
    masses off by ``δ`` (the model's torque: the feed-forward, through the observer's lag), ``δ_c`` times
    the friction model's Coulomb term (a start from rest, a reversal). The thresholds grow by
    ``Uncertainty.torque`` times the change of the model's torque over the window, and by
    ``Uncertainty.friction`` times the change of its friction.

    **Stick-slip.** A joint that lags its command stops or starts when its *measured* speed says so, not
    its command's: a real unit's friction (up to twice the catalogue's) holds it a few ms longer, and the
    arm's momentum goes into the gearbox. Where the measured direction catches up with the command's, the
    friction's change of direction is counted on the larger of the two. A contact that stops, reverses
    or moves a joint takes it away from its command: not counted. So a joint that creeps, or slides back
    after it stopped, is not covered either: a push on a joint held at rest looks the same, and
    detection comes first. Friction's load-dependent part, which the model does not have, adds
    ``Uncertainty.friction_load`` times the motor's torque times that change.

    **The share is learnt.** A real unit's error follows the model's torque by a share of its own
    (seed 3's elbow: 0.68 N·m per N·m reported and links 8 % heavier: the estimate moves by -0.47 N·m per
    N·m the model's torque changes, near the 0.6 the margin allows). :attr:`follow` is that share, fitted
    per joint by least squares over the last :data:`FOLLOW_MEMORY` s of motion (:meth:`learn`: only
    windows where the joint is calm, so a contact teaches nothing), within ``±Uncertainty.torque``; the
    rise judged is the estimate's change less ``follow`` times the model's torque change. The model's
    torque is the plan's (the feed-forward), not the motors' reported torque: a contact's own reaction
    never counts as model error. A fresh start (enable, a new payload or friction) learns again from 0.
    """

    def __init__(self, n: int, coulomb: Sequence[float], viscous: Sequence[float], deadband: Sequence[float],
                 uncertainty: Sequence[Uncertainty], gain: float, period: float) -> None:
        self.n = n
        self.set_model(coulomb, viscous, uncertainty)
        self._deadband = [float(x) for x in deadband]
        self.gain = gain
        self._period = period
        size = max(2, round(WINDOW / period) + 1)
        self._r: collections.deque[list[float]] = collections.deque(maxlen=size)
        self._t: collections.deque[list[float]] = collections.deque(maxlen=size)
        self._f: collections.deque[list[float]] = collections.deque(maxlen=size)
        self._m: collections.deque[list[float]] = collections.deque(maxlen=size)
        self._s: collections.deque[list[float]] = collections.deque(maxlen=size)
        self._rep_lag = [0.0] * n
        self._tau_lag = [0.0] * n
        self._fr_lag = [0.0] * n
        # the friction's direction on the commanded speed, then on the measured (through the observer's lag)
        self._sign_lag = [0.0] * 2 * n
        self._prediction = [0.0] * n
        self.learning_until = -math.inf
        self.fresh = True
        #: the estimate's slow part is held where it was (after a collision: the contact must end, the
        #: estimate come back to it, before the reflex watches again)
        self.frozen = False
        self.margin = [0.0] * n
        self.level_margin = [math.inf] * n
        self._follow = [0.0] * n
        self._sxx = [0.0] * n
        self._sxy = [0.0] * n
        self._x = [0.0] * n  # the model torque's change over the window at the last update, N·m
        self._y = [0.0] * n  # the estimate's

    @property
    def follow(self) -> list[float]:
        """Per joint, the learnt share of the model torque's change that the estimate follows (the model's
        error: a unit's torque scale and masses), within ``±Uncertainty.torque`` (a copy)."""
        return self._follow[:]

    def set_model(self, coulomb: Sequence[float], viscous: Sequence[float],
                  uncertainty: Sequence[Uncertainty]) -> None:
        self._c = [float(x) for x in coulomb]
        self._b = [float(x) for x in viscous]
        self.uncertainty = tuple(uncertainty)
        self._ut = [u.torque for u in self.uncertainty]
        self._uf = [u.friction for u in self.uncertainty]
        self._ul = [u.friction_load for u in self.uncertainty]

    @property
    def slow(self) -> list[float]:
        """The slow part of the estimate per joint, N·m (the model's error as it was a window ago)."""
        return self._prediction[:]

    def _friction(self, v: Sequence[float]) -> list[float]:
        return [(0.0 if -db <= x <= db else c * math.tanh(x / FRICTION_SMOOTHING)) + b * x
                for c, b, db, x in zip(self._c, self._b, self._deadband, v, strict=True)]

    def _signs(self, v: Sequence[float], measured: Sequence[float]) -> list[float]:
        """The Coulomb friction's direction (-1..1; 0 within a step of the feedback) on the commanded
        speeds ``v``, then on the measured ones."""
        return [0.0 if -db <= x <= db else math.tanh(x / FRICTION_SMOOTHING)
                for x, db in zip([*v, *measured], self._deadband * 2, strict=True)]

    def start(self, now: float, estimate: Sequence[float], tau: Sequence[float] | np.ndarray, v: Sequence[float],
              reported: Sequence[float] | None = None, measured: Sequence[float] | None = None) -> None:
        """The observer starts over at ``estimate``: after a fresh start (:attr:`fresh`) learn for
        :data:`LEARN_TIME` (judge nothing while the estimate rises to the model's error)."""
        if self.fresh:
            self.learning_until = now + LEARN_TIME
            self.fresh = False
            self._follow = [0.0] * self.n
            self._sxx = [0.0] * self.n
            self._sxy = [0.0] * self.n
        self._x = [0.0] * self.n
        self._y = [0.0] * self.n
        self._tau_lag = [float(x) for x in tau]
        self._fr_lag = self._friction(v)
        self._sign_lag = self._signs(v, v if measured is None else measured)
        self._rep_lag = [float(x) for x in (tau if reported is None else reported)]
        for q, x in ((self._r, [float(e) for e in estimate]), (self._t, self._tau_lag), (self._f, self._fr_lag),
                     (self._m, self._rep_lag), (self._s, self._sign_lag)):
            if q is self._r and self.frozen:
                continue
            q.clear()
            q.append(x[:])  # (a copy: the lags change in place)
        self._prediction = list(self._r[0])
        self.margin = [0.0] * self.n
        self.level_margin = [math.inf] * self.n

    def update(self, now: float, estimate: Sequence[float], tau: Sequence[float] | np.ndarray, v: Sequence[float],
               dt: float, reported: Sequence[float] | None = None,
               measured: Sequence[float] | None = None) -> list[float]:
        """One step; returns the sudden part of ``estimate`` (N·m per joint); :attr:`margin` is then
        what the thresholds grow by (N·m per joint). ``tau``: the model's torque; ``v``: the speeds its
        friction is taken at (the commanded ones where the arm tracks a command); ``reported``: the
        motors' torque (a scale error is a share of it: the PD's share too); ``measured``: the measured
        speeds (a joint that lags its command stops and starts on these)."""
        a = min(1.0, self.gain * dt)  # what the estimate sees of a torque: through the observer's lag
        tl, fl, ml = self._tau_lag, self._fr_lag, self._rep_lag
        rep = tau if reported is None else reported
        for i, (t, f, m) in enumerate(zip(tau, self._friction(v), rep, strict=True)):
            tl[i] += a * (t - tl[i])
            fl[i] += a * (f - fl[i])
            ml[i] += a * (m - ml[i])
        sl = self._sign_lag
        for i, x in enumerate(self._signs(v, v if measured is None else measured)):
            sl[i] += a * (x - sl[i])
        r = [float(e) for e in estimate]
        if not self.frozen:
            self._r.append(r)
        self._t.append(tl[:])
        self._f.append(fl[:])
        self._m.append(ml[:])
        self._s.append(sl[:])
        if now < self.learning_until:  # the window starts over until the estimate has settled
            self.frozen = False
            for q in (self._r, self._t, self._f, self._m, self._s):
                while len(q) > 1:
                    q.popleft()
        r0, t0, f0, m0, s0 = self._r[0], self._t[0], self._f[0], self._m[0], self._s[0]
        self._prediction = r0
        n = self.n
        margin = [0.0] * n
        for i in range(n):
            ds_cmd = abs(sl[i] - s0[i])  # the friction's change of direction, on the command
            ds = ds_cmd
            if abs(sl[n + i] - sl[i]) < abs(s0[n + i] - s0[i]):
                # and on the measurement, where the joint catches up with its command's direction (a lagging
                # joint that comes to rest after its command did, or breaks away after it started); a
                # contact that stops, reverses or moves a joint takes it away from its command: not counted
                # (a push on a joint held at rest moves it too: counting that hid a push of twice the elbow's
                # threshold for 200 ms in benchmarks/bench_collision.py)
                ds = max(ds_cmd, abs(sl[n + i] - s0[n + i]))
            margin[i] = (self._ut[i] * max(abs(tl[i] - t0[i]), REPORTED_SHARE * abs(ml[i] - m0[i]))
                         + self._uf[i] * (abs(fl[i] - f0[i]) + self._c[i] * (ds - ds_cmd))
                         + self._ul[i] * abs(ml[i]) * ds)
        self.margin = margin
        # the whole estimate may be the model's error up to its uncertainty times the model's torque now
        # (not its change): what a contact that builds up slower than the window (a joint blocked while its
        # command moves on, a person pinned slowly) is judged against
        self.level_margin = [ut * max(abs(x), LEVEL_REPORTED_SHARE * abs(m)) + uf * abs(f)
                             for ut, uf, x, f, m in zip(self._ut, self._uf, tl, fl, ml, strict=True)]
        self._x = [x - y for x, y in zip(tl, t0, strict=True)]
        self._y = [x - y for x, y in zip(r, r0, strict=True)]
        return [y - a * x for a, x, y in zip(self._follow, self._x, self._y, strict=True)]

    def learn(self, calm: Sequence[float]) -> None:
        """Fit :attr:`follow` with the last :meth:`update`'s window: per joint whose model torque changed
        by at least :data:`FOLLOW_MIN` and whose judged rise is under ``calm`` (N·m: half its widened
        threshold; a contact is not the model's error), least squares of the estimate's change on the
        model torque's change, older windows forgotten over :data:`FOLLOW_MEMORY` s of them."""
        forget = 1.0 - self._period / FOLLOW_MEMORY
        for i in range(self.n):
            x, y, a = self._x[i], self._y[i], self._follow[i]
            if not (x >= FOLLOW_MIN or x <= -FOLLOW_MIN) or not abs(y - a * x) < calm[i]:
                continue
            sxx = forget * self._sxx[i] + x * x
            sxy = forget * self._sxy[i] + x * y
            self._sxx[i], self._sxy[i] = sxx, sxy
            ut = self._ut[i]
            self._follow[i] = min(ut, max(-ut, sxy / (sxx + FOLLOW_PRIOR)))


class CollisionReflex:
    """Thresholds, the reaction, and when to check (see the module's docstring).

    Args:
        names: joint names, config order.
        observer: the estimate.
        thresholds: N·m per joint, ``None`` where a joint is not checked.
        reaction: ``"disable"`` (damp, then disable: the default) or ``"hold"``.
        fresh: s per joint: feedback older than this is not new this cycle (a reply missed): the
            observer waits for a complete set and then spans the gap, or starts over after
            :data:`RESET_GAP` loop periods (the supervisor judges missing feedback). Default: none is stale.
        period: s, the loop's period.

    Attributes:
        estimate: the latest external torque estimate per joint, N·m (zeros before the first step).
        last: the last :class:`~akarm.CollisionError`, or ``None``.
        armed: whether the next step may stop the arm.
        peak: per joint, the largest judged part of the estimate (its sudden part) while checking since
            :meth:`clear_peak`, as a share of its threshold widened for the model's uncertainty then,
            times the threshold: N·m, under the threshold unless the reflex fired.
    """

    def __init__(self, names: Sequence[str], observer: MomentumObserver,
                 thresholds: Sequence[float | None], reaction: Reaction = "disable",
                 fresh: Sequence[float] | None = None, period: float = 0.002,
                 uncertainty: Sequence[Uncertainty] | None = None) -> None:
        self.names = tuple(names)
        self.reset_gap = RESET_GAP * period
        self.late = 1.5 * period
        self.early = 0.5 * period
        self._after_late = False  # a late cycle came last: start over again at the next that keeps time
        self._q_last = [0.0] * len(self.names)
        self._v_last = [0.0] * len(self.names)
        self.fresh = tuple(math.inf for _ in self.names) if fresh is None else tuple(float(x) for x in fresh)
        self._fresh_min = min(self.fresh, default=math.inf)
        self.observer = observer
        #: the model's error, learnt and removed: what is judged is the estimate's sudden part
        self.residual = ModelResidual(len(self.names), observer.coulomb.tolist(), observer.viscous.tolist(),
                                      observer.deadband.tolist(),
                                      [Uncertainty()] * len(self.names) if uncertainty is None else uncertainty,
                                      observer.gain, period)
        self._sudden = [0.0] * len(self.names)
        self.set_thresholds(thresholds)
        self.set_reaction(reaction)
        self.last: CollisionError | None = None
        self.armed = False
        self._cycle = -math.inf  # the loop time of the last step
        self._sample_last = -math.inf  # when the feedback of the last update was taken
        self._v_des: list[float] | None = None  # the velocity the last cycle commanded
        self._quiet_until = -math.inf  # no judging before (a motor was at its torque limit)
        self._peak = [0.0] * len(self.names)

    @property
    def peak(self) -> np.ndarray:
        return np.array(self._peak)

    @property
    def estimate(self) -> np.ndarray:
        """The observer's :attr:`~MomentumObserver.estimate` (a new array)."""
        return self.observer.estimate

    @property
    def estimate_list(self) -> list[float]:
        """The observer's estimate as floats (a copy): what the loop records every cycle."""
        return self.observer.estimate_list

    def set_thresholds(self, thresholds: Sequence[float | None]) -> None:
        """N·m per joint (``None``: not checked); each positive and finite."""
        th = list(thresholds)
        if len(th) != len(self.names):
            raise ArgumentError(f"{len(th)} collision thresholds for {len(self.names)} joints",
                             fix="one per joint, config order (None where a joint is not checked)")
        for name, x in zip(self.names, th, strict=True):
            if x is not None and not (isinstance(x, int | float) and x > 0 and math.isfinite(x)):
                raise ArgumentError(f"collision threshold {x!r} must be a positive number of N·m, or None",
                                 joint=name, fix="e.g. the threshold `akarm identify` suggests")
        self.thresholds = np.array([math.inf if x is None else float(x) for x in th])
        self._thresholds = self.thresholds.tolist()

    def set_reaction(self, reaction: str) -> None:
        if reaction not in ("disable", "hold"):
            raise ArgumentError(f"collision reaction must be 'disable' or 'hold', got {reaction!r}")
        self.reaction: Reaction = reaction  # type: ignore[assignment]

    @property
    def active(self) -> bool:
        """Whether any joint has a threshold."""
        return bool(np.any(np.isfinite(self.thresholds)))

    def _on_time(self, q: list[float], v: list[float], dt: float) -> bool:
        """Whether the feedback's motion fits the time assumed between the two samples: the fastest
        joint's travel over its mean measured speed gives the time that really passed (a simulator or
        adapter that answered late shows here; the estimate would take the difference for a push).
        Within a period the motion is not exactly of constant acceleration (the commands' steps):
        a millisecond or two position steps of slack."""
        i, v_i, speed = 0, 0.0, -1.0
        for k, (a, b) in enumerate(zip(v, self._v_last, strict=True)):
            m = 0.5 * (a + b)
            if abs(m) > speed:  # the first of the fastest
                i, v_i, speed = k, m, abs(m)
        if speed < 0.3:  # too slow to time (and a timing error matters little then)
            return True
        passed = (q[i] - self._q_last[i]) / v_i
        return abs(passed - dt) <= max(1e-3, 2.0 * _POSITION_STEP / speed)

    def restart(self) -> None:
        """Start the estimate over at the next step (the model changed: a payload, friction): the
        momentum it tracks would otherwise jump by the change of inertia times the velocity. The
        model's error is learnt again (:data:`LEARN_TIME`)."""
        self.observer.started = False
        self.residual.fresh = True
        self.residual.set_model(self.observer.coulomb.tolist(), self.observer.viscous.tolist(),
                                self.residual.uncertainty)

    @property
    def sudden(self) -> np.ndarray:
        """The estimate less its slow part (the model's error): what the thresholds judge, N·m per joint."""
        return np.array(self._sudden)

    @property
    def margin(self) -> np.ndarray:
        """N·m per joint the thresholds grow by now for the model's uncertainty (:class:`ModelResidual`)."""
        return np.array(self.residual.margin)

    def clear_peak(self) -> None:
        self._peak = [0.0] * len(self.names)

    def step(self, now: float, q: Sequence[float], dq: Sequence[float], tau: Sequence[float], check: bool,
             kp: Sequence[float] | None = None, kd: Sequence[float] | None = None,
             stamps: Sequence[float] | None = None, v_des: ArrayLike | None = None,
             model_torque: Sequence[float] | np.ndarray | None = None) -> CollisionError | None:
        """Update the estimate with the feedback of this cycle (and the MIT gains in force: see
        :meth:`MomentumObserver.update`; ``stamps``: when each joint's feedback arrived, s;
        ``v_des``: the velocity this cycle commands, rad/s, ``None`` when not tracking;
        ``model_torque``: the torque the model asked of the motors for the feedback's cycle, N·m (the
        feed-forward; default the reported torque), whose changes the thresholds grow with); with
        ``check``, the error if a joint's estimate is over its threshold. Without ``check`` (teach
        mode) the reflex disarms."""
        qa, va, ta = _floats(q), _floats(dq), _floats(tau)
        # a sum is finite only if every term is (NaN and ±inf carry through): one test for the usual case
        if not math.isfinite(sum(qa, 0.0) + sum(va, 0.0) + sum(ta, 0.0)) and not (
                all(map(math.isfinite, qa)) and all(map(math.isfinite, va)) and all(map(math.isfinite, ta))):
            return None  # no feedback yet: the supervisor deals with missing feedback
        # this cycle's feedback answers the last cycle's command: it was taken then (the drivers reply at once)
        sample, self._cycle = self._cycle, now
        v_then, self._v_des = self._v_des, (None if v_des is None else _floats(v_des))
        # A late cycle: when the feedback was taken is not known, nor, on a machine that stalled as a
        # whole, when the drivers acted on the commands around it. The observer starts over there and
        # again at the next cycle that keeps time, so that no step integrates across the late one. A
        # cycle soon after a late one (the loop catching up): its feedback may still be the last
        # cycle's reply, or one taken at any time since; it is not used at all.
        if now - sample > self.late:
            self.observer.started = False
            self._after_late = True
        elif now - sample < self.early:
            return None
        elif self._after_late:
            self.observer.started = False
            self._after_late = False
        # (every joint's feedback is fresh when the oldest is fresh by the tightest limit: the usual case)
        if stamps is not None and now - min(stamps, default=now) > self._fresh_min and any(
                now - s > f for s, f in zip(stamps, self.fresh, strict=True)):
            return None  # a joint without new feedback: wait for a complete set (the next step spans the gap)
        obs = self.observer
        dt = sample - self._sample_last
        self._sample_last = sample
        res = self.residual
        if not obs.started or not 0 < dt <= self.reset_gap or not self._on_time(qa, va, dt):
            # (from the estimate before: the model's error is a function of the pose, not of the gap)
            obs.reset(qa, va, ta, v_then, None if res.fresh else obs.estimate_list)
            res.start(now, obs.estimate_list, ta if model_torque is None else model_torque,
                      va if v_then is None else v_then, ta, va)
            self._sudden = [0.0] * len(qa)
        else:
            obs.advance(qa, va, ta, dt, kp, kd, v_then)
            # (friction's regressors on the commanded speed where the arm tracks one: the measured one
            # flips across the deadband at rest, by whole steps of the feedback)
            self._sudden = res.update(now, obs.estimate_list, ta if model_torque is None else model_torque,
                                      va if v_then is None else v_then, dt, ta, va)
        self._q_last, self._v_last = qa, va
        if not check or now < res.learning_until:
            self.armed = False
            return None
        err = self._judge(now, ta)
        # the model's error learnt where nothing is judged a contact (armed: every joint was calm once;
        # not at a motor's torque limit, where the torque is not known)
        if err is None and self.armed and not res.frozen and now >= self._quiet_until:
            res.learn([0.5 * (t + m) for t, m in zip(self._thresholds, res.margin, strict=True)])
        return err

    def _judge(self, now: float, tau: list[float]) -> CollisionError | None:
        """The step's verdict on the new estimate, the motors reporting ``tau`` (N·m)."""
        obs = self.observer
        # a motor at its limit: within a period its torque is not known
        if obs.at_limit(tau):
            self._quiet_until = now + 2.0 / obs.gain
        if now < self._quiet_until:
            return None
        # one pass: the peaks, whether any joint is over its threshold (grown by the model's uncertainty
        # now), whether all are under half of it
        peak, thresholds, margin = self._peak, self._thresholds, self.residual.margin
        over = -1
        calm = True
        for i, x in enumerate(self._sudden):
            m = x if x >= 0.0 else -x
            th = thresholds[i] + margin[i]
            seen = m * thresholds[i] / th  # (as a share of the widened threshold, in N·m of the file's)
            if seen > peak[i]:
                peak[i] = seen
            if m > th and (over < 0 or m / th > abs(self._sudden[over]) / (thresholds[over] + margin[over])):
                over = i
            if not m < 0.5 * th:
                calm = False
        if not self.armed:
            self.armed = calm
            if calm:
                self.residual.frozen = False
            return None
        if over < 0:
            k = self._over_level(thresholds)
            if k < 0:
                return None
            torque = obs.estimate_list[k]
            grown = f" + {self.residual.level_margin[k]:.2f} N·m for the model's uncertainty"
            what = (f"collision: an external torque that built up to {torque:+.2f} N·m (threshold "
                    f"{thresholds[k]:.2f} N·m{grown}); ")
        else:
            k = over
            torque = self._sudden[k]
            grown = f" + {margin[k]:.2f} N·m for the model's uncertainty" if margin[k] >= 0.005 else ""
            what = (f"collision: a sudden external torque of {torque:+.2f} N·m (threshold {thresholds[k]:.2f} "
                    f"N·m{grown}; the model's slow error {self.residual.slow[k]:+.2f} N·m set aside); ")
        err = CollisionError(
            what + ("the arm was damped and disabled" if self.reaction == "disable" else
                    "the arm was brought to rest and holds there"),
            torque=float(torque), threshold=float(thresholds[k]), reaction=self.reaction, joint=self.names[k],
            fix="clear the obstacle (move the arm away from it); if nothing was hit, check the payload "
                "(arm.set_payload), run `akarm identify`, or raise the joint's collision threshold")
        err.at = now
        self.last = err
        self.armed = False
        self.residual.frozen = True  # re-armed once the contact has ended: the estimate back to where it was
        return err

    def _over_level(self, thresholds: Sequence[float]) -> int:
        """The joint whose whole estimate is furthest over its threshold widened by the model's uncertainty
        at the model's torque now (:attr:`ModelResidual.level_margin`), or -1: a contact slower than the
        window, which the sudden part does not show."""
        k, worst = -1, 1.0
        for i, (x, th, lm) in enumerate(zip(self.observer.estimate_list, thresholds, self.residual.level_margin,
                                            strict=True)):
            ratio = abs(x) / (th + lm)
            if ratio > worst:
                k, worst = i, ratio
        return k


def reflex_for(config: RobotConfig, model: RobotModel, gain: float = DEFAULT_GAIN, reaction: Reaction = "disable",
               watch_only: bool = False) -> CollisionReflex:
    """The reflex for ``config`` (its joints' friction and thresholds, its loop rate) on ``model`` (the
    payload included): the observer's gain ``K`` at most ``gain``, its discrete loop gain ``K·dt`` at
    most 0.25 (a slow loop gets a slower estimate); ``watch_only``: no joint checked (a timing profile for
    machines that cannot keep time: the estimate would take the time it does not see for a push)."""
    fr = [j.friction_model() for j in config.joints]
    observer = MomentumObserver(model, [f.coulomb for f in fr], [f.viscous for f in fr], [f.offset for f in fr],
                                min(gain, 0.25 * config.rate_hz), [velocity_resolution(j) for j in config.joints],
                                [j.motor.t_max for j in config.joints])
    observer.set_torque_scale([f.torque_scale for f in fr])
    # a joint's feedback is new when it came this cycle (MIT: a reply per command), or within 1.5 status periods
    fresh = [0.5 / config.rate_hz if j.mode == "mit" else max(0.5 / config.rate_hz, 1.5 / j.status_rate_hz)
             for j in config.joints]
    thresholds = [None if watch_only else j.collision_threshold for j in config.joints]
    return CollisionReflex(config.joint_names, observer, thresholds, reaction, fresh, 1.0 / config.rate_hz,
                           [uncertainty_for(j) for j in config.joints])
