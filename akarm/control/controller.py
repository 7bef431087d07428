"""The arm's real-time side: the mode machine, and what every cycle of the loop does.

:class:`Controller` is what the control loop calls, once per period (in its own thread, or inline
in lock step). :class:`~akarm.Arm`, the user's API, asks it for changes (enable, a new plan, teach,
stop) under its lock and waits for them. It is built complete, from the robot, its model and
planner, a clock and one :class:`~akarm.control.options.ControllerOptions`, and composes objects
that each do one job:

- :class:`~akarm.control.busset.BusSet`: the buses (open, drain and route, send, a lost bus);
- :class:`~akarm.control.enabler.Enabler` and :class:`~akarm.control.enabler.GainRamp`: enabling
  without a kick (listen, contact, settle, ramp);
- :class:`~akarm.control.motions.Motions`: the plan being followed and its
  :class:`~akarm.control.motions.Motion`, or the pose held;
- :class:`~akarm.control.exits.Exits`: the one way out of a program (close, atexit, finalizer, signals);
- :class:`~akarm.control.safety.Supervisor`, :class:`~akarm.control.feedforward.FeedForward`,
  :class:`~akarm.control.collision.CollisionReflex`: the checks, the torque, the reflex.

A cycle: **receive** (drain every bus, route each frame to its joint, which gates it), then by mode:

- ENABLING: the enabler's step (contact, then damping until the arm is at rest), then hold where it
  is with kp ramping up.
- ACTIVE: **trajectory** (sample the plan at the clock's time), **safety** (the supervisor and the
  collision reflex), **feed-forward**, **send** one frame per joint, **telemetry**.
- TEACH: safety, then no stiffness, damping, the arm's weight at the measured pose.
- STOPPING: damping with the feed-forward fading out, then the exit frames.

The loop thread holds only the controller, never the Arm, so an Arm dropped while enabled can be collected.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
import warnings
import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm.buses.frames import message
from akarm.clock import Clock
from akarm.config import JointConfig, RobotConfig
from akarm.control.busset import BusSet
from akarm.control.collision import CollisionReflex, reflex_for, uncertainty_for
from akarm.control.enabler import FOREIGN_RECENT, LISTEN, Enabler, GainRamp, Refusal
from akarm.control.exits import Exits, UnsafeExitWarning
from akarm.control.feedforward import FeedForward
from akarm.control.gripper import GripperDrive
from akarm.control.guard import ContactWatch
from akarm.control.impedance import ImpedanceLaw
from akarm.control.joints import Joint, make_joint
from akarm.control.loop import ControlLoop, StatsSummary, collector_paused, keep_from_collections
from akarm.control.modes import Mode, ModeMachine
from akarm.control.motions import Motion, Motions, PathRecorder, State
from akarm.control.options import ControllerOptions
from akarm.control.safety import Guard, Supervisor, default_following_error, default_stuck_travel
from akarm.control.selfcollision import SelfCollisionGuard
from akarm.control.turns import WEIGH_TIMEOUT, GravityTurnCheck, PositionMemory, Weighed, Weighing, stays_put
from akarm.control.walls import WallGuard
from akarm.dynamics.model import RobotModel
from akarm.errors import (
    AkarmError,
    ArgumentError,
    BusLost,
    CollisionError,
    LoopCrashed,
    LoopStall,
    SafetyStop,
    StateError,
)
from akarm.motion.trajectory import Plan, Planner, release
from akarm.telemetry.log import FIELDS, MAX_TELEMETRY_VALUES, Telemetry, TelemetryLog

if TYPE_CHECKING:
    import can

    from akarm.motion.trajectory import Timed

__all__ = ["PLAN_ATTEMPTS", "RELEASES", "STAGES", "WAIT_SLICE", "WAKE_BACKSTOP", "Controller"]

log = logging.getLogger(__name__)

STAGES = ("receive", "trajectory", "safety", "feedforward", "send", "telemetry")
#: Plans made for one motion at most before it is refused: each one that comes too late to take over
#: from a moving arm is made again to start twice as far ahead (the first starts where the arm is now).
PLAN_ATTEMPTS = 6
#: segments from which a plan is left out of later garbage collections while its loop runs
#: (akarm.control.loop.keep_from_collections): each full collection would scan its objects again
BIG_PLAN = 1000
#: cycles in a row a stop sends the exit (MIT: zero-gain command, EXIT) or release frames on: the
#: frames are idempotent, and one lost frame (a driver's full receive queue, a reader that fell
#: behind) must not leave a motor in motor mode, powered, after its program has let go of it
RELEASES = 3
#: s: how often a caller waiting for a time (``Arm.sleep``) looks for a stop, a close or a crash
#: meanwhile (:meth:`Controller.wait_for`)
WAIT_SLICE = 0.01
#: s: how often a caller waiting for an event that those set too (a motion's end: a stop, a close
#: and a crash of the loop end the motion) looks anyway: a backstop, not the way it learns of them
WAKE_BACKSTOP = 0.1


def _feedback_timeout(j: JointConfig, default: float) -> float:
    """A joint's watchdog limit: its own, else ``default`` (servo joints: at least three status periods)."""
    if j.feedback_timeout is not None:
        return float(j.feedback_timeout)
    if j.mode == "servo":
        return max(default, 3.0 / j.status_rate_hz)
    return default


def _contact_period(rate_hz: float | None) -> float | None:
    """s between an enable's contact cycles at a timing profile's ``contact_rate_hz`` (``None``: the loop's)."""
    return None if rate_hz is None else 1.0 / rate_hz


class Controller:
    """The real-time side of an :class:`~akarm.Arm` (see the module's docstring).

    Everything that changes what the loop does is done under :attr:`lock`, through its methods;
    nothing is set on it from outside.

    Args:
        config: the robot (the timing profile already applied).
        model: the arm's dynamics (the feed-forward's and the collision observer's; its payload is
            changed through :meth:`set_payload`).
        planner: plans the collision reflex's stop (the "hold" reaction).
        clock: the loop's clock.
        options: everything else.
    """

    def __init__(self, config: RobotConfig, model: RobotModel, planner: Planner, clock: Clock,
                 options: ControllerOptions) -> None:
        self.config = config
        self.options = options
        self.joints: list[Joint] = [make_joint(i, j) for i, j in enumerate(config.joints)]
        self.n = n = len(self.joints)
        # the gripper's motor: a joint after the arm's for the buses, the enabler and the supervisor, never
        # one of the arm's (every arm vector has n values); its drive makes its command each cycle
        self.gripper: GripperDrive | None = None
        if config.gripper is not None:
            self.gripper = GripperDrive(config.gripper, make_joint(n, config.gripper.joint), 1.0 / config.rate_hz)
        #: every motor: the arm's joints, then the gripper's
        self.motors: list[Joint] = self.joints + ([self.gripper.joint] if self.gripper is not None else [])
        self.model = model
        self.planner = planner
        self.clock = clock
        self.period = 1.0 / config.rate_hz
        self.lock = threading.RLock()
        self.modes = ModeMachine()
        # the ring holds at most what a telemetry file may (MAX_TELEMETRY_VALUES): it can always be saved
        # and read back, and a mistyped telemetry_seconds (1e12) is refused instead of a MemoryError
        longest = MAX_TELEMETRY_VALUES / ((1 + len(FIELDS) * n) * config.rate_hz)
        if options.telemetry_seconds > longest:
            raise ArgumentError(f"telemetry_seconds {options.telemetry_seconds:g} is more than the telemetry ring "
                                f"holds: {longest:.0f} s of {n} joints at {config.rate_hz:g} Hz "
                                "(akarm.telemetry.log.MAX_TELEMETRY_VALUES numbers, what a telemetry file may hold)",
                                fix=f"give telemetry_seconds of at most {longest:.0f}")
        self.telemetry = Telemetry(config.joint_names, max(1, int(options.telemetry_seconds * config.rate_hz)))
        if self.gripper is not None:
            self.gripper.keep(self.telemetry.capacity)
        joints = self.joints

        lim = [j.limits for j in config.joints]
        self.torque_limit = np.array([x.torque for x in lim])
        self._kp = np.array([j.gains.kp for j in config.joints])
        self._kd = np.array([j.gains.kd for j in config.joints])
        self._mit = [j.answers_commands for j in joints]
        self._t_max = [j.motor.t_max * 0.999 if j.answers_commands else math.inf for j in joints]
        self._saturated = [False] * len(self.motors)  # (the gripper's stays False: its stall is a grasp)
        fr = [j.friction_model() for j in config.joints]
        self._coulomb = [f.coulomb for f in fr]  # what holds a limp joint (the turn memory asks)
        on = 1.0 if options.friction_compensated else 0.0
        self.ff = FeedForward(model, options.feedforward, [f.coulomb * on for f in fr], [f.viscous * on for f in fr],
                              self.torque_limit, options.hold_integral, self._mit)
        self.ff.set_friction([f.coulomb * on for f in fr], [f.viscous * on for f in fr], [f.torque_scale for f in fr],
                             [f.load * on for f in fr])
        # the damping used to settle at enable and to stop: the joint's kd, at least 0.5 N·m·s/rad
        self._damping = [min(max(float(kd), 0.5), j.motor.kd_max) for kd, j in zip(self._kd, joints, strict=True)]
        self._timeouts = [_feedback_timeout(j.config, options.watchdog) for j in joints]
        motors = self.motors
        for j in motors:  # a reply the motor cannot have reached since the last one is rejected
            j.set_gate(1.5 * j.motor.v_max, self.period)
        if self.gripper is not None:
            gj = self.gripper.joint
            self._gripper_timeout = _feedback_timeout(gj.config, options.watchdog)
            self._gripper_damping = min(max(gj.config.gains.kd, 0.5), gj.motor.kd_max)
        self.supervisor = Supervisor(motors, self._guards(), period=self.period,
                                     implausible_limit=options.implausible_limit, lag=options.timing.lag)
        self.stall_limit = options.loop_stall_limit
        self._gains_changed()

        self.bus = BusSet(config, motors, options.can_log, self._bus_lost, clock.now)
        self.supervisor.simulator_late = self._simulator_late
        self.motions = Motions(n, self.wait_for)
        self.ramp = GainRamp(options.enable_ramp)
        gravity: Callable[[Sequence[float]], np.ndarray] = self.ff.gravity
        commanded, damping, timeouts = self._commanded, self._damping, self._timeouts
        if self.gripper is not None:  # the gripper's motor is enabled with the arm's: contact, damping
            gravity, commanded = self._gravity_and_gripper, self._commanded_arm
            damping, timeouts = [*damping, self._gripper_damping], [*timeouts, self._gripper_timeout]
        self.enabler = Enabler(motors, config.buses, self.bus.send, self.supervisor, gravity, commanded,
                               damping=damping, timeouts=timeouts, period=self.period,
                               settle_speed=options.settle_speed, settle_timeout=options.settle_timeout,
                               at_contact=self._turn_check, lag=options.timing.lag,
                               contact_period=_contact_period(options.timing.contact_rate_hz))
        self.reflex = self._make_reflex()
        # a torque law (impedance, akarm.control.impedance): its torque each cycle, kp = 0 meanwhile
        self.law: ImpedanceLaw | None = None
        self._saved_gains = (self._kp.copy(), self._kd.copy())  # (kp, kd) before it
        # a guarded move's contact watch (akarm.control.guard)
        self.watch: ContactWatch | None = None
        # the collision thresholds in force, suspended (the reflex only watches) while a torque law or a watch
        # runs: how many of them suspend them (one at a time: each refuses the other), and what they are
        self._suspended = 0
        self._held_thresholds = np.zeros(n)
        # the robot file's walls: the tool measured outside them is a safety stop (akarm.control.walls)
        self.walls = WallGuard(model, config.workspace) if config.workspace is not None else None
        # the links measured touching (the planner keeps them a margin apart): a safety stop
        sc = options.self_collision
        self.self_collision = (None if sc is None else
                               SelfCollisionGuard(sc.copy(margin=0.0), config.rate_hz, sc.margin))
        self.loop = ControlLoop(config.rate_hz, clock, self.cycle, stages=STAGES,
                                realtime_priority=options.realtime_priority, cpu=options.loop_cpu,
                                on_crash=self._crashed)
        self.exits = Exits(self._shutdown, lambda: self.modes.mode is not Mode.CLOSED, self._on_loop_thread,
                           options.stop_damping_time + 5.0)

        self.des: State = (np.zeros(n), np.zeros(n), np.zeros(n))  # the commanded state this cycle
        self.tau_ff: list[float] | np.ndarray = [0.0] * n  # the feed-forward torque of the last command
        self.fault: SafetyStop | None = None
        self.enable_error: AkarmError | None = None
        self.recorder: PathRecorder | None = None
        self._teach_damping = [0.0] * n
        self._t_open = 0.0
        self._t_last = 0.0
        self._t_stop = 0.0
        self._stop_from = np.zeros(n)
        # plan time: the clock less the slots the loop missed (a stalled loop resumes where its plan was)
        self._lag = 0.0
        self._t_plan = 0.0  # the plan time of the cycle running (or last run)
        # the turn check (akarm.control.turns): positions remembered when the arm stops, compared at enable
        self.positions = PositionMemory(options.position_file, config.joints) if options.position_file else None
        self._remembered: dict[str, float] | None = None  # what this enable compares with (None: accepted)
        self._positions_known = False  # the readings passed the turn check: a stop may remember them
        self._stop_q = [0.0] * n  # each joint's reading when the stop began
        self._releases = 0  # the cycles the exit frames were sent on, this stop
        self._damp_time = options.stop_damping_time  # s of damping this stop (none for a refused enable)
        self._stop_stale = [False] * n  # its feedback went silent during the stop: remember _stop_q
        # the turn check by physics (akarm.control.turns.GravityTurnCheck): the torque holding the arm at
        # enable, weighed once the gains are in, before enable() returns and anything else is commanded
        self.turn_check = GravityTurnCheck(config.joints, self.ff.gravity, self._mit, model.lower, model.upper)
        self.turn_verdict: Weighed | None = None  # the last enable's (None: not weighed)
        self._weigh_next = False  # the enable under way weighs the arm
        self._weighing: Weighing | None = None  # weighing now

    def _make_reflex(self) -> CollisionReflex:
        options = self.options
        # a timing profile for machines that cannot keep time (lag > 0: replies late, then in bursts) leaves
        # the reflex watching only
        return reflex_for(self.config, self.model, options.collision_gain, options.collision_reaction,
                          watch_only=options.timing.lag > 0)

    def _guards(self) -> list[Guard]:
        out = []
        for j, kp, timeout in zip(self.config.joints, self._kp.tolist(), self._timeouts, strict=True):
            # (under a lag, the supervisor adds how far the command moved within it: what a reading that
            # trails by the lag may be behind)
            following = default_following_error(j, kp)
            out.append(Guard(timeout, j.max_temperature, following, default_stuck_travel(j, kp, following),
                             uncertainty_for(j).torque / kp if j.mode == "mit" and kp > 0 else 0.0))
        if self.gripper is not None:
            out.append(self.gripper.guard(self._gripper_timeout))
        return out

    def _gains_changed(self) -> None:
        """Refresh what depends on the gains (plain lists for the hot path; the supervisor's defaults)."""
        self._kp_list, self._kd_list = self._kp.tolist(), self._kd.tolist()
        self.ff.set_gains(self._kp_list)
        self._tracking = [(not m) or kp > 0.0 for m, kp in zip(self._mit, self._kp_list, strict=True)]
        if self.gripper is not None:
            self._tracking.append(False)  # the gripper's position is no tracking: its stall is a grasp
        self._reflex_kd = [k if m else 0.0 for k, m in zip(self._kd_list, self._mit, strict=True)]
        self._reflex_kp: tuple[float, list[float]] = (math.nan, [])  # (ramp scale, MIT kp at it): see _collision_check
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
        self.bus.open()
        self.fault = None
        self.modes.go(Mode.DISABLED)
        self._t_open = self.clock.now()
        self.loop.start()
        self.exits.opened()

    def close(self, warn: str | None = None) -> None:
        """Disable the arm if it may be powered (damping, then exit), stop the loop, close the buses.

        Never raises; signals (Ctrl-C, SIGTERM) are held back until the arm is disabled. ``warn``:
        a warning to give if the arm was still powered (the program ended, or dropped the Arm).
        """
        self.exits.close(warn)

    def track(self, owner: object) -> weakref.finalize:
        """Close (with a warning if still enabled) when ``owner`` (the Arm) is garbage-collected."""
        return self.exits.track(owner)

    def _shutdown(self, warn: str | None) -> None:
        """:meth:`close`'s sequence (run once, by :class:`~akarm.control.exits.Exits`)."""
        try:
            mode = self.modes.mode
            if mode.powered and mode is not Mode.FAULT:
                if warn is not None:
                    warnings.warn(warn, UnsafeExitWarning, stacklevel=5)
                if not self._on_loop_thread():  # (the loop cannot wait for its own cycles)
                    with contextlib.suppress(Exception):  # whatever fails, the frames below still go out
                        self.disable()
        finally:
            self.loop.stop()
            with self.lock:
                if self.modes.mode.powered:  # the stop did not run to its end (a stalled or dead loop): exit now
                    self._release_at_once()
                self.modes.go(Mode.CLOSED)
            self.bus.close()

    def _release_at_once(self, pause: float = 0.0) -> None:
        """The exit frames :data:`RELEASES` times, ``pause`` s apart, whatever fails: for a stop that
        did not run to its end (a stalled, dead or crashed loop)."""
        for _ in range(RELEASES):
            self.bus.release_all(suppress=True)
            if pause:
                time.sleep(pause)

    def _on_loop_thread(self) -> bool:
        return self.loop.thread is threading.current_thread()

    def _crashed(self, exc: BaseException) -> None:
        """The loop died of a bug (on its thread, after the cycle that raised): stop the arm as a stop
        does, damping then exit frames on :data:`RELEASES` cycles, without the cycle that failed (the
        stop's own steps, at the loop's period, in this thread); if they fail too, the exit frames at
        once, a few times. Then the arm is in FAULT with the crash (enable refuses: the loop is gone),
        and the motions end, which wakes their callers (they raise the crash)."""
        crash = LoopCrashed(f"the control loop crashed ({type(exc).__name__}: {exc}): this is a bug in akarm; the "
                            "arm was damped and disabled", fix="close the arm and open it again; report the bug "
                            "with the traceback the log shows")
        crash.__cause__ = exc
        try:
            if self.lock.acquire(timeout=1.0):  # (the cycle that raised let go of it)
                try:
                    self._begin_stop(crash)
                finally:
                    self.lock.release()
            deadline = time.monotonic() + self.options.stop_damping_time + (RELEASES + 5) * self.period
            while self.modes.mode is Mode.STOPPING and time.monotonic() < deadline:
                with self.lock:
                    self._t_plan += self.period
                    self._cycle_stopping(self.clock.now())
                time.sleep(self.period)
        except BaseException:  # the stop's own steps failed: the exit frames alone
            log.exception("stopping after the control loop crashed failed; sending the exit frames")
        finally:
            try:
                if self.modes.mode.powered:
                    self._release_at_once(self.period)
            finally:
                if self.lock.acquire(timeout=1.0):
                    try:
                        self.fault = self.fault or crash
                        if self.modes.mode is not Mode.FAULT:
                            self.modes.go(Mode.FAULT)
                        self.motions.cancel()
                    finally:
                        self.lock.release()

    def _bus_lost(self, stop: BusLost) -> None:
        """A bus failed under the arm (the bus set says so once): stop, or FAULT if nothing was powered."""
        with self.lock:
            mode = self.modes.mode
            if mode in (Mode.ACTIVE, Mode.TEACH, Mode.ENABLING, Mode.STOPPING):
                self._begin_stop(stop)
            elif mode is Mode.DISABLED:
                self.fault = self.fault or stop
                self.modes.go(Mode.FAULT)

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

    def wait_for(self, done: Callable[[], object], timeout: float, what: str, raise_fault: bool = True, *,
                 wake: threading.Event | None = None, until: float | None = None) -> None:
        """Wait (running cycles in lock step) until ``done()`` is true (any value that is: a numpy bool too,
        which a compiled ``bool`` return would refuse); raise the arm's fault if one comes first.

        With a real clock the caller looks at ``done()`` after every cycle, unless it says what can make
        it true: ``wake``, an event set when it may have (a motion's end, which a stop, a close and a
        crash of the loop set too), wakes it at once, and ``until``, the clock time at which it turns
        true by itself, ends its sleep there. Between, it looks for a stop, a close or a crash every
        :data:`WAIT_SLICE` (waiting for a time) or :data:`WAKE_BACKSTOP` (for an event that they set): a
        caller woken every cycle cost the process about 40 µs of CPU a cycle (a thread switch, the
        interpreter lock handed over and back), one woken every 10 ms about 10 µs.
        """
        loop = self.loop
        end = self.clock.now() + timeout
        while True:
            if raise_fault and self.fault is not None:  # before `done`: a motion ended by a stop must raise
                self.raise_fault()
            if loop.crashed is not None:  # before `done` too: the crash ended the motion
                raise StateError(f"the control loop crashed: {loop.crashed!r}",
                                 fix="this is a bug in akarm; please report it with the traceback in the log")
            if done():
                return
            self.require_open()  # closed meanwhile (another thread): nothing will change any more
            if self.clock.now() > end:
                raise StateError(f"timed out after {timeout:.2f} s waiting for {what}")
            if loop.stepped or (wake is None and until is None):
                loop.wait_cycle(0.1)
                continue
            slice_ = WAIT_SLICE if wake is None else WAKE_BACKSTOP
            pause = slice_ if until is None else min(slice_, until - self.clock.now())
            if pause <= 0.0:
                loop.wait_cycle(0.1)
            elif wake is not None:
                wake.wait(pause)
            else:
                time.sleep(pause)

    def _enable_refusal(self) -> AkarmError | None:
        """:attr:`enable_error`, read afresh: the loop's thread sets it while :meth:`enable` waits (a
        compiled ``enable`` would otherwise take it for the ``None`` it cleared earlier)."""
        return self.enable_error

    def enable(self, timeout: float | None = None, accept_position: bool = False) -> None:
        """Enable (see :meth:`Arm.enable`); blocks until held, or raises what refused it. ``timeout``:
        s for every joint's replies (default: the timing profile's); ``accept_position``: skip the
        turn check this once (the positions were checked by eye)."""
        self.require_open()
        if timeout is None:
            timeout = self.options.timing.enable_timeout
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
            self.wait_for(lambda: self.clock.now() - self._t_open >= LISTEN, LISTEN + 1.0, "the bus to be heard",
                          raise_fault=False)
        with self.lock:
            if self.modes.mode is not Mode.DISABLED:  # changed meanwhile (another thread, a lost bus)
                if self.modes.mode is Mode.FAULT:
                    raise self.fault or StateError("the arm is in fault", fix="close the arm and open it again")
                raise StateError(f"the arm became {self.modes.mode} while enable() waited: another thread "
                                 "enables or stops it", fix="enable and disable from one thread")
            now = self.clock.now()
            refused = self.enabler.refuse_foreign(now, now - FOREIGN_RECENT)
            if refused is not None:
                raise refused
            self._clear_errors()
            self.tau_ff = [0.0] * self.n  # a stop during contact fades from here, not the last session's torque
            self._remembered = None if accept_position or self.positions is None else self.positions.load()
            self._positions_known = False
            self._weigh_next = not accept_position and any(self._mit)
            self.turn_verdict = None
            longest = self.enabler.begin(now, timeout)
            self.modes.go(Mode.ENABLING)
            self._enable_begun(now)
        self.wait_for(lambda: self.modes.mode is not Mode.ENABLING,
                      longest + self.options.settle_timeout + 2.0, "the joints to answer and the arm to settle")
        refused_by = self._enable_refusal()
        if refused_by is not None:
            self.wait_disabled()  # the exit frames, on RELEASES cycles, delivered
            raise refused_by
        weigh = self.options.timing.lag + WEIGH_TIMEOUT  # (the turn check's weighing, at most)
        self.wait_for(lambda: self.modes.mode is not Mode.ACTIVE or (self.ramp.done and self._weighing is None),
                      self.options.enable_ramp + weigh + 1.0, "the gains to ramp up and the arm to be weighed")
        refused_by = self._enable_refusal()
        if refused_by is not None:  # the turn check by physics refused it: the arm is being lowered
            self.wait_disabled()
            raise refused_by
        self._forget_positions()

    def _enable_begun(self, now: float) -> None:
        """(Caller, an enable begun) Where contact runs faster than the loop (a slow profile), its first
        cycle comes at once, not at the loop's next slot. The self-collision guard judges once the arm was
        measured clear (it may be enabled folded into itself, and move out)."""
        if self.self_collision is not None:
            self.self_collision.disarm()
        soon = self.enabler.hurry(now)
        if soon is not None:
            self.loop.hasten(now + soon)

    def _clear_errors(self) -> None:
        # a method of its own: a type checker that saw these set to None in enable() would take them for
        # None there afterwards, while the loop's thread sets them (and mypyc checks what it reads)
        self.fault = None
        self.enable_error = None

    def disable(self, wait: bool = True) -> None:
        """Damp every joint for ``stop_damping_time``, then exit motor mode; ``wait``: until done."""
        self.require_open()
        with self.lock:
            self._begin_stop()
        if wait:
            self.wait_disabled()

    def wait_disabled(self) -> None:
        """Wait for the stop sequence to end, then one more cycle so its exit frames are delivered."""
        if self.modes.mode is Mode.STOPPING:
            self.wait_for(lambda: self.modes.mode is not Mode.STOPPING, self.options.stop_damping_time + 2.0,
                          "the arm to disable", raise_fault=False)
            self.loop.wait_cycle(0.1)

    def _begin_stop(self, fault: SafetyStop | None = None, damping: float | None = None) -> None:
        """Start damping (for ``damping`` s; default: the options' stop_damping_time), then exit
        (caller holds the lock or is the loop)."""
        if fault is not None and self.fault is None:
            self.fault = fault
        mode = self.modes.mode
        if mode is Mode.STOPPING or not mode.powered or mode is Mode.FAULT:
            return
        self.modes.go(Mode.STOPPING)
        self._damp_time = self.options.stop_damping_time if damping is None else damping
        self._t_stop = min(self.plan_now(), self._t_plan)
        now = self.clock.now()
        self._stop_q = [j.state.position for j in self.joints]
        self._stop_stale = [now - j.state.stamp > t for j, t in zip(self.joints, self._timeouts, strict=True)]
        self._stop_from = np.asarray(self.tau_ff, dtype=float).copy()
        self._releases = 0
        self._weighing = None
        self.enabler.abandon()
        self.motions.cancel()
        self._drop_law()  # (impedance: the arm is damped now; its gains are back for the next enable)
        self.end_watch()

    def _require_active(self) -> None:
        """(Under the lock) raise the fault, or a StateError, unless the arm is still active: a stop may
        have come between a caller's check and its taking the lock."""
        if self._weighing is not None and self.modes.mode is Mode.ACTIVE:
            raise StateError("the arm is being enabled (its holding torque is weighed for the turn check)",
                             fix="wait for arm.enable() to return")
        if self.modes.mode is not Mode.ACTIVE:
            if self.fault is not None:
                raise self.fault
            raise StateError(f"the arm is {self.modes.mode}, not enabled", fix="call arm.enable() first")

    # -- motion ----------------------------------------------------------------------------------
    def start(self, make_plan: Callable[[State, float], Timed]) -> Motion:
        """Plan from the commanded state (``make_plan(start, t)``: from state ``start`` at plan time ``t``)
        and follow it. The plan is made in the caller's thread without the lock, so the loop goes on
        streaming and supervising the motion in force meanwhile; the new one takes over exactly where
        it was planned from (:class:`~akarm.control.motions.Motions`). A plan that could not take over
        in time (the arm moved on while it was made) is made again, from further ahead.

        Raises:
            StateError: the arm is not enabled, or the motion could not take over after
                :data:`PLAN_ATTEMPTS` plans. Whatever ``make_plan`` raises (nothing is changed).
        """
        self.require_enabled()
        if self.law is not None:
            raise StateError("the arm is under impedance control: it follows no planned motion",
                             fix="leave the `with arm.impedance(...)` block first, or move its target (set_target)")
        ahead = 0.0  # plan time between now and where the new plan starts
        for _ in range(PLAN_ATTEMPTS):
            with self.lock:
                self._require_active()
                ticket = self.motions.ticket(self.plan_now() + ahead)
            began, began_clock = time.perf_counter(), self.clock.now()
            with collector_paused():  # a collection due meanwhile would hold up the loop (see collector_paused)
                plan = make_plan(ticket.state, ticket.t)
                if not self.clock.stepped and len(getattr(plan, "segments", ())) >= BIG_PLAN:
                    keep_from_collections()
            # the time it took on the loop's clock too: on a stepped clock the loop runs on its own time
            took = max(time.perf_counter() - began, self.clock.now() - began_clock)
            with self.lock:
                self._require_active()
                motion = self.motions.take(ticket, plan)
            if motion is not None:
                return motion
            segments = getattr(plan, "segments", None)
            if isinstance(segments, list):  # a fresh plan, shared with nothing: freed a chunk at a time
                release(segments)
            ahead = max(2.0 * ahead, 2.0 * took + 2.0 * self.period)
        raise StateError(f"the motion could not take over from the one in force after {PLAN_ATTEMPTS} plans (the "
                         f"last took {took:.3f} s to make)",
                         fix="wait for the motion in force to end (motion.wait()) before starting a long one")

    def desired_now(self) -> State:
        """The commanded (q, dq, ddq) at the current plan time."""
        with self.lock:
            return self.motions.desired(self.plan_now())

    @property
    def moving(self) -> bool:
        """True while a plan is followed."""
        return self.motions.moving

    def running(self) -> bool:
        """True while a plan is followed and not yet at its end."""
        with self.lock:
            return self.motions.running_at(self.plan_now())

    # -- gains and torque ------------------------------------------------------------------------
    @property
    def gains(self) -> tuple[np.ndarray, np.ndarray]:
        """The MIT gains in force: (kp N·m/rad, kd N·m·s/rad) per joint (copies)."""
        with self.lock:
            return self._kp.copy(), self._kd.copy()

    def set_gains(self, kp: Sequence[float] | float | None, kd: Sequence[float] | float | None) -> None:
        """Change MIT gains, each within its motor's range (see :meth:`Arm.set_gains`)."""
        motors = [j.motor for j in self.joints]
        with self.lock:
            if self.law is not None:  # (kp = 0 is the law's; its end restores the gains saved at its start)
                raise StateError("the arm is under impedance control: its gains are the law's (kp = 0)",
                                 fix="change the stiffness with imp.set_stiffness(...), or the gains after the "
                                     "`with arm.impedance(...)` block")
            new = {}
            for name, value, top in (("kp", kp, [m.kp_max for m in motors]), ("kd", kd, [m.kd_max for m in motors])):
                if value is None:
                    continue
                try:
                    v = np.broadcast_to(np.asarray(value, dtype=float), (self.n,)).copy()
                except (TypeError, ValueError):
                    raise ArgumentError(f"{name} must be one number or one per joint (N·m/rad or N·m·s/rad), "
                                        f"got {value!r}",
                                        fix=f"pass {name} as a number or a list of {self.n}") from None
                for i, (x, hi) in enumerate(zip(v.tolist(), top, strict=True)):
                    if not (math.isfinite(x) and 0.0 <= x <= hi):
                        raise ArgumentError(f"{name} {x:g} is outside the motor's range 0-{hi:g}",
                                            joint=self.joints[i].name,
                                            fix=f"pass {name} within 0-{hi:g} for {motors[i].name}")
                new[name] = v
            if "kp" in new:
                self._kp[:] = new["kp"]
            if "kd" in new:
                self._kd[:] = new["kd"]
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
                raise ArgumentError(f"extra torque needs {self.n} finite values (N·m)",
                                    fix="one per joint, config order")
            self.ff.extra = v.tolist()

    # -- what the model knows: payload and friction -------------------------------------------------
    def set_payload(self, mass: float, com: Sequence[float] | np.ndarray) -> None:
        """The payload at the tool frame (kg, m), from the next cycle: the feed-forward carries it, the
        collision estimate starts over with it."""
        with self.lock:
            self.model.set_payload(mass, com)
            self.ff.reset_integral()  # it made up for the load the model missed: now the model has it
            self.reflex.restart()

    def clear_payload(self) -> None:
        with self.lock:
            self.model.clear_payload()
            self.ff.reset_integral()
            self.reflex.restart()

    def set_friction(self, coulomb: Sequence[float], viscous: Sequence[float], offset: Sequence[float],
                     torque_scale: Sequence[float] | None = None, load: Sequence[float] | None = None) -> None:
        """Each joint's friction (N·m, N·m·s/rad, N·m): the collision observer takes all three; the
        feed-forward, where friction is compensated, Coulomb and viscous (and ``load``, N·m per N·m). A
        ``torque_scale`` (N·m the joint gets per N·m reported) goes to both."""
        values = [np.asarray(x, dtype=float).reshape(-1) for x in (coulomb, viscous, offset)]
        if any(v.shape != (self.n,) or not np.all(np.isfinite(v)) for v in values):
            raise ArgumentError(f"friction needs {self.n} finite values each of Coulomb, viscous and offset",
                                fix="one per joint, config order")
        with self.lock:
            self.reflex.observer.set_friction(*values)
            if torque_scale is not None:
                self.reflex.observer.set_torque_scale(torque_scale)
            if self.options.friction_compensated:
                self.ff.set_friction(values[0].tolist(), values[1].tolist(), torque_scale, load)
            elif torque_scale is not None:
                self.ff.set_friction([0.0] * self.n, [0.0] * self.n, torque_scale)
            self.reflex.restart()

    # -- the collision reflex ----------------------------------------------------------------------
    @property
    def collision_thresholds(self) -> list[float | None]:
        """N·m per joint, ``None`` where a joint is not checked (those set, also while impedance or a guarded
        move suspends them)."""
        held = self._held_thresholds if self._suspended else self.reflex.thresholds
        return [None if math.isinf(x) else float(x) for x in held]

    @property
    def collision_reaction(self) -> str:
        return self.reflex.reaction

    @property
    def collision_gain(self) -> float:
        """The collision observer's bandwidth in force, 1/s."""
        return self.reflex.observer.gain

    @property
    def last_collision(self) -> CollisionError | None:
        return self.reflex.last

    @property
    def collision_peak(self) -> np.ndarray:
        """The largest ``|external torque estimate|`` per joint while judged, since the last reset, N·m."""
        with self.lock:
            return self.reflex.peak.copy()

    def reset_collision_peak(self) -> None:
        with self.lock:
            self.reflex.clear_peak()

    def external_torque(self) -> np.ndarray:
        """The latest external torque estimate per joint, N·m (a copy)."""
        with self.lock:
            return self.reflex.estimate.copy()

    def set_collision(self, thresholds: Sequence[float | None] | None, reaction: str | None) -> None:
        """New thresholds (N·m; while they are suspended, those in force once they are back) and reaction."""
        with self.lock:
            if thresholds is not None:
                self.reflex.set_thresholds(thresholds)  # (checks them)
                if self._suspended:
                    self._held_thresholds = self.reflex.thresholds.copy()
                    self.reflex.set_thresholds([None] * self.n)
            if reaction is not None:
                self.reflex.set_reaction(reaction)

    def _suspend_thresholds(self) -> None:
        """(Under the lock) The reflex only watches until :meth:`_resume_thresholds` (counted)."""
        if self._suspended == 0:
            self._held_thresholds = self.reflex.thresholds.copy()
            self.reflex.set_thresholds([None] * self.n)
        self._suspended += 1

    def _resume_thresholds(self) -> None:
        """(Under the lock) One suspension less; at none, the thresholds in force (set meanwhile or before) again."""
        self._suspended = max(0, self._suspended - 1)
        if self._suspended == 0:
            self.reflex.set_thresholds([None if math.isinf(x) else float(x) for x in self._held_thresholds.tolist()])

    # -- guarded moves: a contact watch ------------------------------------------------------------
    def begin_watch(self, watch: ContactWatch) -> None:
        """Watch for contact (a guarded move) from the next cycle; the collision thresholds are suspended
        meanwhile (the contact is expected: the watch stops the arm instead)."""
        with self.lock:
            self._require_active()
            if self.law is not None:
                raise StateError("a guarded move needs position control, and the arm is under impedance control",
                                 fix="leave the impedance block first (or push against the impedance's target "
                                     "with set_target and read imp.wrench())")
            if self.watch is not None:
                raise StateError("a guarded move is already running", fix="one guarded move at a time")
            self._suspend_thresholds()
            self.watch = watch

    def refuse_during_watch(self, what: str) -> None:
        """A :class:`~akarm.StateError` while a guarded move runs (``what`` would take the arm from it)."""
        if self.watch is not None:
            raise StateError(f"{what} is refused while a guarded move (move_until_contact) runs",
                             fix="wait for move_until_contact to return")

    def end_watch(self) -> None:
        """(Any thread; under the lock) No contact watch: the collision thresholds are back."""
        with self.lock:
            if self.watch is None:
                return
            self.watch = None
            self._resume_thresholds()

    # -- impedance: a torque law -------------------------------------------------------------------
    def begin_torque_law(self, law: ImpedanceLaw, kd: Sequence[float]) -> None:
        """Hold still, then from the next cycle on send ``law``'s torque (on top of the arm's weight at the
        measured pose) with kp = 0 and ``kd`` (N·m·s/rad) on every joint; the collision reflex watches only."""
        with self.lock:
            self._require_active()
            if self.law is not None:
                raise StateError("the arm is already under impedance control", fix="one impedance block at a time")
            self.refuse_during_watch("impedance")
            self._saved_gains = (self._kp.copy(), self._kd.copy())
            self.motions.hold_at(np.array([j.state.position for j in self.joints]))
            self._kp[:] = 0.0
            self._kd[:] = np.asarray(kd, dtype=float)
            self._gains_changed()
            self._suspend_thresholds()
            self.ff.extra = [0.0] * self.n
            self.law = law

    def _drop_law(self) -> None:
        """(Under the lock) No torque law: the gains and collision thresholds in force before it again."""
        if self.law is None:
            return
        self.law = None
        kp, kd = self._saved_gains
        self.ff.extra = [0.0] * self.n
        self._kp[:], self._kd[:] = kp, kd
        self._gains_changed()
        self._resume_thresholds()

    def end_torque_law(self) -> None:
        """Back to position control: hold the measured pose, the gains in force before ramping up from zero."""
        with self.lock:
            if self.law is None:
                return
            self._drop_law()
            if self.modes.mode is not Mode.ACTIVE:
                return
            self._hold_here()
        self.wait_for(lambda: self.ramp.done, self.options.enable_ramp + 1.0, "the gains to ramp up")

    # -- teach mode and its recorder ---------------------------------------------------------------
    def enter_teach(self, damping: float) -> None:
        with self.lock:
            self._require_active()
            if self.law is not None:  # (its torque would go on as teach mode's extra, its old target after)
                raise StateError("the arm is under impedance control: it is not hand-guided too",
                                 fix="leave the `with arm.impedance(...)` block first (a low stiffness is "
                                     "hand-guiding with a spring)")
            self._teach_damping = np.minimum(damping, self._kd).tolist()
            self.motions.cancel()
            self.modes.go(Mode.TEACH)

    def end_teach(self) -> None:
        """Hold the pose the hand left, gains ramping up (and wait for them); nothing outside teach mode."""
        with self.lock:
            if self.modes.mode is not Mode.TEACH:
                return
            self.recorder = None
            self._hold_here()
            self.modes.go(Mode.ACTIVE)
        self.wait_for(lambda: self.ramp.done, self.options.enable_ramp + 1.0, "the gains to ramp up")

    def start_recording(self, rate_hz: float, duration: float | None) -> None:
        with self.lock:
            self.recorder = PathRecorder(rate_hz, duration)

    def stop_recording(self) -> PathRecorder | None:
        """The recording so far (``None`` if none was started); recording stops."""
        with self.lock:
            rec, self.recorder = self.recorder, None
        return rec

    @property
    def recording_finished(self) -> bool:
        rec = self.recorder
        return rec is not None and rec.finished

    def _hold_here(self) -> None:
        """Take the measured pose as the commanded one, kp ramping up from zero (caller holds the lock)."""
        q = np.array([j.state.position for j in self.joints])
        self.motions.hold_at(q)
        self.des = (q.copy(), np.zeros(self.n), np.zeros(self.n))
        t = min(self.plan_now(), self._t_plan)
        self._t_last = t
        self.ramp.start(t)
        self.ff.reset_integral()
        if self.gripper is not None and self.modes.mode is Mode.ENABLING:
            self.gripper.hold_here()

    # -- what the loop measured ----------------------------------------------------------------------
    def telemetry_log(self, since: float | None = None) -> TelemetryLog:
        return self.telemetry.snapshot(since)  # (not under the loop's lock: the ring is read lock-free)

    def stats(self) -> StatsSummary:
        self.require_open()
        return self.loop.stats.summary()

    def reset_stats(self) -> None:
        self.require_open()
        self.loop.stats.reset()

    @property
    def buses(self) -> Mapping[str, can.BusABC]:
        return self.bus.buses

    def _simulator_late(self, bus: str, silent_for: float) -> tuple[str, str] | None:
        """Why bus ``bus`` has been silent for ``silent_for`` s when it is simulated (akarm_local) and its
        simulator has not read it since before the first command left unanswered: the simulator ran late
        (this machine did not run it in real time), not a motor or a cable. None otherwise."""
        read = getattr(self.bus.buses.get(bus), "peers_read", None)
        last = read() if read is not None else None
        if last is None:
            return None
        age = time.monotonic() - last
        if age < silent_for - self.period:  # it read the commands and did not answer: the (simulated) motors
            return None
        return (f"and the simulator on bus {bus!r} has not read the bus for {age * 1e3:.0f} ms, since before the "
                "first unanswered command: the simulator ran late (this machine did not run it in real time: CPU "
                "load, other processes, a client keeping it busy), not a motor, a cable or the power supply",
                "run the simulator at real-time priority (akarm sim --realtime-priority), lower the machine's load, "
                "or give the simulated arm a longer feedback_timeout (the robot file) or the timing profile for slow "
                "or shared machines (--profile slow)")

    # ------------------------------------------------------------------------------------------
    # the cycle (loop thread, or inline with a stepped clock)
    # ------------------------------------------------------------------------------------------
    @property
    def plan_lag(self) -> float:
        """s the plan time trails the clock (:meth:`plan_now`)."""
        return self._lag

    def plan_now(self) -> float:
        """The plan time now, s: the clock less the slots the loop missed (what plans are timed in)."""
        return self.clock.now() - self._lag

    def cycle(self, now: float, slot: int) -> None:
        pc = time.perf_counter
        loop = self.loop
        stage = loop.stats.row(slot)
        t0 = pc()
        self.bus.receive(now)
        t1 = pc()
        stage[0] = t1 - t0
        if loop.skipped:  # the plan waits for the motors: it goes on from where it was, not where it would be
            self._lag += loop.skipped * self.period
        self._t_plan = loop.deadline - self._lag
        mode = self.modes.mode
        if not mode.powered or mode is Mode.FAULT:
            return
        with self.lock:
            mode = self.modes.mode
            if loop.gap - self.period > self.stall_limit and mode is not Mode.STOPPING:
                self._stalled(now, loop.gap - self.period)
                return
            if mode is Mode.ACTIVE:
                self._cycle_active(now, stage, t1)
            elif mode is Mode.TEACH:
                self._cycle_teach(now)
            elif mode is Mode.ENABLING:
                self._cycle_enabling(now)
            elif mode is Mode.STOPPING:
                self._cycle_stopping(now)

    def _stalled(self, now: float, stalled: float) -> None:
        """The loop did not run for ``stalled`` s, more than its stall limit: stop (or refuse the enable)."""
        stop = LoopStall(
            f"the control loop did not run for {stalled * 1e3:.0f} ms (limit {self.stall_limit * 1e3:.0f} ms): this "
            "process was stopped or starved of CPU (a loaded machine, a long garbage collection, swapping, "
            "SIGSTOP), not a motor; the motors held their last command, unsupervised, meanwhile; the arm was damped "
            "and disabled", stalled=stalled, limit=self.stall_limit,
            fix="lower the machine's load, or use the timing profile for slow or shared machines (--profile slow); "
                "give the loop real-time priority (realtime_priority=True, --realtime-priority) and a core of its own "
                "(busy_wait=True, loop_cpu=N); raise stall_limit only if such stalls are known and safe for this arm")
        stop.at = now
        if self.modes.mode is Mode.ENABLING:
            self.enabler.abandon()
            self._enable_failed(Refusal(stop))
            return
        self._begin_stop(stop)
        self._cycle_stopping(now)

    def _cycle_active(self, now: float, stage: Any, t1: float) -> None:
        pc = time.perf_counter
        motions = self.motions
        t = self._t_plan
        q_d, dq_d, ddq_d = motions.sample(t)
        plan = motions.plan
        self.des = (q_d, dq_d, ddq_d)
        qd = q_d.tolist()
        t2 = pc()
        stage[1] = t2 - t1
        grip = self.gripper
        ff_now = self.tau_ff if grip is None else [*self.tau_ff, 0.0]  # (the gripper's law has no feed-forward)
        stop = self.supervisor.check(now, qd if grip is None else [*qd, grip.target], self._tracking, self._saturated,
                                     ff_now)
        fb = self._feedback()
        weighing = self._weighing
        if stop is None:  # (while the arm is weighed the reflex only watches: a lost turn is the turn check's)
            stop = self._collision_check(now, weighing is None, fb)
        walls = self.walls
        if stop is None and walls is not None:
            stop = walls.check(now, fb[0], qd)
        self_collision = self.self_collision
        if stop is None and self_collision is not None:
            stop = self_collision.step(now, fb[0], qd)
        watch = self.watch
        if stop is None and watch is not None and watch.step(fb[0], self.reflex.estimate_list):
            # a guarded move felt its contact: stop (jerk-limited, from this cycle's command) and hold
            self.motions.replace(Plan([self.planner.stop(self.des, t)]), None)
        law = self.law
        if stop is None and law is not None:  # impedance: this cycle's torque from the measured state
            out = law.step(t, fb[0], fb[1])
            if isinstance(out, SafetyStop):
                stop = out
            else:
                self.ff.extra = out
        t3 = pc()
        stage[2] = t3 - t2
        if stop is not None:
            self._begin_stop(stop)
            self._cycle_stopping(now)
            return
        js = self.joints
        q_meas = fb[0]
        ramp = self.ramp
        holding = plan is None and ramp.scale >= 1.0 and weighing is None
        vd = dq_d.tolist()
        live = plan is not None and plan.duration == math.inf  # servoing: the hold integral's torque kept
        ff = self.ff.torques(q_d, dq_d, ddq_d, q_meas, holding, t - self._t_last, qd, vd, live)
        self._t_last = t
        self.tau_ff = ff
        t4 = pc()
        stage[3] = t4 - t3
        g = ramp.update(t)
        kp, kd, tmax, sat = self._kp_list, self._kd_list, self._t_max, self._saturated
        frames = []
        for i, j in enumerate(js):
            k = kp[i] * g
            frames.append(j.track_frame(qd[i], vd[i], k, kd[i], ff[i]))
            # what the firmware will apply (before its clamp): saturated, the motor has no authority left
            s = j.state
            tau = k * (qd[i] - s.position) + kd[i] * (vd[i] - s.velocity) + ff[i]
            sat[i] = tau >= tmax[i] or tau <= -tmax[i]
        if grip is not None:
            frames.append(grip.frame(t))
            grip.record(now)
        self.bus.send_frames(frames)
        t5 = pc()
        stage[4] = t5 - t4
        self._record(now, qd, vd, ff, fb)
        if weighing is not None and ramp.done and weighing.sample(now, fb[0], fb[1], fb[2]):
            self._weighed(now, weighing)
        stage[5] = pc() - t5

    def _weighed(self, now: float, weighing: Weighing) -> None:
        """(Loop) The arm was weighed: refuse the enable if the torque says a turn count was lost."""
        self._weighing = None
        if not weighing.at_rest:
            log.warning("turn check: the arm did not come to rest within %.1f s of holding: not weighed (a lost "
                        "turn count on a joint gravity moves is not checked this time)", weighing.lag + WEIGH_TIMEOUT)
            return
        verdict = self.turn_verdict = self.turn_check.judge(weighing.q, weighing.tau)
        error = verdict.error
        if error is None:
            remembered = self._remembered or {}
            blind = [x for x in verdict.undecided if x not in remembered]
            if blind:
                log.warning("turn check: at this pose the torque holding %s does not tell a lost rotor turn (gravity "
                            "asks the same a whole turn away) and no position of %s is remembered: the reading%s "
                            "believed", ", ".join(blind), "it" if len(blind) == 1 else "them",
                            " is" if len(blind) == 1 else "s are")
            if verdict.unexplained:
                log.warning("turn check: the torque holding the arm (%s N·m) is not what the model's gravity asks "
                            "at the readings nor a whole turn away: a payload akarm does not know (arm.set_payload) "
                            "or something pressing on the arm", ", ".join(f"{x:+.2f}" for x in weighing.tau))
            return
        error.at = now
        self.enable_error = error
        self._positions_known = False  # these readings are not remembered
        tau = weighing.tau.tolist()  # the stop lowers the arm from the torque that held it, not the model's
        self.tau_ff = [tau[i] if m else x for i, (m, x) in enumerate(zip(self._mit, self.tau_ff, strict=True))]
        self._begin_stop()

    def _feedback(self) -> tuple[list[float], list[float], list[float], list[float]]:
        """The joints' latest feedback as lists: positions, velocities, torques and when each came (one
        read a cycle, for the reflex, the feed-forward and telemetry)."""
        states = [j.state for j in self.joints]
        return ([s.position for s in states], [s.velocity for s in states], [s.torque for s in states],
                [s.stamp for s in states])

    def _collision_check(self, now: float, check: bool,
                         fb: tuple[list[float], list[float], list[float], list[float]]) -> SafetyStop | None:
        """Update the collision reflex with the feedback ``fb`` (:meth:`_feedback`); its stop if it fired
        with the "disable" reaction. Its "hold" reaction replaces the plan here by a jerk-limited stop
        from this cycle's desired state."""
        reflex = self.reflex
        if check:  # the MIT gains of this cycle's commands (teach: no stiffness, its damping)
            scale = self.ramp.scale
            at, kp = self._reflex_kp
            if scale != at:  # (it moves only while kp ramps up from the measured pose: enable, after teach)
                kp = [k * scale if m else 0.0 for k, m in zip(self._kp_list, self._mit, strict=True)]
                self._reflex_kp = (scale, kp)
            kd = self._reflex_kd
        else:
            kp, kd = [0.0] * self.n, [d if m else 0.0 for d, m in zip(self._teach_damping, self._mit, strict=True)]
        q, dq, tau, stamps = fb
        err = reflex.step(now, q, dq, tau, check, kp, kd, stamps, self.des[1] if check else None,
                          self.tau_ff if check else None)
        if err is None or err.reaction == "disable":
            return err
        self.motions.replace(Plan([self.planner.stop(self.des, self._t_plan)]), err)
        return None

    def _record(self, now: float, q_d: Any, dq_d: Any, ff: Any,
                fb: tuple[list[float], list[float], list[float], list[float]] | None = None) -> None:
        q, dq, tau, _ = self._feedback() if fb is None else fb
        self.telemetry.record(now, q_d, dq_d, q, dq, tau, ff, self.reflex.estimate_list)

    def _send_gripper(self, now: float) -> None:
        """(Teach, a stop's damping) The gripper's command of this cycle, alone."""
        grip = self.gripper
        if grip is not None:
            f = grip.frame(self._t_plan)
            self.bus.send(grip.joint, message(f[0], f[2], f[1]))
            grip.record(now)

    def _gravity_and_gripper(self, q: Sequence[float]) -> np.ndarray:
        """The enabler's gravity: the arm's joints', and none for the gripper's motor (after them)."""
        return np.append(self.ff.gravity(q[:self.n]), 0.0)

    def _commanded_arm(self, now: float, q: Sequence[float], tau: list[float]) -> None:
        self._commanded(now, q[:self.n], tau[:self.n])

    def _commanded(self, now: float, q: Sequence[float], tau: list[float]) -> None:
        """The enabler damped the arm at ``q`` with ``tau`` feed-forward this cycle."""
        self.tau_ff = tau
        self._record(now, q, [0.0] * self.n, tau)

    def _cycle_teach(self, now: float) -> None:
        """Hand guiding: no stiffness, a little damping, the arm's weight carried (at the measured pose),
        plus the extra torque (:meth:`set_extra_torque`: a teleoperation leader's force feedback)."""
        stop = self.supervisor.check(now)
        if stop is not None:
            self._begin_stop(stop)
            self._cycle_stopping(now)
            return
        fb = self._feedback()
        self._collision_check(now, False, fb)  # estimated (the hand's torque), never checked
        q = np.array(fb[0])
        g = self.ff.carried(q)
        gl = g.tolist()
        send = self.bus.send
        for i, j in enumerate(self.joints):
            send(j, j.carry(self._teach_damping[i], gl[i]))
        self._send_gripper(now)
        self.des = (q, np.zeros(self.n), np.zeros(self.n))
        self.tau_ff = gl
        rec = self.recorder
        if rec is not None:
            rec.sample(now, q)
        self._record(now, q, np.zeros(self.n), g, fb)

    def _cycle_enabling(self, now: float) -> None:
        step = self.enabler.step(now)
        if step is None:
            self.loop.soon = self.enabler.hurry(now)  # (slow profile: contact at its own rate, extra cycles)
            return
        if isinstance(step, Refusal):
            self._enable_failed(step)
            return
        self._hold_here()  # at rest
        if self._weigh_next:
            self._weigh_next = False
            self._weighing = Weighing(self.n, self.options.timing.lag)
        self.modes.go(Mode.ACTIVE)

    def _enable_failed(self, refusal: Refusal) -> None:
        """The enable was refused: if anything was sent, the exit frames go out as a stop's do, on
        :data:`RELEASES` cycles (no damping: nothing held the arm yet); then DISABLED."""
        self.enable_error = refusal.error
        if refusal.release:
            self._begin_stop(damping=0.0)
            self._cycle_stopping(self.clock.now())
            return
        self.supervisor.disarm()
        self.ramp.zero()
        self.modes.go(Mode.DISABLED)

    def _cycle_stopping(self, now: float) -> None:
        """Damping (kp = 0, feed-forward fading out) for stop_damping_time (of plan time), then the
        exit frames, on :data:`RELEASES` cycles that every bus took them (a cycle whose frames a full
        transmit queue refused does not count; refusals that go on lose the bus: a fault)."""
        T = self._damp_time
        s = (self._t_plan - self._t_stop) / T if T > 0 else 1.0
        stale = self._stop_stale
        for i, j in enumerate(self.joints):
            if now - j.state.stamp > self._timeouts[i]:
                stale[i] = True
        if s < 1.0:
            fade = 1.0 - s
            tau = (self._stop_from * fade).tolist()
            send = self.bus.send
            for i, j in enumerate(self.joints):
                send(j, j.damp(self._damping[i], tau[i]))
            self._send_gripper(now)  # it goes on holding what it holds: a stop opens nothing
            self._record(now, self.des[0], np.zeros(self.n), tau)
            return
        if self.bus.release_all():
            self._releases += 1
        if self._releases < RELEASES:  # (a lost bus's refusals do not hold it up: release_all)
            return
        self.ramp.zero()
        self.supervisor.disarm()
        self.recorder = None
        if self.gripper is not None:
            self.gripper.stop_moving()
        self.modes.go(Mode.FAULT if self.bus.lost else Mode.DISABLED)
        self._remember_positions()

    # ------------------------------------------------------------------------------------------
    # the turn check (akarm.control.turns)
    # ------------------------------------------------------------------------------------------
    def _turn_check(self, now: float) -> AkarmError | None:
        """(Loop, at contact) :class:`~akarm.errors.TurnCountLost` when a joint reads whole rotor turns
        from where it was remembered; else ``None``, and a later stop may remember these readings."""
        mem, remembered = self.positions, self._remembered
        error = None
        q = [j.state.position for j in self.joints]
        if mem is not None and remembered:
            error = mem.check(q, remembered)
        if error is None and self._weigh_next:  # (not when the positions were accepted by eye)
            error = self.turn_check.out_of_range(q)
        if error is None:
            self._positions_known = True
        else:
            error.at = now
        return error

    def _forget_positions(self) -> None:
        """(Caller, enabled) Forget the remembered positions: until the arm stops, they are not known."""
        if self.positions is not None:
            try:
                self.positions.forget()
            except AkarmError as e:
                warnings.warn(f"the joint positions could not be forgotten: {e}", RuntimeWarning, stacklevel=3)

    def _remember_positions(self) -> None:
        """(Loop, the stop's end, motors limp) Remember where each joint is: its reading now, or, for
        a joint whose feedback went silent during the stop (a driver power-cycled), its reading when
        the stop began. Only readings that passed the turn check are remembered."""
        mem = self.positions
        if mem is None or not self._positions_known:
            return
        self._positions_known = False
        named = self.fault.joint if self.fault is not None else None  # the joint a stop named: its reading then
        q = [self._stop_q[i] if self._stop_stale[i] or j.name == named else j.state.position
             for i, j in enumerate(self.joints)]
        g = self.model.gravity([x if math.isfinite(x) else 0.0 for x in q]).tolist()
        out = {}
        for i, j in enumerate(self.joints):  # a joint gravity moves while limp is not remembered (turns.stays_put)
            if j.state.stamp != -math.inf and stays_put(g[i], self._coulomb[i], float(self.torque_limit[i])):
                out[j.name] = q[i]
        try:
            mem.save(out)
        except AkarmError as e:  # the loop must go on: the arm is disabled, the next enable compares nothing new
            warnings.warn(f"the joint positions could not be remembered: {e}", RuntimeWarning, stacklevel=2)
