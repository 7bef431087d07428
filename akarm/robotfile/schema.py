"""The robot file's format, declared once: every key, its type, default, allowed values and meaning.

:data:`ROBOT_FILE` (at the end of this module) is the whole format; the loader
(:mod:`akarm.robotfile.load`) reads a file with it, the reference (``docs/robot-file.md``,
:mod:`akarm.robotfile.reference`) and the starter (:mod:`akarm.robotfile.starter`) are written
from it. Reading reports, each at its line and with a fix, and all at once:

- unknown keys (with the nearest known one: ``did you mean 'velocity'?``), keys given twice,
  names that are not text;
- values of the wrong type (a list where a number belongs), outside their range, not one of the
  allowed choices;
- required keys that are missing (for joints: after ``defaults:`` are merged in, see :func:`merged`).

What depends on more than one value (the URDF, the motor catalogue, other joints, the bus) is not
here: :mod:`akarm.robotfile.checks` does it on what this module read. A new key is one
:class:`Key` line in its :class:`Section` (and, for a joint setting, a field of
:class:`~akarm.config.JointConfig` of the same name).

The walk is as deep as the schema (a handful of levels), whatever the file holds.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import MISSING, dataclass, fields
from typing import Any

import yaml

from akarm.config import MAX_RATE_HZ, MIN_RATE_HZ, GripperConfig, JointConfig, Payload, RobotConfig
from akarm.config.canconfig import RESERVED_BUS_KEYS
from akarm.files import over
from akarm.protocol.motors import did_you_mean
from akarm.robotfile.nodes import MAX_JOINTS, NOT_SCALAR, Findings, describe, plain, scalar

__all__ = [
    "BUS",
    "COLLISION",
    "DEFAULTS",
    "FRICTION",
    "GAINS",
    "GRIPPER",
    "INVALID",
    "JOINT",
    "LIMITS",
    "NO_DEFAULT",
    "PAYLOAD",
    "ROBOT_FILE",
    "SELF_COLLISION",
    "WORKSPACE",
    "Choice",
    "Context",
    "Fields",
    "Integer",
    "Item",
    "Key",
    "Kind",
    "ListOf",
    "Name",
    "Number",
    "PassThrough",
    "Raw",
    "Section",
    "Table",
    "Vector",
    "merged",
    "missing",
]


class _Invalid:
    def __repr__(self) -> str:
        return "INVALID"

    def __bool__(self) -> bool:
        return False


#: the value of a key that was given but has a problem (already reported)
INVALID: Any = _Invalid()


class _NoDefault:
    def __repr__(self) -> str:
        return "NO_DEFAULT"


#: a key's default when it has none (or one that depends on something else: see ``Key.default_text``)
NO_DEFAULT: Any = _NoDefault()


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _join(owner: str, what: str) -> str:
    return f"{owner}: {what}" if owner else what


@dataclass(frozen=True)
class Item:
    """One key of a mapping (or one item of a list) as read: its nodes and its value.

    Attributes:
        key: the key's node (``None`` for a list item, or a section merged in from ``defaults:`` only).
        node: the value's node.
        value: the value (a number, a name, :class:`Fields` for a section, ...), or :data:`INVALID`.
    """

    key: yaml.Node | None
    node: yaml.Node
    value: Any

    @property
    def ok(self) -> bool:
        return self.value is not INVALID


class Fields(dict[str, Item]):
    """A mapping as read: key → :class:`Item`, in file order; ``flawed`` when anything in it had a problem."""

    def __init__(self, items: Iterable[tuple[str, Item]] = (), *, flawed: bool = False) -> None:
        super().__init__(items)
        self.flawed = flawed

    def value(self, key: str, default: Any = None) -> Any:
        """The key's value; ``default`` when it is not given or has a problem."""
        item = self.get(key)
        return default if item is None or not item.ok else item.value


@dataclass(frozen=True)
class Context:
    """Where a value is read: ``owner`` names the entry it belongs to in messages (``joint 'elbow'``,
    ``defaults``, ``bus 'arm'``, nothing at the top); ``required``: report missing required keys here
    (not under ``joints:`` and ``defaults:``, which are only complete once merged)."""

    owner: str = ""
    required: bool = True


class Kind:
    """How a value is written. ``read`` gives the value, or :data:`INVALID` after reporting why."""

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        raise NotImplementedError

    def text(self) -> str:
        """The type, for the reference."""
        raise NotImplementedError


# --------------------------------------------------------------------------- scalars


def _range_text(lo: float | str | None, hi: float | str | None) -> str:
    def show(x: float | str | None) -> str:
        return "" if x is None else x if isinstance(x, str) else f"{x:g}"
    return f"{show(lo)}..{show(hi)}"


@dataclass(frozen=True)
class Number(Kind):
    """A finite number, read as a float. A bound given as a name (``"kp_max"``) is the motor's and is
    checked against it (:meth:`within`) once the motor is known; ``null`` reads as ``None``."""

    minimum: float | str | None = None
    maximum: float | str | None = None
    positive: bool = False
    unit: str = ""
    null: bool = False

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        v = scalar(node, found)
        if self.null and v is None:
            return None
        if not _is_number(v) or (isinstance(v, float) and not math.isfinite(v)):
            found.add(node, f"{what} must be a number, got {describe(node)}", fix or "write a number")
            return INVALID
        v = float(v)
        if self.positive and not v > 0:
            found.add(node, f"{what} must be positive, got {v:g}", fix or "give a value above 0")
            return INVALID
        if isinstance(self.minimum, str) or isinstance(self.maximum, str):
            return v  # the motor's range: checked with it
        return self.within(v, node, what, fix, found)

    def within(self, v: float, node: yaml.Node, what: str, fix: str, found: Findings,
               **bounds: float) -> Any:
        """``v``, or :data:`INVALID` (reported) when outside the range; named bounds come from ``bounds``."""
        lo = bounds.get(self.minimum) if isinstance(self.minimum, str) else self.minimum
        hi = bounds.get(self.maximum) if isinstance(self.maximum, str) else self.maximum
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            rng = _range_text(lo, hi)
            found.add(node, f"{what} must be within {rng}, got {v:g}", fix or f"give a value in {rng}")
            return INVALID
        return v

    def text(self) -> str:
        out = "number"
        if self.positive:
            out += " > 0"
        if self.minimum is not None or self.maximum is not None:
            out += " " + _range_text(self.minimum, self.maximum)
        return f"{out} ({self.unit})" if self.unit else out


@dataclass(frozen=True)
class Integer(Kind):
    """A whole number within ``minimum..maximum``."""

    minimum: int
    maximum: int

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        v = scalar(node, found)
        if isinstance(v, bool) or not isinstance(v, int):
            found.add(node, f"{what} must be a whole number, got {describe(node)}",
                      fix or f"write a whole number in {self.minimum}..{self.maximum}")
            return INVALID
        if not self.minimum <= v <= self.maximum:
            found.add(node, f"{what} must be within {self.minimum}..{self.maximum}, got {v}",
                      fix or f"give a value in {self.minimum}..{self.maximum}")
            return INVALID
        return v

    def text(self) -> str:
        return f"whole number {self.minimum}..{self.maximum}"


@dataclass(frozen=True)
class Name(Kind):
    """Non-empty text (a name, a path); with ``numbers``, a whole number is taken as its text too."""

    numbers: bool = False

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        v = scalar(node, found)
        if self.numbers and isinstance(v, int) and not isinstance(v, bool):
            return str(v)
        if not isinstance(v, str) or not v:
            found.add(node, f"{what} must be a name, got {describe(node)}", fix or "write a name")
            return INVALID
        return v

    def text(self) -> str:
        return "name or number" if self.numbers else "name"


@dataclass(frozen=True)
class Choice(Kind):
    """One of ``options`` (names or numbers; ``true``/``false`` are never a number here)."""

    options: tuple[str | int, ...]

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        v = scalar(node, found)
        for option in self.options:
            if not isinstance(v, bool) and type(v) in (str, int, float) and v == option \
                    and isinstance(v, str) == isinstance(option, str):
                return option
        said = " or ".join(str(o) for o in self.options)
        shown = repr(v) if v is not NOT_SCALAR else describe(node)
        hint = did_you_mean(v, [str(o) for o in self.options]) if isinstance(v, str) else ""
        found.add(node, f"{what} must be {said}, got {shown}{hint}", fix or f"use {said}")
        return INVALID

    def text(self) -> str:
        return " \\| ".join(f"`{o}`" for o in self.options)


@dataclass(frozen=True)
class Vector(Kind):
    """A list of numbers (of ``length`` numbers when given), read as a list of floats."""

    length: int | None = None
    unit: str = ""

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        if not isinstance(node, yaml.SequenceNode):
            found.add(node, f"{what} must be a list of numbers, got {describe(node)}", "write [x, y, ...]")
            return INVALID
        if self.length is not None and len(node.value) != self.length:
            found.add(node, f"{what} must have {self.length} numbers, got {len(node.value)}",
                      f"give exactly {self.length} numbers")
            return INVALID
        each = Number()
        out = [each.read(item, f"{what}[{i}]", "", found, ctx) for i, item in enumerate(node.value)]
        return INVALID if any(v is INVALID for v in out) else out

    def text(self) -> str:
        out = "list of numbers" if self.length is None else f"{self.length} numbers"
        return f"{out} ({self.unit})" if self.unit else out


@dataclass(frozen=True)
class Raw(Kind):
    """Any YAML value, taken as it is (checked elsewhere: a motor entry by the catalogue)."""

    what: str = "any value"

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        return plain(node, found)

    def text(self) -> str:
        return self.what


# --------------------------------------------------------------------------- mappings and lists


@dataclass(frozen=True)
class Key:
    """One key of a :class:`Section`.

    Attributes:
        name: the key.
        kind: its type (:class:`Number`, :class:`Choice`, a nested :class:`Section`, ...).
        doc: what it means, one line.
        default: the value when it is left out (:data:`NO_DEFAULT`: none, or ``default_text``).
        default_text: the default in words, when it depends on something else (``the motor's t_max``).
        required: it must be given (a required :class:`Section` is required through its own required keys).
        fix: what to write, for any problem with it (else the type's own advice).
        shared: a joint key that ``defaults:`` may give for every joint.
    """

    name: str
    kind: Kind
    doc: str
    default: Any = NO_DEFAULT
    default_text: str = ""
    required: bool = False
    fix: str = ""
    shared: bool = True

    def default_shown(self) -> str:
        """The default, for the reference and the starter."""
        if self.default_text:
            return self.default_text
        if self.default is NO_DEFAULT:
            return ""
        if isinstance(self.default, tuple | list):
            return "[" + ", ".join(f"{x:g}" for x in self.default) + "]"
        return f"{self.default:g}" if isinstance(self.default, float) else str(self.default)


@dataclass(frozen=True)
class PassThrough:
    """A section's keys besides its own, passed on as they are (python-can keyword arguments): unless
    near one of the section's own keys (a typo), ``reserved``, or not a keyword argument name."""

    doc: str
    reserved: tuple[str, ...] = ()
    examples: str = ""


@dataclass(frozen=True)
class Section(Kind):
    """A mapping with known keys.

    Attributes:
        title: what the mapping is called in messages (``limits``, ``joint``, ``the robot file``).
        keys: its keys, in the order the reference lists them.
        doc: what it is, for the reference.
        term: how one of its values is named in messages (``{key} limit``: ``velocity limit``).
        missing: the message for a missing required key (``{label}``: the mapping, ``{owner}``: its entry).
        nested: a part of its owner's entry (``limits`` of a joint), named after the owner in messages;
            else an entry of its own (``defaults``, a joint, a bus), named by its title or its table.
        named_by: the key whose value names the entry in messages (a joint's ``name``).
        shorthand: the key a plain value stands for (``arm: can0`` is ``arm: {channel: can0}``).
        extra: what keys besides its own mean (:class:`PassThrough`); none: they are unknown keys.
        required: its required keys are reported missing where it is read (not for joints, which
            ``defaults:`` completes: see :func:`missing`).
    """

    title: str
    keys: tuple[Key, ...]
    doc: str = ""
    term: str = "{key}"
    missing: str = "{label} has no `{key}:`"
    nested: bool = True
    named_by: str = ""
    shorthand: str = ""
    extra: PassThrough | None = None
    required: bool = True

    def __getitem__(self, name: str) -> Key:
        for k in self.keys:
            if k.name == name:
                return k
        raise KeyError(name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(k.name for k in self.keys)

    def label(self, owner: str) -> str:
        """The mapping in messages: ``joint 'elbow': limits``, ``defaults``, ``the robot file``."""
        return _join(owner, self.title) if self.nested else owner or self.title

    def what(self, owner: str, key: str) -> str:
        """One of its values in messages: ``joint 'elbow': velocity limit``."""
        return _join(owner, self.term.format(key=key))

    def text(self) -> str:
        return "mapping (below)"

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        owner = ctx.owner if self.nested else what
        ctx = Context(owner, ctx.required and self.required)
        before = found.count
        if self.shorthand and isinstance(node, yaml.ScalarNode):
            out = self._shorthand(node, found, ctx, fix)
        elif not isinstance(node, yaml.MappingNode):
            found.add(node, f"{self.label(owner)} must be a mapping (key: value lines), got {describe(node)}",
                      "write `key: value` lines, or {key: value, ...}")
            return INVALID
        else:
            pairs = _pairs(node, self.label(owner), found)
            if self.named_by in pairs:
                name = self._read_key(self.named_by, pairs[self.named_by], ctx, found)
                ctx = Context(f"{self.title} {name.value!r}" if name.ok else self.title, ctx.required)
                out = Fields([(self.named_by, name)])
            else:
                out = Fields()
            for key, (knode, vnode) in pairs.items():
                if key != self.named_by:
                    self._read_pair(key, knode, vnode, ctx, found, out)
            if ctx.required:
                missing(self, out, node, ctx.owner, found)
        out.flawed = found.count > before
        return out

    def _shorthand(self, node: yaml.ScalarNode, found: Findings, ctx: Context, fix: str) -> Fields:
        if node.value == "":
            return Fields()  # `arm:` alone: every default
        key = self[self.shorthand]
        value = key.kind.read(node, ctx.owner, fix or key.fix, found, ctx)
        return Fields([(self.shorthand, Item(None, node, value))])

    def _read_key(self, key: str, nodes: tuple[yaml.Node, yaml.Node], ctx: Context, found: Findings) -> Item:
        spec = self[key]
        knode, vnode = nodes
        what = self.what(ctx.owner, key) if not isinstance(spec.kind, Section) or spec.kind.nested \
            else spec.kind.title
        return Item(knode, vnode, spec.kind.read(vnode, what, spec.fix, found, ctx))

    def _read_pair(self, key: str, knode: yaml.Node, vnode: yaml.Node, ctx: Context, found: Findings,
                   out: Fields) -> None:
        if key in self.names:
            out[key] = self._read_key(key, (knode, vnode), ctx, found)
            return
        label = self.label(ctx.owner)
        hint = did_you_mean(key, self.names)
        extra = self.extra
        if extra is None or hint:
            also = f", and {extra.doc}" if extra is not None else ""
            found.add(knode, f"{label}: unknown key {key!r}{hint}", "known keys: " + ", ".join(self.names) + also)
        elif key in extra.reserved:
            found.add(knode, f"{label}: {key!r} is set by akarm", "remove it")
        elif not key.isidentifier():
            found.add(knode, f"{label}: {key!r} is not a keyword argument name", extra.examples)
        else:
            out[key] = Item(knode, vnode, plain(vnode, found))


def _pairs(node: yaml.MappingNode, label: str, found: Findings) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    """A mapping's entries by key; keys that are not text, or given twice, are reported and left out."""
    out: dict[str, tuple[yaml.Node, yaml.Node]] = {}
    for knode, vnode in node.value:
        key = plain(knode, found)
        if not isinstance(key, str):
            found.add(knode, f"{label}: key {key!r} is not a name", "write a name (quoted if it looks like a number)")
        elif key in out:
            found.add(knode, f"{label}: {key!r} is given twice (first on line {out[key][0].start_mark.line + 1})",
                      "remove one of them")
        else:
            out[key] = (knode, vnode)
    return out


@dataclass(frozen=True)
class Table(Kind):
    """A mapping whose keys the file chooses (bus names, pose names), each value of one kind.

    ``label`` names one entry in messages (``bus {name!r}``); ``entry`` says what an entry is, for the reference."""

    of: Kind
    label: str
    entry: str

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        if not isinstance(node, yaml.MappingNode):
            found.add(node, f"{what} must be a mapping (key: value lines), got {describe(node)}",
                      "write `key: value` lines, or {key: value, ...}")
            return INVALID
        before = found.count
        out = Fields()
        for name, (knode, vnode) in _pairs(node, what, found).items():
            out[name] = Item(knode, vnode, self.of.read(vnode, self.label.format(name=name), fix, found, ctx))
        out.flawed = found.count > before
        return out

    def text(self) -> str:
        return f"mapping: {self.entry}"


@dataclass(frozen=True)
class ListOf(Kind):
    """A non-empty list of entries of one :class:`Section`, at most ``most`` of them (the limit ``most_name``)."""

    of: Section
    most: int
    most_name: str

    def read(self, node: yaml.Node, what: str, fix: str, found: Findings, ctx: Context) -> Any:
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            found.add(node, f"`{what}:` must be a non-empty list of {self.of.title}s",
                      f"write `- {self.of.named_by}: ...` items under {what}:")
            return INVALID
        if len(node.value) > self.most:
            found.add(node, over(f"`{what}:` lists {len(node.value)} {self.of.title}s", self.most,
                                 f"{self.of.title}s", self.most_name),
                      f"akarm drives at most {self.most} {self.of.title}s from one robot file (the gravity check's "
                      "cost grows with the cube of their number)")
            return INVALID
        return [Item(None, item, self.of.read(item, self.of.title, fix, found, ctx)) for item in node.value]

    def text(self) -> str:
        return f"list of {self.of.title}s (below), at most {self.most}"


# --------------------------------------------------------------------------- after reading


def missing(section: Section, given: Fields, at: yaml.Node, owner: str, found: Findings) -> None:
    """Report the required keys ``given`` lacks, at ``at``; a required section's own required keys too,
    at its key when it was given (``limits: {velocity: 1}`` has no jerk limit)."""
    for key in section.keys:
        item = given.get(key.name)
        if key.required and isinstance(key.kind, Section) and key.kind.nested:
            inner = item.value if item is not None and item.ok else Fields()
            where = item.key if item is not None and item.key is not None else at
            missing(key.kind, inner, where, owner, found)
        elif key.required and item is None:
            fix = key.fix or f"add `{key.name}:` ({key.doc})"
            found.add(at, section.missing.format(label=section.label(owner), owner=owner, key=key.name), fix)


def merged(own: Fields, shared: Fields) -> Fields:
    """A joint's keys with ``defaults:`` merged in: its own first, nested sections (``limits``,
    ``gains``, ...) key by key. ``flawed`` when anything the joint uses had a problem. A section
    only ``defaults:`` gives has no key node (``None``): problems with it are the joint's."""
    out = Fields(flawed=own.flawed)
    for key in JOINT.keys:
        mine, theirs = own.get(key.name), shared.get(key.name) if key.shared else None
        if theirs is not None and (not theirs.ok or getattr(theirs.value, "flawed", False)):
            out.flawed = True
        if isinstance(key.kind, Section) and (mine is not None or theirs is not None):
            parts = [x.value for x in (theirs, mine) if x is not None and x.ok]
            node = mine.node if mine is not None else theirs.node  # type: ignore[union-attr]
            value = Fields([kv for part in parts for kv in part.items()]) if parts else INVALID
            out[key.name] = Item(mine.key if mine is not None else None, node, value)
        elif mine is not None or theirs is not None:
            out[key.name] = mine if mine is not None else theirs  # type: ignore[assignment]
    return out


def _defaults_of(cls: type) -> dict[str, Any]:
    """A dataclass's field defaults: the schema's defaults are the configuration types' own."""
    out = {}
    for f in fields(cls):
        if f.default is not MISSING:
            out[f.name] = f.default
    return out


# --------------------------------------------------------------------------- the format

_JOINT = _defaults_of(JointConfig)
_ROBOT = _defaults_of(RobotConfig)
_PAYLOAD = _defaults_of(Payload)
_GRIPPER = _defaults_of(GripperConfig)

LIMITS = Section("limits", term="{key} limit", missing="{owner}: no {key} limit", doc=(
    "A joint's limits, joint side. `defaults: limits` and a joint's own merge key by key."), keys=(
    Key("lower", Number(unit="rad"), "lower end of the position range: may only narrow the URDF's",
        default_text="the URDF's", fix="rad"),
    Key("upper", Number(unit="rad"), "upper end of the position range: may only narrow the URDF's",
        default_text="the URDF's", fix="rad"),
    Key("velocity", Number(positive=True, unit="rad/s"), "the fastest a move goes; at most the motor's v_max",
        required=True, fix="give a positive value (rad/s) under limits (or defaults: limits)"),
    Key("acceleration", Number(positive=True, unit="rad/s²"), "the largest acceleration of a move", required=True,
        fix="give a positive value (rad/s²) under limits (or defaults: limits)"),
    Key("jerk", Number(positive=True, unit="rad/s³"), "the largest jerk of a move", required=True,
        fix="give a positive value (rad/s³) under limits (or defaults: limits)"),
    Key("torque", Number(positive=True, unit="N·m"), "feed-forward and MIT torque are clamped to it; at most the "
        "motor's t_max", default_text="the motor's t_max", fix="N·m, above 0"),
))

GAINS = Section("gains", doc="MIT position and velocity gains, used while tracking (servo joints ignore them). "
                "Required for MIT joints; `defaults: gains` and a joint's own merge key by key.", keys=(
    Key("kp", Number(minimum=0.0, maximum="kp_max", unit="N·m/rad"), "stiffness, 0..the motor's kp_max (500)",
        fix="N·m/rad, 0..the motor's kp_max (500 on the catalogue's models)"),
    Key("kd", Number(minimum=0.0, maximum="kd_max", unit="N·m·s/rad"), "damping, 0..the motor's kd_max (5)",
        fix="N·m·s/rad, 0..the motor's kd_max (5 on the catalogue's models)"),
))

_FRICTION_FIX = "N·m (coulomb, offset) or N·m·s/rad (viscous), at the output; coulomb and viscous ≥ 0"
FRICTION = Section("friction", term="friction {key}", doc="Identified joint friction at the output (`akarm "
                   "identify`); left out: the motor catalogue's typical values.", keys=(
    Key("coulomb", Number(minimum=0.0, unit="N·m"), "Coulomb friction", default=0.0, fix=_FRICTION_FIX),
    Key("viscous", Number(minimum=0.0, unit="N·m·s/rad"), "viscous friction", default=0.0, fix=_FRICTION_FIX),
    Key("offset", Number(unit="N·m"), "a constant torque the model misses (a cable, a sensor bias)", default=0.0,
        fix=_FRICTION_FIX),
    Key("load", Number(minimum=0.0, maximum=1.0), "Coulomb friction's load-dependent part, N·m per N·m the motor "
        "delivers", default=0.0, fix="a share of the motor's torque, 0..1 (a real AK80-9: about 0.06)"),
    Key("torque_scale", Number(minimum=0.2, maximum=2.0), "N·m the joint gets per N·m the motor reports (a real "
        "unit's torque constant)", default=1.0, fix="a factor, 0.2..2 (`akarm identify` fits it; 1: the catalogue's)"),
))

COLLISION = Section("collision", term="collision {key}", doc="The collision reflex (`akarm.control.collision`).",
                    keys=(
    Key("threshold", Number(positive=True, unit="N·m"), "stop when the joint's external torque estimate is larger "
        "(`akarm identify` suggests one)", default_text="not checked", fix="N·m, e.g. what `akarm identify` suggests"),
))

_NAME = Key("name", Name(), "the URDF joint it drives (revolute, or continuous with lower and upper limits)",
            required=True, fix="give the URDF joint name: `- name: JOINT`", shared=False)
_CAN_ID = Key("can_id", Integer(1, 127), "the motor's CAN ID, unique on its bus", required=True, shared=False,
              fix="the motor's CAN ID, 1-127 (0 is the host's); set a motor's ID with CubeMars' tool")

JOINT = Section("joint", named_by="name", nested=False, required=False, doc=(
    "One item of `joints:`, a joint a motor drives, in the order of every joint vector (poses, telemetry). "
    "`defaults:` may give any of these keys but name and can_id for every joint."), keys=(
    _NAME,
    Key("bus", Name(), "the bus its motor is on", default_text="the only bus, when there is one"),
    _CAN_ID,
    Key("motor", Name(), "its AK model: a catalogue model (akarm/data/motors.yaml) or one under `motors:`",
        required=True, fix="name its AK model, e.g. `motor: AK80-9`"),
    Key("mode", Choice(("mit", "servo")), "MIT (force control) or servo mode", default="mit"),
    Key("firmware", Choice(("v2", "v3")), "v3: the 2024 driver boards' extended-ID MIT frames",
        default_text="the motor entry's"),
    Key("direction", Choice((1, -1)), "joint = direction × motor + offset", default=_JOINT["direction"],
        fix="1 when joint and motor turn the same way, -1 when opposite"),
    Key("offset", Number(unit="rad"), "the joint's position when the motor reads zero", default=_JOINT["offset"]),
    Key("limits", LIMITS, "position range and motion limits", required=True),
    Key("gains", GAINS, "MIT gains; required for MIT joints"),
    Key("friction", FRICTION, "identified friction", default_text="the catalogue's typical values"),
    Key("collision", COLLISION, "the collision reflex"),
    Key("reply_id", Integer(0, 0x7FF), "the arbitration ID MIT replies come on (the motor's own ID on some units)",
        default=_JOINT["reply_id"], fix="0 (the firmware default) or the motor's own CAN ID"),
    Key("feedback_timeout", Number(positive=True, unit="s", null=True), "watchdog: the arm stops when this "
        "joint's feedback is older", default_text="20 ms MIT, 3 status periods servo", fix="seconds, e.g. 0.02"),
    Key("max_temperature", Number(minimum=1.0, maximum=150.0, unit="°C"), "watchdog: the arm stops above it",
        default=_JOINT["max_temperature"], fix="°C, e.g. 80"),
    Key("status_rate_hz", Number(minimum=1.0, maximum=500.0, unit="Hz"), "servo: the status rate set in the motor",
        default=_JOINT["status_rate_hz"], fix="the motor's status rate setting, 1-500 Hz"),
    Key("can_timeout", Number(minimum=0.0, unit="s"), "MIT firmware CAN timeout, 0 = off (simulator only)",
        default=_JOINT["can_timeout"], fix="seconds; 0 = off"),
    Key("following_error", Number(positive=True, unit="rad"), "the supervisor stops the arm when the joint is "
        "further than this from its command", default_text="derived (akarm.control.safety)",
        fix="rad: how far the joint may be from its command, e.g. 0.2"),
    Key("stuck_travel", Number(positive=True, unit="rad"), "the supervisor stops the arm when the command moves "
        "this far while the reading repeats (a frozen encoder)", default_text="derived (akarm.control.safety)",
        fix="rad: how far the command may move while the reading repeats, e.g. 0.2"),
))

DEFAULTS = Section("defaults", tuple(k for k in JOINT.keys if k.shared), nested=False, required=False, doc=(
    "Joint keys shared by every joint (any joint key but name and can_id); a joint's own value wins, "
    "and `limits`, `gains`, `friction`, `collision` merge key by key."))

BUS = Section("bus", nested=False, shorthand="channel", doc=(
    "One entry of `buses:`. Left out keys come from python-can's own configuration (`CAN_INTERFACE`, "
    "`CAN_CHANNEL`, `CAN_BITRATE`, `CAN_CONFIG`, `~/can.conf`, `~/.canrc`, `can.ini`, a section named like the "
    "bus first), then akarm's defaults. A bare channel name (`aux: can1`) is `{channel: can1}`; a bus alone "
    "(`arm:`) takes every default."), keys=(
    Key("interface", Name(), "a python-can interface: socketcan, virtual, pcan, slcan, kvaser, gs_usb, ...",
        default="socketcan", fix="a python-can interface such as socketcan, virtual, pcan"),
    Key("channel", Name(numbers=True), "the interface's channel: can0, PCAN_USBBUS1, a virtual channel's name",
        default="can0", fix="a channel name, or {channel: ..., ...}"),
    Key("bitrate", Integer(10_000, 1_000_000), "bit/s", default=1_000_000, fix="AK drivers use 1000000 bit/s"),
    Key("baudrate", Integer(1_200, 12_000_000), "a serial port's (interface akarm_uart: a servo "
        "motor's UART, one per port) bit/s", default_text="921600, the AK drivers'",
        fix="AK drivers' serial ports run at 921600"),
), extra=PassThrough("the keyword arguments of python-can's bus for the interface",
                     reserved=RESERVED_BUS_KEYS,
                     examples="use python-can's argument names, e.g. device_id, app_name, serial, fd, data_bitrate"))

PAYLOAD = Section("payload", term="payload {key}", doc="A load at the tool frame: the feed-forward, the gravity "
                  "check and the collision observer count it.", keys=(
    Key("mass", Number(minimum=0.0, unit="kg"), "its mass", required=True, fix="give the payload mass in kg"),
    Key("com", Vector(3, unit="m"), "its centre of mass in the tool frame", default=_PAYLOAD["com"]),
))

GRIPPER = Section("gripper", nested=False, doc=(
    "The gripper: a motor (keys as a joint's) moving two jaws. Its motor is on the bus load like a joint's, and "
    "is never one of the arm's joints (see docs/gripper.md)."), keys=(
    Key("name", Name(), "its name: the simulated joint's, telemetry's, a dataset's column; not a joint's name",
        default="gripper"),
    Key("motor", Name(), "its AK model (catalogue or `motors:`)", required=True, fix="name its AK model, e.g. "
        "`motor: AK40-10`"),
    Key("can_id", Integer(1, 127), "the motor's CAN ID, unique on its bus", required=True,
        fix="the motor's CAN ID, 1-127"),
    Key("bus", Name(), "the bus its motor is on", default_text="the only bus, when there is one"),
    Key("mode", Choice(("mit", "servo")), "MIT (the torque law), or servo (the current loop holds the force, "
        "the position loop moves the jaws only where nothing is squeezed)", default=_GRIPPER["mode"]),
    Key("firmware", Choice(("v2", "v3")), "as a joint's", default_text="the motor entry's"),
    Key("direction", Choice((1, -1)), "1 when the jaws open as the motor turns positive, else -1",
        default=_GRIPPER["direction"]),
    Key("offset", Number(unit="rad"), "the angle past closed when the motor reads zero (`calibrate()` finds it)",
        default=_GRIPPER["offset"]),
    Key("kp", Number(minimum=0.0, maximum=500.0, unit="N·m/rad"), "MIT stiffness for moves", default=_GRIPPER["kp"]),
    Key("kd", Number(minimum=0.0, maximum=5.0, unit="N·m·s/rad"), "MIT damping", default=_GRIPPER["kd"]),
    Key("stroke", Number(positive=True, maximum=1.0, unit="m"), "the jaws' distance fully open", required=True,
        fix="m, e.g. 0.08"),
    Key("travel", Number(positive=True, unit="rad"), "motor output angle from closed (0) to fully open; the width "
        "is linear in it", required=True, fix="rad, e.g. 2.0"),
    Key("table", Raw("list of [rad, m] pairs"), "(angle, width) points from closed to open, both increasing, for "
        "a linkage; replaces the linear law", default_text="none: width linear in the angle"),
    Key("force_limit", Number(positive=True, unit="N"), "the most the jaws may ever squeeze", required=True,
        fix="N, e.g. 40"),
    Key("speed", Number(positive=True, unit="m/s"), "the jaws' approach speed", default=_GRIPPER["speed"]),
    Key("fingers", Raw("list of URDF joint names"), "the URDF joints the jaws move (mimic joints, not in the "
        "arm's chain; their mass counts as the tool's)", default_text="none"),
    Key("reply_id", Integer(0, 0x7FF), "as a joint's", default=_GRIPPER["reply_id"]),
    Key("feedback_timeout", Number(positive=True, unit="s", null=True), "watchdog, as a joint's",
        default_text="as a joint's"),
    Key("max_temperature", Number(minimum=1.0, maximum=150.0, unit="°C"), "watchdog: the arm stops above it",
        default=_GRIPPER["max_temperature"]),
    Key("status_rate_hz", Number(minimum=1.0, maximum=500.0, unit="Hz"), "servo: the status rate set in the motor "
        "(the watchdog waits three periods at least)", default=_GRIPPER["status_rate_hz"],
        fix="the motor's status rate setting, 1-500 Hz"),
))

WORKSPACE = Section("workspace", term="workspace {key}", doc="Walls: where the tool frame's origin may be (m, base "
                    "frame). A planned move whose path leaves it is refused, servoing stops at its walls, and an arm "
                    "measured outside it by more than `margin` is a safety stop. With `min`/`max` and `boxes`, the "
                    "tool may be in any of the boxes; `planes` bound it further.", keys=(
    Key("min", Vector(3, unit="m"), "the box's lower corner", fix="[x, y, z] in m, base frame"),
    Key("max", Vector(3, unit="m"), "the box's upper corner", fix="[x, y, z] in m, base frame"),
    Key("boxes", Raw("a list of {min: [x, y, z], max: [x, y, z]}"), "more boxes the tool may be in",
        default_text="none"),
    Key("planes", Raw("a list of {normal: [x, y, z], offset: d}"), "walls: the tool stays where normal · p ≤ offset "
        "(normal pointing out)", default_text="none"),
    Key("margin", Number(minimum=0.0, maximum=1.0, unit="m"), "how far outside a measured pose may be before the "
        "safety stop", default=0.02, fix="m, e.g. 0.02"),
))

SELF_COLLISION = Section("self_collision", term="self_collision {key}", doc="Self-collision: the links' shapes "
                         "checked against each other (docs/compliance.md). A planned move whose path makes two of them "
                         "come closer than `margin` is refused, servoing stops short of it, and the supervisor "
                         "stops an arm measured with two shapes touching. Neighbouring links are left out. On unless "
                         "`shapes: none`; `Arm(self_collision=False)` turns it off for one program.", keys=(
    Key("shapes", Choice(("auto", "collision", "visual", "capsules", "none")), "where the links' shapes come from: "
        "`auto` the URDF's `<collision>`, else its `<visual>`, else capsules from joint to joint; `none`: no check",
        default="auto"),
    Key("margin", Number(minimum=0.0, maximum=0.1, unit="m"), "how close two shapes may come on a planned path or "
        "while servoing", default=0.01, fix="m, e.g. 0.01"),
))

ROBOT_FILE = Section("the robot file", nested=False, doc="The top level of a robot file.", keys=(
    Key("name", Name(), "the robot's name", default_text="the file's name without .yaml"),
    Key("urdf", Name(), "its URDF: kinematics, masses, position limits", required=True,
        fix="the URDF's path, relative to this file: `urdf: NAME.urdf`"),
    Key("tool_frame", Name(), "URDF link or joint for Cartesian queries and the payload",
        default_text="the last link", fix="a link of the URDF, e.g. the flange link"),
    Key("gravity", Vector(3, unit="m/s²"), "gravity in the URDF's base frame (wall or ceiling mounts)",
        default=_ROBOT["gravity"]),
    Key("payload", PAYLOAD, "a load at the tool frame"),
    Key("workspace", WORKSPACE, "walls the tool frame's origin stays within", default_text="none"),
    Key("self_collision", SELF_COLLISION, "the links checked against each other",
        default_text="on: `shapes: auto`, `margin: 0.01`"),
    Key("rate_hz", Number(minimum=MIN_RATE_HZ, maximum=MAX_RATE_HZ, unit="Hz"),
        "the control loop's rate; the bus load must carry it", default=_ROBOT["rate_hz"],
        fix=f"give the loop rate in Hz, e.g. 500 ({MIN_RATE_HZ:g}-{MAX_RATE_HZ:g})"),
    Key("buses", Table(BUS, "bus {name!r}", "bus name → bus"), "the CAN buses, by the name joints use",
        default_text="one bus `arm`: socketcan, can0, 1 Mbit/s"),
    Key("poses", Table(Vector(unit="rad"), "pose {name!r}", "pose name → one position per joint (rad)"),
        "named poses, in the order of `joints:`"),
    Key("motors", Table(Raw("the catalogue's fields"), "motor {name!r}", "model name → catalogue fields "
        "(akarm/data/motors.yaml; `base: MODEL` to start from another)"),
        "catalogue models added or overridden for this robot"),
    Key("defaults", DEFAULTS, "joint keys shared by every joint"),
    Key("joints", ListOf(JOINT, MAX_JOINTS, "MAX_JOINTS"), "the joints motors drive", required=True,
        fix="list the actuated joints under `joints:`"),
    Key("locked", Table(Number(unit="rad or m"), "locked: {name}", "URDF joint → position (rad, or m for prismatic "
        "joints)"), "URDF joints no motor drives, held at a position",
        default_text="where a `<mimic>` master puts them, else 0 with a warning",
        fix="the position to hold it at: rad, or m for a prismatic joint"),
    Key("gripper", GRIPPER, "the gripper: its motor and jaws (docs/gripper.md)", default_text="none"),
))
