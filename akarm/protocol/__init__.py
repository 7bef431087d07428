"""Wire codecs for CubeMars AK drivers: bytes in, bytes out; no I/O, no threads, no time.

- :mod:`akarm.protocol.mit`: MIT ("force control") mode over CAN, SI units at the output shaft,
  V1/V2 standard frames and V3 extended frames; controller and motor (simulator) side.
- :mod:`akarm.protocol.servo`: servo mode over CAN (extended IDs ``packet << 8 | id``), in the
  firmware's units (degrees, ERPM, A); commands and the ``0x29xx`` status frames.
- :mod:`akarm.protocol.uart`: servo mode over the serial port: framing with CRC-16/XMODEM, a
  resynchronising stream decoder, every command of the manual and its replies. Imported only where
  it is used (``from akarm.protocol import uart``).
- :mod:`akarm.protocol.motors`: the catalogue of AK models (ranges, gear ratios, constants), and
  :mod:`akarm.protocol.units`: joint-side SI ⇄ motor units. The codecs' scales come from them.

The manual (V1.0.9) has errata; these codecs follow ``shared/docs/ak-protocol.md`` where they differ
(each module's docstring says where). Every malformed input raises :class:`akarm.ProtocolError` or
its subclass :class:`akarm.FrameError`, never a bare IndexError or struct.error.
"""

from __future__ import annotations

from akarm.protocol import mit, servo
from akarm.protocol.mit import MitCodec, MitCommand, MitReply
from akarm.protocol.servo import ServoCommand, ServoErrorCode, ServoPacket, ServoStatus, describe_error

__all__ = [
    "MitCodec",
    "MitCommand",
    "MitReply",
    "ServoCommand",
    "ServoErrorCode",
    "ServoPacket",
    "ServoStatus",
    "describe_error",
    "mit",
    "servo",
]
