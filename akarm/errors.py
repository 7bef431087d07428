"""The exceptions akarm raises.

Every error is an :class:`AkarmError` and says three things: which joint (where one is concerned),
what went wrong, and what to do about it. Catch :class:`AkarmError` to catch everything akarm
raises on purpose; anything else escaping akarm is a bug.

::

    AkarmError
    ├── ProtocolError          a value or frame the wire protocol cannot carry
    │   └── FrameError         a received frame that is corrupt (CRC, length, end byte, ID)
    ├── UnknownMotorError      a motor model not in the catalogue
    ├── ConfigError            a robot YAML with problems (carries every one of them)
    ├── ModelError             a URDF Pinocchio cannot use
    ├── BusError               a CAN bus that cannot be opened or written
    │   └── UartError          the serial (UART) line to a servo motor failed under the arm
    │       ├── UartNoise          bytes that form no frame (noise, a wrong baud rate)
    │       ├── UartPartialFrame   frames cut short
    │       ├── UartBadCrc         frames whose CRC does not match
    │       └── UartSilent         no byte from the motor
    ├── ArgumentError          a bad argument: wrong type or shape, not finite, out of its domain, an unknown name
    ├── StateError             an Arm call that does not fit its state (move before enable, ...)
    │   └── StopLatched        a command refused: a safety stop is latched until an explicit enable
    ├── LimitError             a target or a planned path past a joint limit
    │   ├── UnreachableError   a Cartesian pose or path the tool cannot reach
    │   └── SingularityError   a Cartesian pose or path at (or through) a singularity
    ├── TrajectoryError        ruckig could not plan the motion
    ├── RecordingError         a teach/replay file that is corrupt or cannot be written
    └── SafetyStop             the arm was stopped (damped, then disabled) for safety
        ├── MotorFault         a motor reported an error code
        ├── FeedbackTimeout    a joint's feedback became too old
        │   └── StaleFeedback  replies come regularly, but each one too long after its command
        ├── OverTemperature    a joint passed its temperature limit
        ├── TrackingError      a joint is too far from where it is commanded, or does not move
        ├── ImplausibleFeedback  replies no physical joint could send (several in a row)
        ├── ForeignTraffic     another program commands, disables or answers for our motors
        ├── TurnCountLost      a joint reads whole rotor turns from where it stopped (its driver was power-cycled)
        ├── WiringError        the bus is not wired as configured, found before anything is powered
        │   ├── DuplicateCanId   two motors answer on one CAN ID
        │   ├── ModeMismatch     a motor speaks the other mode (MIT configured, servo frames seen, or back)
        │   └── StatusRateLow    a servo motor's status frames come far slower than configured
        ├── NotSettled         the arm kept moving while enable() waited for it to come to rest
        ├── CollisionError     the collision reflex: a joint's external torque estimate passed its threshold
        ├── LoopStall          the control loop itself did not run for longer than its stall_limit
        ├── DriverReset        a driver answers, but not in motor mode: it was reset (a brown-out)
        └── BusLost            a bus died under the arm (also a BusError)
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "AkarmError",
    "ArgumentError",
    "BusError",
    "BusLost",
    "CollisionError",
    "ConfigError",
    "ConfigProblem",
    "ConfigWarning",
    "DeviationError",
    "DriverReset",
    "DuplicateCanId",
    "FeedbackTimeout",
    "ForeignTraffic",
    "FrameError",
    "ImplausibleFeedback",
    "LimitError",
    "LoopCrashed",
    "LoopStall",
    "ModeMismatch",
    "ModelError",
    "MotorFault",
    "NotSettled",
    "OverTemperature",
    "ProtocolError",
    "RecordingError",
    "SafetyStop",
    "SelfCollisionStop",
    "SingularityError",
    "StaleFeedback",
    "StateError",
    "StatusRateLow",
    "StopLatched",
    "TrackingError",
    "TrajectoryError",
    "TurnCountLost",
    "UartBadCrc",
    "UartError",
    "UartNoise",
    "UartPartialFrame",
    "UartSilent",
    "UnknownMotorError",
    "UnreachableError",
    "WiringError",
    "WorkspaceExit",
    "did_you_mean",
    "finite_number",
    "num",
]


class AkarmError(Exception):
    """Base of every error akarm raises.

    Attributes:
        what: what went wrong, one sentence.
        joint: the joint concerned, or ``None``.
        fix: what the user can do about it, or ``""``.
    """

    def __init__(self, what: str, *, joint: str | None = None, fix: str = "") -> None:
        self.what = what
        self.joint = joint
        self.fix = fix
        super().__init__(self._render())

    def _render(self) -> str:
        text = f"joint {self.joint!r}: {self.what}" if self.joint else self.what
        if self.fix:
            text = f"{text} (fix: {self.fix})"
        return text


class ProtocolError(AkarmError, ValueError):
    """A value that cannot be encoded, or bytes that are not a frame of the expected kind."""


class FrameError(ProtocolError):
    """A received frame is corrupt: bad CRC, wrong length, missing end byte, wrong ID.

    Attributes:
        data: the offending bytes (as much of them as is known).
    """

    def __init__(self, what: str, *, data: bytes = b"", joint: str | None = None, fix: str = "") -> None:
        self.data = bytes(data)
        super().__init__(what, joint=joint, fix=fix)


class UnknownMotorError(AkarmError, KeyError):
    """A motor model name that is not in the catalogue.

    Attributes:
        name: the name asked for.
        known: the names the catalogue has.
    """

    def __init__(self, name: str, known: list[str]) -> None:
        self.name = name
        self.known = sorted(known)
        super().__init__(
            f"unknown motor model {name!r}",
            fix="use one of " + ", ".join(self.known) + ", or define it under `motors:` in the robot YAML",
        )

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return self._render()


@dataclass(frozen=True)
class ConfigProblem:
    """One problem in a robot configuration.

    Attributes:
        file: the file it is in.
        line: 1-based line number, or ``None`` when no line applies (a URDF joint left out, ...).
        message: what is wrong.
        fix: what to change.
    """

    file: str
    line: int | None
    message: str
    fix: str = ""

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line is not None else self.file
        text = f"{where}: {self.message}"
        if self.fix:
            text = f"{text} (fix: {self.fix})"
        return text


class ConfigError(AkarmError):
    """A robot configuration with problems; ``problems`` lists every one found in one pass."""

    def __init__(self, problems: list[ConfigProblem]) -> None:
        self.problems = list(problems)
        n = len(self.problems)
        head = f"{n} problem{'s' if n != 1 else ''} in the robot configuration"
        super().__init__(head + ":\n" + "\n".join(f"  {p}" for p in self.problems))

    def _render(self) -> str:
        return self.what


class ConfigWarning(UserWarning):
    """A robot file that loads but says less than it should: a URDF joint held at a default position
    because the file does not say where (issued by :func:`~akarm.load_robot`; ``akarm check`` lists
    every warning, the gravity ones included)."""


class ModelError(AkarmError):
    """The URDF cannot be turned into a dynamics model, or a frame/joint is not in it."""


class BusError(AkarmError):
    """A CAN bus cannot be opened, or a frame cannot be sent on it."""


class UartError(BusError):
    """The serial line to a servo motor (:mod:`akarm.buses.uart`) carried no good reply for several
    polls in a row while the motor was being commanded. The arm stops on it: it is the cause
    (``__cause__``) of the :class:`BusLost` the arm raises.

    Attributes:
        port: the serial device (the bus's channel).
        polls: the polls in a row that got no good reply.
        data: some of the bytes received meanwhile (empty for :class:`UartSilent`).
    """

    kind = ""

    def __init__(self, what: str, *, port: str, polls: int, data: bytes = b"", joint: str | None = None,
                 fix: str = "") -> None:
        self.port = port
        self.polls = polls
        self.data = bytes(data)
        super().__init__(what, joint=joint, fix=fix)


class UartNoise(UartError):
    """Bytes arrive, but none of them forms a frame: line noise, a wrong baud rate, another device."""

    kind = "noise"


class UartPartialFrame(UartError):
    """Replies start (a frame header) but are cut short before their end."""

    kind = "partial"


class UartBadCrc(UartError):
    """Replies arrive whole, but their CRC does not match: bits flipped on the line."""

    kind = "crc"


class UartSilent(UartError):
    """Nothing at all comes back from the motor (it may still hear the commands)."""

    kind = "silent"


class ArgumentError(AkarmError, ValueError):
    """A bad argument to akarm's API: of the wrong type or shape, not finite, outside the values it
    can take, or naming something that does not exist (a joint, a pose). Nothing was done.

    A target past a joint limit is not a bad argument but a motion refused: a :class:`LimitError`.
    """


class StateError(AkarmError):
    """An :class:`~akarm.Arm` call that does not fit the arm's state (e.g. move before enable)."""


class StopLatched(StateError):
    """A command refused because a safety stop is latched: ``akarm serve`` stopped the arm for safety
    and nothing moves until the stop is acknowledged by an explicit enable (``akarm enable``, the
    ``akarm/enable`` service, ``ArmServer.enable()``). Each refusal is a new object.

    Attributes:
        stop: the latched stop's error class, e.g. ``"FeedbackTimeout"`` (``""`` if unknown).
        time: when the arm stopped, s since the epoch (``None`` if unknown).
    """

    def __init__(self, what: str, *, stop: str = "", time: float | None = None, joint: str | None = None,
                 fix: str = "") -> None:
        self.stop = stop
        self.time = time
        super().__init__(what, joint=joint, fix=fix)


class LimitError(AkarmError):
    """A target, or a position the planned trajectory passes through, is past a joint limit."""


class UnreachableError(LimitError):
    """A Cartesian target pose, or a point of a straight-line path, that the tool cannot reach with
    any joint positions (the arm is too short, or the orientation is one it cannot take).

    Attributes:
        distance: how close the tool came to the pose: m (position) and rad (orientation).
    """

    def __init__(self, what: str, *, distance: tuple[float, float] = (0.0, 0.0), joint: str | None = None,
                 fix: str = "") -> None:
        self.distance = distance
        super().__init__(what, joint=joint, fix=fix)


class SingularityError(LimitError):
    """A Cartesian target pose, or a straight-line path, at or through a singularity: a pose where
    the joints cannot move the tool in some direction (an arm stretched out, two axes aligned),
    so near it small tool motions need very large joint motions.

    Attributes:
        sigma: the smallest singular value of the tool Jacobian there (m/rad; rotations weighted by
            0.1 m), or, for a path, the joint travel per metre of tool travel, rad/m.
    """

    def __init__(self, what: str, *, sigma: float, joint: str | None = None, fix: str = "") -> None:
        self.sigma = sigma
        super().__init__(what, joint=joint, fix=fix)


class TrajectoryError(AkarmError):
    """ruckig could not plan the requested motion."""


class RecordingError(AkarmError):
    """A teach/replay recording that is corrupt, truncated, or cannot be written."""


class SafetyStop(AkarmError):
    """The arm was brought to a safe stop (damping, then exit) and is disabled.

    Attributes:
        at: the arm's clock time (s) at which the stop was decided, or ``None`` (set by the
            supervisor; the time from a fault to ``at`` is the detection time).
    """

    at: float | None = None


class MotorFault(SafetyStop):
    """A motor reported an error code.

    Attributes:
        code: the numeric error code from the motor.
    """

    def __init__(self, what: str, *, code: int, joint: str | None = None, fix: str = "") -> None:
        self.code = code
        super().__init__(what, joint=joint, fix=fix)


class FeedbackTimeout(SafetyStop):
    """A joint's most recent feedback is older than the configured limit.

    Attributes:
        age: the feedback age in s when the stop was triggered.
        limit: the joint's feedback timeout, s (``None`` where it does not apply).
    """

    def __init__(self, what: str, *, age: float, limit: float | None = None, joint: str | None = None,
                 fix: str = "") -> None:
        self.age = age
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class StaleFeedback(FeedbackTimeout):
    """A joint answers, but each reply arrives longer after its command than the feedback timeout:
    a constant delay (a backed-up adapter or bus), which feedback age alone cannot see.

    Attributes:
        age: the measured delay between a command and its reply, s. limit: the feedback timeout, s.
    """


class OverTemperature(SafetyStop):
    """A joint's reported temperature passed the configured limit.

    Attributes:
        temperature: the reported temperature in °C.
        limit: the joint's ``max_temperature``, °C (``None`` where not given).
    """

    def __init__(self, what: str, *, temperature: float, limit: float | None = None, joint: str | None = None,
                 fix: str = "") -> None:
        self.temperature = temperature
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class TrackingError(SafetyStop):
    """A joint's measured position is further from the commanded one than its following-error
    limit, or its reading stays constant while it is commanded to move: a frozen encoder, a blocked
    joint, an undersized motor, or a motor another program disabled.

    Attributes:
        error: the following error (commanded minus measured), rad; for a reading that stays
            constant, how far the command moved meanwhile, rad.
        limit: the limit it passed, rad.
    """

    def __init__(self, what: str, *, error: float, limit: float, joint: str | None = None, fix: str = "") -> None:
        self.error = error
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class ImplausibleFeedback(SafetyStop):
    """Several replies in a row claimed positions the joint cannot have reached since the last good
    one (faster than its motor can turn): a corrupt or forged reply stream.

    Attributes:
        value: the last rejected position, rad (joint side).
        limit: the fastest the joint can move (the gate's speed, 1.5 × its velocity range), rad/s.
        count: rejected replies in a row.
    """

    def __init__(self, what: str, *, value: float, limit: float, count: int, joint: str | None = None,
                 fix: str = "") -> None:
        self.value = value
        self.limit = limit
        self.count = count
        super().__init__(what, joint=joint, fix=fix)


class ForeignTraffic(SafetyStop):
    """Another program (or a second motor with the same CAN ID) is on the bus with our motors: it
    sent a command, ENTER, EXIT or ZERO to one of them, or replies that no command of ours asked for.

    Attributes:
        kind: ``"exit"``, ``"enter"``, ``"zero"``, ``"command"`` or ``"replies"``.
    """

    def __init__(self, what: str, *, kind: str, joint: str | None = None, fix: str = "") -> None:
        self.kind = kind
        super().__init__(what, joint=joint, fix=fix)


class TurnCountLost(SafetyStop):
    """At enable, a joint reads a whole number of rotor turns (``k · 2π / gear ratio``) from the position
    akarm remembered when the arm last stopped: its driver lost its multi-turn count (a power cycle).
    Nothing was enabled.

    Or, found by physics while the arm is held at enable (a joint gravity moves while limp, whose
    position is not remembered): the torque holding the arm is what the model's gravity asks with that
    joint ``k`` turns from its reading, not at its reading (:class:`akarm.control.turns.GravityTurnCheck`).

    Attributes:
        reading: rad now. remembered: rad when the arm stopped (NaN: found by the torque). turns: ``k``
            (reading minus where the joint stands, in rotor turns).
        measured: N·m holding the joint (NaN: found by the remembered position). expected: N·m the
            model's gravity asks at the reading. explained: N·m it asks with the joint ``k`` turns back.
        alternatives: other turns that explain the torque as well (the sign of a turn near the
            gravity-neutral pose, hanging or upright, may not show).
    """

    def __init__(self, what: str, *, reading: float, remembered: float, turns: int, joint: str | None = None,
                 fix: str = "", measured: float = math.nan, expected: float = math.nan,
                 explained: float = math.nan, alternatives: tuple[int, ...] = ()) -> None:
        self.reading = reading
        self.remembered = remembered
        self.turns = turns
        self.measured = measured
        self.expected = expected
        self.explained = explained
        self.alternatives = tuple(alternatives)
        super().__init__(what, joint=joint, fix=fix)


class WiringError(SafetyStop):
    """The bus is not what the robot file says, found at contact (before any command with gains or
    torque) or by ``akarm scan``. Nothing was enabled.

    Attributes:
        can_id: the CAN ID concerned.
    """

    def __init__(self, what: str, *, can_id: int, joint: str | None = None, fix: str = "") -> None:
        self.can_id = can_id
        super().__init__(what, joint=joint, fix=fix)


class DuplicateCanId(WiringError):
    """Two motors answer on one CAN ID: more replies than frames sent, or more status frames than one
    motor sends."""


class ModeMismatch(WiringError):
    """The motor on a joint's CAN ID speaks the other mode.

    Attributes:
        seen: ``"servo"`` (status frames from a joint configured MIT) or ``"mit"`` (the reverse).
    """

    def __init__(self, what: str, *, can_id: int, seen: str, joint: str | None = None, fix: str = "") -> None:
        self.seen = seen
        super().__init__(what, can_id=can_id, joint=joint, fix=fix)


class StatusRateLow(WiringError):
    """A servo motor's status frames come far slower than the configured ``status_rate_hz``.

    Attributes:
        measured: Hz. configured: Hz.
    """

    def __init__(self, what: str, *, can_id: int, measured: float, configured: float, joint: str | None = None,
                 fix: str = "") -> None:
        self.measured = measured
        self.configured = configured
        super().__init__(what, can_id=can_id, joint=joint, fix=fix)


class NotSettled(SafetyStop):
    """``enable()`` damped the arm but it did not come to rest in time; nothing was held.

    Attributes:
        speed: the joint's speed when enable gave up, rad/s. limit: the settle speed, rad/s.
    """

    def __init__(self, what: str, *, speed: float, limit: float, joint: str | None = None, fix: str = "") -> None:
        self.speed = speed
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class DeviationError(SafetyStop):
    """Under impedance control (``arm.impedance()``) the tool (or a joint) was further from its target than
    the bound the impedance was started with: the arm was pushed far away, or is held; the arm was
    damped and disabled rather than pulled back with ever more torque.

    Attributes:
        deviation: how far, m (position), rad (orientation, or a joint). limit: the bound, same unit.
    """

    def __init__(self, what: str, *, deviation: float, limit: float, joint: str | None = None, fix: str = "") -> None:
        self.deviation = deviation
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class WorkspaceExit(SafetyStop):
    """The tool frame's origin was measured outside the robot file's ``workspace:`` by more than its
    ``margin`` (further out than its command: the arm was pushed out, or lags far behind); the arm was
    damped and disabled.

    Attributes:
        distance: how far outside the workspace the tool was measured, m. margin: the margin, m.
        position: the measured tool position (x, y, z), m, base frame.
    """

    def __init__(self, what: str, *, distance: float, margin: float, position: tuple[float, float, float],
                 joint: str | None = None, fix: str = "") -> None:
        self.distance = distance
        self.margin = margin
        self.position = position
        super().__init__(what, joint=joint, fix=fix)


class SelfCollisionStop(SafetyStop):
    """Two of the arm's links were measured touching (their shapes from the URDF, as the planner checks them,
    :mod:`akarm.dynamics.selfcollision`) while its command kept them apart by the robot file's
    ``self_collision: {margin: ...}``: the arm was pushed into itself, or lags far behind its command; the
    arm was damped and disabled.

    Attributes:
        pair: the two shapes that touched (``link_k`` names). q: the measured joint positions then (rad,
            config order).
    """

    def __init__(self, what: str, *, pair: tuple[str, str], q: tuple[float, ...], joint: str | None = None,
                 fix: str = "") -> None:
        self.pair = pair
        self.q = q
        super().__init__(what, joint=joint, fix=fix)


class CollisionError(SafetyStop):
    """The collision reflex fired: a joint's estimated external torque (measured torque minus what the
    model, friction and payload explain) passed its ``collision: {threshold: ...}``.

    With the default reaction the arm was damped and disabled; with ``collision_reaction="hold"`` it
    was brought to rest, jerk-limited, and holds there (still enabled).

    Attributes:
        torque: the external torque estimate, N·m (its sign: the direction it pushes the joint).
        threshold: the joint's threshold, N·m.
        reaction: ``"disable"`` or ``"hold"``.
    """

    def __init__(self, what: str, *, torque: float, threshold: float, reaction: str = "disable",
                 joint: str | None = None, fix: str = "") -> None:
        self.torque = torque
        self.threshold = threshold
        self.reaction = reaction
        super().__init__(what, joint=joint, fix=fix)


class LoopStall(SafetyStop):
    """The control loop itself did not run for longer than its ``stall_limit``: this process was
    stopped or starved (a loaded machine, a long garbage collection, SIGSTOP, swapping), not a motor.
    The motors kept their last command meanwhile, unsupervised.

    Attributes:
        stalled: s the loop did not run (beyond its one period). limit: the stall limit, s.
    """

    def __init__(self, what: str, *, stalled: float, limit: float, joint: str | None = None, fix: str = "") -> None:
        self.stalled = stalled
        self.limit = limit
        super().__init__(what, joint=joint, fix=fix)


class LoopCrashed(SafetyStop):
    """The control loop's thread died of an error in akarm itself (a bug): the arm was damped and
    disabled by the loop's last act, and stays in fault (no loop runs any more) until it is closed.
    Its ``__cause__`` is the error."""


class DriverReset(SafetyStop):
    """A MIT driver answers, but reports no torque where the law it was sent asks for some: it is out
    of motor mode, reset by a brown-out (a dip in its supply) or told to leave by something that did
    not use the bus.

    Attributes:
        expected: the torque the commanded law asks for at the reported state, N·m.
        reported: the torque the driver reports, N·m.
    """

    def __init__(self, what: str, *, expected: float, reported: float, joint: str | None = None,
                 fix: str = "") -> None:
        self.expected = expected
        self.reported = reported
        super().__init__(what, joint=joint, fix=fix)


class BusLost(SafetyStop, BusError):
    """A CAN bus failed under a running arm (shut down, unplugged, or every frame refused). The joints
    on other buses were damped and disabled; those on the lost bus could not be told anything.

    Attributes:
        bus: the bus's name.
    """

    def __init__(self, what: str, *, bus: str, joint: str | None = None, fix: str = "") -> None:
        self.bus = bus
        super().__init__(what, joint=joint, fix=fix)


def num(x: float, decimals: int = 4, sign: bool = False) -> str:
    """``x`` for a message that echoes a value: fixed point with ``decimals`` (``0.5000``, ``+1.2000``
    with ``sign``) while that reads well, else in powers of ten with as many significant digits
    (``1e+308``, ``-2.5e+07``), and ``nan``/``inf`` as such. A huge value (a refused 1e308 target) is
    never echoed in hundreds of digits. The one formatting of values in akarm's error texts."""
    x = float(x)
    plus = "+" if sign else ""
    if math.isfinite(x) and abs(x) < 1e6:
        return f"{x:{plus}.{decimals}f}"
    return f"{x:{plus}.{max(decimals, 1)}g}"


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``choices``, or ``""`` when none is close: the
    tail of an error's text for a misspelt name (a joint, a key, a motor model)."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def finite_number(value: object, name: str, *, at_least: float | None = None, above: float | None = None,
                  at_most: float | None = None, unit: str = "", joint: str | None = None, fix: str = "") -> float:
    """``value`` as a float when it is a finite real number (not a bool, not text) within the bounds
    given (``at_least`` ≤ value, ``above`` < value, value ≤ ``at_most``), else :class:`ArgumentError`
    naming ``name`` (and ``joint``), what is wrong, and ``fix`` (by default: the range wanted). The
    one check of a number argument at akarm's boundaries, so that no bad value reaches a comparison,
    a loop or numpy inside."""
    wanted = []
    if at_least is not None:
        wanted.append(f"at least {at_least:g}")
    if above is not None:
        wanted.append(f"more than {above:g}")
    if at_most is not None:
        wanted.append(f"at most {at_most:g}")
    unit_text = f" ({unit})" if unit else ""
    need = f"a finite number{unit_text}" + (f", {' and '.join(wanted)}" if wanted else "")
    fix = fix or f"give {need}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ArgumentError(f"{name} must be {need}, got {value!r}", joint=joint, fix=fix)
    x = float(value)
    if not (math.isfinite(x) and (at_least is None or x >= at_least) and (above is None or x > above)
            and (at_most is None or x <= at_most)):
        raise ArgumentError(f"{name} must be {need}, got {value!r}", joint=joint, fix=fix)
    return x
