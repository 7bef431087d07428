"""A bus as python-can users configure it: what the robot file gives, completed from python-can's own
configuration sources, then akarm's defaults.

python-can reads a bus's settings from ``can.rc``, the environment (``CAN_INTERFACE``,
``CAN_CHANNEL``, ``CAN_BITRATE``, ``CAN_CONFIG``; each also with a ``_<context>`` suffix) and
configuration files (``~/can.conf``, ``/etc/can.conf``, ``~/.can``, ``~/.canrc``; ``can.ini`` on
Windows; section ``[<context>]`` before ``[default]``). akarm reads the same sources with the bus's
name as the context, so PCAN, Kvaser, gs_usb, slcan or candle users need no code, and the robot
file's own values take precedence over them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from akarm.config import BusConfig
from akarm.errors import did_you_mean

__all__ = ["BITRATES", "RESERVED_BUS_KEYS", "bitrate_problem", "interface_problem", "python_can_settings",
           "resolve_bus"]

#: bit/s, the lowest and highest bit rate a bus may be given (classic CAN; AK drivers use 1000000)
BITRATES = (10_000, 1_000_000)


def interface_problem(interface: object) -> tuple[str, str] | None:
    """``(what is wrong, the fix)`` when ``interface`` is not a python-can interface (one ``can.Bus``
    could open), else ``None``: the check a bus's interface gets wherever it comes from (the robot
    file, python-can's configuration, ``-i`` on the command line)."""
    import can

    if isinstance(interface, str) and interface in can.VALID_INTERFACES:
        return None
    return (f"{interface!r} is not a python-can interface{did_you_mean(str(interface), sorted(can.VALID_INTERFACES))}",
            "python-can interfaces: " + ", ".join(sorted(can.VALID_INTERFACES)))


def bitrate_problem(bitrate: object) -> tuple[str, str] | None:
    """``(what is wrong, the fix)`` when ``bitrate`` is not a whole number of bit/s within
    :data:`BITRATES`, else ``None`` (as :func:`interface_problem`, for the bit rate)."""
    low, high = BITRATES
    if isinstance(bitrate, int) and not isinstance(bitrate, bool) and low <= bitrate <= high:
        return None
    return f"bitrate must be a whole number within {low}..{high}, got {bitrate!r}", "AK drivers use 1000000 bit/s"


def python_can_settings(context: str | None = None) -> dict[str, Any]:
    """What python-can's own configuration says about a bus, as ``can.Bus()`` would read it: ``can.rc``,
    then the environment (``CAN_INTERFACE_<context>`` ..., then ``CAN_INTERFACE``, ``CAN_CHANNEL``,
    ``CAN_BITRATE``, ``CAN_CONFIG``), then the configuration files (``~/can.conf``, ``/etc/can.conf``,
    ``~/.can``, ``~/.canrc``; ``can.ini`` on Windows), section ``[context]`` before ``[default]``.
    Values are cast as python-can casts them.

    Raises:
        ValueError: ``CAN_CONFIG`` is not JSON, or a configuration file does not parse.
    """
    import configparser

    import can
    from can.util import cast_from_string, load_environment_config, load_file_config

    sources: list[Any] = [lambda: dict(can.rc)]
    if context:
        sources.append(lambda: load_environment_config(context))
    sources.append(load_environment_config)
    if context:
        sources.append(lambda: load_file_config(None, context))
    sources.append(load_file_config)
    out: dict[str, Any] = {}
    for source in sources:
        try:
            found = dict(source())
        except (ValueError, configparser.Error) as e:
            raise ValueError(f"python-can's configuration cannot be read: {e}") from None
        if "bustype" in found:  # python-can's legacy name
            found.setdefault("interface", found["bustype"])
            del found["bustype"]
        for key, value in found.items():
            out.setdefault(key, cast_from_string(value) if isinstance(value, str) else value)
    return out


#: bus keys akarm sets itself, never passed through
RESERVED_BUS_KEYS = ("receive_own_messages", "bustype", "context")


def resolve_bus(name: str, given: Mapping[str, Any], settings: Mapping[str, Any] | None = None
                ) -> tuple[BusConfig | None, list[tuple[str, str, str]]]:
    """A bus from what the robot file (or command line) gives, completed from python-can's configuration
    (``settings``; default :func:`python_can_settings` for context ``name``), then akarm's defaults
    (socketcan, can0, 1 Mbit/s). The file's values take precedence.

    Returns:
        the bus (``None`` when it has problems) and its problems as ``(key, message, fix)``; ``key`` is
        where the problem is (``"interface"``, ``"bitrate"``, an option) or ``""``.
    """

    found: list[tuple[str, str, str]] = []
    if settings is None:
        try:
            settings = python_can_settings(name)
        except ValueError as e:
            return None, [("", str(e), "fix CAN_CONFIG or the can.conf/.canrc file, or give the bus fully in the YAML")]
    taken: list[str] = []

    def pick(key: str, default: Any) -> Any:
        if given.get(key) is not None:
            return given[key]
        if settings.get(key) is not None:
            taken.append(key)
            return settings[key]
        return default

    interface = str(pick("interface", "socketcan"))
    channel = pick("channel", "can0")
    bitrate = pick("bitrate", 1_000_000)
    where = " (from python-can's configuration: CAN_* variables or a can.conf/.canrc file)"
    if (problem := interface_problem(interface)) is not None:
        found.append(("interface", f"bus {name!r}: {problem[0]}{where if 'interface' in taken else ''}", problem[1]))
    if (problem := bitrate_problem(bitrate)) is not None:
        found.append(("bitrate", f"bus {name!r}: {problem[0]}{where if 'bitrate' in taken else ''}", problem[1]))
    options = {k: v for k, v in given.items() if k not in ("interface", "channel", "bitrate")}
    if settings.get("interface") in (None, interface):  # python-can's extras are for its own interface
        for k, v in settings.items():
            if k not in ("interface", "channel", "bitrate", *RESERVED_BUS_KEYS) and k not in options:
                options[k] = v
                taken.append(k)
    if found:
        return None, found
    return BusConfig(name, interface, str(channel), int(bitrate), options, tuple(taken)), []
