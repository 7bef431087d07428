"""A robot file as YAML nodes: every value keeps its line, every problem is collected with one.

:func:`compose` reads the file into PyYAML's node tree (``yaml.compose`` with the safe loader): nodes
keep their position (``start_mark``), plain values do not. The schema (:mod:`akarm.robotfile.schema`)
walks that tree and the checks (:mod:`akarm.robotfile.checks`) report at its nodes, into one
:class:`Findings`: problems, warnings, each with its file, 1-based line and fix.

Limits (the README's "Limits" table): :func:`compose` is the one place a robot file is parsed, and
it reads it within :data:`ROBOT_FILE_LIMITS` (:func:`akarm.files.compose_yaml`): at most
:data:`MAX_ROBOT_FILE_BYTES` bytes, nested at most :data:`akarm.files.MAX_YAML_DEPTH` levels, at
most :data:`MAX_ROBOT_FILE_NODES` values with every alias counted as the whole value it repeats
(an alias bomb is refused as the alias is read, before anything expands it). A file past one is
one problem naming the limit, raised at once, as are a file that cannot be read, is not UTF-8 or
is not valid YAML (nothing else can be checked).

Only the safe loader's tags; anchors and aliases (``&a``/``*a``) are resolved into shared nodes.
Nothing here recurses once per level of the input: the composition keeps its own stack, the
schema's walk recurses only as deep as the schema is (a handful of levels), and the values taken
as they are (:func:`plain`: a python-can keyword argument, a motor entry) are at most
:data:`~akarm.files.MAX_YAML_DEPTH` deep.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from akarm.errors import ConfigError, ConfigProblem
from akarm.files import FileProblem, YamlLimits, construct, read_yaml

__all__ = ["MAX_JOINTS", "MAX_ROBOT_FILE_BYTES", "MAX_ROBOT_FILE_NODES", "NOT_SCALAR", "ROBOT_FILE_LIMITS", "Findings",
           "compose", "describe", "line", "plain", "scalar"]

#: Bytes of a robot file (arm6.yaml has 3 300).
MAX_ROBOT_FILE_BYTES = 1 << 20
#: Values (scalars, lists, mappings) in a robot file, aliases counted at their full size (arm6.yaml has 240).
MAX_ROBOT_FILE_NODES = 100_000
#: Joints under a robot file's ``joints:`` (the gravity check's cost grows with the cube of their number).
MAX_JOINTS = 32
#: How a robot file is read.
ROBOT_FILE_LIMITS = YamlLimits("robot file", MAX_ROBOT_FILE_BYTES, "MAX_ROBOT_FILE_BYTES", MAX_ROBOT_FILE_NODES,
                               "MAX_ROBOT_FILE_NODES")


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
        self._constructor: yaml.constructor.SafeConstructor | None = None

    @property
    def constructor(self) -> yaml.constructor.SafeConstructor:
        """The safe loader's constructor that builds this file's plain values (one per file: it keeps
        what it built)."""
        if self._constructor is None:
            self._constructor = yaml.constructor.SafeConstructor()
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
    """The file's YAML node tree (``None`` for a file with no document), read within :data:`ROBOT_FILE_LIMITS`.

    Raises:
        ConfigError: the file cannot be read, is past a limit (named, with the line where it was
            passed), or is not valid YAML (with the line where the parser stopped).
    """
    try:
        return read_yaml(path, ROBOT_FILE_LIMITS)[1]
    except FileProblem as e:
        raise ConfigError([ConfigProblem(str(path), e.line, e.what, e.fix)]) from None


def plain(node: yaml.Node, found: Findings) -> Any:
    """The node as a plain Python value (``None``, reported, when the safe loader cannot build it)."""
    try:
        return construct(node, found.constructor)
    except FileProblem as e:
        found.add(e.line, e.what, e.fix)
        return None


class _NotScalar:
    def __repr__(self) -> str:
        return "NOT_SCALAR"


#: what :func:`scalar` gives for a mapping or list
NOT_SCALAR: Any = _NotScalar()


def scalar(node: yaml.Node, found: Findings) -> Any:
    """A scalar node's plain value; :data:`NOT_SCALAR` for a mapping or list."""
    return plain(node, found) if isinstance(node, yaml.ScalarNode) else NOT_SCALAR
