"""UART packet numbers, fault codes, GET_VALUES_SETUP fields and their wire formats (AK manual §5.2.2)."""

from __future__ import annotations

import operator
import struct
from enum import IntEnum, IntFlag

from akarm.errors import ProtocolError

DEFAULT_MAX_PAYLOAD = 512
SHORT_MAX = 255
LONG_MAX = 0xFFFF

I32_MIN, I32_MAX = -(1 << 31), (1 << 31) - 1


class UartPacket(IntEnum):
    """Command bytes (the first payload byte) of the serial protocol."""

    FW_VERSION = 0
    GET_VALUES = 4
    SET_DUTY = 5
    SET_CURRENT = 6
    SET_CURRENT_BRAKE = 7
    SET_RPM = 8
    SET_POS = 9
    SET_HANDBRAKE = 10
    SET_DETECT = 11
    ROTOR_POSITION = 22
    GET_VALUES_SETUP = 50
    SET_POS_SPD = 91
    SET_POS_MULTI = 92
    """Multi-turn position mode, ±100 turns (the manual's enum comments swap 92 and 93)."""
    SET_POS_SINGLE = 93
    """Single-turn position mode, 0-360°."""
    SET_POS_UNLIMITED = 94
    SET_POS_ORIGIN = 95


class FaultCode(IntEnum):
    """VESC ``mc_fault_code``: the status byte of a GET_VALUES reply."""

    NONE = 0
    OVER_VOLTAGE = 1
    UNDER_VOLTAGE = 2
    DRV = 3
    ABS_OVER_CURRENT = 4
    OVER_TEMP_FET = 5
    OVER_TEMP_MOTOR = 6
    GATE_DRIVER_OVER_VOLTAGE = 7
    GATE_DRIVER_UNDER_VOLTAGE = 8
    MCU_UNDER_VOLTAGE = 9
    BOOTING_FROM_WATCHDOG_RESET = 10
    ENCODER_SPI = 11
    ENCODER_SINCOS_BELOW_MIN_AMPLITUDE = 12
    ENCODER_SINCOS_ABOVE_MAX_AMPLITUDE = 13
    FLASH_CORRUPTION = 14
    HIGH_OFFSET_CURRENT_SENSOR_1 = 15
    HIGH_OFFSET_CURRENT_SENSOR_2 = 16
    HIGH_OFFSET_CURRENT_SENSOR_3 = 17
    UNBALANCED_CURRENTS = 18


#: A serial fault without a status-frame error code of its own is passed on as this plus its code.
SERIAL_FAULT_BASE = 0x80

# serial fault → the servo status frame's error code (akarm.protocol.servo.ServoErrorCode) that means the same
_STATUS_CODES = {
    FaultCode.NONE: 0,
    FaultCode.OVER_TEMP_MOTOR: 1,
    FaultCode.ABS_OVER_CURRENT: 2,
    FaultCode.OVER_VOLTAGE: 3,
    FaultCode.GATE_DRIVER_OVER_VOLTAGE: 3,
    FaultCode.UNDER_VOLTAGE: 4,
    FaultCode.GATE_DRIVER_UNDER_VOLTAGE: 4,
    FaultCode.MCU_UNDER_VOLTAGE: 4,
    FaultCode.ENCODER_SPI: 5,
    FaultCode.ENCODER_SINCOS_BELOW_MIN_AMPLITUDE: 5,
    FaultCode.ENCODER_SINCOS_ABOVE_MAX_AMPLITUDE: 5,
    FaultCode.OVER_TEMP_FET: 6,
}
# status error code → the serial fault a motor reports for it (the simulator's side)
_FAULT_CODES = {0: FaultCode.NONE, 1: FaultCode.OVER_TEMP_MOTOR, 2: FaultCode.ABS_OVER_CURRENT,
                3: FaultCode.OVER_VOLTAGE, 4: FaultCode.UNDER_VOLTAGE, 5: FaultCode.ENCODER_SPI,
                6: FaultCode.OVER_TEMP_FET}
_FAULT_TEXT = {
    FaultCode.DRV: ("gate driver (DRV) fault", "check the phase wiring for a short; power-cycle the driver"),
    FaultCode.BOOTING_FROM_WATCHDOG_RESET: ("the driver rebooted after a watchdog reset",
                                            "check the supply for brown-outs; report it if it recurs"),
    FaultCode.FLASH_CORRUPTION: ("flash corruption", "re-flash the firmware with CubeMars' tool"),
    FaultCode.HIGH_OFFSET_CURRENT_SENSOR_1: ("current sensor 1 offset too high", "power-cycle the driver; "
                                             "if it persists, the driver needs repair"),
    FaultCode.HIGH_OFFSET_CURRENT_SENSOR_2: ("current sensor 2 offset too high", "power-cycle the driver; "
                                             "if it persists, the driver needs repair"),
    FaultCode.HIGH_OFFSET_CURRENT_SENSOR_3: ("current sensor 3 offset too high", "power-cycle the driver; "
                                             "if it persists, the driver needs repair"),
    FaultCode.UNBALANCED_CURRENTS: ("unbalanced phase currents", "check the phase wiring and connectors"),
}


def status_code(fault: int) -> int:
    """The servo status frame's error code for serial fault ``fault`` (a :class:`FaultCode` value):
    the CAN code that means the same, or :data:`SERIAL_FAULT_BASE` + ``fault`` when CAN has none
    (:func:`describe_serial_fault` describes those)."""
    try:
        return _STATUS_CODES[FaultCode(fault)]
    except (ValueError, KeyError):
        return SERIAL_FAULT_BASE | (int(fault) & 0x7F)


def fault_code(status: int) -> int:
    """Motor side: the serial fault a driver reports for the status frame's error code ``status``
    (motor stall and unknown codes, which the serial list lacks, as :attr:`FaultCode.DRV`)."""
    if status >= SERIAL_FAULT_BASE:
        return status - SERIAL_FAULT_BASE
    return int(_FAULT_CODES.get(status, FaultCode.DRV))


def describe_serial_fault(code: int) -> tuple[str, str] | None:
    """``(description, remedy)`` of a status error code :func:`status_code` made from a serial fault
    CAN has no code for (``0x80 + fault``), or ``None`` for any other code."""
    try:
        fault = FaultCode(code - SERIAL_FAULT_BASE)
    except ValueError:
        return None
    text = _FAULT_TEXT.get(fault)
    if text is None:
        return None
    return f"{text[0]} (serial-port fault {fault.name}, passed on as code {code})", text[1]


class ValueField(IntFlag):
    """The GET_VALUES_SETUP field mask. The manual numbers bits from 1 (bit 1 = least significant).

    A reply carries exactly the requested fields, in bit order. Bits 10-15 and 19-32 are reserved
    (their sizes are not documented), so they cannot be requested.
    """

    MOSFET_TEMPERATURE = 1 << 0
    """bit 1: int16 / 10 → °C"""
    MOTOR_TEMPERATURE = 1 << 1
    """bit 2: int16 / 10 → °C"""
    OUTPUT_CURRENT = 1 << 2
    """bit 3: int32 / 100 → A"""
    INPUT_CURRENT = 1 << 3
    """bit 4: int32 / 100 → A"""
    ID_CURRENT = 1 << 4
    """bit 5: int32 / 100 → A"""
    IQ_CURRENT = 1 << 5
    """bit 6: int32 / 100 → A"""
    DUTY = 1 << 6
    """bit 7: int16 / 1000 → fraction"""
    SPEED = 1 << 7
    """bit 8: int32 → ERPM"""
    INPUT_VOLTAGE = 1 << 8
    """bit 9: int16 / 10 → V"""
    ERROR = 1 << 15
    """bit 16: uint8 fault code (:class:`FaultCode`)"""
    POSITION = 1 << 16
    """bit 17: int32 / 1 000 000 → degrees"""
    MOTOR_ID = 1 << 17
    """bit 18: uint8"""


# field -> (struct format, divisor); divisor None = an integer field returned as int
SETUP_FIELDS: tuple[tuple[ValueField, struct.Struct, float | None], ...] = (
    (ValueField.MOSFET_TEMPERATURE, struct.Struct(">h"), 10.0),
    (ValueField.MOTOR_TEMPERATURE, struct.Struct(">h"), 10.0),
    (ValueField.OUTPUT_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.INPUT_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.ID_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.IQ_CURRENT, struct.Struct(">i"), 100.0),
    (ValueField.DUTY, struct.Struct(">h"), 1000.0),
    (ValueField.SPEED, struct.Struct(">i"), 1.0),
    (ValueField.INPUT_VOLTAGE, struct.Struct(">h"), 10.0),
    (ValueField.ERROR, struct.Struct(">B"), None),
    (ValueField.POSITION, struct.Struct(">i"), 1_000_000.0),
    (ValueField.MOTOR_ID, struct.Struct(">B"), None),
)
SETUP_KNOWN = 0
for _field, *_ in SETUP_FIELDS:
    SETUP_KNOWN |= int(_field)



def integer_argument(name: str, value: int) -> int:
    try:
        return operator.index(value)
    except TypeError:
        raise ProtocolError(f"{name} must be an integer, got {value!r}") from None



def setup_mask(fields: ValueField | int) -> int:
    mask = integer_argument("field mask", fields)
    if mask <= 0 or mask & ~SETUP_KNOWN:
        raise ProtocolError(f"field mask 0x{mask:X} asks for no field or for reserved bits "
                            f"(0x{mask & ~SETUP_KNOWN:X})",
                            fix="combine ValueField members only")
    return mask

