"""Files akarm writes and reads: written so that a crash cannot leave half of one, read within bounds.

Writing: :func:`atomic_write`, and :func:`check_writable` to say before any work is done that a file
cannot be written there. Telemetry, recordings, plots, robot files and the CLI's output files all
write through it.

Reading: every file akarm reads is read within limits that its reader names (its size, and what
the format can multiply: YAML nodes and nesting, CSV rows), checked before the memory they would
take is spent, in time proportional to what was read:

- :func:`read_bytes` / :func:`read_text`: a file within ``max_bytes`` (never more is read);
- :func:`compose_yaml` / :func:`load_yaml`: YAML within :class:`YamlLimits`: nesting depth, entries
  in one list or mapping, and nodes counted with every alias expanded (an alias bomb is refused as
  the alias is read, before anything expands it); no recursion proportional to the input;
- :func:`read_csv_table`: a header line and rows of numbers within a byte and a row limit, the rows
  counted before the table is allocated.

Each refusal is a :class:`FileProblem` (what, with the limit's name and number; the fix; the line),
which the reader raises again as its own error (:class:`~akarm.errors.ConfigError`,
:class:`~akarm.errors.RecordingError`). The limits are listed in the README's "Limits" table.

A low layer: it imports only :mod:`akarm.errors` (and PyYAML, NumPy).
"""

from __future__ import annotations

import csv
import io
import itertools
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from akarm.errors import RecordingError

__all__ = ["MAX_YAML_DEPTH", "YAML_PARSER", "FileProblem", "YamlLimits", "atomic_write", "check_writable",
           "compose_yaml", "construct", "load_yaml", "number", "over", "read_bytes", "read_csv_table", "read_text",
           "read_yaml"]

#: Nesting levels of any YAML file akarm reads (a robot file needs 6).
MAX_YAML_DEPTH = 32


def check_writable(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path if a file can be written there (before anything is done that the file is for).

    Raises:
        RecordingError: it is a directory, or its directory cannot be created or written; the
            message says which and what to do.
    """
    if "\x00" in os.fsdecode(path):
        raise RecordingError("the path holds a NUL character", fix="check the path")
    target = Path(path)
    if target.is_dir():
        raise RecordingError(f"{target} is a directory, not a file", fix="give a file name, e.g. out/run.csv")
    parent = target.parent if str(target.parent) else Path(".")
    existing = parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise RecordingError(f"cannot create directory {parent}: {existing} is not a directory",
                             fix="choose a path whose directories can exist")
    if not os.access(existing, os.W_OK | os.X_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise RecordingError(f"cannot write {target}: permission denied", fix="choose a directory you can write to")
    return target


def atomic_write(path: str | os.PathLike[str], write: Callable[[io.BufferedWriter], object]) -> Path:
    """Write a file through ``write(fileobj)`` to a temporary name beside it, then rename it into place.

    Raises:
        RecordingError: the file cannot be written (a directory, no permission, a full disk); no
            half file and no temporary file is left.
    """
    target = check_writable(path)
    tmp: str | None = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the permissions open() would
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except OSError as e:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise RecordingError(f"cannot write {target}: {e.strerror or e}",
                             fix="check the path, its permissions and the free disk space") from None
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise
    return target


# ------------------------------------------------------------------------------------------------
# reading within bounds
# ------------------------------------------------------------------------------------------------
class FileProblem(Exception):
    """Why a file was not read: ``what`` (a limit's name and number, when a limit refused it), ``fix``,
    and the 1-based ``line`` where one applies. Readers raise it again as their own error."""

    def __init__(self, what: str, fix: str, line: int | None = None) -> None:
        self.what = what
        self.fix = fix
        self.line = line
        super().__init__(what if line is None else f"line {line}: {what}")


def number(n: float) -> str:
    """``2 000 000``: a number for messages, its thousands apart."""
    return f"{int(n) if float(n).is_integer() else n:,}".replace(",", " ")


def over(found: str, limit: float, unit: str, name: str) -> str:
    """``"... over the limit of 10 000 keyframes (MAX_KEYFRAMES)"``: a refusal naming its limit."""
    return f"{found}, over the limit of {number(limit)} {unit}" + (f" ({name})" if name else "")


_NONBLOCK = getattr(os, "O_NONBLOCK", 0)  # (POSIX; elsewhere a plain open)


def _too_large(what: str, size: int | None, max_bytes: int, name: str) -> FileProblem:
    """The file of ``size`` bytes (``None``: more than the limit, not a regular file) is too large."""
    found = f"more than {number(max_bytes)}" if size is None else number(size)
    return FileProblem(over(f"the {what} is {found} bytes", max_bytes, "bytes", name),
                       f"is it the right file? akarm reads at most {number(max_bytes)} bytes of a {what}")


def _open_problem(e: OSError, what: str) -> FileProblem:
    if isinstance(e, FileNotFoundError):
        return FileProblem(f"{what} not found", "check the path (relative paths are from the current directory)")
    return FileProblem(f"cannot read the {what}: {e.strerror or e}", "check the path and its permissions")


@contextmanager
def _opened(path: str | os.PathLike[str], max_bytes: int, what: str, name: str) -> Iterator[io.BufferedReader]:
    """The file open for reading, refused first when it is a regular file of more than ``max_bytes``;
    an OSError while it is open is a :class:`FileProblem` too.

    Opening never waits: a FIFO that no program writes to opens at once and reads as empty (opening it
    plainly would wait for a writer for ever: a server thread, the lock it holds). A pipe with a
    writer (``/dev/stdin``, ``<(...)``) is read as before."""
    if "\x00" in os.fsdecode(path):
        raise FileProblem(f"the {what}'s path holds a NUL character", "check the path")
    try:
        fd = os.open(path, os.O_RDONLY | _NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        try:
            file = os.fdopen(fd, "rb")
        except BaseException:
            os.close(fd)
            raise
    except OSError as e:
        raise _open_problem(e, what) from None
    try:
        with file as f:
            info = os.fstat(fd)
            if stat.S_ISREG(info.st_mode) and info.st_size > max_bytes:
                raise _too_large(what, info.st_size, max_bytes, name)
            if _NONBLOCK and not stat.S_ISREG(info.st_mode):
                os.set_blocking(fd, True)  # (a pipe's reads wait for its writer, as they always did)
            yield f
    except OSError as e:
        raise _open_problem(e, what) from None


def read_bytes(path: str | os.PathLike[str], max_bytes: int, *, what: str = "file", name: str = "") -> bytes:
    """The file's bytes, if it holds at most ``max_bytes`` (a regular file is refused by its size
    before anything is read; anything else is read to one byte past the limit, no further).

    ``what`` names the file in messages ("robot file"); ``name`` the limit ("MAX_ROBOT_FILE_BYTES").

    Raises:
        FileProblem: not found, unreadable (a directory, no permission), or larger than the limit.
    """
    with _opened(path, max_bytes, what, name) as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise _too_large(what, None, max_bytes, name)
    return data


def read_text(path: str | os.PathLike[str], max_bytes: int, *, what: str = "file", name: str = "") -> str:
    """:func:`read_bytes`, as UTF-8 text.

    Raises:
        FileProblem: as :func:`read_bytes`; or the bytes are not UTF-8 (with the line of the first bad one).
    """
    data = read_bytes(path, max_bytes, what=what, name=name)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise FileProblem(f"the {what} is not UTF-8 text (byte {e.start})", f"save the {what} as UTF-8 text",
                          data.count(b"\n", 0, e.start) + 1) from None


# ------------------------------------------------------------------------------------------------
# YAML
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class YamlLimits:
    """The bounds of one kind of YAML file.

    Attributes:
        kind: what the file is, for messages ("robot file").
        max_bytes, bytes_name: its size, and the limit's name.
        max_nodes, nodes_name: its values (scalars, lists, mappings), every alias counted as the
            whole value it repeats, and the limit's name.
        max_items, items, items_name: entries in one list or mapping (``None``: only ``max_nodes``
            bounds them), what they are ("keyframes"), and the limit's name.
        max_depth: nesting levels.
    """

    kind: str
    max_bytes: int
    bytes_name: str
    max_nodes: int
    nodes_name: str
    max_items: int | None = None
    items: str = "entries"
    items_name: str = ""
    max_depth: int = MAX_YAML_DEPTH


#: The parser :func:`compose_yaml` takes events from: PyYAML's in C when it was built with libyaml
#: (three to ten times faster), else its Python one; the two give the same nodes and marks.
YAML_PARSER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _Open:
    """A list or mapping being composed."""

    __slots__ = ("anchor", "key", "node", "start")

    def __init__(self, node: yaml.CollectionNode, anchor: str | None, start: int) -> None:
        self.node = node
        self.anchor = anchor
        self.start = start  # the node count before it
        self.key: yaml.Node | None = None  # a mapping's key waiting for its value


class _Composer:
    """PyYAML's composition (events to a node tree with resolved tags, aliases shared), without its
    recursion, counting nodes as an alias would expand them."""

    def __init__(self, text: str, limits: YamlLimits) -> None:
        self.parser = YAML_PARSER(text)
        self.limits = limits
        self.count = 0
        self.anchors: dict[str, yaml.Node] = {}
        self.sizes: dict[str, int] = {}  # anchor -> nodes the anchored value holds, aliases expanded
        self.open: list[_Open] = []

    def single(self) -> yaml.Node | None:
        p = self.parser
        try:
            p.get_event()  # stream start
            node = None
            if not p.check_event(yaml.StreamEndEvent):
                p.get_event()  # document start
                node = self.compose()
                p.get_event()  # document end
            if not p.check_event(yaml.StreamEndEvent):
                event = p.get_event()
                raise FileProblem(f"the {self.limits.kind} holds more than one YAML document (a second '---')",
                                  "keep one document: remove the second '---' and what follows",
                                  event.start_mark.line + 1)
            return node
        finally:
            p.dispose()

    def _add(self, n: int, mark: Any, alias: str | None = None) -> None:
        self.count += n
        lim = self.limits
        if self.count > lim.max_nodes:
            what = f"the {lim.kind} holds more than {number(lim.max_nodes)} values"
            if alias is not None:
                what = f"the alias *{alias} repeats {number(n)} values: the {lim.kind} would hold more than " \
                       f"{number(lim.max_nodes)}"
            fix = ("is it an alias bomb? write the values out, or reuse fewer of them" if alias is not None else
                   f"is it the right file? akarm reads at most {number(lim.max_nodes)} YAML values of a {lim.kind}")
            raise FileProblem(over(what, lim.max_nodes, "values", lim.nodes_name), fix, mark.line + 1)

    def _tag(self, kind: type[yaml.Node], event: Any, value: str | None) -> str:
        tag = event.tag
        return tag if tag is not None and tag != "!" else self.parser.resolve(kind, value, event.implicit)

    def _anchor(self, event: Any, node: yaml.Node) -> None:
        anchor = event.anchor
        if anchor is None:
            return
        if anchor in self.anchors:
            raise FileProblem(f"the anchor &{anchor} is defined twice (first on line "
                              f"{self.anchors[anchor].start_mark.line + 1})", "give each anchor its own name",
                              event.start_mark.line + 1)
        self.anchors[anchor] = node

    def compose(self) -> yaml.Node:
        p, lim, stack = self.parser, self.limits, self.open
        while True:
            event = p.get_event()
            start: Any = event.start_mark  # (PyYAML's C parser and its Python one: two types of mark)
            end_mark: Any = event.end_mark
            done: yaml.Node
            if isinstance(event, yaml.AliasEvent):
                done = self._alias(event)
            elif isinstance(event, yaml.ScalarEvent):
                self._add(1, start)
                done = yaml.ScalarNode(self._tag(yaml.ScalarNode, event, event.value), event.value,
                                       start, end_mark, style=event.style or None)  # (C: "" for plain)
                self._anchor(event, done)
                if event.anchor is not None:
                    self.sizes[event.anchor] = 1
            elif isinstance(event, yaml.SequenceStartEvent | yaml.MappingStartEvent):
                self._add(1, start)
                if len(stack) >= lim.max_depth:
                    raise FileProblem(over(f"the {lim.kind} nests lists and mappings more than {lim.max_depth} "
                                           "levels deep", lim.max_depth, "levels", "MAX_YAML_DEPTH"),
                                      "flatten it: no robot, motor or recording file needs that depth",
                                      start.line + 1)
                seq = isinstance(event, yaml.SequenceStartEvent)
                kind: type[yaml.CollectionNode] = yaml.SequenceNode if seq else yaml.MappingNode
                made = kind(self._tag(kind, event, None), [], start, None, flow_style=event.flow_style)
                self._anchor(event, made)
                stack.append(_Open(made, event.anchor, self.count - 1))
                continue
            else:  # the end of a list or mapping
                top = stack.pop()
                top.node.end_mark = end_mark
                if top.anchor is not None:
                    self.sizes[top.anchor] = self.count - top.start
                done = top.node
            if not stack:
                return done
            self._attach(stack[-1], done)

    def _alias(self, event: Any) -> yaml.Node:
        name = event.anchor
        if name not in self.anchors:
            raise FileProblem(f"the alias *{name} names no anchor defined before it",
                              f"define &{name} before using *{name}", event.start_mark.line + 1)
        if name not in self.sizes:  # still open: the alias is inside the value it names
            raise FileProblem(f"the alias *{name} is inside the value &{name} it repeats (a loop)",
                              "an alias may repeat a value defined before it, not one that contains it",
                              event.start_mark.line + 1)
        self._add(self.sizes[name], event.start_mark, name)
        return self.anchors[name]

    def _attach(self, parent: _Open, child: yaml.Node) -> None:
        node = parent.node
        if isinstance(node, yaml.MappingNode):
            if parent.key is None:
                parent.key = child
                return
            node.value.append((parent.key, child))
            parent.key = None
        else:
            node.value.append(child)
        lim = self.limits
        if lim.max_items is not None and len(node.value) > lim.max_items:
            what = "list" if isinstance(node, yaml.SequenceNode) else "mapping"
            raise FileProblem(over(f"the {what} from line {node.start_mark.line + 1} has more than "
                                   f"{number(lim.max_items)} {lim.items}", lim.max_items, lim.items, lim.items_name),
                              f"split it: akarm reads at most {number(lim.max_items)} {lim.items} of a {lim.kind}",
                              child.start_mark.line + 1)


def compose_yaml(text: str, limits: YamlLimits) -> yaml.Node | None:
    """The YAML text's node tree, as ``yaml.compose`` with the safe loader gives it (``None`` for no
    document), composed within ``limits`` without recursion.

    Raises:
        FileProblem: not valid YAML (at its line), past a limit (which, where), an alias to an
            undefined anchor or inside its own anchor, a second document.
    """
    if len(text) > limits.max_bytes:  # (a character is at least a byte)
        raise _too_large(limits.kind, None, limits.max_bytes, limits.bytes_name)
    try:
        return _Composer(text, limits).single()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        what = " ".join(x for x in (e.context, e.problem) if x)
        raise FileProblem(f"not valid YAML: {what}", "fix the YAML syntax on or just before this line "
                          "(indentation, a missing ':' or a stray quote)",
                          mark.line + 1 if mark is not None else None) from None
    except yaml.YAMLError as e:
        raise FileProblem(f"not valid YAML: {e}", "fix the YAML syntax") from None


def construct(node: yaml.Node, constructor: yaml.constructor.SafeConstructor | None = None) -> Any:
    """A composed node as plain Python values (the safe loader's), deeply.

    Raises:
        FileProblem: a value the safe loader cannot build (an unknown tag, an integer of more than
            4300 digits, merges (``<<``) nested too deeply), at its line.
    """
    c = constructor if constructor is not None else yaml.constructor.SafeConstructor()
    try:
        return c.construct_object(node, deep=True)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        raise FileProblem(f"cannot read this value: {e.problem or e}", "write a plain YAML value",
                          mark.line + 1 if mark is not None else node.start_mark.line + 1) from None
    except (yaml.YAMLError, ValueError, RecursionError) as e:
        raise FileProblem(f"cannot read this value: {e}", "write a plain YAML value",
                          node.start_mark.line + 1) from None


def read_yaml(path: str | os.PathLike[str], limits: YamlLimits) -> tuple[str, yaml.Node | None]:
    """The YAML file's text and node tree (``None`` for no document), read and composed within ``limits``.

    Raises:
        FileProblem: see :func:`read_text` and :func:`compose_yaml`.
    """
    text = read_text(path, limits.max_bytes, what=limits.kind, name=limits.bytes_name)
    return text, compose_yaml(text, limits)


def load_yaml(path: str | os.PathLike[str], limits: YamlLimits) -> Any:
    """The YAML file's plain value (``None`` for an empty file), read, composed and built within ``limits``.

    Raises:
        FileProblem: see :func:`read_text`, :func:`compose_yaml` and :func:`construct`.
    """
    node = read_yaml(path, limits)[1]
    return None if node is None else construct(node)


# ------------------------------------------------------------------------------------------------
# CSV tables of numbers
# ------------------------------------------------------------------------------------------------
_CHUNK = 1 << 20  # bytes read at a time while counting rows
_ROWS_AT_ONCE = 1 << 15  # rows parsed at a time
_MAX_HEADER = 1 << 16  # bytes of a header line


def read_csv_table(path: str | os.PathLike[str], *, what: str, max_bytes: int, bytes_name: str, max_rows: int,
                   rows_name: str, rows: str = "rows", max_values: int | None = None, values_name: str = "",
                   check_header: Callable[[list[str]], object] | None = None) -> tuple[list[str], np.ndarray]:
    """A CSV file of one header line and rows of numbers: ``(header, values)``, values (rows × columns).

    The file is refused by its size first, its rows are then counted (in chunks, without keeping
    them) and refused past ``max_rows`` (``rows`` says what they are, ``rows_name`` names the limit),
    or past ``max_values`` numbers in all (``values_name``), and only then is the table allocated
    and parsed, a block of rows at a time. ``check_header`` (raising :class:`FileProblem`) looks at
    the header before any row is read. Row numbers in messages are the file's lines (the header is
    line 1).

    Raises:
        FileProblem: not found or unreadable, too large, too many rows, not UTF-8, a header line over
            64 KiB, a row with another number of values than the header, a value that is not a number.
    """
    with _opened(path, max_bytes, what, bytes_name) as f:
        first = f.readline(_MAX_HEADER + 1)
        if len(first) > _MAX_HEADER:
            raise FileProblem(f"the {what}'s header line is longer than {_MAX_HEADER} bytes", f"is it a {what}?", 1)
        header = _csv_line(first, 1, what)
        if check_header is not None:
            check_header(header)
        limit = max_rows if max_values is None else min(max_rows, max_values // max(1, len(header)))
        start = f.tell()
        n = _count_rows(f, limit, len(first), max_bytes, what, bytes_name)
        if n > limit:
            found = f"the {what} has more than {number(limit)} {rows}"
            if limit < max_rows:
                raise FileProblem(over(f"{found} of {len(header)} values", max_values or 0, "values", values_name),
                                  f"is it the right file? akarm reads at most {number(max_values or 0)} values of "
                                  f"a {what}")
            raise FileProblem(over(found, max_rows, rows, rows_name),
                              f"is it the right file? akarm reads at most {number(max_rows)} {rows} of a {what}")
        f.seek(start)
        return header, _parse_rows(f, n, len(header), what)


def _csv_line(raw: bytes, line: int, what: str) -> list[str]:
    try:
        text = raw.decode("utf-8")
        return next(csv.reader([text]), [])
    except UnicodeDecodeError:
        raise FileProblem(f"line {line} of the {what} is not UTF-8 text", f"save the {what} as UTF-8 text",
                          line) from None
    except csv.Error as e:
        raise FileProblem(f"line {line} of the {what} is not a CSV row ({e})", "fix that row", line) from None


def _count_rows(f: io.BufferedReader, limit: int, read: int, max_bytes: int, what: str, bytes_name: str) -> int:
    """Lines from here to the end (the last one without its newline counted too), at most one past ``limit``."""
    n = 0
    last = b"\n"
    while chunk := f.read(_CHUNK):
        read += len(chunk)
        if read > max_bytes:  # (not a regular file, or one that grows)
            raise _too_large(what, None, max_bytes, bytes_name)
        n += chunk.count(b"\n")
        last = chunk[-1:]
        if n > limit:
            return n
    return n + (last != b"\n")


def _parse_rows(f: io.BufferedReader, n: int, width: int, what: str) -> np.ndarray:
    """``n`` rows of ``width`` numbers: NumPy's parser a block at a time, Python's csv where a block
    fails it (to say which row and why)."""
    out = np.empty((n, width))
    text = io.TextIOWrapper(f, encoding="utf-8", newline="\n")
    done = 0
    try:
        while done < n:
            block = list(itertools.islice(text, min(_ROWS_AT_ONCE, n - done)))
            if not block:
                break
            try:
                values = np.loadtxt(block, delimiter=",", comments=None, dtype=float, ndmin=2)
            except ValueError:
                values = np.empty((0, 0))
            if values.shape != (len(block), width):
                values = _parse_slowly(block, done + 2, width, what)
            out[done:done + len(block)] = values
            done += len(block)
    except UnicodeDecodeError:
        raise FileProblem(f"the {what} is not UTF-8 text (near line {done + 2})", f"save the {what} as UTF-8 text",
                          done + 2) from None
    finally:
        text.detach()
    return out[:done]


def _parse_slowly(block: list[str], first: int, width: int, what: str) -> np.ndarray:
    """A block of rows, one by one: the first row that is not ``width`` numbers is refused with its number."""
    out = np.empty((len(block), width))
    for k, line in enumerate(block):
        number = first + k
        try:
            row = next(csv.reader([line]), [])
        except csv.Error as e:
            raise FileProblem(f"row {number} is not a CSV row ({e})", "fix that row", number) from None
        if len(row) != width:
            raise FileProblem(f"row {number} has {len(row)} values, expected {width} (truncated file?)",
                              "delete the broken rows or re-record", number)
        try:
            out[k] = [float(x) for x in row]
        except ValueError:
            raise FileProblem(f"row {number} has a value that is not a number", "fix that row", number) from None
    return out
