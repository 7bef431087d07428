"""Self-collision: the arm's links against each other, with Pinocchio's collision support (coal).

The links' shapes come from the URDF's ``<collision>`` elements, else its ``<visual>`` ones, else
capsules from each joint to the next (as ``akarm view`` draws an arm without visuals: 30 mm for a
1 kg link, growing with the cube root of its mass). Pairs that cannot tell anything are left out:
shapes on one link, on neighbouring links (a joint between them), and pairs that touch in nearly
every pose (:data:`ALWAYS` of :data:`SAMPLES` random poses within the ranges). Two shapes count as
colliding closer than ``margin`` (m).

:class:`SelfCollision` is used on one thread (each caller its own, :meth:`SelfCollision.copy` shares the
shapes): the planner checks a path's samples (:meth:`SelfCollision.check_path`), servoing the pose a
step ahead, the supervisor the measured pose (:mod:`akarm.control.selfcollision`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
import pinocchio as pin

from akarm.config import RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, LimitError

__all__ = ["ALWAYS", "SAMPLES", "SelfCollision", "Source", "self_collision_for"]

Source = Literal["auto", "collision", "visual", "capsules"]
#: random poses tried to find the pairs that always touch, and the share of them that makes "always"
SAMPLES = 200
ALWAYS = 0.95
#: s between a path's samples checked (at most MAX_SAMPLES of them)
STEP = 0.01
MAX_SAMPLES = 5000


def _capsules(model: pin.Model) -> pin.GeometryModel:
    """A capsule from each joint to the next (to its farthest frame for a last link), per link."""
    import coal

    geom = pin.GeometryModel()
    children: dict[int, list[int]] = {i: [] for i in range(model.njoints)}
    for j in range(1, model.njoints):
        children[int(model.parents[j])].append(j)
    for i in range(1, model.njoints):
        mass = float(model.inertias[i].mass)
        radius = min(0.06, max(0.008, 0.03 * (max(mass, 0.0) ** (1.0 / 3.0))))
        ends = [np.array(model.jointPlacements[j].translation) for j in children[i]]
        if not ends:
            frames = [np.array(f.placement.translation) for f in model.frames if int(f.parentJoint) == i]
            far = max(frames, key=lambda p: float(np.linalg.norm(p)), default=np.zeros(3))
            ends = [far]
        for k, end in enumerate(ends):
            length = float(np.linalg.norm(end))
            placement = pin.SE3.Identity()
            if length > 1e-6:
                axis = end / length
                z = np.array([0.0, 0.0, 1.0])
                rot = pin.Quaternion.FromTwoVectors(z, axis).matrix()
                placement = pin.SE3(rot, end / 2.0)
            shape = coal.Capsule(radius, length)
            obj = pin.GeometryObject(f"link{i}_{k}", i, placement, shape)
            geom.addGeometryObject(obj)
    return geom


class SelfCollision:
    """The arm's self-collision check (see the module).

    Args:
        config: the robot. source: where the shapes come from (``"auto"``: collision, else visual, else
            capsules). margin: m; shapes closer than this count as colliding.

    Attributes:
        source: the source used. pairs: the pairs checked, as (shape, shape) names.
    """

    def __init__(self, config: RobotConfig, source: Source = "auto", margin: float = 0.0, *,
                 like: SelfCollision | None = None) -> None:
        if source not in ("auto", "collision", "visual", "capsules"):
            raise ArgumentError(f"self-collision shapes come from 'auto', 'collision', 'visual' or 'capsules', "
                                f"not {source!r}", fix="e.g. self_collision='auto'")
        if not (isinstance(margin, int | float) and math.isfinite(margin) and margin >= 0.0):
            raise ArgumentError(f"the self-collision margin must be a finite number of m ≥ 0, got {margin!r}",
                                fix="e.g. 0.01")
        self.margin = float(margin)
        self.model: RobotModel
        self.source: str
        self.geom: pin.GeometryModel
        self.pairs: list[tuple[str, str]]
        if like is not None:  # a copy (copy()): its shapes and pairs, data of its own
            self.model, self.source, self.geom, self.pairs = like.model, like.source, like.geom, like.pairs
            self._data = self.model.pin_model.createData()
            self._new_geometry_data()
            return
        self.model = RobotModel(config)
        pm = self.model.pin_model
        geom = None
        used: str = "capsules"
        for kind, gtype in (("collision", pin.GeometryType.COLLISION), ("visual", pin.GeometryType.VISUAL)):
            if source not in ("auto", kind):
                continue
            try:
                g = self._from_urdf(config, gtype)
            except (ValueError, RuntimeError):  # meshes it cannot find: the next source
                g = None
            if g is not None and len(g.geometryObjects):
                geom, used = g, kind
                break
        if geom is None:
            if source in ("collision", "visual"):
                raise ArgumentError(f"the URDF has no usable <{source}> shapes", fix="use source 'auto' or 'capsules'")
            geom = _capsules(pm)
        self.source = used
        self.geom = geom
        geom.addAllCollisionPairs()
        self._data = pm.createData()
        self._leave_out_neighbours()
        self._new_geometry_data()
        self._leave_out_always(config)
        self.pairs = [(geom.geometryObjects[p.first].name, geom.geometryObjects[p.second].name)
                      for p in geom.collisionPairs]

    def copy(self, margin: float | None = None) -> SelfCollision:
        """The same check for another thread (the shapes and pairs shared, read only), with its own
        ``margin`` (m) if given."""
        source: Source = self.source  # type: ignore[assignment]
        return SelfCollision(self.model.config, source, self.margin if margin is None else margin, like=self)

    def _from_urdf(self, config: RobotConfig, gtype: pin.GeometryType) -> pin.GeometryModel:
        """The URDF's shapes on the (reduced) model: built on the full model, then reduced alike."""
        full = pin.buildModelFromUrdf(str(config.urdf))
        geom = pin.buildGeomFromUrdf(full, str(config.urdf), gtype, package_dirs=[str(config.urdf.parent)])
        driven = set(config.joint_names)
        lock = [j for j in range(1, full.njoints) if str(full.names[j]) not in driven]
        if not lock:
            return geom
        q_ref = pin.neutral(full)
        for jid in lock:
            joint = full.joints[jid]
            x = float(config.locked.get(str(full.names[jid]), 0.0))
            if joint.nq == 1:
                q_ref[joint.idx_q] = x
        _, reduced = pin.buildReducedModel(full, geom, lock, q_ref)
        return reduced

    def _leave_out_neighbours(self) -> None:
        pm, geom = self.model.pin_model, self.geom
        keep = []
        for p in geom.collisionPairs:
            a, b = geom.geometryObjects[p.first].parentJoint, geom.geometryObjects[p.second].parentJoint
            if a == b or int(pm.parents[a]) == b or int(pm.parents[b]) == a:
                continue
            keep.append(pin.CollisionPair(p.first, p.second))
        geom.removeAllCollisionPairs()
        for p in keep:
            geom.addCollisionPair(p)

    def _leave_out_always(self, config: RobotConfig) -> None:
        """Pairs colliding in nearly every pose (a shape that overlaps its link's neighbour's) are left out."""
        geom = self.geom
        if not geom.collisionPairs:
            return
        rng = np.random.default_rng(0)
        lo, hi = np.array([j.limits.lower for j in config.joints]), np.array([j.limits.upper for j in config.joints])
        hits = np.zeros(len(geom.collisionPairs))
        for _ in range(SAMPLES):
            self._compute(rng.uniform(lo, hi))
            hits += [r.isCollision() for r in self._gdata.collisionResults]
        keep = [pin.CollisionPair(p.first, p.second) for p, h in zip(geom.collisionPairs, hits, strict=True)
                if h < ALWAYS * SAMPLES]
        if len(keep) != len(geom.collisionPairs):
            geom.removeAllCollisionPairs()
            for p in keep:
                geom.addCollisionPair(p)
            self._new_geometry_data()

    def _new_geometry_data(self) -> None:
        self._gdata = pin.GeometryData(self.geom)
        for req in self._gdata.collisionRequests:
            req.security_margin = self.margin

    def _compute(self, q: Sequence[float] | np.ndarray) -> bool:
        return bool(pin.computeCollisions(self.model.pin_model, self._data, self.geom, self._gdata,
                                          self.model.to_pin_q(q), False))

    def colliding(self, q: Sequence[float] | np.ndarray) -> list[tuple[str, str]]:
        """The pairs of shapes that collide (closer than the margin) at ``q`` (rad, config order)."""
        if not self.geom.collisionPairs or not self._compute(q):
            return []
        objs = self.geom.geometryObjects
        return [(objs[p.first].name, objs[p.second].name)
                for p, r in zip(self.geom.collisionPairs, self._gdata.collisionResults, strict=True)
                if r.isCollision()]

    def collides(self, q: Sequence[float] | np.ndarray) -> bool:
        return bool(self.geom.collisionPairs) and self._compute(q)

    def check_path(self, samples: Sequence[tuple[float, np.ndarray]], start_colliding: bool) -> None:
        """Refuse (:class:`~akarm.LimitError`) a path whose samples ``(t, q)`` collide; a path that starts in
        collision (``start_colliding``) is let go until it first leaves it."""
        inside = start_colliding
        for t, q in samples:
            hit = self.colliding(q)
            if not hit:
                inside = False
                continue
            if inside:
                continue
            a, b = hit[0]
            raise LimitError(f"the planned path makes the arm collide with itself ({a} with {b}"
                             f"{f', closer than {self.margin * 1e3:.0f} mm' if self.margin else ''}) {t:.2f} s into "
                             "the move; nothing moved", fix="choose another target or path (move_through waypoints "
                                                            "around it)")


#: checks built (the URDF read, the pairs sampled: about 25 ms for arm6), by what they depend on; at most
#: _MAX_BUILT of them, each handed out as a copy
_BUILT: dict[tuple[object, ...], SelfCollision] = {}
_MAX_BUILT = 32


def self_collision_for(config: RobotConfig, source: Source = "auto", margin: float = 0.0) -> SelfCollision:
    """A :class:`SelfCollision` for ``config``: a copy of one built before for the same URDF (and file
    time), source, margin, joint ranges and locked joints, else a new one (an Arm is made in a few ms)."""
    try:
        stamp = config.urdf.stat().st_mtime_ns
    except OSError:
        stamp = -1
    key = (str(config.urdf), stamp, source, float(margin) if isinstance(margin, int | float) else repr(margin),
           tuple((j.name, j.limits.lower, j.limits.upper) for j in config.joints), tuple(sorted(config.locked.items())))
    built = _BUILT.get(key)
    if built is None:
        built = SelfCollision(config, source, margin)
        if len(_BUILT) >= _MAX_BUILT:
            _BUILT.clear()
        _BUILT[key] = built
    return built.copy()
