"""Talking to the motors without a control loop: find them, read their state, set their zero.

The command line's ``scan``, ``status``, ``zero`` and ``disable`` are thin users of this module::

    from akarm import probe
    found = probe.scan(config.buses["arm"])            # which CAN IDs answer, MIT or servo
    for s in probe.read_state(config):                  # joint-side SI, a row per configured joint
        print(s.name, s.position, s.missing)
    probe.zero(config, "elbow")                         # its current position becomes 0

How each kind of motor is heard:

- **MIT (V1/V2 firmware)** answers every frame it receives with a state reply, special frames
  included. Sending EXIT (``FF..FD``) is the query that commands nothing: a disabled motor answers
  and stays disabled, an enabled one answers and is *disabled* (its output goes limp). Replies
  come on arbitration ID 0 on most units and on the motor's own ID on some, so they are matched
  on byte 0, the driver ID.
- **Servo** motors send ``0x2900 | id`` status frames on their own, at their configured rate
  (1-500 Hz; 50 Hz in factory settings; off on some units, which then cannot be found here).
  Nothing is sent to them to read them.
- **MIT V3 boards** answer commands only, with ``0x29xx`` status frames, and have no EXIT frame:
  :func:`scan` sees them only if they are already being commanded (they then look like servo
  motors); :func:`read_state` queries a silent one with its zero-gain, zero-torque command.

Every function listens first: when a controller is already driving a MIT motor its replies are
flowing, and nothing is sent to that motor (an EXIT would drop the arm the controller is holding).

Positions reported by :func:`scan` are motor side (rad at the output, before the joint's direction
and offset); everything :func:`read_state` reports is joint side, converted by the same
:mod:`akarm.control.joints` classes the controller uses.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

from akarm.buses.bus import close_buses, open_bus
from akarm.errors import AkarmError, BusError, StateError, finite_number
from akarm.protocol import mit, servo

if TYPE_CHECKING:
    import can

    from akarm.config import BusConfig, RobotConfig
    from akarm.control.joints import Joint
    from akarm.protocol.motors import MotorModel

__all__ = ["Found", "JointStatus", "Probe", "read_state", "release", "scan", "zero"]

#: Catalogue model whose MIT position range (±12.5 rad, that of nearly every AK model) decodes
#: replies from IDs no configuration describes.
GENERIC_MIT_MODEL = "AK80-9"
_SEND_RETRY = 0.2  # s to keep retrying a frame a full transmit queue refused
_ZERO_READBACK = 0.01  # rad: a servo position read back after SET_ORIGIN_HERE this close to 0 shows it took


@dataclass(frozen=True)
class Found:
    """A motor that answered a :func:`scan`.

    Attributes:
        can_id: the motor's CAN ID.
        mode: ``"mit"`` (answered EXIT with a state reply) or ``"servo"`` (sends ``0x29xx`` status frames).
        position: rad at the output, motor side (before a joint's direction and offset).
        temperature: °C, or ``None`` when the reply has no temperature (6-byte MIT replies).
        error: the motor's error code (0 none; :func:`akarm.protocol.servo.describe_error`), ``None`` if not sent.
        reply_id: arbitration ID the frame came on (MIT: 0 on most units, the motor's own ID on some).
        model: the catalogue model used to decode the position, or ``None`` when none was known
            (MIT: the ±12.5 rad range; servo: degrees taken as output-side degrees).
        active: MIT only: its replies were flowing before anything was sent, i.e. a controller
            is driving it; it was left alone.
        duplicate: two motors answer on this ID: more than one reply to one EXIT (MIT), or status
            frames at two positions (servo).
    """

    can_id: int
    mode: Literal["mit", "servo"]
    position: float
    temperature: float | None
    error: int | None
    reply_id: int
    model: str | None = None
    active: bool = False
    duplicate: bool = False

    def fault_text(self) -> str:
        """The error code with its meaning, e.g. ``"2 over-current"``; ``"-"`` when unknown."""
        return _fault_text(self.error)


@dataclass(frozen=True)
class JointStatus:
    """One configured joint as read from the bus, joint side, SI.

    A joint that did not answer has ``missing = True`` and ``None`` for every measured value.

    Attributes:
        name: the joint. mode: ``"mit"`` or ``"servo"``. bus: its bus name. can_id: its motor's ID.
        position: rad. velocity: rad/s. torque: N·m. temperature: °C (``None`` if the motor does
            not report it). fault: the motor's error code (0 none).
        missing: True when nothing was heard from the joint within the timeout.
        queried: True when the joint was silent and exit frames were sent to read it (MIT: it is
            disabled now, whatever it was before).
        age: how old the reading was when it was reported, s (``None`` when missing, or not known).
    """

    name: str
    mode: str
    bus: str
    can_id: int
    position: float | None
    velocity: float | None
    torque: float | None
    temperature: float | None
    fault: int | None
    missing: bool
    queried: bool = False
    age: float | None = None

    def fault_text(self) -> str:
        """The error code with its meaning, e.g. ``"0 no fault"``; ``"-"`` when missing."""
        return _fault_text(self.fault)

    def as_dict(self) -> dict[str, object]:
        """Plain values for JSON (units in the key names' documentation above)."""
        return {"name": self.name, "mode": self.mode, "bus": self.bus, "can_id": self.can_id,
                "position": self.position, "velocity": self.velocity, "torque": self.torque,
                "temperature": self.temperature, "fault": self.fault,
                "fault_text": None if self.fault is None else servo.describe_error(self.fault)[0],
                "missing": self.missing, "queried": self.queried, "age": self.age}


def _fault_text(code: int | None) -> str:
    if code is None:
        return "-"
    return f"{code} {servo.describe_error(code)[0]}"


def _send(bus: can.BusABC, msg: can.Message, what: str) -> None:
    """Send ``msg``; retry briefly while the transmit queue is full; :class:`BusError` if it stays refused."""
    import can

    end = time.monotonic() + _SEND_RETRY
    while True:
        try:
            bus.send(msg)
            return
        except can.CanError as e:
            if time.monotonic() > end:
                raise BusError(f"cannot send {what}: {e}",
                               fix="check the adapter, cabling and termination, and that the bus is up "
                                   "(ip -details link show)") from None
            time.sleep(0.002)


# ------------------------------------------------------------------------------------------------
# scan
# ------------------------------------------------------------------------------------------------
def _ids(ids: Iterable[int]) -> list[int]:
    out = sorted(set(ids))
    bad = [i for i in out if not 1 <= i <= 255]
    if bad:
        raise AkarmError(f"CAN IDs {bad} are outside 1-255", fix="scan motor IDs 1-255 (e.g. --ids 1-32)")
    if not out:
        raise AkarmError("no CAN IDs to scan", fix="give at least one ID, e.g. --ids 1-32")
    return out


def scan(bus: BusConfig, ids: Iterable[int] = range(1, 128), *, timeout: float = 0.1, listen: float = 0.3,
         models: Mapping[int, MotorModel | str] | None = None) -> list[Found]:
    """Find the motors on one bus: which CAN IDs answer, and in which mode.

    1. Listen for ``listen`` s: servo motors' status frames (long enough for the slowest
       status rate: 0.3 s hears motors at 4 Hz and up), and MIT replies if a controller is running.
    2. Send EXIT to every ID in ``ids`` that was not heard in step 1, then wait ``timeout`` s for
       the MIT replies. A MIT motor that answers is in rest mode afterwards (EXIT keeps a disabled
       motor disabled, and disables an enabled one that no controller was driving).

    Args:
        bus: the bus to scan (opened here, closed before returning).
        ids: CAN IDs to look for (1-255); frames from other IDs are ignored.
        timeout: s to wait for MIT replies after the last EXIT.
        listen: s to listen before sending anything.
        models: catalogue model per CAN ID (e.g. from a robot YAML) to decode positions with.

    Returns:
        One :class:`Found` per (ID, mode) heard, sorted by ID.

    Raises:
        BusError: the bus cannot be opened or written (the message says how to bring it up).
    """
    import can

    sc = _Scan(_ids(ids), models)
    with open_bus(bus) as b:
        sc.read_for(b, listen, passive=True)
        active = {k[0] for k in sc.found if k[1] == "mit"}
        for can_id in sc.wanted:
            if can_id in active:
                continue
            sc.queried.add(can_id)
            _send(b, can.Message(arbitration_id=can_id, data=mit.EXIT, is_extended_id=False),
                  f"EXIT to ID {can_id} on bus {bus.name!r}")
            while (msg := b.recv(timeout=0.0)) is not None:
                sc.handle(msg, passive=False)
        sc.read_for(b, timeout, passive=False)
    return [_with_duplicates(sc.found[k], sc.heard.get(k, [])) for k in sorted(sc.found)]


class _Scan:
    """What a :func:`scan` has heard: the motors found, the IDs queried, the positions per (ID, mode)."""

    def __init__(self, wanted: list[int], models: Mapping[int, MotorModel | str] | None) -> None:
        from akarm.protocol import motors

        self.wanted = wanted
        self.wanted_set = set(wanted)
        self.models = dict(models or {})
        self.generic = motors.get(GENERIC_MIT_MODEL)
        self.codecs: dict[int, mit.MitCodec] = {}
        self.found: dict[tuple[int, str], Found] = {}
        self.queried: set[int] = set()
        self.heard: dict[tuple[int, str], list[float]] = {}  # positions per (ID, mode): two motors show here

    def read_for(self, b: can.BusABC, seconds: float, passive: bool) -> None:
        """Handle what comes in for ``seconds`` s."""
        end = time.monotonic() + max(0.0, seconds)
        while (left := end - time.monotonic()) > 0:
            msg = b.recv(timeout=left)
            if msg is not None:
                self.handle(msg, passive)

    def handle(self, msg: can.Message, passive: bool) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        data = bytes(msg.data)
        if msg.is_extended_id:
            self._servo(msg.arbitration_id, data)
        elif len(data) in (6, 8) and mit.special_frame(data) is None:
            self._mit(msg.arbitration_id, data, passive)

    def _servo(self, arbitration_id: int, data: bytes) -> None:
        from akarm.protocol import motors
        from akarm.protocol.units import servo_deg_to_rad

        if arbitration_id >> 8 != servo.ServoPacket.STATUS or len(data) != 8:
            return
        can_id = arbitration_id & 0xFF
        if can_id not in self.wanted_set:
            return
        st = servo.decode_status(arbitration_id, data)
        m = self.models.get(can_id)
        if m is not None:
            pos, name = servo_deg_to_rad(motors.get(m), st.position_deg), motors.get(m).name
        else:
            pos, name = math.radians(st.position_deg), None
        self.found[(can_id, "servo")] = Found(can_id, "servo", pos, st.temperature_c, st.error, arbitration_id, name)
        self.heard.setdefault((can_id, "servo"), []).append(pos)

    def _mit(self, arbitration_id: int, data: bytes, passive: bool) -> None:
        from akarm.protocol import motors

        can_id = data[0]
        if can_id not in self.wanted_set:
            return
        # Before anything is sent, only frames on the usual reply IDs count (a controller's own
        # commands to a motor are standard frames too); afterwards, any ID the queried motor answers on.
        if (passive and arbitration_id not in (0, can_id)) or (not passive and can_id not in self.queried):
            return
        m = self.models.get(can_id)
        if can_id not in self.codecs:
            self.codecs[can_id] = mit.codec(m if m is not None else self.generic)
        try:
            r = self.codecs[can_id].decode_reply(data)
        except AkarmError:
            return
        self.found[(can_id, "mit")] = Found(can_id, "mit", r.position, r.temperature, r.error, arbitration_id,
                                            motors.get(m).name if m is not None else None, active=passive)
        if not passive:
            self.heard.setdefault((can_id, "mit"), []).append(r.position)


#: rad: consecutive status frames of one ID this far apart, back and forth, come from two motors
_TWO_POSITIONS = 0.05


def _with_duplicates(f: Found, positions: list[float]) -> Found:
    """``f``, marked :attr:`Found.duplicate` when what was heard on its ID shows two motors: more than
    one reply to the one EXIT sent (MIT), or status frames that jump back and forth between two
    positions (servo: a moving motor's frames go one way)."""
    if f.mode == "mit":
        two = len(positions) > 1
    else:
        steps = [b - a for a, b in itertools.pairwise(positions) if abs(b - a) > _TWO_POSITIONS]
        two = sum(1 for a, b in itertools.pairwise(steps) if (a > 0) != (b > 0)) >= 2
    return replace(f, duplicate=True) if two else f


# ------------------------------------------------------------------------------------------------
# reading joints
# ------------------------------------------------------------------------------------------------
class Probe:
    """The configured joints on open buses, without a control loop (a context manager).

    Frames are decoded and converted to joint-side SI by the controller's own
    :class:`akarm.control.joints.Joint` classes and routed by its :class:`akarm.control.joints.Router`.

    Args:
        config: the robot.
        joints: names of the joints to work with (default: all); only their buses are opened.
    """

    def __init__(self, config: RobotConfig, joints: Iterable[str] | None = None) -> None:
        from akarm.control.joints import Router, make_joint

        self.config = config
        names = set(joints) if joints is not None else None
        if names is not None:
            for n in names:
                config.joint(n)  # ConfigError naming the joints when there is no such joint
        # every motor: the arm's joints and the gripper's (its row reads its motor as a joint's)
        self.joints: list[Joint] = [make_joint(i, j) for i, j in enumerate(config.motors)
                                    if names is None or j.name in names]
        self._bus_names = sorted({j.bus for j in self.joints})
        self._routers = {b: Router([j for j in self.joints if j.bus == b]) for b in self._bus_names}
        self._buses: dict[str, can.BusABC] = {}

    def open(self) -> Probe:
        """Open the joints' buses. :class:`BusError` (with how to bring the bus up) if one will not open."""
        if self._buses:
            return self
        try:
            for name in self._bus_names:
                self._buses[name] = open_bus(self.config.buses[name])
        except BaseException:
            self.close()
            raise
        return self

    def close(self) -> None:
        """Close the buses."""
        close_buses(self._buses)

    def __enter__(self) -> Probe:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def joint(self, name: str) -> Joint:
        """The controller-side joint called ``name``."""
        for j in self.joints:
            if j.name == name:
                return j
        self.config.joint(name)  # ConfigError naming the joints
        raise StateError(f"joint {name!r} is not part of this probe", joint=name)

    # -- frames ------------------------------------------------------------------------------
    def send(self, j: Joint, msg: can.Message) -> None:
        """Send ``msg`` on ``j``'s bus."""
        if j.bus not in self._buses:
            raise StateError("the probe's buses are not open", fix="use `with Probe(config) as p:`")
        _send(self._buses[j.bus], msg, f"a frame to joint {j.name!r}")

    def pump(self, until: float, done: Callable[[], bool] | None = None) -> None:
        """Receive and route frames until ``time.monotonic() >= until`` or ``done()`` is true."""
        if not self._buses:
            raise StateError("the probe's buses are not open", fix="use `with Probe(config) as p:`")
        items = list(self._buses.items())
        while True:
            if done is not None and done():
                return
            left = until - time.monotonic()
            if left <= 0:
                return
            for name, bus in items:
                msg = bus.recv(timeout=left if len(items) == 1 else min(left, 0.001))
                if msg is not None:
                    self._routers[name].route(msg, time.monotonic())
                    while (more := bus.recv(timeout=0.0)) is not None:
                        self._routers[name].route(more, time.monotonic())

    def discard(self) -> None:
        """Drop every frame already received (so what follows is fresh)."""
        for bus in self._buses.values():
            while bus.recv(timeout=0.0) is not None:
                pass

    def default_timeout(self) -> float:
        """s :meth:`read_state` waits by default: 0.25, or 2.5 periods of the slowest servo status rate."""
        periods = [2.5 / j.config.status_rate_hz for j in self.joints
                   if j.mode == "servo" and j.config.status_rate_hz > 0]
        return max([0.25, *periods])

    def read_state(self, timeout: float | None = None, listen: float = 0.05) -> list[JointStatus]:
        """Read every joint of the probe once.

        1. Listen ``listen`` s: with a controller running, replies are flowing and nothing is sent.
        2. Send each still-silent MIT joint its exit frames (EXIT; V3: a zero-gain, zero-torque
           command). **A joint queried this way is disabled afterwards** (``queried`` in the result):
           EXIT keeps a disabled motor disabled and disables an enabled one.
        3. Wait for the rest (servo joints: their next status frame) until ``timeout`` s after the
           start (default :meth:`default_timeout`).

        Returns:
            A :class:`JointStatus` per joint, config order; a joint that did not answer has
            ``missing = True`` and ``None`` values.
        """
        from akarm.control.joints import JointState

        t0 = time.monotonic()
        timeout = self.default_timeout() if timeout is None else timeout
        for j in self.joints:
            j.state = JointState()

        def all_heard() -> bool:
            return all(j.state.stamp > -math.inf for j in self.joints)

        self.pump(t0 + max(0.0, min(listen, timeout)), all_heard)
        queried = set()
        for j in self.joints:
            if j.state.stamp == -math.inf:
                for f in j.query_frames():
                    self.send(j, f)
                    queried.add(j.name)
        self.pump(t0 + max(timeout, listen), all_heard)
        return [self._status(j, j.name in queried) for j in self.joints]

    @staticmethod
    def _status(j: Joint, queried: bool) -> JointStatus:
        s = j.state
        c = j.config
        if s.stamp == -math.inf:
            return JointStatus(j.name, j.mode, j.bus, c.can_id, None, None, None, None, None, True, queried)

        def num(x: float) -> float | None:
            return None if x != x else float(x)

        return JointStatus(j.name, j.mode, j.bus, c.can_id, num(s.position), num(s.velocity), num(s.torque),
                           None if s.temperature is None else float(s.temperature), int(s.error), False, queried,
                           max(0.0, time.monotonic() - s.stamp))

    # -- zero and release --------------------------------------------------------------------
    def zero(self, name: str, permanent: bool = False, wait: float = 1.5, timeout: float = 1.0) -> float:
        """Make joint ``name``'s current motor position its zero; return the position read back (rad, ≈ 0).

        MIT (V1/V2): the joint is first sent EXIT (so a motor left enabled cannot jump to its old
        target in the new frame; it must answer, which also shows it is there), then ZERO. The
        driver is off-line for 0.5-1.5 s afterwards: this waits ``wait`` s, then queries it with
        EXIT until it answers (up to ``timeout`` s more). The output is limp meanwhile: support
        the arm, or zero a joint resting at its reference. Whether the firmware keeps the zero
        across power cycles depends on the firmware; ``permanent`` is not used.

        Servo: waits for a status frame, sends SET_ORIGIN_HERE (``permanent``: saved in flash, else
        until power is lost), then reads status frames until one reads within 0.01 rad of 0 (frames
        already on their way show the old origin), or returns the last one read after ``timeout`` s
        (or 2.5 status periods, if longer).

        The value returned is motor side; joint side the joint now reads ``offset`` (± what it
        moved meanwhile).

        Raises:
            ArgumentError: a ``wait`` that is not a finite number ≥ 0 s, a ``timeout`` not one > 0 s
                (nothing is sent).
            AkarmError: the joint does not answer, does not come back, is being driven by a
                controller, or is a MIT V3 board (no zero frame); the message names the joint.
        """
        from akarm.control.joints import JointState

        wait = finite_number(wait, "zero wait", at_least=0.0, unit="s")
        timeout = finite_number(timeout, "zero timeout", above=0.0, unit="s")
        j = self.joint(name)
        c = j.config
        where = f"{j.mode} ID {c.can_id} on bus {j.bus!r}"
        zero_frames = j.zero_frames(permanent)
        if not zero_frames:
            raise AkarmError("MIT V3 boards have no zero frame; akarm cannot zero them", joint=name,
                             fix="set the zero with CubeMars' upper-computer tool")
        j.state = JointState()
        if j.answers_commands:  # MIT: answers when asked; off-line for a while after ZERO
            return self._zero_mit(j, zero_frames, where, wait, timeout)
        return self._zero_servo(j, zero_frames, where, timeout)

    def _zero_mit(self, j: Joint, zero_frames: list[can.Message], where: str, wait: float, timeout: float) -> float:
        """:meth:`zero` of a MIT joint: EXIT (it must answer), ZERO, wait, ask until it answers again."""
        name = j.name
        self.pump(time.monotonic() + 0.05)
        if j.state.stamp > -math.inf:
            raise StateError("a controller is driving it (its replies are flowing); zeroing now would move "
                             "its target", joint=name, fix="stop that controller (akarm disable) first")
        if not self._ask(j, timeout):
            raise AkarmError(f"no answer from its motor ({where}); nothing was zeroed", joint=name,
                             fix="check power, CAN wiring, bit rate and the CAN ID (akarm scan)")
        for frame in zero_frames:
            self.send(j, frame)
        j.rezeroed()
        end = time.monotonic() + max(0.0, wait)
        while time.monotonic() < end:
            self.discard()
            time.sleep(min(0.02, max(0.0, end - time.monotonic())))
        self.discard()
        if not self._ask(j, timeout, every=0.1):
            raise AkarmError(f"its motor ({where}) did not come back {wait + timeout:.1f} s after ZERO",
                             joint=name, fix="wait a moment, then check it with akarm status; power-cycle it "
                                             "if it stays silent")
        return j.motor_position(j.state.position)

    def _zero_servo(self, j: Joint, zero_frames: list[can.Message], where: str, timeout: float) -> float:
        """:meth:`zero` of a servo joint: SET_ORIGIN_HERE, then status frames until one reads about 0."""
        from akarm.control.joints import JointState

        name, c = j.name, j.config
        period = 1.0 / c.status_rate_hz if c.status_rate_hz > 0 else 1.0
        wait_status = max(timeout, 2.5 * period)
        self.pump(time.monotonic() + wait_status, lambda: j.state.stamp > -math.inf)
        if j.state.stamp == -math.inf:
            raise AkarmError(f"no status frame from its motor ({where}) within {wait_status:.2f} s; nothing was "
                             "zeroed", joint=name,
                             fix="check power, CAN wiring, bit rate, the CAN ID and that status frames are on")
        for frame in zero_frames:  # servo: SET_ORIGIN_HERE, then read the status frames back
            self.send(j, frame)
        # Status frames already on their way still show the old origin, and nothing in a status
        # frame says which origin it is relative to: skip a little, then take frames until one
        # reads about 0 (a joint that moves meanwhile reads what it moved: the caller warns).
        time.sleep(min(0.05, 2 * period))
        self.discard()
        end = time.monotonic() + wait_status
        heard = False
        while True:
            j.state = JointState()
            self.pump(end, lambda: j.state.stamp > -math.inf)
            if j.state.stamp == -math.inf:
                break
            heard = True
            p = j.motor_position(j.state.position)
            if abs(p) < _ZERO_READBACK:
                return p
        if not heard:
            raise AkarmError(f"no status frame from its motor ({where}) after setting the origin", joint=name,
                             fix="check it with akarm status")
        return p

    def _ask(self, j: Joint, timeout: float, every: float | None = None) -> bool:
        """Send ``j``'s query frames (again every ``every`` s) until it answers or ``timeout`` s pass."""
        from akarm.control.joints import JointState

        j.state = JointState()
        end = time.monotonic() + timeout
        while True:
            for f in j.query_frames():
                self.send(j, f)
            step = end if every is None else min(end, time.monotonic() + every)
            self.pump(step, lambda: j.state.stamp > -math.inf)
            if j.state.stamp > -math.inf:
                return True
            if time.monotonic() >= end:
                return False

    def release(self, timeout: float | None = None) -> list[JointStatus]:
        """Send every joint the frames that make its output limp, and see who answered.

        MIT: a zero-gain, zero-torque command (replaces the command the driver remembers, so the
        next enable cannot kick) then EXIT. Servo: zero current (the output goes limp; the
        firmware's own timeout releases it fully about 1 s later). For an arm this process did not
        enable there is nothing to damp; an :class:`~akarm.Arm` disables its own joints itself.

        Returns:
            A :class:`JointStatus` per joint (``missing``: no reply, or for servo no status frame, seen).
        """
        from akarm.control.joints import JointState

        t0 = time.monotonic()
        timeout = self.default_timeout() if timeout is None else timeout
        answers = []  # the frame count each joint reaches once it has answered all it was sent
        for j in self.joints:
            j.state = JointState()
            frames = j.release_frames()
            answers.append(j.frames_received + (len(frames) if j.answers_commands else 1))
            for f in frames:
                self.send(j, f)
        # an MIT driver answers every frame, EXIT too: returning on the first reply (to the
        # zero-gain command) could leave a driver not yet out of motor mode
        self.pump(t0 + timeout, lambda: all(j.frames_received >= n for j, n in zip(self.joints, answers, strict=True)))
        return [self._status(j, j.answers_commands) for j in self.joints]


# ------------------------------------------------------------------------------------------------
# one-shot functions
# ------------------------------------------------------------------------------------------------
def read_state(config: RobotConfig, timeout: float | None = None, listen: float = 0.05) -> list[JointStatus]:
    """Each configured joint's position, velocity, torque, temperature and fault (joint side, SI).

    Opens the buses, reads once (see :meth:`Probe.read_state`: silent MIT joints are queried with
    EXIT, which leaves them **disabled**), closes them. A joint that does not answer is reported
    with ``missing = True``, not raised.

    Raises:
        BusError: a bus cannot be opened.
    """
    with Probe(config) as p:
        return p.read_state(timeout, listen)


def zero(config: RobotConfig, joint: str, permanent: bool = False, *, wait: float = 1.5,
         timeout: float = 1.0) -> float:
    """Make ``joint``'s current position its motor's zero; return the motor position read back (rad, ≈ 0).

    See :meth:`Probe.zero`. Only that joint's bus is opened.
    """
    with Probe(config, [joint]) as p:
        return p.zero(joint, permanent, wait=wait, timeout=timeout)


def release(config: RobotConfig, timeout: float | None = None) -> list[JointStatus]:
    """Make every joint limp (MIT: zero-gain command then EXIT; servo: zero current); see :meth:`Probe.release`."""
    with Probe(config) as p:
        return p.release(timeout)

