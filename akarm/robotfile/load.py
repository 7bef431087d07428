"""Robot YAML → :class:`~akarm.config.RobotConfig`, validated in one pass.

A robot is described once, in a YAML file next to its URDF::

    name: arm6
    urdf: arm6.urdf                 # relative to this file
    tool_frame: tool0               # optional: frame for Cartesian queries and the payload
    gravity: [0.0, 0.0, -9.81]      # optional, m/s² in the URDF base frame (wall/ceiling mounts)
    payload: {mass: 0.5, com: [0.0, 0.0, 0.04]}   # optional: kg, m in the tool frame
    rate_hz: 500                    # control loop rate, Hz (default 500)
    buses:                          # optional: one bus `arm` on socketcan can0 at 1 Mbit/s if left out
      arm: {interface: socketcan, channel: can0, bitrate: 1000000}   # each key optional;
      aux: can1                     # a bare channel name: socketcan at 1 Mbit/s
    poses:                          # optional named poses, rad, config order
      home: [0, 0, 0, 0, 0, 0]
    motors:                         # optional: add/override catalogue models for this robot
      AK80-9: {v_max: 25.64}
    defaults:                       # optional: any joint key but name/can_id, shared by all joints;
      limits: {velocity: 3.0, acceleration: 15.0, jerk: 150.0}   # limits/gains merge key by key
      gains: {kp: 60.0, kd: 2.0}
    locked:                         # optional: URDF joints no motor drives, held at a position
      finger_joint1: 0.02           #   (rad, or m for prismatic joints); others are held at 0 with a warning
    joints:
      - name: shoulder_pan          # URDF joint name (revolute or continuous)
        bus: arm                    # may be left out when there is one bus
        can_id: 1                   # 1-127
        motor: AK80-9
        mode: mit                   # mit (default) | servo
        firmware: v2                # v2 | v3, default: the motor entry's
        direction: 1                # joint = direction * motor + offset
        offset: 0.0                 # rad
        limits: {lower: -1.5, upper: 1.5, velocity: 3.0, acceleration: 15.0, jerk: 150.0, torque: 10.0}
        gains: {kp: 60.0, kd: 2.0}  # required for MIT joints
        # optional: reply_id, feedback_timeout, max_temperature, status_rate_hz, can_timeout,
        #   friction: {coulomb: N·m, viscous: N·m·s/rad, offset: N·m} (identified; default: the catalogue's
        #   typical values), collision: {threshold: N·m} (the collision reflex; `akarm identify` suggests one),
        #   following_error, stuck_travel: rad, the supervisor's limits (default: derived, see akarm.control.safety)

Rules the loader applies:

- The URDF is read as exporters write it: only the robot's own ``<joint>``/``<link>`` elements count
  (not those named in ``<transmission>``, ``<gazebo>`` or ``<ros2_control>``); meshes are never
  opened. Its problems are reported at their URDF line (:mod:`akarm.config.urdf`).
- ``joints:`` are the joints motors drive (revolute or continuous). Every other movable URDF joint
  (a gripper's fingers, a prismatic axis, a ``<mimic>`` joint) is held still in the dynamics model:
  at its ``locked:`` position, where its mimic master puts it, or at 0 within its limits with a warning.
- Gravity (:mod:`akarm.dynamics.gravity`): the largest gravity torque of every joint over the joint ranges,
  payload included, may not exceed the joint's torque limit; above the motor's rated torque it is a
  warning.
- Position limits come from the URDF; ``lower``/``upper`` under ``limits`` may only narrow them.
  A **continuous** URDF joint has none, so its YAML must give both ``lower`` and ``upper``
  (the MIT position field wraps at ±p_max, so an unbounded range cannot be tracked).
- MIT joints: the position range, seen from the motor (``motor = (joint - offset) * direction``),
  must lie within ±p_max. Servo joints: within the status frame's ±3276.7° (at the output, or at
  the rotor for ``servo_position: rotor`` models).
- ``velocity``, ``acceleration`` and ``jerk`` are required and positive; velocity at most the motor's
  v_max. ``torque`` defaults to and may not exceed the motor's t_max.
- Bus load: rejected when the nominal load of a bus exceeds 80 % at ``rate_hz`` (see
  :mod:`akarm.config.busload`).

Every problem found is collected, with its file, 1-based line and a fix, and raised together as one
:class:`~akarm.ConfigError`; YAML syntax errors and URDF parse errors become problems too.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from akarm.config import BusConfig, Friction, Gains, JointConfig, Limits, Payload, RobotConfig
from akarm.config.busload import LOAD_LIMIT, load_of
from akarm.config.canconfig import RESERVED_BUS_KEYS, resolve_bus
from akarm.config.urdf import Urdf, UrdfJoint, pinocchio_complaint, read_urdf
from akarm.errors import AkarmError, ConfigError, ConfigProblem, ConfigWarning, did_you_mean
from akarm.protocol.motors import Catalogue, MotorModel, default_catalogue

__all__ = ["JOINT_KEYS", "TOP_KEYS", "UrdfJoint", "load_robot", "read_urdf_joints"]

TOP_KEYS = ("name", "urdf", "tool_frame", "gravity", "payload", "rate_hz", "buses", "poses", "motors",
            "defaults", "joints", "locked")
JOINT_KEYS = ("name", "bus", "can_id", "motor", "mode", "firmware", "direction", "offset", "limits", "gains",
              "reply_id", "feedback_timeout", "max_temperature", "status_rate_hz", "can_timeout", "friction",
              "following_error", "stuck_travel", "collision")
DEFAULT_KEYS = tuple(k for k in JOINT_KEYS if k not in ("name", "can_id"))
LIMIT_KEYS = ("lower", "upper", "velocity", "acceleration", "jerk", "torque")
GAIN_KEYS = ("kp", "kd")
BUS_KEYS = ("interface", "channel", "bitrate")
PAYLOAD_KEYS = ("mass", "com")
DEFAULT_BUS = "arm"
#: Servo status frames carry position as int16 × 0.1°.
SERVO_POSITION_RANGE = math.radians(3276.7)


def read_urdf_joints(path: Path) -> tuple[dict[str, UrdfJoint], set[str]]:
    """Joints (by name, in file order) and link names of a URDF: the robot's own, not those named in
    ``<transmission>``, ``<gazebo>`` or ``<ros2_control>`` blocks (see :func:`akarm.config.urdf.read_urdf`).

    Raises:
        ValueError: the file is not a URDF, or has problems; the message says where.
        OSError: the file cannot be read.
    """
    if not Path(path).is_file():
        raise FileNotFoundError(f"URDF {path} not found")
    urdf, found = read_urdf(path)
    if found:
        raise ValueError("; ".join(f"URDF line {p.line}: {p.message}" if p.line else p.message for p in found))
    assert urdf is not None
    return dict(urdf.joints), set(urdf.links)


# --------------------------------------------------------------------------- YAML with line numbers

def _line(node: yaml.Node | None) -> int | None:
    return None if node is None else node.start_mark.line + 1


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


class _Reader:
    """Walks a composed YAML node tree, collecting problems with line numbers."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.problems: list[ConfigProblem] = []
        self.warnings: list[ConfigProblem] = []
        self.issued: list[ConfigProblem] = []
        self._ctor = yaml.SafeLoader("")

    def add(self, at: yaml.Node | int | None, message: str, fix: str = "", *, file: str | None = None,
            warning: bool = False, issue: bool = False) -> None:
        """A problem (or with ``warning``, a warning) at a node or line of the YAML, or of ``file``;
        ``issue``: a warning that :func:`load_robot` also issues as a :class:`~akarm.errors.ConfigWarning`."""
        line = at if isinstance(at, int) or at is None else _line(at)
        problem = ConfigProblem(file or self.file, line, message, fix)
        found = self.warnings if warning else self.problems
        if problem not in found:  # `defaults:` entries are read once per joint
            found.append(problem)
            if issue:
                self.issued.append(problem)

    def sorted(self, found: list[ConfigProblem]) -> list[ConfigProblem]:
        """The robot file's own first, then other files' (the URDF); by line."""
        return sorted(found, key=lambda p: (p.file != self.file, p.file, p.line is None, p.line or 0))

    def plain(self, node: yaml.Node) -> Any:
        try:
            return self._ctor.construct_object(node, deep=True)
        except yaml.YAMLError as e:
            self.add(node, f"cannot read this value: {getattr(e, 'problem', e)}", "write a plain YAML value")
            return None

    def mapping(self, node: yaml.Node, what: str, allowed: tuple[str, ...]) -> dict[str, tuple[yaml.Node, yaml.Node]]:
        """Key → (key node, value node); reports non-mappings, unknown and duplicate keys."""
        if not isinstance(node, yaml.MappingNode):
            self.add(node, f"{what} must be a mapping (key: value lines), got {self._kind(node)}",
                     "write `key: value` lines, or {key: value, ...}")
            return {}
        out: dict[str, tuple[yaml.Node, yaml.Node]] = {}
        for knode, vnode in node.value:
            key = self.plain(knode)
            if not isinstance(key, str):
                self.add(knode, f"{what}: key {key!r} is not a name", "keys are names such as " + allowed[0])
                continue
            if key in out:
                self.add(knode, f"{what}: {key!r} is given twice (first on line {_line(out[key][0])})",
                         "remove one of them")
                continue
            if allowed and key not in allowed:
                self.add(knode, f"{what}: unknown key {key!r}{did_you_mean(key, allowed)}",
                         "known keys: " + ", ".join(allowed))
                continue
            out[key] = (knode, vnode)
        return out

    def free_mapping(self, node: yaml.Node, what: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
        """A mapping with user-chosen keys (bus names, pose names, motor names)."""
        return self.mapping(node, what, ())

    @staticmethod
    def _kind(node: yaml.Node) -> str:
        if isinstance(node, yaml.MappingNode):
            return "a mapping"
        if isinstance(node, yaml.SequenceNode):
            return "a list"
        return f"{node.value!r}" if node.value != "" else "nothing"

    def number(self, node: yaml.Node, what: str, *, positive: bool = False, minimum: float | None = None,
               maximum: float | None = None, fix: str = "") -> float | None:
        v = self.plain(node) if isinstance(node, yaml.ScalarNode) else node
        if not _is_number(v) or (isinstance(v, float) and not math.isfinite(v)):
            self.add(node, f"{what} must be a number, got {self._kind(node)}", fix or "write a number")
            return None
        v = float(v)  # type: ignore[arg-type]  # a number, checked above
        if positive and not v > 0:
            self.add(node, f"{what} must be positive, got {v:g}", fix or "give a value above 0")
            return None
        if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
            lo = "" if minimum is None else f"{minimum:g}"
            hi = "" if maximum is None else f"{maximum:g}"
            self.add(node, f"{what} must be within {lo}..{hi}, got {v:g}", fix or f"give a value in {lo}..{hi}")
            return None
        return v

    def integer(self, node: yaml.Node, what: str, minimum: int, maximum: int, fix: str = "") -> int | None:
        v = self.plain(node) if isinstance(node, yaml.ScalarNode) else node
        if isinstance(v, bool) or not isinstance(v, int):
            self.add(node, f"{what} must be a whole number, got {self._kind(node)}",
                     fix or f"write a whole number in {minimum}..{maximum}")
            return None
        if not minimum <= v <= maximum:
            self.add(node, f"{what} must be within {minimum}..{maximum}, got {v}",
                     fix or f"give a value in {minimum}..{maximum}")
            return None
        return v

    def string(self, node: yaml.Node, what: str, fix: str = "") -> str | None:
        v = self.plain(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(v, str) or not v:
            self.add(node, f"{what} must be a name, got {self._kind(node)}", fix or "write a name")
            return None
        return v

    def choice(self, node: yaml.Node, what: str, allowed: tuple[str, ...]) -> str | None:
        v = self.plain(node) if isinstance(node, yaml.ScalarNode) else None
        if v not in allowed:
            shown = repr(v) if isinstance(node, yaml.ScalarNode) else self._kind(node)
            hint = did_you_mean(v, allowed) if isinstance(v, str) else ""
            self.add(node, f"{what} must be {' or '.join(allowed)}, got {shown}{hint}", f"use {' or '.join(allowed)}")
            return None
        return str(v)

    def vector(self, node: yaml.Node, what: str, length: int | None = None) -> list[float] | None:
        if not isinstance(node, yaml.SequenceNode):
            self.add(node, f"{what} must be a list of numbers, got {self._kind(node)}", "write [x, y, ...]")
            return None
        if length is not None and len(node.value) != length:
            self.add(node, f"{what} must have {length} numbers, got {len(node.value)}",
                     f"give exactly {length} numbers")
            return None
        out = [self.number(item, f"{what}[{i}]") for i, item in enumerate(node.value)]
        if any(v is None for v in out):
            return None
        return [float(v) for v in out if v is not None]


# --------------------------------------------------------------------------- loading

def _compose(path: Path, r: _Reader) -> yaml.Node | None:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError([ConfigProblem(str(path), None, "robot file not found",
                                         "check the path (relative paths are from the current directory)")]) from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError([ConfigProblem(str(path), None, f"cannot read the robot file: {e}",
                                         "check the path and that it is a UTF-8 text file")]) from None
    try:
        return yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = mark.line + 1 if mark is not None else None
        what = " ".join(x for x in (e.context, e.problem) if x)
        raise ConfigError([ConfigProblem(str(path), line, f"not valid YAML: {what}",
                                         "fix the YAML syntax on or just before this line "
                                         "(indentation, a missing ':' or a stray quote)")]) from None
    except yaml.YAMLError as e:
        raise ConfigError([ConfigProblem(str(path), None, f"not valid YAML: {e}", "fix the YAML syntax")]) from None


def _motors(r: _Reader, node: yaml.Node, cat: Catalogue, failed: set[str]) -> Catalogue:
    """The catalogue with the file's `motors:` entries; names of entries with problems go to ``failed``."""
    for name, (knode, vnode) in r.free_mapping(node, "motors").items():
        entry = r.plain(vnode)
        found = cat.check_entry(name, entry)
        if found:
            failed.add(name.strip().upper())
            keys = {}
            if isinstance(vnode, yaml.MappingNode):
                keys = {r.plain(k): k for k, _ in vnode.value}
            for field, msg, fix in found:
                r.add(keys.get(field, knode) if field else knode, msg, fix)
            continue
        model = cat.build_entry(name, entry)
        models = {m.name.upper(): m for m in cat.values()}
        models[model.name.upper()] = model
        cat = Catalogue({m.name: m for m in models.values()})
    return cat


def _buses(r: _Reader, node: yaml.Node | None) -> dict[str, BusConfig]:
    specs: dict[str, tuple[dict[str, Any], dict[str, yaml.Node], yaml.Node | None]] = {}
    if node is None:
        specs[DEFAULT_BUS] = ({}, {}, None)
    else:
        items = r.free_mapping(node, "buses")
        if isinstance(node, yaml.MappingNode) and not node.value:
            r.add(node, "`buses:` is empty", "name at least one bus, e.g. `arm: {channel: can0}`, or drop `buses:`")
        for name, (key_node, vnode) in items.items():
            given, nodes = _bus_entry(r, name, vnode)
            if given is not None:
                specs[name] = (given, nodes, key_node)
    buses: dict[str, BusConfig] = {}
    for name, (given, nodes, knode) in specs.items():
        bus, found = resolve_bus(name, given)
        for key, message, fix in found:
            r.add(nodes.get(key, knode), message, fix)
        # a bus with problems (reported) still has its name, so its joints are checked without follow-on errors
        buses[name] = bus if bus is not None else BusConfig(name)
    return buses


def _bus_entry(r: _Reader, name: str, vnode: yaml.Node) -> tuple[dict[str, Any] | None, dict[str, yaml.Node]]:
    """A `buses:` entry: what it gives (None when it has problems) and the value node of each key."""
    if isinstance(vnode, yaml.ScalarNode):
        if vnode.value == "":
            return {}, {}  # `arm:` alone: all defaults
        channel = r.string(vnode, f"bus {name!r}", "a channel name, or {channel: ..., ...}")
        return ({"channel": channel}, {"channel": vnode}) if channel else (None, {})  # `arm: can0`: the channel
    fields = r.mapping(vnode, f"bus {name!r}", ())
    n_before = len(r.problems)
    given: dict[str, Any] = {}
    nodes = {k: v for k, (_, v) in fields.items()}
    for key, (knode, value) in fields.items():
        if key == "interface":
            given[key] = r.string(value, f"bus {name!r}: interface",
                                  "a python-can interface such as socketcan, virtual, pcan")
        elif key == "channel":
            ch = r.plain(value)
            if isinstance(ch, int) and not isinstance(ch, bool):
                given[key] = str(ch)  # kvaser/ixxat channels may be numbers
            else:
                given[key] = r.string(value, f"bus {name!r}: channel")
        elif key == "bitrate":
            given[key] = r.integer(value, f"bus {name!r}: bitrate", 10_000, 1_000_000, "AK drivers use 1000000 bit/s")
        elif hint := did_you_mean(key, BUS_KEYS):
            r.add(knode, f"bus {name!r}: unknown key {key!r}{hint}",
                  "known keys: " + ", ".join(BUS_KEYS) + ", and the keyword arguments of python-can's bus for "
                  "the interface")
        elif key in RESERVED_BUS_KEYS:
            r.add(knode, f"bus {name!r}: {key!r} is set by akarm", "remove it")
        elif not key.isidentifier():
            r.add(knode, f"bus {name!r}: {key!r} is not a keyword argument name", "use python-can's argument names, "
                  "e.g. device_id, app_name, serial, fd, data_bitrate")
        else:
            given[key] = r.plain(value)  # a keyword argument of the interface's bus, passed through
    return (given if len(r.problems) == n_before else None), nodes


def _clip(x: float, joint: UrdfJoint) -> float:
    """``x`` within the URDF joint's limits (continuous joints have none)."""
    if joint.lower is None or joint.upper is None:
        return x
    return min(max(x, joint.lower), joint.upper)


@dataclass
class _Field:
    """A joint key's value node, from the joint itself or from `defaults:`."""

    key: yaml.Node
    value: yaml.Node


def _merged(joint: Mapping[str, tuple[yaml.Node, yaml.Node]], defaults: Mapping[str, tuple[yaml.Node, yaml.Node]],
            r: _Reader, key: str, subkeys: tuple[str, ...]) -> dict[str, _Field]:
    """A limits/gains mapping merged key by key: the joint's own entries over those of `defaults:`."""
    out: dict[str, _Field] = {}
    if key in defaults:
        for k, (kn, vn) in r.mapping(defaults[key][1], f"defaults: {key}", subkeys).items():
            out[k] = _Field(kn, vn)
    if key in joint:
        for k, (kn, vn) in r.mapping(joint[key][1], key, subkeys).items():
            out[k] = _Field(kn, vn)
    return out


class _Loader:
    def __init__(self, path: Path, catalogue: Catalogue | None) -> None:
        self.path = path
        self.joint_entries = 0  # items under joints:, valid or not
        self.failed_motors: set[str] = set()  # `motors:` entries with problems (already reported)
        self.seen_ids: dict[tuple[str, int], tuple[str, int | None]] = {}  # (bus, CAN ID) -> joint, line
        self.driven: dict[str, int | None] = {}  # names under joints: (valid or not) -> line
        self.joints_key: yaml.Node | None = None  # the `joints:` key, where joint-set findings are reported
        self.torque_lines: dict[str, int | None] = {}  # joint -> line of its torque limit (or motor)
        self._torque_at: yaml.Node | None = None
        self.r = _Reader(str(path))
        self.catalogue = catalogue if catalogue is not None else default_catalogue()

    def load(self, rate_override: float | None) -> RobotConfig:
        r = self.r
        root = _compose(self.path, r)
        if root is None:
            raise ConfigError([ConfigProblem(str(self.path), None, "the robot file is empty",
                                             "describe the robot: name, urdf, joints (see docs)")])
        top = r.mapping(root, "the robot file", TOP_KEYS)
        if not isinstance(root, yaml.MappingNode):
            raise ConfigError(r.problems)

        name = self.path.stem
        if "name" in top:
            name = r.string(top["name"][1], "name") or name

        urdf_path, urdf = self._urdf(top, root)

        cat = self.catalogue
        if "motors" in top:
            cat = _motors(r, top["motors"][1], cat, self.failed_motors)

        buses = _buses(r, top["buses"][1] if "buses" in top else None)

        rate_hz: float | None = 500.0
        if "rate_hz" in top:
            rate_hz = r.number(top["rate_hz"][1], "rate_hz", positive=True, fix="give the loop rate in Hz, e.g. 500")
        rate_line = _line(top["rate_hz"][0]) if "rate_hz" in top else None
        if rate_override is not None:
            if not _is_number(rate_override) or not rate_override > 0:
                r.add(None, f"rate_hz override must be a positive number, got {rate_override!r}", "pass e.g. 500")
                rate_override = None
            else:
                rate_hz = float(rate_override)
                rate_line = None

        gravity = (0.0, 0.0, -9.81)
        if "gravity" in top:
            g = r.vector(top["gravity"][1], "gravity", 3)
            if g is not None:
                gravity = (g[0], g[1], g[2])

        tool_frame = None
        if "tool_frame" in top:
            tool_frame = r.string(top["tool_frame"][1], "tool_frame")
            frames = set(urdf.links) | set(urdf.joints) if urdf is not None else set()
            if tool_frame and urdf is not None and tool_frame not in frames:
                r.add(top["tool_frame"][1], f"tool_frame {tool_frame!r} is not a link or joint of the URDF"
                      f"{did_you_mean(tool_frame, sorted(frames))}",
                      "name a URDF link (e.g. the flange link), or drop tool_frame to use the last link")

        payload = None
        if "payload" in top:
            payload = self._payload(top["payload"][1])

        defaults: dict[str, tuple[yaml.Node, yaml.Node]] = {}
        if "defaults" in top:
            defaults = r.mapping(top["defaults"][1], "defaults", DEFAULT_KEYS)

        joints: list[JointConfig] = []
        if "joints" not in top:
            r.add(root, "no `joints:` list", "list the actuated joints under `joints:`")
        else:
            joints = self._joints(top["joints"], defaults, buses, cat, urdf)
        locked: dict[str, float] = {}
        if urdf is not None:
            locked = self._locked(top, root, urdf)

        poses: dict[str, tuple[float, ...]] = {}
        if "poses" in top:
            poses = self._poses(top["poses"][1], joints)

        if rate_hz is not None:  # with the joints that are valid: a lower bound when some are not
            for bname, bus in buses.items():
                on_bus = [j for j in joints if j.bus == bname]
                load = load_of(bname, bus.bitrate, rate_hz, on_bus)
                if load.over_limit:
                    given = "" if rate_line is not None else " (given as an override)"
                    r.add(rate_line, f"rate_hz {rate_hz:g}{given} puts {load.percent_nominal:.0f} % "
                          f"(worst case {load.percent:.0f} %) on bus {bname!r}, over the "
                          f"{100 * LOAD_LIMIT:.0f} % limit",
                          f"lower rate_hz to at most {math.floor(load.max_rate_hz_nominal)} Hz, or move joints "
                          "to another bus")

        if r.problems:
            raise ConfigError(r.sorted(r.problems))
        assert urdf_path is not None and rate_hz is not None
        config = RobotConfig(name=name, urdf=urdf_path, buses=buses, joints=tuple(joints), rate_hz=rate_hz,
                             source=self.path, tool_frame=tool_frame, gravity=gravity, payload=payload, poses=poses,
                             catalogue=cat, locked=locked)
        self._gravity(config, top)
        if r.problems:
            raise ConfigError(r.sorted(r.problems))
        return replace(config, warnings=tuple(r.sorted(r.warnings)))

    # ---------------------------------------------------------------- pieces

    def _urdf(self, top: Mapping[str, tuple[yaml.Node, yaml.Node]], root: yaml.Node
              ) -> tuple[Path | None, Urdf | None]:
        """The URDF's path and what it declares; ``None`` for the latter when it has problems
        (reported, each at its line of the URDF), so that joint checks against it are skipped."""
        r = self.r
        if "urdf" not in top:
            r.add(root, "no `urdf:` given", "add `urdf: NAME.urdf` (a path relative to this file)")
            return None, None
        node = top["urdf"][1]
        text = r.string(node, "urdf", "the URDF's path, relative to this file")
        if text is None:
            return None, None
        path = Path(os.path.expanduser(text))
        if not path.is_absolute():
            path = self.path.parent / path
        path = path.resolve()
        if not path.is_file():
            r.add(node, f"URDF file {str(path)!r} not found",
                  "give the URDF's path relative to this YAML file (or an absolute path)")
            return path, None
        urdf, found = read_urdf(path)
        for p in found:
            r.add(p.line, f"URDF: {p.message}", p.fix, file=str(path))
        if urdf is None or found:
            return path, None
        complaint = pinocchio_complaint(path)
        if complaint is not None:
            r.add(node, f"URDF {path.name} is not a valid robot model: {complaint}",
                  "fix the URDF (unique link names, every joint a known type, parent and child link)")
            return path, None
        return path, urdf

    def _payload(self, node: yaml.Node) -> Payload | None:
        r = self.r
        f = r.mapping(node, "payload", PAYLOAD_KEYS)
        if "mass" not in f:
            if isinstance(node, yaml.MappingNode):
                r.add(node, "payload needs `mass` (kg)", "write payload: {mass: 0.5, com: [0, 0, 0.04]}")
            return None
        mass = r.number(f["mass"][1], "payload mass", minimum=0.0, fix="give the payload mass in kg")
        com: list[float] | None = [0.0, 0.0, 0.0]
        if "com" in f:
            com = r.vector(f["com"][1], "payload com", 3)
        if mass is None or com is None:
            return None
        return Payload(mass, (com[0], com[1], com[2]))

    def _joints(self, item: tuple[yaml.Node, yaml.Node], defaults: Mapping[str, tuple[yaml.Node, yaml.Node]],
                buses: Mapping[str, BusConfig], cat: Catalogue, urdf: Urdf | None) -> list[JointConfig]:
        r = self.r
        knode, node = item
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            r.add(node, "`joints:` must be a non-empty list of joints", "write `- name: JOINT` items under joints:")
            return []
        self.joint_entries = len(node.value)
        out: list[JointConfig] = []
        seen_names: dict[str, int | None] = {}
        for jnode in node.value:
            config = self._joint(jnode, defaults, buses, cat, urdf, seen_names)
            if config is not None:
                out.append(config)
        self.driven = seen_names
        self.joints_key = knode
        return out

    def _joint(self, jnode: yaml.Node, defaults: Mapping[str, tuple[yaml.Node, yaml.Node]],
               buses: Mapping[str, BusConfig], cat: Catalogue, urdf: Urdf | None,
               seen_names: dict[str, int | None]) -> JointConfig | None:
        r = self.r
        n_before = len(r.problems)
        own = r.mapping(jnode, "joint", JOINT_KEYS)
        if not isinstance(jnode, yaml.MappingNode):
            return None

        def get(key: str) -> yaml.Node | None:
            if key in own:
                return own[key][1]
            if key in defaults:
                return defaults[key][1]
            return None

        # name and URDF joint
        name = None
        if "name" not in own:
            r.add(jnode, "a joint without `name:`", "give the URDF joint name: `- name: JOINT`")
        else:
            name = r.string(own["name"][1], "joint name")
        label = f"joint {name!r}" if name else "joint"
        uj: UrdfJoint | None = None
        if name is not None:
            if name in seen_names:
                r.add(own["name"][1], f"{label} is listed twice (first on line {seen_names[name]})",
                      "list every joint once")
            seen_names.setdefault(name, _line(own["name"][1]))
            if urdf is not None:
                uj = self._urdf_joint(urdf, name, own["name"][1], label)

        # bus and CAN ID
        bus = None
        bnode = get("bus")
        if bnode is None:
            if len(buses) == 1:
                bus = next(iter(buses))
            else:
                r.add(jnode, f"{label} has no `bus:` and there are {len(buses)} buses",
                      "add `bus:` with one of " + ", ".join(buses))
        else:
            bus = r.string(bnode, f"{label}: bus")
            if bus is not None and bus not in buses:
                r.add(bnode, f"{label}: unknown bus {bus!r}{did_you_mean(bus, list(buses))}",
                      "buses are: " + ", ".join(buses) + " (define others under `buses:`)")
                bus = None
        can_id = None
        id_node = own["can_id"][1] if "can_id" in own else None
        if id_node is None:
            r.add(jnode, f"{label} has no `can_id:`", "give the motor's CAN ID (1-127)")
        else:
            can_id = r.integer(id_node, f"{label}: can_id", 1, 127,
                               "CAN IDs 1-127 (0 is the host's); set the motor's ID with CubeMars' tool")
        if bus is not None and can_id is not None and id_node is not None:
            if (bus, can_id) in self.seen_ids:
                other, other_line = self.seen_ids[(bus, can_id)]
                r.add(id_node, f"{label}: CAN ID {can_id} on bus {bus!r} is already used by joint {other!r} "
                      f"(line {other_line})", "give every motor on a bus its own CAN ID")
            else:
                self.seen_ids[(bus, can_id)] = (name or "?", _line(id_node))

        # motor
        motor: MotorModel | None = None
        mnode = get("motor")
        if mnode is None:
            r.add(jnode, f"{label} has no `motor:`", "name its AK model, e.g. `motor: AK80-9`")
        else:
            mname = r.string(mnode, f"{label}: motor")
            if mname is not None:
                if mname in cat:
                    motor = cat.get(mname)
                elif mname.strip().upper() in self.failed_motors:
                    pass  # its entry under `motors:` has problems, reported there
                else:
                    r.add(mnode, f"{label}: unknown motor model {mname!r}{did_you_mean(mname.upper(), cat.names())}",
                          "known models: " + ", ".join(cat.names()) + "; or define it under `motors:`")

        mode = "mit"
        if (node := get("mode")) is not None:
            mode = r.choice(node, f"{label}: mode", ("mit", "servo")) or "mit"
        firmware: str = motor.firmware if motor is not None else "v2"
        if (node := get("firmware")) is not None:
            firmware = r.choice(node, f"{label}: firmware", ("v2", "v3")) or firmware
        direction = 1
        if (node := get("direction")) is not None:
            d = r.plain(node) if isinstance(node, yaml.ScalarNode) else None
            if not _is_number(d) or d not in (1, -1):
                r.add(node, f"{label}: direction must be 1 or -1, got {d!r}",
                      "1 when joint and motor turn the same way, -1 when opposite")
            else:
                direction = int(d)
        offset = 0.0
        if (node := get("offset")) is not None:
            offset = r.number(node, f"{label}: offset") or 0.0

        extras: dict[str, Any] = {}
        if (node := get("reply_id")) is not None:
            extras["reply_id"] = r.integer(node, f"{label}: reply_id", 0, 0x7FF,
                                           "0 (the firmware default) or the motor's own CAN ID")
        node = get("feedback_timeout")
        if node is not None and not (isinstance(node, yaml.ScalarNode) and r.plain(node) is None):
            extras["feedback_timeout"] = r.number(node, f"{label}: feedback_timeout", positive=True,
                                                  fix="seconds, e.g. 0.02")
        if (node := get("max_temperature")) is not None:
            extras["max_temperature"] = r.number(node, f"{label}: max_temperature", minimum=1.0, maximum=150.0,
                                                 fix="°C, e.g. 80")
        if (node := get("status_rate_hz")) is not None:
            extras["status_rate_hz"] = r.number(node, f"{label}: status_rate_hz", minimum=1.0, maximum=500.0,
                                                fix="the motor's status rate setting, 1-500 Hz")
        if (node := get("can_timeout")) is not None:
            extras["can_timeout"] = r.number(node, f"{label}: can_timeout", minimum=0.0, fix="seconds; 0 = off")
        for key, what in (("following_error", "rad: how far the joint may be from its command"),
                          ("stuck_travel", "rad: how far the command may move while the reading repeats")):
            if (node := get(key)) is not None:
                extras[key] = r.number(node, f"{label}: {key}", positive=True, fix=f"{what}, e.g. 0.2")

        if "friction" in own or "friction" in defaults:
            fr = _merged(own, defaults, r, "friction", ("coulomb", "viscous", "offset"))
            fvals = {k: r.number(fr[k].value, f"{label}: friction {k}", minimum=None if k == "offset" else 0.0,
                                 fix="N·m (coulomb, offset) or N·m·s/rad (viscous), at the output; coulomb and "
                                     "viscous ≥ 0") for k in fr}
            if all(v is not None for v in fvals.values()):
                extras["friction"] = Friction(**fvals)  # type: ignore[arg-type]
        if "collision" in own or "collision" in defaults:
            col = _merged(own, defaults, r, "collision", ("threshold",))
            if "threshold" in col:
                extras["collision_threshold"] = r.number(col["threshold"].value, f"{label}: collision threshold",
                                                         positive=True, fix="N·m, e.g. what `akarm identify` suggests")
        limits = self._limits(own, defaults, jnode, label, motor, mode, direction, offset, uj)
        if name is not None:
            self.torque_lines[name] = _line(self._torque_at) or _line(mnode) or _line(jnode)
        gains = self._gains(own, defaults, jnode, label, motor, mode)

        if len(r.problems) > n_before or None in (name, bus, can_id, motor, limits, gains):
            return None
        assert name is not None and bus is not None and can_id is not None and motor is not None
        assert limits is not None and gains is not None
        config = JointConfig(name=name, bus=bus, can_id=can_id, motor=motor, mode=mode,  # type: ignore[arg-type]
                             limits=limits, firmware=firmware, direction=direction,  # type: ignore[arg-type]
                             offset=offset, gains=gains, **{k: v for k, v in extras.items() if v is not None})
        return config

    def _urdf_joint(self, urdf: Urdf, name: str, at: yaml.Node, label: str) -> UrdfJoint | None:
        """The URDF joint a `joints:` entry names, when a motor can drive it; else the problem is reported."""
        r = self.r
        uj = urdf.joints.get(name)
        where = f"URDF line {uj.line}" if uj is not None else ""
        if uj is None:
            movable = [j.name for j in urdf.movable]
            r.add(at, f"{label} is not in the URDF{did_you_mean(name, list(urdf.joints))}",
                  "URDF joints are: " + (", ".join(movable) or "none"))
        elif uj.type == "fixed":
            r.add(at, f"{label} is fixed in the URDF ({where}), so no motor can drive it",
                  "make it revolute or continuous in the URDF, or remove it from joints:")
        elif uj.mimic is not None:
            r.add(at, f"{label} follows joint {uj.mimic.joint!r} in the URDF (<mimic>, {where}): it has no motor of "
                  "its own", f"drive {uj.mimic.joint!r} instead, or remove {name!r} from joints: (it is then held "
                  f"where {uj.mimic.joint!r} puts it)")
        elif uj.type not in ("revolute", "continuous"):
            r.add(at, f"{label} is {uj.type} in the URDF ({where}); akarm drives revolute and continuous joints "
                  "(AK actuators turn)", "remove it from joints: and hold it with `locked: {" + name + ": POSITION}`, "
                  "or make it revolute or continuous in the URDF")
        else:
            return uj
        return None

    def _locked(self, top: Mapping[str, tuple[yaml.Node, yaml.Node]], root: yaml.Node, urdf: Urdf
                ) -> dict[str, float]:
        """Where each URDF joint that no motor drives is held: the YAML's `locked:`, else where its
        <mimic> master puts it, else 0 within its limits (with a warning)."""
        r = self.r
        driven = set(self.driven)
        at = self.joints_key if self.joints_key is not None else root
        given: dict[str, float] = {}
        if "locked" in top:
            for name, (knode, vnode) in r.free_mapping(top["locked"][1], "locked").items():
                uj = urdf.joints.get(name)
                if uj is None:
                    r.add(knode, f"locked: {name!r} is not a joint of the URDF"
                          f"{did_you_mean(name, [j.name for j in urdf.movable])}",
                          "name a URDF joint that no motor drives: " +
                          (", ".join(j.name for j in urdf.movable if j.name not in driven) or "there is none"))
                elif name in driven:
                    r.add(knode, f"locked: {name!r} is also under joints: (driven by a motor)",
                          "a joint is either driven (joints:) or held (locked:): remove one")
                elif uj.mimic is not None:
                    r.add(knode, f"locked: {name!r} follows {uj.mimic.joint!r} in the URDF (<mimic>, URDF line "
                          f"{uj.line})", f"lock {uj.mimic.joint!r} instead; {name!r} is held where it puts it")
                elif uj.type not in ("revolute", "continuous", "prismatic"):
                    r.add(knode, f"locked: {name!r} is {uj.type} in the URDF: it has no single position",
                          "remove it: it is held at its neutral configuration")
                else:
                    unit = "m" if uj.type == "prismatic" else "rad"
                    v = r.number(vnode, f"locked: {name}", fix=f"the position ({unit}) to hold it at")
                    if v is None:
                        continue
                    if uj.lower is not None and uj.upper is not None and not uj.lower <= v <= uj.upper:
                        r.add(vnode, f"locked: {name} = {v:g} {unit} is outside its URDF limits "
                              f"[{uj.lower:g}, {uj.upper:g}] (URDF line {uj.line})", "give a position within them")
                        continue
                    given[name] = v
        held: dict[str, float] = {}
        pending = [j for j in urdf.movable if j.name not in driven and j.type in ("revolute", "continuous",
                                                                                  "prismatic")]
        for _ in range(len(pending) + 1):  # masters before the joints that mimic them
            later = []
            for j in pending:
                if j.name in given:
                    held[j.name] = given[j.name]
                elif j.mimic is not None and j.mimic.joint in held:
                    held[j.name] = j.mimic.multiplier * held[j.mimic.joint] + j.mimic.offset
                elif j.mimic is not None and j.mimic.joint in driven:
                    master = urdf.joints[j.mimic.joint]
                    held[j.name] = j.mimic.multiplier * _clip(0.0, master) + j.mimic.offset
                    r.add(at, f"URDF joint {j.name!r} follows the driven joint {master.name!r} (<mimic>, URDF line "
                          f"{j.line}); the dynamics model holds it at {held[j.name]:g} instead",
                          f"nothing to do for light parts (a gripper's second finger); else drive {j.name!r}'s "
                          "mass through its own URDF joint", warning=True, issue=True)
                elif j.mimic is not None and j.mimic.joint in urdf.joints and j.mimic.joint not in driven:
                    later.append(j)
                else:
                    held[j.name] = _clip(0.0, j)
                    unit = "m" if j.type == "prismatic" else "rad"
                    r.add(at, f"URDF joint {j.name!r} ({j.type}, URDF line {j.line}) has no motor in joints: and is "
                          f"not under locked:; it is held at {held[j.name]:g} {unit}",
                          f"say where it is: `locked: {{{j.name}: POSITION}}` ({unit}), or drive it: add it under "
                          "joints: with its motor", warning=True, issue=True)
            if not later:
                break
            pending = later
        return {name: held[name] for name in (j.name for j in urdf.movable) if name in held}

    def _gravity(self, config: RobotConfig, top: Mapping[str, tuple[yaml.Node, yaml.Node]]) -> None:
        """Will the motors hold the arm? Refuse gravity above a joint's torque limit; warn above the
        motor's rated (continuous) torque."""
        from akarm.dynamics.gravity import gravity_peaks

        r = self.r
        try:
            peaks = gravity_peaks(config)
        except AkarmError as e:
            r.add(top["urdf"][1] if "urdf" in top else None, f"the dynamics model cannot be built: {e.what}",
                  e.fix or "check the URDF and tool_frame")
            return
        for j, peak in zip(config.joints, peaks, strict=True):
            where = self.torque_lines.get(j.name)
            if peak.torque > j.limits.torque:
                limit = (f"its torque limit {j.limits.torque:g} N·m" if j.limits.torque < j.motor.t_max
                         else f"the {j.motor.name}'s {j.motor.t_max:g} N·m")
                r.add(where, f"joint {j.name!r}: gravity alone needs up to {peak.torque:.1f} N·m (at {peak.pose()}, "
                      f"payload included) over its range, above {limit}: the motor cannot hold the arm there",
                      "a stronger motor or more reduction, a narrower range (lower/upper under limits), or a "
                      "lighter arm or payload")
            elif j.motor.rated_torque is not None and peak.torque > j.motor.rated_torque:
                r.add(where, f"joint {j.name!r}: gravity needs up to {peak.torque:.1f} N·m (at {peak.pose()}), above "
                      f"the {j.motor.name}'s rated (continuous) torque {j.motor.rated_torque:g} N·m: holding such a "
                      "pose for long heats the motor until it stops on over-temperature",
                      "keep such poses short, or use a stronger motor", warning=True)

    def _limits(self, own: Mapping[str, tuple[yaml.Node, yaml.Node]],
                defaults: Mapping[str, tuple[yaml.Node, yaml.Node]], jnode: yaml.Node, label: str,
                motor: MotorModel | None, mode: str, direction: int, offset: float, uj: UrdfJoint | None
                ) -> Limits | None:
        r = self.r
        fields = _merged(own, defaults, r, "limits", LIMIT_KEYS)
        at = own["limits"][0] if "limits" in own else own["name"][1] if "name" in own else jnode
        ok = True
        values: dict[str, float] = {}
        for key, unit in (("velocity", "rad/s"), ("acceleration", "rad/s²"), ("jerk", "rad/s³")):
            if key not in fields:
                r.add(at, f"{label}: no {key} limit", f"add `{key}: ...` ({unit}) under limits (or defaults: limits)")
                ok = False
                continue
            v = r.number(fields[key].value, f"{label}: {key} limit", positive=True, fix=f"give a positive {unit} value")
            if v is None:
                ok = False
            else:
                values[key] = v
        if motor is not None and "velocity" in values and values["velocity"] > motor.v_max:
            r.add(fields["velocity"].value, f"{label}: velocity limit {values['velocity']:g} rad/s is above the "
                  f"{motor.name}'s {motor.v_max:g} rad/s", f"give at most {motor.v_max:g}")
            ok = False
        torque = motor.t_max if motor is not None else 0.0
        self._torque_at = fields["torque"].value if "torque" in fields else None
        if "torque" in fields:
            t = r.number(fields["torque"].value, f"{label}: torque limit", positive=True, fix="N·m, above 0")
            if t is None:
                ok = False
            elif motor is not None and t > motor.t_max:
                r.add(fields["torque"].value, f"{label}: torque limit {t:g} N·m is above the {motor.name}'s "
                      f"t_max {motor.t_max:g} N·m", f"give at most {motor.t_max:g}, or leave it out to use t_max")
                ok = False
            else:
                torque = t

        # position range: URDF, narrowed by the YAML
        lower = upper = None
        given: dict[str, float] = {}
        for key in ("lower", "upper"):
            if key in fields:
                v = r.number(fields[key].value, f"{label}: {key} limit", fix="rad")
                if v is None:
                    ok = False
                else:
                    given[key] = v
        if uj is not None:
            if uj.type == "continuous":
                missing = [k for k in ("lower", "upper") if k not in fields]
                if missing:
                    r.add(at, f"{label} is continuous in the URDF and has no {' or '.join(missing)} limit",
                          "give `lower:` and `upper:` (rad) under limits; the motor's position wraps at ±p_max")
                    ok = False
                lower, upper = given.get("lower"), given.get("upper")
            else:
                assert uj.lower is not None and uj.upper is not None
                lower, upper = uj.lower, uj.upper
                if "lower" in given:
                    if given["lower"] < uj.lower:
                        r.add(fields["lower"].value, f"{label}: lower limit {given['lower']:g} is below the URDF's "
                              f"{uj.lower:g}", "the YAML may only narrow the URDF's range")
                        ok = False
                    lower = given["lower"]
                if "upper" in given:
                    if given["upper"] > uj.upper:
                        r.add(fields["upper"].value, f"{label}: upper limit {given['upper']:g} is above the URDF's "
                              f"{uj.upper:g}", "the YAML may only narrow the URDF's range")
                        ok = False
                    upper = given["upper"]
            if lower is not None and upper is not None and not lower < upper:
                r.add(at, f"{label}: position range [{lower:g}, {upper:g}] is empty", "give lower < upper")
                ok = False
            elif lower is not None and upper is not None and motor is not None:
                ends = sorted(((lower - offset) * direction, (upper - offset) * direction))
                if mode == "mit":
                    span, what = motor.p_max, f"the {motor.name}'s MIT position range ±{motor.p_max:g} rad"
                else:
                    scale = motor.gear_ratio if motor.servo_position == "rotor" else 1.0
                    span = SERVO_POSITION_RANGE / scale
                    what = f"the servo status frame's range ±{span:g} rad at the output"
                if ends[0] < -span or ends[1] > span:
                    src = "YAML" if given else "URDF"
                    line = (fields["lower"].value if "lower" in given else
                            fields["upper"].value if "upper" in given else own["name"][1] if "name" in own else jnode)
                    r.add(line, f"{label}: position range [{lower:g}, {upper:g}] rad ({src}) is motor "
                          f"[{ends[0]:g}, {ends[1]:g}] rad with direction {direction} and offset {offset:g}, "
                          f"outside {what}",
                          "narrow it with `lower:`/`upper:` under limits, or change the offset")
                    ok = False
        if not ok or uj is None or lower is None or upper is None or motor is None:
            return None
        return Limits(lower=lower, upper=upper, velocity=values["velocity"], acceleration=values["acceleration"],
                      jerk=values["jerk"], torque=torque)

    def _gains(self, own: Mapping[str, tuple[yaml.Node, yaml.Node]],
               defaults: Mapping[str, tuple[yaml.Node, yaml.Node]], jnode: yaml.Node, label: str,
               motor: MotorModel | None, mode: str) -> Gains | None:
        r = self.r
        fields = _merged(own, defaults, r, "gains", GAIN_KEYS)
        where = own["gains"][0] if "gains" in own else own["name"][1] if "name" in own else None
        kp_max = motor.kp_max if motor is not None else 500.0
        kd_max = motor.kd_max if motor is not None else 5.0
        values: dict[str, float] = {}
        ok = True
        for key, hi, unit in (("kp", kp_max, "N·m/rad"), ("kd", kd_max, "N·m·s/rad")):
            if key in fields:
                v = r.number(fields[key].value, f"{label}: {key}", minimum=0.0, maximum=hi,
                             fix=f"give {key} in 0..{hi:g} {unit}")
                if v is None:
                    ok = False
                else:
                    values[key] = v
            elif mode == "mit":
                r.add(where if where is not None else jnode, f"{label}: MIT joint without gain {key}",
                      f"add `gains: {{kp: ..., kd: ...}}` (kp 0-{kp_max:g}, kd 0-{kd_max:g}), or in defaults:")
                ok = False
        return Gains(**values) if ok else None

    def _poses(self, node: yaml.Node, joints: list[JointConfig]) -> dict[str, tuple[float, ...]]:
        r = self.r
        poses: dict[str, tuple[float, ...]] = {}
        n = len(joints)
        for name, (_, vnode) in r.free_mapping(node, "poses").items():
            v = r.vector(vnode, f"pose {name!r}")
            if v is None:
                continue
            if n != self.joint_entries:
                continue  # some joints have problems of their own: lengths and limits cannot be checked
            if len(v) != n:
                r.add(vnode, f"pose {name!r} has {len(v)} values for {n} joints",
                      "give one value per joint (rad), in the order of joints: " + ", ".join(j.name for j in joints))
                continue
            bad = False
            for j, x, item in zip(joints, v, vnode.value, strict=True):
                if not j.limits.lower <= x <= j.limits.upper:
                    r.add(item, f"pose {name!r}: {j.name} = {x:g} rad is outside its limits "
                          f"[{j.limits.lower:g}, {j.limits.upper:g}]", "give a value within the joint's limits")
                    bad = True
            if not bad:
                poses[name] = tuple(v)
        return poses


def load_robot(
    path: str | os.PathLike[str],
    *,
    interface: str | None = None,
    channel: str | Mapping[str, str] | None = None,
    bitrate: int | None = None,
    rate_hz: float | None = None,
    catalogue: Catalogue | None = None,
) -> RobotConfig:
    """Read and validate a robot YAML file.

    Args:
        path: the robot YAML (its ``urdf:`` is relative to it).
        interface, channel, bitrate: bus overrides, applied with :meth:`RobotConfig.with_bus`
            (``channel`` may map bus names to channels).
        rate_hz: loop-rate override, Hz (validated against the bus load like the file's own).
        catalogue: the motor catalogue to start from (default: :func:`akarm.protocol.motors.default_catalogue`).

    Returns:
        the configuration; ``config.warnings`` lists what was accepted with a warning (URDF joints held
        at a default position, gravity above a motor's rated torque), each with its line and fix.

    Warns:
        ConfigWarning: for each URDF joint held at a default position (the file does not say where).

    Raises:
        ConfigError: listing every problem found, each with file, line and fix.
    """
    p = Path(path)
    loader = _Loader(p, catalogue)
    config = loader.load(rate_hz)
    for w in loader.r.issued:
        warnings.warn(str(w), ConfigWarning, stacklevel=2)
    if interface is not None or channel is not None or bitrate is not None:
        config = config.with_bus(interface=interface, channel=channel, bitrate=bitrate)
    return config
