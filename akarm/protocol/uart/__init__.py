"""Servo mode over UART (the R-link serial port, 921 600 baud): VESC-style framed packets (AK manual §5.2.2).

Framing::

    02 LEN PAYLOAD CRC_HI CRC_LO 03                payload of 1-255 bytes ("short" frame)
    03 LEN_HI LEN_LO PAYLOAD CRC_HI CRC_LO 03      payload of 256 bytes and more ("long" frame)

The CRC is CRC-16/XMODEM (poly 0x1021, init 0) over the payload only, sent big-endian. The first
payload byte is the command (:class:`UartPacket`).

The short frame's LEN is one byte, so a 256-byte payload cannot be a short frame, whatever the
manual's ``len <= 256`` test says (it would send LEN 0): :func:`encode_frame` uses the short form up
to 255 bytes and the long form from 256 on. The decoders accept a long frame of any length from 1 (as
VESC does) and refuse a short frame with LEN 0 (an empty payload has no command byte).

Controller side: one encoder per command (each returns the whole frame, ready to write), decoders
for the replies (:func:`decode_get_values`, :func:`decode_get_values_setup`,
:func:`decode_rotor_position`, :func:`decode_fw_version`, or :func:`decode_payload` to dispatch on
the command byte) and :class:`FrameDecoder`, which finds payloads in a byte stream and resynchronises
after garbage. Motor side: :func:`decode_command` and the reply encoders.

Scales are those of the protocol notes' UART table (``shared/docs/ak-protocol.md`` §3); note that
SET_POS here is degrees × 1 000 000 (CAN uses × 10 000), so it only reaches ±2147.48°, and
SET_POS_SPD's position is degrees × 1000. Values outside the documented (or, where nothing is
documented, the field's) range raise :class:`~akarm.ProtocolError`, and are rounded to the nearest
wire step.
"""

from __future__ import annotations

from akarm.protocol.uart.commands import (
    UartCommand,
    decode_command,
    encode_current,
    encode_current_brake,
    encode_detect,
    encode_duty,
    encode_fw_version,
    encode_get_values,
    encode_get_values_setup,
    encode_handbrake,
    encode_multi_turn,
    encode_origin,
    encode_position,
    encode_position_speed,
    encode_rpm,
    encode_single_turn,
    encode_unlimited,
)
from akarm.protocol.uart.framing import (
    FrameDecoder,
    crc16,
    decode_frame,
    encode_frame,
)
from akarm.protocol.uart.packets import (
    DEFAULT_MAX_PAYLOAD,
    FaultCode,
    UartPacket,
    ValueField,
)
from akarm.protocol.uart.replies import (
    FirmwareVersion,
    GetValues,
    RotorPosition,
    decode_fw_version,
    decode_get_values,
    decode_get_values_setup,
    decode_payload,
    decode_rotor_position,
    encode_get_values_reply,
    encode_get_values_setup_reply,
    encode_rotor_position,
)

__all__ = [
    "DEFAULT_MAX_PAYLOAD",
    "FaultCode",
    "FirmwareVersion",
    "FrameDecoder",
    "GetValues",
    "RotorPosition",
    "UartCommand",
    "UartPacket",
    "ValueField",
    "crc16",
    "decode_command",
    "decode_frame",
    "decode_fw_version",
    "decode_get_values",
    "decode_get_values_setup",
    "decode_payload",
    "decode_rotor_position",
    "encode_current",
    "encode_current_brake",
    "encode_detect",
    "encode_duty",
    "encode_frame",
    "encode_fw_version",
    "encode_get_values",
    "encode_get_values_reply",
    "encode_get_values_setup",
    "encode_get_values_setup_reply",
    "encode_handbrake",
    "encode_multi_turn",
    "encode_origin",
    "encode_position",
    "encode_position_speed",
    "encode_rotor_position",
    "encode_rpm",
    "encode_single_turn",
    "encode_unlimited",
]
