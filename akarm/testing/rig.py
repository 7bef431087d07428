"""A simulated arm for tests: a robot's simulated drivers on a bus, and what a test needs around them.

::

    from akarm.testing.rig import SimulatedArm
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
channel, :mod:`akarm.sim.channel`). Servo joints can instead be put on serial ports
(``serial=["elbow"]``): their drivers then answer the UART protocol on a pseudo-terminal pair, and
the arms made here drive them through ``akarm_uart`` buses on the pairs' other ends (joints the robot
file already puts on a serial port always are). The frames are those the simulated drivers took in and sent,
stamped with simulated time. Leaving a rig closes the arms it made (damped, disabled)
and switches off any simulated driver still enabled. The pytest plugin (:mod:`akarm.testing.plugin`) gives
tests a rig per test.
"""

from __future__ import annotations

import itertools
import os
import sys
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akarm.errors import AkarmError, BusError, StateError
from akarm.sim.records import Frame

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.config import RobotConfig
    from akarm.sim.faults import Fault
    from akarm.sim.records import DriverState
    from akarm.timing import TimingProfile

__all__ = ["TRANSPORTS", "Frame", "LeftEnabledWarning", "SimulatedArm", "default_channel", "missing_interfaces"]

#: The transports, by their python-can interface name.
TRANSPORTS = ("virtual", "akarm_local", "socketcan")
_channels = itertools.count()


class LeftEnabledWarning(UserWarning):
    """A test ended with simulated drivers enabled that no injected fault explains."""


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
    _closed = False

    def __init__(self) -> None:
        self._arms: list[Arm] = []
        self._faulted: set[str] = set()
        self._frames: list[Frame] = []
        self._next_frame = 0

    # ------------------------------------------------------------------ starting

    @staticmethod
    def start(robot: str | os.PathLike[str], transport: str = "virtual",
              channel: str | Mapping[str, str] | None = None, timing: str | TimingProfile | None = None,
              pose: str | None = None, serial: Iterable[str] = ()) -> SimulatedArm:
        """The simulated drivers of the robot file ``robot`` on ``transport``, started, the arm at rest
        in ``pose`` (a named pose; default all zeros), the servo joints named in ``serial`` (and those
        the file puts on a serial port) on serial ports, each over a pseudo-terminal pair.

        ``channel``: the bus's channel (for several buses a mapping ``{bus: channel}``, or one name
        each bus's channel is made from). Default: a name unique to this call (``virtual``,
        ``akarm_local``); ``vcan0``, ``vcan1``, ... in the order of the file's buses (``socketcan``).

        Raises:
            AkarmError: an unknown transport; a robot file with problems (:class:`~akarm.ConfigError`);
                :class:`~akarm.BusError` when a SocketCAN interface does not exist (see
                :func:`missing_interfaces`); :class:`~akarm.StateError` when the simulator did not start.
        """
        from akarm.robotfile.load import load_robot
        from akarm.timing import get_profile

        if transport not in TRANSPORTS:
            raise AkarmError(f"unknown transport {transport!r}", fix="use one of: " + ", ".join(TRANSPORTS))
        from akarm.buses.uart import INTERFACE as UART

        config = load_robot(robot)
        serial = list(dict.fromkeys([*serial, *(j.name for j in config.joints
                                                if config.buses[j.bus].interface == UART)]))
        for name in serial:
            if config.joint(name).mode != "servo":
                raise AkarmError(f"joint {name!r} is in MIT mode, which has no serial protocol",
                                 fix="only servo-mode joints run over UART")
        profile = get_profile(timing)
        channel = default_channel(config, transport) if channel is None else channel
        config = config.with_bus(interface=transport, channel=channel)
        missing = missing_interfaces(config)
        if missing:
            raise BusError(missing, fix="create it: sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && "
                                        "sudo ip link set up vcan0 (or give the channel of one that exists)")
        q0 = config.pose(pose) if pose else None
        if transport == "virtual":
            return _InProcess(config, profile, q0, serial)
        return _OwnProcess(Path(robot), config, profile, channel, pose, serial)

    def __enter__(self) -> SimulatedArm:
        return self

    def __exit__(self, exc_type: object, exc: BaseException | None, tb: object) -> None:
        try:
            self.close()
        except AkarmError as e:
            if exc is None:
                raise
            # the block failed: that failure stays what is reported, with closing's as a note on it
            note = f"then closing the simulated arm failed too: {type(e).__name__}: {e}"
            if sys.version_info >= (3, 11):
                exc.add_note(note)
            else:  # no notes before 3.11: said on stderr
                warnings.warn(note, RuntimeWarning, stacklevel=2)

    # ------------------------------------------------------------------ arms

    def arm(self, **options: Any) -> Arm:
        """A new :class:`~akarm.Arm` on the simulated bus, not yet open (``with sim.arm() as arm:``),
        with this simulator's timing profile and, in lock step, its clock. ``options`` go to the Arm
        (e.g. ``feedforward="gravity"``). Arms made here are closed (damped, disabled) by :meth:`close`.
        """
        from akarm.arm import Arm

        options.setdefault("timing", self.timing)
        options.setdefault("remember_positions", False)  # a simulated arm: not the real one's positions to keep
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

    def late(self) -> float:
        """The longest a frame waited before the simulator took it in, s, since the last call (0 in lock
        step): on a machine that cannot run the simulator in real time, frames wait, the drivers take a
        backlog of commands in a burst, and the arm does not move as they asked."""
        raise NotImplementedError

    def enabled_joints(self) -> list[str]:
        """The joints whose simulated driver drives its output now (MIT: motor mode; servo: not released)."""
        return [s.name for s in self.state() if s.enabled]

    def disable_drivers(self) -> list[str]:
        """Switch every simulated driver's output off now, even one cut off by a fault; the joints that were on."""
        raise NotImplementedError

    def frames(self, joint: str | None = None, to_motor: bool | None = None) -> list[Frame]:
        """The CAN frames the simulated drivers took in (commands, ``to_motor=True``) and sent (replies,
        status frames) so far, every one sent to them before the call included, oldest first (the
        simulator keeps the last 200 000): all, or those of ``joint``, or of one direction. After
        :meth:`close` they are still there."""
        if self._ended_by_itself() is None and not self._closed:
            new, self._next_frame = self._new_frames(self._next_frame)
            self._frames.extend(new)
        return [f for f in self._frames
                if (joint is None or f.joint == joint) and (to_motor is None or f.to_motor == to_motor)]

    def _new_frames(self, since: int) -> tuple[list[Frame], int]:
        raise NotImplementedError

    def _inject(self, joint: str, fault: Fault | str) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------------ the end

    def close(self) -> None:
        """Close the arms made by :meth:`arm`, switch off any driver still enabled (warning with
        :class:`LeftEnabledWarning` for joints no injected fault explains), stop the simulator. Safe
        to call twice."""
        if self._closed:
            return
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
                try:
                    if gone is None:
                        self.frames()  # the last ones, kept for after
                finally:  # whatever the simulator answered: a simulator left running would answer on the
                    self._closed = True  # next test's bus too (in vcan-vm, as a second motor on each ID)
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

    def __init__(self, config: RobotConfig, timing: TimingProfile, q0: Any, serial: list[str]) -> None:
        from akarm.sim.robot import SimulatedRobot

        super().__init__()
        self.sim = SimulatedRobot(config, realtime=False, q0=q0, timing=timing, log_frames=True,
                                  serial=dict.fromkeys(serial, "pty"))
        self.config, self.timing, self.clock = self.sim.config, timing, self.sim.clock
        self.sim.start()

    def _inject(self, joint: str, fault: Fault | str) -> None:
        from akarm.sim import faults

        if isinstance(fault, str):
            joint, fault = faults.parse(f"{joint}:{fault}")
        self.sim.inject(joint, fault)

    def clear_faults(self, joint: str | None = None) -> None:
        self.sim.clear_faults(joint)

    def _new_frames(self, since: int) -> tuple[list[Frame], int]:
        self.sim.wait_received()
        return self.sim.logged_frames(since)

    def state(self) -> list[DriverState]:
        self.sim.wait_received()
        return self.sim.driver_states()

    def late(self) -> float:
        return self.sim.take_late()

    def disable_drivers(self) -> list[str]:
        self.sim.wait_received()
        return self.sim.disable_drivers()

    def _ended_by_itself(self) -> str | None:
        return None

    def _stop(self) -> None:
        self.clock.detach(self.sim.advance_to)  # an Arm left open can still be closed, with nobody answering
        self.sim.close()


class _OwnProcess(SimulatedArm):
    """Real time: ``akarm sim`` in a process of its own, reached through its control channel."""

    def __init__(self, robot: Path, config: RobotConfig, timing: TimingProfile, channel: str | Mapping[str, str],
                 pose: str | None, serial: list[str]) -> None:
        from akarm.buses.uart import INTERFACE as UART
        from akarm.buses.uart import serial_config
        from akarm.sim.process import SimulatorProcess

        super().__init__()
        self.transport = next((b.interface for b in config.buses.values() if b.interface != UART), "akarm_local")
        self.timing = timing
        text = channel if isinstance(channel, str) else ",".join(f"{k}={v}" for k, v in channel.items())
        args = [a for name in serial for a in ("--serial", f"{name}=pty")]
        self.process = SimulatorProcess(robot, interface=self.transport, channel=text, pose=pose, timing=timing,
                                        control=True, start_timeout=300.0, args=args)
        self.process.__enter__()
        assert self.process.control is not None
        self.control = self.process.control
        self.config = serial_config(config, self.process.serial_ports) if serial else config

    def _inject(self, joint: str, fault: Fault | str) -> None:
        self.control.inject(joint, fault)

    def clear_faults(self, joint: str | None = None) -> None:
        self.control.clear_faults(joint)

    def _new_frames(self, since: int) -> tuple[list[Frame], int]:
        return self.control.frames(since)

    def state(self) -> list[DriverState]:
        return self.control.state()

    def late(self) -> float:
        return self.control.late()

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
