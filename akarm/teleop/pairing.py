"""Which leader joint drives which follower joint, and how: ``follower = scale · leader + offset``.

Joints pair in order by default (the two arms need as many joints). A mapping file (YAML) names the
pairs, each with an optional scale and offset, and leaves joints out: a follower joint no pair
names holds where it was when following began; a leader joint no pair names moves freely::

    # leader joint → follower joint; follower position = scale · leader position + offset (rad)
    pairs:
      - {leader: shoulder, follower: left_shoulder}
      - {leader: elbow, follower: left_elbow, scale: -1.0, offset: 0.1}

Torques go back the other way by the same scale (the work done is the same on both sides):
``leader torque = scale · follower torque``.

**Grippers.** When both arms have a gripper, the leader's drives the follower's (the same fraction of
each one's stroke). A leader without one can drive the follower's gripper with a trigger: one of its
joints, named in the mapping file's ``gripper:`` section (and in no pair), whose angle from ``closed``
to ``open`` (rad) opens the follower's jaws from 0 to their stroke; ``force`` (N) is the squeeze the
follower grasps with (default: its gripper's default force; never more than its ``force_limit``)::

    gripper: {trigger: trigger_joint, closed: 0.0, open: 0.6, force: 15.0}
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akarm.errors import ArgumentError, ConfigError, ConfigProblem, did_you_mean
from akarm.files import FileProblem, YamlLimits, load_yaml

__all__ = ["MAP_FILE_LIMITS", "MAX_MAP_BYTES", "MAX_MAP_NODES", "GripperPair", "Pair", "Pairing"]

#: A mapping file larger than this is refused unread.
MAX_MAP_BYTES = 1 << 20
#: Values in a mapping file, every alias counted as the whole value it repeats.
MAX_MAP_NODES = 100_000
#: How a mapping file is read (nesting within :data:`akarm.files.MAX_YAML_DEPTH`, as every YAML file).
MAP_FILE_LIMITS = YamlLimits("mapping file", MAX_MAP_BYTES, "MAX_MAP_BYTES", MAX_MAP_NODES, "MAX_MAP_NODES")


@dataclass(frozen=True)
class Pair:
    """Leader joint ``leader`` (its index) drives follower joint ``follower``: ``scale · q + offset``."""

    leader: int
    follower: int
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class GripperPair:
    """What drives the follower's gripper: leader joint ``trigger`` (its index; None: the leader's own
    gripper), whose angle ``closed`` closes the jaws and ``open`` opens them fully (rad), and the force
    the follower grasps with (N; None: its gripper's default)."""

    trigger: int | None = None
    closed: float = 0.0
    open: float = 1.0
    force: float | None = None

    def fraction(self, angle: float) -> float:
        """How open the trigger at ``angle`` (rad) asks the jaws to be: 0 (closed) .. 1 (fully open)."""
        f = (angle - self.closed) / (self.open - self.closed)
        return min(max(f, 0.0), 1.0) if math.isfinite(f) else 0.0


class Pairing:
    """The pairs between a leader's and a follower's joints, and what drives the follower's gripper
    (see the module's docstring).

    Raises:
        ArgumentError: a joint paired twice, a scale that is zero or not finite, an offset that is not
            finite; a trigger joint that is paired too, a trigger range that is empty or not finite, a
            negative force.
    """

    def __init__(self, leader_names: Sequence[str], follower_names: Sequence[str], pairs: Sequence[Pair],
                 gripper: GripperPair | None = None) -> None:
        self.leader_names = tuple(leader_names)
        self.follower_names = tuple(follower_names)
        if not pairs:
            raise ArgumentError("a pairing needs at least one pair of joints", fix="name a leader and a follower joint")
        for attr, names in (("leader", self.leader_names), ("follower", self.follower_names)):
            used = [getattr(p, attr) for p in pairs]
            for i in used:
                if not 0 <= i < len(names):
                    raise ArgumentError(f"{attr} joint index {i} is out of range", fix=f"{attr} joints: {list(names)}")
            twice = sorted({names[i] for i in used if used.count(i) > 1})
            if twice:
                raise ArgumentError(f"{attr} joint {twice[0]!r} is paired twice", joint=twice[0],
                                    fix="pair each joint once")
        for p in pairs:
            if not (math.isfinite(p.scale) and p.scale != 0.0 and math.isfinite(p.offset)):
                raise ArgumentError(f"scale {p.scale!r} and offset {p.offset!r} must be finite, the scale not 0",
                                    joint=self.follower_names[p.follower], fix="e.g. scale: -1.0, offset: 0.1")
        self._check_gripper(gripper, pairs)
        self.gripper = gripper
        self.pairs = tuple(pairs)
        self.leader_index = np.array([p.leader for p in self.pairs], dtype=int)
        self.follower_index = np.array([p.follower for p in self.pairs], dtype=int)
        self.scale = np.array([p.scale for p in self.pairs], dtype=float)
        self.offset = np.array([p.offset for p in self.pairs], dtype=float)

    def _check_gripper(self, gripper: GripperPair | None, pairs: Sequence[Pair]) -> None:
        if gripper is None:
            return
        if gripper.trigger is not None:
            if not 0 <= gripper.trigger < len(self.leader_names):
                raise ArgumentError(f"trigger joint index {gripper.trigger} is out of range",
                                    fix=f"leader joints: {list(self.leader_names)}")
            trigger = self.leader_names[gripper.trigger]
            if any(p.leader == gripper.trigger for p in pairs):
                raise ArgumentError(f"the trigger joint {trigger!r} also drives a follower joint", joint=trigger,
                                    fix="a trigger drives the gripper alone: take it out of the pairs")
            if not (math.isfinite(gripper.closed) and math.isfinite(gripper.open)
                    and gripper.closed != gripper.open):
                raise ArgumentError(f"the trigger's closed ({gripper.closed!r}) and open ({gripper.open!r}) "
                                    "angles must be two different numbers", joint=trigger,
                                    fix="e.g. closed: 0.0, open: 0.6 (rad)")
        if gripper.force is not None and not (math.isfinite(gripper.force) and gripper.force >= 0.0):
            raise ArgumentError(f"the gripper's force {gripper.force!r} must be a number ≥ 0 N",
                                fix="e.g. force: 15.0 (N), within the follower gripper's force_limit")

    @classmethod
    def in_order(cls, leader_names: Sequence[str], follower_names: Sequence[str]) -> Pairing:
        """The first leader joint drives the first follower joint, and so on (scale 1, offset 0).

        Raises:
            ArgumentError: the arms have different numbers of joints (a mapping file says which pair).
        """
        if len(leader_names) != len(follower_names):
            raise ArgumentError(f"the leader has {len(leader_names)} joints, the follower {len(follower_names)}: "
                                "they cannot pair in order",
                                fix="give a mapping file (--map) that names the pairs; see akarm.teleop.pairing")
        return cls(leader_names, follower_names, [Pair(i, i) for i in range(len(leader_names))])

    @classmethod
    def load(cls, path: str | os.PathLike[str], leader_names: Sequence[str], follower_names: Sequence[str]) -> Pairing:
        """Read a mapping file (see the module's docstring).

        Raises:
            ConfigError: the file cannot be read, is too large, or names an unknown joint, a pair twice,
                a bad scale or offset; the problem says which pair and what to do.
        """
        p = Path(path)

        def problem(what: str, fix: str, line: int | None = None) -> ConfigError:
            return ConfigError([ConfigProblem(str(p), line, what, fix)])

        try:
            doc = load_yaml(p, MAP_FILE_LIMITS)
        except FileProblem as e:
            raise problem(e.what, e.fix, e.line) from None
        gripper = cls._gripper(doc.get("gripper") if isinstance(doc, dict) else None, leader_names, problem)
        items = doc.get("pairs") if isinstance(doc, dict) else None
        if not isinstance(items, list) or not items:
            raise problem("no `pairs:` list", "pairs: [{leader: JOINT, follower: JOINT, scale: 1.0, offset: 0.0}]")
        pairs = []
        for k, item in enumerate(items):
            if not isinstance(item, dict) or not {"leader", "follower"} <= set(item) or \
                    set(item) - {"leader", "follower", "scale", "offset"}:
                raise problem(f"pair {k + 1} is {item!r}",
                              "each pair is {leader: JOINT, follower: JOINT} with optional scale and offset")
            index = []
            for side, names in (("leader", leader_names), ("follower", follower_names)):
                name = item[side]
                if not isinstance(name, str):
                    raise problem(f"pair {k + 1}: the {side} joint {name!r} is not a joint name",
                                  f"{side} joints: {', '.join(names)}")
                if name not in names:
                    raise problem(f"pair {k + 1}: the {side} has no joint {name!r}{did_you_mean(name, names)}",
                                  f"{side} joints: {', '.join(names)}")
                index.append(list(names).index(name))
            try:
                scale, offset = float(item.get("scale", 1.0)), float(item.get("offset", 0.0))
            except (TypeError, ValueError):
                raise problem(f"pair {k + 1}: scale and offset must be numbers",
                              "e.g. scale: -1.0, offset: 0.1") from None
            pairs.append(Pair(index[0], index[1], scale, offset))
        try:
            return cls(leader_names, follower_names, pairs, gripper)
        except ArgumentError as e:
            raise problem(str(e.what), e.fix) from None

    @staticmethod
    def _gripper(item: object, leader_names: Sequence[str],
                 problem: Callable[[str, str], ConfigError]) -> GripperPair | None:
        """The mapping file's ``gripper:`` section (None without one)."""
        if item is None:
            return None
        keys = {"trigger", "closed", "open", "force"}
        if not isinstance(item, dict) or set(item) - keys:
            raise problem(f"gripper: is {item!r}", "gripper: {trigger: JOINT, closed: RAD, open: RAD, force: N}, "
                          "each optional (no trigger: the leader's own gripper)")
        trigger = item.get("trigger")
        index = None
        if trigger is not None:
            if not isinstance(trigger, str) or trigger not in leader_names:
                hint = did_you_mean(trigger, leader_names) if isinstance(trigger, str) else ""
                raise problem(f"gripper: the leader has no joint {trigger!r}{hint}",
                              f"leader joints: {', '.join(leader_names)}")
            index = list(leader_names).index(trigger)
        try:
            closed, open_ = float(item.get("closed", 0.0)), float(item.get("open", 1.0))
            force = None if item.get("force") is None else float(item["force"])
        except (TypeError, ValueError):
            raise problem("gripper: closed, open and force must be numbers",
                          "e.g. closed: 0.0, open: 0.6 (rad), force: 15.0 (N)") from None
        return GripperPair(index, closed, open_, force)

    def follower_positions(self, leader_q: np.ndarray, held: np.ndarray) -> np.ndarray:
        """The follower's positions for the leader's ``leader_q`` (rad); unpaired joints at ``held``."""
        out = np.array(held, dtype=float)
        out[self.follower_index] = self.scale * np.asarray(leader_q, dtype=float)[self.leader_index] + self.offset
        return out

    def follower_velocities(self, leader_dq: np.ndarray) -> np.ndarray:
        """The follower's velocities for the leader's ``leader_dq`` (rad/s); unpaired joints 0."""
        out = np.zeros(len(self.follower_names))
        out[self.follower_index] = self.scale * np.asarray(leader_dq, dtype=float)[self.leader_index]
        return out

    def leader_torques(self, follower_tau: np.ndarray) -> np.ndarray:
        """The leader's torques for the follower's ``follower_tau`` (N·m); unpaired joints 0."""
        out = np.zeros(len(self.leader_names))
        out[self.leader_index] = self.scale * np.asarray(follower_tau, dtype=float)[self.follower_index]
        return out
