"""The user's API: an :class:`Arm` that enables, moves, holds and disables a robot arm safely.

::

    import akarm
    arm = akarm.Arm.from_yaml("robots/arm6.yaml")
    with arm:                       # any exit, exception or Ctrl-C: damped, then disabled
        arm.enable()                # no kick: starts at the measured position, gains ramp up
        arm.move_to("home")         # jerk-limited, time-synchronised, blocks
        arm.move_to([0.3, -0.5, 1.0, 0.0, 0.4, 0.0], speed=0.5)

Every cycle of the control loop (``config.rate_hz``): take the joints' latest feedback, check the
watchdog, sample the trajectory at the current clock time, compute feed-forward torque with
Pinocchio (full inverse dynamics by default), encode and send one frame per joint, record telemetry.

All positions are rad, velocities rad/s, torques N·m, times s, in config joint order.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from os import PathLike
from typing import Literal

import numpy as np

from . import recording as rec_mod
from . import units
from .bus import close_buses, open_bus
from .clock import Clock, RealClock
from .config import RobotConfig
from .errors import (
    AkarmError,
    BusError,
    ConfigError,
    ConfigProblem,
    FeedbackTimeout,
    LimitError,
    MotorFault,
    OverTemperature,
    SafetyStop,
    StateError,
)
from .joints import Joint, MitJoint, Router, ServoJoint, make_joint
from .loop import ControlLoop, StatsSummary
from .model import RobotModel
from .protocol.servo import describe_error
from .telemetry import Telemetry, TelemetryLog
from .timing import TimingProfile, get_profile
from .trajectory import Chain, JointLimits, Plan, Planner

__all__ = ["Arm", "ArmState", "JointReport", "Motion"]

FeedForward = Literal["full", "gravity", "none"]
Target = str | Sequence[float] | np.ndarray | Mapping[str, float]

_STAGES = ("receive", "safety", "trajectory", "feedforward", "send", "telemetry")
_DRAIN_LIMIT = 1024  # frames read per bus per cycle at most (a flooded bus must not stall the loop)
_INV_FRICTION_SMOOTHING = 1.0 / 0.02  # Coulomb feed-forward is c·tanh(v_des / 0.02 rad/s): smooth through zero


@dataclass(frozen=True)
class JointReport:
    """One joint's latest feedback (joint side, SI): position rad, velocity rad/s, torque N·m,
    temperature °C (None if not reported), fault code (0 none), age s (time since the feedback)."""

    name: str
    position: float
    velocity: float
    torque: float
    temperature: float | None
    fault: int
    age: float


@dataclass(frozen=True)
class ArmState:
    """A snapshot of the arm: per-joint feedback plus the controller's own state.

    Attributes:
        time: clock time of the snapshot, s.
        joints: a :class:`JointReport` per joint, config order.
        q, dq, tau: measured positions (rad), velocities (rad/s), torques (N·m) as arrays.
        q_des: the commanded position (rad) this cycle.
        enabled: True while the arm is powered and tracking. moving: True while a motion runs.
    """

    time: float
    joints: tuple[JointReport, ...]
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    q_des: np.ndarray
    enabled: bool
    moving: bool

    def __str__(self) -> str:
        head = f"{'joint':<16}{'pos rad':>10}{'vel rad/s':>11}{'torque Nm':>11}{'temp C':>8}{'fault':>7}{'age ms':>9}"
        rows = [head]
        for j in self.joints:
            temp = f"{j.temperature:8.1f}" if j.temperature is not None else f"{'-':>8}"
            rows.append(f"{j.name:<16}{j.position:10.4f}{j.velocity:11.4f}{j.torque:11.3f}{temp}{j.fault:7d}"
                        f"{j.age * 1e3:9.1f}")
        return "\n".join(rows)


class Motion:
    """A motion the arm is executing (returned by :meth:`Arm.move_to` and friends).

    Attributes:
        plan: the planned trajectory. duration: its length, s.
    """

    def __init__(self, arm: Arm, plan: Plan) -> None:
        self._arm = arm
        self.plan = plan
        self.duration = plan.duration
        self.superseded = False
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
        self._arm._wait_for(lambda: self._finished.is_set(), limit, f"the motion ({self.duration:.2f} s) to end")
        return self

    def _finish(self, superseded: bool = False) -> None:
        self.superseded = superseded
        self._finished.set()


class _PathRecorder:
    """The samples of :meth:`Arm.start_recording`, taken by the loop on a grid of ``1 / rate`` s
    from the first one; a stall skips the grid points it missed (no burst of samples after it)."""

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
        if not self.times:
            self._next = now
            if self.duration is not None:  # the last grid point within the duration (slack for rounding)
                self._last = now + math.floor(self.duration * self.rate + 1e-9) / self.rate + 1e-9
        self.times.append(now)
        self.positions.append(q)
        self._next += (max(0, math.floor((now - self._next) * self.rate)) + 1) / self.rate


class Arm:
    """A robot arm of AK actuators, driven by a fixed-rate control loop.

    Args:
        config: the robot (see :func:`akarm.load_robot`).
        clock: the loop's clock. Default: wall clock. Pass ``sim.clock`` of a
            ``SimulatedRobot(..., realtime=False)`` to run in lock step with the simulator.
        feedforward: ``"full"`` (inverse dynamics of the planned trajectory, default),
            ``"gravity"`` (gravity only) or ``"none"``; always clamped to each joint's torque limit.
        friction_feedforward: add each joint's friction (its ``friction:`` in the YAML, else the
            catalogue's typical values) at the *desired* velocity: ``c·tanh(v/0.02) + b·v``. Off
            with ``feedforward="none"``.
        feedback_timeout: s; the watchdog stops the arm when a joint's feedback is older
            (default: the timing profile's, 20 ms normally; servo joints at least 3 status periods;
            a joint's own setting wins, but not below the profile's ``min_feedback_timeout``).
        timing: a timing profile (:mod:`akarm.timing`): ``"normal"`` (default) or ``"slow"`` for
            slow or shared machines, or a :class:`~akarm.timing.TimingProfile`. It caps the loop rate
            (:attr:`config` then says the rate in force) and gives the watchdog's and
            :meth:`enable`'s default timeouts. Kept as :attr:`timing`.
        enable_ramp: s over which MIT gains rise from zero at enable.
        stop_damping_time: s of damping (kp = 0) before exit when disabling or stopping for safety.
        telemetry_seconds: how much history the telemetry ring keeps, s.
        can_log: optional path of a raw CAN log (``.log`` candump, ``.asc``, ``.blf``, ...).
        realtime_priority: ask for SCHED_FIFO and locked memory for the loop thread, freeze the
            garbage collector's view of existing objects and shorten the interpreter's thread switch
            interval (:func:`akarm.loop.request_realtime`; reported, never fatal).
        busy_wait: the loop thread keeps its core between cycles (it yields instead of sleeping),
            so it starts every cycle with warm caches: for six joints at 500 Hz on our 2-core
            machines, 130-170 µs of compute per cycle instead of 175-195 µs, for a whole core
            (:class:`~akarm.clock.RealClock`). With ``realtime_priority``, give it a core of its
            own (``loop_cpu``, and keep other busy processes off that core). Only with the default clock.
        loop_cpu: pin the loop thread to this CPU (Linux; reported in :attr:`realtime_report`).
        hold_integral: 1/s; while holding still (no motion running), MIT joints add integral action
            ``ki = hold_integral · kp`` to their torque, which removes the steady-state error that
            friction leaves with a pure PD (kp = 40 N·m/rad against 0.3 N·m of friction: 7.5 mrad).
            Reset whenever a motion starts; its torque is clamped to 10 % of the joint's torque
            limit. 0 turns it off.
    """

    def __init__(self, config: RobotConfig, *, clock: Clock | None = None, feedforward: FeedForward = "full",
                 feedback_timeout: float | None = None, enable_ramp: float = 0.3,
                 stop_damping_time: float = 0.3, telemetry_seconds: float = 60.0,
                 can_log: str | PathLike[str] | None = None, realtime_priority: bool = False,
                 hold_integral: float = 3.0, friction_feedforward: bool = True, busy_wait: bool = False,
                 loop_cpu: int | None = None, timing: str | TimingProfile | None = None) -> None:
        if feedforward not in ("full", "gravity", "none"):
            raise StateError(f"feedforward must be 'full', 'gravity' or 'none', got {feedforward!r}")
        self.timing = get_profile(timing)
        config = self.timing.apply(config)
        self.config = config
        self.clock: Clock = clock if clock is not None else RealClock(busy=busy_wait)
        self.feedforward: FeedForward = feedforward
        self.enable_ramp = enable_ramp
        self.stop_damping_time = stop_damping_time
        self.joints: list[Joint] = [make_joint(i, j) for i, j in enumerate(config.joints)]
        self.names = config.joint_names
        self.n = len(self.joints)
        self.model = RobotModel(config, armature=True)
        lim = [j.limits for j in config.joints]
        self.limits = JointLimits(
            self.names, np.array([x.lower for x in lim]), np.array([x.upper for x in lim]),
            np.array([x.velocity for x in lim]), np.array([x.acceleration for x in lim]),
            np.array([x.jerk for x in lim]))
        self._torque_limit = np.array([x.torque for x in lim])
        self.planner = Planner(self.limits)
        self._kp = np.array([j.gains.kp for j in config.joints])
        self._kd = np.array([j.gains.kd for j in config.joints])
        is_mit = np.array([j.mode == "mit" for j in config.joints])
        self._hold_integral = hold_integral
        self._is_mit = is_mit
        # per-joint constants of the hot path as plain lists (see the feed-forward stage)
        self._gains_changed()
        self._tlim = self._torque_limit.tolist()
        self._imax = (0.1 * self._torque_limit).tolist()
        self._extra = [0.0] * self.n  # user torque added to MIT commands, N·m
        self._integral = [0.0] * self.n  # ∫(q_des - q) dt while holding, rad·s
        self._t_last = 0.0
        fr = [j.friction_model() for j in config.joints]
        on = 1.0 if friction_feedforward and feedforward != "none" else 0.0
        self._fric_c = [f.coulomb * on for f in fr]
        self._fric_b = [f.viscous * on for f in fr]
        self._timeouts = [self.timing.watchdog(j.config, feedback_timeout) for j in self.joints]  # s
        self._max_temp = [j.config.max_temperature for j in self.joints]
        self.telemetry_ring = Telemetry(self.names, max(1, int(telemetry_seconds * config.rate_hz)))
        self._can_log_path = can_log
        self._can_logger = None
        self._realtime_priority = realtime_priority
        self._loop_cpu = loop_cpu

        self._lock = threading.RLock()
        self._buses: dict[str, object] = {}
        self._routers: dict[str, Router] = {}
        self._bus_of = [j.bus for j in self.joints]
        self._loop: ControlLoop | None = None
        self._mode = "closed"  # closed | disabled | enabling | active | stopping
        self._plan: Plan | None = None
        self._motion: Motion | None = None
        self._hold = np.zeros(self.n)
        self._des = (np.zeros(self.n), np.zeros(self.n), np.zeros(self.n))
        self._ff = np.zeros(self.n)
        self._gain_scale = 0.0
        self._t_enable = 0.0
        self._enable_timeout = 0.5
        self._t_active = 0.0
        self._t_stop = 0.0
        self._stop_from = np.zeros(self.n)
        self._fault: SafetyStop | None = None
        self._enable_error: AkarmError | None = None
        self._send_errors = 0
        self._entered = False
        self._teach_damping = np.zeros(self.n)
        self._recorder: _PathRecorder | None = None

    @classmethod
    def from_yaml(cls, path: str | PathLike[str], *, interface: str | None = None,
                  channel: str | Mapping[str, str] | None = None, bitrate: int | None = None, **kwargs) -> Arm:
        """Load a robot YAML (bus overrides: ``interface=``, ``channel=``, ``bitrate=``) and build its Arm."""
        from .config_loader import load_robot

        config = load_robot(path)
        if interface is not None or channel is not None or bitrate is not None:
            config = config.with_bus(interface=interface, channel=channel, bitrate=bitrate)
        return cls(config, **kwargs)

    # ------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------
    def open(self) -> Arm:
        """Open the CAN buses and start the control loop (nothing is sent until :meth:`enable`).

        Raises:
            BusError: a bus cannot be opened (the message says which, and how to create it).
        """
        if self._mode != "closed":
            return self
        try:
            for name, bus_cfg in self.config.buses.items():
                if any(b == name for b in self._bus_of):
                    self._buses[name] = open_bus(bus_cfg)
        except BusError:
            self._close_buses()
            raise
        for name in self._buses:
            self._routers[name] = Router([j for j in self.joints if j.bus == name])
        if self._can_log_path is not None:
            import can

            self._can_logger = can.Logger(str(self._can_log_path))
        self._mode = "disabled"
        self._loop = ControlLoop(self.config.rate_hz, self.clock, self._cycle, stages=_STAGES,
                                 realtime_priority=self._realtime_priority, cpu=self._loop_cpu,
                                 on_crash=self._crashed)
        self._loop.start()
        return self

    def close(self) -> None:
        """Disable the arm if it is enabled (damping, then exit), stop the loop, close the buses."""
        if self._mode == "closed":
            return
        try:
            if self._mode in ("enabling", "active", "stopping"):
                with contextlib.suppress(SafetyStop):
                    self.disable()
        finally:
            if self._loop is not None:
                self._loop.stop()
            self._mode = "closed"
            self._close_buses()
            if self._can_logger is not None:
                self._can_logger.stop()
                self._can_logger = None

    def _close_buses(self) -> None:
        close_buses(self._buses)  # type: ignore[arg-type]
        self._routers.clear()

    def __enter__(self) -> Arm:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------------------------------
    # enable / disable
    # ------------------------------------------------------------------------------------------
    def enable(self, timeout: float | None = None) -> None:
        """Power the joints without a kick and hold them where they are.

        MIT joints: ENTER, at once followed by a zero-gain, zero-torque command (the driver would
        otherwise apply the last command it remembers), then the measured positions become the
        commanded ones and the gains ramp up from zero over ``enable_ramp`` s, with feed-forward
        from the start. Servo joints: their status frames give the position to hold.

        Args:
            timeout: s to wait for every joint's first feedback (default: the timing profile's,
                0.5 s normally).

        Raises:
            FeedbackTimeout: a joint did not answer (it names the joint; the arm is left disabled).
        """
        self._require_open()
        if self._mode in ("active", "enabling"):
            return
        self._fault = None
        self._enable_error = None
        if timeout is None:
            timeout = self.timing.enable_timeout
        with self._lock:
            for j in self.joints:
                j.state.stamp = -math.inf
            self._t_enable = self.clock.now()
            self._enable_timeout = timeout
            self._mode = "enabling"
        self._wait_for(lambda: self._mode != "enabling", timeout + 1.0, "the joints to answer")
        if self._enable_error is not None:
            self._loop.wait_cycle(0.1)  # type: ignore[union-attr]  # deliver the exit frames
            raise self._enable_error
        self._wait_for(lambda: self._gain_scale >= 1.0, self.enable_ramp + 1.0, "the gains to ramp up")

    def disable(self) -> None:
        """Damp every joint (kp = 0) for ``stop_damping_time`` s, then exit motor mode. Blocks."""
        self._require_open()
        if self._mode in ("disabled",):
            return
        with self._lock:
            if self._mode != "stopping":
                self._begin_stop()
        self._wait_disabled()

    def _wait_disabled(self) -> None:
        """Wait for the stop sequence to end, then one more cycle so its exit frames are delivered."""
        self._wait_for(lambda: self._mode == "disabled", self.stop_damping_time + 2.0, "the arm to disable",
                       raise_fault=False)
        if self._loop is not None:
            self._loop.wait_cycle(0.1)

    @property
    def enabled(self) -> bool:
        """True while the arm is enabled and tracking."""
        return self._mode == "active"

    # ------------------------------------------------------------------------------------------
    # motion
    # ------------------------------------------------------------------------------------------
    def _target_vector(self, target: Target) -> np.ndarray:
        if isinstance(target, str):
            return np.array(self.config.pose(target), dtype=float)
        if isinstance(target, Mapping):
            q = self._desired_now()[0].copy()
            for name, value in target.items():
                if name not in self.names:
                    raise LimitError(f"no joint named {name!r}", fix="joints are: " + ", ".join(self.names))
                q[self.names.index(name)] = float(value)
            return q
        q = np.asarray(target, dtype=float).reshape(-1)
        if q.shape != (self.n,):
            raise LimitError(f"target has {q.size} values, the arm has {self.n} joints",
                             fix="give one angle (rad) per joint in config order: " + ", ".join(self.names))
        return q

    def _desired_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The commanded (q, dq, ddq) at the current clock time."""
        with self._lock:
            if self._plan is not None:
                return self._plan.sample(self.clock.now())
            return self._hold.copy(), np.zeros(self.n), np.zeros(self.n)

    def _start(self, make_plan) -> Motion:
        self._require_enabled()
        with self._lock:
            now = self.clock.now()
            start = self._plan.sample(now) if self._plan is not None else (self._hold, np.zeros(self.n),
                                                                           np.zeros(self.n))
            plan = make_plan(start, now)
            motion = Motion(self, plan)
            if self._motion is not None:
                self._motion._finish(superseded=True)
            self._plan, self._motion = plan, motion
        return motion

    def move_to(self, target: Target, speed: float = 1.0, wait: bool = True) -> Motion:
        """Move to ``target``: jerk-limited, every joint arriving together.

        Args:
            target: joint positions (rad, config order), a named pose from the YAML, or a mapping
                ``{joint: rad}`` (other joints keep their commanded position).
            speed: fraction of the joint limits, in (0, 1]: the same path, 1/speed times slower.
            wait: block until the motion ends.

        Raises:
            LimitError: the target or any point of the planned path is outside a joint's range
                (checked before anything moves; names the joint).
        """
        q = self._target_vector(target)
        return self._run(self._start(lambda start, now: Plan([self.planner.move(start, q, now, speed)])), wait)

    def move_through(self, points: Sequence[Target], speed: float = 1.0, wait: bool = True) -> Motion:
        """Move through every point without stopping at the intermediate ones; end at rest on the last.

        Each intermediate point is passed exactly (the path is continuous in position, velocity and
        acceleration). ``points`` are joint vectors, pose names or mappings; ``speed`` as in
        :meth:`move_to`. Raises :class:`~akarm.LimitError` before moving if any point or any
        position on the path is outside a joint's range.
        """
        qs = [self._target_vector(p) for p in points]
        return self._run(self._start(lambda start, now: self.planner.through(start, qs, now, speed)), wait)

    def stream_to(self, target: Target, speed: float = 1.0) -> Motion:
        """Retarget online: from the current commanded state (position, velocity, acceleration) to
        ``target``, without a jump. Does not block; call it as often as new targets arrive."""
        q = self._target_vector(target)
        return self._start(lambda start, now: Plan([self.planner.move(start, q, now, speed)]))

    def stop(self, wait: bool = True) -> Motion:
        """Bring the commanded motion to rest, jerk-limited, and hold there."""
        return self._run(self._start(lambda start, now: Plan([self.planner.stop(start, now)])), wait)

    def hold(self) -> None:
        """Hold the current commanded position (stopping, jerk-limited, first if moving)."""
        self._require_enabled()
        with self._lock:
            moving = self._plan is not None and not self._plan.done(self.clock.now())
        if moving:
            self.stop(wait=True)

    def _run(self, motion: Motion, wait: bool) -> Motion:
        return motion.wait() if wait else motion

    @property
    def moving(self) -> bool:
        """True while a motion is being executed."""
        return self._plan is not None

    def set_gains(self, kp: Sequence[float] | float | None = None, kd: Sequence[float] | float | None = None) -> None:
        """Change MIT gains while running: kp in N·m/rad (0-500), kd in N·m·s/rad (0-5), per joint or one for all.

        ``set_gains(kp=0, kd=0.5)`` with :meth:`set_extra_torque` gives pure torque control with
        the arm's weight carried: joints with kp = 0 get their gravity torque at the *measured* pose
        (they are not held at the commanded one). Servo joints ignore gains.
        """
        with self._lock:
            for arr, new, hi, what in ((self._kp, kp, 500.0, "kp"), (self._kd, kd, 5.0, "kd")):
                if new is None:
                    continue
                v = np.broadcast_to(np.asarray(new, dtype=float), (self.n,))
                if not np.all(np.isfinite(v)) or np.any(v < 0) or np.any(v > hi):
                    raise LimitError(f"{what} must be within 0-{hi:g}, got {list(v)}",
                                     fix=f"pass {what} in the MIT range 0-{hi:g}")
                arr[:] = v
            self._gains_changed()

    def _gains_changed(self) -> None:
        """Refresh the hot path's per-joint gain constants (plain floats: numpy scalars are slow there)."""
        self._kp_list, self._kd_list = self._kp.tolist(), self._kd.tolist()
        self._ki = [self._hold_integral * kp if m else 0.0 for kp, m in zip(self._kp_list, self._is_mit, strict=True)]
        self._limp = [i for i in range(self.n) if self._is_mit[i] and self._kp_list[i] == 0.0]  # MIT, kp = 0

    def set_extra_torque(self, tau: Sequence[float] | None) -> None:
        """Add ``tau`` (N·m per joint, config order; ``None`` clears) to every MIT command's torque,
        on top of the feed-forward, clamped to each joint's torque limit."""
        with self._lock:
            if tau is None:
                self._extra = [0.0] * self.n
                return
            v = np.asarray(tau, dtype=float).reshape(-1)
            if v.shape != (self.n,) or not np.all(np.isfinite(v)):
                raise LimitError(f"extra torque needs {self.n} finite values (N·m)", fix="one per joint, config order")
            self._extra = v.tolist()

    # ------------------------------------------------------------------------------------------
    # teach and replay
    # ------------------------------------------------------------------------------------------
    def teach(self, damping: float = 0.1) -> None:
        """Make the arm hand-guidable, its weight carried, until :meth:`end_teach`.

        MIT joints: kp = 0, kd = ``damping`` (N·m·s/rad, at most the joint's own kd), gravity
        feed-forward at the measured pose. Servo joints: current mode with the gravity current
        (``g(q) / (kt · gear_ratio)``). The watchdog stays on.
        """
        self._require_enabled()
        for j in self.joints:
            if isinstance(j, ServoJoint) and j.motor.kt is None:
                raise ConfigError([ConfigProblem(str(self.config.source or self.config.name), None,
                                                 f"joint {j.name!r}: motor {j.motor.name} has no kt",
                                                 "set kt (N·m/A at the rotor) under `motors:` to teach servo joints")])
        self.hold()
        with self._lock:
            self._teach_damping = np.minimum(damping, self._kd)
            self._plan, self._motion = None, None
            self._mode = "teach"

    def keyframe(self, name: str | None = None) -> rec_mod.Keyframe:
        """The measured pose now, as a keyframe (rad, config order) with an optional name."""
        with self._lock:
            return rec_mod.Keyframe(tuple(float(j.state.position) for j in self.joints), name)

    def start_recording(self, rate_hz: float = 50.0, duration: float | None = None) -> None:
        """Start recording the measured pose continuously at ``rate_hz`` (in teach mode).

        With ``duration`` (s) the loop itself stops sampling once that much is recorded, so the
        path is ``duration`` long and holds ``floor(duration * rate_hz) + 1`` samples however late
        the caller gets round to :meth:`stop_recording`; :attr:`recording_finished` tells when.
        """
        if self._mode != "teach":
            raise StateError("recording a path needs teach mode", fix="call arm.teach() first")
        if not 0 < rate_hz <= self.config.rate_hz:
            raise StateError(f"rate_hz must be in (0, {self.config.rate_hz:g}] (the loop rate)")
        if duration is not None and not 0 < duration < math.inf:
            raise StateError(f"duration must be a positive number of seconds, not {duration}")
        with self._lock:
            self._recorder = _PathRecorder(rate_hz, duration)

    @property
    def recording_finished(self) -> bool:
        """True once a recording started with a ``duration`` has all its samples (False with none)."""
        rec = self._recorder
        return rec is not None and rec.finished

    def stop_recording(self) -> rec_mod.PathRecording:
        """Stop the continuous recording and return it (times from 0, s; positions rad)."""
        with self._lock:
            rec, self._recorder = self._recorder, None
        if rec is None or len(rec.times) < 2:
            raise StateError("no path was recorded", fix="call start_recording() and move the arm for a while")
        t = np.array(rec.times) - rec.times[0]
        return rec_mod.PathRecording(self.names, t, np.array(rec.positions))

    def end_teach(self) -> None:
        """Leave teach mode: hold the pose the arm was left in, gains ramping up from zero."""
        with self._lock:
            if self._mode != "teach":
                return
            self._recorder = None
            q = np.array([j.state.position for j in self.joints])
            self._hold = q
            self._des = (q.copy(), np.zeros(self.n), np.zeros(self.n))
            self._t_active = self.clock.now()
            self._gain_scale = 0.0 if self.enable_ramp > 0 else 1.0
            self._integral = [0.0] * self.n
            self._mode = "active"
        self._wait_for(lambda: self._gain_scale >= 1.0, self.enable_ramp + 1.0, "the gains to ramp up")

    def check_replay(self, recording: rec_mod.Keyframes | rec_mod.PathRecording | str | PathLike[str],
                     speed: float = 1.0) -> rec_mod.Keyframes | rec_mod.PathRecording:
        """Load and check a recording against every limit without moving (nor enabling) the arm.

        Returns the recording. Raises :class:`~akarm.RecordingError` or :class:`~akarm.LimitError`
        exactly as :meth:`replay` would before moving. Keyframes are checked for position and
        planned (from rest at the first keyframe) so a path past a limit is found too.
        """
        rec = recording if isinstance(recording, rec_mod.Keyframes | rec_mod.PathRecording) else \
            rec_mod.load(recording, self.names)
        if tuple(rec.joint_names) != tuple(self.names):
            raise LimitError(f"the recording is for joints {list(rec.joint_names)}",
                             fix=f"replay it on an arm with joints {list(self.names)}")
        if isinstance(rec, rec_mod.Keyframes):
            lim = self.limits
            for k, frame in enumerate(rec.frames):
                for i, q in enumerate(frame.q):
                    if not lim.lower[i] - 1e-9 <= q <= lim.upper[i] + 1e-9:
                        label = f" {frame.name!r}" if frame.name else ""
                        raise LimitError(f"keyframe {k}{label} is at {q:+.4f} rad, outside "
                                         f"[{lim.lower[i]:+.4f}, {lim.upper[i]:+.4f}] rad", joint=self.names[i],
                                         fix="edit that keyframe or the joint limits")
            qs = [np.array(f.q) for f in rec.frames]
            self.planner.through((qs[0], np.zeros(self.n), np.zeros(self.n)), qs, 0.0, min(speed, 1.0))
        else:
            rec_mod.check_path(rec_mod.PathPlan(rec, 0.0, speed), self.limits)
        return rec

    def replay(self, recording: rec_mod.Keyframes | rec_mod.PathRecording | str | PathLike[str],
               speed: float = 1.0, wait: bool = True) -> Motion:
        """Replay a recording (or a recording file), checked against every limit before anything moves.

        A soft start first moves, jerk-limited, from wherever the arm is to the first point.
        Keyframes are then passed through as one smooth move (``speed`` as in :meth:`move_to`);
        a path is followed at its recorded timing divided by ``speed`` (any positive factor).

        Raises:
            RecordingError: an unreadable, truncated or mismatched file.
            LimitError: the path breaks a limit after scaling; names the joint and the time, and
                suggests the speed factor that would pass.
        """
        rec = self.check_replay(recording, speed)
        if isinstance(rec, rec_mod.Keyframes):
            return self.move_through([np.array(f.q) for f in rec.frames], speed=min(speed, 1.0), wait=wait)
        check = rec_mod.PathPlan(rec, 0.0, speed)

        def make(start, now):
            soft = self.planner.move(start, check.q[0], now, min(speed, 1.0))
            return Chain([Plan([soft]), rec_mod.PathPlan(rec, now + soft.duration, speed)])

        return self._run(self._start(make), wait)

    # ------------------------------------------------------------------------------------------
    # state, payload, time
    # ------------------------------------------------------------------------------------------
    def state(self) -> ArmState:
        """The latest feedback of every joint and the commanded position (see :class:`ArmState`)."""
        now = self.clock.now()
        with self._lock:
            reps = tuple(JointReport(j.name, j.state.position, j.state.velocity, j.state.torque,
                                     j.state.temperature, j.state.error, j.state.age(now)) for j in self.joints)
            q_des = self._des[0].copy()
        return ArmState(now, reps, np.array([r.position for r in reps]), np.array([r.velocity for r in reps]),
                        np.array([r.torque for r in reps]), q_des, self._mode == "active", self._plan is not None)

    def set_payload(self, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Tell the feed-forward about a payload at the tool frame: kg, centre of mass in the tool frame (m)."""
        with self._lock:
            self.model.set_payload(mass, com)

    def clear_payload(self) -> None:
        """Remove the payload from the feed-forward model."""
        with self._lock:
            self.model.clear_payload()

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of the arm's clock while the loop keeps the arm under control.

        With a stepped (simulated) clock this is what advances time. Raises the arm's
        :class:`~akarm.SafetyStop` if it stopped meanwhile.
        """
        end = self.clock.now() + seconds
        self._wait_for(lambda: self.clock.now() >= end - 1e-12, seconds + 5.0, "time to pass")

    def telemetry(self, since: float | None = None) -> TelemetryLog:
        """The recorded cycles (desired and measured q, dq, τ, feed-forward), oldest first."""
        with self._lock:
            return self.telemetry_ring.snapshot(since)

    def reset_stats(self) -> None:
        """Forget the loop timings measured so far (e.g. to leave start-up out of a benchmark)."""
        self._require_open()
        self._loop.stats.reset()  # type: ignore[union-attr]

    @property
    def realtime_report(self) -> str:
        """What the loop thread was granted of real-time priority, memory locking and CPU pinning (if it asked)."""
        return self._loop.realtime_report if self._loop is not None else "not open"

    @property
    def fault(self) -> SafetyStop | None:
        """The safety stop that disabled the arm (it is raised by the next call), or ``None``."""
        return self._fault

    def stats(self) -> StatsSummary:
        """Loop timing: achieved rate, lateness and period percentiles, missed slots, time per stage."""
        self._require_open()
        return self._loop.stats.summary()  # type: ignore[union-attr]

    # ------------------------------------------------------------------------------------------
    # waiting
    # ------------------------------------------------------------------------------------------
    def _require_open(self) -> None:
        if self._mode == "closed":
            raise StateError("the arm is not open", fix="use `with arm:` or call arm.open() first")

    def _require_enabled(self) -> None:
        self._raise_fault()
        if self._mode != "active":
            raise StateError(f"the arm is {self._mode}, not enabled", fix="call arm.enable() first")

    def _raise_fault(self) -> None:
        if self._fault is not None:
            if self._mode != "disabled":
                self._wait_disabled()
            raise self._fault

    def _wait_for(self, done, timeout: float, what: str, raise_fault: bool = True) -> None:
        loop = self._loop
        assert loop is not None
        end = self.clock.now() + timeout
        while True:
            if raise_fault and self._fault is not None:  # before `done`: a motion ended by a stop must raise
                self._raise_fault()
            if done():
                return
            if loop.crashed is not None:
                raise StateError(f"the control loop crashed: {loop.crashed!r}",
                                 fix="this is a bug in akarm; please report it with the traceback in the log")
            if self.clock.now() > end:
                raise StateError(f"timed out after {timeout:.2f} s waiting for {what}")
            loop.wait_cycle(0.1)

    # ------------------------------------------------------------------------------------------
    # the cycle (runs in the loop thread, or inline with a stepped clock)
    # ------------------------------------------------------------------------------------------
    def _crashed(self, exc: BaseException) -> None:
        """The loop died of a bug: tell every motor to go limp, as a last resort."""
        for j in self.joints:
            frames = j.exit_frames() if isinstance(j, MitJoint) else [j.release()]  # type: ignore[union-attr]
            for f in frames:
                self._send(j, f)

    def _send(self, j: Joint, msg) -> None:
        bus = self._buses.get(j.bus)
        if bus is None:
            return
        try:
            bus.send(msg)  # type: ignore[attr-defined]
            self._send_errors = 0
        except Exception:  # a full TX queue or unplugged adapter: counted; 20 in a row stop the arm
            self._send_errors += 1
        if self._can_logger is not None:
            msg.timestamp = time.time()
            self._can_logger.on_message_received(msg)

    def _begin_stop(self, fault: SafetyStop | None = None) -> None:
        if fault is not None and self._fault is None:
            self._fault = fault
        if self._mode == "stopping":
            return
        self._mode = "stopping"
        self._t_stop = self.clock.now()
        self._stop_from = np.array([self._ff[i] for i in range(self.n)])
        if self._motion is not None:
            self._motion._finish(superseded=True)
        self._plan, self._motion = None, None

    def _check_safety(self, now: float) -> None:
        for j, limit, max_temp in zip(self.joints, self._timeouts, self._max_temp, strict=True):
            s = j.state
            age = now - s.stamp
            if age > limit:
                self._begin_stop(FeedbackTimeout(
                    f"no feedback for {age * 1e3:.0f} ms (limit {limit * 1e3:.0f} ms); the arm was "
                    f"damped and disabled", age=age, joint=j.name,
                    fix="check the motor's power and CAN wiring, its CAN ID, the bit rate, and the bus load"))
                return
            if s.error:
                desc, remedy = describe_error(s.error)
                self._begin_stop(MotorFault(f"motor reports error {s.error} ({desc}); the arm was damped and "
                                            f"disabled", code=s.error, joint=j.name, fix=remedy))
                return
            if s.temperature is not None and s.temperature > max_temp:
                self._begin_stop(OverTemperature(
                    f"temperature {s.temperature:.0f} °C is above the limit {max_temp:.0f} °C; "
                    f"the arm was damped and disabled", temperature=s.temperature, joint=j.name,
                    fix="let the motor cool; lower duty, speed or payload; check max_temperature in the YAML"))
                return
        if self._send_errors > 20:
            self._begin_stop(SafetyStop("more than 20 consecutive frames could not be sent; the arm was damped "
                                        "and disabled", fix="check the CAN adapter, the cabling and termination"))

    def _cycle(self, now: float, slot: int) -> None:
        pc = time.perf_counter
        stage = self._loop.stats.stage[slot]  # type: ignore[union-attr]
        t0 = pc()
        logger = self._can_logger
        for name, bus in self._buses.items():
            route = self._routers[name].route
            recv = bus.recv  # type: ignore[attr-defined]
            for _ in range(_DRAIN_LIMIT):  # everything already received, never waiting
                msg = recv(0.0)
                if msg is None:
                    break
                route(msg, now)
                if logger is not None:
                    logger.on_message_received(msg)
        t1 = pc()
        stage[0] = t1 - t0
        mode = self._mode
        if mode == "disabled" or mode == "closed":
            return
        with self._lock:
            if mode == "enabling":
                self._cycle_enabling(now)
                return
            if mode == "active" or mode == "teach":
                self._check_safety(now)
            t2 = pc()
            stage[1] = t2 - t1
            if self._mode == "stopping":
                self._cycle_stopping(now)
                return
            if self._mode == "teach":
                self._cycle_teach(now)
                return
            # trajectory
            plan = self._plan
            if plan is not None:
                q_d, dq_d, ddq_d = plan.sample(now)
                if plan.done(now):
                    self._hold = q_d.copy()
                    self._plan = None
                    if self._motion is not None:
                        self._motion._finish()
                        self._motion = None
            else:
                q_d, dq_d, ddq_d = self._hold, np.zeros(self.n), np.zeros(self.n)
            self._des = (q_d, dq_d, ddq_d)
            t3 = pc()
            stage[2] = t3 - t2
            # feed-forward: the rigid-body model (Pinocchio), then friction, hold integral, user torque
            # and clamping per joint in plain floats (for six values numpy's per-call overhead costs
            # more than the arithmetic)
            if self.feedforward == "full":
                model_tau = self.model.inverse_dynamics(q_d, dq_d, ddq_d).tolist()
            elif self.feedforward == "gravity":
                model_tau = self.model.gravity(q_d).tolist()
            else:
                model_tau = [0.0] * self.n
            if self._limp and self.feedforward != "none":
                # joints without stiffness are not at the commanded pose: carry their weight where they are
                g_meas = self.model.gravity([j.state.position for j in self.joints]).tolist()
                for i in self._limp:
                    model_tau[i] = g_meas[i]
            qd, vd = q_d.tolist(), dq_d.tolist()
            holding = plan is None and self._gain_scale >= 1.0
            dt = now - self._t_last
            self._t_last = now
            c, b, ex, lim, ki, imax = self._fric_c, self._fric_b, self._extra, self._tlim, self._ki, self._imax
            integ, js = self._integral, self.joints
            ff = [0.0] * self.n
            for i in range(self.n):
                v = vd[i]
                t = model_tau[i] + c[i] * math.tanh(v * _INV_FRICTION_SMOOTHING) + b[i] * v + ex[i]
                if holding:
                    if ki[i] > 0.0:
                        ti = ki[i] * (integ[i] + (qd[i] - js[i].state.position) * dt)
                        ti = imax[i] if ti > imax[i] else -imax[i] if ti < -imax[i] else ti
                        integ[i] = ti / ki[i]
                        t += ti
                else:
                    integ[i] = 0.0
                ff[i] = lim[i] if t > lim[i] else -lim[i] if t < -lim[i] else t
            self._ff = ff
            t4 = pc()
            stage[3] = t4 - t3
            # send
            if self._gain_scale < 1.0:
                self._gain_scale = min(1.0, (now - self._t_active) / self.enable_ramp) if self.enable_ramp > 0 else 1.0
            g = self._gain_scale
            kp, kd = self._kp_list, self._kd_list
            for i, j in enumerate(js):
                if isinstance(j, MitJoint):
                    msg = j.command(qd[i], vd[i], kp[i] * g, kd[i] * g, ff[i])
                else:
                    msg = j.command(qd[i])  # type: ignore[attr-defined]
                self._send(j, msg)
            t5 = pc()
            stage[4] = t5 - t4
            self._record(now, qd, vd, ff)
            stage[5] = pc() - t5

    def _record(self, now: float, q_d, dq_d, ff) -> None:
        states = [j.state for j in self.joints]
        self.telemetry_ring.record(now, q_d, dq_d, [s.position for s in states], [s.velocity for s in states],
                                   [s.torque for s in states], ff)

    def _cycle_teach(self, now: float) -> None:
        """Hand guiding: no stiffness, a little damping, the arm's weight carried (at the measured pose)."""
        q = np.array([j.state.position for j in self.joints])
        g = np.clip(self.model.gravity(q), -self._torque_limit, self._torque_limit)
        for i, j in enumerate(self.joints):
            if isinstance(j, MitJoint):
                self._send(j, j.command(math.nan, 0.0, 0.0, self._teach_damping[i], g[i]))
            else:
                amps = units.torque_to_amps(j.motor, g[i] * j.direction)
                self._send(j, j.current(amps))  # type: ignore[attr-defined]
        self._des = (q, np.zeros(self.n), np.zeros(self.n))
        self._ff = g
        rec = self._recorder
        if rec is not None:
            rec.sample(now, q)
        self._record(now, q, np.zeros(self.n), g)

    def _cycle_enabling(self, now: float) -> None:
        first = not self._entered
        for j in self.joints:
            if isinstance(j, MitJoint):
                if first:
                    for f in j.enter_frames():
                        self._send(j, f)
                # zero gains, zero torque: overrides the remembered command and asks for a reply
                self._send(j, j.command(math.nan, 0.0, 0.0, 0.0, 0.0))
        self._entered = True
        missing = [j for j in self.joints if j.state.stamp < self._t_enable]
        if not missing:
            q = np.array([j.state.position for j in self.joints])
            self._hold = q
            self._des = (q.copy(), np.zeros(self.n), np.zeros(self.n))
            self._plan = None
            self._t_active = now
            self._gain_scale = 0.0 if self.enable_ramp > 0 else 1.0
            self._integral = [0.0] * self.n
            self._entered = False
            self._mode = "active"
            return
        if now - self._t_enable > self._enable_timeout:
            names = ", ".join(j.name for j in missing)
            for j in self.joints:
                if isinstance(j, MitJoint):
                    for f in j.exit_frames():
                        self._send(j, f)
            self._entered = False
            self._enable_error = FeedbackTimeout(
                f"no answer within {self._enable_timeout * 1e3:.0f} ms from: {names}; nothing was enabled",
                age=now - self._t_enable, joint=missing[0].name,
                fix="check power, CAN wiring and bit rate, the CAN ID, and that the motor is in the configured "
                    "mode (MIT or servo)")
            self._mode = "disabled"

    def _cycle_stopping(self, now: float) -> None:
        """Damping (kp = 0, feed-forward fading out) for stop_damping_time, then exit."""
        T = self.stop_damping_time
        s = (now - self._t_stop) / T if T > 0 else 1.0
        js = self.joints
        if s < 1.0:
            fade = 1.0 - s
            for i, j in enumerate(js):
                if isinstance(j, MitJoint):
                    kd = max(self._kd[i], 0.5)
                    self._send(j, j.command(math.nan, 0.0, 0.0, min(kd, j.motor.kd_max),
                                            self._stop_from[i] * fade))
                else:
                    rated = j.motor.rated_current or 2.0
                    self._send(j, j.brake(0.5 * rated))  # type: ignore[attr-defined]
            self._record(now, self._des[0], np.zeros(self.n), self._stop_from * fade)
            return
        for j in js:
            if isinstance(j, MitJoint):
                self._send(j, j.command(math.nan, 0.0, 0.0, 0.0, 0.0))
                for f in j.exit_frames():
                    self._send(j, f)
            elif isinstance(j, ServoJoint):
                self._send(j, j.release())
        self._gain_scale = 0.0
        self._mode = "disabled"
