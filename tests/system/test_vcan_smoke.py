"""SocketCAN sanity check: frames cross vcan0 between two python-can buses (runs in vcan-vm)."""

from __future__ import annotations

import pytest

from .conftest import has_vcan

pytestmark = [pytest.mark.vcan, pytest.mark.skipif(not has_vcan(), reason="no vcan0 on this machine")]


def test_frames_cross_vcan0() -> None:
    import can

    with can.Bus(interface="socketcan", channel="vcan0") as a, can.Bus(interface="socketcan", channel="vcan0") as b:
        a.send(can.Message(arbitration_id=0x123, data=b"\x01\x02", is_extended_id=False))
        a.send(can.Message(arbitration_id=0x2901, data=bytes(8), is_extended_id=True))
        got = [b.recv(timeout=2.0) for _ in range(2)]
    assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got] == [
        (0x123, False, b"\x01\x02"), (0x2901, True, bytes(8))]
