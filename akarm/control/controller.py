"""The arm's real-time side: the buses, the mode machine, and what every cycle of the loop does.

:class:`Controller` is what the control loop calls, once per period (in its own thread, or inline
in lock step). :class:`~akarm.Arm`, the user's API, asks it for changes (enable, a new plan, teach,
stop) under its lock and waits for them; everything that happens on the wire happens here.

A cycle: **receive** (drain every bus, route each frame to its joint, which gates it), then by mode:

- ENABLING: make contact (ENTER, then a zero-gain command each cycle, until every joint gave two
  consistent replies in time), then damp (kp = 0, kd, gravity feed-forward) until the arm is at
  rest, then hold where it is with kp ramping up. See :class:`_Enabling`.
- ACTIVE: **trajectory** (sample the plan at the clock's time), **safety** (the
  :class:`~akarm.control.safety.Supervisor`), **feed-forward**, **send** one frame per joint, **telemetry**.
- TEACH: safety, then no stiffness, damping, the arm's weight at the measured pose.
- STOPPING: damping with the feed-forward fading out, then the exit frames.

Every way out ends damped and disabled: :meth:`Controller.close` is the one path, taken by
``Arm.close()``, by leaving ``with arm:``, by the interpreter's exit (an atexit hook, with a warning)
and by the garbage collector (a finalizer on the Arm, with a warning). The loop thread holds only
the controller, never the Arm, so an Arm dropped while enabled can be collected.
"""

from __future__ import annotations

import atexit
import contextlib
import math
import threading
import time
import warnings
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from os import PathLike
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm import signals
from akarm.buses.bus import close_buses, no_answer_hint, open_bus
from akarm.clock import Clock
from akarm.config import RobotConfig
from akarm.control.feedforward import FeedForward, FeedForwardKind
from akarm.control.joints import Joint, Router
from akarm.control.loop import ControlLoop
from akarm.control.modes import Mode, ModeMachine
from akarm.control.safety import Guard, Supervisor, contact_delay, default_following_error, default_stuck_travel
from akarm.dynamics.model import RobotModel
from akarm.errors import (
    AkarmError,
    BusError,
    BusLost,
    FeedbackTimeout,
    ForeignTraffic,
    LimitError,
    NotSettled,
    SafetyStop,
    StaleFeedback,
    StateError,
)
from akarm.telemetry.log import Telemetry

if TYPE_CHECKING:
    import can

    from akarm.control.collision import CollisionReflex
    from akarm.motion.trajectory import Timed

__all__ = ["Controller", "Motion", "PathRecorder", "UnsafeExitWarning"]

STAGES = ("receive", "trajectory", "safety", "feedforward", "send", "telemetry")
_DRAIN_LIMIT = 1024  # frames read per bus per cycle at most (a flooded bus must not stall the loop)
_SEND_FAILURES = 20  # frames in a row a bus refuses before it counts as lost
_CONTACT_REPLIES = 2  # consistent replies in a row that establish contact with a joint at enable
_LISTEN = 0.02  # s the loop listens to a bus before the first enable (a controller at 50 Hz or more shows)
_FOREIGN_RECENT = 0.5  # s: foreign frames this recent refuse an enable


class UnsafeExitWarning(UserWarning):
    """An Arm was still enabled when the program ended or dropped it: akarm damped and disabled it.
    Use ``with arm:`` or call ``arm.disable()`` / ``arm.close()`` yourself."""


class Motion:
    """A motion the arm is executing (returned by :meth:`Arm.move_to` and friends).

    Attributes:
        plan: the planned trajectory. duration: its length, s. superseded: True when another
            motion (or a stop) replaced it before its end.
    """

    def __init__(self, controller: Controller, plan: Timed) -> None:
        self._ctl = controller
        self.plan = plan
        self.duration = plan.duration
        self.superseded = False
        self.error: AkarmError | None = None
        self._finished = threading.Event()

    @property
    def done(self) -> bool:
        """True once the motion has ended (or was replaced by another, or the arm stopped)."""
        return self._finished.is_set()

    def wait(self, timeout: float | None = None) -> Motion:
        """Block until the motion has ended; raise the arm's :class:`~akarm.SafetyStop` if it stopped.

        ``timeout`` is in s of the arm's clock; ``None`` waits for the motion's duration plus a margin.
        """
        limit = self.duration + 5.0 if timeout is None else timeout
        self._ctl.wait_for(self._finished.is_set, limit, f"the motion ({self.duration:.2f} s) to end")
        if self.error is not None:  # it was cut short without a safety stop (a collision, the arm holding)
            raise self.error
        return self

    def _finish(self, superseded: bool = False, error: AkarmError | None = None) -> None:
        self.superseded = superseded
        self.error = error
        self._finished.set()


class PathRecorder:
    """The samples of :meth:`Arm.start_recording`, taken by the loop on a grid of ``1 / rate`` s
    from the first one; a stall skips the grid points it missed (no burst of samples after it), and
    with a duration, no sample is taken more than half a grid step past its end."""

    __slots__ = ("_last", "_next", "duration", "positions", "rate", "times")

    def __init__(self, rate: float, duration: float | None) -> None:
        self.rate, self.duration = rate, duration
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self._next = -math.inf
        self._last = math.inf

    @property
    def finished(self) -> bool:
        return self._next > self._last

    def sample(self, now: float, q: np.ndarray) -> None:
        if now < self._next - 1e-9 or self.finished:  # a nanosecond's slack: clocks sum periods
            return
        if now > self._last + 0.5 / self.rate:  # a stall across the end: that grid point is lost too
            self._next = math.inf
            return
        if not self.times:
            self._next = now
            if self.duration is not None:  # the last grid point within the duration (slack for rounding)
                self._last = now + math.floor(self.duration * self.rate + 1e-9) / self.rate + 1e-9
        self.times.append(now)
        self.positions.append(q)
        self._next += (max(0, math.floor((now - self._next) * self.rate)) + 1) / self.rate


@dataclass
class _Enabling:
    """Where an enable is: contact with every joint, then damping until the arm is at rest.

    Contact needs, per joint, :data:`_CONTACT_REPLIES` consecutive replies that agree (the gate in
    :mod:`akarm.control.joints`; when the replies after the first one all disagree with it, the first one
    was the odd one out and contact starts over from the next), and, for joints that answer every
    frame, a first reply within the joint's feedback timeout of the first frame: a constant delay is
    visible only here, where the stream of replies starts.
    """

    t0: float
    timeout: list[float]  # s per joint to make contact
    settle_speed: float
    settle_timeout: float
    received0: list[int]  # frames_received per joint when the enable began
    first_reply: list[float | None]
    entered: bool = False
    first_sent: float = 0.0  # when the first frames (ENTER) went out
    settling_since: float | None = None  # contact made with every joint; damping since


class Controller:
    """The real-time side of an :class:`~akarm.Arm` (see the module's docstring).

    Built by the Arm; its attributes are the Arm's internals, not a public API. Everything that
    changes what the loop does is done under :attr:`lock`.
    """

    def __init__(self, config: RobotConfig, joints: list[Joint], model: RobotModel, clock: Clock, *,
                 feedforward: FeedForwardKind, friction_feedforward: bool, hold_integral: float,
                 feedback_timeout: float, enable_ramp: float, stop_damping_time: float, telemetry_seconds: float,
                 can_log: str | PathLike[str] | None, realtime_priority: bool, loop_cpu: int | None,
                 settle_speed: float, settle_timeout: float, implausible_limit: int, lag: float = 0.0) -> None:
        self.config = config
        self.lag = lag  # s a reading may trail on this machine (akarm.timing): widens the tracking limits
        self.joints = joints
        self.n = n = len(joints)
        self.model = model
        self.clock = clock
        self.period = 1.0 / config.rate_hz
        self.enable_ramp = enable_ramp
        self.stop_damping_time = stop_damping_time
        self.settle_speed = settle_speed
        self.settle_timeout = settle_timeout
        self._can_log_path = can_log
        self._realtime_priority = realtime_priority
        self._loop_cpu = loop_cpu
        self.lock = threading.RLock()
        self.modes = ModeMachine()
        self.loop: ControlLoop | None = None
        self._closing: threading.Event | None = None  # set when a close() under way (in any thread) ends
        self._signals_installed = False  # this controller counts in akarm.signals' handlers
        self.telemetry = Telemetry(config.joint_names, max(1, int(telemetry_seconds * config.rate_hz)))

        lim = [j.limits for j in config.joints]
        self.torque_limit = np.array([x.torque for x in lim])
        self.kp = np.array([j.gains.kp for j in config.joints])
        self.kd = np.array([j.gains.kd for j in config.joints])
        self._mit = [j.answers_commands for j in joints]
        self._t_max = [j.motor.t_max * 0.999 if j.answers_commands else math.inf for j in joints]
        self._saturated = [False] * n
        fr = [j.friction_model() for j in config.joints]
        on = 1.0 if friction_feedforward and feedforward != "none" else 0.0
        self.ff = FeedForward(model, feedforward, [f.coulomb * on for f in fr], [f.viscous * on for f in fr],
                              self.torque_limit, hold_integral, self._mit)
        # the damping used to settle at enable and to stop: the joint's kd, at least 0.5 N·m·s/rad
        self._damping = [min(max(float(kd), 0.5), j.motor.kd_max) for kd, j in zip(self.kd, joints, strict=True)]
        self._timeouts = [self._feedback_timeout(j.config, feedback_timeout) for j in joints]
        for j in joints:  # a reply the motor cannot have reached since the last one is rejected
            j.set_gate(1.5 * j.motor.v_max, self.period)
        self.supervisor = Supervisor(joints, self._guards(), implausible_limit=implausible_limit)
        self._gains_changed()

        self.buses: dict[str, can.BusABC] = {}
        self._routers: dict[str, Router] = {}
        self._live: list[tuple[str, Any, Any]] = []  # (name, bus.recv, router.route) of the buses not lost
        self._bus_of: list[Any] = [None] * n  # each joint's bus (a lost one is still tried)
        self._send_failures: dict[str, int] = {}
        self.lost: dict[str, BaseException] = {}
        self._can_logger: Any = None
        self._t_open = 0.0

        self.plan: Timed | None = None
        self.motion: Motion | None = None
        self.hold = np.zeros(n)
        self.des = (np.zeros(n), np.zeros(n), np.zeros(n))
        self.tau_ff: list[float] | np.ndarray = [0.0] * n
        self.gain_scale = 0.0
        self._t_active = 0.0
        self._t_last = 0.0
        self._t_stop = 0.0
        self._stop_from = np.zeros(n)
        self.fault: SafetyStop | None = None
        self.enable_error: AkarmError | None = None
        self._enabling: _Enabling | None = None
        self._teach_damping = [0.0] * n
        self.recorder: PathRecorder | None = None
        #: the collision reflex (akarm.control.collision), and the plan that brings the arm to rest for its
        #: "hold" reaction (``stop_plan(start, now)``); attached by the Arm
        self.reflex: CollisionReflex | None = None
        self.stop_plan: Callable[[tuple[np.ndarray, np.ndarray, np.ndarray], float], Timed] | None = None

    @staticmethod
    def _feedback_timeout(j: Any, default: float) -> float:
        if j.feedback_timeout is not None:
            return float(j.feedback_timeout)
        if j.mode == "servo":
            return max(default, 3.0 / j.status_rate_hz)
        return default

    def _guards(self) -> list[Guard]:
        out = []
        for j, kp, timeout in zip(self.config.joints, self.kp.tolist(), self._timeouts, strict=True):
            following = default_following_error(j, kp)
            slack = j.limits.velocity * self.lag  # how far a reading that trails by `lag` can be behind
            out.append(Guard(timeout, j.max_temperature, following + slack,
                             default_stuck_travel(j, kp, following) + slack))
        return out

    def _gains_changed(self) -> None:
        """Refresh what depends on the gains (plain lists for the hot path; the supervisor's defaults)."""
        self._kp_list, self._kd_list = self.kp.tolist(), self.kd.tolist()
        self.ff.set_gains(self._kp_list)
        self._tracking = [(not m) or kp > 0.0 for m, kp in zip(self._mit, self._kp_list, strict=True)]
        self.supervisor.set_guards(self._guards())

    @property
    def mode(self) -> Mode:
        return self.modes.mode

    # ------------------------------------------------------------------------------------------
    # open and close: the one way in and the one way out
    # ------------------------------------------------------------------------------------------
    def open(self) -> None:
        """Open the buses and start the loop (nothing is sent until an enable).

        Raises:
            BusError: a bus will not open.
        """
        if self.modes.mode is not Mode.CLOSED:
            return
        used = {j.bus for j in self.joints}
        try:
            for name, bus_cfg in self.config.buses.items():
                if name in used:
                    self.buses[name] = open_bus(bus_cfg)
        except BusError:
            close_buses(self.buses)
            raise
        self._routers = {name: Router([j for j in self.joints if j.bus == name]) for name in self.buses}
        self._live = [(name, bus.recv, self._routers[name].route) for name, bus in self.buses.items()]
        self._bus_of = [self.buses[j.bus] for j in self.joints]
        self._send_failures = dict.fromkeys(self.buses, 0)
        self.lost = {}
        if self._can_log_path is not None:
            import can

            self._can_logger = can.Logger(str(self._can_log_path))
        self.fault = None
        self.modes.go(Mode.DISABLED)
        self._t_open = self.clock.now()
        self.loop = ControlLoop(self.config.rate_hz, self.clock, self.cycle, stages=STAGES,
                                realtime_priority=self._realtime_priority, cpu=self._loop_cpu,
                                on_crash=self._crashed)
        self.loop.start()
        _open_controllers.add(self)
        self._signals_installed = signals.install()

    def close(self, warn: str | None = None) -> None:
        """Disable the arm if it may be powered (damping, then exit), stop the loop, close the buses.

        Never raises; signals (Ctrl-C, SIGTERM) are held back until the arm is disabled. ``warn``:
        a warning to give if the arm was still powered (the program ended, or dropped the Arm).
        """
        with self.lock:
            if self.modes.mode is Mode.CLOSED:
                return
            closing = self._closing
            if not closing:
                self._closing = threading.Event()
        if closing:  # another thread closes it: return once it is closed (the loop's own thread cannot wait)
            if not self._on_loop_thread():
                closing.wait(self.stop_damping_time + 5.0)
            return
        with signals.deferred(reraise=threading.current_thread() is threading.main_thread() and warn is None):
            try:
                if self.modes.mode.powered and self.modes.mode is not Mode.FAULT:
                    if warn is not None:
                        warnings.warn(warn, UnsafeExitWarning, stacklevel=3)
                    if not self._on_loop_thread():  # (the loop cannot wait for its own cycles)
                        with contextlib.suppress(Exception):  # whatever fails, the frames below still go out
                            self.disable()
            finally:
                if self.loop is not None:
                    self.loop.stop()
                with self.lock:
                    if self.modes.mode.powered:  # the stop did not run to its end (a stalled or dead loop): exit now
                        self._release_all()
                    self.modes.go(Mode.CLOSED)
                close_buses(self.buses)
                self._live = []
                self._bus_of = [None] * self.n
                if self._can_logger is not None:
                    with contextlib.suppress(Exception):
                        self._can_logger.stop()
                    self._can_logger = None
                _open_controllers.discard(self)
                if self._signals_installed:
                    self._signals_installed = False
                    signals.uninstall()
                done, self._closing = self._closing, None
                if done:
                    done.set()

    def _on_loop_thread(self) -> bool:
        return self.loop is not None and self.loop.thread is threading.current_thread()

    def _release_all(self) -> None:
        """Exit motor mode (MIT) or release (servo) on every joint at once, without damping: the last
        resort when the loop cannot run the stop sequence."""
        for j in self.joints:
            for f in j.release_frames():
                with contextlib.suppress(Exception):
                    self._send(j, f)

    def close_collected(self) -> None:
        """The Arm was garbage-collected while open: close, with a warning if it was still enabled.

        The collection may run in the loop's own thread (Python's cycle collector runs in whichever
        thread allocates): the loop cannot wait for its own cycles, so a thread of its own closes
        the arm, with the damping, while the loop goes on; if no thread can be started (the
        interpreter is exiting), the joints exit motor mode at once."""
        warn = ("an akarm Arm was garbage-collected while enabled: akarm damped and disabled it "
                "(use `with arm:` or call arm.close())")
        if self._on_loop_thread():
            try:
                threading.Thread(target=self.close, kwargs={"warn": warn}, name="akarm-close").start()
                return
            except RuntimeError:
                pass
        self.close(warn=warn)

    # ------------------------------------------------------------------------------------------
    # requests from the Arm (caller's thread)
    # ------------------------------------------------------------------------------------------
    def require_open(self) -> None:
        if self.modes.mode is Mode.CLOSED:
            raise StateError("the arm is not open", fix="use `with arm:` or call arm.open() first")

    def raise_fault(self) -> None:
        """Raise the safety stop that ended the arm's motion, once the arm is disabled."""
        fault = self.fault
        if fault is not None:
            if self.modes.mode is Mode.STOPPING:
                self.wait_disabled()
            raise fault

    def require_enabled(self) -> None:
        self.raise_fault()
        if self.modes.mode is not Mode.ACTIVE:
            raise StateError(f"the arm is {self.modes.mode}, not enabled", fix="call arm.enable() first")

    def wait_for(self, done: Callable[[], bool], timeout: float, what: str, raise_fault: bool = True) -> None:
        """Wait (running cycles in lock step) until ``done()``; raise the arm's fault if one comes first."""
        loop = self.loop
        if loop is None:
            raise StateError("the arm is not open", fix="use `with arm:` or call arm.open() first")
        end = self.clock.now() + timeout
        while True:
            if raise_fault and self.fault is not None:  # before `done`: a motion ended by a stop must raise
                self.raise_fault()
            if done():
                return
            if loop.crashed is not None:
                raise StateError(f"the control loop crashed: {loop.crashed!r}",
                                 fix="this is a bug in akarm; please report it with the traceback in the log")
            if self.clock.now() > end:
                raise StateError(f"timed out after {timeout:.2f} s waiting for {what}")
            loop.wait_cycle(0.1)

    def enable(self, timeout: float) -> None:
        """Enable (see :meth:`Arm.enable`); blocks until held, or raises what refused it."""
        self.require_open()
        if self.modes.mode is Mode.FAULT:
            raise self.fault or StateError("the arm is in fault", fix="close the arm and open it again")
        if self.modes.mode in (Mode.ACTIVE, Mode.TEACH, Mode.ENABLING):
            return
        if self.modes.mode is Mode.STOPPING:
            self.wait_disabled()
            if self.modes.mode is Mode.FAULT:  # the stop ended in a fault (a bus lost): say that one
                raise self.fault or StateError("the arm is in fault", fix="close the arm and open it again")
        # listen first: another controller driving our motors shows within this time (in lock step the
        # frames already sent are read by the first cycle, before anything is sent)
        if not self.clock.stepped:
            self.wait_for(lambda: self.clock.now() - self._t_open >= _LISTEN, _LISTEN + 1.0, "the bus to be heard",
                          raise_fault=False)
        with self.lock:
            if self.modes.mode is not Mode.DISABLED:  # changed meanwhile (another thread, a lost bus)
                if self.modes.mode is Mode.FAULT:
                    raise self.fault or StateError("the arm is in fault", fix="close the arm and open it again")
                raise StateError(f"the arm became {self.modes.mode} while enable() waited: another thread "
                                 "enables or stops it", fix="enable and disable from one thread")
            now = self.clock.now()
            refused = self._refuse_foreign(now, now - _FOREIGN_RECENT)
            if refused is not None:
                raise refused
            self.fault = None
            self.enable_error = None
            self.tau_ff = [0.0] * self.n  # a stop during contact fades from here, not the last session's torque
            for j in self.joints:
                j.begin_contact()
            contact = []
            for j in self.joints:
                t = timeout
                if not j.answers_commands and j.config.status_rate_hz > 0:  # status frames at their own rate
                    t = max(t, (_CONTACT_REPLIES + 0.5) / j.config.status_rate_hz)
                contact.append(t)
            self._enabling = _Enabling(now, contact, self.settle_speed, self.settle_timeout,
                                       [j.frames_received for j in self.joints], [None] * self.n)
            self.supervisor.arm(now)
            self.modes.go(Mode.ENABLING)
        self.wait_for(lambda: self.modes.mode is not Mode.ENABLING,
                      max(contact) + self.settle_timeout + 2.0, "the joints to answer and the arm to settle")
        if self.enable_error is not None:
            self.loop.wait_cycle(0.1)  # type: ignore[union-attr]  # deliver the exit frames
            raise self.enable_error
        self.wait_for(lambda: self.gain_scale >= 1.0, self.enable_ramp + 1.0, "the gains to ramp up")

    def _refuse_foreign(self, now: float, since: float) -> ForeignTraffic | None:
        """The error refusing an enable when another node sent our joints frames since ``since`` (s)."""
        other = self.supervisor.foreign_since(since)
        if other is None:
            return None
        j, kind = other
        error = ForeignTraffic(f"another program sent it a frame ({kind}) {max(0.0, now - j.foreign_at):.2f} s ago: "
                               "two controllers on one bus; nothing was enabled", kind=kind, joint=j.name,
                               fix="stop the other controller (or akarm serve) first, or use it instead")
        error.at = now
        return error

    def begin_stop(self, fault: SafetyStop | None = None) -> None:
        """Start damping, then exit (caller holds the lock or is the loop)."""
        if fault is not None and self.fault is None:
            self.fault = fault
        mode = self.modes.mode
        if mode is Mode.STOPPING or not mode.powered:
            return
        if mode is Mode.FAULT:
            return
        self.modes.go(Mode.STOPPING)
        self._t_stop = self.clock.now()
        self._stop_from = np.asarray(self.tau_ff, dtype=float).copy()
        self._enabling = None
        if self.motion is not None:
            self.motion._finish(superseded=True)
        self.plan, self.motion = None, None

    def disable(self) -> None:
        """Damp every joint for ``stop_damping_time``, then exit motor mode. Blocks."""
        self.require_open()
        with self.lock:
            self.begin_stop()
        self.wait_disabled()

    def wait_disabled(self) -> None:
        """Wait for the stop sequence to end, then one more cycle so its exit frames are delivered."""
        if self.modes.mode is Mode.STOPPING:
            self.wait_for(lambda: self.modes.mode is not Mode.STOPPING, self.stop_damping_time + 2.0,
                          "the arm to disable", raise_fault=False)
            if self.loop is not None:
                self.loop.wait_cycle(0.1)

    def start(self, make_plan: Callable[[tuple[np.ndarray, np.ndarray, np.ndarray], float], Timed]) -> Motion:
        """Plan from the commanded state now (``make_plan(start, now)``) and follow it."""
        self.require_enabled()
        with self.lock:
            self._require_active()
            now = self.clock.now()
            start = self.plan.sample(now) if self.plan is not None else (self.hold, np.zeros(self.n), np.zeros(self.n))
            plan = make_plan(start, now)
            motion = Motion(self, plan)
            if self.motion is not None:
                self.motion._finish(superseded=True)
            self.plan, self.motion = plan, motion
        return motion

    def desired_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The commanded (q, dq, ddq) at the current clock time."""
        with self.lock:
            if self.plan is not None:
                return self.plan.sample(self.clock.now())
            return self.hold.copy(), np.zeros(self.n), np.zeros(self.n)

    def set_gains(self, kp: Sequence[float] | float | None, kd: Sequence[float] | float | None) -> None:
        """Change MIT gains, each within its motor's range (see :meth:`Arm.set_gains`)."""
        motors = [j.motor for j in self.joints]
        with self.lock:
            new = {}
            for name, value, top in (("kp", kp, [m.kp_max for m in motors]), ("kd", kd, [m.kd_max for m in motors])):
                if value is None:
                    continue
                try:
                    v = np.broadcast_to(np.asarray(value, dtype=float), (self.n,)).copy()
                except (TypeError, ValueError):
                    raise LimitError(f"{name} must be one number or one per joint (N·m/rad or N·m·s/rad), "
                                     f"got {value!r}", fix=f"pass {name} as a number or a list of {self.n}") from None
                for i, (x, hi) in enumerate(zip(v.tolist(), top, strict=True)):
                    if not (math.isfinite(x) and 0.0 <= x <= hi):
                        raise LimitError(f"{name} {x:g} is outside the motor's range 0-{hi:g}",
                                         joint=self.joints[i].name,
                                         fix=f"pass {name} within 0-{hi:g} for {motors[i].name}")
                new[name] = v
            if "kp" in new:
                self.kp[:] = new["kp"]
            if "kd" in new:
                self.kd[:] = new["kd"]
            self._gains_changed()

    def set_extra_torque(self, tau: Sequence[float] | None) -> None:
        with self.lock:
            if tau is None:
                self.ff.extra = [0.0] * self.n
                return
            try:
                v = np.asarray(tau, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                v = np.full(0, math.nan)
            if v.shape != (self.n,) or not np.all(np.isfinite(v)):
                raise LimitError(f"extra torque needs {self.n} finite values (N·m)", fix="one per joint, config order")
            self.ff.extra = v.tolist()

    def _require_active(self) -> None:
        """(Under the lock) raise the fault, or a StateError, unless the arm is still active: a stop may
        have come between a caller's check and its taking the lock."""
        if self.modes.mode is not Mode.ACTIVE:
            if self.fault is not None:
                raise self.fault
            raise StateError(f"the arm is {self.modes.mode}, not enabled", fix="call arm.enable() first")

    def enter_teach(self, damping: float) -> None:
        with self.lock:
            self._require_active()
            self._teach_damping = np.minimum(damping, self.kd).tolist()
            if self.motion is not None:
                self.motion._finish(superseded=True)
            self.plan, self.motion = None, None
            self.modes.go(Mode.TEACH)

    def leave_teach(self) -> bool:
        """Hold the pose the hand left, gains ramping up; False if the arm was not in teach mode."""
        with self.lock:
            if self.modes.mode is not Mode.TEACH:
                return False
            self.recorder = None
            self._hold_here(self.clock.now())
            self.modes.go(Mode.ACTIVE)
        return True

    def _hold_here(self, now: float) -> None:
        """Take the measured pose as the commanded one, kp ramping up from zero (caller holds the lock)."""
        q = np.array([j.state.position for j in self.joints])
        self.hold = q
        self.des = (q.copy(), np.zeros(self.n), np.zeros(self.n))
        self.plan = None
        self._t_active = now
        self._t_last = now
        self.gain_scale = 0.0 if self.enable_ramp > 0 else 1.0
        self.ff.reset_integral()

    # ------------------------------------------------------------------------------------------
    # the cycle (loop thread, or inline with a stepped clock)
    # ------------------------------------------------------------------------------------------
    def cycle(self, now: float, slot: int) -> None:
        pc = time.perf_counter
        stage = self.loop.stats.stage[slot]  # type: ignore[union-attr]
        t0 = pc()
        self._receive(now)
        t1 = pc()
        stage[0] = t1 - t0
        mode = self.modes.mode
        if not mode.powered or mode is Mode.FAULT:
            return
        with self.lock:
            mode = self.modes.mode
            if mode is Mode.ACTIVE:
                self._cycle_active(now, stage, t1)
            elif mode is Mode.TEACH:
                self._cycle_teach(now)
            elif mode is Mode.ENABLING:
                self._cycle_enabling(now)
            elif mode is Mode.STOPPING:
                self._cycle_stopping(now)

    def _receive(self, now: float) -> None:
        logger = self._can_logger
        for name, recv, route in self._live:
            try:
                for _ in range(_DRAIN_LIMIT):  # everything already received, never waiting
                    msg = recv(0.0)
                    if msg is None:
                        break
                    route(msg, now)
                    if logger is not None:
                        logger.on_message_received(msg)
            except Exception as e:  # the bus is gone (shut down, unplugged, the interface down)
                self._bus_lost(name, e, now)

    def _send(self, j: Joint, msg: can.Message) -> None:
        bus = self._bus_of[j.index]
        if bus is None:
            return
        try:
            bus.send(msg)
        except Exception as e:  # a full TX queue or an unplugged adapter: counted; many in a row = lost
            failures = self._send_failures[j.bus] = self._send_failures[j.bus] + 1
            if failures >= _SEND_FAILURES:
                self._bus_lost(j.bus, e, self.clock.now())
            return
        self._send_failures[j.bus] = 0
        j.sent()
        if self._can_logger is not None:
            msg.timestamp = time.time()
            self._can_logger.on_message_received(msg)

    def _bus_lost(self, name: str, error: BaseException, now: float) -> None:
        if name in self.lost:
            return
        with self.lock:
            self.lost[name] = error
            self._live = [x for x in self._live if x[0] != name]  # sends go on being tried: damping, exit
            on_it = [j for j in self.joints if j.bus == name]
            cfg = self.config.buses[name]
            stop = BusLost(
                f"bus {name!r} ({cfg.interface} channel {cfg.channel!r}) failed: {str(error) or type(error).__name__}; "
                f"{', '.join(j.name for j in on_it)} may not have been damped or disabled (the frames were tried; a "
                "MIT driver keeps its last command until its CAN timeout, if it has one); the other joints were",
                bus=name,
                fix="cut the motors' power (e-stop) if they are still holding; check the adapter, cable and "
                    "interface (ip link), then close the arm and open it again")
            stop.at = now
            mode = self.modes.mode
            if mode in (Mode.ACTIVE, Mode.TEACH, Mode.ENABLING, Mode.STOPPING):
                self.begin_stop(stop)
            elif mode is Mode.DISABLED:
                self.fault = self.fault or stop
                self.modes.go(Mode.FAULT)

    def _crashed(self, exc: BaseException) -> None:
        """The loop died of a bug: tell every motor to go limp, as a last resort."""
        for j in self.joints:
            for f in j.release_frames():
                self._send(j, f)

    def _cycle_active(self, now: float, stage: Any, t1: float) -> None:
        pc = time.perf_counter
        plan = self.plan
        n = self.n
        if plan is not None:
            q_d, dq_d, ddq_d = plan.sample(now)
            if plan.done(now):
                self.hold = q_d.copy()
                self.plan = None
                if self.motion is not None:
                    self.motion._finish()
                    self.motion = None
        else:
            q_d, dq_d, ddq_d = self.hold, np.zeros(n), np.zeros(n)
        self.des = (q_d, dq_d, ddq_d)
        qd = q_d.tolist()
        t2 = pc()
        stage[1] = t2 - t1
        stop = self.supervisor.check(now, qd, self._tracking, self._saturated)
        if stop is None and self.reflex is not None:
            stop = self._collision_check(now, True)
        t3 = pc()
        stage[2] = t3 - t2
        if stop is not None:
            self.begin_stop(stop)
            self._cycle_stopping(now)
            return
        js = self.joints
        q_meas = [j.state.position for j in js]
        holding = plan is None and self.gain_scale >= 1.0
        ff = self.ff.torques(q_d, dq_d, ddq_d, q_meas, holding, now - self._t_last)
        self._t_last = now
        self.tau_ff = ff
        t4 = pc()
        stage[3] = t4 - t3
        if self.gain_scale < 1.0:
            self.gain_scale = min(1.0, (now - self._t_active) / self.enable_ramp) if self.enable_ramp > 0 else 1.0
        g = self.gain_scale
        kp, kd, tmax, sat = self._kp_list, self._kd_list, self._t_max, self._saturated
        vd = dq_d.tolist()
        for i, j in enumerate(js):
            k = kp[i] * g
            self._send(j, j.track(qd[i], vd[i], k, kd[i], ff[i]))
            # what the firmware will apply (before its clamp): saturated, the motor has no authority left
            s = j.state
            tau = k * (qd[i] - s.position) + kd[i] * (vd[i] - s.velocity) + ff[i]
            sat[i] = tau >= tmax[i] or tau <= -tmax[i]
        t5 = pc()
        stage[4] = t5 - t4
        self._record(now, qd, vd, ff)
        stage[5] = pc() - t5

    def _collision_check(self, now: float, check: bool) -> SafetyStop | None:
        """Update the collision reflex; its stop if it fired with the "disable" reaction. Its "hold"
        reaction replaces the plan here by a jerk-limited stop from this cycle's desired state."""
        js, reflex = self.joints, self.reflex
        assert reflex is not None
        if check:  # the MIT gains of this cycle's commands (teach: no stiffness, its damping)
            kp = [k * self.gain_scale if m else 0.0 for k, m in zip(self._kp_list, self._mit, strict=True)]
            kd = [k if m else 0.0 for k, m in zip(self._kd_list, self._mit, strict=True)]
        else:
            kp, kd = [0.0] * self.n, [d if m else 0.0 for d, m in zip(self._teach_damping, self._mit, strict=True)]
        err = reflex.step(now, [j.state.position for j in js], [j.state.velocity for j in js],
                          [j.state.torque for j in js], check, kp, kd, [j.state.stamp for j in js],
                          self.des[1] if check else None)
        if err is None or err.reaction == "disable" or self.stop_plan is None:
            return err
        if self.motion is not None:
            self.motion._finish(superseded=True, error=err)
        self.plan, self.motion = self.stop_plan(self.des, now), None
        return None

    def _record(self, now: float, q_d: Any, dq_d: Any, ff: Any) -> None:
        states = [j.state for j in self.joints]
        ext = self.reflex.estimate if self.reflex is not None else None
        self.telemetry.record(now, q_d, dq_d, [s.position for s in states], [s.velocity for s in states],
                              [s.torque for s in states], ff, ext)

    def _cycle_teach(self, now: float) -> None:
        """Hand guiding: no stiffness, a little damping, the arm's weight carried (at the measured pose)."""
        stop = self.supervisor.check(now)
        if stop is not None:
            self.begin_stop(stop)
            self._cycle_stopping(now)
            return
        if self.reflex is not None:  # estimated (the hand's torque), never checked
            self._collision_check(now, False)
        q = np.array([j.state.position for j in self.joints])
        g = self.ff.gravity(q)
        gl = g.tolist()
        for i, j in enumerate(self.joints):
            self._send(j, j.carry(self._teach_damping[i], gl[i]))
        self.des = (q, np.zeros(self.n), np.zeros(self.n))
        self.tau_ff = gl
        rec = self.recorder
        if rec is not None:
            rec.sample(now, q)
        self._record(now, q, np.zeros(self.n), g)

    def _cycle_enabling(self, now: float) -> None:
        en = self._enabling
        assert en is not None
        js = self.joints
        if en.settling_since is None:
            self._make_contact(en, now)
            return
        stop = self.supervisor.check(now)
        if stop is not None:
            self._enable_failed(stop)
            return
        q = [j.state.position for j in js]
        g = self.ff.gravity(q).tolist()
        for i, j in enumerate(js):
            self._send(j, j.damp(self._damping[i], g[i]))
        self.tau_ff = g
        self._record(now, q, [0.0] * self.n, g)
        fastest = max(range(self.n), key=lambda i: abs(js[i].state.velocity))
        speed = abs(js[fastest].state.velocity)
        if speed < en.settle_speed:  # at rest (with gravity carried, a swing only decays): hold here
            self._hold_here(now)
            self._enabling = None
            self.modes.go(Mode.ACTIVE)
            return
        if now - en.settling_since > en.settle_timeout:
            stop = NotSettled(f"still moving at {speed:.2f} rad/s after {en.settle_timeout:.1f} s of damping (it must "
                              f"come below {en.settle_speed:.2f} rad/s before it is held); nothing was held, the arm "
                              "was disabled", speed=speed, limit=en.settle_speed, joint=js[fastest].name,
                              fix="let the arm come to rest (support it) and enable again; raise settle_timeout "
                                  "for an arm that swings for long")
            stop.at = now
            self._enable_failed(stop)

    def _make_contact(self, en: _Enabling, now: float) -> None:
        js = self.joints
        refused = self._refuse_foreign(now, en.t0 - _FOREIGN_RECENT)
        if refused is not None:  # before anything is sent: another controller must not lose its arm to us
            self._enable_failed(refused, release=en.entered)
            return
        if not en.entered:
            for j in js:
                for f in j.enter_frames():
                    self._send(j, f)
            en.entered = True
            en.first_sent = now
        for j in js:  # zero gains, zero torque: overrides the remembered command and asks for a reply
            msg = j.neutral()
            if msg is not None:
                self._send(j, msg)
        ready = True
        late: list[Joint] = []
        for i, j in enumerate(js):
            if en.first_reply[i] is None and j.frames_received > en.received0[i]:
                en.first_reply[i] = now
                delay = contact_delay(en.first_sent, now, self.period)
                if j.answers_commands and delay > self._timeouts[i]:
                    stop = StaleFeedback(
                        f"its first reply came {delay * 1e3:.0f} ms after the first frame (limit "
                        f"{self._timeouts[i] * 1e3:.0f} ms): replies arrive late; nothing was enabled",
                        age=delay, limit=self._timeouts[i], joint=j.name,
                        fix="a CAN adapter or bus that queues frames (check the bus load with akarm check, the "
                            "adapter's latency, other traffic); raise feedback_timeout only if the delay is known "
                            "and harmless")
                    stop.at = now
                    self._enable_failed(stop)
                    return
            if j.rejected_run >= 2:  # the reference disagrees with every reply since: it was the odd one
                j.rebase()
            if j.accepted_run < _CONTACT_REPLIES:
                ready = False
                if now - en.t0 > en.timeout[i]:
                    late.append(j)
        if late:
            limit = en.timeout[late[0].index]
            heard = [j for j in late if j.frames_received > en.received0[j.index]]
            names = ", ".join(j.name for j in late)
            if heard:
                what = f"no {_CONTACT_REPLIES} consistent replies within {limit * 1e3:.0f} ms from: {names}"
            else:
                what = f"no answer within {limit * 1e3:.0f} ms from: {names}"
            silent = FeedbackTimeout(f"{what}; nothing was enabled", age=now - en.t0, limit=limit,
                                     joint=late[0].name, fix=no_answer_hint(self.config.buses[late[0].bus]))
            silent.at = now
            self._enable_failed(silent)
            return
        if ready:
            en.settling_since = now

    def _enable_failed(self, error: AkarmError, release: bool = True) -> None:
        if release:
            for j in self.joints:
                for f in j.release_frames():
                    self._send(j, f)
        self._enabling = None
        self.enable_error = error
        self.supervisor.disarm()
        self.gain_scale = 0.0
        self.modes.go(Mode.DISABLED)

    def _cycle_stopping(self, now: float) -> None:
        """Damping (kp = 0, feed-forward fading out) for stop_damping_time, then exit."""
        T = self.stop_damping_time
        s = (now - self._t_stop) / T if T > 0 else 1.0
        js = self.joints
        if s < 1.0:
            fade = 1.0 - s
            tau = (self._stop_from * fade).tolist()
            for i, j in enumerate(js):
                self._send(j, j.damp(self._damping[i], tau[i]))
            self._record(now, self.des[0], np.zeros(self.n), tau)
            return
        for j in js:
            for f in j.release_frames():
                self._send(j, f)
        self.gain_scale = 0.0
        self.supervisor.disarm()
        self.recorder = None
        self.modes.go(Mode.FAULT if self.lost else Mode.DISABLED)


# ----------------------------------------------------------------------------------------------
# the way out at interpreter exit
# ----------------------------------------------------------------------------------------------
_open_controllers: weakref.WeakSet[Controller] = weakref.WeakSet()


def _close_all_at_exit() -> None:
    for ctl in list(_open_controllers):
        ctl.close(warn="an akarm Arm was still enabled when the program ended: akarm damped and disabled it "
                       "(use `with arm:` or call arm.close())")


atexit.register(_close_all_at_exit)


def track_arm(arm: object, controller: Controller) -> weakref.finalize:
    """Close ``controller`` (with a warning if it is still enabled) when ``arm`` is garbage-collected."""
    fin = weakref.finalize(arm, controller.close_collected)
    fin.atexit = False  # the interpreter's exit has its own hook (_close_all_at_exit)
    return fin

