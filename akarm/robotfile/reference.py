"""The robot file's reference (``docs/robot-file.md``), written from the schema and the checks' rules.

``python -m akarm.robotfile.reference > docs/robot-file.md`` writes it; a test fails when the file and
:func:`markdown` disagree, so a key added to :mod:`akarm.robotfile.schema` shows up in the reference.
"""

from __future__ import annotations

from akarm.robotfile.checks import RULES
from akarm.robotfile.schema import (
    BUS,
    COLLISION,
    DEFAULTS,
    FRICTION,
    GAINS,
    GRIPPER,
    JOINT,
    LIMITS,
    PAYLOAD,
    ROBOT_FILE,
    SELF_COLLISION,
    WORKSPACE,
    Section,
)

__all__ = ["markdown"]

_INTRO = """\
# The robot file

<!-- Written from akarm/robotfile/schema.py by `python -m akarm.robotfile.reference > docs/robot-file.md`:
     edit the schema, not this file (tests/test_config.py fails when they disagree). -->

A robot is a YAML file next to its URDF: the URDF gives the kinematics, masses and position limits,
the YAML the motors, buses, gains and motion limits. `akarm check ROBOT.yaml` (and `akarm.load_robot`)
reports every problem in a file at once, each with its line and a fix. `akarm init ROBOT.urdf` writes
a commented starting file; docs/robot-file-guide.md has an annotated example, `robots/` complete ones.

Units are SI, joint side: rad, rad/s, N·m, s.
"""

#: each section's heading, in the order they are listed
_HEADINGS = (
    (ROBOT_FILE, "Top level"),
    (BUS, "A bus: an entry of `buses:`"),
    (JOINT, "A joint: an item of `joints:`"),
    (LIMITS, "`limits:`"),
    (GAINS, "`gains:`"),
    (FRICTION, "`friction:`"),
    (COLLISION, "`collision:`"),
    (PAYLOAD, "`payload:`"),
    (GRIPPER, "`gripper:`"),
    (WORKSPACE, "`workspace:`"),
    (SELF_COLLISION, "`self_collision:`"),
)


def _cell(text: str) -> str:
    return text.replace("|", "\\|") if "\\|" not in text else text


def _table(section: Section) -> list[str]:
    rows = ["| key | type | default | meaning |", "|---|---|---|---|"]
    for key in section.keys:
        default = "**required**" if key.required else key.default_shown() or "—"
        rows.append(f"| `{key.name}` | {_cell(key.kind.text())} | {_cell(default)} | {_cell(key.doc)} |")
    if section.extra is not None:
        rows.append(f"| *any other* | as python-can takes it | — | {_cell(section.extra.doc)}; not "
                    f"{', '.join(section.extra.reserved)} |")
    return rows


def markdown() -> str:
    """The reference, as ``docs/robot-file.md`` holds it."""
    lines = [_INTRO]
    for section, heading in _HEADINGS:
        lines += [f"## {heading}", "", section.doc, "", *_table(section), ""]
    lines += ["## `defaults:`", "", DEFAULTS.doc, ""]
    lines += ["## What is checked beyond each value", "", *(f"- {rule}" for rule in RULES), ""]
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(), end="")
