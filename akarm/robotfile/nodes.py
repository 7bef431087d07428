"""A robot file as YAML nodes: every value keeps its line, every problem is collected with one.

:func:`compose` reads the file into PyYAML's node tree (``yaml.compose`` with the safe loader): nodes
keep their position (``start_mark``), plain values do not. The schema (:mod:`akarm.robotfile.schema`)
walks that tree and the checks (:mod:`akarm.robotfile.checks`) report at its nodes, into one
:class:`Findings`: problems, warnings, each with its file, 1-based line and fix.

Limits, as they stand:

- The whole file is read into memory (``yaml.compose`` of its text); a file that cannot be read, is
  not UTF-8 or is not valid YAML is one problem, raised at once (nothing else can be checked).
- Only the safe loader's tags; anchors and aliases (``&a``/``*a``) are resolved by PyYAML into shared
  nodes. Nothing bounds the file's size, nesting depth or node count yet, and PyYAML's composer and
  :func:`plain` recurse once per nesting level: bounds belong in :func:`compose`, the one place a
  robot file is parsed.
- The schema's own walk recurses only as deep as the schema is (a handful of levels), whatever the
  input; only values taken as they are (:func:`plain`: a python-can keyword argument, a motor
  entry) are constructed to their full depth.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from akarm.errors import ConfigError, ConfigProblem

__all__ = ["NOT_SCALAR", "Findings", "compose", "describe", "line", "plain", "scalar"]


def line(node: yaml.Node | None) -> int | None:
    """The node's 1-based line (``None`` for no node)."""
    return None if node is None else node.start_mark.line + 1


def describe(node: yaml.Node) -> str:
    """What a node is, for messages: ``a mapping``, ``a list``, ``'text'`` or ``nothing``."""
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    return f"{node.value!r}" if node.value != "" else "nothing"


class Findings:
    """Problems and warnings found in one robot file (and the files it names: the URDF)."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.problems: list[ConfigProblem] = []
        self.warnings: list[ConfigProblem] = []
        #: warnings :func:`~akarm.robotfile.load.load_robot` also issues as :class:`~akarm.errors.ConfigWarning`
        self.issued: list[ConfigProblem] = []
        self._constructor: yaml.SafeLoader | None = None

    @property
    def constructor(self) -> yaml.SafeLoader:
        """The safe loader that builds this file's plain values (one per file: it keeps what it built)."""
        if self._constructor is None:
            self._constructor = yaml.SafeLoader("")
        return self._constructor

    def add(self, at: yaml.Node | int | None, message: str, fix: str = "", *, file: str | None = None,
            warning: bool = False, issue: bool = False) -> None:
        """A problem (or with ``warning``, a warning) at a node or line of the robot file, or of ``file``;
        ``issue``: a warning that is also issued as a :class:`~akarm.errors.ConfigWarning`."""
        problem = ConfigProblem(file or self.file, at if isinstance(at, int) or at is None else line(at), message, fix)
        found = self.warnings if warning else self.problems
        if problem not in found:  # one `defaults:` entry can be found wanting for several joints
            found.append(problem)
            if issue:
                self.issued.append(problem)

    @property
    def count(self) -> int:
        """How many problems so far (a check compares it before and after)."""
        return len(self.problems)

    def sorted(self, found: list[ConfigProblem]) -> list[ConfigProblem]:
        """The robot file's own first, then other files' (the URDF); by line."""
        return sorted(found, key=lambda p: (p.file != self.file, p.file, p.line is None, p.line or 0))

    def raise_if_any(self) -> None:
        """Raise every problem found so far as one :class:`~akarm.errors.ConfigError`."""
        if self.problems:
            raise ConfigError(self.sorted(self.problems))


def compose(path: Path) -> yaml.Node | None:
    """The file's YAML node tree (``None`` for a file with no document).

    Raises:
        ConfigError: the file cannot be read, or is not valid YAML (with the line where the parser stopped).
    """
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
        at = mark.line + 1 if mark is not None else None
        what = " ".join(x for x in (e.context, e.problem) if x)
        raise ConfigError([ConfigProblem(str(path), at, f"not valid YAML: {what}",
                                         "fix the YAML syntax on or just before this line "
                                         "(indentation, a missing ':' or a stray quote)")]) from None
    except yaml.YAMLError as e:
        raise ConfigError([ConfigProblem(str(path), None, f"not valid YAML: {e}", "fix the YAML syntax")]) from None


def plain(node: yaml.Node, found: Findings) -> Any:
    """The node as a plain Python value (``None``, reported, when the safe loader cannot build it)."""
    try:
        return found.constructor.construct_object(node, deep=True)
    except yaml.YAMLError as e:
        found.add(node, f"cannot read this value: {getattr(e, 'problem', e)}", "write a plain YAML value")
        return None


class _NotScalar:
    def __repr__(self) -> str:
        return "NOT_SCALAR"


#: what :func:`scalar` gives for a mapping or list
NOT_SCALAR: Any = _NotScalar()


def scalar(node: yaml.Node, found: Findings) -> Any:
    """A scalar node's plain value; :data:`NOT_SCALAR` for a mapping or list."""
    return plain(node, found) if isinstance(node, yaml.ScalarNode) else NOT_SCALAR
