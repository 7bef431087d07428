"""Reading a URDF as ROS tools and CAD exporters write it: the robot's own joints and links, with lines.

A URDF exported by xacro, ``sw_urdf_exporter``, onshape-to-robot or a robot vendor's
``*_description`` package holds much that akarm never needs: ``<transmission>`` and ``<ros2_control>``
blocks (whose ``<joint>`` elements name joints, they do not declare them), ``<gazebo>`` tags,
``package://`` and ``file://`` meshes, materials. Only the ``<joint>`` and ``<link>`` elements that
are direct children of ``<robot>`` describe the robot; everything else is passed over.

:func:`read_urdf` returns a :class:`Urdf` (joints and links by name, in file order, each with its
1-based line) and the problems found, each with a line and a fix, so that a robot file's loader can
report them all at once as a :class:`~akarm.ConfigError`. What is checked is what urdfdom (and so
Pinocchio) would refuse, but said where and how to fix it: not XML, not a ``<robot>``, an unexpanded
xacro file, a joint without name, type, parent or child, an unknown joint type, names used twice, a
joint naming a link that does not exist, a link with two parents, no single root link, a loop,
revolute or prismatic joints without ``<limit>``, limits and masses that are not numbers, ``<mimic>``
naming a joint that is not there.

Joint types: ``revolute``, ``continuous`` (akarm can drive these), ``prismatic`` (can be locked),
``fixed`` (merged into its parent link by Pinocchio), ``floating`` and ``planar`` (locked at their
neutral configuration). A ``<mimic>`` joint follows another joint: ``q = multiplier * q_master + offset``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple
from xml.parsers import expat

from akarm.errors import did_you_mean
from akarm.files import FileProblem, number, over, read_bytes

__all__ = ["JOINT_TYPES", "MAX_URDF_BYTES", "MAX_URDF_JOINTS", "MAX_URDF_LINKS", "Mimic", "Urdf", "UrdfJoint",
           "UrdfLink", "UrdfProblem", "pinocchio_complaint", "read_urdf"]

#: joint types of the URDF specification
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: joint types with one degree of freedom and a position in rad or m
ONE_DOF = ("revolute", "continuous", "prismatic")

#: Bytes of a URDF (meshes are files of their own; a humanoid's URDF has a few hundred thousand).
MAX_URDF_BYTES = 8 << 20
#: ``<joint>`` elements of a URDF, fixed ones included (a humanoid has about a hundred).
MAX_URDF_JOINTS = 1000
#: ``<link>`` elements of a URDF.
MAX_URDF_LINKS = 1000

_CHECK = "check it with `check_urdf FILE` (liburdfdom-tools) or in RViz"


class UrdfProblem(NamedTuple):
    """One problem in a URDF: 1-based line (``None`` when no line applies), what, and the fix."""

    line: int | None
    message: str
    fix: str


class Mimic(NamedTuple):
    """``<mimic joint=... multiplier=... offset=...>``: this joint is ``multiplier * q(joint) + offset``."""

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class UrdfJoint:
    """A joint as the URDF declares it.

    Attributes:
        name, type: the ``name`` and ``type`` attributes.
        parent, child: link names.
        lower, upper: position limits (rad or m) of revolute and prismatic joints, else ``None``.
        velocity, effort: the ``<limit>``'s velocity (rad/s or m/s) and effort (N·m or N), when given.
        mimic: the joint this one follows, if any.
        line: 1-based line of the ``<joint>`` element.
    """

    name: str
    type: str
    parent: str = ""
    child: str = ""
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None
    mimic: Mimic | None = None
    line: int = 0

    @property
    def movable(self) -> bool:
        """Not ``fixed``: the joint has a configuration of its own (or follows another's)."""
        return self.type != "fixed"


@dataclass(frozen=True)
class UrdfLink:
    """A link: its name, mass (kg; 0 without ``<inertial>``) and 1-based line."""

    name: str
    mass: float = 0.0
    line: int = 0


@dataclass(frozen=True)
class Urdf:
    """The robot a URDF describes.

    Attributes:
        path: the file.
        name: the ``<robot name=...>``.
        joints, links: by name, in file order.
        root: the root link (the one that is no joint's child), ``""`` when there is not exactly one.
    """

    path: Path
    name: str
    joints: dict[str, UrdfJoint] = field(default_factory=dict)
    links: dict[str, UrdfLink] = field(default_factory=dict)
    root: str = ""

    @property
    def movable(self) -> list[UrdfJoint]:
        """Joints that are not fixed, in chain order (:meth:`chain_order`)."""
        return [self.joints[n] for n in self.chain_order() if self.joints[n].movable]

    def chain_order(self) -> list[str]:
        """Joint names from the root outwards: depth first, children in file order.

        For a serial arm this is base to tool; at a branch (a gripper's two fingers) each branch is
        finished before the next begins.
        """
        children = self._children()
        order: list[str] = []
        seen: set[str] = set()
        if not self.root:
            return order
        seen.add(self.root)
        below = [iter(children.get(self.root, []))]  # per link on the way down, its joints still to walk
        while below:  # (a walk with its own stack: a chain of any length, no recursion)
            j = next(below[-1], None)
            if j is None:
                below.pop()
                continue
            order.append(j.name)
            if j.child not in seen:  # (a loop: reported by read_urdf)
                seen.add(j.child)
                below.append(iter(children.get(j.child, [])))
        return order

    def _children(self) -> dict[str, list[UrdfJoint]]:
        """Link name -> the joints whose parent it is, in file order."""
        children: dict[str, list[UrdfJoint]] = {}
        for j in self.joints.values():
            children.setdefault(j.parent, []).append(j)
        return children


class _Element(NamedTuple):
    tag: str
    attrs: dict[str, str]
    line: int


def _float(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        return math.nan
    return v


#: a joint's elements that are read (the first of each; the others, and a link's own but <inertial>, are passed over)
_JOINT_PARTS = ("parent", "child", "origin", "axis", "limit", "mimic")


class _Scan:
    """A streaming parse that keeps line numbers: the robot's direct children (<joint>, <link>), a
    joint's parts (:data:`_JOINT_PARTS`) and a link's <inertial>'s <mass>, <inertia> and <origin>.

    It keeps nothing else (memory in proportion to the joints and links), and stops with a
    :class:`~akarm.files.FileProblem` at the joint or link past :data:`MAX_URDF_JOINTS` or
    :data:`MAX_URDF_LINKS`.
    """

    def __init__(self) -> None:
        self.stack: list[str] = []
        self.root: _Element | None = None
        self.tops: list[tuple[_Element, dict[str, _Element]]] = []
        #: index in tops -> <inertial>'s <mass>, <inertia>, <origin>
        self.inertials: dict[int, dict[str, _Element]] = {}
        self.counts = {"joint": 0, "link": 0}
        self.xacro_line: int | None = None
        self.parser = expat.ParserCreate()
        self.parser.StartElementHandler = self.start
        self.parser.EndElementHandler = self.end

    def start(self, tag: str, attrs: dict[str, str]) -> None:
        line = self.parser.CurrentLineNumber
        depth, stack = len(self.stack), self.stack
        stack.append(tag)
        if tag.startswith("xacro:") and self.xacro_line is None:
            self.xacro_line = line
        if depth == 0:
            self.root = _Element(tag, attrs, line)
        elif depth == 1 and tag in ("joint", "link"):
            self._count(tag, line)
            self.tops.append((_Element(tag, attrs, line), {}))
        elif depth == 2 and stack[1] == "joint" and tag in _JOINT_PARTS and self.tops:
            self.tops[-1][1].setdefault(tag, _Element(tag, attrs, line))
        elif depth == 3 and stack[1] == "link" and stack[2] == "inertial" and self.tops:
            self.inertials.setdefault(len(self.tops) - 1, {}).setdefault(tag, _Element(tag, attrs, line))

    def _count(self, tag: str, line: int) -> None:
        self.counts[tag] += 1
        limit, name = (MAX_URDF_JOINTS, "MAX_URDF_JOINTS") if tag == "joint" else (MAX_URDF_LINKS, "MAX_URDF_LINKS")
        if self.counts[tag] > limit:
            raise FileProblem(over(f"the URDF has more than {number(limit)} {tag}s", limit, f"{tag}s", name),
                              "is it the right file? akarm drives arms, not chains of thousands of links: "
                              "remove the joints and links no motor drives or holds", line)

    def end(self, tag: str) -> None:
        self.stack.pop()


def read_urdf(path: str | os.PathLike[str]) -> tuple[Urdf | None, list[UrdfProblem]]:
    """Read the robot of a URDF file.

    Returns:
        ``(urdf, problems)``: ``urdf`` is ``None`` when the file is not a URDF at all (not XML, not a
        ``<robot>``, unreadable); ``problems`` lists everything wrong, each with a line and a fix.
    """
    p = Path(path)
    scan = _Scan()
    try:
        scan.parser.Parse(read_bytes(p, MAX_URDF_BYTES, what="URDF", name="MAX_URDF_BYTES"), True)
    except FileProblem as e:
        return None, [UrdfProblem(e.line, e.what, e.fix)]
    except expat.ExpatError as e:
        return None, [UrdfProblem(e.lineno, f"not well-formed XML: {expat.ErrorString(e.code)}",
                                  "fix the XML on or just before this line (an unclosed or mistyped tag, a stray "
                                  "'<' or '&')")]
    root = scan.root
    if root is None or root.tag != "robot":
        tag = root.tag if root is not None else "nothing"
        return None, [UrdfProblem(root.line if root else None, f"the root element is <{tag}>, not <robot>",
                                  "give akarm the robot's URDF (a file whose top element is <robot name=...>)")]
    problems: list[UrdfProblem] = []
    if scan.xacro_line is not None:
        problems.append(UrdfProblem(scan.xacro_line, "this is a xacro file, not yet a URDF (it has xacro: elements)",
                                    "expand it first: `xacro ROBOT.urdf.xacro > ROBOT.urdf` (ROS), or export the "
                                    "URDF from your CAD tool, and give akarm the result"))

    links: dict[str, UrdfLink] = {}
    joints: dict[str, UrdfJoint] = {}
    for k, (el, parts) in enumerate(scan.tops):
        if el.tag == "link":
            _read_link(el, scan.inertials.get(k, {}), links, problems)
        else:
            _read_joint(el, parts, joints, problems)

    urdf = Urdf(path=p, name=root.attrs.get("name", p.stem), joints=joints, links=links)
    _check_tree(urdf, problems, root.line)
    root_link = _root(urdf)
    if root_link:
        urdf = Urdf(path=p, name=urdf.name, joints=joints, links=links, root=root_link)
    return urdf, problems


def _vector(el: _Element, key: str, what: str, problems: list[UrdfProblem]) -> tuple[float, ...] | None:
    """The attribute ``key`` of ``el`` as three numbers (``None`` when absent or reported)."""
    text = el.attrs.get(key)
    if text is None:
        return None
    parts = text.split()
    values = [_float(x) for x in parts]
    if len(parts) != 3 or not all(v is not None and math.isfinite(v) for v in values):
        problems.append(UrdfProblem(el.line, f"{what}: <{el.tag} {key}={text!r}> is not three numbers",
                                    f'write {key}="X Y Z" with numbers (a xacro expression must be expanded first)'))
        return None
    return tuple(v for v in values if v is not None)


def _read_link(el: _Element, inertial: dict[str, _Element], links: dict[str, UrdfLink],
               problems: list[UrdfProblem]) -> None:
    name = el.attrs.get("name")
    if not name:
        problems.append(UrdfProblem(el.line, "a <link> without a name", 'give it one: <link name="...">'))
        return
    if name in links:
        problems.append(UrdfProblem(el.line, f"link {name!r} is declared twice (first on line {links[name].line})",
                                    "give every link its own name"))
        return
    label = f"link {name!r}"
    mass = 0.0
    if (mass_el := inertial.get("mass")) is not None:
        m = _float(mass_el.attrs.get("value"))
        if m is None or not math.isfinite(m) or m < 0:
            problems.append(UrdfProblem(mass_el.line, f"{label}: <mass value={mass_el.attrs.get('value')!r}> "
                                        "is not a mass", "give the mass in kg, a number ≥ 0"))
        else:
            mass = m
    if (origin := inertial.get("origin")) is not None:
        for key in ("xyz", "rpy"):
            _vector(origin, key, f"{label}'s inertial", problems)
    if (inertia := inertial.get("inertia")) is not None:
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        values = {k: _float(inertia.attrs.get(k, "0")) for k in keys}
        bad = [k for k, v in values.items() if v is None or not math.isfinite(v)]
        if bad:
            problems.append(UrdfProblem(inertia.line, f"{label}: <inertia {bad[0]}={inertia.attrs.get(bad[0])!r}> "
                                        "is not a number", "give the six inertia values in kg·m² as numbers"))
        else:
            v = {k: float(x) for k, x in values.items() if x is not None}
            matrix = ((v["ixx"], v["ixy"], v["ixz"]), (v["ixy"], v["iyy"], v["iyz"]), (v["ixz"], v["iyz"], v["izz"]))
            if _smallest_eigenvalue(matrix) < -1e-9 * max(1e-12, v["ixx"] + v["iyy"] + v["izz"]):
                problems.append(UrdfProblem(inertia.line, f"{label}: its <inertia> is not physically possible "
                                            "(the matrix has a negative principal moment)",
                                            "export it again (CAD exporters: check the units, kg·m²), or compute "
                                            "it from the link's shape"))
    links[name] = UrdfLink(name, mass, el.line)


def _smallest_eigenvalue(m: tuple[tuple[float, float, float], ...]) -> float:
    """The smallest eigenvalue of a symmetric 3×3 matrix (closed form)."""
    a, b, c = m[0][0], m[1][1], m[2][2]
    d, e, f = m[0][1], m[1][2], m[0][2]
    p1 = d * d + e * e + f * f
    q = (a + b + c) / 3.0
    if p1 == 0.0:
        return min(a, b, c)
    p2 = (a - q) ** 2 + (b - q) ** 2 + (c - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    bm = [[(m[i][j] - (q if i == j else 0.0)) / p for j in range(3)] for i in range(3)]
    det = (bm[0][0] * (bm[1][1] * bm[2][2] - bm[1][2] * bm[2][1])
           - bm[0][1] * (bm[1][0] * bm[2][2] - bm[1][2] * bm[2][0])
           + bm[0][2] * (bm[1][0] * bm[2][1] - bm[1][1] * bm[2][0]))
    r = max(-1.0, min(1.0, det / 2.0))
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)


def _joint_kind(el: _Element, joints: dict[str, UrdfJoint], problems: list[UrdfProblem]) -> tuple[str, str] | None:
    """A <joint>'s name and type; ``None`` (reported) without a name or a known type, or with a name used before."""
    name, jtype = el.attrs.get("name"), el.attrs.get("type")
    if not name:
        problems.append(UrdfProblem(el.line, "a <joint> without a name", 'give it one: <joint name="..." type="...">'))
        return None
    label = f"joint {name!r}"
    if name in joints:
        problems.append(UrdfProblem(el.line, f"{label} is declared twice (first on line {joints[name].line})",
                                    "give every joint its own name"))
        return None
    if not jtype:
        problems.append(UrdfProblem(el.line, f"{label} has no type", "add type=\"revolute\" (or continuous, "
                                    "prismatic, fixed)"))
        return None
    if jtype not in JOINT_TYPES:
        hint = did_you_mean(jtype, JOINT_TYPES)
        problems.append(UrdfProblem(el.line, f"{label} has the unknown type {jtype!r}{hint}",
                                    "URDF joint types: " + ", ".join(JOINT_TYPES)))
        return None
    return name, jtype


def _read_joint(el: _Element, first: dict[str, _Element], joints: dict[str, UrdfJoint],
                problems: list[UrdfProblem]) -> None:
    """A <joint>, from its element and the first of each of its parts."""
    kind = _joint_kind(el, joints, problems)
    if kind is None:
        return
    name, jtype = kind
    label = f"joint {name!r}"
    ends = {}
    for key in ("parent", "child"):
        end = first.get(key)
        ends[key] = end.attrs.get("link", "") if end is not None else ""
        if not ends[key]:
            problems.append(UrdfProblem(end.line if end is not None else el.line, f"{label} has no {key} link",
                                        f'add <{key} link="LINK"/> inside the <joint>'))
    _joint_frame(first, label, jtype, problems)
    lower, upper, velocity, effort = _joint_limit(el, first.get("limit"), label, jtype, problems)
    mimic = _joint_mimic(first.get("mimic"), label, problems)
    joints[name] = UrdfJoint(name=name, type=jtype, parent=ends["parent"], child=ends["child"], lower=lower,
                             upper=upper, velocity=velocity, effort=effort, mimic=mimic, line=el.line)


def _joint_frame(first: dict[str, _Element], label: str, jtype: str, problems: list[UrdfProblem]) -> None:
    """A joint's <origin> and <axis> are numbers; its axis is not zero."""
    if (origin := first.get("origin")) is not None:
        for key in ("xyz", "rpy"):
            _vector(origin, key, label, problems)
    if (axis := first.get("axis")) is not None and jtype in (*ONE_DOF, "planar"):
        xyz = _vector(axis, "xyz", label, problems)
        if xyz is not None and not any(xyz):
            problems.append(UrdfProblem(axis.line, f"{label}: its <axis> is zero", 'give the direction it turns '
                                        'or slides about, e.g. <axis xyz="0 0 1"/>'))


_Limit = tuple[float | None, float | None, float | None, float | None]


def _joint_limit(el: _Element, lim: _Element | None, label: str, jtype: str, problems: list[UrdfProblem]) -> _Limit:
    """A joint's <limit>: lower, upper (of revolute and prismatic joints), velocity, effort."""
    bounded = jtype in ("revolute", "prismatic")
    if lim is None:
        if bounded:
            unit = "rad" if jtype == "revolute" else "m"
            problems.append(UrdfProblem(el.line, f"{label} is {jtype} but has no <limit>",
                                        f'add <limit lower="..." upper="..." effort="..." velocity="..."/> ({unit}); '
                                        "or make it continuous"))
        return None, None, None, None
    missing = [k for k in ("effort", "velocity") if k not in lim.attrs]
    if bounded and missing:
        problems.append(UrdfProblem(lim.line, f"{label}: its <limit> has no {' and no '.join(missing)} (URDF "
                                    "requires both)", "add " + " and ".join(f'{k}="..."' for k in missing) +
                                    " (the maximum effort and velocity; akarm takes its own from the YAML)"))
    values = {}
    for key in ("lower", "upper", "velocity", "effort"):
        v = _float(lim.attrs.get(key))
        if v is not None and not math.isfinite(v):
            problems.append(UrdfProblem(lim.line, f"{label}: <limit {key}={lim.attrs[key]!r}> is not a number",
                                        f"write {key} as a number"))
            v = None
        values[key] = v
    if not bounded:
        return None, None, values["velocity"], values["effort"]
    lower = values["lower"] if values["lower"] is not None else 0.0  # urdfdom's defaults
    upper = values["upper"] if values["upper"] is not None else 0.0
    if lower > upper:
        problems.append(UrdfProblem(lim.line, f"{label}: <limit> lower {lower:g} is above upper {upper:g}",
                                    "swap them, or fix the signs"))
    return lower, upper, values["velocity"], values["effort"]


def _joint_mimic(mel: _Element | None, label: str, problems: list[UrdfProblem]) -> Mimic | None:
    if mel is None:
        return None
    target = mel.attrs.get("joint", "")
    mult = _float(mel.attrs.get("multiplier"))
    off = _float(mel.attrs.get("offset"))
    if not target:
        problems.append(UrdfProblem(mel.line, f"{label}: <mimic> names no joint", 'add joint="..." to <mimic>'))
    elif (mult is not None and not math.isfinite(mult)) or (off is not None and not math.isfinite(off)):
        problems.append(UrdfProblem(mel.line, f"{label}: <mimic> multiplier/offset are not numbers",
                                    "write them as numbers (defaults: multiplier 1, offset 0)"))
    else:
        return Mimic(target, 1.0 if mult is None else mult, 0.0 if off is None else off)
    return None


def _check_tree(urdf: Urdf, problems: list[UrdfProblem], robot_line: int) -> None:
    links, joints = urdf.links, urdf.joints
    if not links:
        problems.append(UrdfProblem(robot_line, "the robot has no <link>", "describe the robot's links and joints"))
        return
    parent_of = _check_joint_links(urdf, problems)
    _check_mimic_loops(joints, problems)
    roots = [n for n in links if n not in parent_of]
    if len(roots) == 1:
        _check_reach(urdf, roots[0], problems)
    elif roots:
        shown = ", ".join(f"{n!r} (line {links[n].line})" for n in roots[:6])
        problems.append(UrdfProblem(links[roots[1]].line, f"the URDF has {len(roots)} root links: {shown}",
                                    "connect every link to the tree with a joint (a URDF has one root, e.g. "
                                    "base_link or world)"))
    else:
        problems.append(UrdfProblem(robot_line, "every link is some joint's child: the joints form a loop",
                                    "a URDF is a tree: remove the joint that closes the loop"))


def _check_joint_links(urdf: Urdf, problems: list[UrdfProblem]) -> dict[str, UrdfJoint]:
    """Every joint names declared links (a link has one parent joint) and an existing mimic master;
    returns the parent joint of each link."""
    links, joints = urdf.links, urdf.joints
    parent_of: dict[str, UrdfJoint] = {}
    for j in joints.values():
        for key, link in (("parent", j.parent), ("child", j.child)):
            if link and link not in links:
                problems.append(UrdfProblem(j.line, f"joint {j.name!r}: its {key} link {link!r} is not declared"
                                            f"{did_you_mean(link, list(links))}",
                                            f'declare <link name="{link}"> or name an existing link'))
        if j.child and j.child in parent_of:
            problems.append(UrdfProblem(j.line, f"link {j.child!r} is the child of joints {parent_of[j.child].name!r} "
                                        f"(line {parent_of[j.child].line}) and {j.name!r}",
                                        "a link has one parent joint: a URDF is a tree (close loops in your "
                                        "controller, not in the URDF)"))
        elif j.child:
            parent_of[j.child] = j
        if j.mimic is not None and j.mimic.joint not in joints:
            problems.append(UrdfProblem(j.line, f"joint {j.name!r} mimics {j.mimic.joint!r}, which is not declared"
                                        f"{did_you_mean(j.mimic.joint, list(joints))}", "name an existing joint"))
        elif j.mimic is not None and j.mimic.joint == j.name:
            problems.append(UrdfProblem(j.line, f"joint {j.name!r} mimics itself", "name the joint it follows"))
    return parent_of


def _check_reach(urdf: Urdf, root: str, problems: list[UrdfProblem]) -> None:
    """Loops hanging below the root: every link must be reachable from it."""
    links = urdf.links
    reach = {root}
    todo = [root]
    by_parent: dict[str, list[UrdfJoint]] = {}
    for j in urdf.joints.values():
        by_parent.setdefault(j.parent, []).append(j)
    while todo:
        for j in by_parent.get(todo.pop(), []):
            if j.child in links and j.child not in reach:
                reach.add(j.child)
                todo.append(j.child)
    lost = [n for n in links if n not in reach]
    if lost:
        problems.append(UrdfProblem(links[lost[0]].line, f"links {', '.join(map(repr, lost[:6]))} form a loop "
                                    "not connected to the root", "a URDF is a tree: remove the joint that closes "
                                    "the loop"))


def _check_mimic_loops(joints: dict[str, UrdfJoint], problems: list[UrdfProblem]) -> None:
    """Joints that follow each other round a loop (A mimics B, B mimics A) have no position to start from."""
    seen: set[str] = set()
    for start in joints.values():
        path: list[str] = []
        name = start.name
        while name in joints and name not in seen and name not in path:
            m = joints[name].mimic
            if m is None:
                break
            path.append(name)
            name = m.joint
        seen.update(path)
        if name not in path or path.index(name) == len(path) - 1:  # no loop, or one mimicking itself (said above)
            continue
        loop = path[path.index(name):]
        first = min(range(len(loop)), key=lambda i: joints[loop[i]].line)
        loop = loop[first:] + loop[:first]
        chain = " mimics " + ", which mimics ".join(f"{n!r} (line {joints[n].line})" for n in loop[1:])
        problems.append(UrdfProblem(joints[loop[0]].line, f"joint {loop[0]!r} (line {joints[loop[0]].line}){chain}, "
                                    f"which mimics {loop[0]!r}: the <mimic> joints form a loop, and none of them "
                                    "has a position of its own",
                                    "a <mimic> follows a joint that follows no other (one a motor drives, or one "
                                    "held by locked:): remove the <mimic> of one of them"))


def _root(urdf: Urdf) -> str:
    children = {j.child for j in urdf.joints.values()}
    roots = [n for n in urdf.links if n not in children]
    return roots[0] if len(roots) == 1 else ""


def pinocchio_complaint(path: str | os.PathLike[str]) -> str | None:
    """None when Pinocchio builds a model from the URDF, else why not.

    Pinocchio's exception only says "does not contain a valid URDF model"; the reason is printed by
    urdfdom on the C++ side to file descriptor 2, so that is captured for the duration of the call.
    """
    import sys
    import tempfile

    import pinocchio as pin

    captured = ""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        saved = -1
    try:
        with tempfile.TemporaryFile(mode="w+b") as tmp:
            if saved >= 0:
                os.dup2(tmp.fileno(), 2)
            try:
                pin.buildModelFromUrdf(str(path))
                error = None
            except Exception as e:  # Pinocchio raises ValueError/RuntimeError/std exceptions
                error = str(e).strip() or type(e).__name__
            finally:
                if saved >= 0:
                    os.dup2(saved, 2)
            if error is not None:
                tmp.seek(0)
                captured = tmp.read().decode("utf-8", "replace")
    finally:
        if saved >= 0:
            os.close(saved)
    if error is None:
        return None
    reasons = [ln.split("Error:", 1)[1].strip() for ln in captured.splitlines() if "Error:" in ln]
    return "; ".join(reasons) if reasons else error.splitlines()[0]
