"""Shared test fixtures."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ROOT / "robots"
_counter = itertools.count()


@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    """A virtual-bus channel name unique to this test (python-can virtual buses share by name)."""
    return f"akarm-test-{os.getpid()}-{next(_counter)}-{request.node.name}"


def has_vcan(name: str = "vcan0") -> bool:
    """True when a SocketCAN interface ``name`` exists on this machine."""
    return Path(f"/sys/class/net/{name}").exists()
