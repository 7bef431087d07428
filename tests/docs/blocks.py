"""The fenced code blocks of the documentation: README.md and every page under docs/.

A ```` ```python ```` block is a program that must run; blocks not meant to run are fenced ``text``,
``console``, ``sh``, ``yaml`` (...). An HTML comment on the line before a block gives it what it needs:

- ``<!-- docs: arm=ROBOT -->``: the block runs with ``arm`` (an enabled :class:`akarm.Arm` of
  ``robots/ROBOT.yaml``) and ``sim`` (its :class:`akarm.sim.SimulatedRobot`), in lock step.

A block that defines ``test_*`` functions is a test file: each function is called, its ``akarm_sim``
argument a lock-step :class:`akarm.testing.rig.SimulatedArm` of robots/arm6.yaml (as the pytest
plugin's fixture gives it).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^(?P<indent> *)(?P<fence>```+|~~~+)(?P<info>[^\n`]*)$")
DIRECTIVE = re.compile(r"^\s*<!--\s*docs:\s*(?P<args>.*?)\s*-->\s*$")


@dataclass(frozen=True)
class Block:
    path: Path  # the Markdown file
    line: int  # 1-based line of the opening fence
    language: str  # the fence's first word ("" for none)
    code: str
    options: dict[str, str]  # from a `<!-- docs: key=value ... -->` on the line before

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def blocks(path: Path) -> list[Block]:
    """Every fenced block of ``path``, in order (nested fences are left to the block they are in)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, indent = m["fence"], len(m["indent"])
        language = (m["info"].strip().split() or [""])[0].lstrip(".{").rstrip("}")
        before = DIRECTIVE.match(lines[i - 1]) if i > 0 else None
        options = dict(arg.split("=", 1) for arg in before["args"].split()) if before else {}
        end = i + 1
        while end < len(lines) and not (lines[end].strip().startswith(fence[0] * len(fence))
                                        and not lines[end].strip().strip(fence[0])):
            end += 1
        if end == len(lines):
            raise ValueError(f"{path}:{i + 1}: a code block that never ends")
        code = "\n".join(line[indent:] for line in lines[i + 1:end]) + "\n"
        found.append(Block(path, i + 1, language, code, options))
        i = end + 1
    return found


def python_blocks() -> list[Block]:
    return [b for path in markdown_files() for b in blocks(path) if b.language in ("python", "py")]
