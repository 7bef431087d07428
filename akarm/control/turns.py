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
"""

from __future__ import annotations

import json
import math
import os
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from akarm.config import JointConfig
from akarm.errors import AkarmError, TurnCountLost
from akarm.files import FileProblem, atomic_write, read_text

__all__ = ["MAX_STATE_BYTES", "TOLERANCE", "PositionMemory", "TurnJump", "find_jump", "state_file", "tolerance",
           "turn_step"]

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


def state_file(robot: str, environ: Mapping[str, str] | None = None, *, simulator: bool = False) -> Path:
    """Where robot ``robot``'s positions are remembered: ``$XDG_STATE_HOME/akarm/positions/ROBOT.json``
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
