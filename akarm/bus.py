"""python-can buses: opening them with errors a user can act on, and draining them without blocking."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, MutableMapping
from typing import TYPE_CHECKING

from .errors import BusError

if TYPE_CHECKING:
    import can

    from .config import BusConfig

__all__ = ["close_buses", "drain", "how_to_create", "open_bus"]


def how_to_create(interface: str, channel: str, bitrate: int = 1_000_000) -> str:
    """The shell commands that bring up ``channel`` for ``interface`` (best effort)."""
    if interface == "socketcan":
        if channel.startswith("vcan"):
            return (f"create it: sudo modprobe vcan && sudo ip link add dev {channel} type vcan && "
                    f"sudo ip link set up {channel}")
        return (f"bring it up: sudo ip link set {channel} up type can bitrate {bitrate} "
                f"(check the adapter is plugged in: ip -br link)")
    if interface == "virtual":
        return "virtual buses need no setup; check the channel name"
    if interface == "akarm_local":
        return ("akarm_local needs no setup: check that the channel's file (see akarm.localbus.channel_path) "
                "can be created, and that fewer than 32 buses use the channel")
    return f"check that the {interface} adapter is connected and its driver installed (see python-can's docs)"


def open_bus(bus: BusConfig, *, receive_own_messages: bool = False) -> can.BusABC:
    """Open the python-can bus ``bus`` describes.

    Raises:
        BusError: the bus cannot be opened; the message says which bus and how to create it.
    """
    import can

    kwargs: dict[str, object] = {"interface": bus.interface, "channel": bus.channel,
                                 "receive_own_messages": receive_own_messages}
    if bus.interface not in ("virtual", "socketcan", "akarm_local"):
        kwargs["bitrate"] = bus.bitrate  # socketcan takes the bit rate from `ip link`, not from us
    try:
        return can.Bus(**kwargs)  # type: ignore[arg-type]
    except (OSError, can.CanError, ValueError, ImportError, NotImplementedError) as e:
        raise BusError(
            f"cannot open CAN bus {bus.name!r} ({bus.interface} channel {bus.channel!r}): {e}",
            fix=how_to_create(bus.interface, bus.channel, bus.bitrate),
        ) from None


def close_buses(buses: MutableMapping[str, can.BusABC]) -> None:
    """Shut down every bus in ``buses`` and empty it; a bus that fails to close is passed over, so
    closing (often on the way out of an error) never raises and never masks the original error."""
    for bus in buses.values():
        with contextlib.suppress(Exception):
            bus.shutdown()
    buses.clear()


def drain(bus: can.BusABC, limit: int = 1024) -> Iterator[can.Message]:
    """Every frame already received on ``bus``, without waiting (at most ``limit``)."""
    for _ in range(limit):
        msg = bus.recv(timeout=0.0)
        if msg is None:
            return
        yield msg
