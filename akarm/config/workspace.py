"""Walls: the region of the base frame the tool frame's origin must stay in (the robot file's ``workspace:``).

A :class:`Workspace` is boxes (the tool inside any one of them) and half-spaces (the tool on the
inner side of every plane). It only does geometry, in metres, on points: the planner refuses a path
that leaves it (:func:`akarm.motion.walls.check_path`), the supervisor stops an arm measured outside
it by more than :attr:`Workspace.margin`, servoing slows to a stop before its walls.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_WALL_MARGIN", "Box", "Plane", "Workspace"]

#: m a measured tool position may be outside the workspace before the supervisor stops the arm
#: (the planner and servoing keep the *commanded* pose inside; tracking error and a push take it out)
DEFAULT_WALL_MARGIN = 0.02

Point = Sequence[float] | np.ndarray


@dataclass(frozen=True)
class Box:
    """An axis-aligned box of the base frame: ``lower`` and ``upper`` corners, m."""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]

    def outside(self, p: Point) -> float:
        """How far ``p`` is outside the box, m (0 inside)."""
        d = 0.0
        for x, lo, hi in zip(p, self.lower, self.upper, strict=True):
            e = lo - x if x < lo else (x - hi if x > hi else 0.0)
            d += e * e
        return math.sqrt(d)

    def faces(self, p: Point) -> list[tuple[float, np.ndarray]]:
        """Each face as (how far ``p`` is inside it, m; its outward unit normal)."""
        out = []
        for axis in range(3):
            n = np.zeros(3)
            n[axis] = 1.0
            out.append((self.upper[axis] - float(p[axis]), n))
            out.append((float(p[axis]) - self.lower[axis], -n))
        return out


@dataclass(frozen=True)
class Plane:
    """A wall: the tool stays where ``normal · p ≤ offset`` (``normal`` points out of the workspace;
    stored as a unit vector, ``offset`` in m)."""

    normal: tuple[float, float, float]
    offset: float

    def outside(self, p: Point) -> float:
        """How far ``p`` is past the plane, m (0 on its inner side)."""
        n = self.normal
        return max(0.0, n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - self.offset)

    def face(self, p: Point) -> tuple[float, np.ndarray]:
        n = self.normal
        return self.offset - (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]), np.array(n, dtype=float)


@dataclass(frozen=True)
class Workspace:
    """Where the tool frame's origin may be: inside one of ``boxes`` (if there are any) and on the inner
    side of every one of ``planes``. ``margin`` (m): how far outside a *measured* pose may be before the
    supervisor stops the arm."""

    boxes: tuple[Box, ...] = ()
    planes: tuple[Plane, ...] = ()
    margin: float = DEFAULT_WALL_MARGIN

    @staticmethod
    def box(lower: Point, upper: Point, margin: float = DEFAULT_WALL_MARGIN) -> Workspace:
        """A workspace of one box (a convenience for code and tests)."""
        lo = (float(lower[0]), float(lower[1]), float(lower[2]))
        hi = (float(upper[0]), float(upper[1]), float(upper[2]))
        return Workspace((Box(lo, hi),), (), margin)

    @staticmethod
    def plane(normal: Point, offset: float) -> Plane:
        """A :class:`Plane` from any non-zero ``normal`` (scaled to unit length with its ``offset``)."""
        n = np.asarray(normal, dtype=float)
        size = float(np.linalg.norm(n))
        if not size > 0.0:
            raise ValueError("a plane's normal must not be zero")
        u = n / size
        return Plane((float(u[0]), float(u[1]), float(u[2])), float(offset) / size)

    def outside(self, p: Point) -> float:
        """How far the point ``p`` (m, base frame) is outside the workspace, m (0 inside)."""
        d = min((b.outside(p) for b in self.boxes), default=0.0)
        for plane in self.planes:
            d = max(d, plane.outside(p))
        return d

    def walls(self, p: Point) -> list[tuple[float, np.ndarray]]:
        """The walls that bound ``p``: (how far inside each one it is, m; its outward unit normal):
        the faces of the box it is deepest in (the nearest one if it is in none) and every plane."""
        out: list[tuple[float, np.ndarray]] = []
        if self.boxes:
            best = max(self.boxes, key=lambda b: min(d for d, _ in b.faces(p)) - b.outside(p))
            out.extend(best.faces(p))
        out.extend(plane.face(p) for plane in self.planes)
        return out

    def describe(self) -> str:
        parts = [f"box [{', '.join(f'{x:g}' for x in b.lower)}] to [{', '.join(f'{x:g}' for x in b.upper)}] m"
                 for b in self.boxes]
        parts += [f"plane normal [{', '.join(f'{x:.3g}' for x in pl.normal)}] offset {pl.offset:g} m"
                  for pl in self.planes]
        return "; ".join(parts) or "everywhere"
