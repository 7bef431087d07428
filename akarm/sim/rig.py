"""A simulated arm for tests: a robot's simulated drivers on a bus, and what a test needs around them.

::

    from akarm.sim.rig import SimulatedArm
    from akarm.sim import faults

    with SimulatedArm.start("robots/arm6.yaml", "akarm_local", timing="slow") as sim:
        with sim.arm() as arm:                      # an akarm.Arm on the simulated arm's bus
            arm.enable()
            sim.inject("elbow", faults.Unplugged())  # into the simulator, in its own process
            ...
        sim.frames(joint="elbow")                   # the CAN frames to and from the elbow

Transports, by python-can interface name: ``virtual`` (a :class:`~akarm.sim.SimulatedRobot` in this
process, in lock step with the arms made by :meth:`SimulatedArm.arm`), ``akarm_local`` and
``socketcan`` (``akarm sim`` in a process of its own, in real time, reached through its control
channel, :mod:`akarm.sim.control`). The frames are seen through buses of the rig's own on the same
channels, as ``candump`` would see them. Leaving a rig closes the arms it made (damped, disabled)
and switches off any simulated driver still enabled. The pytest plugin (:mod:`akarm.testing`) gives
tests a rig per test.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import math
import os
import sys
import threading
import time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from ..errors import AkarmError, BusError, StateError

if TYPE_CHECKING:
    import can

    from ..arm import Arm
    from ..config import RobotConfig
    from ..timing import TimingProfile
    from .control import DriverState
    from .faults import Fault

__all__ = ["TRANSPORTS", "Frame", "LeftEnabledWarning", "SimulatedArm", "default_channel", "missing_interfaces"]

#: The transports, by their python-can interface name.
TRANSPORTS = ("virtual", "akarm_local", "socketcan")
_channels = itertools.count()


class LeftEnabledWarning(UserWarning):
    """A test ended with simulated drivers enabled that no injected fault explains."""


class Frame(NamedTuple):
    """A CAN frame seen on the simulated arm's bus.

    Attributes:
        t: when it was seen, s: simulated time in lock step, else since the simulator started.
        bus: the bus's name in the robot file. arbitration_id, is_extended, data: the frame.
        joint: the joint it was sent to or by (``None``: nobody's).
        to_motor: ``True`` sent to the motor (a command), ``False`` sent by it (a reply or status).
    """

    t: float
    bus: str
    arbitration_id: int
    is_extended: bool
    data: bytes
    joint: str | None
    to_motor: bool


class _Classifier:
    """Whose frame is it, and which way does it go: from the robot's joints, as the firmware addresses them.

    MIT (V1/V2) commands go to the motor's ID in a standard frame; its replies come on its reply ID
    with its ID in byte 0. Extended frames carry the motor's ID in the low byte: ``0x29xx`` is a
    status frame (servo, and V3 replies), any other packet a command.
    """

    def __init__(self, config: RobotConfig) -> None:
        self._command: dict[tuple[str, int], str] = {}
        self._reply: dict[tuple[str, int, int], str] = {}
        self._extended: dict[tuple[str, int], str] = {}
        for j in config.joints:
            if j.mode == "mit" and j.firmware != "v3":
                self._command[(j.bus, j.can_id)] = j.name
                self._reply[(j.bus, j.reply_id, j.can_id)] = j.name
            else:
                self._extended[(j.bus, j.can_id)] = j.name

    def __call__(self, bus: str, arbitration_id: int, is_extended: bool, data: bytes) -> tuple[str | None, bool]:
        if is_extended:
            return self._extended.get((bus, arbitration_id & 0xFF)), (arbitration_id >> 8) != 0x29
        if data and (bus, arbitration_id, data[0]) in self._reply and len(data) in (6, 8):
            return self._reply[(bus, arbitration_id, data[0])], False
        return self._command.get((bus, arbitration_id)), True


class _Recorder:
    """Every frame on the robot's buses, seen through buses of its own on the same channels.

    In lock step it takes them whenever the clock advances (no thread: the run stays repeatable);
    in real time a thread per bus takes them as they come.
    """

    def __init__(self, config: RobotConfig, clock: Any = None, max_frames: int = 200_000) -> None:
        from ..bus import open_bus

        self._classify = _Classifier(config)
        self._frames: collections.deque[Frame] = collections.deque(maxlen=max_frames)
        self._buses: dict[str, can.BusABC] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clock = clock
        self._t0 = time.monotonic()
        self._emptied = {name: -math.inf for name in config.buses}  # real time: when each listener last found
        # its bus's queue empty
        try:
            for name, bus_cfg in config.buses.items():
                self._buses[name] = open_bus(bus_cfg)
        except BaseException:
            self.close()
            raise
        if clock is not None:
            clock.attach(self._take)
        else:
            for name, bus in self._buses.items():
                th = threading.Thread(target=self._listen, args=(name, bus), name=f"akarm-test-frames-{name}",
                                      daemon=True)
                self._threads.append(th)
                th.start()

    def _add(self, name: str, msg: can.Message, t: float) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        data = bytes(msg.data)
        joint, to_motor = self._classify(name, msg.arbitration_id, msg.is_extended_id, data)
        self._frames.append(Frame(t, name, msg.arbitration_id, msg.is_extended_id, data, joint, to_motor))

    def _take(self, _t: float | None = None) -> None:
        """Lock step: every frame waiting, stamped with the clock's time (when they were sent)."""
        if not self._buses:
            return
        now = self._clock.now()
        with self._lock:
            for name, bus in self._buses.items():
                while (msg := bus.recv(timeout=0.0)) is not None:
                    self._add(name, msg, now)

    def _listen(self, name: str, bus: can.BusABC) -> None:
        import can

        while not self._stop.is_set():
            try:
                msg = bus.recv(timeout=0.02)
                while msg is not None:  # everything queued, then note that the queue was empty
                    with self._lock:
                        self._add(name, msg, time.monotonic() - self._t0)
                    msg = bus.recv(timeout=0.0)
            except can.CanError:
                if self._stop.wait(0.01):
                    return
                continue
            self._emptied[name] = time.monotonic()

    def frames(self) -> list[Frame]:
        """Every frame so far: in real time, every frame sent before the call (each listener has found
        its queue empty since), unless that takes over 2 s."""
        if self._clock is not None:
            self._take()
        elif not self._stop.is_set():
            asked, end = time.monotonic(), time.monotonic() + 2.0
            while any(t < asked for t in self._emptied.values()) and time.monotonic() < end:
                time.sleep(0.002)
        with self._lock:
            return list(self._frames)

    def close(self) -> None:
        from ..bus import close_buses

        with contextlib.suppress(Exception):
            self.frames()  # the last ones too
        if self._clock is not None:
            self._clock.detach(self._take)
        self._stop.set()
        for th in self._threads:
            th.join(2.0)
        close_buses(self._buses)


class SimulatedArm:
    """A simulated arm for a test: the simulated drivers of a robot's joints on a bus, and what a
    test needs around them (an :class:`~akarm.Arm` factory, fault injection, the frames on the bus).

    Start one with :meth:`start` (the pytest fixtures do); leave it with :meth:`close` or a ``with``
    block, which closes the arms it made and ends with every simulated driver disabled.

    Attributes:
        transport: ``"virtual"`` (lock step, in this process), ``"akarm_local"`` or ``"socketcan"``
            (real time, the simulator in a process of its own).
        config: the robot with the simulated bus in force: build your own Arm from it, or use :meth:`arm`.
        timing: the :class:`~akarm.timing.TimingProfile` of the simulator and of the arms made here.
        clock: the lock-step clock to give an Arm you build yourself (``None`` in real time).
    """

    transport: str
    config: RobotConfig
    timing: TimingProfile
    clock: Any = None

    def __init__(self) -> None:
        self._arms: list[Arm] = []
        self._faulted: set[str] = set()
        self._recorder: _Recorder | None = None

    # ------------------------------------------------------------------ starting

    @staticmethod
    def start(robot: str | os.PathLike[str], transport: str = "virtual",
              channel: str | Mapping[str, str] | None = None, timing: str | TimingProfile | None = None,
              pose: str | None = None) -> SimulatedArm:
        """The simulated drivers of the robot file ``robot`` on ``transport``, started, the arm at rest
        in ``pose`` (a named pose; default all zeros).

        ``channel``: the bus's channel (for several buses a mapping ``{bus: channel}``, or one name
        each bus's channel is made from). Default: a name unique to this call (``virtual``,
        ``akarm_local``); ``vcan0``, ``vcan1``, ... in the order of the file's buses (``socketcan``).

        Raises:
            AkarmError: an unknown transport; a robot file with problems (:class:`~akarm.ConfigError`);
                :class:`~akarm.BusError` when a SocketCAN interface does not exist (see
                :func:`missing_interfaces`); :class:`~akarm.StateError` when the simulator did not start.
        """
        from ..config_loader import load_robot
        from ..timing import get_profile

        if transport not in TRANSPORTS:
            raise AkarmError(f"unknown transport {transport!r}", fix="use one of: " + ", ".join(TRANSPORTS))
        config = load_robot(robot)
        profile = get_profile(timing)
        channel = default_channel(config, transport) if channel is None else channel
        config = config.with_bus(interface=transport, channel=channel)
        missing = missing_interfaces(config)
        if missing:
            raise BusError(missing, fix="create it: sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && "
                                        "sudo ip link set up vcan0 (or give the channel of one that exists)")
        q0 = config.pose(pose) if pose else None
        if transport == "virtual":
            return _InProcess(config, profile, q0)
        return _OwnProcess(Path(robot), config, profile, channel, pose)

    def __enter__(self) -> SimulatedArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ arms

    def arm(self, **options: Any) -> Arm:
        """A new :class:`~akarm.Arm` on the simulated bus, not yet open (``with sim.arm() as arm:``),
        with this simulator's timing profile and, in lock step, its clock. ``options`` go to the Arm
        (e.g. ``feedforward="gravity"``). Arms made here are closed (damped, disabled) by :meth:`close`.
        """
        from ..arm import Arm

        options.setdefault("timing", self.timing)
        if self.clock is not None:
            options.setdefault("clock", self.clock)
        arm = Arm(self.config, **options)
        self._arms.append(arm)
        return arm

    # ------------------------------------------------------------------ the simulated drivers

    def inject(self, joint: str, fault: Fault | str) -> None:
        """Start ``fault`` on ``joint`` now: one of :mod:`akarm.sim.faults` (``faults.Unplugged()``), or
        the text ``akarm sim --fault`` takes after the joint (``"drop:0.3"``)."""
        self._inject(joint, fault)
        self._faulted.add(joint)

    def clear_faults(self, joint: str | None = None) -> None:
        """End the faults of ``joint`` (default: of every joint)."""
        raise NotImplementedError

    def state(self) -> list[DriverState]:
        """Every simulated driver as it is now (enabled, position, torque, error, faults), config order."""
        raise NotImplementedError

    def enabled_joints(self) -> list[str]:
        """The joints whose simulated driver drives its output now (MIT: motor mode; servo: not released)."""
        return [s.name for s in self.state() if s.enabled]

    def disable_drivers(self) -> list[str]:
        """Switch every simulated driver's output off now, even one cut off by a fault; the joints that were on."""
        raise NotImplementedError

    def frames(self, joint: str | None = None, to_motor: bool | None = None) -> list[Frame]:
        """The CAN frames seen on the simulated arm's buses so far, oldest first (up to the last 200 000):
        all, or those of ``joint``, or only commands (``to_motor=True``) or replies (``False``)."""
        assert self._recorder is not None
        return [f for f in self._recorder.frames()
                if (joint is None or f.joint == joint) and (to_motor is None or f.to_motor == to_motor)]

    def _inject(self, joint: str, fault: Fault | str) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------------ the end

    def close(self) -> None:
        """Close the arms made by :meth:`arm`, switch off any driver still enabled (warning with
        :class:`LeftEnabledWarning` for joints no injected fault explains), stop the simulator. Safe
        to call twice."""
        arms, self._arms = self._arms, []
        gone = None
        try:
            for arm in arms:
                arm.close()
        finally:
            try:
                gone = self._ended_by_itself()
                if gone is None:
                    left = [j for j in self.disable_drivers() if j not in self._faulted]
                    if left:
                        warnings.warn(LeftEnabledWarning(
                            f"the simulated drivers of {', '.join(left)} were still enabled at the end: on a real arm "
                            "those motors would have stayed powered (disable the arm, e.g. leave `with arm:`); "
                            "the test's fixture switched them off"), stacklevel=2)
            finally:
                if self._recorder is not None:
                    self._recorder.close()  # its frames stay readable
                self._stop()
        if gone is not None:
            raise StateError(f"the simulator stopped before the test ended: {gone}",
                             fix="its output above says why; this is a bug in akarm's simulator if it shows a "
                                 "traceback")

    def _ended_by_itself(self) -> str | None:
        """``None`` while the simulator runs; else what it said when it stopped."""
        raise NotImplementedError

    def _stop(self) -> None:
        raise NotImplementedError


class _InProcess(SimulatedArm):
    """Lock step: a SimulatedRobot in this process, the arm's clock its clock."""

    transport = "virtual"

    def __init__(self, config: RobotConfig, timing: TimingProfile, q0: Any) -> None:
        from .robot import SimulatedRobot

        super().__init__()
        self.sim = SimulatedRobot(config, realtime=False, q0=q0, timing=timing)
        self.config, self.timing, self.clock = self.sim.config, timing, self.sim.clock
        self.sim.start()
        try:
            self._recorder = _Recorder(self.config, clock=self.clock)
        except BaseException:
            self.sim.close()
            raise

    def _inject(self, joint: str, fault: Fault | str) -> None:
        from . import faults

        if isinstance(fault, str):
            joint, fault = faults.parse(f"{joint}:{fault}")
        self.sim.inject(joint, fault)

    def clear_faults(self, joint: str | None = None) -> None:
        self.sim.clear_faults(joint)

    def state(self) -> list[DriverState]:
        return self.sim.driver_states()

    def disable_drivers(self) -> list[str]:
        return self.sim.disable_drivers()

    def _ended_by_itself(self) -> str | None:
        return None

    def _stop(self) -> None:
        self.clock.detach(self.sim.advance_to)  # an Arm left open can still be closed, with nobody answering
        self.sim.close()


class _OwnProcess(SimulatedArm):
    """Real time: ``akarm sim`` in a process of its own, reached through its control channel."""

    def __init__(self, robot: Path, config: RobotConfig, timing: TimingProfile, channel: str | Mapping[str, str],
                 pose: str | None) -> None:
        from .process import SimulatorProcess

        super().__init__()
        self.transport = next(iter(config.buses.values())).interface
        self.config, self.timing = config, timing
        text = channel if isinstance(channel, str) else ",".join(f"{k}={v}" for k, v in channel.items())
        self.process = SimulatorProcess(robot, interface=self.transport, channel=text, pose=pose, timing=timing,
                                        control=True, start_timeout=300.0)
        # listening before the simulator starts: its first frames are recorded too
        self._recorder = _Recorder(config)
        try:
            self.process.__enter__()
        except BaseException:
            self._recorder.close()
            raise
        assert self.process.control is not None
        self.control = self.process.control

    def _inject(self, joint: str, fault: Fault | str) -> None:
        self.control.inject(joint, fault)

    def clear_faults(self, joint: str | None = None) -> None:
        self.control.clear_faults(joint)

    def state(self) -> list[DriverState]:
        return self.control.state()

    def disable_drivers(self) -> list[str]:
        return self.control.disable_drivers()

    def _ended_by_itself(self) -> str | None:
        proc = self.process.proc
        if proc is None or proc.poll() is None:
            return None
        return f"exit status {proc.returncode}\n{self.process.output}"

    def _stop(self) -> None:
        self.process.__exit__()


def default_channel(config: RobotConfig, transport: str) -> str | dict[str, str]:
    """The channel(s) a transport uses when none is given: ``vcan0``, ``vcan1``, ... per bus for
    ``socketcan``; a name unique to this process and call otherwise."""
    if transport == "socketcan":
        names = list(config.buses)
        return "vcan0" if len(names) == 1 else {name: f"vcan{k}" for k, name in enumerate(names)}
    return f"akarm-pytest-{os.getpid()}-{next(_channels)}"


def missing_interfaces(config: RobotConfig) -> str | None:
    """Why the SocketCAN interfaces of ``config``'s buses cannot be used here, or ``None`` when they can."""
    wanted = sorted({b.channel for b in config.buses.values() if b.interface == "socketcan"})
    if not wanted:
        return None
    if not sys.platform.startswith("linux"):
        return f"SocketCAN ({', '.join(wanted)}) needs Linux"
    missing = [name for name in wanted if not Path(f"/sys/class/net/{name}").exists()]
    if missing:
        return f"no SocketCAN interface {', '.join(missing)} on this machine"
    return None
