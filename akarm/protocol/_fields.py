"""Scaled integer fields, shared by the servo CAN and UART codecs: a value is range-checked in its
own unit, then sent as ``round(value * scale)``."""

from __future__ import annotations

from typing import NamedTuple

from akarm.errors import ProtocolError


class Field(NamedTuple):
    """One command argument: its name and unit for messages, the wire scale and the allowed range."""

    name: str
    unit: str
    scale: float  # wire integer = round(value * scale)
    lo: float
    hi: float


def fmt(x: float) -> str:
    """A range bound for a message: ``60``, ``0.5``, ``360000000``."""
    return f"{x:g}" if abs(x) < 1e6 else f"{x:.0f}"


def as_number(name: str, value: object) -> float:
    """``value`` as a float (NaN and infinities included), or :class:`ProtocolError` naming ``name``."""
    try:
        if isinstance(value, str | bytes | bytearray):  # float("5") would accept text
            raise TypeError
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ProtocolError(f"{name} must be a number, got {value!r}") from None


def checked(field: Field, value: float) -> float:
    """``value`` as a float when it is a finite number in the field's range, else :class:`ProtocolError`."""
    x = as_number(field.name, value)
    if not field.lo <= x <= field.hi:  # also catches NaN
        unit = f" {field.unit}" if field.unit else ""
        raise ProtocolError(
            f"{field.name} {value!r}{unit} is outside the range {fmt(field.lo)} .. {fmt(field.hi)}{unit}",
            fix=f"send a {field.name} within {fmt(field.lo)} .. {fmt(field.hi)}{unit}")
    return x
