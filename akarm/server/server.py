"""One long-lived controller that holds the arm, which the CLI, scripts and other machines drive.

:class:`ArmServerCore` claims the robot's buses (a second controller on them is refused), enables
the arm, and holds it. It runs one command at a time on the arm, and serves

- the ``akarm`` CLI of this machine through a Unix socket (:mod:`akarm.server.socket`): ``move``,
  ``enable``, ``disable``, ``status``, ``teach`` and ``replay`` use the server when one runs; each
  request's arguments are checked against its operation's signature first (:mod:`akarm.server.ops`);
- its :class:`Frontend` objects, made from the factories it is given: each gets the server, calls
  its commands (:meth:`~ArmServerCore.follow`, :meth:`~ArmServerCore.enable`, ...), and is started
  once the arm is held and stopped once the server has disabled it.

**Latched stops.** A safety stop (any :class:`~akarm.SafetyStop`: a silent joint, a lost bus, a
collision, also one that refused an enable) latches: every client waiting on a motion, a teach or a
replay gets it (its own class and text, as the Arm would raise it), status and ROS 2 diagnostics
show it, and every motion request from then on is refused with a :class:`~akarm.StopLatched` that
names it (:meth:`ArmServerCore.refuse_if_latched`, which a frontend calls too), so nothing moves.
Only an explicit enable (:meth:`ArmServerCore.enable`: ``akarm enable``, the ``akarm/enable``
service) acknowledges it, and enables through the usual kick-free enable. Errors are raised as new
copies, never the stored one again (a re-raised exception keeps growing its traceback).

Users build :class:`akarm.ArmServer` (:mod:`akarm.serving`), which is this core with the ROS 2
node of :mod:`akarm.ros.node` as its frontend; this layer knows nothing of ROS.

Stopping it (:meth:`ArmServerCore.stop`) damps and disables the arm.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import sys
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from akarm import signals as _signals
from akarm.buses.ownership import BusLock, runtime_dir, sweep_sockets
from akarm.control.gripper import Gripper, GripperState
from akarm.control.modes import Mode
from akarm.errors import AkarmError, ArgumentError, SafetyStop, StateError, StopLatched
from akarm.server import socket as _socket
from akarm.server.ops import Operation
from akarm.server.snapshot import Snapshot, take
from akarm.server.socket import SocketServer
from akarm.server.streaming import DEFAULT_TIMEOUT, TargetStream

if TYPE_CHECKING:
    from akarm.arm import Arm, Motion
    from akarm.motion.servo import Servo

__all__ = ["ArmServerCore", "Frontend", "FrontendFactory", "LatchedStop", "copy_error"]

_E = TypeVar("_E", bound=BaseException)
PROTOCOL = 2  #: the control socket's protocol version (``describe``)
_READ_TIMEOUT = 0.25  # s a disabled arm's joints get to answer a status request (as akarm status's default)
_POLL = 0.02  # s between looks while a request waits (a motion to end, time to pass)
#: What the control socket carries when every connection is busy (one of its reserved connections):
#: what an operator needs to stop the arm and see it, while long requests hold the others.
URGENT_OPERATIONS = frozenset({"disable", "stop", "hold", "status", "state", "snapshot", "describe"})
_STOP_WAIT = 0.5  # s stop() waits for a running command before it disables the arm without it
_STOP_GRACE = 10.0  # s it then waits for that command to end (to disable again after it), at most
_OP = re.compile(r"^[a-z][a-z_]{0,39}$")
_STREAM_POLL = 0.005  # s between the looks of the stream's watchdog (a silent client is seen this late at most)


def copy_error(e: _E) -> _E:
    """A new exception of ``e``'s class with its text and attributes, without its traceback: what to
    raise instead of an exception that is kept (raising the same object again grows its traceback)."""
    new = type(e).__new__(type(e), *e.args)
    vars(new).update(vars(e))
    return new


def _clock_text(t: float) -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(t)) + f".{int(t % 1 * 1000):03d}"


@dataclass(frozen=True)
class LatchedStop:
    """A safety stop the server latched, until an explicit enable acknowledges it.

    Attributes:
        error: the stop (kept, never raised itself: :meth:`copy`).
        time: when the arm stopped, s since the epoch.
        seq: 1 for the first stop the server saw, 2 for the next, ...
    """

    error: SafetyStop
    time: float
    seq: int

    @property
    def name(self) -> str:
        """The stop's error class, e.g. ``"FeedbackTimeout"``."""
        return type(self.error).__name__

    def as_dict(self) -> dict[str, Any]:
        """``error``, ``joint``, ``time`` (s since the epoch), ``text``, ``what`` and ``fix``, for JSON."""
        e = self.error
        return {"error": self.name, "joint": e.joint, "time": self.time, "text": str(e), "what": e.what, "fix": e.fix}

    def copy(self) -> SafetyStop:
        """The stop as a new exception of its class (to raise to a client whose motion it ended)."""
        return copy_error(self.error)

    def refusal(self) -> StopLatched:
        """The error a request refused because of this stop gets (a new one each time)."""
        e = self.error
        return StopLatched(f"refused: the arm stopped for safety at {_clock_text(self.time)} ({self.name}: {e.what}); "
                           "the stop is latched and nothing moves until it is acknowledged", stop=self.name,
                           time=self.time, joint=e.joint,
                           fix=(f"{e.fix}; then " if e.fix else "") + "acknowledge the stop by enabling the arm: "
                               "akarm enable ROBOT.yaml, the akarm/enable service, or ArmServer.enable()")


_OPERATIONS: dict[type, dict[str, Operation]] = {}


def _operations(cls: type) -> dict[str, Operation]:
    """The control socket's operations of ``cls``: its ``_op_NAME`` methods (read once per class)."""
    ops = _OPERATIONS.get(cls)
    if ops is None:
        ops = _OPERATIONS[cls] = {name[4:]: Operation(name[4:], getattr(cls, name)) for name in dir(cls)
                                  if name.startswith("_op_")}
    return ops


class Frontend(Protocol):
    """Another way in to a server (the ROS 2 node): it drives the server's commands from threads of
    its own between :meth:`start` and :meth:`stop`."""

    def start(self) -> None:
        """Start serving (the arm is held by now)."""

    def stop(self) -> None:
        """Stop serving and let go of what it holds. The server calls it when it stops, once the arm
        is disabled and before its socket closes; also when it failed to start (maybe before
        :meth:`start`)."""


#: Makes a server's frontend, for the server, when the server starts: before anything is opened or
#: enabled, so that a frontend that cannot be made (a missing extra, a bad name) is said then.
FrontendFactory = Callable[["ArmServerCore"], Frontend]

_Server = TypeVar("_Server", bound="ArmServerCore")



def _check_row(k: int, row: Sequence[float], joint_names: Sequence[str], what: str, unit: str, or_none: str) -> None:
    """Point ``k``'s ``row`` of ``what`` (one per joint name, finite), else ArgumentError naming the
    point, and the joint and value that is not a number."""
    if len(row) != len(joint_names):
        plural = "velocities" if what == "velocity" else what + "s"
        raise ArgumentError(f"point {k} has {len(row)} {plural} for {len(joint_names)} joint_names",
                            fix=f"give one {what} ({unit}) per name in joint_names{or_none}")
    for name, x in zip(joint_names, row, strict=True):
        if not math.isfinite(x):
            raise ArgumentError(f"point {k}: {what} {x} is not a number", joint=name,
                                fix=f"give a finite {what} in {unit}")


class ArmServerCore:
    """Serves ``arm`` to the CLI (local socket) and to its frontends until :meth:`stop`.

    Args:
        arm: the arm; opened here if it is not open yet (and then closed by :meth:`stop`). It must
            run on the wall clock (a lock-step simulation has nobody to advance its time).
        frontends: factories of the other ways in (:data:`FrontendFactory`), called by :meth:`start`.
        enable: enable (without a kick) and hold when starting.
        log: where the server's one-line reports go (default: stderr).
        about: what else the bus lock says about this server, for whoever reads it (the ROS 2
            domain and namespace).
    """

    def __init__(self, arm: Arm, *, frontends: Sequence[FrontendFactory] = (), enable: bool = True,
                 log: Callable[[str], None] | None = None, about: Mapping[str, Any] | None = None) -> None:
        if arm.clock.stepped:
            raise StateError("akarm serve needs an arm on the wall clock, not a lock-step simulation",
                             fix="build the Arm without clock= (a simulator in its own process works)")
        self.arm = arm
        self._frontend_factories = tuple(frontends)
        self._about = dict(about or {})
        self._enable_at_start = enable
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self._cmd = threading.RLock()  # one command at a time reaches the arm
        self._stop = threading.Event()
        self._motions: OrderedDict[int, tuple[Motion, int]] = OrderedDict()  # id → (motion, stops seen before it)
        self._next_id = 0
        self._teaching = False
        self._servo: Servo | None = None  # the control socket's servoing session (servo_twist), if any
        self._teacher: int | None = None  # the control connection that started teach mode (None: ROS, Python)
        self._teach_seq = 0  # stops seen before teach mode began
        self._opened_arm = False
        self._lock: BusLock | None = None
        self._socket: SocketServer | None = None
        self._frontends: list[Frontend] = []
        self.socket_path = runtime_dir() / f"serve-{os.getpid()}-{id(self):x}.sock"
        self.last_refusal = ""
        self.counts = {"accepted": 0, "refused": 0}
        self._latch_lock = threading.Lock()
        self._latched: LatchedStop | None = None
        self._last_stop: LatchedStop | None = None  # the latest stop, acknowledged or not
        self._stop_seq = 0
        self._seen: tuple[object, ...] = ()  # the arm's fault and last collision as last seen
        # every stop latched, acknowledged or raised to a client as a copy: none is latched (again) later
        # (an old motion's stop waited for after its acknowledgement; a copy a request reported)
        self._known: weakref.WeakSet[BaseException] = weakref.WeakSet()
        self._refusals_logged = (0.0, 0)  # when a refusal was last logged, and how many since
        self._stream: TargetStream | None = None  # a client's stream of targets (the ``stream`` operation)

    # ------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------
    def start(self: _Server) -> _Server:
        """Claim the buses, make the frontends, open and enable the arm, start serving. Raises on any
        failure, leaving the arm as it was (disabled) and the buses free."""
        sweep_sockets()  # of servers killed before they could remove them
        source = self.arm.config.source
        self._lock = BusLock(self.arm.config, {"robot": str(source) if source else self.arm.config.name,
                                               "socket": str(self.socket_path), **self._about})
        try:
            for make in self._frontend_factories:  # first: a frontend that cannot be made is said before
                self._frontends.append(make(self))  # anything is enabled (a missing extra, a bad name)
            if self.arm.mode is Mode.CLOSED:
                self.arm.open()
                self._opened_arm = True
            self._update_latch()  # a stop from before (a script's arm): latched, unless enabled now
            if self._enable_at_start:
                self.enable()
            self._socket = SocketServer(self.socket_path, self.dispatch, closed=self._client_left, log=self.log,
                                        urgent=URGENT_OPERATIONS)
            threading.Thread(target=self._watch_stops, name="akarm-serve-faults", daemon=True).start()
            threading.Thread(target=self._watch_stream, name="akarm-serve-stream", daemon=True).start()
            for frontend in self._frontends:
                frontend.start()
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        """Damp and disable the arm (first: at once), stop serving, close the arm if the server opened
        it, free the buses. Commands that arrive meanwhile are refused."""
        self._stop.set()
        held = False
        try:
            # no signal cuts the damping short
            with _signals.deferred(), contextlib.suppress(AkarmError), self._fresh_errors():
                held = self._cmd.acquire(timeout=_STOP_WAIT)
                if not held:
                    # a command is still being carried out (a long plan being made; a file that is slow to
                    # read): the motors are not left powered for it; the arm is disabled again after it
                    self.log(f"akarm serve: a request still runs after {_STOP_WAIT:g} s; disabling the arm now")
                    self.arm.disable()
                    held = self._cmd.acquire(timeout=_STOP_GRACE)
                if held:
                    self._end_teach()
                self.arm.disable()
        finally:
            if held:
                self._cmd.release()
            frontends, self._frontends = self._frontends, []
            for frontend in frontends:
                frontend.stop()
            sock, self._socket = self._socket, None
            if sock is not None:
                sock.close()
            if self._opened_arm:
                self.arm.close()
                self._opened_arm = False
            if self._lock is not None:
                self._lock.release()
                self._lock = None

    def _watch_stops(self) -> None:
        """Latch (and say) a safety stop soon after it happens, whether or not a client is asking."""
        while not self._stop.wait(0.05):
            self._update_latch()

    def _watch_stream(self) -> None:
        """Bring the arm to a hold when a client streaming targets goes silent (:meth:`TargetStream.check`)."""
        while not self._stop.wait(_STREAM_POLL):
            stream = self._stream
            if stream is None or stream.last is None:
                continue
            with self.try_command() as free:
                if free and stream is self._stream:
                    with contextlib.suppress(AkarmError), self._fresh_errors():
                        stream.check()

    def __enter__(self: _Server) -> _Server:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def request_stop(self) -> None:
        """Make :meth:`wait` return (from a signal handler or another thread)."""
        self._stop.set()

    def wait(self, timeout: float | None = None, signals: bool = True) -> bool:
        """Serve until :meth:`request_stop` (and, with ``signals`` in the main thread, SIGINT or
        SIGTERM). True when stopping was requested, False on ``timeout``."""
        previous: dict[signal.Signals, Any] = {}
        if signals and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, lambda signum, frame: self._stop.set())
        try:
            return self._stop.wait(timeout)
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)

    # ------------------------------------------------------------------------------------------
    # latched stops
    # ------------------------------------------------------------------------------------------
    def _update_latch(self) -> None:
        """Latch a safety stop of the arm (its fault, or a collision with the "hold" reaction) not seen before."""
        arm = self.arm
        now = (arm.fault, arm.last_collision)
        with self._latch_lock:
            for e in now:
                if e is not None and not any(e is seen for seen in self._seen):
                    self._latch(e)
            self._seen = now

    def _latch(self, e: SafetyStop) -> None:
        """(Under the latch lock) latch ``e``, and say so, unless the server knows it already."""
        if e in self._known:
            return
        self._known.add(e)
        e.with_traceback(None)  # kept: let its frames go
        at = getattr(e, "at", None)
        t = time.time() - max(0.0, self.arm.clock.now() - at) if isinstance(at, float) and math.isfinite(at) \
            else time.time()
        self._stop_seq += 1
        self._latched = self._last_stop = LatchedStop(e, t, self._stop_seq)
        self.log(f"akarm serve: safety stop ({type(e).__name__}) at {_clock_text(t)}: {e}; latched: nothing moves "
                 "until it is acknowledged (akarm enable, the akarm/enable service, ArmServer.enable())")

    @property
    def latched(self) -> LatchedStop | None:
        """The safety stop latched now (``None``: none, or acknowledged)."""
        self._update_latch()
        return self._latched

    def refuse_if_latched(self) -> None:
        """Raise a new :class:`~akarm.StopLatched` naming the latched stop, if one is: what every
        frontend calls before it starts a motion (nothing may move until an explicit enable)."""
        stop = self.latched
        if stop is not None:
            raise stop.refusal()

    def _raise_stop_since(self, seq: int) -> None:
        """Raise (a copy of) the latest stop if it came after the ``seq``-th: it ended what began then."""
        self._update_latch()
        stop = self._last_stop
        if stop is not None and stop.seq > seq:
            raise self._copy(stop.error)

    def _copy(self, e: SafetyStop) -> SafetyStop:
        """A copy of the stop ``e`` to raise to a client, known to the server (never latched itself)."""
        new = copy_error(e)
        with self._latch_lock:
            self._known.add(new)
        return new

    @contextlib.contextmanager
    def _fresh_errors(self) -> Iterator[None]:
        """A safety stop raised inside (the arm's stored fault, raised again) is latched, and leaves as a copy."""
        try:
            yield
        except SafetyStop as e:
            with self._latch_lock:
                self._latch(e)  # an enable refused, or a fault not latched yet
                self._seen = (*self._seen, e)
            e.with_traceback(None)
            raise self._copy(e) from None

    # ------------------------------------------------------------------------------------------
    # what the arm is doing
    # ------------------------------------------------------------------------------------------
    @property
    def mode(self) -> str:
        """``holding``, ``moving``, ``teach``, ``disabled`` or ``fault`` (a safety stop is latched)."""
        arm = self.arm
        if self.latched is not None:
            return "fault"
        if self._teaching or arm.mode is Mode.TEACH:
            return "teach"
        if not arm.enabled:
            return "disabled"
        return "moving" if arm.moving else "holding"

    def status(self) -> dict[str, Any]:
        """Mode, the latched stop, loop statistics, the oldest feedback, the last refused command, for
        ``akarm/status`` and the ``status`` operation."""
        stop = self.latched
        state = self.arm.state()
        doc: dict[str, Any] = {
            "mode": self.mode, "fault": str(stop.error) if stop else "",
            "stop_error": stop.name if stop else "", "stop_joint": (stop.error.joint or "") if stop else "",
            "stop_time": _clock_text(stop.time) if stop else "",
            "feedback_age_max_ms": round(max((j.age for j in state.joints), default=0.0) * 1e3, 1),
            "last_refusal": self.last_refusal, **{f"trajectories_{k}": v for k, v in self.counts.items()}}
        with contextlib.suppress(AkarmError):
            s = self.arm.stats()
            doc.update(loop_rate_hz=round(s.rate, 1), missed_slots=s.missed, late_p99_us=round(s.late_p99 * 1e6, 1),
                       compute_p99_us=round(s.compute_p99 * 1e6, 1))
        return doc

    # ------------------------------------------------------------------------------------------
    # commands (from the CLI socket and from the frontends)
    # ------------------------------------------------------------------------------------------
    def _require_serving(self) -> None:
        if self._stop.is_set():
            raise StateError("akarm serve is stopping: the arm is being disabled", fix="start the server again")

    def enable(self, accept_position: bool = False) -> None:
        """Acknowledge a latched stop, if any, and enable the arm without a kick (it is then held).
        A stop that refuses the enable is latched in its place. ``accept_position``: skip the turn
        check once (see :meth:`akarm.Arm.enable`)."""
        with self._cmd:
            self._require_serving()
            with self._fresh_errors():
                self._end_teach()
                self._update_latch()
                with self._latch_lock:
                    acknowledged, self._latched = self._latched, None
                if acknowledged is not None:
                    self.log(f"akarm serve: the safety stop of {_clock_text(acknowledged.time)} "
                             f"({acknowledged.name}) is acknowledged; enabling")
                self._stream = None
                self.arm.enable(accept_position=accept_position)

    def disable(self) -> None:
        """Damp, then disable the arm (it is limp). A latched stop stays latched."""
        with self._cmd, self._fresh_errors():
            self._stream = None
            self._end_teach()
            self.arm.disable()

    def hold(self) -> None:
        """Come to rest and hold (ending teach mode); refused while a stop is latched (it names the stop)."""
        with self._cmd, self._fresh_errors():
            self._stream = None
            if self._teaching:
                self._end_teach()
                return
            self.refuse_if_latched()
            self.arm.hold()

    def _end_teach(self) -> None:
        if self._teaching:
            self._teaching = False
            self._teacher = None
            with contextlib.suppress(AkarmError):
                self.arm.stop_recording()
            self.arm.end_teach()

    def _require_commandable(self) -> None:
        self._require_serving()
        self.refuse_if_latched()
        if self._teaching:
            raise StateError("the arm is in teach mode", fix="end teaching first (akarm/hold, or finish akarm teach)")
        if not self.arm.enabled:
            raise StateError("the arm is disabled", fix="enable it first (akarm enable, or the akarm/enable service)")

    def check_motion_allowed(self) -> None:
        """Raise what refuses a motion request now (a safety stop no enable has acknowledged, a disabled
        arm, teach mode, the server stopping); return if one would be taken. Frontends call it before
        they accept a request (the FollowJointTrajectory action, for its goals)."""
        with self._cmd:
            self._require_commandable()

    @contextlib.contextmanager
    def try_command(self) -> Iterator[bool]:
        """Hold the command lock inside if it is free now (yields True), without waiting for it (False:
        another command has it, an enable or a disable for as long as it takes). The server's commands
        called inside (:meth:`check_motion_allowed`, :meth:`follow`) then never wait. For a frontend's
        thread that must not stop (the ROS 2 node's, which publishes ``joint_states``): it tries again later."""
        free = self._cmd.acquire(blocking=False)
        try:
            yield free
        finally:
            if free:
                self._cmd.release()

    def _register(self, motion: Motion, seq: int) -> int:
        self._next_id += 1
        self._motions[self._next_id] = (motion, seq)
        while len(self._motions) > 16:
            self._motions.popitem(last=False)
        return self._next_id

    def follow(self, joint_names: Sequence[str], times: Sequence[float], positions: Sequence[Sequence[float]],
               velocities: Sequence[Sequence[float]] | None = None) -> Motion | None:
        """A ROS 2 ``JointTrajectory`` with the semantics of ros2_control's JointTrajectoryController
        topic: joints matched by name (a subset is allowed; the others keep their commanded
        position), each point reached at its time, jerk-limited; no points stops the arm; a new
        one replaces the running one smoothly. A bad message is refused whole (ArgumentError; a point past
        a limit: LimitError; a latched stop: StopLatched) and nothing moves. Returns the motion (None for a stop)."""
        try:
            with self._cmd, self._fresh_errors():
                self._require_commandable()
                self._stream = None
                if len(times) == 0:
                    self.arm.stop(wait=False)
                    return None
                names = list(self.arm.names)
                unknown = [n for n in joint_names if n not in names]
                if unknown or len(set(joint_names)) != len(joint_names) or not joint_names:
                    raise ArgumentError(f"joint_names {list(joint_names)} must be distinct joints of this arm",
                                        fix="joints are: " + ", ".join(names))
                index = [names.index(n) for n in joint_names]
                full = np.full((len(times), len(names)), math.nan)
                vel = None
                for k, p in enumerate(positions):
                    _check_row(k, p, joint_names, "position", "rad", "")
                    full[k, index] = p
                if velocities is not None and any(len(v) for v in velocities):
                    vel = np.full((len(times), len(names)), math.nan)
                    for k, v in enumerate(velocities):
                        _check_row(k, v, joint_names, "velocity", "rad/s", ", or none at all")
                        vel[k, index] = v
                motion = self.arm.follow(list(times), full, vel, wait=False)
                self.counts["accepted"] += 1
                return motion
        except AkarmError as e:
            self.note_refusal(e)
            raise

    def note_refusal(self, e: AkarmError) -> None:
        """Count and report a refused trajectory (in ``akarm/status``: ``trajectories_refused``,
        ``last_refusal``): a line now, or (a flood of them) one a second with the count. :meth:`follow`
        and :meth:`refuse` call it; a frontend, for what it refuses itself (a goal that
        :meth:`check_motion_allowed` refused)."""
        self.counts["refused"] += 1
        self.last_refusal = str(e)
        last, quiet = self._refusals_logged
        now = time.monotonic()
        if now - last < 1.0:
            self._refusals_logged = (last, quiet + 1)
            return
        more = f" ({quiet} more refused in the last second)" if quiet else ""
        self.log(f"akarm serve: refused a trajectory, nothing moved: {e}{more}")
        self._refusals_logged = (now, 0)

    def refuse(self, what: str, fix: str = "") -> None:
        """Refuse a trajectory the caller found unusable: counted, reported, raised as ArgumentError."""
        e = ArgumentError(what, fix=fix)
        self.note_refusal(e)
        raise e

    # -- the CLI's operations (JSON in, JSON out) --------------------------------------------------
    def dispatch(self, op: str, args: dict[str, Any], client: int | None = None) -> Any:
        """Run a control-socket operation (see :mod:`akarm.cli.served` for the client side) for the
        control connection ``client``, once its arguments are checked against it (an
        :class:`~akarm.ArgumentError` names the first that is missing, unknown or of the wrong type)."""
        ops = _operations(type(self))
        operation = ops.get(op) if isinstance(op, str) and _OP.match(op) else None
        if operation is None:
            raise ArgumentError(f"unknown server operation {str(op)[:40]!r}",
                                fix="is the CLI the same akarm version as the server? operations: " + ", ".join(ops))
        kwargs = operation.check(args)
        handler = getattr(self, f"_op_{op}")
        if "client" in handler.__code__.co_varnames[:handler.__code__.co_argcount]:
            kwargs["client"] = client
        with self._fresh_errors():
            return handler(**kwargs)

    def _client_left(self, client: int) -> None:
        """A control connection ended: teach mode it started ends with it (the client was killed, hung
        up, or lost its terminal without ending it): the arm holds where the hand left it."""
        with self._cmd:
            if self._teaching and self._teacher == client:
                with contextlib.suppress(AkarmError), self._fresh_errors():
                    self._end_teach()
                self.log("akarm serve: the client that started teach mode left without ending it; "
                         "teach mode ended, the arm holds where it was left")

    def _gone(self, client: int | None) -> bool:
        sock = self._socket
        return client is not None and sock is not None and sock.gone(client)

    def _state_doc(self, read: bool = False) -> dict[str, Any]:
        with self._cmd:  # no enable begins while a disabled arm's joints are asked
            asked = read and not self.arm.enabled
            s = self.arm.read_state(_READ_TIMEOUT) if asked else self.arm.state()
        cfg = self.arm.config
        stop = self.latched
        return {"names": list(self.arm.names), "modes": [j.mode for j in cfg.joints],
                "buses": [j.bus for j in cfg.joints], "can_ids": [j.can_id for j in cfg.joints],
                "q": s.q.tolist(), "dq": s.dq.tolist(), "tau": s.tau.tolist(),
                "temperature": [j.temperature for j in s.joints], "fault": [j.fault for j in s.joints],
                "age": [j.age for j in s.joints], "time": time.time(), "asked": asked,
                "enabled": s.enabled, "moving": s.moving, "mode": self.mode,
                "stop": stop.as_dict() if stop else None,
                "robot": cfg.name, "pid": os.getpid(), "rate_hz": cfg.rate_hz,
                # the gripper's reading too (None without one): a client sampling the arm (a LeRobot
                # observation) needs both in one round trip
                "gripper": _gripper_doc(self.arm.gripper.state()) if self.arm.gripper is not None else None}

    def _op_describe(self) -> dict[str, Any]:
        """The protocol: its version, each operation with its arguments, the socket's limits."""
        return {"protocol": PROTOCOL, "ops": {name: op.describe() for name, op in _operations(type(self)).items()},
                "limits": {"connections": _socket.MAX_CONNECTIONS, "request_bytes": _socket.MAX_REQUEST_BYTES,
                           "request_seconds": _socket.REQUEST_TIMEOUT, "idle_seconds": _socket.IDLE_TIMEOUT,
                           "reserved_connections": _socket.RESERVED_CONNECTIONS,
                           "urgent_ops": sorted(URGENT_OPERATIONS)}}

    def _op_state(self, read: bool = True) -> dict[str, Any]:
        """Every joint's reading with its age; a disabled arm's joints are asked first (``read``)."""
        return self._state_doc(read)

    def _op_status(self) -> dict[str, Any]:
        return {**self.status(), "stop": stop.as_dict() if (stop := self.latched) else None}

    def snapshot(self) -> Snapshot:
        """The arm now, for a live view (:mod:`akarm.server.snapshot`): read only, any thread."""
        return take(self.arm, mode=self.mode)

    def _op_snapshot(self) -> dict[str, Any]:
        return self.snapshot().to_doc()

    def _op_enable(self, accept_position: bool = False) -> dict[str, Any]:
        self.enable(accept_position is True)
        return self._state_doc()

    def _op_ready(self) -> dict[str, Any]:
        """Before a motion or teach mode: refused while a stop is latched; a disabled arm (``akarm
        disable``) is enabled, as the verb would enable it without a server."""
        with self._cmd:
            self._require_serving()
            self.refuse_if_latched()
            if not self.arm.enabled:
                self.enable()
        return self._state_doc()

    def _op_disable(self) -> None:
        self.disable()

    def _op_hold(self) -> None:
        self.hold()

    def _op_stop(self) -> None:
        with self._cmd:
            self._stream = None
            if self.arm.enabled and self.arm.moving:
                self.arm.stop(wait=False)
        for m, _ in list(self._motions.values()):
            with contextlib.suppress(AkarmError), self._fresh_errors():
                m.wait()

    def _op_servo_twist(self, twist: list[float], timeout: float = 0.1, frame: str = "base") -> dict[str, Any]:
        return self.servo_twist(twist, timeout, frame)

    def servo_twist(self, twist: Sequence[float], timeout: float = 0.1, frame: str = "base") -> dict[str, Any]:
        """Servo the tool by a twist (``arm.servo()``; the control socket's ``servo_twist``, ROS 2's
        ``servo/twist``): the first command starts a session that later ones go on (another timeout or
        frame starts a new one); commands that stop for ``timeout`` s bring the arm to rest, holding; a
        motion, a stop or ``servo_stop`` ends the session. Returns the status."""
        with self._cmd:
            self._require_commandable()
            s = self._servo
            live = s is not None and s.motion is not None and not s.motion.done
            if s is None or not live or (s.stream.timeout, s.stream.frame) != (timeout, frame):
                if s is not None and live:
                    s.__exit__(None, None, None)
                s = self.arm.servo(timeout=timeout, frame=frame)
                s.__enter__()
                self._servo = s
            s.twist(twist)
            st = s.status
            return {"state": st.state, "reason": st.reason, "scale": st.scale, "joint": st.joint}

    def _op_servo_stop(self) -> None:
        """End the control socket's servoing session: the arm comes to rest, jerk-limited, and holds."""
        with self._cmd:
            s, self._servo = self._servo, None
            if s is not None and s.motion is not None and not s.motion.done:
                s.__exit__(None, None, None)

    def _motion_doc(self, motion: Motion, seq: int) -> dict[str, Any]:
        return {"id": self._register(motion, seq), "duration": motion.duration, "t0": motion.plan.t0,
                "target": motion.plan.sample(motion.plan.t_end)[0].tolist()}

    def _op_move(self, target: str | list[float] | Mapping[str, float], speed: float = 1.0) -> dict[str, Any]:
        with self._cmd:
            self._require_commandable()
            self._stream = None
            return self._motion_doc(self.arm.move_to(target, speed=speed, wait=False), self._stop_seq)

    def _gripper(self) -> Gripper:
        g = self.arm.gripper
        if g is None:
            raise StateError(f"robot {self.arm.config.name!r} has no gripper",
                             fix="describe one under `gripper:` in the robot file (docs/gripper.md)")
        return g

    def _op_gripper_state(self) -> dict[str, Any]:
        """The gripper now: width (m), velocity (m/s), force (N), grasped, target (m), moving, temperature (°C)."""
        return _gripper_doc(self._gripper().state())

    def _op_gripper_move(self, width: float, force: float | None = None, wait: bool = True,
                         client: int | None = None) -> dict[str, Any]:
        """Move the gripper's jaws ``width`` m apart, pressing with at most ``force`` N (``None``: half its
        limit); ``wait``: until it reached the width or grasped (a safety stop meanwhile is raised)."""
        g = self._gripper()
        with self._cmd:
            self._require_commandable()
            seq = self._stop_seq
            g.move_to(width, force, wait=False)
        while wait and g.state().moving:
            self._require_serving()
            self._raise_stop_since(seq)
            if self._gone(client):  # nobody to answer: stop waiting (the move goes on)
                break
            time.sleep(_POLL)
        if wait:
            self._raise_stop_since(seq)
        return _gripper_doc(g.state())

    def _op_wait(self, id: int, client: int | None = None) -> dict[str, Any]:
        """Wait for a motion to end: its safety stop raised (a copy), or whether it was superseded."""
        entry = self._motions.get(id)
        if entry is None:
            raise StateError(f"no motion {id} on this server")
        motion, seq = entry
        while not motion.done:
            self._require_serving()
            if self._gone(client):  # nobody to answer: stop waiting (the motion goes on)
                return {"superseded": False, "q": []}
            time.sleep(_POLL)
        motion.wait()  # its stop, or what cut it short (a collision with the "hold" reaction)
        if motion.superseded:
            self._raise_stop_since(seq)  # ended by a stop that was acknowledged meanwhile
        return {"superseded": motion.superseded, "q": self.arm.state().q.tolist()}

    def _op_sleep(self, seconds: float, client: int | None = None) -> None:
        """Let ``seconds`` pass with the arm held; a safety stop meanwhile (or latched already) is raised."""
        if seconds < 0:
            raise ArgumentError(f"argument 'seconds' of 'sleep' must not be negative, got {seconds}")
        seq = self._stop_seq
        stop = self.latched
        if stop is not None:
            raise self._copy(stop.error)
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            time.sleep(min(_POLL, left))
            self._raise_stop_since(seq)
            self._require_serving()
            if self._gone(client):
                return

    def _op_teach(self, damping: float = 0.1, client: int | None = None) -> None:
        with self._cmd:
            self._require_commandable()
            self._stream = None
            self.arm.teach(damping)
            self._teaching = True
            self._teacher = client
            self._teach_seq = self._stop_seq

    def _teach_ok(self) -> None:
        """What teach mode's operations check first: a stop since teach mode began ended it (raised)."""
        self._raise_stop_since(self._teach_seq)

    def _op_keyframe(self, name: str | None = None) -> list[float]:
        self._teach_ok()
        return list(self.arm.keyframe(name).q)

    def _op_start_recording(self, rate: float, seconds: float | None = None) -> None:
        self._teach_ok()
        self.arm.start_recording(rate, seconds)

    def _op_recording_finished(self) -> bool:
        self._teach_ok()
        return self.arm.recording_finished

    def _op_stop_recording(self) -> dict[str, Any]:
        rec = self.arm.stop_recording()
        return {"names": list(rec.joint_names), "t": rec.t.tolist(), "q": rec.q.tolist()}

    def _op_end_teach(self) -> None:
        with self._cmd:
            self._end_teach()

    def _op_replay(self, path: str, speed: float = 1.0) -> dict[str, Any]:
        from akarm.motion.recording import Keyframes

        # read and checked first, outside the command lock: a file that is slow to read (a large one, a
        # FIFO, a slow disk) keeps no other request, nor the server's stop, waiting
        self._require_serving()
        rec = self.arm.check_replay(path, speed)
        with self._cmd:
            self._require_commandable()
            self._stream = None
            doc = self._motion_doc(self.arm.replay(rec, speed=speed, wait=False), self._stop_seq)
        doc["kind"] = f"{len(rec.frames)} keyframes" if isinstance(rec, Keyframes) else f"a {rec.duration:.2f} s path"
        return doc

    def _op_stream(self, target: list[float | None] | Mapping[str, float | None], partial: bool = False,
                   gripper: float | None = None, timeout: float = DEFAULT_TIMEOUT,
                   speed: float = 1.0, lead: bool = True) -> dict[str, Any]:
        """Stream a target (a policy's action) into the loop: :class:`~akarm.server.streaming.TargetStream`'s
        rules (clamped to the range and counted; a target that is not a number (``null``), an unknown or a
        missing joint (unless ``partial``) refused, the arm brought to a hold; a client silent for
        ``timeout`` s leaves the arm decelerating to a hold; moving targets led by their braking distance
        unless ``lead`` is false). ``gripper``: its width, m. Another command
        (move, hold, stop, a trajectory, teach, enable, disable) ends the stream."""
        with self._cmd:
            self._require_commandable()
            stream = self._stream
            if stream is None or (stream.timeout, stream.speed, stream.lead) != (timeout, speed, lead):
                stream = self._stream = TargetStream(self.arm, timeout=timeout, speed=speed, log=self.log, lead=lead)
            try:
                report = stream.send(target, partial=partial, gripper=gripper)
            except ArgumentError as e:
                self.note_refusal(e)
                raise
        return {**report.as_dict(), "refused_total": stream.refused, "sent_total": stream.sent}

    def _op_check_replay(self, path: str, speed: float = 1.0) -> None:
        self.arm.check_replay(path, speed)

    def _op_telemetry(self, since: float, save: str | None = None) -> dict[str, Any]:
        log = self.arm.telemetry(since=since)
        return {"rms": log.rms_error().tolist(), "path": str(log.save(save)) if save else None}


def _gripper_doc(s: GripperState) -> dict[str, Any]:
    """A gripper state as JSON (``None`` for what is not known: JSON has no NaN)."""
    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {"width": num(s.width), "velocity": num(s.velocity), "force": num(s.force), "grasped": s.grasped,
            "target": num(s.target), "moving": s.moving, "temperature": num(s.temperature)}
