"""Shared test fixtures."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from pathlib import Path

import can
import pytest

from akarm.bus import drain as _drain

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def _no_python_can_configuration(monkeypatch: pytest.MonkeyPatch) -> None:
    """Robot files are read as python-can users configure their buses (CAN_* variables, can.conf,
    .canrc): a developer's own configuration must not change what the tests see."""
    import can.util

    for name in list(os.environ):
        if name.startswith(("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG")):
            monkeypatch.delenv(name)
    monkeypatch.setattr(can.util, "CONFIG_FILES", [])
    monkeypatch.setattr(can, "rc", {})
ROBOTS = ROOT / "robots"
_counter = itertools.count()


@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    """A virtual-bus channel name unique to this test (python-can virtual buses share by name)."""
    return f"akarm-test-{os.getpid()}-{next(_counter)}-{request.node.name}"


def has_vcan(name: str = "vcan0") -> bool:
    """True when a SocketCAN interface ``name`` exists on this machine."""
    return Path(f"/sys/class/net/{name}").exists()


def has_can_sockets() -> bool:
    """True when this kernel supports CAN sockets (AF_CAN); without, SocketCAN buses fail with errno 97."""
    import socket

    try:
        socket.socket(socket.PF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except (OSError, AttributeError):
        return False
    return True


def missing_socketcan_fix(channel: str) -> str:
    """What the error for a missing SocketCAN ``channel`` must say here: how to create the interface
    where the kernel has CAN support, that it has none (not "bring the link up") where it has not."""
    if not has_can_sockets():
        return "this kernel has no CAN support"
    if channel.startswith("vcan"):
        return f"sudo ip link add dev {channel} type vcan && sudo ip link set up {channel}"
    return f"sudo ip link set {channel} up type can"


def wait_until(cond: Callable[[], bool], timeout: float) -> bool:
    """Poll ``cond`` every 5 ms for up to ``timeout`` s (simulators and CLIs run on threads of their
    own: a test waits for what it checks, with a deadline, instead of sleeping a fixed time)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return bool(cond())


def send(bus: can.BusABC, arbitration_id: int, data: bytes, extended: bool = False) -> None:
    """Send one frame on ``bus`` (a test playing the host or another node)."""
    bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=extended))


def drain(bus: can.BusABC) -> list[can.Message]:
    """Every frame already waiting on ``bus``."""
    return list(_drain(bus, limit=1 << 20))


@pytest.fixture(scope="module")
def planar2():
    """robots/planar2.yaml, loaded once per module."""
    from akarm.config_loader import load_robot

    return load_robot(ROBOTS / "planar2.yaml")
