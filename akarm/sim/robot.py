"""A whole simulated robot: one simulated driver per joint, on the config's CAN buses, around the plant.

In-process, for tests and demos::

    with SimulatedRobot(config, interface="virtual", channel="demo", realtime=False) as sim:
        arm = Arm(sim.config, clock=sim.clock)   # the same bus override, the same stepped clock
        ...

Lock-step (``realtime=False``): nothing runs by itself. ``sim.advance_to(t)`` (which the stepped
clock calls from ``sleep_until``) first handles every frame already received, at the current
simulated time, then integrates the plant in fixed steps up to ``t``, sending the frames that come
due on the way (servo status frames, delayed replies, fault timers) at their simulated times. No
threads, so a run is exactly repeatable and as fast as the CPU allows.

Serial ports: ``serial={"elbow": "pty"}`` puts that joint's driver on a serial port instead of its
CAN bus (a :class:`~akarm.sim.uart.UartServoDriver`, servo joints only): ``"pty"`` makes a
pseudo-terminal pair and keeps one end, the other's path is in :attr:`SimulatedRobot.serial_ports`
and :attr:`SimulatedRobot.config` has the joint on an ``akarm_uart`` bus with that path, so an Arm
built from it drives the joint over UART; a device's path (``/dev/ttyUSB1``, one end of a ``socat``
pair) is opened at the baud rate instead (point the controller at the line's other end yourself). A
joint the robot file already puts on a serial port needs one.

Real time (default, and what ``akarm sim`` uses): a thread per bus blocks on ``recv`` and answers each
frame at once (after bringing the plant up to the wall clock), and a ticker thread brings it there
for whatever comes due between frames (a status frame, a delayed reply, a driver's timeout, a fault's
next step) and at least every :attr:`SimulatedRobot.idle_interval` (20 ms): it sleeps in between, so an
idle simulator costs little CPU (a ticker that woke at every step took most of a CPU in vcan-vm).
When the machine cannot keep up, simulated time slips (it runs slower than the wall clock) rather
than bursting: :attr:`SimulatedRobot.slip` says by how much. Frames that wait in the receive queue are
taken in together; of the setpoints among them that waited longer than
:attr:`SimulatedRobot.overrun_after`, only the newest to each driver is answered, as a driver whose
receive buffer overflowed answers the last (:attr:`SimulatedRobot.overruns` counts the others), so a
backlog cannot grow without end (in vcan-vm on a busy host, frames had waited 55 s).
"""

from __future__ import annotations

import collections
import heapq
import itertools
import math
import threading
import time
import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from akarm.buses.bus import close_buses, open_bus
from akarm.buses.serialport import DEFAULT_BAUDRATE, Port, open_pty, open_serial
from akarm.clock import RealClock, SteppedClock
from akarm.errors import ConfigError, ConfigProblem, StateError
from akarm.protocol import mit
from akarm.sim import faults as _faults
from akarm.sim.drivers import MitDriver, ServoDriver, SimulatedDriver, make_driver
from akarm.sim.gripper import DEFAULT_OBJECT_STIFFNESS, SimGripper
from akarm.sim.params import MotorSimParams, default_params
from akarm.sim.plant import Plant
from akarm.sim.records import DriverState, Frame
from akarm.sim.uart import UartServoDriver
from akarm.sim.variation import Truth, Variation
from akarm.timing import TimingProfile, get_profile

if TYPE_CHECKING:
    import can

    from akarm.config import RobotConfig

__all__ = ["FRAME_LOG_SIZE", "SimulatedRobot", "overrun"]

#: How many of the frames its drivers took in and sent a simulator keeps (:meth:`SimulatedRobot.logged_frames`).
FRAME_LOG_SIZE = 200_000


def _close_ports(ports: Mapping[str, Port]) -> None:
    for port in ports.values():
        port.close()


_SPECIAL = frozenset((mit.ENTER, mit.EXIT, mit.ZERO))  # never dropped
_BATCH = 256  # frames taken in at one simulated time, at most


def _setpoint(msg: can.Message) -> bool:
    """A frame a driver may lose to a newer one without harm beyond a missed reply: an MIT command
    (standard ID, 8 bytes, not ENTER/EXIT/ZERO); extended-ID servo frames are kept whole."""
    data = msg.data
    return not msg.is_extended_id and len(data) == 8 and bytes(data) not in _SPECIAL


def overrun(batch: Sequence[can.Message], now: float, after: float) -> list[can.Message]:
    """What drivers whose receive buffers overflowed answer of ``batch`` (frames found waiting together,
    oldest first; ``now`` and their timestamps in wall-clock s): every frame but a setpoint that waited
    more than ``after`` s with a newer setpoint to the same CAN ID behind it."""
    newest = {m.arbitration_id: k for k, m in enumerate(batch) if _setpoint(m)}
    return [m for k, m in enumerate(batch)
            if not _setpoint(m) or newest[m.arbitration_id] == k or now - m.timestamp <= after]


class _WorldObject:
    """An object placed at a position: its width, where it is, its mass, whether the jaws hold it."""

    def __init__(self, width: float, position: np.ndarray, mass: float, reach: float) -> None:
        self.width = width
        self.position = position
        self.mass = mass
        self.reach = reach
        self.held = False
        self.grip = np.zeros(3)  # where it is from the tool while held (m, base frame)


def _driving(d: SimulatedDriver) -> bool:
    """Whether a driver drives its output now (MIT: motor mode; servo: a control mode, not released)."""
    return bool(d.enabled) if isinstance(d, MitDriver | ServoDriver) else False


class SimulatedRobot:
    """The AK drivers of ``config``'s joints on its CAN buses, moving a simulated arm.

    Args:
        config: the robot. Its buses are used as they are, or with ``interface``/``channel``
            overridden (``config.with_bus(interface, channel)``): pass the same override to the
            controller, or simply give it :attr:`config`. Several buses each get their own python-can bus.
        interface, channel: bus override (e.g. ``"virtual"`` and a channel name unique to a test).
        realtime: ``True`` (default): threads answer frames as they come and the plant follows the wall
            clock. ``False``: lock step through :meth:`advance_to` / :attr:`clock`.
        dt: integration step, s (default: the timing profile's, 0.0005 s (2 kHz) normally).
        timing: a timing profile (:mod:`akarm.timing`), ``"normal"`` (default) or ``"slow"``: the
            integration rate when ``dt`` is not given. Kept as :attr:`timing`.
        log_frames: keep the last :data:`FRAME_LOG_SIZE` frames the drivers took in and sent
            (:meth:`logged_frames`; the test rig and ``akarm sim --control`` turn it on).
        params: per joint name, simulation constants replacing :func:`~akarm.sim.params.default_params`.
        q0: initial joint positions (rad, config order); default 0 (clipped into the URDF limits).
        zero_silence: s an MIT driver stays off-line after ZERO (default 1.0).
        servo_release: s after the last command a servo driver releases its output (default 1.0).
        max_lag: real time only: s the plant may fall behind the wall clock before time slips.
        overrun_after: real time only: s a setpoint frame (an MIT command; never ENTER, EXIT, ZERO nor
            an extended-ID servo frame) may have waited in the receive queue before a newer one to
            the same driver waiting behind it replaces it unanswered (default 0.25).
        faults: per joint name, faults in force from the start (e.g. a reply delay the controller
            meets at its first frame): ``{"elbow": faults.DelayReplies(0.06)}``.
        serial: per joint name, the serial port its driver answers on instead of CAN: ``"pty"`` (a
            pseudo-terminal pair) or a device's path (see the module's docstring).
        baudrate: bit/s of those ports (921 600, the AK drivers').
        clock: lock step only: a :class:`~akarm.clock.SteppedClock` to run on, shared with other
            simulators (two arms in one process: one clock drives both, and both arms' loops); the
            simulator starts at its time. Default: a clock of its own, from 0.
        variation: a real unit instead of the robot file's model (:class:`~akarm.sim.variation.Variation`:
            torque constants, friction, backlash, masses, reply jitter); default: the nominal model.

    Attributes:
        config: the configuration in force (with the bus override).
        plant: the :class:`~akarm.sim.plant.Plant`; model: its :class:`~akarm.dynamics.model.RobotModel`.
        drivers: the simulated drivers, config order.
        clock: a :class:`~akarm.clock.SteppedClock` driving :meth:`advance_to` (lock step), or a
            :class:`~akarm.clock.RealClock` (real time).
        send_errors: frames the bus refused to send (a full socketcan queue, ...).
        timing: the :class:`~akarm.timing.TimingProfile` in force.
        variation: the :class:`~akarm.sim.variation.Variation` given, or ``None``; :attr:`truth` what it drew.
        serial_ports: per joint on a serial port, the path a controller opens (a pseudo-terminal's
            other end), or the device's path the simulator itself opened.
    """

    # C901 15 > 12, left as it was: the simulator's options, each checked in turn
    def __init__(  # noqa: C901
        self,
        config: RobotConfig,
        interface: str | None = None,
        channel: str | Mapping[str, str] | None = None,
        *,
        realtime: bool = True,
        dt: float | None = None,
        params: Mapping[str, MotorSimParams] | None = None,
        q0: Sequence[float] | None = None,
        zero_silence: float = 1.0,
        servo_release: float = 1.0,
        max_lag: float = 0.05,
        overrun_after: float = 0.25,
        faults: Mapping[str, _faults.Fault | Sequence[_faults.Fault]] | None = None,
        timing: str | TimingProfile | None = None,
        log_frames: bool = False,
        serial: Mapping[str, str] | None = None,
        baudrate: int = DEFAULT_BAUDRATE,
        clock: SteppedClock | None = None,
        variation: Variation | None = None,
    ) -> None:
        if interface is not None or channel is not None:
            config = config.with_bus(interface=interface, channel=channel)
        self._ports: dict[str, Port] = {}
        self.serial_ports: dict[str, str] = {}
        weakref.finalize(self, _close_ports, self._ports)  # also when the rest of __init__ raises
        config = self._open_ports(config, dict(serial or {}), baudrate)
        self.config = config
        self.timing = get_profile(timing)
        if dt is None:
            dt = 1.0 / self.timing.sim_rate_hz
        self.realtime = realtime
        self._lock = threading.RLock()
        params = dict(params or {})
        gconf = config.gripper
        unknown = [name for name in params if name not in config.joint_names
                   and (gconf is None or name != gconf.name)]
        if unknown:
            raise ConfigError([ConfigProblem(str(config.source or config.name), None,
                                             f"simulation params for unknown joint(s) {', '.join(unknown)}",
                                             "joints are: " + ", ".join(config.joint_names))])
        plist = [params.get(j.name) or default_params(j.motor) for j in config.joints]
        gp = None if gconf is None else params.get(gconf.name) or default_params(gconf.motor)
        self.variation = variation
        if variation is not None:
            plist = variation.apply(config, plist, gp)
            if gp is not None:  # the gripper's motor is a real unit too
                gp = variation.apply_gripper(gp)
        self.plant = Plant(config, plist, dt)
        self.model = self.plant.model
        if variation is not None and any(x.mass != 1.0 or x.com != 1.0 for x in variation.truth().links):
            self.model.scale_links({x.name: (x.mass, x.com) for x in variation.truth().links})
            self.plant.update_inertia()
        self.dt = self.plant.dt
        if clock is not None and realtime:
            raise StateError("a simulator in real time runs on the wall clock, not on a given clock",
                             fix="pass clock= with realtime=False (lock step)")
        self._k = 0 if clock is None else math.floor(clock.now() / self.dt + 1e-6)  # steps: simulated time is k·dt
        self._t = self._k * self.dt
        q_init: np.ndarray = np.zeros(self.plant.n) if q0 is None else np.asarray(q0, dtype=float)
        self.set_state(np.clip(q_init, self.model.lower, self.model.upper) if q0 is None else q_init)
        inertia = self.plant.joint_inertia()
        drivers: list[SimulatedDriver] = []
        for i, (j, p) in enumerate(zip(config.joints, plist, strict=True)):
            if j.name in self._ports:
                drivers.append(UartServoDriver(j, p, self, self._state_getter(i), self.dt,
                                               load_inertia=float(inertia[i]), release_after=servo_release,
                                               baudrate=baudrate))
                continue
            drivers.append(make_driver(j, p, self, self._state_getter(i), self.dt, load_inertia=float(inertia[i]),
                                       zero_silence=zero_silence, servo_release=servo_release))
        self.drivers: tuple[SimulatedDriver, ...] = tuple(drivers)
        self.plant.attach(drivers)
        #: the gripper's motor, jaws and object (:mod:`akarm.sim.gripper`); ``None`` without a gripper
        self.gripper: SimGripper | None = None
        self._object: _WorldObject | None = None
        if gconf is not None and gp is not None:
            self.gripper = SimGripper(gconf, gp, self.dt)
            gdrv = make_driver(gconf.joint, gp, self, self.gripper.motor_state, self.dt,
                               load_inertia=self.gripper.inertia, zero_silence=zero_silence,
                               servo_release=servo_release)
            self.gripper.attach(gdrv)
            drivers.append(gdrv)
        #: every driver: the joints' (config order), then the gripper's
        self.all_drivers: tuple[SimulatedDriver, ...] = tuple(drivers)
        self._by_name = {d.name: d for d in drivers}
        self._routes: dict[str, dict[tuple[int, bool], SimulatedDriver]] = {b: {} for b in config.buses}
        for d in self.all_drivers:
            table = self._routes.setdefault(d.bus, {})
            for key in d.routes():
                other = table.get(key)
                if other is not None:
                    raise ConfigError([ConfigProblem(
                        str(config.source or config.name), None,
                        f"joints {other.name!r} and {d.name!r} both listen to CAN ID 0x{key[0]:X} on bus {d.bus!r}",
                        "give each motor on a bus its own can_id")])
                table[key] = d
        # who sent a frame (for the frame log): MIT replies by (bus, reply ID, driver ID in byte 0),
        # extended status frames by (bus, whole ID)
        self._senders: dict[tuple[str, int, int], str] = {}
        for d in self.all_drivers:
            if isinstance(d, UartServoDriver):
                continue
            if isinstance(d, MitDriver) and not d.v3:
                self._senders[(d.bus, d.joint.reply_id, d.can_id)] = d.name
            else:
                self._senders[(d.bus, (0x29 << 8) | d.can_id, -1)] = d.name
        # plain tuples of numbers, strings and bytes: the garbage collector stops looking at them, where
        # 200 000 NamedTuples cost every full collection 20-40 ms, a stall a driver must not have
        self.log_frames = log_frames
        self._frame_log: collections.deque[tuple[float, str, int, bool, bytes, str | None, bool]] = \
            collections.deque(maxlen=FRAME_LOG_SIZE)
        self._frames_logged = 0
        self._rx_empty: dict[str, float] = {}
        self._outbox: list[tuple[float, int, str, int, bytes, bool]] = []
        self._serial_outbox: list[tuple[float, int, str, bytes]] = []  # (due, seq, joint, bytes)
        self._uart = {d.name: d for d in self.all_drivers if isinstance(d, UartServoDriver)}
        self._seq = itertools.count()
        self._buses: dict[str, can.BusABC] = {}
        self._open = False  # start() opened the buses (there may be none: every joint on a serial port)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._t0 = 0.0
        self.max_lag = max_lag
        #: real time: the most s the ticker sleeps with nothing due (it wakes for each timer of a driver and
        #: each frame queued to go out at a later time; frames received are answered at once regardless, the
        #: plant brought up to the wall clock first): 20 ms, less than ``max_lag`` (a sleep must not slip time)
        self.idle_interval = min(0.02, max_lag / 2)
        #: real time: the times the ticker woke (an idle simulator: about 1/:attr:`idle_interval` a second)
        self.ticks = 0
        self._wake = threading.Event()  # an earlier deadline than the ticker sleeps to, or close()
        self._tick_due = math.inf  # simulated time the ticker sleeps to
        self.slip = 0.0
        self.overrun_after = overrun_after
        #: real time: setpoint frames dropped: they waited longer than :attr:`overrun_after` and a newer
        #: one to the same driver waited behind them
        self.overruns = 0
        self._late = 0.0
        self.send_errors = 0
        self.thread_error: BaseException | None = None
        for name, fs in (faults or {}).items():
            for fault in (fs if isinstance(fs, Sequence) else [fs]):
                self.joint(name).inject(fault)
        self.clock: SteppedClock | RealClock
        if realtime:
            self.clock = RealClock()
        else:
            self.clock = clock if clock is not None else SteppedClock(0.0)
            self.clock.attach(self.advance_to)

    # ------------------------------------------------------------------ life cycle

    def start(self) -> SimulatedRobot:
        """Open the buses (and, in real time, start the threads). :class:`~akarm.BusError` if a bus won't open."""
        if self._open:
            return self
        from akarm.buses.uart import INTERFACE as UART

        try:
            for name, bus_cfg in self.config.buses.items():
                if bus_cfg.interface == UART:
                    continue  # the controller's end of a serial line: the driver has the other (self._ports)
                bus = self._buses[name] = open_bus(bus_cfg)
                # real time: take in only what the drivers listen to (in the kernel on socketcan): a
                # simulator that read every frame of a busy bus could fall behind and lose the ones it
                # needs. Not in lock step: python-can filters in software there, and recv(0) returns
                # None at a frame it filters out with more behind it, which would leave commands
                # waiting a cycle behind another node's traffic (_dispatch ignores frames for no one).
                if self.realtime:
                    bus.set_filters([{"can_id": aid, "can_mask": 0x1FFFFFFF if ext else 0x7FF, "extended": ext}
                                     for (aid, ext) in self._routes.get(name, {})])
        except BaseException:
            self._shutdown_buses()
            raise
        self._open = True
        if self.realtime:
            self._stop.clear()
            self._rx_empty = dict.fromkeys(self._buses, -math.inf)
            self._t0 = time.perf_counter() - self._t
            for name, bus in self._buses.items():
                th = threading.Thread(target=self._rx_loop, args=(name, bus), name=f"akarm-sim-rx-{name}", daemon=True)
                self._threads.append(th)
            for joint, port in self._ports.items():
                self._rx_empty[f"serial:{joint}"] = -math.inf
                self._threads.append(threading.Thread(target=self._serial_loop, args=(joint, port),
                                                      name=f"akarm-sim-serial-{joint}", daemon=True))
            self._threads.append(threading.Thread(target=self._tick_loop, name="akarm-sim-tick", daemon=True))
            for th in self._threads:
                th.start()
        return self

    def close(self) -> None:
        """Stop the threads and shut every bus down (in lock step, leave the clock). Safe to call twice."""
        if isinstance(self.clock, SteppedClock):
            self.clock.detach(self.advance_to)
        self._stop.set()
        self._wake.set()
        for th in self._threads:
            th.join(timeout=2.0)
        self._threads.clear()
        self._shutdown_buses()
        _close_ports(self._ports)

    def _shutdown_buses(self) -> None:
        self._open = False
        close_buses(self._buses)

    def _open_ports(self, config: RobotConfig, serial: dict[str, str], baudrate: int) -> RobotConfig:
        """Open the serial ports of the joints in ``serial`` (and check that every joint the robot file
        puts on a serial port has one); the config with those joints on ``akarm_uart`` buses."""
        from akarm.buses.uart import INTERFACE as UART
        from akarm.buses.uart import serial_config

        where = str(config.source or config.name)
        for j in config.joints:
            if config.buses[j.bus].interface == UART and j.name not in serial:
                raise ConfigError([ConfigProblem(where, None, f"joint {j.name!r} is on serial port bus {j.bus!r}, "
                                                 "and the simulator was given no port for its driver",
                                                 f"give it one: serial={{{j.name!r}: 'pty'}} (akarm sim --serial "
                                                 f"{j.name}=pty, or {j.name}=PATH of the line's other end)")])
        for name in serial:
            if config.joint(name).mode != "servo":
                raise ConfigError([ConfigProblem(where, None, f"joint {name!r} is in MIT mode, which has no serial "
                                                 "protocol", "only servo-mode joints run over UART")])
        try:
            for name, path in serial.items():
                if path == "pty":
                    self._ports[name], self.serial_ports[name] = open_pty()
                else:
                    self._ports[name] = open_serial(path, baudrate)
                    self.serial_ports[name] = path
        except BaseException:
            _close_ports(self._ports)
            raise
        return serial_config(config, self.serial_ports, baudrate) if serial else config

    def __enter__(self) -> SimulatedRobot:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ state

    @property
    def t(self) -> float:
        """Simulated time, s (a whole number of steps)."""
        return self._t

    @property
    def q(self) -> np.ndarray:
        """Joint positions, rad, config order (a copy)."""
        return self.plant.q.copy()

    @property
    def dq(self) -> np.ndarray:
        """Joint velocities, rad/s, config order (a copy)."""
        return self.plant.dq.copy()

    @property
    def tau(self) -> np.ndarray:
        """Joint torques the motors apply, N·m, config order (a copy)."""
        return self.plant.tau.copy()

    @property
    def temperatures(self) -> np.ndarray:
        """Motor winding temperatures, °C, config order."""
        return np.array([d.temperature for d in self.drivers])

    def set_state(self, q: Sequence[float] | np.ndarray, dq: Sequence[float] | np.ndarray | None = None) -> None:
        """Place the arm: joint positions ``q`` (rad) and velocities ``dq`` (rad/s, default 0), config order."""
        qa = np.asarray(q, dtype=float)
        va = np.zeros(self.plant.n) if dq is None else np.asarray(dq, dtype=float)
        if qa.shape != (self.plant.n,) or va.shape != (self.plant.n,):
            raise StateError(f"set_state needs {self.plant.n} values per vector, in the order "
                             + ", ".join(self.config.joint_names))
        with self._lock:
            self.plant.q[:] = qa
            self.plant.dq[:] = va

    @property
    def truth(self) -> Truth | None:
        """What this simulated unit really is (:meth:`Variation.truth <akarm.sim.variation.Variation.truth>`),
        or ``None`` for the nominal model."""
        return None if self.variation is None else self.variation.truth()

    def set_payload(self, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Attach a payload at the tool frame now: ``mass`` kg at ``com`` (m, tool frame); 0 kg removes it."""
        with self._lock:
            self.plant.set_payload(mass, com)

    def set_blocked(self, name: str, blocked: bool) -> None:
        """Hold joint ``name`` where it is now, at rest, whatever its motor does (``False``: free it)."""
        i = self.config.joint_names.index(name)
        with self._lock:
            if blocked:
                self.plant.block(i)
            else:
                self.plant.blocked.pop(i, None)

    def set_external_torque(self, tau: Sequence[float] | np.ndarray | None) -> None:
        """Push the arm: joint torques ``tau`` (N·m, config order) from outside, on top of the motors,
        friction and gravity, until changed (a person guiding the arm in teach mode). ``None`` clears it.
        """
        with self._lock:
            self.plant.set_external_torque(tau)

    def set_external_wrench(self, wrench: Sequence[float] | np.ndarray | None) -> None:
        """Push the tool: a wrench ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) at the tool frame's origin, in the
        base frame's axes, applied as joint torques ``Jᵀ·wrench`` at every step (so it follows the arm),
        until changed; ``None`` clears it."""
        with self._lock:
            self.plant.set_external_wrench(wrench)

    def set_surface(self, height: float | None, stiffness: float = 2e4, damping: float = 200.0) -> None:
        """A stiff horizontal surface at ``height`` (m, base z) under the tool frame's origin: below it,
        it pushes up with ``stiffness · depth − damping · vz`` N (never pulls); ``None`` removes it."""
        with self._lock:
            self.plant.set_surface(height, stiffness, damping)

    @property
    def contact_force(self) -> float:
        """The surface's push on the tool at the last step, N (0 off it)."""
        return self.plant.contact_force

    @property
    def contact_peak(self) -> float:
        """The surface's largest push on the tool since :meth:`set_surface`, N."""
        return self.plant.contact_peak

    def clear_payload(self) -> None:
        """Remove the payload."""
        self.set_payload(0.0)

    # ------------------------------------------------------------------ the gripper and its object

    def _require_gripper(self) -> SimGripper:
        if self.gripper is None:
            raise StateError(f"robot {self.config.name!r} has no gripper",
                             fix="describe one under `gripper:` in the robot file (docs/gripper.md)")
        return self.gripper

    def place_object(self, width: float, stiffness: float = DEFAULT_OBJECT_STIFFNESS, *, mass: float = 0.0,
                     position: Sequence[float] | None = None, reach: float = 0.03) -> None:
        """An object ``width`` m wide, ``stiffness`` N/m, between the gripper's jaws.

        ``position`` (m, the URDF's base frame): where it lies; it is between the jaws only while the
        tool frame is within ``reach`` m of it, moves with the tool while squeezed, and stays where the
        jaws let go of it (:meth:`object_position`); while held, its ``mass`` (kg) adds to the arm's
        load. Without a position it is always between the jaws.
        """
        g = self._require_gripper()
        with self._lock:
            g.place_object(width, stiffness)
            self._object = None
            if position is not None:
                pos = np.asarray(position, dtype=float)
                if pos.shape != (3,) or not np.all(np.isfinite(pos)) or not (math.isfinite(mass) and mass >= 0):
                    raise StateError("an object's position is 3 numbers (m) and its mass a number >= 0 (kg)")
                self._object = _WorldObject(float(g.object_width or width), pos, float(mass), float(reach))
                self._carry()

    def remove_object(self) -> None:
        """Take the object away (the jaws close on nothing)."""
        g = self._require_gripper()
        with self._lock:
            if self._object is not None and self._object.held:
                self._drop()
            g.remove_object()
            self._object = None

    def object_force(self) -> float:
        """The jaws' true squeeze on the object, N (0 without one, or not touching it)."""
        return self._require_gripper().object_force

    def object_position(self) -> np.ndarray | None:
        """Where the object is (m, base frame; a copy), ``None`` for one placed without a position."""
        with self._lock:
            return None if self._object is None else self._object.position.copy()

    @property
    def object_held(self) -> bool:
        """The jaws squeeze the object (it moves with the tool)."""
        return self._object is not None and self._object.held

    def object_doc(self) -> dict[str, float | bool | None]:
        """The placed object as a picture needs it: ``object`` its width (m; None: none placed) and
        ``between``: it is between the jaws now (placed without a position, or the tool is at it)."""
        g = self._require_gripper()
        with self._lock:
            if self._object is None:
                return {"object": g.object_width, "between": g.object_width is not None}
            return {"object": self._object.width, "between": g.object_width is not None}

    def gripper_width(self) -> float:
        """m between the jaws now."""
        return self._require_gripper().width

    def set_gripper_width(self, width: float) -> None:
        """Put the jaws ``width`` m apart, at rest."""
        g = self._require_gripper()
        with self._lock:
            g.set_width(width)

    def _carry(self) -> None:
        """(Lock held) A placed object: between the jaws when the tool is near it; carried while squeezed."""
        obj, g = self._object, self.gripper
        assert obj is not None and g is not None
        tool = self.model.tool_pose(self.plant.q)[:3, 3]
        if obj.held:
            if g.object_force > 0.0:
                obj.position = tool + obj.grip
                return
            self._drop()
        near = float(np.linalg.norm(tool - obj.position)) <= obj.reach
        if not near:
            g.object_width, g.engaged = None, False
        elif g.object_width is None:  # the tool came to it: between the jaws if they are open wide enough
            g.object_width, g.engaged = obj.width, g.width >= obj.width
        if near and g.object_force > 0.0:
            obj.held = True
            obj.grip = obj.position - tool
            if obj.mass > 0.0:
                base = self.config.payload.mass if self.config.payload is not None else 0.0
                self.plant.set_payload(base + obj.mass)

    def _drop(self) -> None:
        obj = self._object
        assert obj is not None
        obj.held = False
        if obj.mass > 0.0:
            p = self.config.payload
            self.plant.set_payload(p.mass if p is not None else 0.0, p.com if p is not None else (0.0, 0.0, 0.0))

    def joint(self, name: str) -> SimulatedDriver:
        """The simulated driver of joint ``name`` (:class:`MitDriver` or :class:`ServoDriver`); the
        gripper's motor too, by the gripper's name."""
        try:
            return self._by_name[name]
        except KeyError:
            raise ConfigError([ConfigProblem(str(self.config.source or self.config.name), None,
                                             f"no joint named {name!r}",
                                             "joints are: " + ", ".join(self.config.joint_names))]) from None

    def inject(self, joint: str, fault: _faults.Fault) -> None:
        """``sim.joint(joint).inject(fault)``, under the simulator's lock (safe in real time)."""
        with self._lock:
            self.joint(joint).inject(fault)
            self._nudge()

    def clear_faults(self, joint: str | None = None) -> None:
        """End every fault of ``joint`` (default: of every joint)."""
        with self._lock:
            for d in self.all_drivers if joint is None else [self.joint(joint)]:
                d.clear_faults()

    def driver_states(self) -> list[DriverState]:
        """Every driver as it is now (enabled, position, torque, error, faults ...), config order (in real
        time, the plant brought up to the wall clock first)."""
        with self._lock:
            if self.realtime and self._open:
                self._integrate_to(self._wall())
            q, dq, tau = self.plant.q.tolist(), self.plant.dq.tolist(), self.plant.tau.tolist()
            return [DriverState(d.name, _driving(d), q[i], dq[i], tau[i], float(d.temperature), int(d.error),
                                tuple(repr(f) for f in d.faults), d.frames_received, d.frames_sent)
                    for i, d in enumerate(self.drivers)]

    def take_late(self) -> float:
        """Real time: the longest a frame waited, s, from its arrival on this machine's bus (its
        python-can timestamp) until the simulator took it in, since the last call (0 in lock step).
        A machine that cannot run the simulator in real time makes frames wait: the drivers then take a
        backlog of commands in a burst, and the arm does not move as they asked."""
        with self._lock:
            late, self._late = self._late, 0.0
        return late

    def disable_drivers(self) -> list[str]:
        """Take every driver out of motor mode (MIT) or release it (servo) at once, as if it had received
        EXIT or a zero-current frame, even one that cannot hear the bus (a fault): the outputs go limp.
        Returns the joints that were enabled."""
        with self._lock:
            was = [d for d in self.all_drivers if _driving(d)]
            for d in was:
                d.output_off()
            return [d.name for d in was]

    def status_line(self) -> str:
        """One line: time and, per joint, position (rad), torque (N·m), temperature (°C), mode, fault."""
        with self._lock:
            parts = [f"t={self._t:8.2f}s"]
            for d, q, tau in zip(self.drivers, self.plant.q.tolist(), self.plant.tau.tolist(), strict=True):
                if isinstance(d, MitDriver):
                    state = "on" if d.enabled else "off"
                elif isinstance(d, ServoDriver):
                    state = d.control or "off"
                else:
                    state = "?"
                flag = f" E{d.error}" if d.error else ""
                flag += " X" if d.faults else ""
                parts.append(f"{d.name} {q + 0.0:+7.3f}rad {tau + 0.0:+6.2f}Nm {d.temperature:5.1f}C {state}{flag}")
            g = self.gripper
            if g is not None:
                d = self._by_name[g.config.name]
                state = "on" if isinstance(d, MitDriver) and d.enabled else "off"
                squeeze = f" squeeze {g.object_force:.1f}N" if g.object_width is not None else ""
                parts.append(f"{d.name} {g.width * 1e3:5.1f}mm{squeeze} {d.temperature:5.1f}C {state}")
            if self.slip > 0.001:
                parts.append(f"slip {self.slip:.2f}s")
            if self.overruns:
                parts.append(f"overruns {self.overruns}")
            return " | ".join(parts)

    # ------------------------------------------------------------------ DriverHost

    def now(self) -> float:
        """Simulated time, s (for the drivers)."""
        return self._t

    def transmit(self, bus: str, arbitration_id: int, data: bytes, is_extended: bool, due: float) -> None:
        """Send a frame on ``bus`` now, or queue it until simulated time ``due`` (s) (or until the buses open)."""
        if due <= self._t + 1e-9 and self._open:
            self._send_now(bus, arbitration_id, data, is_extended)
        else:
            heapq.heappush(self._outbox, (due, next(self._seq), bus, arbitration_id, data, is_extended))

    def transmit_serial(self, joint: str, data: bytes, due: float) -> None:
        """Write ``data`` on joint ``joint``'s serial port now, or at simulated time ``due`` (s)."""
        if due <= self._t + 1e-9:
            self._write_now(joint, data)
        else:
            heapq.heappush(self._serial_outbox, (due, next(self._seq), joint, data))

    def _write_now(self, joint: str, data: bytes) -> None:
        try:
            self._ports[joint].write(data)
        except OSError:
            self.send_errors += 1
            return
        if self.log_frames:
            d = self._uart[joint]
            self._log(d.bus, data[2] if len(data) > 2 else -1, False, data, joint, False)

    def _send_now(self, bus_name: str, arbitration_id: int, data: bytes, is_extended: bool) -> None:
        import can

        bus = self._buses.get(bus_name)
        if bus is None:
            raise StateError("the simulator's buses are not open",
                             fix="use `with SimulatedRobot(...) as sim:` or call sim.start() first")
        try:
            bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=is_extended,
                                 timestamp=self._t))
        except can.CanError:
            self.send_errors += 1
            return
        if self.log_frames:
            key = (bus_name, arbitration_id, -1) if is_extended else (bus_name, arbitration_id, data[0] if data else -2)
            self._log(bus_name, arbitration_id, is_extended, bytes(data), self._senders.get(key), False)

    def _log(self, bus: str, arbitration_id: int, is_extended: bool, data: bytes, joint: str | None,
             to_motor: bool) -> None:
        self._frame_log.append((self._t, bus, arbitration_id, is_extended, data, joint, to_motor))
        self._frames_logged += 1

    def logged_frames(self, since: int = 0) -> tuple[list[Frame], int]:
        """The frames the simulated drivers took in from the bus (commands, ``to_motor``; also those a
        fault kept from the driver) and sent (replies, status frames), oldest first, from the
        ``since``-th one on (of the last :data:`FRAME_LOG_SIZE`), and the number to ask from next time.

        In real time, call :meth:`wait_received` first to have every frame sent to the drivers so far.

        Raises:
            StateError: the simulator was built without ``log_frames=True``.
        """
        if not self.log_frames:
            raise StateError("this simulator keeps no frame log",
                             fix="build it with SimulatedRobot(..., log_frames=True) (akarm sim: --control)")
        with self._lock:
            first = self._frames_logged - len(self._frame_log)
            frames = [Frame(*f) for f in itertools.islice(self._frame_log, max(0, since - first), None)]
            return frames, self._frames_logged

    def wait_received(self, timeout: float = 2.0) -> bool:
        """Take in every frame already sent to the simulator: in lock step at once; in real time wait
        until each bus's queue has been found empty since the call (at most ``timeout`` s, False then)."""
        if not self.realtime:
            with self._lock:
                self._poll()
            return True
        asked, end = time.monotonic(), time.monotonic() + timeout
        while any(t < asked for t in self._rx_empty.values()):
            if time.monotonic() > end or self._stop.is_set():
                return False
            time.sleep(0.002)
        return True

    def _state_getter(self, i: int) -> Callable[[], tuple[float, float]]:
        plant = self.plant
        return lambda: plant.motor_state(i)

    # ------------------------------------------------------------------ time

    def advance_to(self, t: float) -> None:
        """Lock step: handle every frame received so far at the current time, then integrate to ``t`` (s).

        Frames that come due on the way (servo status frames, delayed replies) are sent at their
        simulated times. Raises :class:`~akarm.StateError` in real-time mode or before :meth:`start`.
        """
        if self.realtime:
            raise StateError("advance_to is for lock step; this simulator runs in real time",
                             fix="build it with realtime=False")
        if not self._open:
            raise StateError("the simulator's buses are not open",
                             fix="use `with SimulatedRobot(...) as sim:` or call sim.start() first")
        self._poll()
        self._integrate_to(t)

    def run_for(self, seconds: float) -> None:
        """Advance by ``seconds``: through the stepped clock in lock step, by sleeping in real time."""
        if self.realtime:
            time.sleep(seconds)
        else:
            assert isinstance(self.clock, SteppedClock)
            self.clock.sleep_until(max(self.clock.now(), self._t) + seconds)

    def _poll(self) -> None:
        """Handle every frame waiting on every bus and serial port, at the current simulated time."""
        for name, bus in self._buses.items():
            routes = self._routes.get(name, {})
            while True:
                msg = bus.recv(timeout=0.0)
                if msg is None:
                    break
                self._dispatch(name, routes, msg)
        for joint, port in self._ports.items():
            self._serial_in(joint, port)

    def _serial_in(self, joint: str, port: Port) -> bool:
        """Hand the bytes that arrived on ``joint``'s serial port to its driver (and to the frame log);
        False when the port failed (a device that went away: the driver hears nothing, as unplugged)."""
        try:
            data = port.read()
        except OSError:
            return False
        if not data:
            return True
        d = self._uart[joint]
        for payload in d.receive_bytes(data, self._t):
            if self.log_frames:
                from akarm.protocol.uart import encode_frame

                self._log(d.bus, payload[0], False, encode_frame(payload), joint, True)
        return True

    def _dispatch(self, name: str, routes: Mapping[tuple[int, bool], SimulatedDriver], msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        drv = routes.get((msg.arbitration_id, msg.is_extended_id))
        data = bytes(msg.data)
        if self.log_frames:
            self._log(name, msg.arbitration_id, msg.is_extended_id, data, drv.name if drv is not None else None, True)
        if drv is not None:
            drv.receive(msg.arbitration_id, msg.is_extended_id, data, self._t)

    def _integrate_to(self, t: float) -> None:
        dt = self.dt
        target = math.floor(t / dt + 1e-6)
        plant = self.plant
        outbox = self._outbox
        serial = self._serial_outbox
        drivers = self.all_drivers
        grip = self.gripper
        while self._k < target:
            tk = self._k * dt
            self._t = tk
            plant.step(tk)
            if grip is not None:
                grip.step(tk)
            self._k += 1
            self._t = self._k * dt
            if (outbox and outbox[0][0] <= self._t + 1e-9) or (serial and serial[0][0] <= self._t + 1e-9):
                self._flush()
        # timers due exactly now (a status frame at t) run now, not at the start of the next step
        tk = self._t
        for d in drivers:
            d.tick(tk)
        if (outbox and outbox[0][0] <= tk + 1e-9) or (serial and serial[0][0] <= tk + 1e-9):
            self._flush()
        if self._object is not None:
            self._carry()

    def _flush(self) -> None:
        outbox = self._outbox
        while outbox and outbox[0][0] <= self._t + 1e-9:
            _, _, bus, aid, data, ext = heapq.heappop(outbox)
            self._send_now(bus, aid, data, ext)
        serial = self._serial_outbox
        while serial and serial[0][0] <= self._t + 1e-9:
            _, _, joint, data = heapq.heappop(serial)
            self._write_now(joint, data)

    # ------------------------------------------------------------------ real time

    def _wall(self) -> float:
        """Where simulated time should be now, s; slips when the plant fell more than max_lag behind."""
        target = time.perf_counter() - self._t0
        behind = target - self._t
        if behind > self.max_lag:
            slip = behind - self.max_lag
            self._t0 += slip
            self.slip += slip
            target -= slip
        return target

    def _take_in(self, name: str, routes: dict[tuple[int, bool], SimulatedDriver], batch: list[can.Message]) -> None:
        """The frames found waiting on bus ``name``, oldest first, at one simulated time: a setpoint
        that waited more than :attr:`overrun_after` with a newer one to the same driver behind it is
        dropped (:attr:`overruns`), as a driver whose receive buffer overflowed answers only the last."""
        now = time.time()  # (python-can stamps a frame in wall-clock time)
        late = max(now - m.timestamp if m.timestamp > 0.0 else 0.0 for m in batch)
        if len(batch) > 1 and late > self.overrun_after:
            kept = overrun(batch, now, self.overrun_after)
            self.overruns += len(batch) - len(kept)
            batch = kept
        with self._lock:
            if late > self._late:
                self._late = late
            self._integrate_to(self._wall())
            for m in batch:
                self._dispatch(name, routes, m)
            self._nudge()

    def _rx_loop(self, name: str, bus: can.BusABC) -> None:
        import can

        routes = self._routes.get(name, {})
        beat = getattr(bus, "beat", None)  # akarm_local: tell the controllers when this simulator last read
        try:
            while not self._stop.is_set():
                try:
                    msg = bus.recv(timeout=0.02)
                    while msg is not None:  # every frame waiting, then note that the queue was empty
                        batch = [msg]
                        while len(batch) < _BATCH and (msg := bus.recv(timeout=0.0)) is not None:
                            batch.append(msg)
                        self._take_in(name, routes, batch)
                        msg = bus.recv(timeout=0.0)
                except can.CanError:
                    if self._stop.is_set():
                        return
                    time.sleep(0.01)
                    continue
                self._rx_empty[name] = time.monotonic()
                if beat is not None:
                    beat()
        except BaseException as e:  # reported through thread_error
            if not self._stop.is_set():
                self.thread_error = e
                self._stop.set()

    def _serial_loop(self, joint: str, port: Port) -> None:
        key = f"serial:{joint}"
        try:
            while not self._stop.is_set():
                port.wait(0.02)
                with self._lock:
                    self._integrate_to(self._wall())
                    ok = self._serial_in(joint, port)
                    self._nudge()
                self._rx_empty[key] = time.monotonic()
                if not ok:
                    time.sleep(0.05)  # a failed port reads as ready at once: do not spin
        except BaseException as e:  # reported through thread_error
            if not self._stop.is_set():
                self.thread_error = e
                self._stop.set()

    def _next_due(self) -> float:
        """Simulated time, s, of the next thing due: a driver's timer or a frame queued to go out."""
        due = min(d.next_timer for d in self.all_drivers) if self.all_drivers else math.inf
        if self._outbox:
            due = min(due, self._outbox[0][0])
        if self._serial_outbox:
            due = min(due, self._serial_outbox[0][0])
        return due

    def _nudge(self) -> None:
        """Wake the ticker if something now comes due before the time it sleeps to (under the lock)."""
        if self._next_due() < self._tick_due:
            self._wake.set()

    def _tick_loop(self) -> None:
        """Bring the plant up to the wall clock at each thing due (a driver's timer, a frame queued for
        later) and at least every :attr:`idle_interval`: an idle simulator wakes 50 times a second,
        where one that ticked every step woke 250-500 times (in vcan-vm that alone took most of a CPU)."""
        try:
            while not self._stop.is_set():
                with self._lock:
                    self.ticks += 1
                    self._integrate_to(self._wall())
                    due = max(self._next_due(), self._t + self.dt)  # the plant moves in whole steps
                    self._tick_due = due = min(due, self._t + self.idle_interval)
                    self._wake.clear()
                    wait = due - (time.perf_counter() - self._t0)
                if wait > 0.0:
                    self._wake.wait(wait)
        except BaseException as e:  # reported through thread_error
            self.thread_error = e
            self._stop.set()
