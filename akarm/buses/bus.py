"""python-can buses: opening them with errors a user can act on, and draining them without blocking."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, MutableMapping
from typing import TYPE_CHECKING

from akarm.errors import BusError

if TYPE_CHECKING:
    import can

    from akarm.config import BusConfig

__all__ = ["RECEIVE_BUFFER", "close_buses", "drain", "grow_receive_buffer", "how_to_create", "no_answer_hint",
           "open_bus", "open_error", "polled", "simulated"]


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
    if interface == "akarm_uart":
        return (f"check that {channel} exists (ls /dev/ttyUSB* /dev/ttyACM*), that you may open it (the dialout "
                "group) and that no other program has it open")
    if interface == "akarm_local":
        return ("akarm_local needs no setup: check that the channel's file (see akarm.buses.localbus.channel_path) "
                "can be created, and that fewer than 32 buses use the channel")
    return f"check that the {interface} adapter is connected and its driver installed (see python-can's docs)"


#: the python-can packages some interfaces need (their import fails without them)
_EXTRA_PACKAGES = {"gs_usb": "gs_usb", "slcan": "pyserial", "serial": "pyserial", "robotell": "pyserial",
                   "seeedstudio": "pyserial", "canalystii": "canalystii", "cantact": "cantact",
                   "neovi": "python-ics"}


def open_error(bus: BusConfig, error: BaseException) -> BusError:
    """The :class:`BusError` for a bus that python-can could not open, specific to the cause."""
    import errno as errno_

    import can

    what = f"cannot open CAN bus {bus.name!r} ({bus.interface} channel {bus.channel!r})"
    code = getattr(error, "errno", None)
    text = str(error)
    if code == errno_.EAFNOSUPPORT:
        return BusError(f"{what}: this kernel has no CAN support (no AF_CAN sockets: {text})",
                        fix="load the kernel modules (sudo modprobe can can_raw; vcan for a virtual bus), or use a "
                            "USB adapter's own python-can interface instead of socketcan (-i gs_usb, pcan, slcan, "
                            "candle, ...); for the simulator alone, -i akarm_local needs no kernel support")
    if code in (errno_.ENODEV, errno_.ENXIO) or "No such device" in text:
        return BusError(f"{what}: there is no such network interface", fix=how_to_create(bus.interface, bus.channel,
                                                                                            bus.bitrate))
    if code == errno_.ENETDOWN:
        return BusError(f"{what}: the interface is down",
                        fix=f"bring it up: sudo ip link set {bus.channel} up type can bitrate {bus.bitrate}")
    if code in (errno_.EPERM, errno_.EACCES):
        return BusError(f"{what}: not allowed ({text})",
                        fix="check the device's permissions (udev rules for USB adapters, the dialout group for "
                            "serial ones)")
    if isinstance(error, can.CanInterfaceNotImplementedError) and "Unknown interface type" in text:
        from akarm.errors import did_you_mean

        return BusError(f"{what}: {bus.interface!r} is not a python-can interface"
                        f"{did_you_mean(bus.interface, sorted(can.VALID_INTERFACES))}",
                        fix="python-can interfaces: " + ", ".join(sorted(can.VALID_INTERFACES)))
    if isinstance(error, (ImportError, can.CanInterfaceNotImplementedError)) or "library not found" in text:
        package = _EXTRA_PACKAGES.get(bus.interface)
        return BusError(f"{what}: python-can's {bus.interface} interface cannot load what it needs ({text})",
                        fix=f"install its Python package: pip install {package}" if package else
                        f"install the adapter's driver library (python-can's documentation for {bus.interface})")
    if isinstance(error, TypeError):
        return BusError(f"{what}: the {bus.interface} interface does not take these arguments ({text})",
                        fix="check the keyword arguments under `buses:` in the robot file, --bus-kwargs, or "
                            "python-can's configuration (CAN_CONFIG, can.conf)")
    return BusError(f"{what}: {text}", fix=how_to_create(bus.interface, bus.channel, bus.bitrate))


#: bytes asked for a SocketCAN socket's receive queue (the kernel doubles it, and counts each frame
#: at about 1 kB, its buffer's whole size): about 2000 frames, a third of a second of six joints
#: answering at 1 kHz, or seconds at a slow machine's 25 Hz. The default (rmem_default, 208 kB:
#: about 200 frames, 33 ms at 6 kHz) loses replies to a process that paused for longer (a garbage
#: collection, a busy machine), and the watchdog then stops the arm for a motor that did answer.
RECEIVE_BUFFER = 1 << 20
_SO_RCVBUFFORCE = 33  # Linux: SO_RCVBUF past net.core.rmem_max, for a process with CAP_NET_ADMIN


def grow_receive_buffer(bus: object, size: int = RECEIVE_BUFFER) -> int:
    """Ask for a receive queue of ``size`` bytes on a SocketCAN bus's socket (past ``rmem_max`` where
    this process may, else up to it); the size the kernel granted, 0 for a bus without a socket."""
    import socket

    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return 0
    for option in (_SO_RCVBUFFORCE, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, size)
            break
        except OSError:  # not permitted (no CAP_NET_ADMIN), or not Linux
            continue
    return int(sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))


def open_bus(bus: BusConfig, *, receive_own_messages: bool = False) -> can.BusABC:
    """Open the python-can bus ``bus`` describes, with its keyword arguments (``bus.options``).
    A SocketCAN bus gets a receive queue of :data:`RECEIVE_BUFFER` bytes (:func:`grow_receive_buffer`).

    Raises:
        BusError: the bus cannot be opened; the message says which bus, why, and what to do.
    """
    import can

    kwargs: dict[str, object] = {**bus.options, "interface": bus.interface, "channel": bus.channel,
                                 "receive_own_messages": receive_own_messages}
    if bus.interface not in ("virtual", "socketcan", "akarm_local", "akarm_uart"):
        kwargs["bitrate"] = bus.bitrate  # socketcan takes the bit rate from `ip link`, not from us
    try:
        opened = can.Bus(**kwargs)  # type: ignore[arg-type]
        grow_receive_buffer(opened)
        return opened
    except BusError:
        raise  # already says which port and what to check (akarm_uart)
    except (OSError, can.CanError, ValueError, ImportError, NotImplementedError, TypeError) as e:
        raise open_error(bus, e) from None


def polled(bus: BusConfig) -> bool:
    """Whether ``bus``'s status frames answer our own polls (``akarm_uart``: one motor on a serial port,
    asked once a cycle), so their rate and their count are ours to set, not the motor's to show."""
    return bus.interface == "akarm_uart"


def simulated(bus: BusConfig) -> bool:
    """Whether only a simulator answers on ``bus``: python-can's ``virtual``, ``akarm_local``, a
    SocketCAN ``vcan`` channel."""
    return bus.interface in ("virtual", "akarm_local") or (bus.interface == "socketcan"
                                                          and str(bus.channel).startswith("vcan"))


def no_answer_hint(bus: BusConfig) -> str:
    """What to check when nothing answered on ``bus`` (for the error a caller raises, e.g. at enable).

    On ``akarm_local`` it says whether any other process is on the channel at all; on ``virtual``,
    that such a bus only reaches buses of the same process. On hardware, the usual suspects.
    """
    if bus.interface == "akarm_uart":
        from akarm.buses.uart import diagnose

        return diagnose(bus.channel) or (
            f"check that the motor on serial port {bus.channel} is powered and in servo mode, and the wiring; "
            "a simulator answers on a serial line with akarm sim ROBOT.yaml --serial JOINT=pty")
    sim = f"akarm sim ROBOT.yaml -i {bus.interface} -c {bus.channel}"
    if bus.interface == "akarm_local":
        from akarm.buses.localbus import peers

        others = peers(bus.channel)
        if not others:
            return (f"no simulator or motor is on akarm_local channel {bus.channel!r}: nothing else has that "
                    f"channel open. Start the simulator first ({sim}), with the same channel name")
        return (f"processes {', '.join(map(str, others))} are on akarm_local channel {bus.channel!r}, but none "
                "answered as these joints: check that the simulator runs this robot file (same CAN IDs and modes)")
    if bus.interface == "virtual":
        return (f"no simulator or motor is on virtual channel {bus.channel!r}: a python-can virtual bus only "
                "reaches buses of this same process. Start a SimulatedRobot in this process on that channel, or "
                f"use akarm_local to reach a simulator in another process ({sim.replace('virtual', 'akarm_local')})")
    return ("check that the motors are powered and in the configured mode (MIT or servo; power-cycle after "
            "switching), their CAN IDs and the bit rate match the robot file, and the bus is wired and terminated "
            f"(120 Ω at both ends); `akarm scan -i {bus.interface} -c {bus.channel}` lists what answers")


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
