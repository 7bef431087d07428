"""Turn counts lost at power-up: remember where each joint was when the arm stopped, compare at enable.

An AK driver knows its output position only within one turn of its rotor: after a power cycle the
multi-turn count is gone and the joint may read off by ``k · 2π / gear ratio`` (40° on an AK10-9,
60° on an AK60-6). Inside the joint's range such a reading passes every other check.

So akarm remembers each joint's last measured position when the arm stops (a disable or a safety
stop), in a small state file per robot (:func:`state_file`), written atomically
(:func:`akarm.files.atomic_write`), and forgets it when the arm is enabled (while enabled, where the
arm ends is not known until it stops). At the next enable, once every joint has answered and before
any command with gains or torque is sent, :meth:`PositionMemory.check` compares each reading with the
remembered position: a difference within :func:`tolerance` of ``k`` rotor turns, ``k ≠ 0``, refuses
the enable with :class:`~akarm.errors.TurnCountLost`. Where exactly one ``k`` puts the joint back
inside its range near the remembered position, the error suggests it; nothing is ever corrected.

A difference that is not near a whole number of turns is a joint moved by hand while limp: passed.

A joint gravity moves while limp is not remembered (it may lie anywhere at the next enable, a whole
number of turns away too): physics checks it instead (:class:`GravityTurnCheck`). While the enable
holds the arm where it stands (kp ramping up, the gravity feed-forward at the readings, no motion
commanded), the torque that holds it is what the model's gravity asks at the joints' true pose,
within their friction. Where it is clearly not what gravity asks at the readings, but is what it asks
with a joint ``k`` rotor turns from its reading, the enable is refused with
:class:`~akarm.errors.TurnCountLost` before anything else is commanded. A joint whose torque does not
change by a turn (near its gravity-neutral pose, or a joint whose axis is vertical) cannot be told:
the check says so in the log (and such a joint, if it stays put while limp, is remembered).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akarm.config import JointConfig, RobotConfig
from akarm.control.collision import uncertainty_for
from akarm.errors import AkarmError, TurnCountLost
from akarm.files import FileProblem, atomic_write, read_text

__all__ = ["MAX_STATE_BYTES", "TOLERANCE", "GravityTurnCheck", "PositionMemory", "TurnJump", "Weighed", "Weighing",
           "arm_key", "find_jump", "state_file", "tolerance", "turn_step"]

#: rad at the joint: how far a limp joint may have moved (sagged, been nudged) between a stop and the
#: next enable and still count as "where it was"; never more than a quarter of a turn step.
TOLERANCE = 0.05
#: bytes of a state file akarm reads (a few lines per joint).
MAX_STATE_BYTES = 64 * 1024
#: how many rotor turns either way a suggestion looks at.
_SEARCH = 64


#: share of a joint's torque limit its own friction and cogging hold limp, when its friction is not
#: known (an AK drive's gearbox is backdrivable: a limp joint under more load than that moves).
LIMP_HOLD_SHARE = 0.02


def stays_put(gravity: float, coulomb: float, torque_limit: float) -> bool:
    """True when a limp joint with ``gravity`` N·m on it stays where it is (its Coulomb friction, or
    :data:`LIMP_HOLD_SHARE` of its torque limit, holds it): only such a joint's position is remembered.
    One that gravity moves may lie anywhere at the next enable, a whole number of turns away too (a
    limp elbow that fell 40° reads as an AK80-9 that lost a turn): it is not compared."""
    return abs(gravity) <= max(coulomb, LIMP_HOLD_SHARE * torque_limit)


def turn_step(joint: JointConfig) -> float:
    """rad at the joint of one rotor turn: ``2π / gear ratio``."""
    return 2.0 * math.pi / float(joint.motor.gear_ratio)


def tolerance(joint: JointConfig) -> float:
    """rad: a reading within this of ``k`` turns from the remembered position has lost ``k`` turns."""
    return min(TOLERANCE, turn_step(joint) / 4.0)


@dataclass(frozen=True)
class TurnJump:
    """A joint whose reading lies ``turns`` rotor turns from where it was remembered.

    Attributes:
        joint: its name. reading: rad now. remembered: rad when the arm last stopped.
        turns: ``k``, ``reading - remembered ≈ k · step``. step: rad of one rotor turn.
        suggested: the one reading ``reading - k' · step`` inside the range near the remembered
            position, when exactly one ``k'`` gives it (else ``None``).
    """

    joint: str
    reading: float
    remembered: float
    turns: int
    step: float
    suggested: float | None

    def error(self) -> TurnCountLost:
        """The :class:`~akarm.errors.TurnCountLost` refusing the enable."""
        deg = math.degrees(self.turns * self.step)
        what = (f"reads {self.reading:+.3f} rad but was at {self.remembered:+.3f} rad when the arm last stopped: "
                f"{self.turns:+d} rotor turn{'s' if abs(self.turns) != 1 else ''} ({deg:+.0f}°) off, as after a "
                "power cycle of its driver; nothing was enabled")
        if self.suggested is not None:
            what += f"; it most likely stands at {self.suggested:+.3f} rad (the reading less {self.turns:+d} turns)"
        return TurnCountLost(what, reading=self.reading, remembered=self.remembered, turns=self.turns,
                             joint=self.joint,
                             fix="put the joint at its reference and run `akarm zero` for it, or check by eye "
                                 "where it stands and run `akarm enable --accept-position` "
                                 "(Arm.enable(accept_position=True))")


def find_jump(joint: JointConfig, reading: float, remembered: float) -> TurnJump | None:
    """The turns ``joint`` lost between ``remembered`` and ``reading`` (rad), or ``None`` (none, or the
    difference is not near a whole number of turns: the joint was moved)."""
    step, tol = turn_step(joint), tolerance(joint)
    d = reading - remembered
    if not (math.isfinite(d) and abs(d) < (_SEARCH + 0.5) * step):
        return None
    k = round(d / step)
    if k == 0 or abs(d - k * step) > tol:
        return None
    lo, hi = joint.limits.lower, joint.limits.upper
    fits = [kk for kk in range(-_SEARCH, _SEARCH + 1)
            if lo - tol <= reading - kk * step <= hi + tol and abs(reading - kk * step - remembered) <= tol]
    suggested = reading - fits[0] * step if len(fits) == 1 else None
    return TurnJump(joint.name, reading, remembered, k, step, suggested)


def arm_key(config: RobotConfig, arm_id: str | None = None) -> str:
    """The name one physical arm's positions are remembered under (:func:`state_file`): ``id-ARM_ID``
    when ``arm_id`` is given (the user names the arm, as LeRobot's ``--robot.id``), else the robot file's
    name and where its motors are: each bus's interface and channel, and a digest of every joint's bus,
    channel and CAN ID (``arm6@socketcan-can0-1a2b3c4d``). Two arms of one robot file on two channels
    are two arms: neither is judged by the other's positions."""
    if arm_id is not None:
        return f"id-{arm_id}"
    where = "+".join(f"{b.interface}-{b.channel}" for _, b in sorted(config.buses.items()))
    wiring = ";".join(f"{j.name}={config.buses[j.bus].interface}:{config.buses[j.bus].channel}:{j.can_id}"
                      for j in config.joints)
    return f"{config.name}@{where}-{hashlib.sha256(wiring.encode()).hexdigest()[:8]}"


def state_file(robot: str, environ: Mapping[str, str] | None = None, *, simulator: bool = False) -> Path:
    """Where the arm keyed ``robot`` (:func:`arm_key`) remembers its positions:
    ``$XDG_STATE_HOME/akarm/positions/ROBOT.json``
    (``~/.local/state/akarm/positions/ROBOT.json`` without XDG_STATE_HOME); ``simulator``: ``ROBOT.sim.json``
    beside it (a simulated arm never writes, nor is judged against, the real arm's positions)."""
    env = os.environ if environ is None else environ
    base = env.get("XDG_STATE_HOME") or ""
    root = Path(base) if os.path.isabs(base) else Path.home() / ".local" / "state"
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", robot).lstrip(".") or "robot"
    return root / "akarm" / "positions" / f"{safe}{'.sim' if simulator else ''}.json"


class PositionMemory:
    """The state file of one robot: what it remembers, checked against readings, and written again.

    Args:
        path: the state file. joints: the robot's joints, config order.
    """

    def __init__(self, path: str | os.PathLike[str], joints: Sequence[JointConfig]) -> None:
        self.path = Path(path)
        self.joints = list(joints)

    def load(self) -> dict[str, float]:
        """Joint name → remembered position, rad; empty when nothing is remembered.

        Raises:
            AkarmError: the file is there but unreadable or not a state file (names it; the fix says
                to delete it after checking the arm).
        """
        try:
            text = read_text(self.path, MAX_STATE_BYTES, what="position state file", name="MAX_STATE_BYTES")
        except FileProblem as e:
            if not self.path.exists():
                return {}
            raise self._bad(e.what) from None
        try:
            doc = json.loads(text)
            positions = doc["positions"]
            out = {str(k): float(v) for k, v in positions.items()}
        except (ValueError, TypeError, KeyError, AttributeError):
            raise self._bad("it is not a position state file") from None
        return {k: v for k, v in out.items() if math.isfinite(v)}

    def _bad(self, why: str) -> AkarmError:
        return AkarmError(f"cannot read the remembered joint positions in {self.path}: {why}",
                          fix="check where each joint stands, then delete the file (the next stop writes it again)")

    def check(self, readings: Sequence[float], remembered: Mapping[str, float]) -> TurnCountLost | None:
        """The error for the first joint whose reading (rad, config order) lies whole rotor turns from
        its ``remembered`` position (:meth:`load`'s), or ``None``."""
        for j, q in zip(self.joints, readings, strict=True):
            if j.name in remembered:
                jump = find_jump(j, q, remembered[j.name])
                if jump is not None:
                    return jump.error()
        return None

    def save(self, positions: Mapping[str, float]) -> None:
        """Remember ``positions`` (joint name → rad; the others are forgotten), atomically.

        Raises:
            RecordingError: the file cannot be written.
        """
        doc = {"robot_positions": 1, "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
               "positions": {k: float(v) for k, v in positions.items() if math.isfinite(v)}}
        data = (json.dumps(doc, indent=1) + "\n").encode()
        atomic_write(self.path, lambda f: f.write(data))

    def update(self, joint: str, position: float) -> None:
        """Remember ``position`` (rad) for ``joint`` (zeroed: it reads anew), if a position is remembered
        for it; an unreadable file is left for the next enable to name.

        Raises:
            RecordingError: the file cannot be written.
        """
        try:
            remembered = self.load()
        except AkarmError:
            return
        if joint in remembered:
            remembered[joint] = position
            self.save(remembered)

    def forget(self) -> None:
        """Remember nothing (the arm is enabled: where it will stop is not known yet)."""
        if self.path.exists():
            self.save({})


_FIX = ("put the joint at its reference and run `akarm zero` for it, or check by eye where it stands and run "
        "`akarm enable --accept-position` (Arm.enable(accept_position=True))")

#: share of a joint's torque limit added to its Coulomb friction for what a holding torque may differ
#: from the model's gravity and still be explained by it (the model's and the payload's error, the
#: torque field's resolution, a little motion): the band of :class:`GravityTurnCheck`.
WEIGH_SHARE = 0.02
#: a turn explains the holding torque "clearly better" than the readings when the readings leave it
#: outside the band on some joint and the turn fits it at least this many bands better.
WEIGH_CLEAR = 0.5
#: rad past a joint's mechanical range (the URDF's limits: its hard stops, which give a little) where a
#: joint may stand; a reading further out than that, by about a whole number of turns, is a lost turn
#: count at once (:meth:`GravityTurnCheck.out_of_range`).
WEIGH_RANGE_MARGIN = 0.1
#: rad: a joint this near its hard stop (or past it) may rest on it: the stop carries what gravity presses
#: onto it, so its torque may be anything from the model's gravity towards the stop.
WEIGH_STOP = 0.05
#: the most rotor turns either way :class:`GravityTurnCheck` looks at.
WEIGH_TURNS = 8
#: the most combinations of turns on several joints it tries (each costs a gravity evaluation).
WEIGH_COMBINATIONS = 400
#: rad/s: the arm is weighed once every joint is slower than this (held with its full gains, a joint
#: a turn off first moves until its PD takes the load: a light-damped arm swings for a while).
WEIGH_REST_SPEED = 0.03
#: s the arm must stay that slow before it is weighed, and s over which it is weighed (the mean of the
#: readings; a faster joint meanwhile starts it over).
WEIGH_DWELL = 0.05
WEIGH_WINDOW = 0.05
#: s after the gains are in by which the arm must have come to rest to be weighed (plus the timing
#: profile's lag); one still moving then is not weighed (the log says so).
WEIGH_TIMEOUT = 2.0


@dataclass(frozen=True)
class Weighed:
    """What :meth:`GravityTurnCheck.judge` found.

    Attributes:
        error: the :class:`~akarm.errors.TurnCountLost` refusing the enable, or ``None``.
        undecided: the joints a lost turn of which the torque cannot tell at this pose (gravity asks the
            same, within the band, with the joint a whole number of turns away).
        unexplained: the holding torque is not what gravity asks at the readings, nor with any joint
            whole turns away (a payload akarm does not know, an obstacle): not judged here.
        off: bands the torque lies off what gravity asks at the readings (the largest over the joints;
            at most 1: explained).
    """

    error: TurnCountLost | None
    undecided: tuple[str, ...] = ()
    unexplained: bool = False
    off: float = 0.0


class GravityTurnCheck:
    """Whether the torque holding the arm at rest says a joint stands whole rotor turns from its reading.

    Args:
        joints: the robot's joints, config order.
        gravity: ``gravity(q)``: the model's gravity torques at ``q`` (rad, config order), N·m, with the
            payload akarm knows.
        checked: per joint, whether its torque is known (MIT joints): only those are compared.
        lower, upper: the joints' mechanical range (the URDF's limits, where the hard stops are), rad;
            default: the robot file's limits.

    A joint's torque at rest is the model's gravity within its band: its Coulomb friction plus
    :data:`WEIGH_SHARE` of its torque limit, plus the model's uncertainty share of that gravity torque
    (:func:`~akarm.control.collision.uncertainty_for`: a real unit is not its model). The readings explain the
    torque when every checked joint is within its band; a hypothesis (joint ``i`` ``k`` turns from its
    reading: it stands at ``reading - k·step``) explains it likewise. A joint at (or near) a hard stop may
    rest on it: its torque may then lie anywhere from gravity's towards the stop (:data:`WEIGH_STOP`). The
    enable is refused when the readings do not explain the torque (outside the band on some joint) and a
    hypothesis does, :data:`WEIGH_CLEAR` bands better at least: each joint alone first (the fewest turns that
    explain it are named, the others listed), then combinations over the joints a turn changes the torque of.
    """

    def __init__(self, joints: Sequence[JointConfig], gravity: Callable[[np.ndarray], np.ndarray],
                 checked: Sequence[bool], lower: Sequence[float] | np.ndarray | None = None,
                 upper: Sequence[float] | np.ndarray | None = None) -> None:
        self.joints = list(joints)
        self._gravity = gravity
        self.checked = [i for i, c in enumerate(checked) if c]
        self.band = np.array([j.friction_model().coulomb + WEIGH_SHARE * j.limits.torque for j in self.joints])
        # and a share of gravity's torque: a real unit's torque constant, reported-to-true torque and link
        # masses differ from the model's (akarm.control.collision.Uncertainty; less once identified)
        self.share = np.array([uncertainty_for(j).torque for j in self.joints])
        self.step = [turn_step(j) for j in self.joints]
        self.lower = np.array([j.limits.lower for j in self.joints] if lower is None else lower, dtype=float)
        self.upper = np.array([j.limits.upper for j in self.joints] if upper is None else upper, dtype=float)

    def candidates(self, i: int, reading: float) -> list[int]:
        """The turns ``k ≠ 0`` that put joint ``i`` (reading ``reading``, rad) inside its mechanical
        range (and a little past it: :data:`WEIGH_RANGE_MARGIN`), nearest first."""
        step = self.step[i]
        lo, hi = self.lower[i] - WEIGH_RANGE_MARGIN, self.upper[i] + WEIGH_RANGE_MARGIN
        ks = [k for k in range(-WEIGH_TURNS, WEIGH_TURNS + 1) if k and lo <= reading - k * step <= hi]
        return sorted(ks, key=lambda k: (abs(k), k))

    def out_of_range(self, q: Sequence[float]) -> TurnCountLost | None:
        """The error for the first joint whose reading (rad) lies past its hard stop (by more than
        :data:`WEIGH_RANGE_MARGIN`) where a whole number of turns puts it inside: no joint can stand
        there, so its driver lost its turn count (known before any torque is sent)."""
        for i, j in enumerate(self.joints):
            x = float(q[i])
            if not math.isfinite(x) or self.lower[i] - WEIGH_RANGE_MARGIN <= x <= self.upper[i] + WEIGH_RANGE_MARGIN:
                continue
            ks = self.candidates(i, x)
            if not ks:
                continue
            k, step = ks[0], self.step[i]
            also = f" (or {', '.join(f'{kk:+d}' for kk in ks[1:])} turns)" if len(ks) > 1 else ""
            what = (f"reads {x:+.3f} rad, past its hard stop ({self.lower[i]:+.3f} to {self.upper[i]:+.3f} rad), "
                    f"where it cannot stand: {k:+d} rotor turn{'s' if abs(k) != 1 else ''}{also} "
                    f"({math.degrees(k * step):+.0f}°) off, as after a power cycle of its driver; it most likely "
                    f"stands at {x - k * step:+.3f} rad; nothing was enabled")
            return TurnCountLost(what, reading=x, remembered=math.nan, turns=k, joint=j.name, fix=_FIX,
                                 alternatives=tuple(ks[1:]))
        return None

    def _ratio(self, tau: np.ndarray, g: np.ndarray, q: np.ndarray) -> float:
        """The largest residual ``tau - g`` over the checked joints in bands; a joint on a hard stop at
        ``q`` only counts one that the stop cannot carry."""
        idx = self.checked
        if not idx:
            return 0.0
        e = tau[idx] - g[idx]
        qi = q[idx]
        # at the upper stop the stop pushes down: the motor may hold more than gravity asks; at the lower, less
        e = np.where(qi >= self.upper[idx] - WEIGH_STOP, np.minimum(e, 0.0), e)
        e = np.where(qi <= self.lower[idx] + WEIGH_STOP, np.maximum(e, 0.0), e)
        return float(np.max(np.abs(e) / (self.band[idx] + self.share[idx] * np.abs(g[idx]))))

    def _pose(self, q: np.ndarray, turns: Mapping[int, int]) -> np.ndarray:
        qk = q.copy()
        for i, k in turns.items():
            qk[i] -= k * self.step[i]
        return qk

    def _explains(self, tau: np.ndarray, q: np.ndarray, turns: Mapping[int, int]) -> tuple[float, np.ndarray]:
        """How well joints ``turns`` turns from their readings ``q`` explain ``tau`` (bands off), and the
        gravity torques there."""
        qk = self._pose(q, turns)
        g = np.asarray(self._gravity(qk), dtype=float)
        return self._ratio(tau, g, qk), g

    def judge(self, q: Sequence[float] | np.ndarray, tau: Sequence[float] | np.ndarray) -> Weighed:
        """The verdict on the arm held at rest at readings ``q`` (rad) with torques ``tau`` (N·m)."""
        qa, ta = np.asarray(q, dtype=float), np.asarray(tau, dtype=float)
        if not (np.all(np.isfinite(qa)) and np.all(np.isfinite(ta))) or not self.checked:
            return Weighed(None)
        r0, g0 = self._explains(ta, qa, {})
        found: list[tuple[float, dict[int, int], np.ndarray]] = []  # the single turns that explain it
        undecided: list[str] = []
        sensitive: dict[int, list[int]] = {}
        for i in self.checked:
            for k in self.candidates(i, float(qa[i])):
                rk, gk = self._explains(ta, qa, {i: k})
                if np.max(np.abs(gk - g0)[self.checked] / self.band[self.checked]) > 1.0:
                    sensitive.setdefault(i, []).append(k)
                if rk <= 1.0:
                    found.append((rk, {i: k}, gk))
                    if r0 <= 1.0 and self.joints[i].name not in undecided:
                        undecided.append(self.joints[i].name)
        if r0 <= 1.0:
            return Weighed(None, tuple(undecided), off=r0)
        if not found and len(sensitive) > 1:
            combo = self._combinations(qa, ta, sensitive)
            if combo is not None:
                found.append(combo)
        found = [f for f in found if f[0] <= r0 - WEIGH_CLEAR]  # clearly better only
        if not found:
            return Weighed(None, (), unexplained=True, off=r0)
        # the fewest turns that explain the torque (then the best fit) are named; the others listed
        found.sort(key=lambda f: (sum(abs(k) for k in f[1].values()), f[0]))
        _, turns, g = found[0]
        named = next(iter(turns)) if len(turns) == 1 else None
        same = [f[1][named] for f in found[1:] if named is not None and set(f[1]) == {named}]
        elsewhere = [", ".join(f"{self.joints[x].name} {k:+d}" for x, k in f[1].items())
                     for f in found[1:] if named is None or set(f[1]) != {named}]
        return Weighed(self._error(qa, ta, g0, turns, g, same, elsewhere[:3]), off=r0)

    def _combinations(self, q: np.ndarray, tau: np.ndarray,
                      sensitive: Mapping[int, list[int]]) -> tuple[float, dict[int, int], np.ndarray] | None:
        """The best combination of turns on several joints that explains ``tau``, or ``None``."""
        joints = list(sensitive)
        options = [[0, *sensitive[i]] for i in joints]
        if math.prod(len(o) for o in options) > WEIGH_COMBINATIONS:  # the nearest turns only
            options = [o[:3] for o in options]
        best = None
        combos: list[list[int]] = [[]]
        for o in options:
            combos = [[*c, k] for c in combos for k in o]
        for c in combos[:WEIGH_COMBINATIONS]:
            turns = {i: k for i, k in zip(joints, c, strict=True) if k}
            if len(turns) < 2:  # (the single ones were tried)
                continue
            r, g = self._explains(tau, q, turns)
            if r <= 1.0 and (best is None or r < best[0]):
                best = (r, turns, g)
        return best

    def _error(self, q: np.ndarray, tau: np.ndarray, g0: np.ndarray, turns: Mapping[int, int],
               g: np.ndarray, alternatives: Sequence[int] = (), elsewhere: Sequence[str] = ()) -> TurnCountLost:
        i = max(turns, key=lambda x: abs(g[x] - g0[x]) / self.band[x])  # the joint whose torque says it most
        k, step = turns[i], self.step[i]
        deg = math.degrees(k * step)
        name = self.joints[i].name
        what = (f"held at rest at {q[i]:+.3f} rad, it takes {tau[i]:+.2f} N·m where the model's gravity asks "
                f"{g0[i]:+.2f} N·m at the readings, and {g[i]:+.2f} N·m with it {k:+d} rotor "
                f"turn{'s' if abs(k) != 1 else ''} ({deg:+.0f}°) back, at {q[i] - k * step:+.3f} rad: its driver "
                "most likely lost its turn count (a power cycle)")
        if alternatives:
            what += f" ({', '.join(f'{x:+d}' for x in alternatives)} turns explain it too)"
        if elsewhere:
            what += f" (so would turns lost on another joint: {'; '.join(elsewhere)})"
        others = [f"{self.joints[x].name} {kk:+d}" for x, kk in turns.items() if x != i]
        if others:
            what += f", and so did {', '.join(others)} turns"
        what += "; nothing but holding was commanded, the arm was lowered and disabled"
        return TurnCountLost(what, reading=float(q[i]), remembered=math.nan, turns=k, joint=name,
                             measured=float(tau[i]), expected=float(g0[i]), explained=float(g[i]),
                             alternatives=tuple(alternatives),
                             fix=_FIX + "; a payload other than the one akarm knows (arm.set_payload) changes the "
                                        "holding torque too")


class Weighing:
    """The torque holding the arm, weighed once the gains are in: once every joint has been slower than
    :data:`WEIGH_REST_SPEED` for :data:`WEIGH_DWELL` s (after ``lag``, the timing profile's: readings
    trail on a slow machine), the mean of the readings over :data:`WEIGH_WINDOW` s; given up after
    :data:`WEIGH_TIMEOUT` s (:attr:`at_rest` false)."""

    def __init__(self, n: int, lag: float = 0.0) -> None:
        self.lag = lag
        self.t0 = math.nan  # the gains are in
        self._still = math.nan  # every joint slow since
        self._q = np.zeros(n)
        self._tau = np.zeros(n)
        self.count = 0
        self.at_rest = False

    def sample(self, now: float, q: Sequence[float], dq: Sequence[float], tau: Sequence[float]) -> bool:
        """Take this cycle's readings (the gains are in); ``True`` once weighed, or given up."""
        if math.isnan(self.t0):
            self.t0 = now
        if now - self.t0 > WEIGH_TIMEOUT + self.lag:
            return True
        if now - self.t0 < self.lag - 1e-9:
            return False
        if max((abs(x) for x in dq), default=0.0) >= WEIGH_REST_SPEED:
            self._still = math.nan
            self.count = 0
            self._q[:] = 0.0
            self._tau[:] = 0.0
            return False
        if math.isnan(self._still):
            self._still = now
        if now - self._still < WEIGH_DWELL - 1e-9:
            return False
        self._q += np.asarray(q, dtype=float)
        self._tau += np.asarray(tau, dtype=float)
        self.count += 1
        self.at_rest = now - self._still >= WEIGH_DWELL + WEIGH_WINDOW - 1e-9
        return self.at_rest

    @property
    def q(self) -> np.ndarray:
        """The mean reading, rad."""
        return self._q / max(1, self.count)

    @property
    def tau(self) -> np.ndarray:
        """The mean torque, N·m."""
        return self._tau / max(1, self.count)
