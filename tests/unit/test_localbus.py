"""akarm_local's frames are python-can's own Messages, field for field (the bus itself: tests/sim/test_localbus.py)."""

from __future__ import annotations

import can
import pytest


@pytest.mark.parametrize("fields", [
    (0x141, b"\x01\x02", False, {}),
    (0x2903, bytes(range(8)), True, {"timestamp": 12.5, "channel": "can1", "is_rx": False}),
    (0x7FF, b"", False, {"is_remote_frame": True, "dlc": 6}),
    (0x20000080, b"\x00" * 8, True, {"is_error_frame": True}),
])
def test_fast_messages_equal_python_cans_own(fields):
    from akarm.buses import frames

    arbitration_id, data, extended, kw = fields
    fast = frames._fast(arbitration_id, data, extended, **kw)
    slow = frames._slow(arbitration_id, data, extended, **kw)
    assert fast.equals(slow, timestamp_delta=None, check_channel=True, check_direction=True)
    assert [getattr(fast, f) for f in can.Message.__slots__ if f != "__weakref__"] == \
        [getattr(slow, f) for f in can.Message.__slots__ if f != "__weakref__"]
    assert frames.message is frames._fast  # this python-can's Message has the fields it fills
