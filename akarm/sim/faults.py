"""Faults a simulated driver can be given, to test how a controller copes with a misbehaving motor.

Inject them from Python::

    from akarm.sim import faults
    sim.joint("elbow").inject(faults.DropReplies(0.3, seed=1))
    sim.joint("elbow").inject(faults.DelayReplies(0.005))
    sim.joint("elbow").clear_faults()

or from the command line with ``akarm sim ROBOT.yaml --fault elbow:drop:0.3`` (see :func:`parse`).

Every fault is a small immutable value; the driver keeps the state a fault needs (the random
generator of :class:`DropReplies`, the frozen reading of :class:`FrozenEncoder`, the start time of
:class:`FaultAfter`). Times are in seconds of simulated time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from akarm.errors import AkarmError

__all__ = [
    "KINDS",
    "SERIAL",
    "BadCrc",
    "Blocked",
    "Brownout",
    "CorruptBytes",
    "DelayReplies",
    "DropReplies",
    "ErrorCode",
    "Fault",
    "FaultAfter",
    "ForgedReply",
    "FrozenEncoder",
    "MissedFrames",
    "PartialFrame",
    "PowerCycle",
    "RogueExit",
    "SilentPort",
    "Twin",
    "Unplugged",
    "parse",
]


class Fault:
    """Base class of the faults (a marker: the driver recognises each kind)."""


@dataclass(frozen=True)
class DropReplies(Fault):
    """Lose a fraction of the frames the motor sends (replies and status frames).

    Attributes:
        fraction: probability 0..1 that each frame is dropped.
        seed: seed of the driver's own random generator, so a run is repeatable.
    """

    fraction: float
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0.0 <= self.fraction <= 1.0:
            raise AkarmError(f"DropReplies fraction {self.fraction!r} is outside 0..1",
                             fix="give the share of frames to drop, e.g. 0.3")


@dataclass(frozen=True)
class MissedFrames(Fault):
    """The driver misses the next ``count`` frames addressed to it (its CAN controller's receive
    queue was full: a bus loaded past what it takes, a burst of frames); the ones after arrive.

    Attributes:
        count: frames missed, at least 1.
    """

    count: int = 1

    def __post_init__(self) -> None:
        if not (isinstance(self.count, int) and self.count >= 1):
            raise AkarmError(f"MissedFrames count {self.count!r} is not a whole number, count ≥ 1",
                             fix="give how many frames the driver misses, e.g. 2")


@dataclass(frozen=True)
class DelayReplies(Fault):
    """Send every frame the motor sends ``delay`` seconds late (order kept).

    Attributes:
        delay: s, ≥ 0.
    """

    delay: float

    def __post_init__(self) -> None:
        if not self.delay >= 0.0:
            raise AkarmError(f"DelayReplies delay {self.delay!r} s is negative", fix="give a delay ≥ 0 s")


@dataclass(frozen=True)
class Unplugged(Fault):
    """The motor's CAN cable is out: it sends nothing and receives nothing.

    Attributes:
        power_lost: ``False`` (only CAN is lost): the motor keeps applying its last command (until
            its own timeouts, if any, make it limp). ``True`` (power lost too): the output goes limp
            at once, and when the fault is cleared the driver starts as after power-up (MIT:
            disabled, stored command zero; servo: released, temporary origin forgotten).
    """

    power_lost: bool = False


@dataclass(frozen=True)
class PowerCycle(Fault):
    """The driver's power is switched off and on again: for ``seconds`` it is off (output limp, no
    frames in or out), then it starts as after power-up, out of motor mode (MIT: disabled, stored
    command zero; servo: released, temporary origin forgotten), and its multi-turn count is gone: it
    reports its position shifted by ``turns`` rotor turns (``turns · 2π / gear ratio`` rad at the
    output, motor side), as a real AK driver may after a power cycle.

    Attributes:
        turns: whole rotor turns the reading is off by after the power cycle (0: none).
        seconds: s the driver is off, > 0.
    """

    turns: int
    seconds: float = 0.1

    def __post_init__(self) -> None:
        if isinstance(self.turns, bool) or not isinstance(self.turns, int):
            raise AkarmError(f"PowerCycle turns {self.turns!r} is not a whole number",
                             fix="give the rotor turns the reading shifts by, e.g. PowerCycle(turns=1)")
        if not (isinstance(self.seconds, int | float) and 0.0 < self.seconds < math.inf):
            raise AkarmError(f"PowerCycle time {self.seconds!r} s is not a positive number",
                             fix="give how long the driver is off, e.g. PowerCycle(1, seconds=0.1)")


@dataclass(frozen=True)
class Twin(Fault):
    """A second motor on this joint's CAN ID (a wiring mistake): it hears what this driver hears and
    answers too. Every frame the driver sends (a reply, a status frame) is followed by the twin's, which
    reads motor position ``position`` (rad at the output, motor side: the twin's own shaft, at rest).

    Attributes:
        position: rad.
    """

    position: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.position, int | float) and math.isfinite(self.position)):
            raise AkarmError(f"Twin position {self.position!r} rad is not a finite number",
                             fix="e.g. Twin(0.7): the second motor stands at 0.7 rad")


@dataclass(frozen=True)
class ErrorCode(Fault):
    """Report ``code`` in the error byte (MIT reply byte 7, servo status byte 7) from now on.

    Codes as in the manual: 1 motor over-temperature, 2 over-current, 3 over-voltage,
    4 under-voltage, 5 encoder fault, 6 MOSFET over-temperature, 7 motor stall.
    """

    code: int

    def __post_init__(self) -> None:
        if not 0 <= int(self.code) <= 255:
            raise AkarmError(f"error code {self.code!r} is outside 0..255", fix="use a code 1-7 as the manual lists")


@dataclass(frozen=True)
class FrozenEncoder(Fault):
    """The encoder reading stops changing: the reported position stays at its value when the fault was
    injected and the reported velocity is 0, while the joint itself goes on moving.

    Attributes:
        affects_control: ``False`` (default): only the reports freeze, the firmware's own loops still
            see the true position. ``True``: the firmware's loops see the frozen reading too (as a real
            failed encoder would do), so a position hold no longer holds.
    """

    affects_control: bool = False


@dataclass(frozen=True)
class FaultAfter(Fault):
    """Start reporting error ``code`` ``after`` seconds (simulated time) after the fault is injected.

    Attributes:
        after: s, ≥ 0.
        code: the error code reported from then on (default 1, motor over-temperature).
    """

    after: float
    code: int = 1

    def __post_init__(self) -> None:
        if not self.after >= 0.0:
            raise AkarmError(f"FaultAfter time {self.after!r} s is negative", fix="give a time ≥ 0 s")
        if not 0 <= int(self.code) <= 255:
            raise AkarmError(f"error code {self.code!r} is outside 0..255", fix="use a code 1-7 as the manual lists")


@dataclass(frozen=True)
class ForgedReply(Fault):
    """Another node on the bus sends replies in this joint's name: ``count`` of them, one every
    ``interval`` s from now, each claiming motor position ``position`` (rad at the output, before
    the joint's direction and offset, as on the wire), velocity and torque 0. MIT V1/V2 joints get
    standard-frame replies on ID 0; servo and V3 joints ``0x29xx`` status frames. The driver itself
    goes on as before.

    Attributes:
        position: rad, motor side. count: how many (≥ 1). interval: s between them (≥ 0).
        error: the error code they carry (0: none; a flood of random frames carries any byte).
    """

    position: float
    count: int = 1
    interval: float = 0.0
    error: int = 0

    def __post_init__(self) -> None:
        if int(self.count) < 1 or not 0.0 <= self.interval < math.inf:
            raise AkarmError(f"ForgedReply needs count ≥ 1 and a finite interval ≥ 0, got {self.count!r}, "
                             f"{self.interval!r}", fix="e.g. ForgedReply(12.45, 5, 0.01): five replies 10 ms apart")
        if not math.isfinite(self.position):  # a reply cannot carry it: the simulator would fail to encode it
            raise AkarmError(f"ForgedReply position {self.position!r} rad is not a finite number",
                             fix="e.g. ForgedReply(12.45) for one reply at +12.45 rad")


@dataclass(frozen=True)
class RogueExit(Fault):
    """Another program disables the joint now: MIT, an EXIT frame; servo, a zero-current command.

    Attributes:
        on_bus: ``True`` (default): the frame is sent on the CAN bus, where a controller can see it
            (the driver answers it, as it answers every frame). ``False``: the driver leaves motor
            mode without anything on the bus (told over its serial port, a brown-out): a controller
            sees only what follows.
    """

    on_bus: bool = True


@dataclass(frozen=True)
class Brownout(Fault):
    """The driver's supply dips and it resets: for ``seconds`` it is off (output limp, no frames in or
    out), then it starts as after power-up, out of motor mode (MIT: disabled, stored command zero; servo:
    released), and answers again. Nothing of this is seen on the bus but the silence.

    Attributes:
        seconds: s the driver is off, > 0.
    """

    seconds: float

    def __post_init__(self) -> None:
        if not (isinstance(self.seconds, int | float) and 0.0 < self.seconds < math.inf):
            raise AkarmError(f"Brownout time {self.seconds!r} s is not a positive number",
                             fix="give how long the driver is off, e.g. Brownout(0.01)")


@dataclass(frozen=True)
class Blocked(Fault):
    """The joint is mechanically blocked where it is (an obstacle, a jammed gear): it stops at once and
    moves no more, whatever torque its motor applies, until the fault is cleared."""


def _fraction(kind: str, fraction: float) -> None:
    if not 0.0 <= fraction <= 1.0:
        raise AkarmError(f"{kind} fraction {fraction!r} is outside 0..1",
                         fix="give the share of replies it spoils, e.g. 1.0 for every one")


@dataclass(frozen=True)
class CorruptBytes(Fault):
    """Serial port only: a ``fraction`` of the motor's replies arrive as line noise (random bytes of the
    same length, as a wrong baud rate or interference makes them).

    Attributes:
        fraction: probability 0..1 that a reply is replaced (default 1: every one). seed: of the
            driver's random generator, so a run is repeatable.
    """

    fraction: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        _fraction("CorruptBytes", self.fraction)


@dataclass(frozen=True)
class PartialFrame(Fault):
    """Serial port only: a ``fraction`` of the motor's replies are cut short (their first half arrives,
    the rest is lost: a loose connector, an adapter dropping bytes).

    Attributes:
        fraction: probability 0..1 that a reply is cut (default 1). seed: as :class:`CorruptBytes`.
    """

    fraction: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        _fraction("PartialFrame", self.fraction)


@dataclass(frozen=True)
class BadCrc(Fault):
    """Serial port only: a ``fraction`` of the motor's replies arrive whole but with a wrong CRC (bits
    flipped on the line).

    Attributes:
        fraction: probability 0..1 that a reply is spoilt (default 1). seed: as :class:`CorruptBytes`.
    """

    fraction: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        _fraction("BadCrc", self.fraction)


@dataclass(frozen=True)
class SilentPort(Fault):
    """Serial port only: the motor sends nothing (a broken TX wire) but still hears, and carries out,
    the commands it is sent (:class:`Unplugged` cuts both ways)."""


#: The faults that only a simulated driver on a serial port (``akarm sim --serial``) can have.
SERIAL = (CorruptBytes, PartialFrame, BadCrc, SilentPort)

#: The CLI's fault kinds: ``--fault JOINT:KIND[:ARG]``, with what ARG means.
KINDS: dict[str, str] = {
    "drop": "drop:FRACTION[,SEED]   lose that share of the replies (e.g. drop:0.3)",
    "delay": "delay:SECONDS          send every reply that late (e.g. delay:0.005)",
    "missed": "missed[:COUNT]         the next COUNT frames to the motor (default 1) never reach it",
    "unplugged": "unplugged[:power]      no frames in or out; ':power' makes the output limp too",
    "power-cycle": "power-cycle:TURNS[,SECONDS]   off (default 0.1 s), back out of motor mode, TURNS rotor turns off",
    "twin": "twin[:POS]             a second motor on the same CAN ID, its shaft at POS rad (default 0)",
    "error": "error:CODE             report that error code (1 over-temperature, 5 encoder, ...)",
    "frozen": "frozen[:control]       reported position stops changing; ':control' freezes the loops' too",
    "fault-after": "fault-after:SECONDS[,CODE]   report CODE (default 1) after that many seconds",
    "forged": "forged:POS[,COUNT[,INTERVAL]]   another node sends COUNT replies at motor position POS rad",
    "rogue-exit": "rogue-exit[:silent]    another program disables the joint (':silent': not seen on the bus)",
    "blocked": "blocked                the joint is mechanically blocked where it is",
    "corrupt": "corrupt[:FRACTION[,SEED]]   serial port: replies arrive as noise (default: every one)",
    "partial": "partial[:FRACTION[,SEED]]   serial port: replies are cut short",
    "bad-crc": "bad-crc[:FRACTION[,SEED]]   serial port: replies arrive with a wrong CRC",
    "silent": "silent                 serial port: the motor sends nothing (but hears commands)",
    "brownout": "brownout:SECONDS       the driver resets: off that long, then back out of motor mode",
}


_WIRE: dict[str, type[CorruptBytes | PartialFrame | BadCrc]] = {"corrupt": CorruptBytes, "partial": PartialFrame,
                                                                  "bad-crc": BadCrc}


def _bad(spec: str, why: str) -> AkarmError:
    kinds = "; ".join(KINDS.values())
    return AkarmError(f"bad fault {spec!r}: {why}", fix=f"write JOINT:KIND[:ARG], KIND one of: {kinds}")


# C901 23 > 12, left as it was: the fault syntax of the command line, a branch per kind of fault
def parse(spec: str) -> tuple[str, Fault]:  # noqa: C901
    """Parse a command-line fault ``JOINT:KIND[:ARG]`` into ``(joint name, fault)``.

    Examples: ``elbow:drop:0.3``, ``elbow:drop:0.3,7``, ``elbow:delay:0.005``, ``elbow:missed:2``, ``elbow:unplugged``,
    ``elbow:unplugged:power``, ``elbow:error:1``, ``elbow:frozen``, ``elbow:fault-after:2.0,5``,
    ``elbow:forged:12.45``, ``elbow:forged:12.45,5,0.01``, ``elbow:rogue-exit``, ``elbow:blocked``,
    ``elbow:brownout:0.01``; on a serial port ``elbow:corrupt``, ``elbow:partial:0.5``, ``elbow:bad-crc:1,3``,
    ``elbow:silent``.

    Raises:
        AkarmError: the text is not a fault; the message lists the kinds.
    """
    parts = spec.split(":")
    if len(parts) < 2 or not parts[0]:
        raise _bad(spec, "expected JOINT:KIND[:ARG]")
    joint, kind = parts[0], parts[1].strip().lower().replace("_", "-")
    arg = ":".join(parts[2:]) if len(parts) > 2 else None
    args = [a.strip() for a in arg.split(",")] if arg else []
    try:
        if kind == "drop":
            if not args:
                raise _bad(spec, "drop needs a fraction")
            return joint, DropReplies(float(args[0]), seed=int(args[1]) if len(args) > 1 else 0)
        if kind == "delay":
            if not args:
                raise _bad(spec, "delay needs a time in seconds")
            return joint, DelayReplies(float(args[0]))
        if kind == "missed":
            if len(args) > 1:
                raise _bad(spec, "missed takes at most a count")
            return joint, MissedFrames(int(args[0]) if args else 1)
        if kind == "unplugged":
            if args and args[0] not in ("power", "power_lost", "power-lost"):
                raise _bad(spec, f"unplugged takes nothing or 'power', not {args[0]!r}")
            return joint, Unplugged(power_lost=bool(args))
        if kind == "power-cycle":
            if not args or len(args) > 2:
                raise _bad(spec, "power-cycle needs the rotor turns the reading shifts by (and the seconds off)")
            return joint, PowerCycle(int(args[0]), float(args[1]) if len(args) > 1 else 0.1)
        if kind == "twin":
            return joint, Twin(float(args[0]) if args else 0.0)
        if kind == "error":
            if not args:
                raise _bad(spec, "error needs a code")
            return joint, ErrorCode(int(args[0]))
        if kind == "frozen":
            if args and args[0] != "control":
                raise _bad(spec, f"frozen takes nothing or 'control', not {args[0]!r}")
            return joint, FrozenEncoder(affects_control=bool(args))
        if kind == "fault-after":
            if not args:
                raise _bad(spec, "fault-after needs a time in seconds")
            return joint, FaultAfter(float(args[0]), code=int(args[1]) if len(args) > 1 else 1)
        if kind == "forged":
            if not args:
                raise _bad(spec, "forged needs a position in rad")
            return joint, ForgedReply(float(args[0]), int(args[1]) if len(args) > 1 else 1,
                                      float(args[2]) if len(args) > 2 else 0.0)
        if kind == "rogue-exit":
            if args and args[0] != "silent":
                raise _bad(spec, f"rogue-exit takes nothing or 'silent', not {args[0]!r}")
            return joint, RogueExit(on_bus=not args)
        if kind == "blocked":
            if args:
                raise _bad(spec, "blocked takes no argument")
            return joint, Blocked()
        if kind in _WIRE:
            if len(args) > 2:
                raise _bad(spec, f"{kind} takes at most a fraction and a seed")
            return joint, _WIRE[kind](float(args[0]) if args else 1.0, int(args[1]) if len(args) > 1 else 0)
        if kind == "silent":
            if args:
                raise _bad(spec, "silent takes no argument")
            return joint, SilentPort()
        if kind == "brownout":
            if len(args) != 1:
                raise _bad(spec, "brownout needs a time in seconds")
            return joint, Brownout(float(args[0]))
    except ValueError as e:
        raise _bad(spec, str(e)) from None
    raise _bad(spec, f"unknown kind {kind!r}")
