"""One long-lived controller that holds the arm, which the CLI, scripts and other machines drive.

::

    import akarm
    arm = akarm.Arm.from_yaml("robots/arm6.yaml")
    with arm:
        akarm.serve(arm, namespace="arm6")     # enables without a kick, holds, serves until Ctrl-C/SIGTERM
    # leaving: damped, then disabled

:class:`ArmServer` claims the robot's buses (a second controller on them is refused), enables the
arm, and holds it. It serves

- the ``akarm`` CLI of this machine through a Unix socket (:mod:`akarm.server.socket`): ``move``,
  ``enable``, ``disable``, ``status``, ``teach`` and ``replay`` use the server when one runs;
- ROS 2 over Cyclone DDS (:mod:`akarm.ros.node`, with the ``ros`` extra): ``joint_states``,
  ``joint_trajectory``, ``akarm/status`` and the ``akarm/enable|disable|hold`` services.

Stopping it (:meth:`ArmServer.stop`, SIGINT or SIGTERM in :func:`serve`) damps and disables the arm.
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
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm import signals as _signals
from akarm.buses.ownership import BusLock, runtime_dir, sweep_sockets
from akarm.control.modes import Mode
from akarm.errors import AkarmError, ArgumentError, StateError
from akarm.server.socket import ControlServer

if TYPE_CHECKING:
    from akarm.arm import Arm, Motion
    from akarm.ros.node import RosNode

__all__ = ["ArmServer", "serve"]


def _default_domain() -> int:
    try:
        return int(os.environ.get("ROS_DOMAIN_ID", "0"))
    except ValueError:
        return 0


class ArmServer:
    """Serves ``arm`` to the CLI (local socket) and to ROS 2 (DDS) until :meth:`stop`.

    Args:
        arm: the arm; opened here if it is not open yet (and then closed by :meth:`stop`). It must
            run on the wall clock (a lock-step simulation has nobody to advance its time).
        domain: DDS domain ID (default: ``ROS_DOMAIN_ID``, else 0).
        namespace: ROS 2 namespace of every topic and service (default none).
        ros: offer the ROS 2 interfaces (needs the ``ros`` extra); False serves the CLI only.
        joint_states_hz: rate of ``joint_states``; default the loop rate divided by
            ``round(rate_hz / 100)`` (100 Hz at 500 Hz).
        status_hz: rate of ``akarm/status``.
        enable: enable (without a kick) and hold when starting.
        log: where the server's one-line reports go (default: stderr).
    """

    def __init__(self, arm: Arm, *, domain: int | None = None, namespace: str = "", ros: bool = True,
                 joint_states_hz: float | None = None, status_hz: float = 2.0, enable: bool = True,
                 log: Callable[[str], None] | None = None) -> None:
        if arm.clock.stepped:
            raise StateError("akarm serve needs an arm on the wall clock, not a lock-step simulation",
                             fix="build the Arm without clock= (a simulator in its own process works)")
        for what, hz in (("joint_states_hz", joint_states_hz), ("status_hz", status_hz)):
            if hz is not None and not (isinstance(hz, int | float) and 0 < hz < math.inf):
                raise ArgumentError(f"{what} must be a positive number of Hz, got {hz!r}",
                                    fix="e.g. --joint-states-hz 100 --status-hz 2")
        self.arm = arm
        self.domain = _default_domain() if domain is None else int(domain)
        self.namespace = namespace.strip("/")
        self.ros = ros
        rate = arm.config.rate_hz
        self.joint_states_hz = joint_states_hz if joint_states_hz is not None else rate / max(1, round(rate / 100.0))
        self.status_hz = status_hz
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
        self._control: ControlServer | None = None
        self._node: RosNode | None = None
        self.socket_path = runtime_dir() / f"serve-{os.getpid()}-{id(self):x}.sock"
        self.last_refusal = ""
        self.counts = {"accepted": 0, "refused": 0}

    # ------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------
    def start(self) -> ArmServer:
        """Claim the buses, open and enable the arm, start serving. Raises on any failure, leaving
        the arm as it was (disabled) and the buses free."""
        sweep_sockets()  # of servers killed before they could remove them
        source = self.arm.config.source
        self._lock = BusLock(self.arm.config, {"robot": str(source) if source else self.arm.config.name,
                                               "socket": str(self.socket_path), "domain": self.domain,
                                               "namespace": self.namespace})
        try:
            if self.ros:  # first: a missing extra or a bad domain or namespace is said before anything is enabled
                from akarm.ros import node as ros_node

                self._node = ros_node.RosNode(self, self.domain, self.namespace, self.joint_states_hz, self.status_hz)
            if self.arm.mode is Mode.CLOSED:
                self.arm.open()
                self._opened_arm = True
            if self._enable_at_start:
                self.arm.enable()
            self._control = ControlServer(self.socket_path, self.dispatch, closed=self._client_left)
            threading.Thread(target=self._report_faults, name="akarm-serve-faults", daemon=True).start()
            if self._node is not None:
                self._node.start()
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
            node, self._node = self._node, None
            if node is not None:
                node.stop()
            control, self._control = self._control, None
            if control is not None:
                control.close()
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

    def __enter__(self) -> ArmServer:
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
    # commands (from the CLI socket and from ROS 2)
    # ------------------------------------------------------------------------------------------
    def _require_serving(self) -> None:
        if self._stop.is_set():
            raise StateError("akarm serve is stopping: the arm is being disabled", fix="start the server again")

    def enable(self) -> None:
        with self._cmd:
            self._require_serving()
            self._end_teach()
            self.arm.enable()

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

    def _op_enable(self) -> dict[str, Any]:
        self.enable()
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


def serve(arm: Arm, **options: Any) -> None:
    """Serve ``arm`` (see :class:`ArmServer` for ``options``) until SIGINT or SIGTERM, then damp and
    disable it. Blocks; for a script that owns its Arm."""
    with ArmServer(arm, **options) as server:
        server.wait()
