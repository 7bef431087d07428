"""akarm.files' bounded readers on their own: bytes, YAML (the same nodes as PyYAML, within limits
and without recursion), CSV tables (rows counted before they are parsed). The readers that use them:
tests/unit/test_hostile_files.py."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from akarm import RecordingError, files
from akarm.files import FileProblem, YamlLimits, compose_yaml, construct, read_bytes, read_csv_table, read_text

ROOT = Path(__file__).resolve().parents[2]
PARSERS = [yaml.SafeLoader] + ([yaml.CSafeLoader] if hasattr(yaml, "CSafeLoader") else [])
WIDE = YamlLimits("test file", 1 << 30, "MAX_TEST_BYTES", 10_000_000, "MAX_TEST_NODES")


def limits(**changes: object) -> YamlLimits:
    base: dict[str, object] = {"kind": "test file", "max_bytes": 1 << 20, "bytes_name": "MAX_TEST_BYTES",
                               "max_nodes": 1000, "nodes_name": "MAX_TEST_NODES"}
    return YamlLimits(**(base | changes))  # type: ignore[arg-type]


def refused(text: str, lim: YamlLimits = WIDE) -> FileProblem:
    with pytest.raises(FileProblem) as info:
        compose_yaml(text, lim)
    return info.value


# ---- bytes ---------------------------------------------------------------------------------------
def test_a_file_is_read_up_to_its_limit_and_refused_one_byte_past_it(tmp_path: Path) -> None:
    f = tmp_path / "f.bin"
    f.write_bytes(b"x" * 100)
    assert read_bytes(f, 100) == b"x" * 100
    with pytest.raises(FileProblem) as info:
        read_bytes(f, 99, what="robot file", name="MAX_ROBOT_FILE_BYTES")
    assert info.value.what == "the robot file is 100 bytes, over the limit of 99 bytes (MAX_ROBOT_FILE_BYTES)"


def test_an_endless_file_is_read_to_one_byte_past_the_limit_no_further() -> None:
    with pytest.raises(FileProblem, match=r"more than 4 096 bytes, over the limit of 4 096 bytes \(MAX_X\)"):
        read_bytes("/dev/zero", 4096, what="file", name="MAX_X")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX")
def test_a_fifo_nobody_writes_to_opens_at_once_and_reads_empty(tmp_path: Path) -> None:
    """Opening a FIFO plainly waits for a writer, for ever if none comes (a server's thread, its lock)."""
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    t0 = time.monotonic()
    assert read_bytes(fifo, 100) == b""
    assert time.monotonic() - t0 < 5.0
    r, w = os.pipe()  # a pipe with a writer is read as before (/dev/stdin, <(...))
    os.write(w, b"hello")
    os.close(w)
    try:
        assert read_bytes(f"/dev/fd/{r}", 100) == b"hello"
    finally:
        os.close(r)


def test_a_path_with_a_nul_character_is_a_problem_not_a_value_error(tmp_path: Path) -> None:
    with pytest.raises(FileProblem, match="NUL character"):
        read_text(str(tmp_path / "a\x00b.yaml"), 100, what="recording")
    with pytest.raises(RecordingError, match="NUL character"):
        files.check_writable(str(tmp_path / "a\x00b.csv"))


def test_missing_unreadable_and_not_utf8(tmp_path: Path) -> None:
    with pytest.raises(FileProblem, match=r"^URDF not found$"):
        read_bytes(tmp_path / "none", 10, what="URDF")
    with pytest.raises(FileProblem, match="cannot read the URDF: Is a directory"):
        read_bytes(tmp_path, 10, what="URDF")
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"a: 1\nb: \xff\n")
    with pytest.raises(FileProblem, match=r"not UTF-8 text \(byte 8\)") as info:
        read_text(bad, 100)
    assert info.value.line == 2


# ---- YAML: the same nodes as PyYAML ---------------------------------------------------------------
def _same(a: yaml.Node, b: yaml.Node) -> None:
    assert type(a) is type(b) and a.tag == b.tag
    for m in ("start_mark", "end_mark"):
        ma, mb = getattr(a, m), getattr(b, m)
        assert (ma.index, ma.line, ma.column) == (mb.index, mb.line, mb.column)
    if isinstance(a, yaml.ScalarNode):
        assert (a.value, a.style) == (b.value, b.style)
    elif isinstance(a, yaml.MappingNode):
        assert len(a.value) == len(b.value) and a.flow_style == b.flow_style
        for (ka, va), (kb, vb) in zip(a.value, b.value, strict=True):
            _same(ka, kb)
            _same(va, vb)
    else:
        assert len(a.value) == len(b.value) and a.flow_style == b.flow_style
        for xa, xb in zip(a.value, b.value, strict=True):
            _same(xa, xb)


SAMPLES = [*(ROOT / "robots").glob("*.yaml"), ROOT / "akarm" / "data" / "motors.yaml"]
TEXTS = ["a: &x [1, 2, {b: c}]\nb: *x\nc: !!str 3\nd: {<<: {e: 1}, f: 2}\n'q': |\n  block\n  text\n",
         "- [1, 2.5, .inf, ~, yes, 0x1f, 2001-12-14]\n- {? explicit : v, nested: {x: [{}]}}\n", "plain\n",
         "# nothing\n"]


@pytest.mark.parametrize("parser", PARSERS, ids=lambda p: p.__name__)
@pytest.mark.parametrize("text", [p.read_text() for p in SAMPLES] + TEXTS,
                         ids=[p.name for p in SAMPLES] + [f"text{k}" for k in range(len(TEXTS))])
def test_the_nodes_are_pyyamls(monkeypatch: pytest.MonkeyPatch, parser: type, text: str) -> None:
    monkeypatch.setattr(files, "YAML_PARSER", parser)
    ours = compose_yaml(text, WIDE)
    theirs = yaml.compose(text, Loader=yaml.SafeLoader)
    if theirs is None:
        assert ours is None
        return
    assert ours is not None
    _same(ours, theirs)
    assert construct(ours) == yaml.safe_load(text)


@pytest.mark.parametrize("parser", PARSERS, ids=lambda p: p.__name__)
def test_syntax_errors_keep_their_line(monkeypatch: pytest.MonkeyPatch, parser: type) -> None:
    monkeypatch.setattr(files, "YAML_PARSER", parser)
    e = refused("name: x\njoints:\n  - name: a\n   can_id: 1\n")
    assert e.what.startswith("not valid YAML: ") and e.line == 4


# ---- YAML: limits ----------------------------------------------------------------------------------
def billion_laughs(levels: int = 9) -> str:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("parser", PARSERS, ids=lambda p: p.__name__)
def test_an_alias_bomb_is_refused_at_the_alias_that_passes_the_limit(monkeypatch: pytest.MonkeyPatch,
                                                                     parser: type) -> None:
    monkeypatch.setattr(files, "YAML_PARSER", parser)
    e = refused(billion_laughs(), limits(max_nodes=100_000))
    # a0 10 values, a1 91, a2 820, a3 7 381, a4 66 430: the fifth a4 brings the count past 100 000
    assert e.what == ("the alias *a4 repeats 66 430 values: the test file would hold more than 100 000, over the "
                      "limit of 100 000 values (MAX_TEST_NODES)")
    assert e.line == 6 and "alias bomb" in e.fix


def test_the_node_limit_is_exact_with_aliases_counted_at_their_full_size() -> None:
    text = "a: &a [1, 2, 3]\nb: *a\n"  # mapping 1, a 1, [1, 2, 3] 4, b 1, *a 4: 11 values
    assert construct(compose_yaml(text, limits(max_nodes=11))) == {"a": [1, 2, 3], "b": [1, 2, 3]}
    e = refused(text, limits(max_nodes=10))
    assert "alias *a repeats 4 values" in e.what and e.line == 2
    e = refused("[1, 2, 3, 4]", limits(max_nodes=4))
    assert e.what == "the test file holds more than 4 values, over the limit of 4 values (MAX_TEST_NODES)"


def test_an_alias_inside_its_own_anchor_is_a_loop_not_a_recursive_value() -> None:
    e = refused("a: &a [1, *a]\n")
    assert "inside the value &a it repeats" in e.what and e.line == 1
    assert "names no anchor" in refused("a: *nowhere\n").what
    assert "defined twice (first on line 1)" in refused("a: &x 1\nb: &x 2\n").what
    assert "more than one YAML document" in refused("a: 1\n---\nb: 2\n").what


@pytest.mark.parametrize("parser", PARSERS, ids=lambda p: p.__name__)
def test_nesting_is_bounded_without_recursion(monkeypatch: pytest.MonkeyPatch, parser: type) -> None:
    monkeypatch.setattr(files, "YAML_PARSER", parser)
    ok = "[" * files.MAX_YAML_DEPTH + "]" * files.MAX_YAML_DEPTH
    assert compose_yaml(ok, WIDE) is not None
    e = refused("[" * (files.MAX_YAML_DEPTH + 1) + "]" * (files.MAX_YAML_DEPTH + 1))
    assert e.what.endswith(f"over the limit of {files.MAX_YAML_DEPTH} levels (MAX_YAML_DEPTH)")
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(150)  # nothing in the composition recurses per level
    try:
        deep = refused("[" * 100_000).what  # (libyaml refuses past 1000 flow levels as it scans ahead)
        assert "MAX_YAML_DEPTH" in deep or deep.endswith("exceeded maximum nesting depth")
        assert compose_yaml("[" * 30 + "]" * 30, WIDE) is not None
    finally:
        sys.setrecursionlimit(limit)


def test_entries_in_one_list_or_mapping() -> None:
    lim = limits(max_items=3, items="keyframes", items_name="MAX_KEYFRAMES")
    assert compose_yaml("k:\n  - 1\n  - 2\n  - 3\n", lim) is not None
    e = refused("k:\n  - 1\n  - 2\n  - 3\n  - 4\n  - 5\n", lim)
    assert e.what == ("the list from line 2 has more than 3 keyframes, over the limit of 3 keyframes (MAX_KEYFRAMES)")
    assert e.line == 5  # refused at the entry past the limit: nothing after it is read
    assert "mapping from line 1" in refused("{a: 1, b: 2, c: 3, d: 4}", lim).what


def test_values_the_safe_loader_cannot_build_are_problems_not_tracebacks() -> None:
    node = compose_yaml("x: " + "9" * 5000 + "\n", WIDE)
    assert node is not None
    with pytest.raises(FileProblem, match="cannot read this value") as info:
        construct(node)
    assert info.value.line == 1
    node = compose_yaml("x: !!python/object:os.system ls\n", WIDE)
    assert node is not None
    with pytest.raises(FileProblem, match="cannot read this value"):
        construct(node)


def test_too_large_text() -> None:
    assert "over the limit of 10 bytes (MAX_TEST_BYTES)" in refused("a: 12345678\n", limits(max_bytes=10)).what


# ---- CSV tables --------------------------------------------------------------------------------------
def table(path: Path, **changes: object) -> tuple[list[str], np.ndarray]:
    args: dict[str, object] = {"what": "path recording", "max_bytes": 1 << 20, "bytes_name": "MAX_B",
                               "max_rows": 5, "rows_name": "MAX_ROWS", "rows": "samples"}
    return read_csv_table(path, **(args | changes))  # type: ignore[arg-type]


def test_a_table_up_to_its_row_limit(tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    f.write_text("t [s],a [rad]\n" + "".join(f"{k * 0.1:.1f},{k}\n" for k in range(5)))
    header, values = table(f)
    assert header == ["t [s]", "a [rad]"]
    np.testing.assert_array_equal(values, [[float(f"{k * 0.1:.1f}"), k] for k in range(5)])
    f.write_text("t [s],a [rad]\n" + "".join(f"{k * 0.1:.1f},{k}\n" for k in range(6)))
    with pytest.raises(FileProblem) as info:
        table(f)
    assert info.value.what == ("the path recording has more than 5 samples, over the limit of 5 samples (MAX_ROWS)")


def test_rows_are_counted_before_any_is_parsed(tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    f.write_text("t [s],a [rad]\n" + "not a number\n" * 6)  # refused by its count, not by its first row
    with pytest.raises(FileProblem, match="more than 5 samples"):
        table(f)
    with pytest.raises(FileProblem, match="more than 3 rows of 2 values, over the limit of 6 values \\(MAX_V\\)"):
        table(f, max_rows=100, rows="rows", max_values=6, values_name="MAX_V")


def test_header_checked_first(tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    f.write_text("time,a\n" + "1,2\n" * 10)

    def check(header: list[str]) -> None:
        raise FileProblem(f"bad header {header}", "fix it")

    with pytest.raises(FileProblem, match=r"bad header \['time', 'a'\]"):
        table(f, check_header=check)


@pytest.mark.parametrize(("rows", "message", "line"), [
    ("0,1\n0.1,2,3\n", "row 3 has 3 values, expected 2", 3),
    ("0,1\n\n0.2,2\n", "row 3 has 0 values, expected 2", 3),
    ("0,1\n0.1,x\n", "row 3 has a value that is not a number", 3),
    ("0,1\n0.1", "row 3 has 1 values, expected 2", 3),
])
def test_bad_rows_are_named(tmp_path: Path, rows: str, message: str, line: int) -> None:
    f = tmp_path / "t.csv"
    f.write_text("t [s],a [rad]\n" + rows)
    with pytest.raises(FileProblem, match=message) as info:
        table(f)
    assert info.value.line == line


def test_quoted_numbers_and_crlf_still_parse(tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    f.write_bytes(b't [s],a [rad]\r\n"0.5",1\r\n0.75,"2"\r\n')
    np.testing.assert_array_equal(table(f)[1], [[0.5, 1.0], [0.75, 2.0]])


def test_a_table_past_its_bytes_is_refused_by_its_size(tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    f.write_text("t [s],a [rad]\n" + "0,1\n" * 100)
    with pytest.raises(FileProblem, match=r"the path recording is 414 bytes, over the limit of 100 bytes \(MAX_B\)"):
        table(f, max_bytes=100, max_rows=1000)
