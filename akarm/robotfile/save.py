"""Writing values into a robot YAML: in place, its comments and layout kept, with a backup.

:func:`save_values` puts ``payload:`` and, per joint, ``friction:`` and ``collision:`` into the file
(what ``akarm identify --save`` found, or any other source of them). It edits the text where the
YAML parser says each entry is (replacing an entry that is there, adding one after the joint's last
entry, or the payload after ``urdf:``), so every comment and the order of keys stay as the user
wrote them. The result is loaded and checked before the
original is touched; the original is copied to ``NAME.yaml.YYYYmmdd-HHMMSS.bak`` and the new text
written atomically (no half file after a crash).
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml

from akarm.config import Friction, Payload
from akarm.errors import ConfigError, ConfigProblem
from akarm.files import FileProblem, atomic_write, read_yaml
from akarm.robotfile.nodes import ROBOT_FILE_LIMITS

__all__ = ["JointValues", "flow_collision", "flow_friction", "flow_payload", "save_values"]


@dataclass(frozen=True)
class JointValues:
    """What to write for one joint: its ``friction:`` and its ``collision: {threshold: ...}`` (N·m);
    ``None`` leaves an entry as the file has it."""

    friction: Friction | None = None
    collision_threshold: float | None = None


def flow_payload(p: Payload) -> str:
    """``payload:``'s value as YAML flow text."""
    return f"{{mass: {p.mass:.4f}, com: [{p.com[0]:.4f}, {p.com[1]:.4f}, {p.com[2]:.4f}]}}"


def flow_friction(f: Friction) -> str:
    """``friction:``'s value as YAML flow text (no ``offset``, ``load`` or ``torque_scale`` at their defaults)."""
    text = f"{{coulomb: {f.coulomb:.4f}, viscous: {f.viscous:.5f}"
    text += f", offset: {f.offset:.4f}" if f.offset != 0.0 else ""
    text += f", load: {f.load:.4f}" if f.load != 0.0 else ""
    text += f", torque_scale: {f.torque_scale:.4f}" if f.torque_scale != 1.0 else ""
    return text + "}"


def flow_collision(threshold: float) -> str:
    """``collision:``'s value as YAML flow text."""
    return f"{{threshold: {threshold:.2f}}}"

_Edit = tuple[int, int, str]  # replace text[start:end] with the string


def _key(mapping: yaml.MappingNode, name: str) -> tuple[yaml.Node, yaml.Node] | None:
    for k, v in mapping.value:
        if isinstance(k, yaml.ScalarNode) and k.value == name:
            return k, v
    return None


def _line_end(text: str, index: int) -> int:
    """The index just after the newline ending the line that holds ``index`` (or the end of the text)."""
    nl = text.find("\n", index)
    return len(text) if nl < 0 else nl + 1


def _end(node: yaml.Node) -> int:
    """The index just after the node's own text. PyYAML's ``end_mark`` of a block mapping or sequence
    is where the next token starts (on a later line, after the newline and the next line's indent):
    its text ends with its last scalar, or flow collection, instead."""
    if isinstance(node, yaml.MappingNode | yaml.SequenceNode) and not node.flow_style and node.value:
        last = node.value[-1]
        return _end(last[1] if isinstance(last, tuple) else last)
    return int(node.end_mark.index)


def _line_start(text: str, index: int) -> int:
    return text.rfind("\n", 0, index) + 1


def _set(text: str, mapping: yaml.MappingNode, key: str, flow: str, after: yaml.Node | None = None) -> list[_Edit]:
    """The edits that make ``key: flow`` an entry of ``mapping``: replace its value, or add it (in a
    block mapping on a line of its own after ``after`` or the last entry, in a flow mapping before ``}``)."""
    found = _key(mapping, key)
    if found is not None:
        k, value = found
        start, end = value.start_mark.index, _end(value)
        on_key_line = "\n" not in text[k.end_mark.index:start]
        block_scalar = isinstance(value, yaml.ScalarNode) and value.style in ("|", ">")
        if on_key_line and not block_scalar and end > start:  # `key: value` or `key: {...}`
            return [(start, end, flow)]
        # a block value on the lines below (or a block scalar, or nothing): the flow value goes on the
        # key's line, after its colon (a comment there stays), and the value's own lines go
        colon = text.index(":", k.end_mark.index) + 1
        if end <= start:  # `key:` with no value
            return [(colon, colon, f" {flow}")]
        if on_key_line:  # `key: |` ...: the block scalar's lines end with its newline
            return [(start, end, flow + ("\n" if text[end - 1] == "\n" else ""))]
        cut_from = _line_start(text, start)
        if text[cut_from:start].strip():  # something before it on its line (an anchor): keep that
            cut_from = start
        cut_to = _line_end(text, end - 1) if not text[end:_line_end(text, end - 1)].strip() else end
        return [(colon, colon, f" {flow}"), (cut_from, cut_to, "")]
    if mapping.flow_style:
        close = mapping.end_mark.index - 1
        return [(close, close, f", {key}: {flow}")]
    first_key = mapping.value[0][0]
    indent = " " * first_key.start_mark.column
    last = after if after is not None else mapping.value[-1][1]
    end = _end(last)
    at = _line_end(text, end - 1 if end > 0 else 0)
    return [(at, at, f"{indent}{key}: {flow}\n")]


def _edits(text: str, root: yaml.MappingNode, payload: Payload | None, joint_values: Mapping[str, JointValues],
           path: Path) -> list[_Edit]:
    def problem(what: str) -> ConfigError:
        return ConfigError([ConfigProblem(str(path), None, what, "write the values by hand (akarm identify prints "
                                                                 "them as YAML)")])

    edits: list[_Edit] = []
    if payload is not None:
        urdf = _key(root, "urdf")
        edits += _set(text, root, "payload", flow_payload(payload), after=urdf[1] if urdf else None)
    joints = _key(root, "joints")
    if joints is None or not isinstance(joints[1], yaml.SequenceNode):
        raise problem("it has no `joints:` list")
    by_name = {}
    for item in joints[1].value:
        name = _key(item, "name") if isinstance(item, yaml.MappingNode) else None
        if name is not None:
            by_name[name[1].value] = item
    for joint, v in joint_values.items():
        item = by_name.get(joint)
        if item is None:
            raise problem(f"joint {joint!r} is not under `joints:`")
        values = []
        if v.friction is not None:
            values.append(("friction", flow_friction(v.friction)))
        if v.collision_threshold is not None:
            values.append(("collision", flow_collision(v.collision_threshold)))
        for key, flow in values:
            edits += _set(text, item, key, flow)
    return edits


def _apply(text: str, edits: list[_Edit]) -> str:
    # from the end: an edit never moves the places of those before it; inserts at one place keep their order
    order = sorted(range(len(edits)), key=lambda i: (edits[i][0], edits[i][1], i), reverse=True)
    for i in order:
        start, end, new = edits[i]
        text = text[:start] + new + text[end:]
    return text


def save_values(path: str | Path, *, payload: Payload | None = None, joints: Mapping[str, JointValues] | None = None,
                check: Callable[[Path], object] | None = None) -> tuple[Path, Path]:
    """Write ``payload`` and each joint's values (by joint name) into the robot file at ``path``;
    returns (the file, its backup).

    ``check`` loads a candidate file and raises if it is not a valid robot (default:
    :func:`akarm.load_robot`). Nothing is changed if it raises.

    Raises:
        ConfigError: the file cannot be read or parsed, has no such joints, or would not load after the edit.
    """
    p = Path(path)
    try:
        text, root = read_yaml(p, ROBOT_FILE_LIMITS)
    except FileProblem as e:
        raise ConfigError([ConfigProblem(str(p), e.line, f"cannot read it: {e.what}", e.fix)]) from None
    if not isinstance(root, yaml.MappingNode):
        raise ConfigError([ConfigProblem(str(p), None, "it is not a robot file (not a mapping)", "check the path")])
    new = _apply(text, _edits(text, root, payload, joints or {}, p))
    candidate = p.with_name(f".{p.name}.identified.tmp")
    try:
        candidate.write_text(new, encoding="utf-8")
        if check is None:
            from akarm.robotfile.load import load_robot

            load_robot(candidate)
        else:
            check(candidate)
    finally:
        candidate.unlink(missing_ok=True)
    backup = p.with_name(f"{p.name}.{time.strftime('%Y%m%d-%H%M%S')}.bak")
    n = 1
    while backup.exists():
        backup = p.with_name(f"{p.name}.{time.strftime('%Y%m%d-%H%M%S')}-{n}.bak")
        n += 1
    shutil.copy2(p, backup)
    atomic_write(p, lambda f: f.write(new.encode("utf-8")))
    return p, backup
