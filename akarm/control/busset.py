"""The arm's CAN buses as one set: opened and closed together, drained and routed every cycle,
written one frame at a time, and a bus that fails under the arm counted as lost.

A bus is lost when reading it raises (shut down, unplugged, the interface down) or when it refuses
:data:`SEND_FAILURES` frames in a row (a full transmit queue that never drains). A lost bus is no
longer read; frames for its joints are still tried (damping and exit frames may yet get through).
The set says so once per bus, through ``on_lost(stop)``: what that means for the arm is the
controller's business.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Mapping, Sequence
from os import PathLike
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from akarm.buses.bus import close_buses, open_bus
from akarm.buses.frames import Frame, message
from akarm.buses.localbus import LocalBus
from akarm.config import RobotConfig
from akarm.control.joints import Joint, Router
from akarm.errors import BusError, BusLost, RecordingError

if TYPE_CHECKING:
    import can

__all__ = ["DRAIN_LIMIT", "SEND_FAILURES", "BusSet"]

DRAIN_LIMIT = 1024  #: frames read per bus per cycle at most (a flooded bus must not stall the loop)
SEND_FAILURES = 20  #: frames in a row a bus refuses before it counts as lost


class BusSet:
    """The buses the joints are on (see the module's docstring).

    Args:
        config: the robot (its buses).
        joints: the joints, config order (each names its bus).
        can_log: optional path of a raw CAN log, every frame received and sent.
        on_lost: called once per lost bus with the :class:`~akarm.BusLost` that says so (``at`` set),
            from the thread that found it (the loop's, or a caller's sending frames).
        clock: the time a failed send is found at.
    """

    def __init__(self, config: RobotConfig, joints: Sequence[Joint], can_log: str | PathLike[str] | None,
                 on_lost: Callable[[BusLost], None], clock: Callable[[], float]) -> None:
        self.config = config
        self.joints = list(joints)
        self._can_log = can_log
        self._on_lost = on_lost
        self._clock = clock
        self._buses: dict[str, can.BusABC] = {}
        # (name, read, route, drains) of the buses not lost: drains: read(limit) gives a cycle's frames
        # (LocalBus.drain, routed by Router.route_frames), else read(0) gives one message (routed by Router.route)
        self._live: list[tuple[str, Any, Any, bool]] = []
        self._bus_of: list[Any] = [None] * len(self.joints)  # each joint's bus (a lost one is still tried)
        # (name, bus, akarm_local: takes a batch of frames by their fields, its joints) of every open bus
        self._send_plan: list[tuple[str, Any, bool, list[Joint]]] = []
        self._failures: dict[str, int] = {}
        self._lost: dict[str, BaseException] = {}
        self._logger: Any = None

    @property
    def buses(self) -> Mapping[str, can.BusABC]:
        """The open buses by name (read-only; empty while closed)."""
        return MappingProxyType(self._buses)

    @property
    def lost(self) -> Mapping[str, BaseException]:
        """The buses lost since they were opened, with what failed (read-only)."""
        return MappingProxyType(self._lost)

    def open(self) -> None:
        """Open every bus a joint is on (all or none).

        Raises:
            BusError: a bus will not open (the others are closed again).
            RecordingError: the CAN log cannot be written (every bus is closed again).
        """
        used = {j.bus for j in self.joints}
        try:
            for name, bus_cfg in self.config.buses.items():
                if name in used:
                    self._buses[name] = open_bus(bus_cfg)
        except BusError:
            close_buses(self._buses)
            raise
        if self._can_log is not None:
            import can

            try:
                self._logger = can.Logger(str(self._can_log))
            except (OSError, ValueError) as e:  # no such directory, no permission, a format python-can lacks
                close_buses(self._buses)
                raise RecordingError(f"cannot write the CAN log {str(self._can_log)!r}: {e}",
                                     fix="give can_log a file in a directory that exists and can be written, "
                                         "ending in .log, .asc, .blf, .csv, .txt, ...") from None
        routers = {name: Router([j for j in self.joints if j.bus == name]) for name in self._buses}
        # an akarm_local bus hands over a cycle's frames in one call, without a message each (unless
        # every frame is to be logged: the log takes messages)
        self._live = [(name, bus.drain, routers[name].route_frames, True)
                      if isinstance(bus, LocalBus) and self._logger is None else
                      (name, bus.recv, routers[name].route, False) for name, bus in self._buses.items()]
        self._bus_of = [self._buses[j.bus] for j in self.joints]
        self._send_plan = [(name, bus, isinstance(bus, LocalBus), [j for j in self.joints if j.bus == name])
                           for name, bus in self._buses.items()]
        self._failures = dict.fromkeys(self._buses, 0)
        self._lost = {}

    def close(self) -> None:
        """Close every bus (and the CAN log); nothing is read or sent afterwards. Never raises."""
        close_buses(self._buses)
        self._live = []
        self._bus_of = [None] * len(self.joints)
        self._send_plan = []
        if self._logger is not None:
            with contextlib.suppress(Exception):
                self._logger.stop()
            self._logger = None

    def receive(self, now: float) -> None:
        """Route everything already received on every live bus to its joint, never waiting."""
        logger = self._logger
        for name, recv, route, drains in self._live:
            try:
                if drains:
                    route(recv(DRAIN_LIMIT), now)
                    continue
                for _ in range(DRAIN_LIMIT):
                    msg = recv(0.0)
                    if msg is None:
                        break
                    route(msg, now)
                    if logger is not None:
                        logger.on_message_received(msg)
            except Exception as e:  # the bus is gone (shut down, unplugged, the interface down)
                self._lose(name, e, now)

    def send(self, j: Joint, msg: can.Message) -> bool:
        """Send ``msg`` on joint ``j``'s bus; a refusal is counted (many in a row: the bus is lost).
        Whether the bus took it (``False``: refused, or the buses are closed)."""
        bus = self._bus_of[j.index]
        if bus is None:
            return False
        try:
            bus.send(msg)
        except Exception as e:  # a full TX queue or an unplugged adapter: counted; many in a row = lost
            self._refused(j, e)
            return False
        self._failures[j.bus] = 0
        j.sent()
        if self._logger is not None:
            msg.timestamp = time.time()
            self._logger.on_message_received(msg)
        return True

    def send_frames(self, frames: Sequence[Frame]) -> None:
        """:meth:`send` for each joint's frame given by its fields, one a joint in config order
        (:meth:`Joint.track_frame`: the loop's commands). An akarm_local bus takes its joints' frames
        in one call; any other bus is sent a message built from each. Refusals are counted per joint
        as :meth:`send` counts them (a batch refused is refused for each of its joints)."""
        failures, logger = self._failures, self._logger
        for name, bus, local, members in self._send_plan:
            if not local:
                for j in members:
                    frame = frames[j.index]
                    self.send(j, message(frame[0], frame[2], frame[1]))
                continue
            try:
                bus.send_frames([frames[j.index] for j in members])
            except Exception as e:  # as send's
                for j in members:
                    self._refused(j, e)
                continue
            failures[name] = 0
            for j in members:
                j.sent()
                if logger is not None:
                    frame = frames[j.index]
                    logger.on_message_received(message(frame[0], frame[2], frame[1], time.time()))

    def _refused(self, j: Joint, error: Exception) -> None:
        """Joint ``j``'s bus refused a frame: counted; :data:`SEND_FAILURES` in a row and it is lost."""
        failures = self._failures[j.bus] = self._failures[j.bus] + 1
        if failures >= SEND_FAILURES:
            self._lose(j.bus, error, self._clock())

    def release_all(self, *, suppress: bool = False) -> bool:
        """Send every joint its exit (MIT) or release (servo) frames; ``suppress``: whatever raises, go on.

        Whether every bus that is not lost took every frame (a stop counts a release only then: a
        frame a full transmit queue refused is not one a driver heard; a lost bus's are tried all the
        same, and its stop is a fault)."""
        taken = True
        for j in self.joints:
            for f in j.release_frames():
                ok = False
                if suppress:
                    with contextlib.suppress(Exception):
                        ok = self.send(j, f)
                else:
                    ok = self.send(j, f)
                if not ok and j.bus not in self._lost:
                    taken = False
        return taken

    def _lose(self, name: str, error: BaseException, now: float) -> None:
        if name in self._lost:
            return
        self._lost[name] = error
        self._live = [x for x in self._live if x[0] != name]  # sends go on being tried: damping, exit
        on_it = [j for j in self.joints if j.bus == name]
        cfg = self.config.buses[name]
        stop = BusLost(
            f"bus {name!r} ({cfg.interface} channel {cfg.channel!r}) failed: {str(error) or type(error).__name__}; "
            f"{', '.join(j.name for j in on_it)} may not have been damped or disabled (the frames were tried; a "
            "MIT driver keeps its last command until its CAN timeout, if it has one); the other joints were",
            bus=name,
            fix="cut the motors' power (e-stop) if they are still holding; check the adapter, cable and "
                "interface (ip link), then close the arm and open it again")
        stop.at = now
        stop.__cause__ = error  # what failed, by its own name (a serial line's UartError ...)
        self._on_lost(stop)
