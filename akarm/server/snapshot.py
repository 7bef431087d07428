"""One look at a running arm, for a live view: what the server's ``snapshot`` operation returns.

:func:`take` reads an :class:`~akarm.Arm` from outside its loop's thread: the joints' latest
feedback and the commanded position (:meth:`Arm.state <akarm.Arm.state>`, one short hold of the
controller's lock), the feed-forward torque last commanded, the safety stop that latched (if any)
and the loop's counters (read as they are, without the percentiles of :meth:`Arm.stats
<akarm.Arm.stats>`). Nothing in it changes what the arm does. A :class:`Snapshot` travels over the
control socket as a JSON object (:meth:`Snapshot.to_doc`, :meth:`Snapshot.from_doc`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

from akarm.errors import StateError

if TYPE_CHECKING:
    from akarm.arm import Arm

__all__ = ["Snapshot", "take"]


def _floats(values: Iterable[Any]) -> tuple[float, ...]:
    return tuple(math.nan if v is None else float(v) for v in values)


def _float(value: Any) -> float:
    return math.nan if value is None else float(value)


@dataclass(frozen=True)
class Snapshot:
    """The arm at one instant (joint side, SI; per-joint tuples in the robot file's joint order).

    Attributes:
        t: the arm's clock time, s.
        names: the joints.
        q: measured positions, rad. q_des: commanded positions, rad (NaN where nobody commands:
            a source that only measures). error: ``q_des - q``, rad.
        tau: measured torques, N·m. tau_ff: the feed-forward torque last commanded, N·m.
        temperature: °C (NaN: the motor does not report it). age: s since each joint's feedback.
        fault: each motor's error code (0: none).
        mode: what the arm does: ``holding``, ``moving``, ``teach``, ``disabled``, ``fault`` (a
            server's :attr:`~akarm.server.server.ArmServerCore.mode`), or the controller's mode in
            lower case for an Arm without a server.
        enabled: the motors are powered and under control. moving: a motion runs.
        stop: the safety stop that latched (it disabled the arm, and stays until the arm is enabled
            again), as text; ``""`` none.
        rate_hz: the loop's target rate. loop_rate_hz: the rate it kept since its statistics started
            (0: not running). cycles: cycles run. missed_slots: slots skipped because a cycle started late.
        gripper: the gripper's name (``""``: none). gripper_width: the width between its jaws, m;
            gripper_target: the width asked, m; gripper_force: its squeeze, N (estimated);
            gripper_grasped: it holds something; gripper_temperature: its motor's, °C (NaN: unknown).
    """

    t: float
    names: tuple[str, ...]
    q: tuple[float, ...]
    q_des: tuple[float, ...]
    error: tuple[float, ...]
    tau: tuple[float, ...]
    tau_ff: tuple[float, ...]
    temperature: tuple[float, ...]
    age: tuple[float, ...]
    fault: tuple[int, ...]
    mode: str
    enabled: bool
    moving: bool
    stop: str
    rate_hz: float
    loop_rate_hz: float
    cycles: int
    missed_slots: int
    gripper: str = ""
    gripper_width: float = math.nan
    gripper_target: float = math.nan
    gripper_force: float = math.nan
    gripper_grasped: bool = False
    gripper_temperature: float = math.nan

    def to_doc(self) -> dict[str, Any]:
        """A JSON-able dict (tuples as lists; NaN stays NaN, which Python's json reads back)."""
        return {f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v for f in fields(self)}

    @classmethod
    def from_doc(cls, doc: Mapping[str, Any]) -> Snapshot:
        """The snapshot a server sent (:meth:`to_doc`).

        Raises:
            StateError: the document is not a snapshot of this akarm version's shape.
        """
        try:
            names = tuple(str(n) for n in doc["names"])
            per_joint = {k: _floats(doc[k]) for k in ("q", "q_des", "error", "tau", "tau_ff", "temperature", "age")}
            if any(len(v) != len(names) for v in per_joint.values()):
                raise ValueError("a per-joint list of the wrong length")
            return cls(t=float(doc["t"]), names=names, **per_joint, fault=tuple(int(x) for x in doc["fault"]),
                       mode=str(doc["mode"]), enabled=bool(doc["enabled"]), moving=bool(doc["moving"]),
                       stop=str(doc["stop"]), rate_hz=float(doc["rate_hz"]), loop_rate_hz=float(doc["loop_rate_hz"]),
                       cycles=int(doc["cycles"]), missed_slots=int(doc["missed_slots"]),
                       gripper=str(doc.get("gripper", "")), gripper_grasped=bool(doc.get("gripper_grasped", False)),
                       gripper_width=_float(doc.get("gripper_width")),
                       gripper_target=_float(doc.get("gripper_target")),
                       gripper_force=_float(doc.get("gripper_force")),
                       gripper_temperature=_float(doc.get("gripper_temperature")))
        except (KeyError, TypeError, ValueError) as e:
            raise StateError(f"the server's snapshot is not one this akarm reads ({e!r})",
                             fix="is the server the same akarm version as this view?") from None


def _gripper(arm: Arm) -> dict[str, Any]:
    """The gripper's fields of a snapshot (none without one; NaN while its motor is not heard)."""
    g = arm.gripper
    if g is None:
        return {}
    try:
        s = g.state()
    except StateError:
        return {"gripper": str(g.name)}
    return {"gripper": str(g.name), "gripper_width": float(s.width), "gripper_target": float(s.target),
            "gripper_force": float(s.force), "gripper_grasped": bool(s.grasped),
            "gripper_temperature": float(s.temperature)}


def take(arm: Arm, mode: str | None = None) -> Snapshot:
    """A :class:`Snapshot` of ``arm`` now; ``mode`` (a server's) replaces the controller's mode name.

    Raises:
        StateError: the arm is not open.
    """
    s = arm.state()
    tau_ff = _floats(arm.observe.tau_ff)
    stats = arm.observe.loop.stats
    cycles, missed, first, last = stats.cycles, stats.missed, stats.first_start, stats.last_start
    span = (last - first) if first is not None and last is not None else 0.0
    q, q_des = _floats(s.q), _floats(s.q_des)
    fault = arm.fault
    return Snapshot(t=float(s.time), names=tuple(arm.names), q=q, q_des=q_des,
                    error=tuple(d - m for d, m in zip(q_des, q, strict=True)), tau=_floats(s.tau), tau_ff=tau_ff,
                    temperature=_floats([j.temperature for j in s.joints]), age=_floats([j.age for j in s.joints]),
                    fault=tuple(int(j.fault) for j in s.joints),
                    mode=mode if mode is not None else s.mode.name.lower(), enabled=s.enabled, moving=s.moving,
                    stop="" if fault is None else str(fault), rate_hz=float(arm.config.rate_hz),
                    loop_rate_hz=(cycles - 1) / span if span > 0 else 0.0, cycles=int(cycles), missed_slots=int(missed),
                    **_gripper(arm))
