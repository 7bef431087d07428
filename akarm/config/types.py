"""Typed, immutable robot configuration (what a robot YAML says, validated).

The loader :func:`load_robot` (in :mod:`akarm.robotfile.load`) turns a YAML file into a
:class:`RobotConfig`. These types are what every other layer (model, controller, simulator, CLI)
reads; they never hold motor-side units.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from akarm.config.workspace import Workspace
from akarm.errors import ArgumentError, ConfigError, ConfigProblem, did_you_mean
from akarm.protocol.motors import Catalogue, MotorModel

__all__ = [
    "DEFAULT_FORCE_FRACTION",
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "BusConfig",
    "Friction",
    "Gains",
    "GripperConfig",
    "JointConfig",
    "Limits",
    "Payload",
    "RobotConfig",
    "SelfCollisionConfig",
    "parse_channel",
]

Mode = Literal["mit", "servo"]
Firmware = Literal["v2", "v3"]

#: Hz: the slowest control loop akarm runs (a period of 0.1 s, half its default stall limit; the
#: ``slow`` timing profile runs at 25 Hz).
MIN_RATE_HZ = 10.0
#: Hz: the fastest (a period of 100 µs: more than a CAN bus at 1 Mbit/s carries for one joint).
MAX_RATE_HZ = 10_000.0


@dataclass(frozen=True)
class BusConfig:
    """One CAN bus, passed to ``can.Bus(interface=..., channel=..., bitrate=..., **options)``.

    Attributes:
        name: the name joints refer to (the key under ``buses:``).
        interface: python-can interface (``socketcan``, ``virtual``, ``pcan``, ``slcan``, ...).
        channel: python-can channel (``can0``, ``vcan0``, a virtual channel name, ...).
        bitrate: bit/s; 1 000 000 for AK drivers.
        options: more keyword arguments for the interface's bus (``device_id``, ``app_name``,
            ``serial``, ``fd``, ``data_bitrate``, ...), passed through as given.
        python_can: the settings that came from python-can's own configuration (``CAN_INTERFACE``,
            ``CAN_CHANNEL``, ``CAN_BITRATE``, ``~/can.conf``, ``~/.canrc``, ...) rather than from
            the robot file, by name (``"interface"``, ``"bitrate"``, an option's key).
    """

    name: str
    interface: str = "socketcan"
    channel: str = "can0"
    bitrate: int = 1_000_000
    options: Mapping[str, Any] = field(default_factory=dict, hash=False)
    python_can: tuple[str, ...] = ()

    def describe(self) -> str:
        """``socketcan:can0 @ 1000 kbit/s`` and the keyword arguments, for tables and messages."""
        text = f"{self.interface}:{self.channel} @ {self.bitrate // 1000} kbit/s"
        if self.options:
            text += " " + " ".join(f"{k}={v!r}" for k, v in self.options.items())
        if self.python_can:
            text += f" ({', '.join(self.python_can)} from python-can's configuration)"
        return text


@dataclass(frozen=True)
class Limits:
    """A joint's limits, joint side, SI units.

    Attributes:
        lower, upper: position range, rad (the URDF's, possibly narrowed by the YAML).
        velocity: rad/s. acceleration: rad/s². jerk: rad/s³.
        torque: N·m, at most the motor's ``t_max`` (feed-forward and MIT torque are clamped to it).
    """

    lower: float
    upper: float
    velocity: float
    acceleration: float
    jerk: float
    torque: float


@dataclass(frozen=True)
class Gains:
    """MIT position/velocity gains: kp in N·m/rad (0-500), kd in N·m·s/rad (0-5)."""

    kp: float = 0.0
    kd: float = 0.0


@dataclass(frozen=True)
class Friction:
    """Joint friction, output side: Coulomb N·m, viscous N·m·s/rad, and a constant torque offset N·m
    the model misses (a cable, a sensor bias). The collision observer uses all three; the
    feed-forward (where friction is compensated) only Coulomb and viscous: the offset is not
    compensated, it only keeps the observer from taking it for an external torque."""

    coulomb: float = 0.0
    viscous: float = 0.0
    offset: float = 0.0
    #: N·m of Coulomb friction more per N·m the motor delivers (friction's load-dependent part; a real
    #: AK80-9: 0.049 N·m per A of Iq, 6 % of its load)
    load: float = 0.0
    #: N·m the joint gets per N·m the motor reports (a real unit's torque constant and gearbox; 1: the
    #: catalogue's); the feed-forward asks for the model's torque over it, the observer counts it in
    torque_scale: float = 1.0


@dataclass(frozen=True)
class SelfCollisionConfig:
    """The robot file's ``self_collision:``: where the links' shapes come from (``"auto"``: the URDF's
    ``<collision>``, else its ``<visual>``, else capsules; ``"none"``: no check) and the margin (m) the
    planner and servoing keep between two shapes (:mod:`akarm.dynamics.selfcollision`)."""

    shapes: Literal["auto", "collision", "visual", "capsules", "none"] = "auto"
    margin: float = 0.01


@dataclass(frozen=True)
class Payload:
    """A mass attached to the tool frame: kg, centre of mass in the tool frame (m)."""

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        # one built in code may give a list or an array: the model, a cache key and a compiled caller
        # all take the tuple the annotation promises
        if not isinstance(self.com, tuple):
            object.__setattr__(self, "com", tuple(self.com))


@dataclass(frozen=True)
class JointConfig:
    """One actuated joint and the motor that drives it.

    ``joint = direction * motor + offset`` (rad), so ``motor = (joint - offset) * direction``.

    Attributes:
        name: URDF joint name.
        bus: name of the :class:`BusConfig` the motor is on.
        can_id: the motor's CAN ID (1-127 in practice; 0 is the host/master ID).
        motor: the catalogue model (overrides from the YAML already applied).
        mode: ``"mit"`` or ``"servo"``.
        firmware: ``"v2"`` (the V1.0.9 manual's MIT frames) or ``"v3"`` (extended-ID MIT frames).
        direction: +1 or -1.
        offset: rad, joint position when the motor reads zero.
        limits: see :class:`Limits`.
        gains: MIT gains used while tracking; servo joints ignore them.
        reply_id: arbitration ID the driver answers on in MIT mode (0 on most units, the motor's own
            ID on some). The controller routes by the reply's byte 0 anyway; the simulator uses it.
        feedback_timeout: s; the watchdog stops the arm when this joint's feedback is older.
            ``None`` uses the arm's default (20 ms, or 3 status periods for servo joints).
        max_temperature: °C; the watchdog stops the arm above it.
        status_rate_hz: servo joints: the rate the motor sends status frames at (its own setting).
        can_timeout: s; MIT firmware CAN timeout (0 = off, as on units in the field). Simulator only.
        friction: identified friction (see :class:`Friction`: the feed-forward compensates its Coulomb and
            viscous terms, the collision observer uses the offset too); ``None`` uses the catalogue's typical values.
        following_error: rad; the supervisor stops the arm when the joint is further than this from
            its commanded position. ``None``: derived (:func:`akarm.control.safety.default_following_error`).
        stuck_travel: rad; the supervisor stops the arm when the command moves this far while the
            joint's reading repeats. ``None``: derived (:func:`akarm.control.safety.default_stuck_travel`).
        collision_threshold: N·m; the collision reflex stops the arm when this joint's external
            torque estimate is larger (:mod:`akarm.control.collision`). ``None``: not checked.
    """

    name: str
    bus: str
    can_id: int
    motor: MotorModel
    mode: Mode
    limits: Limits
    firmware: Firmware = "v2"
    direction: int = 1
    offset: float = 0.0
    gains: Gains = field(default_factory=Gains)
    reply_id: int = 0
    feedback_timeout: float | None = None
    max_temperature: float = 80.0
    status_rate_hz: float = 50.0
    can_timeout: float = 0.0
    friction: Friction | None = None
    following_error: float | None = None
    stuck_travel: float | None = None
    collision_threshold: float | None = None

    def friction_model(self) -> Friction:
        """The friction to compensate: this joint's own, else the motor catalogue's, else none."""
        if self.friction is not None:
            return self.friction
        return Friction(self.motor.friction_coulomb or 0.0, self.motor.friction_viscous or 0.0)



# --------------------------------------------------------------------------- the gripper
# A gripper: a small AK motor moving two jaws (rack and pinion, or a linkage), as the robot file's
# ``gripper:`` entry describes it.
#
# :class:`GripperConfig` is validated and immutable, like :class:`~akarm.config.JointConfig`; it maps
# the motor's output angle to the distance between the jaws and a torque to the squeeze they exert:
#
# - ``width_at(angle)`` / ``angle_at(width)``: linear (``width = stroke · angle / travel``, a rack and
#   pinion) or, with a ``table`` of (rad, m) points, piecewise linear between them (a linkage);
# - ``force_at(torque, angle)`` / ``torque_at(force, angle)``: by virtual work,
#   ``force · dwidth = torque · dangle``, so ``force = torque / (dwidth/dangle)``.
#
# The angle is the motor's output angle past closed: ``angle = direction · motor + offset`` (rad), as
# a joint's. :attr:`GripperConfig.joint` is the motor seen as a joint (a
# :class:`~akarm.config.JointConfig` with the range 0..travel), which the controller drives and the
# simulator simulates like any other; it is never one of the arm's joints.
#: the force a close asks for when it names none: this fraction of ``force_limit``
DEFAULT_FORCE_FRACTION = 0.5


@dataclass(frozen=True)
class GripperConfig:
    """The gripper: its motor (as a joint's), its jaws and its limits. SI units.

    Attributes:
        name: its name (``gripper``): the simulated joint's, the telemetry's, the dataset column's.
        motor, can_id, bus, mode, firmware, direction, reply_id: as a joint's.
        offset: rad: the angle past closed when the motor reads zero (``calibrate()`` finds it).
        kp, kd: MIT gains for position moves (N·m/rad, N·m·s/rad).
        stroke: m, the jaws' distance fully open.
        travel: rad of motor output from closed (0) to fully open.
        table: (angle rad, width m) points from closed to open, both increasing (a linkage); empty:
            width linear in the angle.
        force_limit: N, the most the jaws may squeeze.
        fingers: URDF joints the jaws move (mimic joints, not in the arm's chain).
        speed: m/s, the jaws' approach speed.
        max_temperature: °C, the watchdog's limit. feedback_timeout: s (``None``: the arm's default).
        status_rate_hz: servo mode: the rate the motor sends status frames at (its own setting).
    """

    name: str
    motor: MotorModel
    can_id: int
    bus: str
    stroke: float
    travel: float
    force_limit: float
    mode: Mode = "mit"
    firmware: Firmware = "v2"
    direction: int = 1
    offset: float = 0.0
    kp: float = 5.0
    kd: float = 0.2
    table: tuple[tuple[float, float], ...] = ()
    fingers: tuple[str, ...] = ()
    speed: float = 0.1
    reply_id: int = 0
    max_temperature: float = 80.0
    feedback_timeout: float | None = None
    status_rate_hz: float = 50.0
    _angles: tuple[float, ...] = field(default=(), repr=False, compare=False)
    _widths: tuple[float, ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.table:
            pts = tuple((float(a), float(w)) for a, w in self.table)
        else:
            pts = ((0.0, 0.0), (float(self.travel), float(self.stroke)))
        object.__setattr__(self, "_angles", tuple(a for a, _ in pts))
        object.__setattr__(self, "_widths", tuple(w for _, w in pts))

    # ------------------------------------------------------------------ angle <-> width
    def width_at(self, angle: float) -> float:
        """The jaws' distance (m) at output ``angle`` (rad past closed); outside the table, extended
        with its end slopes."""
        a, w = self._angles, self._widths
        k = min(max(bisect.bisect_right(a, angle) - 1, 0), len(a) - 2)
        return w[k] + (angle - a[k]) * (w[k + 1] - w[k]) / (a[k + 1] - a[k])

    def angle_at(self, width: float) -> float:
        """The output angle (rad past closed) that puts the jaws ``width`` (m) apart."""
        a, w = self._angles, self._widths
        k = min(max(bisect.bisect_right(w, width) - 1, 0), len(w) - 2)
        return a[k] + (width - w[k]) * (a[k + 1] - a[k]) / (w[k + 1] - w[k])

    def slope_at(self, angle: float) -> float:
        """dwidth/dangle at ``angle``, m/rad (positive: the jaws open as the angle grows)."""
        a, w = self._angles, self._widths
        k = min(max(bisect.bisect_right(a, angle) - 1, 0), len(a) - 2)
        return (w[k + 1] - w[k]) / (a[k + 1] - a[k])

    def force_at(self, torque: float, angle: float) -> float:
        """The squeeze (N) a closing ``torque`` (N·m, positive closes) exerts at ``angle``."""
        return torque / self.slope_at(angle)

    def torque_at(self, force: float, angle: float) -> float:
        """The closing torque (N·m) that squeezes with ``force`` (N) at ``angle``."""
        return force * self.slope_at(angle)

    @property
    def max_slope(self) -> float:
        """The largest dwidth/dangle over the travel, m/rad."""
        a, w = self._angles, self._widths
        return max((w[k + 1] - w[k]) / (a[k + 1] - a[k]) for k in range(len(a) - 1))

    @property
    def open_angle(self) -> float:
        """rad: the angle fully open (the travel, or the table's last angle)."""
        return self._angles[-1]

    @property
    def default_force(self) -> float:
        """N: what a close squeezes with when it names no force."""
        return DEFAULT_FORCE_FRACTION * self.force_limit

    def check_width(self, width: float) -> float:
        """``width`` as a float, or :class:`~akarm.ArgumentError` outside 0..stroke (or not a number)."""
        try:
            w = float(width)
        except (TypeError, ValueError):
            raise ArgumentError(f"gripper width must be a number of metres, got {width!r}", joint=self.name,
                                fix=f"give a width in 0..{self.stroke:g} m") from None
        if not (math.isfinite(w) and 0.0 <= w <= self.stroke):
            raise ArgumentError(f"gripper width {w:g} m is outside its stroke 0..{self.stroke:g} m", joint=self.name,
                                fix=f"give a width in 0..{self.stroke:g} m")
        return w

    def check_force(self, force: float | None) -> float:
        """The force asked (``None``: :attr:`default_force`), or :class:`~akarm.ArgumentError` when it is
        negative, not a number, or over ``force_limit``."""
        if force is None:
            return self.default_force
        try:
            f = float(force)
        except (TypeError, ValueError):
            raise ArgumentError(f"gripper force must be a number of newtons, got {force!r}", joint=self.name,
                                fix=f"give a force in 0..{self.force_limit:g} N") from None
        if not (math.isfinite(f) and 0.0 <= f <= self.force_limit):
            raise ArgumentError(f"gripper force {f:g} N is outside 0..{self.force_limit:g} N (its force_limit)",
                                joint=self.name, fix=f"give a force in 0..{self.force_limit:g} N")
        return f

    # ------------------------------------------------------------------ the motor as a joint
    @property
    def torque_limit(self) -> float:
        """N·m: the torque that squeezes ``force_limit`` where the transmission is steepest, at most t_max."""
        return min(self.motor.t_max, self.force_limit * self.max_slope)

    @property
    def joint(self) -> JointConfig:
        """The gripper's motor as a joint (range 0..open angle, rad), for the controller and the simulator."""
        velocity = min(self.motor.v_max, self.speed / self.max_slope * 2.0)
        return JointConfig(name=self.name, bus=self.bus, can_id=self.can_id, motor=self.motor, mode=self.mode,
                           limits=Limits(0.0, self.open_angle, velocity, 20.0 * velocity, 400.0 * velocity,
                                         self.torque_limit),
                           firmware=self.firmware, direction=self.direction, offset=self.offset,
                           gains=Gains(self.kp, self.kd), reply_id=self.reply_id,
                           feedback_timeout=self.feedback_timeout, max_temperature=self.max_temperature,
                           status_rate_hz=self.status_rate_hz)


@dataclass(frozen=True)
class RobotConfig:
    """A whole arm: its URDF, buses, joints (in config order) and named poses.

    Attributes:
        name: the robot's name.
        source: the YAML file it was read from (``None`` when built in code).
        urdf: path of the URDF.
        tool_frame: URDF frame for Cartesian queries and the payload (``None``: the last link).
        gravity: m/s², in the URDF's base frame.
        payload: optional payload at the tool frame.
        rate_hz: control loop rate, Hz.
        buses: bus name → :class:`BusConfig`.
        joints: actuated joints in config order (the order of every joint vector in akarm).
        poses: name → joint positions (rad, config order).
        catalogue: the motor catalogue in force (bundled + the YAML's ``motors:``).
        locked: URDF joints that no motor drives, and where they are held (rad, or m for prismatic
            joints): the YAML's ``locked:``, defaults, and joints that mimic others. The dynamics
            model holds them there (their mass still counts); URDF joints in neither ``joints`` nor
            ``locked`` are held at their neutral position (0, or the identity for floating joints).
        warnings: what the loader found questionable but accepted (a joint held at a default
            position, gravity above a motor's rated torque, ...), each with its line and a fix.
        gripper: the gripper (:class:`GripperConfig`), ``None`` without one. Its motor is never one of
            ``joints``: every joint vector of the arm leaves it out.
        workspace: the walls the tool frame's origin stays within (``workspace:``;
            :class:`~akarm.config.workspace.Workspace`), or ``None``: no walls.
        self_collision: the links' self-collision check (``self_collision:``; :class:`SelfCollisionConfig`):
            on by default.
    """

    name: str
    urdf: Path
    buses: Mapping[str, BusConfig]
    joints: tuple[JointConfig, ...]
    rate_hz: float = 500.0
    source: Path | None = None
    tool_frame: str | None = None
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    payload: Payload | None = None
    poses: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    catalogue: Catalogue | None = None
    locked: Mapping[str, float] = field(default_factory=dict)
    warnings: tuple[ConfigProblem, ...] = ()
    gripper: GripperConfig | None = None
    workspace: Workspace | None = None
    self_collision: SelfCollisionConfig = field(default_factory=SelfCollisionConfig)

    @property
    def motors(self) -> tuple[JointConfig, ...]:
        """Every motor on the buses: the joints, then the gripper's (:attr:`GripperConfig.joint`)."""
        return self.joints if self.gripper is None else (*self.joints, self.gripper.joint)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in config order."""
        return tuple(j.name for j in self.joints)

    def joint(self, name: str) -> JointConfig:
        """The joint called ``name``; :class:`~akarm.ConfigError` if there is none."""
        for j in self.joints:
            if j.name == name:
                return j
        raise ConfigError([ConfigProblem(str(self.source or self.name), None,
                                         f"no joint named {name!r}{did_you_mean(name, self.joint_names)}",
                                         "joints are: " + ", ".join(self.joint_names))])

    def pose(self, name: str) -> tuple[float, ...]:
        """The named pose (rad, config order); :class:`~akarm.ConfigError` if there is none."""
        try:
            return self.poses[name]
        except KeyError:
            known = ", ".join(self.poses) or "none defined"
            hint = did_you_mean(name, list(self.poses)) if self.poses else ""
            raise ConfigError([ConfigProblem(str(self.source or self.name), None, f"no pose named {name!r}{hint}",
                                             f"poses are: {known}; add it under `poses:`")]) from None

    def with_bus(
        self,
        interface: str | None = None,
        channel: str | Mapping[str, str] | None = None,
        bitrate: int | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> RobotConfig:
        """A copy with bus settings overridden (e.g. to run on the simulator's virtual bus).

        ``interface`` and ``bitrate`` apply to every bus. ``channel`` is either a mapping from bus
        name to channel, or one channel name: used as is when there is one bus, and suffixed with
        ``-<bus name>`` for each bus when there are several (so the buses stay apart). ``options``
        (python-can keyword arguments) are added to every bus's. A bus whose interface changes drops
        the keyword arguments it had: they were meant for the other interface. A serial port
        (``akarm_uart``) is no CAN bus: it keeps its settings, but for its channel where a mapping names it.

        Raises:
            ArgumentError: a mapping names a bus the robot does not have (a misspelled name would
                leave that bus on the robot file's channel: a real arm where a virtual one was meant).
        """
        if isinstance(channel, Mapping):
            unknown = [str(k) for k in channel if k not in self.buses]
            if unknown:
                first = unknown[0]
                raise ArgumentError(f"no bus named {first!r} on robot {self.name!r}"
                                    f"{did_you_mean(first, list(self.buses))}",
                                    fix=f"its buses are: {', '.join(self.buses)} (BUS=CHANNEL,BUS=CHANNEL)")
        buses = {}
        for name, b in self.buses.items():
            if b.interface == "akarm_uart":  # a serial port: only a channel mapping that names it changes it
                named = isinstance(channel, Mapping) and name in channel
                buses[name] = replace(b, channel=channel[name]) if named else b  # type: ignore[index]
                continue
            ch = b.channel
            if isinstance(channel, Mapping):
                ch = channel.get(name, ch)
            elif channel is not None:
                ch = channel if len(self.buses) == 1 else f"{channel}-{name}"
            kept = dict(b.options) if interface is None or interface == b.interface else {}
            given = {k for k, v in (("interface", interface), ("bitrate", bitrate)) if v is not None}
            if channel is not None and (not isinstance(channel, Mapping) or name in channel):
                given.add("channel")
            buses[name] = replace(
                b,
                interface=interface if interface is not None else b.interface,
                channel=ch,
                bitrate=bitrate if bitrate is not None else b.bitrate,
                options={**kept, **(options or {})},
                python_can=tuple(k for k in b.python_can if k not in given and k not in (options or {})
                                 and (k in ("interface", "channel", "bitrate") or k in kept)),
            )
        return replace(self, buses=buses)


def parse_channel(text: str | None) -> str | dict[str, str] | None:
    """The ``channel`` of :meth:`RobotConfig.with_bus` as a command line or an ini file spells it:
    ``vcan0`` → ``"vcan0"``; ``arm=vcan0,aux=vcan1`` → ``{"arm": "vcan0", "aux": "vcan1"}``."""
    if text is None or "=" not in text:
        return text
    mapping: dict[str, str] = {}
    for part in text.split(","):
        name, _, channel = part.partition("=")
        name, channel = name.strip(), channel.strip()
        if not name or not channel:
            raise ArgumentError(f"bus channels {text!r}: {part!r} is not BUS=CHANNEL",
                                fix="give one channel, or BUS=CHANNEL for each bus, separated by commas "
                                    "(arm=vcan0,aux=vcan1)")
        if name in mapping:
            raise ArgumentError(f"bus channels {text!r} name bus {name!r} twice", fix="give each bus one channel")
        mapping[name] = channel
    return mapping
