"""Building :class:`can.Message` objects on the control loop's hot path.

``can.Message(...)`` checks and normalises its arguments (about 1-1.4 µs); the loop builds and reads
a dozen frames per cycle whose fields it already knows to be valid. :func:`message` fills the slots
of a new Message directly (about 0.4 µs), and falls back to the constructor if python-can's Message
ever gains or loses a field, so a python-can upgrade can make it slower but never wrong.
"""

from __future__ import annotations

import can

__all__ = ["Frame", "message"]

#: A classic data frame by its fields, ``(arbitration_id, is_extended_id, data)``: what the control loop
#: sends every cycle (an akarm_local bus takes it as it is: :meth:`akarm.buses.localbus.LocalBus.send_frames`).
Frame = tuple[int, bool, bytes]

_FIELDS = frozenset({"__weakref__", "arbitration_id", "bitrate_switch", "channel", "data", "dlc",
                     "error_state_indicator", "is_error_frame", "is_extended_id", "is_fd", "is_remote_frame",
                     "is_rx", "timestamp"})
_Message = can.Message
_new = _Message.__new__


def _slow(arbitration_id: int, data: bytes | bytearray, is_extended_id: bool, timestamp: float = 0.0,
          is_remote_frame: bool = False, is_error_frame: bool = False, dlc: int | None = None,
          channel: str | int | None = None, is_rx: bool = True) -> can.Message:
    return _Message(timestamp=timestamp, arbitration_id=arbitration_id, is_extended_id=is_extended_id,
                    is_remote_frame=is_remote_frame, is_error_frame=is_error_frame, dlc=dlc, data=data,
                    channel=channel, is_rx=is_rx, check=False)


def _fast(arbitration_id: int, data: bytes | bytearray, is_extended_id: bool, timestamp: float = 0.0,
          is_remote_frame: bool = False, is_error_frame: bool = False, dlc: int | None = None,
          channel: str | int | None = None, is_rx: bool = True) -> can.Message:
    m = _new(_Message)
    m.timestamp = timestamp
    m.arbitration_id = arbitration_id
    m.is_extended_id = is_extended_id
    m.is_remote_frame = is_remote_frame
    m.is_error_frame = is_error_frame
    m.channel = channel
    m.data = data if type(data) is bytearray else bytearray(data)
    m.dlc = len(data) if dlc is None else dlc
    m.is_fd = False
    m.is_rx = is_rx
    m.bitrate_switch = False
    m.error_state_indicator = False
    return m


#: A classic CAN frame as a :class:`can.Message`, built without python-can's argument checks (the
#: caller guarantees a valid ID and at most 8 bytes of data): ``message(arbitration_id, data,
#: is_extended_id, timestamp=0.0, is_remote_frame=False, is_error_frame=False, dlc=None,
#: channel=None, is_rx=True)``.
message = _fast if frozenset(getattr(_Message, "__slots__", ())) == _FIELDS else _slow
