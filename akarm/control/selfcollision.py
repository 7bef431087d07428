"""The supervisor's self-collision check: two of the arm's links measured touching.

The planner and servoing keep the *command* clear by the robot file's ``self_collision: {margin: ...}``
(:mod:`akarm.dynamics.selfcollision`); tracking error and a push move the measured pose away from it.
Every :attr:`SelfCollisionGuard.every`-th cycle of an active arm (about :data:`RATE` Hz), the guard
puts the links' shapes where the *measured* joint positions put them; two shapes touching (closer than
0, the margin used up) while the command's do not is a :class:`~akarm.SelfCollisionStop` safety stop.
An arm enabled folded into itself (a limp arm falls onto a hard stop where its housings touch) may move
out: from an enable (:meth:`SelfCollisionGuard.disarm`) the guard judges nothing until the measured pose
was clear once, since the reading trails the command out of contact. A check takes 10-20 µs (arm6: 51 pairs; see
benchmarks/bench_compliance.py), a few µs a cycle on average.
"""

from __future__ import annotations

from collections.abc import Sequence

from akarm.dynamics.selfcollision import SelfCollision
from akarm.errors import SelfCollisionStop

__all__ = ["RATE", "SelfCollisionGuard"]

#: Hz: about how often the measured pose is checked (every cycle of a loop slower than this)
RATE = 120.0


class SelfCollisionGuard:
    """The self-collision check of one arm (loop thread: ``check`` is the loop's own copy, margin 0).

    Args:
        check: the shapes, with the margin at which they count as touching (0: contact).
        rate_hz: the loop's rate; the guard checks every ``ceil(rate_hz / RATE)``-th cycle.
        margin: m, the planner's margin (said in the stop's message).
    """

    def __init__(self, check: SelfCollision, rate_hz: float, margin: float) -> None:
        self.check = check
        self.every = max(1, round(rate_hz / RATE))
        self.margin = margin
        self.checks = 0  # checks made (for tests and benchmarks)
        #: the measured pose was clear at a check since :meth:`disarm` (a contact is judged only then)
        self.armed = True
        self._k = 0

    def disarm(self) -> None:
        """(An enable begins) Judge no contact until the measured pose is clear once: an arm enabled in
        contact with itself moves out with its reading behind its command."""
        self.armed = False

    def step(self, now: float, q: Sequence[float], q_des: Sequence[float]) -> SelfCollisionStop | None:
        self._k += 1
        if self._k < self.every:
            return None
        self._k = 0
        self.checks += 1
        check = self.check
        if not check.collides(q):
            self.armed = True
            return None
        if not self.armed or check.collides(q_des):
            return None  # the command is in collision too (enabled there): let it move out
        pair = check.colliding(q)
        a, b = pair[0] if pair else ("?", "?")
        stop = SelfCollisionStop(
            f"the arm was measured with {a} touching {b} while its command kept them {self.margin * 1e3:.0f} mm "
            "apart: pushed into itself, or far behind its command; the arm was damped and disabled",
            pair=(a, b), q=tuple(float(x) for x in q),
            fix="find what pushed the arm (or what held it), enable it again and move it out (move_to a named pose)")
        stop.at = now
        return stop
