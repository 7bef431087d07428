"""The robot file's domain checks: what a value means given the URDF, the motors, the other joints, the bus.

:mod:`akarm.robotfile.schema` has read the file (keys, types, ranges, required keys); these checks
take what it read and report, each at its line with a fix, into the same
:class:`~akarm.robotfile.nodes.Findings`. :data:`RULES` says what they check, in the words the
reference (``docs/robot-file.md``) prints.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Collection, Mapping
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import Any

import yaml

from akarm.config import (
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    BusConfig,
    Friction,
    Gains,
    GripperConfig,
    JointConfig,
    Limits,
    Payload,
    RobotConfig,
    SelfCollisionConfig,
)
from akarm.config.busload import LOAD_LIMIT, load_of
from akarm.config.canconfig import resolve_bus
from akarm.config.urdf import Urdf, UrdfJoint, pinocchio_complaint, read_urdf
from akarm.config.workspace import Box, Plane, Workspace
from akarm.errors import AkarmError
from akarm.protocol.motors import Catalogue, MotorModel, did_you_mean
from akarm.robotfile.nodes import Findings, line, plain
from akarm.robotfile.schema import (
    GAINS,
    GRIPPER,
    INVALID,
    JOINT,
    PAYLOAD,
    ROBOT_FILE,
    Fields,
    Item,
    Number,
    Section,
    merged,
    missing,
)

__all__ = ["DEFAULT_BUS", "RULES", "SERVO_POSITION_RANGE", "Joints", "bus_load", "buses", "catalogue", "gravity",
           "gripper", "locked", "payload", "poses", "rate", "serial_ports", "tool_frame", "urdf_file"]

DEFAULT_BUS = "arm"
#: Servo status frames carry position as int16 × 0.1°.
SERVO_POSITION_RANGE = math.radians(3276.7)
#: A UART reply carries position as int32 millionths of a degree.
UART_POSITION_RANGE = math.radians(2147.483647)
#: the gains' range without a known motor: the catalogue's usual kp_max and kd_max
_GAIN_RANGE: dict[str, float] = {f.name: f.default for f in dataclass_fields(MotorModel)  # type: ignore[misc]
                                  if f.name in ("kp_max", "kd_max")}
#: joint keys read as they are into the :class:`~akarm.config.JointConfig` field of the same name
_SETTINGS = tuple(k.name for k in JOINT.keys if not isinstance(k.kind, Section)
                  and k.name in {f.name for f in dataclass_fields(JointConfig)}
                  and k.name not in ("name", "bus", "can_id", "motor"))


#: What the checks refuse (or warn about), one rule an item, for the reference (markdown).
RULES = (
    "The URDF is read as exporters write it: only the robot's own `<joint>` and `<link>` elements count (not "
    "those named in `<transmission>`, `<gazebo>` or `<ros2_control>`); meshes are never opened. Its problems are "
    "reported at their URDF line.",
    "`joints:` are the joints motors drive (revolute, or continuous), each listed once, with a CAN ID used once "
    "on its bus, a known bus (which may be left out when there is one) and a known motor model.",
    "Every other movable URDF joint (a gripper's fingers, a prismatic axis, a `<mimic>` joint) is held still in "
    "the dynamics model, its mass still counted: at its `locked:` position, where its mimic master puts it, or "
    "at 0 within its limits with a warning.",
    "Position limits come from the URDF; `lower`/`upper` under `limits` may only narrow them. A continuous URDF "
    "joint has none, so the file must give both (the MIT position field wraps at ±p_max: an unbounded range "
    "cannot be tracked).",
    "MIT joints: the position range, seen from the motor (`motor = (joint - offset) * direction`), must lie "
    "within ±p_max. Servo joints: within the status frame's ±3276.7° (at the output, or at the rotor for "
    "`servo_position: rotor` models).",
    "`velocity` at most the motor's v_max; `torque` defaults to, and may not exceed, the motor's t_max; MIT "
    "joints need `kp` and `kd`, within the motor's kp_max and kd_max.",
    "A pose has one value per joint, each within the joint's limits.",
    "A serial port (`interface: akarm_uart`) carries one servo-mode motor: no second joint, no MIT joint; its "
    "range, seen from the motor, within the ±2147.48° a UART reply carries.",
    "Bus load: a bus whose nominal load would pass 80 % at `rate_hz` is refused (see `akarm.config.busload`; "
    "`akarm check` prints the load and the highest rate each bus carries).",
    "Gravity: the largest gravity torque of every joint over the joint ranges, payload included, may not exceed "
    "the joint's torque limit; above the motor's rated (continuous) torque it is a warning.",
)


def _clip(x: float, joint: UrdfJoint) -> float:
    """``x`` within the URDF joint's limits (continuous joints have none)."""
    if joint.lower is None or joint.upper is None:
        return x
    return min(max(x, joint.lower), joint.upper)


def _usable(item: Item | None) -> Any:
    """A section's :class:`Fields` when given and read without a problem; else ``None``."""
    if item is None or not item.ok or item.value.flawed:
        return None
    return item.value


# --------------------------------------------------------------------------- the top level


def urdf_file(found: Findings, item: Item | None, folder: Path) -> tuple[Path | None, Urdf | None]:
    """The URDF's path and what it declares; ``None`` for the latter when it has problems (reported,
    each at its line of the URDF), so that the checks against it are skipped."""
    if item is None or not item.ok:
        return None, None
    path = Path(os.path.expanduser(item.value))
    if not path.is_absolute():
        path = folder / path
    path = path.resolve()
    if not path.is_file():
        found.add(item.node, f"URDF file {str(path)!r} not found",
                  "give the URDF's path relative to this YAML file (or an absolute path)")
        return path, None
    urdf, problems = read_urdf(path)
    for p in problems:
        found.add(p.line, f"URDF: {p.message}", p.fix, file=str(path))
    if urdf is None or problems:
        return path, None
    complaint = pinocchio_complaint(path)
    if complaint is not None:
        found.add(item.node, f"URDF {path.name} is not a valid robot model: {complaint}",
                  "fix the URDF (unique link names, every joint a known type, parent and child link)")
        return path, None
    return path, urdf


def catalogue(found: Findings, item: Item | None, cat: Catalogue) -> tuple[Catalogue, set[str]]:
    """The catalogue with the file's `motors:` entries, and the names of entries with problems (reported)."""
    failed: set[str] = set()
    if item is None or not item.ok:
        return cat, failed
    for name, entry in item.value.items():
        problems = cat.check_entry(name, entry.value)
        if problems:
            failed.add(name.strip().upper())
            keys = {}
            if isinstance(entry.node, yaml.MappingNode):
                keys = {plain(k, found): k for k, _ in entry.node.value}
            for key, message, fix in problems:
                found.add(keys.get(key, entry.key) if key else entry.key, message, fix)
            continue
        model = cat.build_entry(name, entry.value)
        models = {m.name.upper(): m for m in cat.values()}
        models[model.name.upper()] = model
        cat = Catalogue({m.name: m for m in models.values()})
    return cat, failed


def buses(found: Findings, item: Item | None) -> dict[str, BusConfig]:
    """The buses, completed from python-can's configuration (:func:`~akarm.config.canconfig.resolve_bus`).
    A bus with problems (reported) still has its name, so its joints are checked without follow-on errors."""
    if item is None:
        entries = {DEFAULT_BUS: Item(None, yaml.MappingNode("", []), Fields())}
    elif not item.ok:
        return {}
    else:
        entries = item.value
        if not entries:
            found.add(item.node, "`buses:` is empty", "name at least one bus, e.g. `arm: {channel: can0}`, or drop "
                      "`buses:`")
    out: dict[str, BusConfig] = {}
    for name, entry in entries.items():
        given = _usable(entry)
        bus = None
        if given is not None:
            bus, problems = resolve_bus(name, {k: v.value for k, v in given.items()})
            for key, message, fix in problems:
                found.add(given[key].node if key in given else entry.key, message, fix)
        out[name] = bus if bus is not None else BusConfig(name)
    return out


def rate(found: Findings, item: Item | None, override: float | None) -> tuple[float | None, int | None]:
    """The loop rate (``None`` when it has problems) and the line it is on (``None``: the default or an override)."""
    hz: float | None = ROBOT_FILE["rate_hz"].default
    at = None
    if item is not None:
        hz, at = (item.value if item.ok else None), line(item.key)
    if override is None:
        return hz, at
    if isinstance(override, bool) or not isinstance(override, int | float) or \
            not MIN_RATE_HZ <= override <= MAX_RATE_HZ:
        found.add(None, f"rate_hz override must be a number of Hz from {MIN_RATE_HZ:g} to {MAX_RATE_HZ:g}, got "
                  f"{override!r}", "pass e.g. 500")
        return hz, at
    return float(override), None


def tool_frame(found: Findings, item: Item | None, urdf: Urdf | None) -> str | None:
    """The tool frame, when the URDF has it."""
    if item is None or not item.ok:
        return None
    frames = set(urdf.links) | set(urdf.joints) if urdf is not None else set()
    if urdf is not None and item.value not in frames:
        found.add(item.node, f"tool_frame {item.value!r} is not a link or joint of the URDF"
                  f"{did_you_mean(item.value, sorted(frames))}",
                  "name a URDF link (e.g. the flange link), or drop tool_frame to use the last link")
    return str(item.value)


def payload(item: Item | None) -> Payload | None:
    """The payload, when it is given and has no problems."""
    given = _usable(item)
    if given is None or "mass" not in given:
        return None
    com = given.value("com", PAYLOAD["com"].default)
    return Payload(given.value("mass"), (com[0], com[1], com[2]))


def self_collision(item: Item | None) -> SelfCollisionConfig:
    """The self-collision check's settings (its defaults when ``self_collision:`` is not given)."""
    given = _usable(item)
    if given is None:
        return SelfCollisionConfig()
    return SelfCollisionConfig(given.value("shapes", "auto"), float(given.value("margin", 0.01)))


# --------------------------------------------------------------------------- joints


class Joints:
    """The ``joints:`` list checked against the URDF, the buses, the catalogue and each other."""

    def __init__(self, found: Findings, buses: Mapping[str, BusConfig], cat: Catalogue, failed_motors: set[str],
                 urdf: Urdf | None) -> None:
        self.found = found
        self.buses = buses
        self.catalogue = cat
        self.failed_motors = failed_motors  # `motors:` entries with problems (already reported)
        self.urdf = urdf
        #: names under joints: (valid or not) → line
        self.driven: dict[str, int | None] = {}
        #: how many items joints: has, valid or not (``None``: it is not a list)
        self.entries: int | None = None
        #: joint → line of its torque limit (or motor): where gravity above it is reported
        self.torque_lines: dict[str, int | None] = {}
        self._ids: dict[tuple[str, int], tuple[str, int | None]] = {}  # (bus, CAN ID) → joint, line

    def read(self, item: Item | None, shared: Fields) -> list[JointConfig]:
        """The joints without problems (every problem reported)."""
        if item is None or not item.ok:
            return []
        self.entries = len(item.value)
        out = [self.joint(entry, shared) for entry in item.value]
        return [j for j in out if j is not None]

    def joint(self, item: Item, shared: Fields) -> JointConfig | None:
        """One joint, ``None`` when it has problems (reported)."""
        found = self.found
        before = found.count
        if not item.ok:
            return None
        own: Fields = item.value
        given = merged(own, shared)
        name = own.value("name")
        owner = f"joint {name!r}" if name else "joint"
        anchor = own["name"].node if "name" in own else item.node
        missing(JOINT, given, anchor, owner, found)
        uj = self._urdf_joint(own, owner)
        bus = self.bus_of(given, owner, anchor)
        can_id = self.can_id_of(own, bus, name, owner)
        motor = self.motor_of(given, owner)
        settings = {k: given.value(k) for k in _SETTINGS if given.value(k) is not None}
        settings.setdefault("mode", JOINT["mode"].default)
        settings["firmware"] = given.value("firmware", motor.firmware if motor is not None else "v2")
        limits = self._limits(given, owner, anchor, motor, settings, uj)
        gains = self._gains(given, owner, anchor, motor, settings["mode"])
        extras = self._extras(given)
        if name is not None:
            torque, motor_item = given.value("limits", Fields()).get("torque"), given.get("motor")
            self.torque_lines[name] = line(torque.node if torque is not None else
                                           motor_item.node if motor_item is not None else item.node)
        if found.count > before or given.flawed or None in (name, bus, can_id, motor, limits, gains):
            return None
        return JointConfig(name=name, bus=bus, can_id=can_id, motor=motor, limits=limits,  # type: ignore[arg-type]
                           gains=gains, **settings, **extras)  # type: ignore[arg-type]

    def _urdf_joint(self, own: Fields, owner: str) -> UrdfJoint | None:
        """The URDF joint a `joints:` entry names, when a motor can drive it; else the problem is reported."""
        item = own.get("name")
        if item is None or not item.ok:
            return None
        name, at = item.value, item.node
        if name in self.driven:
            self.found.add(at, f"{owner} is listed twice (first on line {self.driven[name]})", "list every joint once")
        self.driven.setdefault(name, line(at))
        if self.urdf is None:
            return None
        uj = self.urdf.joints.get(name)
        where = f"URDF line {uj.line}" if uj is not None else ""
        if uj is None:
            movable = [j.name for j in self.urdf.movable]
            self.found.add(at, f"{owner} is not in the URDF{did_you_mean(name, list(self.urdf.joints))}",
                           "URDF joints are: " + (", ".join(movable) or "none"))
        elif uj.type == "fixed":
            self.found.add(at, f"{owner} is fixed in the URDF ({where}), so no motor can drive it",
                           "make it revolute or continuous in the URDF, or remove it from joints:")
        elif uj.mimic is not None:
            self.found.add(at, f"{owner} follows joint {uj.mimic.joint!r} in the URDF (<mimic>, {where}): it has no "
                           f"motor of its own", f"drive {uj.mimic.joint!r} instead, or remove {name!r} from joints: "
                           f"(it is then held where {uj.mimic.joint!r} puts it)")
        elif uj.type not in ("revolute", "continuous"):
            self.found.add(at, f"{owner} is {uj.type} in the URDF ({where}); akarm drives revolute and continuous "
                           "joints (AK actuators turn)", "remove it from joints: and hold it with `locked: {"
                           + name + ": POSITION}`, or make it revolute or continuous in the URDF")
        else:
            return uj
        return None

    def bus_of(self, given: Fields, owner: str, anchor: yaml.Node) -> str | None:
        item = given.get("bus")
        if item is None:
            if len(self.buses) == 1:
                return next(iter(self.buses))
            self.found.add(anchor, f"{owner} has no `bus:` and there are {len(self.buses)} buses",
                           "add `bus:` with one of " + ", ".join(self.buses))
            return None
        if item.ok and item.value not in self.buses:
            hint = did_you_mean(item.value, list(self.buses))
            self.found.add(item.node, f"{owner}: unknown bus {item.value!r}{hint}",
                           "buses are: " + ", ".join(self.buses) + " (define others under `buses:`)")
            return None
        return item.value if item.ok else None

    def can_id_of(self, own: Fields, bus: str | None, name: str | None, owner: str) -> int | None:
        item = own.get("can_id")
        if item is None or not item.ok:
            return None
        if bus is not None:
            if (bus, item.value) in self._ids:
                other, other_line = self._ids[(bus, item.value)]
                self.found.add(item.node, f"{owner}: CAN ID {item.value} on bus {bus!r} is already used by joint "
                               f"{other!r} (line {other_line})", "give every motor on a bus its own CAN ID")
            else:
                self._ids[(bus, item.value)] = (name or "?", line(item.node))
        return int(item.value)

    def motor_of(self, given: Fields, owner: str) -> MotorModel | None:
        item = given.get("motor")
        if item is None or not item.ok:
            return None
        cat, name = self.catalogue, item.value
        if name in cat:
            return cat.get(name)
        if name.strip().upper() not in self.failed_motors:  # else its entry under `motors:` has problems, reported
            self.found.add(item.node, f"{owner}: unknown motor model {name!r}{did_you_mean(name.upper(), cat.names())}",
                           "known models: " + ", ".join(cat.names()) + "; or define it under `motors:`")
        return None

    def _extras(self, given: Fields) -> dict[str, Any]:
        """The joint's identified friction and collision threshold, when given."""
        out: dict[str, Any] = {}
        friction = _usable(given.get("friction"))
        if friction is not None:
            out["friction"] = Friction(**{k: v.value for k, v in friction.items()})
        collision = _usable(given.get("collision"))
        if collision is not None and "threshold" in collision:
            out["collision_threshold"] = collision.value("threshold")
        return out

    # ------------------------------------------------------------ limits and gains

    def _limits(self, given: Fields, owner: str, anchor: yaml.Node, motor: MotorModel | None,
                settings: Mapping[str, Any], uj: UrdfJoint | None) -> Limits | None:
        item = given.get("limits")
        fields = item.value if item is not None and item.ok else Fields()
        at = item.key if item is not None and item.key is not None else anchor
        motion = [fields.value(k) for k in ("velocity", "acceleration", "jerk")]
        fast = motor is not None and motion[0] is not None and motion[0] > motor.v_max
        if fast:
            assert motor is not None
            self.found.add(fields["velocity"].node, f"{owner}: velocity limit {motion[0]:g} rad/s is above the "
                           f"{motor.name}'s {motor.v_max:g} rad/s", f"give at most {motor.v_max:g}")
        torque = self._torque(fields, owner, motor)
        span = self._range(fields, at, anchor, owner, motor, settings, uj)
        if fast or None in motion or torque is None or span is None:
            return None
        velocity, acceleration, jerk = motion
        return Limits(span[0], span[1], velocity, acceleration, jerk, torque)

    def _torque(self, fields: Fields, owner: str, motor: MotorModel | None) -> float | None:
        """The torque limit: the file's, at most the motor's t_max, else t_max."""
        item = fields.get("torque")
        if item is None:
            return motor.t_max if motor is not None else None
        if item.ok and motor is not None and item.value > motor.t_max:
            self.found.add(item.node, f"{owner}: torque limit {item.value:g} N·m is above the {motor.name}'s t_max "
                           f"{motor.t_max:g} N·m", f"give at most {motor.t_max:g}, or leave it out to use t_max")
            return None
        return float(item.value) if item.ok else None

    def _range(self, fields: Fields, at: yaml.Node, anchor: yaml.Node, owner: str, motor: MotorModel | None,
               settings: Mapping[str, Any], uj: UrdfJoint | None) -> tuple[float, float] | None:
        """The position range: the URDF's, narrowed by the file; within what the motor can report."""
        if uj is None:
            return None
        given = {k: fields.value(k) for k in ("lower", "upper") if fields.value(k) is not None}
        if uj.type == "continuous":
            lacking = [k for k in ("lower", "upper") if k not in fields]
            if lacking:
                self.found.add(at, f"{owner} is continuous in the URDF and has no {' or '.join(lacking)} limit",
                               "give `lower:` and `upper:` (rad) under limits; the motor's position wraps at ±p_max")
            lower, upper, ok = given.get("lower"), given.get("upper"), not lacking
        else:
            lower, upper, ok = self._narrowed(fields, given, owner, uj)
        if lower is None or upper is None:
            return None
        if not lower < upper:
            self.found.add(at, f"{owner}: position range [{lower:g}, {upper:g}] is empty", "give lower < upper")
            return None
        if motor is not None and not self._reachable(fields, given, anchor, owner, motor, settings, (lower, upper)):
            return None
        return (lower, upper) if ok else None

    def _narrowed(self, fields: Fields, given: Mapping[str, float], owner: str, uj: UrdfJoint
                  ) -> tuple[float, float, bool]:
        """The URDF's limits narrowed by the file's, and whether the file's only narrow them (else reported)."""
        assert uj.lower is not None and uj.upper is not None
        out = {"lower": uj.lower, "upper": uj.upper}
        ok = True
        for key, urdf_value, wider, word in (("lower", uj.lower, -1.0, "below"), ("upper", uj.upper, 1.0, "above")):
            if key in given:
                out[key] = given[key]
                if (given[key] - urdf_value) * wider > 0:
                    self.found.add(fields[key].node, f"{owner}: {key} limit {given[key]:g} is {word} the URDF's "
                                   f"{urdf_value:g}", "the YAML may only narrow the URDF's range")
                    ok = False
        return out["lower"], out["upper"], ok

    def _reachable(self, fields: Fields, given: Mapping[str, float], anchor: yaml.Node, owner: str,
                   motor: MotorModel, settings: Mapping[str, Any], span: tuple[float, float]) -> bool:
        """Whether the range, seen from the motor, lies within what its position field can say."""
        direction, offset = settings.get("direction", 1), settings.get("offset", 0.0)
        if direction is None or offset is None:
            return False
        ends = sorted(((span[0] - offset) * direction, (span[1] - offset) * direction))
        if settings["mode"] == "mit":
            reach, what = motor.p_max, f"the {motor.name}'s MIT position range ±{motor.p_max:g} rad"
        else:
            reach = SERVO_POSITION_RANGE / (motor.gear_ratio if motor.servo_position == "rotor" else 1.0)
            what = f"the servo status frame's range ±{reach:g} rad at the output"
        if -reach <= ends[0] and ends[1] <= reach:
            return True
        at = fields["lower"].node if "lower" in given else fields["upper"].node if "upper" in given else anchor
        self.found.add(at, f"{owner}: position range [{span[0]:g}, {span[1]:g}] rad ({'YAML' if given else 'URDF'}) "
                       f"is motor [{ends[0]:g}, {ends[1]:g}] rad with direction {direction} and offset {offset:g}, "
                       f"outside {what}", "narrow it with `lower:`/`upper:` under limits, or change the offset")
        return False

    def _gains(self, given: Fields, owner: str, anchor: yaml.Node, motor: MotorModel | None, mode: str
               ) -> Gains | None:
        item = given.get("gains")
        fields = item.value if item is not None and item.ok else Fields()
        where = item.key if item is not None and item.key is not None else anchor
        bounds = {k: getattr(motor, k) if motor is not None else v for k, v in _GAIN_RANGE.items()}
        values: dict[str, float] = {}
        ok = True
        for key in GAINS.names:
            spec, gain = GAINS[key].kind, fields.get(key)
            assert isinstance(spec, Number) and isinstance(spec.maximum, str)
            if gain is None:
                if mode == "mit":
                    self.found.add(where, f"{owner}: MIT joint without gain {key}", "add `gains: {kp: ..., kd: ...}` "
                                   f"(kp 0-{bounds['kp_max']:g}, kd 0-{bounds['kd_max']:g}), or in defaults:")
                    ok = False
                continue
            v = INVALID if not gain.ok else spec.within(gain.value, gain.node, GAINS.what(owner, key), f"give {key} "
                                                        f"in 0..{bounds[spec.maximum]:g} {spec.unit}", self.found,
                                                        **bounds)
            if v is INVALID:
                ok = False
            else:
                values[key] = v
        return Gains(**values) if ok else None


# --------------------------------------------------------------------------- after the joints


def locked(found: Findings, item: Item | None, urdf: Urdf, driven: Mapping[str, int | None], at: yaml.Node,
           fingers: Collection[str] = ()) -> dict[str, float]:
    """Where each URDF joint that no motor drives is held: the file's `locked:`, else where its <mimic>
    master puts it, else 0 within its limits (with a warning, at ``at``; a gripper's ``fingers``, and the
    joints that mimic them, without one: the gripper moves them, their mass counts as the tool's)."""
    given = _locked_given(found, item, urdf, driven) if item is not None and item.ok else {}
    held: dict[str, float] = {}
    pending = [j for j in urdf.movable if j.name not in driven and j.type in ("revolute", "continuous", "prismatic")]
    for _ in range(len(pending) + 1):  # masters before the joints that mimic them
        later = []
        for j in pending:
            if j.name in given:
                held[j.name] = given[j.name]
            elif j.name in fingers and j.mimic is None:
                held[j.name] = _clip(0.0, j)
            elif j.mimic is not None and j.mimic.joint in held:
                held[j.name] = j.mimic.multiplier * held[j.mimic.joint] + j.mimic.offset
            elif j.mimic is not None and j.mimic.joint in driven:
                held[j.name] = _follows_driven(found, urdf, j, at)
            elif j.mimic is not None and j.mimic.joint in urdf.joints:
                later.append(j)
            else:
                held[j.name] = _held_at_default(found, j, at)
        if not later:
            break
        pending = later
    return {name: held[name] for name in (j.name for j in urdf.movable) if name in held}


def _follows_driven(found: Findings, urdf: Urdf, j: UrdfJoint, at: yaml.Node) -> float:
    assert j.mimic is not None
    master = urdf.joints[j.mimic.joint]
    x = j.mimic.multiplier * _clip(0.0, master) + j.mimic.offset
    found.add(at, f"URDF joint {j.name!r} follows the driven joint {master.name!r} (<mimic>, URDF line {j.line}); the "
              f"dynamics model holds it at {x:g} instead", f"nothing to do for light parts (a gripper's second "
              f"finger); else drive {j.name!r}'s mass through its own URDF joint", warning=True, issue=True)
    return x


def _held_at_default(found: Findings, j: UrdfJoint, at: yaml.Node) -> float:
    x = _clip(0.0, j)
    unit = "m" if j.type == "prismatic" else "rad"
    found.add(at, f"URDF joint {j.name!r} ({j.type}, URDF line {j.line}) has no motor in joints: and is not under "
              f"locked:; it is held at {x:g} {unit}", f"say where it is: `locked: {{{j.name}: POSITION}}` ({unit}), or "
              "drive it: add it under joints: with its motor", warning=True, issue=True)
    return x


def _locked_given(found: Findings, item: Item, urdf: Urdf, driven: Mapping[str, int | None]) -> dict[str, float]:
    given: dict[str, float] = {}
    for name, entry in item.value.items():
        uj = urdf.joints.get(name)
        if uj is None:
            found.add(entry.key, f"locked: {name!r} is not a joint of the URDF"
                      f"{did_you_mean(name, [j.name for j in urdf.movable])}", "name a URDF joint that no motor "
                      "drives: " + (", ".join(j.name for j in urdf.movable if j.name not in driven) or "there is none"))
        elif name in driven:
            found.add(entry.key, f"locked: {name!r} is also under joints: (driven by a motor)",
                      "a joint is either driven (joints:) or held (locked:): remove one")
        elif uj.mimic is not None:
            found.add(entry.key, f"locked: {name!r} follows {uj.mimic.joint!r} in the URDF (<mimic>, URDF line "
                      f"{uj.line})", f"lock {uj.mimic.joint!r} instead; {name!r} is held where it puts it")
        elif uj.type not in ("revolute", "continuous", "prismatic"):
            found.add(entry.key, f"locked: {name!r} is {uj.type} in the URDF: it has no single position",
                      "remove it: it is held at its neutral configuration")
        elif entry.ok and uj.lower is not None and uj.upper is not None and not uj.lower <= entry.value <= uj.upper:
            unit = "m" if uj.type == "prismatic" else "rad"
            found.add(entry.node, f"locked: {name} = {entry.value:g} {unit} is outside its URDF limits "
                      f"[{uj.lower:g}, {uj.upper:g}] (URDF line {uj.line})", "give a position within them")
        elif entry.ok:
            given[name] = entry.value
    return given


def poses(found: Findings, item: Item | None, joints: list[JointConfig], entries: int | None
          ) -> dict[str, tuple[float, ...]]:
    """The named poses: one value per joint, within its limits. When some joints have problems of their
    own (``len(joints) != entries``), lengths and limits cannot be checked."""
    out: dict[str, tuple[float, ...]] = {}
    if item is None or not item.ok:
        return out
    n = len(joints)
    for name, entry in item.value.items():
        if not entry.ok or n != entries:
            continue
        if len(entry.value) != n:
            found.add(entry.node, f"pose {name!r} has {len(entry.value)} values for {n} joints", "give one value per "
                      "joint (rad), in the order of joints: " + ", ".join(j.name for j in joints))
            continue
        bad = False
        for j, x, node in zip(joints, entry.value, entry.node.value, strict=True):
            if not j.limits.lower <= x <= j.limits.upper:
                found.add(node, f"pose {name!r}: {j.name} = {x:g} rad is outside its limits "
                          f"[{j.limits.lower:g}, {j.limits.upper:g}]", "give a value within the joint's limits")
                bad = True
        if not bad:
            out[name] = tuple(entry.value)
    return out


def bus_load(found: Findings, buses: Mapping[str, BusConfig], joints: list[JointConfig], hz: float | None,
             at: int | None) -> None:
    """Refuse a rate that puts a bus over :data:`~akarm.config.busload.LOAD_LIMIT` (with the joints that are
    valid: a lower bound when some are not); ``at``: the rate's line (``None``: an override)."""
    if hz is None:
        return
    for name, bus in buses.items():
        load = load_of(name, bus.bitrate, hz, [j for j in joints if j.bus == name])
        if load.over_limit:
            given = "" if at is not None else " (given as an override)"
            found.add(at, f"rate_hz {hz:g}{given} puts {load.percent_nominal:.0f} % (worst case {load.percent:.0f} %) "
                      f"on bus {name!r}, over the {100 * LOAD_LIMIT:.0f} % limit",
                      f"lower rate_hz to at most {math.floor(load.max_rate_hz_nominal)} Hz, or move joints to another "
                      "bus")


def serial_ports(found: Findings, buses: Mapping[str, BusConfig], joints: list[JointConfig], item: Item | None
                 ) -> None:
    """Refuse a serial-port bus (``akarm_uart``) with more than one joint, or with a joint in MIT mode."""
    for name, bus in buses.items():
        if bus.interface != "akarm_uart":
            continue
        on = [j for j in joints if j.bus == name]
        at = item.value[name].key if item is not None and item.ok and name in item.value else None
        if len(on) > 1:
            found.add(at, f"bus {name!r} is a serial port (akarm_uart), and joints {', '.join(j.name for j in on)} "
                      "are on it: the serial protocol has no addresses, one motor per port",
                      "give each motor its own serial port (a bus each), or put them on a CAN bus")
        for j in on:
            if j.mode != "servo":
                found.add(at, f"joint {j.name!r} is in MIT mode on serial port bus {name!r}: MIT mode has no serial "
                          "protocol", "use servo mode (mode: servo) for a motor on a serial port, or a CAN bus")
                continue
            reach = UART_POSITION_RANGE / (j.motor.gear_ratio if j.motor.servo_position == "rotor" else 1.0)
            ends = sorted(((j.limits.lower - j.offset) * j.direction, (j.limits.upper - j.offset) * j.direction))
            if ends[0] < -reach or ends[1] > reach:
                found.add(at, f"joint {j.name!r} on serial port bus {name!r}: its range is motor [{ends[0]:g}, "
                          f"{ends[1]:g}] rad, outside the ±{reach:g} rad a UART reply's position carries (int32 "
                          "millionths of a degree)", "narrow it with `lower:`/`upper:` under limits, or use CAN")


def gravity(found: Findings, config: RobotConfig, urdf_item: Item | None, torque_lines: Mapping[str, int | None]
            ) -> None:
    """Will the motors hold the arm? Refuse gravity above a joint's torque limit; warn above the motor's
    rated (continuous) torque."""
    from akarm.dynamics.gravity import gravity_peaks

    try:
        peaks = gravity_peaks(config)
    except AkarmError as e:
        found.add(urdf_item.node if urdf_item is not None else None, f"the dynamics model cannot be built: {e.what}",
                  e.fix or "check the URDF and tool_frame")
        return
    for j, peak in zip(config.joints, peaks, strict=True):
        where = torque_lines.get(j.name)
        if peak.torque > j.limits.torque:
            limit = (f"its torque limit {j.limits.torque:g} N·m" if j.limits.torque < j.motor.t_max
                     else f"the {j.motor.name}'s {j.motor.t_max:g} N·m")
            found.add(where, f"joint {j.name!r}: gravity alone needs up to {peak.torque:.1f} N·m (at {peak.pose()}, "
                      f"payload included) over its range, above {limit}: the motor cannot hold the arm there",
                      "a stronger motor or more reduction, a narrower range (lower/upper under limits), or a "
                      "lighter arm or payload")
        elif j.motor.rated_torque is not None and peak.torque > j.motor.rated_torque:
            found.add(where, f"joint {j.name!r}: gravity needs up to {peak.torque:.1f} N·m (at {peak.pose()}), above "
                      f"the {j.motor.name}'s rated (continuous) torque {j.motor.rated_torque:g} N·m: holding such a "
                      "pose for long heats the motor until it stops on over-temperature",
                      "keep such poses short, or use a stronger motor", warning=True)


# --------------------------------------------------------------------------- the gripper


def gripper(found: Findings, item: Item | None, joints: Joints, urdf: Urdf | None) -> GripperConfig | None:
    """The `gripper:` entry checked against the catalogue, the buses, the joints' names and CAN IDs and
    the URDF (its fingers); ``None`` when there is none or it has problems (reported)."""
    if item is None or not item.ok:
        return None
    given: Fields = item.value
    if given.flawed:
        return None
    before = found.count
    at = item.key if item.key is not None else item.node
    name = given.value("name", GRIPPER["name"].default)
    owner = f"gripper {name!r}"
    if name in joints.driven:
        found.add(given["name"].node if "name" in given else at, f"{owner} has the name of a joint (line "
                  f"{joints.driven[name]})", "give the gripper a name of its own: `name: gripper`")
    bus = joints.bus_of(given, owner, at)
    can_id = joints.can_id_of(given, bus, name, owner)
    motor = joints.motor_of(given, owner)
    table = _gripper_table(found, given.get("table"), owner)
    fingers = _fingers(found, given.get("fingers"), owner, joints, urdf)
    if motor is not None:
        for key, top in (("kp", motor.kp_max), ("kd", motor.kd_max)):
            v = given.value(key, GRIPPER[key].default)
            if v > top:
                found.add(given[key].node, f"{owner}: {key} {v:g} is above the {motor.name}'s {top:g}",
                          f"give at most {top:g}")
    if found.count > before or None in (bus, can_id, motor, table, fingers):
        return None
    assert motor is not None and bus is not None and can_id is not None and table is not None
    stroke, travel = given.value("stroke"), given.value("travel")
    if table:
        if abs(table[-1][1] - stroke) > 1e-9 or abs(table[0][1]) > 1e-9:
            found.add(given["table"].node, f"{owner}: the table's widths run {table[0][1]:g}..{table[-1][1]:g} m, "
                      f"not 0..stroke ({stroke:g} m)", "start the table at width 0 (closed) and end it at the stroke")
            return None
        travel = table[-1][0]
    settings = {k: given.value(k) for k in ("mode", "direction", "offset", "kp", "kd", "speed", "reply_id",
                                            "max_temperature", "status_rate_hz") if given.value(k) is not None}
    settings["firmware"] = given.value("firmware", motor.firmware)
    out = GripperConfig(name=name, motor=motor, can_id=can_id, bus=bus, stroke=stroke, travel=travel,
                        force_limit=given.value("force_limit"), table=tuple(table), fingers=tuple(fingers or ()),
                        feedback_timeout=given.value("feedback_timeout"), **settings)
    lo, hi = sorted(((0.0 - out.offset) * out.direction, (out.open_angle - out.offset) * out.direction))
    reach = motor.p_max if out.mode == "mit" else SERVO_POSITION_RANGE
    if lo < -reach or hi > reach:
        found.add(at, f"{owner}: its travel is motor [{lo:g}, {hi:g}] rad, outside the {motor.name}'s ±{reach:g} rad",
                  "shorten the travel, or change the offset")
        return None
    return out


def _gripper_table(found: Findings, item: Item | None, owner: str) -> list[tuple[float, float]] | None:
    if item is None:
        return []
    v = item.value
    fix = "write [[0, 0], [ANGLE, WIDTH], ..., [TRAVEL, STROKE]]: rad and m, both increasing"
    ok = isinstance(v, list) and len(v) >= 2 and all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(x, int | float) and not isinstance(x, bool)
                                                    and math.isfinite(x) for x in p) for p in v)
    if not ok:
        found.add(item.node, f"{owner}: table must be a list of at least two [angle, width] pairs", fix)
        return None
    pts = [(float(a), float(w)) for a, w in v]
    if any(b[0] <= a[0] or b[1] <= a[1] for a, b in itertools.pairwise(pts)) or pts[0][0] != 0.0:
        found.add(item.node, f"{owner}: table's angles and widths must both increase, from angle 0", fix)
        return None
    return pts


def _fingers(found: Findings, item: Item | None, owner: str, joints: Joints, urdf: Urdf | None) -> list[str] | None:
    if item is None:
        return []
    v = item.value
    if not isinstance(v, list) or not all(isinstance(x, str) and x for x in v):
        found.add(item.node, f"{owner}: fingers must be a list of URDF joint names", "write [left_finger, "
                  "right_finger]")
        return None
    bad = False
    for name in v:
        if urdf is not None and name not in urdf.joints:
            found.add(item.node, f"{owner}: finger {name!r} is not a joint of the URDF"
                      f"{did_you_mean(name, list(urdf.joints))}", "name the URDF joints the jaws move")
            bad = True
        elif name in joints.driven:
            found.add(item.node, f"{owner}: finger {name!r} is under joints: (an arm joint)",
                      "a finger is moved by the gripper, not by a motor of the arm: remove it from joints:")
            bad = True
    return None if bad else list(v)
# --------------------------------------------------------------------------- walls

#: boxes and planes a `workspace:` may list (each is checked on every planned path's samples)
MAX_WALLS = 32


def _triple(value: Any) -> tuple[float, float, float] | None:
    """Three finite numbers, or ``None``."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        return None
    if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in value):
        return None
    return (float(value[0]), float(value[1]), float(value[2]))


def workspace(found: Findings, item: Item | None) -> Workspace | None:
    """The walls of ``workspace:``: its box (``min``/``max``), its ``boxes`` and ``planes``, each box's
    ``min`` below its ``max`` on every axis, each plane's normal not zero."""
    given = _usable(item)
    if given is None or item is None:
        return None
    at = item.key if item.key is not None else item.node
    boxes: list[Box] = []
    planes: list[Plane] = []
    if ("min" in given) != ("max" in given):
        found.add(at, "workspace: gives one of min and max", "give both corners of the box, min: [x, y, z] and "
                  "max: [x, y, z] (m, base frame)")
    elif "min" in given:
        boxes.append(_box(found, given["min"].node, given.value("min"), given.value("max"), "workspace"))
    for key in ("boxes", "planes"):
        entries = given.value(key)
        if entries is not None:
            _walls(found, given[key].node, key, entries, boxes, planes)
    if not boxes and not planes:
        found.add(at, "workspace: gives no box and no plane", "give min and max (a box), or boxes or planes")
        return None
    return Workspace(tuple(boxes), tuple(planes), float(given.value("margin", 0.02)))


def _box(found: Findings, node: Any, lower: Any, upper: Any, what: str) -> Box:
    lo, hi = _triple(lower), _triple(upper)
    if lo is None or hi is None:
        found.add(node, f"{what}: min and max must each be 3 finite numbers (m)", "e.g. min: [-0.5, -0.5, 0.0]")
        return Box((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    if not all(a < b for a, b in zip(lo, hi, strict=True)):
        found.add(node, f"{what}: min {list(lo)} is not below max {list(hi)} on every axis",
                  "give the lower corner as min and the upper one as max")
    return Box(lo, hi)


def _walls(found: Findings, node: Any, key: str, entries: Any, boxes: list[Box], planes: list[Plane]) -> None:
    """The boxes or planes of a ``workspace:`` (``key``), added to ``boxes`` or ``planes``."""
    if not isinstance(entries, list) or len(entries) > MAX_WALLS:
        found.add(node, f"workspace {key} must be a list of at most {MAX_WALLS} entries (MAX_WALLS)",
                  "write `- {min: [x, y, z], max: [x, y, z]}` items" if key == "boxes" else
                  "write `- {normal: [x, y, z], offset: d}` items")
        return
    for k, e in enumerate(entries):
        what = f"workspace {key}[{k}]"
        if key == "boxes":
            if not isinstance(e, dict) or set(e) != {"min", "max"}:
                found.add(node, f"{what} must be {{min: [x, y, z], max: [x, y, z]}}, got {e!r}",
                          "give both corners of the box (m, base frame)")
                continue
            boxes.append(_box(found, node, e["min"], e["max"], what))
            continue
        if not isinstance(e, dict) or set(e) != {"normal", "offset"}:
            found.add(node, f"{what} must be {{normal: [x, y, z], offset: d}}, got {e!r}",
                      "the tool stays where normal · p ≤ offset (normal pointing out of the workspace; m)")
            continue
        n = _triple(e["normal"])
        off = e["offset"]
        if n is None or not any(n) or not (isinstance(off, int | float) and not isinstance(off, bool)
                                           and math.isfinite(off)):
            found.add(node, f"{what}: the normal must be 3 finite numbers, not all zero, and the offset a "
                      f"finite number (m); got {e!r}", "e.g. {normal: [0, 0, -1], offset: -0.05}: z ≥ 0.05 m")
            continue
        planes.append(Workspace.plane(n, float(off)))
