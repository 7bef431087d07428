"""One long-lived controller that holds the arm, which the CLI, scripts and other machines drive.

:class:`ArmServerCore` claims the robot's buses (a second controller on them is refused), enables
the arm, and holds it. It runs one command at a time on the arm, and serves

- the ``akarm`` CLI of this machine through a Unix socket (:mod:`akarm.server.socket`): ``move``,
  ``enable``, ``disable``, ``status``, ``teach`` and ``replay`` use the server when one runs;
- its :class:`Frontend` objects, made from the factories it is given: each gets the server, calls
  its commands (:meth:`~ArmServerCore.follow`, :meth:`~ArmServerCore.enable`, ...), and is started
  once the arm is held and stopped once the server has disabled it.

Users build :class:`akarm.ArmServer` (:mod:`akarm.serving`), which is this core with the ROS 2
node of :mod:`akarm.ros.node` as its frontend; this layer knows nothing of ROS.

Stopping it (:meth:`ArmServerCore.stop`) damps and disables the arm.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from akarm import signals as _signals
from akarm.buses.ownership import BusLock, runtime_dir, sweep_sockets
from akarm.control.modes import Mode
from akarm.errors import AkarmError, ArgumentError, StateError
from akarm.server.socket import SocketServer

if TYPE_CHECKING:
    from akarm.arm import Arm, Motion

__all__ = ["ArmServerCore", "Frontend", "FrontendFactory"]


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
        self._motions: OrderedDict[int, Motion] = OrderedDict()
        self._next_id = 0
        self._teaching = False
        self._teacher: int | None = None  # the control connection that started teach mode (None: ROS, Python)
        self._opened_arm = False
        self._lock: BusLock | None = None
        self._socket: SocketServer | None = None
        self._frontends: list[Frontend] = []
        self.socket_path = runtime_dir() / f"serve-{os.getpid()}-{id(self):x}.sock"
        self.last_refusal = ""
        self.counts = {"accepted": 0, "refused": 0}

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
            if self._enable_at_start:
                self.arm.enable()
            self._socket = SocketServer(self.socket_path, self.dispatch, closed=self._client_left)
            threading.Thread(target=self._report_faults, name="akarm-serve-faults", daemon=True).start()
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
        try:
            with _signals.deferred(), self._cmd, contextlib.suppress(AkarmError):  # no signal cuts the damping short
                self._end_teach()
                self.arm.disable()
        finally:
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

    def _report_faults(self) -> None:
        """Say so when the arm stops for safety (it is then damped and disabled; the server goes on)."""
        reported = None
        while not self._stop.wait(0.1):
            fault = self.arm.fault
            if fault is not None and fault is not reported:
                self.log(f"akarm serve: safety stop: {fault}; enable the arm again with akarm enable or the "
                         "akarm/enable service")
            reported = fault

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
    # what the arm is doing
    # ------------------------------------------------------------------------------------------
    @property
    def mode(self) -> str:
        """``holding``, ``moving``, ``teach``, ``disabled`` or ``fault``."""
        arm = self.arm
        if arm.fault is not None:
            return "fault"
        if self._teaching or arm.mode is Mode.TEACH:
            return "teach"
        if not arm.enabled:
            return "disabled"
        return "moving" if arm.moving else "holding"

    def status(self) -> dict[str, Any]:
        """Mode, fault text, loop statistics and the last refused command, for ``akarm/status``."""
        doc: dict[str, Any] = {"mode": self.mode, "fault": str(self.arm.fault) if self.arm.fault else "",
                               "last_refusal": self.last_refusal, **{f"trajectories_{k}": v for k, v in
                                                                     self.counts.items()}}
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
        """Enable the arm (``accept_position``: skip the turn check once, see :meth:`akarm.Arm.enable`)."""
        with self._cmd:
            self._require_serving()
            self._end_teach()
            self.arm.enable(accept_position=accept_position)

    def disable(self) -> None:
        with self._cmd:
            self._end_teach()
            self.arm.disable()

    def hold(self) -> None:
        with self._cmd:
            if self._teaching:
                self._end_teach()
                return
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
        if self._teaching:
            raise StateError("the arm is in teach mode", fix="end teaching first (akarm/hold, or finish akarm teach)")
        if not self.arm.enabled:
            self._raise_fault()
            raise StateError("the arm is disabled", fix="enable it first (akarm enable, or the akarm/enable service)")

    def _register(self, motion: Motion) -> int:
        self._next_id += 1
        self._motions[self._next_id] = motion
        while len(self._motions) > 16:
            self._motions.popitem(last=False)
        return self._next_id

    def follow(self, joint_names: Sequence[str], times: Sequence[float], positions: Sequence[Sequence[float]],
               velocities: Sequence[Sequence[float]] | None = None) -> Motion | None:
        """A ROS 2 ``JointTrajectory`` with the semantics of ros2_control's JointTrajectoryController
        topic: joints matched by name (a subset is allowed; the others keep their commanded
        position), each point reached at its time, jerk-limited; no points stops the arm; a new
        one replaces the running one smoothly. A bad message is refused whole (ArgumentError; a point past
        a limit: LimitError) and nothing moves. Returns the motion (None for a stop)."""
        try:
            with self._cmd:
                self._require_commandable()
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
                    if len(p) != len(index) or not all(math.isfinite(x) for x in p):
                        raise ArgumentError(f"point {k} has {len(p)} positions for {len(index)} joint_names, or "
                                            "one that is not a number",
                                            fix="give one position (rad) per name in joint_names")
                    full[k, index] = p
                if velocities is not None and any(len(v) for v in velocities):
                    vel = np.full((len(times), len(names)), math.nan)
                    for k, v in enumerate(velocities):
                        if len(v) != len(index):
                            raise ArgumentError(f"point {k} has {len(v)} velocities for {len(index)} joint_names",
                                                fix="give one velocity per name in joint_names, or none at all")
                        vel[k, index] = v
                motion = self.arm.follow(list(times), full, vel, wait=False)
                self.counts["accepted"] += 1
                return motion
        except AkarmError as e:
            self._refused(e)
            raise

    def _refused(self, e: AkarmError) -> None:
        self.counts["refused"] += 1
        self.last_refusal = str(e)
        self.log(f"akarm serve: refused a trajectory, nothing moved: {e}")

    def refuse(self, what: str, fix: str = "") -> None:
        """Refuse a trajectory the caller found unusable: counted, reported, raised as ArgumentError."""
        e = ArgumentError(what, fix=fix)
        self._refused(e)
        raise e

    # -- the CLI's operations (JSON in, JSON out) --------------------------------------------------
    def dispatch(self, op: str, args: dict[str, Any], client: int | None = None) -> Any:
        """Run a control-socket operation (see :mod:`akarm.cli.served` for the client side) for the
        control connection ``client``."""
        handler = getattr(self, f"_op_{op}", None)
        if handler is None:
            raise StateError(f"unknown server operation {op!r}", fix="is the CLI the same akarm version as the server?")
        if op == "teach":
            return self._op_teach(**args, client=client)
        return handler(**args)

    def _client_left(self, client: int) -> None:
        """A control connection ended: teach mode it started ends with it (the client was killed, hung
        up, or lost its terminal without ending it): the arm holds where the hand left it."""
        with self._cmd:
            if self._teaching and self._teacher == client:
                with contextlib.suppress(AkarmError):
                    self._end_teach()
                self.log("akarm serve: the client that started teach mode left without ending it; "
                         "teach mode ended, the arm holds where it was left")

    def _state_doc(self) -> dict[str, Any]:
        s = self.arm.state()
        cfg = self.arm.config
        return {"names": list(self.arm.names), "modes": [j.mode for j in cfg.joints],
                "buses": [j.bus for j in cfg.joints], "can_ids": [j.can_id for j in cfg.joints],
                "q": s.q.tolist(), "dq": s.dq.tolist(), "tau": s.tau.tolist(),
                "temperature": [j.temperature for j in s.joints], "fault": [j.fault for j in s.joints],
                "age": [j.age for j in s.joints], "enabled": s.enabled, "moving": s.moving, "mode": self.mode,
                "robot": cfg.name, "pid": os.getpid(), "rate_hz": cfg.rate_hz}

    def _op_state(self) -> dict[str, Any]:
        return self._state_doc()

    def _op_enable(self, accept_position: bool = False) -> dict[str, Any]:
        self.enable(accept_position is True)
        return self._state_doc()

    def _op_disable(self) -> None:
        self.disable()

    def _op_hold(self) -> None:
        self.hold()

    def _op_stop(self) -> None:
        with self._cmd:
            if self.arm.enabled and self.arm.moving:
                self.arm.stop(wait=False)
        for m in list(self._motions.values()):
            with contextlib.suppress(AkarmError):
                m.wait()

    def _motion_doc(self, motion: Motion) -> dict[str, Any]:
        return {"id": self._register(motion), "duration": motion.duration, "t0": motion.plan.t0,
                "target": motion.plan.sample(motion.plan.t_end)[0].tolist()}

    def _op_move(self, target: str | list[float] | Mapping[str, float], speed: float = 1.0) -> dict[str, Any]:
        with self._cmd:
            self._require_commandable()
            return self._motion_doc(self.arm.move_to(target, speed=speed, wait=False))

    def _op_wait(self, id: int) -> dict[str, Any]:
        motion = self._motions.get(id)
        if motion is None:
            raise StateError(f"no motion {id} on this server")
        motion.wait()
        return {"superseded": motion.superseded, "q": self.arm.state().q.tolist()}

    def _op_sleep(self, seconds: float) -> None:
        self.arm.sleep(seconds)

    def _op_teach(self, damping: float = 0.1, client: int | None = None) -> None:
        with self._cmd:
            self._require_commandable()
            self.arm.teach(damping)
            self._teaching = True
            self._teacher = client

    def _raise_fault(self) -> None:
        if self.arm.fault is not None:
            raise self.arm.fault

    def _op_keyframe(self, name: str | None = None) -> list[float]:
        self._raise_fault()
        return list(self.arm.keyframe(name).q)

    def _op_start_recording(self, rate: float, seconds: float | None = None) -> None:
        self.arm.start_recording(rate, seconds)

    def _op_recording_finished(self) -> bool:
        self._raise_fault()
        return self.arm.recording_finished

    def _op_stop_recording(self) -> dict[str, Any]:
        rec = self.arm.stop_recording()
        return {"names": list(rec.joint_names), "t": rec.t.tolist(), "q": rec.q.tolist()}

    def _op_end_teach(self) -> None:
        with self._cmd:
            self._end_teach()

    def _op_replay(self, path: str, speed: float = 1.0) -> dict[str, Any]:
        from akarm.motion.recording import Keyframes

        with self._cmd:
            rec = self.arm.check_replay(path, speed)
            self._require_commandable()
            doc = self._motion_doc(self.arm.replay(rec, speed=speed, wait=False))
        doc["kind"] = f"{len(rec.frames)} keyframes" if isinstance(rec, Keyframes) else f"a {rec.duration:.2f} s path"
        return doc

    def _op_check_replay(self, path: str, speed: float = 1.0) -> None:
        self.arm.check_replay(path, speed)

    def _op_telemetry(self, since: float, save: str | None = None) -> dict[str, Any]:
        log = self.arm.telemetry(since=since)
        return {"rms": log.rms_error().tolist(), "path": str(log.save(save)) if save else None}
