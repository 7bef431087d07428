"""Typed, immutable robot configuration (what a robot YAML says, validated).

The loader :func:`load_robot` (in :mod:`akarm.robotfile.load`) turns a YAML file into a
:class:`RobotConfig`. These types are what every other layer (model, controller, simulator, CLI)
reads; they never hold motor-side units.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from akarm.errors import ArgumentError, ConfigError, ConfigProblem, did_you_mean
from akarm.protocol.motors import Catalogue, MotorModel

__all__ = [
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "BusConfig",
    "Friction",
    "Gains",
    "JointConfig",
    "Limits",
    "Payload",
    "RobotConfig",
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
