"""Every ``python`` block of README.md and docs/ runs, in lock step against the simulator (see
tests/docs/blocks.py for the conventions). A block runs in a folder of its own, where ``robots/`` is
the repository's, so that what it writes (``run.csv``) lands there."""

from __future__ import annotations

import contextlib
import inspect
import io
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .blocks import ROOT, Block, python_blocks
from .conftest import lockstep_arm

BLOCKS = python_blocks()


@contextlib.contextmanager
def given(block: Block, channel: str) -> Iterator[dict[str, Any]]:
    """The names a block is handed (its `<!-- docs: ... -->` options)."""
    robot = block.options.get("arm")
    if robot is None:
        yield {}
        return
    with lockstep_arm(robot, channel, enable=True) as (arm, sim):
        yield {"arm": arm, "sim": sim}


def call_tests(namespace: dict[str, Any]) -> list[str]:
    """Call the block's ``test_*`` functions, each with a fresh lock-step ``akarm_sim`` of arm6."""
    from akarm.testing.rig import SimulatedArm

    called = []
    for name, fn in list(namespace.items()):
        if not (name.startswith("test_") and inspect.isfunction(fn)):
            continue
        params = list(inspect.signature(fn).parameters)
        assert set(params) <= {"akarm_sim"}, f"{name}: only the akarm_sim fixture is given to docs tests"
        with SimulatedArm.start(ROOT / "robots" / "arm6.yaml", "virtual") as akarm_sim:
            fn(*([akarm_sim] if params else []))
        called.append(name)
    return called


@pytest.mark.parametrize("block", BLOCKS, ids=[b.name for b in BLOCKS])
def test_python_block_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, channel: str) -> None:
    (tmp_path / "robots").symlink_to(ROOT / "robots")
    monkeypatch.chdir(tmp_path)
    code = compile(block.code, block.name, "exec")
    with given(block, channel) as names, contextlib.redirect_stdout(io.StringIO()):
        namespace: dict[str, Any] = {"__name__": "__docs__", **names}
        exec(code, namespace)
        called = call_tests(namespace)
    assert called or "def test_" not in block.code, "a test file whose tests were not called"


def test_the_blocks_are_found() -> None:
    """The collector sees the blocks it must run (a fence it misreads would silently run nothing)."""
    names = {b.name.split(":")[0] for b in BLOCKS}
    assert {"README.md", "docs/python-api.md", "docs/testing.md", "docs/index.md"} <= names
    assert len(BLOCKS) >= 6 and any(b.options for b in BLOCKS)
