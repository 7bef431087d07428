"""The user's API: an :class:`Arm` that enables, moves, holds and disables a robot arm safely.

::

    import akarm
    arm = akarm.Arm.from_yaml("robots/arm6.yaml")
    with arm:                       # any exit, exception, Ctrl-C or SIGTERM: damped, then disabled
        arm.enable()                # no kick: waits for the arm to be at rest, holds it, gains ramp up
        arm.move_to("home")         # jerk-limited, time-synchronised, blocks
        arm.move_to([0.3, -0.5, 1.0, 0.0, 0.4, 0.0], speed=0.5)

The Arm checks what it is asked (targets, paths, recordings: before anything moves) and asks its
:class:`~akarm.control.controller.Controller` to do it; the controller runs the fixed-rate loop, the mode
machine (:mod:`akarm.control.modes`) and the safety supervisor (:mod:`akarm.control.safety`).

All positions are rad, velocities rad/s, torques N·m, times s, in config joint order.
"""

from __future__ import annotations

import logging
import math
import numbers
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from os import PathLike
from typing import Any

import numpy as np

from akarm.buses.bus import simulated
from akarm.clock import Clock, RealClock
from akarm.config import RobotConfig
from akarm.control.collision import DEFAULT_GAIN, Reaction
from akarm.control.controller import Controller
from akarm.control.feedforward import FeedForwardKind
from akarm.control.gripper import Gripper
from akarm.control.guard import Contact
from akarm.control.impedance import Impedance
from akarm.control.joints import Joint
from akarm.control.loop import StatsSummary
from akarm.control.modes import Mode
from akarm.control.motions import Motion, State
from akarm.control.options import ControllerOptions
from akarm.control.turns import arm_key, state_file
from akarm.control.view import ControllerView
from akarm.dynamics.gravity import GravityPeak
from akarm.dynamics.ik import IKSolver, as_pose
from akarm.dynamics.model import RobotModel
from akarm.dynamics.selfcollision import SelfCollision, self_collision_for
from akarm.errors import (
    ArgumentError,
    CollisionError,
    ConfigError,
    ConfigProblem,
    LimitError,
    RecordingError,
    SafetyStop,
    StateError,
    did_you_mean,
    finite_number,
    num,
)
from akarm.motion import recording as rec_mod
from akarm.motion.bounds import MAX_DURATION, MAX_KEYFRAMES, MAX_PATH_SAMPLES, MAX_TRAJECTORY_POINTS
from akarm.motion.cartesian import plan_linear
from akarm.motion.servo import Servo, ServoStream
from akarm.motion.torque import TorqueBudget
from akarm.motion.trajectory import Chain, JointLimits, Plan, Planner, Timed
from akarm.telemetry.log import TelemetryLog
from akarm.timing import TimingProfile, get_profile

__all__ = ["Arm", "ArmState", "JointReport", "Motion"]


def _bounded(items: object, limit: int, what: str, context: str, fix: str) -> None:
    """Raise :class:`~akarm.ArgumentError` if ``items`` (anything with a length) has more than ``limit``
    elements: checked before anything looks at them."""
    try:
        n = len(items)  # type: ignore[arg-type]
    except TypeError:
        return  # not a sequence: the code that reads it says what is wrong
    if n > limit:
        raise ArgumentError(f"{n} {what}: {context} at most {limit} (akarm.motion.bounds)", fix=fix)


def _self_collision(config: RobotConfig, which: object, margin: object) -> SelfCollision | None:
    """The Arm's self-collision check: ``which`` True (the robot file's ``self_collision:``), False (none) or
    a source of shapes; ``margin`` m, or ``None``: the robot file's."""
    fix = "self_collision=True (the robot file's), False (off), or 'auto', 'collision', 'visual', 'capsules'"
    if which is True or (isinstance(which, np.bool_) and bool(which)):
        source = config.self_collision.shapes
    elif which is False or isinstance(which, np.bool_):
        return None
    elif which in ("auto", "collision", "visual", "capsules"):
        source = which
    else:
        raise ArgumentError(f"self_collision must be True, False or where the shapes come from, got {which!r}", fix=fix)
    m = config.self_collision.margin if margin is None else finite_number(margin, "self_collision_margin",
                                                                         at_least=0.0, unit="m", fix="e.g. 0.01")
    if source == "none":
        return None
    sc = self_collision_for(config, source, m)
    if source == "auto" and sc.source == "capsules":
        # capsules guessed from the masses can refuse the moves a real arm makes (or miss what it hits): on
        # request only
        logging.getLogger(__name__).warning(
            "self-collision is not checked: the URDF %s has no <collision> or <visual> shapes akarm can read (meshes "
            "not found?); give it <collision> shapes, or `self_collision: {shapes: capsules}` in the robot file",
            config.urdf.name)
        return None
    return sc


FeedForward = FeedForwardKind
Target = str | Sequence[float] | np.ndarray | Mapping[str, float]
#: rad: on a machine whose readings trail the commands (a timing profile with ``lag``), a move that waits
#: returns once every joint reads this close to its command (or after twice the lag)
ARRIVED = 0.005
#: The smallest speed factor a move takes (a 1.5 rad move of planar2 lasts 6000 s at it).
MIN_SPEED = 1e-4
#: rad/s: every joint this slow when a move is planned, the arm holds still: what its motors report then
#: is what the unit needs to hold the pose (:meth:`akarm.motion.torque.TorqueBudget.measure_hold`)
HOLD_STILL = 0.05


@dataclass(frozen=True)
class JointReport:
    """One joint's latest feedback (joint side, SI): position rad, velocity rad/s, torque N·m,
    temperature °C (None if not reported), fault code (0 none), age s (time since the feedback),
    and the collision observer's estimate of the external torque on it, N·m (:mod:`akarm.control.collision`)."""

    name: str
    position: float
    velocity: float
    torque: float
    temperature: float | None
    fault: int
    age: float
    external_torque: float = math.nan


@dataclass(frozen=True)
class ArmState:
    """A snapshot of the arm: per-joint feedback plus the controller's own state.

    Attributes:
        time: clock time of the snapshot, s.
        joints: a :class:`JointReport` per joint, config order.
        q, dq, tau: measured positions (rad), velocities (rad/s), torques (N·m) as arrays.
        q_des: the commanded position (rad) this cycle.
        enabled: True while the motors are powered and under control (ACTIVE: holding or moving;
            TEACH: hand-guided). moving: True while a motion runs.
        mode: the arm's :class:`~akarm.control.modes.Mode`.
        tau_ext: the external torque estimate per joint, N·m (:mod:`akarm.control.collision`).
    """

    time: float
    joints: tuple[JointReport, ...]
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    q_des: np.ndarray
    enabled: bool
    moving: bool
    mode: Mode = Mode.DISABLED
    tau_ext: np.ndarray | None = None

    def __str__(self) -> str:
        head = (f"{'joint':<16}{'pos rad':>10}{'vel rad/s':>11}{'torque Nm':>11}{'temp C':>8}{'fault':>7}{'age ms':>9}"
                f"{'ext Nm':>9}")
        rows = [head]
        for j in self.joints:
            temp = f"{j.temperature:8.1f}" if j.temperature is not None else f"{'-':>8}"
            rows.append(f"{j.name:<16}{j.position:10.4f}{j.velocity:11.4f}{j.torque:11.3f}{temp}{j.fault:7d}"
                        f"{j.age * 1e3:9.1f}{j.external_torque:9.2f}")
        return "\n".join(rows)


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
        feedback_timeout: s; the supervisor stops the arm when a joint is silent this long, counted
            on what it was sent (a MIT joint: that many loop periods of commands unanswered; a servo
            joint: no status frame in that much time the loop ran), and refuses an enable whose first
            reply comes later (default: the timing profile's, 20 ms normally; servo joints at least 3
            status periods; a joint's own setting wins; none below the profile's ``min_feedback_timeout``).
        stall_limit: s the control loop itself may fail to run (this process stopped or starved: a
            loaded machine, a long garbage collection, SIGSTOP) and resume without a stop: the plan
            waits for the motors (no command steps ahead), the watchdog counts no time. Longer stops
            the arm with :class:`~akarm.LoopStall` (default: the timing profile's, 0.2 s normally, 1 s
            with ``slow``; one for the loop, so not a robot-file key).
        timing: a timing profile (:mod:`akarm.timing`): ``"normal"`` (default) or ``"slow"`` for
            slow or shared machines, or a :class:`~akarm.timing.TimingProfile`. It caps the loop rate
            (:attr:`config` then says the rate in force) and gives the watchdog's and
            :meth:`enable`'s defaults. Kept as :attr:`timing`.
        enable_ramp: s over which MIT stiffness (kp) rises from zero once the arm is held.
        stop_damping_time: s of damping (kp = 0) before exit when disabling or stopping for safety.
        settle_speed: rad/s; ``enable()`` damps the arm until every joint is slower than this.
        settle_timeout: s; ``enable()`` gives up (:class:`~akarm.NotSettled`) if the arm is not at
            rest by then.
        range_margin: rad; a move may start outside a joint's range (an arm resting on its hard stop),
            up to this far past its mechanical range (the URDF's limits), and come back into it.
        implausible_limit: rejected replies in a row that stop the arm (:class:`~akarm.ImplausibleFeedback`).
        collision_reaction: what the collision reflex does when a joint's external torque estimate
            passes its YAML ``collision: {threshold: ...}``: ``"disable"`` (damp, then disable; the
            default) or ``"hold"`` (come to rest, jerk-limited, and hold). See :mod:`akarm.control.collision`.
        collision_gain: 1/s, the bandwidth of the external torque estimate (default 50: a 20 ms
            time constant; at most a quarter of the loop rate). With a ``timing`` profile for machines
            that cannot keep time (``slow``), the reflex only watches: no thresholds.
        telemetry_seconds: how much history the telemetry ring keeps, s.
        can_log: optional path of a raw CAN log (``.log`` candump, ``.asc``, ``.blf``, ...).
        realtime_priority: ask for SCHED_FIFO and locked memory for the loop thread, freeze the
            garbage collector's view of existing objects and shorten the interpreter's thread switch
            interval (:func:`akarm.control.loop.request_realtime`), and hold the CPUs out of deep idle
            states while the loop runs, so that its cycles start warm and on time
            (:mod:`akarm.control.cpuidle`; needs root; for arm6 at 480 Hz here about a quarter less CPU
            per cycle and half the lateness p99). Each part is reported, never fatal.
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
        remember_positions: ``True`` (default): remember each joint's position when the arm stops,
            in the arm's state file (:func:`akarm.control.turns.state_file`:
            ``$XDG_STATE_HOME/akarm/positions/KEY.json``, ``KEY`` the physical arm's: ``arm_id``, else
            the robot file's name with its buses, channels and CAN IDs, :func:`akarm.control.turns.arm_key`),
            and refuse an enable where a joint reads
            whole rotor turns from it (:class:`~akarm.TurnCountLost`, a driver that lost its turn
            count in a power cycle; see :meth:`enable`'s ``accept_position``); on buses only a
            simulator answers on (``akarm_local``, ``vcan*``), ``KEY.sim.json``: a simulated arm never
            touches the real one's. On python-can's ``virtual`` buses alone, nothing: such a bus lives
            in one process, so its simulator started with this program, where another program's
            simulated arm stopped says nothing of it (a fresh simulator a rotor turn from there was
            refused as a lost turn count). A path: that state file. ``False``: nothing is remembered
            or compared (the torque check at enable, for joints gravity moves, still runs: see
            :meth:`enable`).
        arm_id: the physical arm's name (as LeRobot's ``--robot.id``; ``akarm ... --id``): its positions
            are remembered under it, whatever its robot file, buses or channels. Default: keyed by the
            robot file's name, buses, channels and CAN IDs, so that two arms of one robot file (a leader
            and a follower, two identical arms on ``can0`` and ``can1``) never share one memory.
        self_collision: the links checked against each other (:mod:`akarm.dynamics.selfcollision`): a planned
            path that makes two of them come closer than the margin is refused (nothing moves), servoing
            stops short of it, and the supervisor stops an arm measured with two shapes touching
            (:class:`~akarm.SelfCollisionStop`). ``True`` (default): as the robot file's ``self_collision:``
            says (on, with the URDF's ``<collision>`` shapes, unless ``shapes: none``); ``False``: off; or
            where the shapes come from: ``"auto"``, ``"collision"``, ``"visual"``, ``"capsules"``.
        self_collision_margin: m two shapes keep apart on a planned path or while servoing; ``None``
            (default): the robot file's (10 mm unless it says otherwise).

    While it is open, an Arm makes SIGTERM and SIGHUP (where their action is the default) raise
    :class:`akarm.signals.Terminated`, a :class:`KeyboardInterrupt`, so that ``with arm:`` unwinds
    and disables the arm; an Arm still enabled when the program ends, or when it is dropped, is
    damped and disabled with an :class:`~akarm.control.exits.UnsafeExitWarning`.

    Bad arguments raise :class:`~akarm.ArgumentError` (nothing is done).
    """

    def __init__(self, config: RobotConfig, *, clock: Clock | None = None, feedforward: FeedForward = "full",
                 feedback_timeout: float | None = None, stall_limit: float | None = None, enable_ramp: float = 0.3,
                 stop_damping_time: float = 0.3, telemetry_seconds: float = 60.0,
                 can_log: str | PathLike[str] | None = None, realtime_priority: bool = False,
                 hold_integral: float = 3.0, friction_feedforward: bool = True, busy_wait: bool = False,
                 loop_cpu: int | None = None, settle_speed: float = 0.1, settle_timeout: float = 3.0,
                 range_margin: float = 0.05, implausible_limit: int = 3,
                 timing: str | TimingProfile | None = None, collision_reaction: Reaction = "disable",
                 collision_gain: float = DEFAULT_GAIN,
                 remember_positions: bool | str | PathLike[str] = True, self_collision: bool | str = True,
                 self_collision_margin: float | None = None, arm_id: str | None = None) -> None:
        for name, flag in (("realtime_priority", realtime_priority), ("friction_feedforward", friction_feedforward),
                           ("busy_wait", busy_wait)):
            if not isinstance(flag, bool | np.bool_):
                raise ArgumentError(f"{name} must be True or False, got {flag!r}", fix=f"e.g. {name}=True")
        if clock is not None and not (callable(getattr(clock, "now", None))
                                      and callable(getattr(clock, "sleep_until", None)) and hasattr(clock, "stepped")):
            raise ArgumentError(f"clock must be a clock (now(), sleep_until(t), stepped), got {clock!r}",
                                fix="leave it out for the wall clock, or pass a simulator's: clock=sim.clock")
        if arm_id is not None and not (isinstance(arm_id, str) and re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}",
                                                                                arm_id)):
            raise ArgumentError(f"arm_id must be a name of letters, digits, '_', '.' and '-' (at most 64, not "
                                f"starting with '.', '_' or '-'), got {arm_id!r}", fix="e.g. arm_id='left_follower'")
        self.timing = get_profile(timing)
        position_file: str | PathLike[str] | None
        if remember_positions is True and all(b.interface == "virtual" for b in config.buses.values()):
            position_file = None  # a simulator in this process, started with it: nothing of it to remember
        elif remember_positions is True:
            on_simulator = all(map(simulated, config.buses.values()))
            position_file = state_file(arm_key(config, arm_id), simulator=on_simulator)
        elif remember_positions is False:
            position_file = None
        elif isinstance(remember_positions, str | PathLike) and str(remember_positions):
            position_file = remember_positions
        else:
            raise ArgumentError(f"remember_positions must be True, False or a file's path, got {remember_positions!r}")
        options = ControllerOptions(
            timing=self.timing, feedforward=feedforward, friction_feedforward=friction_feedforward,
            hold_integral=hold_integral, feedback_timeout=feedback_timeout, stall_limit=stall_limit,
            enable_ramp=enable_ramp,
            stop_damping_time=stop_damping_time, settle_speed=settle_speed, settle_timeout=settle_timeout,
            implausible_limit=implausible_limit, telemetry_seconds=telemetry_seconds, can_log=can_log,
            realtime_priority=realtime_priority, loop_cpu=loop_cpu,
            collision_reaction=collision_reaction, collision_gain=collision_gain, position_file=position_file,
            self_collision=_self_collision(config, self_collision, self_collision_margin))
        config = self.timing.apply(config)
        self.config = config
        self.clock: Clock = clock if clock is not None else RealClock(busy=busy_wait)
        self.feedforward: FeedForward = feedforward
        self.names = config.joint_names
        self.n = len(config.joints)
        self.model = RobotModel(config, armature=True)
        self._torque_budget: TorqueBudget | None = None  # (its own model: made at the first move)
        lim = [j.limits for j in config.joints]
        self.limits = JointLimits(
            self.names, np.array([x.lower for x in lim]), np.array([x.upper for x in lim]),
            np.array([x.velocity for x in lim]), np.array([x.acceleration for x in lim]),
            np.array([x.jerk for x in lim]))
        self.planner = Planner(self.limits, range_margin, outer=(self.model.lower, self.model.upper))
        self._ik_solver: IKSolver | None = None
        #: the self-collision check (the planner's; ``None``: off), :mod:`akarm.dynamics.selfcollision`
        self.self_collision: SelfCollision | None = options.self_collision
        self._ctl = Controller(config, self.model, self.planner, self.clock, options)
        self.joints: list[Joint] = self._ctl.joints
        self._observe = ControllerView(self._ctl)
        #: the gripper (:class:`~akarm.Gripper`: open, close, move_to, state, calibrate); ``None`` without one
        self.gripper: Gripper | None = Gripper(self._ctl, self._ctl.gripper) if self._ctl.gripper is not None else None
        self._finalizer = self._ctl.track(self)

    @classmethod
    def from_yaml(cls, path: str | PathLike[str], *, interface: str | None = None,
                  channel: str | Mapping[str, str] | None = None, bitrate: int | None = None, **kwargs: Any) -> Arm:
        """Load a robot YAML (bus overrides: ``interface=``, ``channel=``, ``bitrate=``) and build its Arm."""
        from akarm.robotfile.load import load_robot

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
            RecordingError: ``can_log`` cannot be written (the buses are closed again).
            StateError: an ``akarm serve`` of another process drives one of the buses.
        """
        if self.mode is Mode.CLOSED:
            from akarm.buses.ownership import refuse_if_served

            refuse_if_served(self.config, "opening this Arm")  # akarm serve drives these buses: one controller only
        self._ctl.open()
        return self

    def close(self) -> None:
        """Disable the arm if it may be powered (damping, then exit; from any mode, teach included),
        stop the loop, close the buses. Never raises; Ctrl-C and SIGTERM wait until it is done."""
        self._ctl.close()

    def __enter__(self) -> Arm:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------------------------------
    # enable / disable
    # ------------------------------------------------------------------------------------------
    def enable(self, timeout: float | None = None, *, accept_position: bool = False) -> None:
        """Power the joints without a kick, wait for the arm to be at rest, and hold it where it is.

        1. Listen to the buses briefly: another controller driving these motors refuses the enable
           (:class:`~akarm.ForeignTraffic`).
        2. MIT joints: ENTER, at once followed by a zero-gain, zero-torque command (the driver would
           otherwise apply the last command it remembers), repeated until every joint gave two
           consistent replies, the first within its feedback timeout (else
           :class:`~akarm.StaleFeedback`). Servo joints: two status frames.
        3. Damping (kp = 0, the joint's kd, gravity feed-forward at the measured pose; servo: a
           braking current) until every joint is slower than ``settle_speed`` (with its weight
           carried a swing only decays, so the first reading below it is rest; else
           :class:`~akarm.NotSettled` after ``settle_timeout``).
        4. The measured pose becomes the commanded one; kp ramps up from zero over ``enable_ramp`` s.

        Between 2 and 3, once every joint answered and before anything with gains or torque is sent,
        each reading is compared with the position remembered when the arm last stopped (see
        ``remember_positions``): a joint whole rotor turns from it refuses the enable with
        :class:`~akarm.TurnCountLost`.

        Args:
            timeout: s to wait for every joint's replies (default: the timing profile's, 0.5 s normally).
            accept_position: skip that comparison this once: the positions the joints read now were
                checked by eye (or the joints were zeroed).

        Raises:
            ArgumentError: a ``timeout`` that is not a finite number ≥ 0, an ``accept_position`` that is
                not a bool (nothing is sent, the mode is unchanged).
            FeedbackTimeout: a joint did not answer (it names the joint; nothing is left enabled).
            TurnCountLost: a joint reads whole rotor turns from where it stopped (nothing was enabled).
            SafetyStop: what else refused it (the arm is left disabled).
        """
        if timeout is not None:
            timeout = finite_number(timeout, "enable timeout", at_least=0.0, unit="s",
                                    fix="give the seconds to wait for the joints' replies, e.g. 0.5, or None "
                                        "for the timing profile's")
        if not isinstance(accept_position, bool):
            raise ArgumentError(f"accept_position must be True or False, got {accept_position!r}")
        self._ctl.enable(timeout, accept_position)

    def disable(self, wait: bool = True) -> None:
        """Damp every joint (kp = 0) for ``stop_damping_time`` s, then exit motor mode. Blocks unless
        ``wait`` is False (the stop is then under way: :attr:`mode` is STOPPING until it is done)."""
        self._ctl.disable(wait)

    @property
    def enabled(self) -> bool:
        """True while the motors are powered and under control: holding, moving, or in teach mode
        (:attr:`mode` is ACTIVE or TEACH; only ACTIVE takes motions)."""
        return self._ctl.mode.enabled

    @property
    def mode(self) -> Mode:
        """What the arm is doing now (:class:`~akarm.control.modes.Mode`)."""
        return self._ctl.mode

    # ------------------------------------------------------------------------------------------
    # motion
    # ------------------------------------------------------------------------------------------
    def target_positions(self, target: Target) -> np.ndarray:
        """The joint positions (rad, config order) ``target`` stands for: a named pose of the YAML, one
        angle per joint, or a ``{joint: angle}`` mapping (the other joints: where they are commanded now).

        Raises:
            ArgumentError: an unknown pose or joint, the wrong number of values, a value that is not a
                finite number (names the joint).
        """
        if isinstance(target, str):
            if target not in self.config.poses:
                hint = did_you_mean(target, list(self.config.poses))
                raise ArgumentError(f"no pose named {target!r}{hint}",
                                    fix="poses are: " + (", ".join(self.config.poses) or "none (add `poses:` to the "
                                                                                        "robot file)"))
            return np.array(self.config.pose(target), dtype=float)
        if isinstance(target, Mapping):
            q = self._ctl.desired_now()[0].copy()
            for name, value in target.items():
                if name not in self.names:
                    raise ArgumentError(f"no joint named {name!r}{did_you_mean(str(name), self.names)}",
                                        fix="joints are: " + ", ".join(self.names))
                q[self.names.index(name)] = self._number(value, name)
            return q
        try:
            values = list(target)
        except TypeError:
            raise ArgumentError(f"a target must be a pose name, one angle per joint or a {{joint: angle}} mapping, "
                                f"not {target!r}",
                                fix="give one angle (rad) per joint: " + ", ".join(self.names)) from None
        if len(values) != self.n:
            raise ArgumentError(f"target has {len(values)} values, the arm has {self.n} joints",
                                fix="give one angle (rad) per joint in config order: " + ", ".join(self.names))
        return np.array([self._number(v, name) for v, name in zip(values, self.names, strict=True)])

    @staticmethod
    def _number(value: object, joint: str) -> float:
        """``value`` as a finite float, or :class:`ArgumentError` naming ``joint``."""
        try:
            x = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise ArgumentError(f"target {value!r} is not a number", joint=joint, fix="give an angle in rad") from None
        if not math.isfinite(x):
            raise ArgumentError(f"target {x} is not a finite angle", joint=joint, fix="give an angle in rad")
        return x

    @staticmethod
    def _speed(speed: object) -> float:
        """A move's ``speed`` (a fraction of the joint limits) as a float in [:data:`MIN_SPEED`, 1], or
        :class:`ArgumentError` (a speed near 0 scales the jerk limit by its cube: ruckig cannot plan it)."""
        return finite_number(speed, "speed", at_least=MIN_SPEED, at_most=1.0,
                             fix="give a fraction of the joint limits, e.g. speed=0.5")

    def _per_joint(self, values: object, what: str, *, unit: str = "rad", at_least: float | None = None) -> np.ndarray:
        """``values``: one finite number per joint (``unit``, config order; each ≥ ``at_least`` if given), else
        :class:`ArgumentError` naming ``what`` (and the joint)."""
        fix = f"give one value ({unit}) per joint in config order: " + ", ".join(self.names)
        try:
            if isinstance(values, str | bytes | Mapping):
                raise TypeError
            items = list(values)  # type: ignore[call-overload]
        except TypeError:
            raise ArgumentError(f"{what} must be one value per joint, not {values!r}", fix=fix) from None
        if len(items) != self.n:
            raise ArgumentError(f"{what} has {len(items)} values, the arm has {self.n} joints", fix=fix)
        return np.array([finite_number(v, what, joint=name, unit=unit, at_least=at_least)
                         for v, name in zip(items, self.names, strict=True)])

    def _start(self, make_plan: Callable[[State, float], Timed], *, walls: bool = True) -> Motion:
        """Plan (``make_plan(start, t)``) and follow; a plan whose path takes the tool outside the robot
        file's ``workspace:`` is refused before anything moves (:func:`akarm.motion.walls.check_path`; not
        a stop: ``walls=False``)."""
        workspace, sc = self.config.workspace, self.self_collision
        if (workspace is None and sc is None) or not walls:
            return self._ctl.start(make_plan)
        from akarm.motion.walls import check_path, path_samples

        def checked(start: State, now: float) -> Timed:
            plan = make_plan(start, now)
            if workspace is not None:
                check_path(self.ik.model, workspace, plan)
            if sc is not None:
                sc.check_path(path_samples(plan), sc.collides(start[0]))
            return plan

        return self._ctl.start(checked)

    def _within_torque(self, make: Callable[[float], Timed], speed: float) -> Timed:
        """``make(speed)``, slower where its torque asks more than a joint's budget
        (:class:`akarm.motion.torque.TorqueBudget`: a real unit may give 30 % less torque than its datasheet;
        an identified one what its torque scale says; where the arm holds still, what its motors report
        against the model's gravity there). Refused where gravity alone needs more than a joint's limit
        (:class:`~akarm.LimitError`)."""
        plan = make(speed)
        if self._torque_budget is None:
            self._torque_budget = TorqueBudget(self.config, RobotModel(self.config, armature=True))
        budget = self._torque_budget
        budget.set_payload(self.payload)
        st = self.state()
        if st.enabled and not st.moving and float(np.max(np.abs(st.dq), initial=0.0)) < HOLD_STILL:
            budget.measure_hold(st.q, st.tau)  # what the unit needs to hold where it is, against the model
        for _ in range(3):
            factor, _joint = budget.speed_factor(plan.sample, plan.t0, plan.t_end)
            if factor >= 0.995:
                break
            speed = max(speed * factor * 0.98, 0.01)
            plan = make(speed)
        return plan

    def move_to(self, target: Target, speed: float = 1.0, wait: bool = True) -> Motion:
        """Move to ``target``: jerk-limited, every joint arriving together.

        Args:
            target: joint positions (rad, config order), a named pose from the YAML, or a mapping
                ``{joint: rad}`` (other joints keep their commanded position).
            speed: fraction of the joint limits, in (0, 1]: the same path, 1/speed times slower.
            wait: block until the motion ends (where the timing profile says readings trail the commands,
                as ``slow`` does, until they show every joint within :data:`ARRIVED` of its target, for
                at most twice the profile's ``lag``).

        Raises:
            LimitError: the target or any point of the planned path is outside a joint's range
                (checked before anything moves; names the joint). A move may start up to
                ``range_margin`` outside a range, and come back into it.
        """
        speed = self._speed(speed)
        q = self.target_positions(target)
        return self._run(self._start(lambda start, now: self._within_torque(
            lambda s: self.planner.move_from(start, q, now, s), speed)), wait)

    def move_through(self, points: Sequence[Target], speed: float = 1.0, wait: bool = True) -> Motion:
        """Move through every point without stopping at the intermediate ones; end at rest on the last.

        Each intermediate point is passed exactly (the path is continuous in position, velocity and
        acceleration). ``points`` are joint vectors, pose names or mappings; ``speed`` as in
        :meth:`move_to`. Raises :class:`~akarm.LimitError` before moving if any point or any
        position on the path is outside a joint's range, and :class:`~akarm.ArgumentError` for more
        than :data:`~akarm.motion.bounds.MAX_KEYFRAMES` points (before looking at them).
        """
        speed = self._speed(speed)
        _bounded(points, MAX_KEYFRAMES, "points", "move_through takes", "split the path into several moves")
        qs = [self.target_positions(p) for p in points]
        return self._run(self._start(lambda start, now: self._within_torque(
            lambda s: self.planner.through(start, qs, now, s), speed)), wait)

    def follow(self, times: Sequence[float], positions: Sequence[Sequence[float]] | np.ndarray,
               velocities: Sequence[Sequence[float]] | np.ndarray | None = None, wait: bool = True) -> Motion:
        """Move through ``positions[k]`` (rad, config order; NaN: keep that joint where it is
        commanded), reaching each ``times[k]`` s from now, or as soon after as the limits allow.

        Jerk-limited through every point (:func:`akarm.motion.timed.timed_plan`); replaces a running motion
        smoothly. Raises :class:`~akarm.LimitError` before anything moves if a point or the path
        leaves a joint's range, and :class:`~akarm.ArgumentError` before anything is planned for more
        than :data:`~akarm.motion.bounds.MAX_TRAJECTORY_POINTS` points or a last time past
        :data:`~akarm.motion.bounds.MAX_DURATION`.
        """
        from akarm.motion.timed import timed_plan

        _bounded(times, MAX_TRAJECTORY_POINTS, "points", "a trajectory has", "send it in parts")
        _bounded(positions, MAX_TRAJECTORY_POINTS, "points", "a trajectory has", "send it in parts")
        try:
            last = float(times[-1]) if len(times) else 0.0
        except (TypeError, ValueError, IndexError):
            last = 0.0  # not times at all: timed_plan says what is wrong
        if last > MAX_DURATION:
            raise ArgumentError(f"the trajectory's last point is at {last:g} s, past the {MAX_DURATION:g} s a motion "
                                "may last (akarm.motion.bounds.MAX_DURATION)", fix="send it in parts")

        return self._run(self._start(lambda start, now: timed_plan(self.planner, start, now, times, positions,
                                                                   velocities)), wait)

    def stream_to(self, target: Target, speed: float = 1.0, *, synchronize: bool = True) -> Motion:
        """Retarget online: from the current commanded state (position, velocity, acceleration) to
        ``target``, without a jump. Does not block; call it as often as new targets arrive.

        ``synchronize=False``: each joint heads for its target as fast as its own limits allow instead
        of all arriving together (tracking a stream, as :mod:`akarm.teleop` does)."""
        speed = self._speed(speed)
        q = self.target_positions(target)
        return self._start(lambda start, now: self.planner.move_from(start, q, now, speed, synchronize))

    def stop(self, wait: bool = True) -> Motion:
        """Bring the commanded motion to rest, jerk-limited, and hold there."""
        return self._run(self._start(lambda start, now: Plan([self.planner.stop(start, now)]), walls=False), wait)

    def hold(self) -> None:
        """Hold the current commanded position (stopping, jerk-limited, first if moving)."""
        self._ctl.require_enabled()
        if self._ctl.running():
            self.stop(wait=True)

    def _run(self, motion: Motion, wait: bool) -> Motion:
        if not wait:
            return motion
        motion.wait()
        if self.timing.lag > 0 and not motion.superseded:
            self._await_readings(2.0 * self.timing.lag)
        return motion

    def _await_readings(self, window: float) -> None:
        """On a machine whose readings trail the commands (a timing profile with ``lag``, e.g. ``slow``):
        wait, at most ``window`` s, until every joint reads within :data:`ARRIVED` of its command, so that
        a move that returned shows the arm where it was sent (a move's end is the plan's)."""
        end = self.clock.now() + window

        def there() -> bool:
            with self._ctl.lock:
                error = max(abs(j.state.position - c) for j, c in zip(self.joints, self._ctl.des[0], strict=True))
            return error < ARRIVED or self.clock.now() >= end

        self._ctl.wait_for(there, window + 5.0, "the readings to catch up with the commands")

    # ------------------------------------------------------------------------------------------
    # Cartesian: the tool frame's pose (akarm.dynamics.ik, akarm.motion.cartesian)
    # ------------------------------------------------------------------------------------------
    @property
    def ik(self) -> IKSolver:
        """The IK solver (:class:`akarm.dynamics.ik.IKSolver`), on a model of its own (the loop thread's
        is not shared), within the joint limits."""
        if self._ik_solver is None:
            self._ik_solver = IKSolver(RobotModel(self.config), self.limits.lower, self.limits.upper)
        return self._ik_solver

    def tool_pose(self, q: Sequence[float] | None = None) -> np.ndarray:
        """The 4×4 pose of the YAML's ``tool_frame`` in the base frame (translation in m), at the
        measured joint positions (or at ``q``, rad).

        Raises:
            ArgumentError: a ``q`` that is not one finite angle per joint (names the joint).
        """
        if q is None:
            with self._ctl.lock:  # (only the reading under the loop's lock)
                measured = [j.state.position for j in self.joints]
            return self.ik.model.tool_pose(measured)
        return self.ik.model.tool_pose(self._per_joint(q, "tool_pose q"))

    def _pose_target(self, pose: object) -> tuple[np.ndarray, np.ndarray, bool]:
        """(start q: the commanded position, the target 4×4, position only?) for a Cartesian move."""
        self._ctl.require_enabled()
        q0 = self._ctl.desired_now()[0]
        target, oriented = as_pose(pose, self.ik.model.tool_pose(q0))
        return q0, target, self.ik.position_only(oriented)

    def move_to_pose(self, pose: object, speed: float = 1.0, wait: bool = True) -> Motion:
        """Move the tool to ``pose`` by a joint-space move (jerk-limited, joints arriving together).

        ``pose``: a 4×4 transform of the tool frame in the base frame (m), ``(xyz, quaternion xyzw)``,
        or a position ``(x, y, z)`` alone: the tool keeps its orientation (arms with fewer than six
        joints cannot, and go to the position whatever their orientation). The joint positions are
        solved (:class:`akarm.dynamics.ik.IKSolver`) nearest the commanded ones; ``speed`` as in :meth:`move_to`.

        Raises:
            UnreachableError: out of reach (says how close the tool gets).
            LimitError: the pose needs a joint past its range (names it), or the path does.
            SingularityError: the pose is reached only at a singularity.
        """
        speed = self._speed(speed)
        q0, target, position_only = self._pose_target(pose)
        q = self.ik.solve(target, q0, position_only)
        return self.move_to(q, speed=speed, wait=wait)

    def move_linear(self, pose: object, speed: float = 1.0, wait: bool = True, *, max_velocity: float | None = None,
                    max_acceleration: float | None = None) -> Motion:
        """Move the tool in a straight line to ``pose`` (``pose`` as in :meth:`move_to_pose`), its
        orientation turning about one axis on the way (slerp), from rest to rest.

        The timing is jerk-limited along the line; every joint's velocity, acceleration and jerk stay
        within its limits times ``speed``, ``speed²``, ``speed³``, and ``max_velocity`` (m/s) /
        ``max_acceleration`` (m/s²) cap the tool's. The whole joint path is solved and checked
        before anything moves (:mod:`akarm.motion.cartesian`).

        Raises:
            StateError: the arm is moving (a line starts from rest: wait for the motion, or stop()).
            UnreachableError, LimitError, SingularityError: a point of the line the tool cannot
                reach, one past a joint's range (names the joint), a singularity on the way; each
                says where on the line. Nothing moved.
        """
        speed = self._speed(speed)
        q0, target, position_only = self._pose_target(pose)
        if self._ctl.moving:
            raise StateError("move_linear starts from rest and the arm is moving",
                             fix="wait for the motion to end (motion.wait()), or call arm.stop() first")
        plan = plan_linear(self.ik, self.limits, q0, target, speed=speed, position_only=position_only,
                           max_velocity=max_velocity, max_acceleration=max_acceleration)

        def make(start: State, now: float) -> Timed:
            if self._ctl.moving or not np.array_equal(start[0], q0):
                raise StateError("the arm moved while the line was planned",
                                 fix="start one motion at a time (wait for each)")
            return plan.at(now)

        return self._run(self._start(make), wait)

    def servo(self, timeout: float = 0.1, frame: str = "base", *, max_speed: float = 0.25,
              max_rotation: float = 1.0) -> Servo:
        """Steer the tool live: ``with arm.servo() as s: s.twist([vx, vy, vz, wx, wy, wz])`` or
        ``s.pose(T)``, at any rate up to the loop's (:mod:`akarm.motion.servo`).

        Every cycle the command becomes joint motion by damped least squares, within each joint's
        velocity, acceleration and jerk limits and its range less a margin; near a singularity, a joint
        limit or a wall of ``workspace:`` the arm slows and stops short (``s.status`` says which).
        Commands that stop coming for ``timeout`` s bring it to rest, jerk-limited, and hold it; the next
        resumes. Leaving the block brings it to rest and holds. Another motion (or a stop) ends servoing.

        Args:
            timeout: s a command lasts. frame: ``"base"`` or ``"tool"``: the axes of a twist.
            max_speed, max_rotation: m/s and rad/s the tool goes at most (a faster twist is scaled down).

        Raises:
            ArgumentError: a timeout, speed or rotation that is not a finite number > 0, an unknown frame.
            StateError: the arm is not enabled.
        """
        timeout = finite_number(timeout, "servo timeout", above=0.0, unit="s", fix="e.g. timeout=0.1")
        max_speed = finite_number(max_speed, "servo max_speed", above=0.0, unit="m/s", fix="e.g. max_speed=0.25")
        max_rotation = finite_number(max_rotation, "servo max_rotation", above=0.0, unit="rad/s",
                                     fix="e.g. max_rotation=1.0")
        if frame not in ("base", "tool"):
            raise ArgumentError(f"frame must be \"base\" or \"tool\", got {frame!r}",
                                fix="the axes a twist is given in: frame=\"base\" or frame=\"tool\"")
        self._ctl.require_enabled()
        sc = self.self_collision
        stream = ServoStream(RobotModel(self.config), self.limits, self.config.workspace, 1.0 / self.config.rate_hz,
                             timeout, "tool" if frame == "tool" else "base", max_speed, max_rotation,
                             None if sc is None else sc.copy())

        def start(s: ServoStream) -> Motion:
            return self._start(s.begin, walls=False)

        return Servo(stream, start, self._ctl.plan_now, self._ctl.require_enabled, self.ik.model, self._ctl.raise_fault)

    def impedance(self, stiffness: Sequence[float] | None = None, damping_ratio: float = 1.0, *,
                  joint_stiffness: Sequence[float] | None = None, max_deviation: tuple[float, float] = (0.1, 0.5),
                  joint_damping: float = 0.3) -> Impedance:
        """Make the arm soft about where it is: ``with arm.impedance(stiffness=[kx, ky, kz, krx, kry, krz]) as
        imp:`` holds the tool there as a spring-damper (N/m, N·m/rad, base axes; damping ``damping_ratio``
        of critical), or with ``joint_stiffness=[...]`` (N·m/rad per joint) each joint
        (:mod:`akarm.control.impedance`). The torque is computed every cycle from the measured state and
        sent as the MIT feed-forward with kp = 0, the arm's weight carried; a null-space posture keeps
        redundant joints where they were. ``imp.set_target(...)``, ``imp.set_stiffness(...)``,
        ``imp.wrench()`` (the external wrench, from the collision observer). Meanwhile the collision
        reflex only watches (a push is the point); a deviation from the target past ``max_deviation``
        (m, rad; a joint's in rad under joint impedance) is a :class:`~akarm.DeviationError` safety stop.
        Leaving the block holds the arm where it is, stiff again.

        Args:
            joint_damping: each joint's own damping meanwhile, N·m·s/rad (the MIT kd, at most its motor's).

        Raises:
            ArgumentError: not exactly one of ``stiffness`` (6 values) and ``joint_stiffness`` (one per
                joint), values that are not finite and ≥ 0, a damping ratio or bound that is not > 0.
            StateError: the arm is not enabled, a joint is in servo mode (no torque control), or a guarded
                move (:meth:`move_until_contact`) runs.
        """
        from akarm.control.impedance import ImpedanceLaw, stiffness_values

        if (stiffness is None) == (joint_stiffness is None):
            raise ArgumentError("give either stiffness (Cartesian: 6 values) or joint_stiffness (one per joint)",
                                fix="e.g. arm.impedance(stiffness=[500, 500, 500, 20, 20, 20])")
        k = None if stiffness is None else stiffness_values(stiffness, 6, "stiffness")
        kj = None if joint_stiffness is None else stiffness_values(joint_stiffness, self.n, "joint_stiffness")
        zeta = finite_number(damping_ratio, "damping_ratio", above=0.0, fix="e.g. 1.0: critically damped")
        try:
            bound = (finite_number(max_deviation[0], "max_deviation", above=0.0, unit="m"),
                     finite_number(max_deviation[1], "max_deviation", above=0.0, unit="rad"))
        except (TypeError, IndexError, KeyError):
            raise ArgumentError(f"max_deviation must be (m, rad), got {max_deviation!r}", fix="e.g. (0.1, 0.5)") \
                from None
        kd = finite_number(joint_damping, "joint_damping", at_least=0.0, unit="N·m·s/rad", fix="e.g. 0.3")
        for j in self.joints:
            if not j.answers_commands:
                raise StateError("impedance needs torque control, and this joint is in servo mode",
                                 joint=j.name, fix="drive it in MIT mode (`mode: mit` in the robot file)")
        self._ctl.require_enabled()
        self._ctl.refuse_during_watch("impedance")  # (before the hold that would stop it; again under the lock)
        self.hold()
        fr = [j.friction_model() for j in self.config.joints]
        on = 1.0 if self._ctl.options.friction_compensated else 0.0
        law = ImpedanceLaw(RobotModel(self.config, armature=True), self.names, self._ctl.torque_limit,
                           np.array([j.state.position for j in self.joints]), k, kj, zeta, bound,
                           [f.coulomb * on for f in fr], [f.viscous * on for f in fr])
        kds = [min(kd, j.motor.kd_max) for j in self.joints]

        def measured() -> np.ndarray:
            with self._ctl.lock:
                return np.array([j.state.position for j in self.joints])

        def reach(T: np.ndarray) -> None:
            self.ik.solve(T, measured(), position_only=self.n < 6, check_singular=False)  # (fewer joints: where)

        return Impedance(self._ctl, law, kds, self.ik.model, measured, self.limits, self.config.workspace, reach)

    def move_until_contact(self, direction: Sequence[float], speed: float = 0.02, force: float = 5.0, *,
                           max_distance: float = 0.2, back_off: float = 0.0) -> Contact:
        """A guarded move: the tool in a straight line along ``direction`` (base frame; its length does not
        matter) at ``speed`` m/s, its orientation kept, until the external force against the motion reaches
        ``force`` N (from the collision observer's estimate, :mod:`akarm.control.guard`); then it stops,
        jerk-limited (the collision reflex's "stop and report"), goes back to where it touched (its
        command went on past it as far as the arm gave), or ``back_off`` m short of it, and holds there.
        At most ``max_distance`` m. Meanwhile the collision thresholds are suspended:
        a force of twice ``force`` in any direction stops the move too.

        Returns:
            the :class:`~akarm.control.guard.Contact`: whether it touched, where (measured), with what force.

        Raises:
            ArgumentError: a direction that is not 3 finite numbers (not all 0), a speed, force or distance
                that is not a finite number > 0 (back_off ≥ 0).
            StateError: the arm is moving or not enabled, or under impedance control (:meth:`impedance`).
                LimitError, UnreachableError, SingularityError:
                the line is refused before anything moves (as :meth:`move_linear`'s).
        """
        from akarm.control.guard import ContactWatch

        try:
            d = np.asarray(direction, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            d = np.full(0, math.nan)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise ArgumentError(f"direction must be 3 finite numbers, not all 0 (base frame), got {direction!r}",
                                fix="e.g. [0, 0, -1]: down")
        d = d / np.linalg.norm(d)
        speed = finite_number(speed, "speed", above=0.0, unit="m/s", fix="e.g. speed=0.02")
        force = finite_number(force, "force", above=0.0, unit="N", fix="e.g. force=5.0")
        max_distance = finite_number(max_distance, "max_distance", above=0.0, unit="m", fix="e.g. 0.2")
        back_off = finite_number(back_off, "back_off", at_least=0.0, unit="m", fix="e.g. 0.005, or 0 to hold")
        start = self.ik.model.tool_pose(self._ctl.desired_now()[0])
        end = start.copy()
        end[:3, 3] += d * max_distance
        watch = ContactWatch(RobotModel(self.config), d, force, start[:3, 3])
        self._ctl.begin_watch(watch)
        try:
            motion = self.move_linear(end, wait=False, max_velocity=speed)
            while not motion.done and not watch.fired:
                self.sleep(1.0 / self.config.rate_hz)
            found = watch.found
            if found is None:
                motion.wait()
            else:
                while self.moving:  # the stop, to rest
                    self.sleep(1.0 / self.config.rate_hz)
                # the command went on past the contact as far as the arm gave: back to where it touched
                # (less back_off), so that it holds there without pressing
                away = self.ik.model.tool_pose(self._ctl.desired_now()[0])
                away[:3, 3] = found[1] - d * back_off
                self.move_linear(away, max_velocity=max(speed, 0.01))
        finally:
            self._ctl.end_watch()
        if found is None:
            here = self.tool_pose()
            return Contact(False, watch.peak, here[:3, 3], np.zeros(6), float((here[:3, 3] - start[:3, 3]) @ d), here)
        return Contact(True, found[0], found[1], found[2], found[3], self.tool_pose())

    @property
    def moving(self) -> bool:
        """True while a motion is being executed."""
        return self._ctl.moving

    def set_gains(self, kp: Sequence[float] | float | None = None, kd: Sequence[float] | float | None = None) -> None:
        """Change MIT gains while running: kp in N·m/rad, kd in N·m·s/rad, per joint or one for all,
        each within its motor's range (``kp_max``, ``kd_max``: 500 and 5 on most models).

        ``set_gains(kp=0, kd=0.5)`` with :meth:`set_extra_torque` gives pure torque control with
        the arm's weight carried: joints with kp = 0 get their gravity torque at the *measured* pose
        (they are not held at the commanded one, and the following-error check leaves them alone).
        Servo joints ignore gains. The default following-error limits follow the new kp.

        Raises:
            ArgumentError: a gain that is not a finite number ≥ 0 within its motor's range, a list
                that is not one per joint (names the joint).
            StateError: under impedance control (:meth:`impedance`: its gains are the law's).
        """
        self._ctl.set_gains(self._gain(kp, "kp", "N·m/rad"), self._gain(kd, "kd", "N·m·s/rad"))

    def _gain(self, value: object, name: str, unit: str) -> float | list[float] | None:
        """A gain argument: ``None``, one number for every joint, or one per joint (each finite, ≥ 0)."""
        if value is None:
            return None
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return finite_number(value, name, at_least=0.0, unit=unit)
        return self._per_joint(value, name, unit=unit, at_least=0.0).tolist()

    def set_extra_torque(self, tau: Sequence[float] | None) -> None:
        """Add ``tau`` (N·m per joint, config order; ``None`` clears) to every MIT command's torque,
        on top of the feed-forward (in teach mode on top of the arm's weight: force feedback to a hand),
        clamped to each joint's torque limit."""
        self._ctl.set_extra_torque(tau)

    # ------------------------------------------------------------------------------------------
    # teach and replay
    # ------------------------------------------------------------------------------------------
    def teach(self, damping: float = 0.1) -> None:
        """Make the arm hand-guidable, its weight carried, until :meth:`end_teach`.

        MIT joints: kp = 0, kd = ``damping`` (N·m·s/rad, at most the joint's own kd), gravity
        feed-forward at the measured pose, plus :meth:`set_extra_torque`'s torque. Servo joints:
        current mode with the gravity current (``g(q) / (kt · gear_ratio)``). The supervisor stays on (all
        but the following error).
        """
        if not (isinstance(damping, int | float) and math.isfinite(damping) and damping >= 0):
            raise ArgumentError(f"teach damping must be a finite number of N·m·s/rad, at least 0, got {damping!r}",
                                fix="e.g. arm.teach(0.1); 0 leaves the joints free")
        self._ctl.require_enabled()
        for j in self.joints:
            if not j.answers_commands and j.motor.kt is None:
                raise ConfigError([ConfigProblem(str(self.config.source or self.config.name), None,
                                                 f"joint {j.name!r}: motor {j.motor.name} has no kt",
                                                 "set kt (N·m/A at the rotor) under `motors:` to teach servo joints")])
        self.hold()
        self._ctl.enter_teach(damping)

    def keyframe(self, name: str | None = None) -> rec_mod.Keyframe:
        """The measured pose now, as a keyframe (rad, config order) with an optional name."""
        if name is not None and not isinstance(name, str):
            raise ArgumentError(f"a keyframe's name must be text or None, got {name!r}", fix='e.g. "grasp"')
        with self._ctl.lock:
            return rec_mod.Keyframe(tuple(float(j.state.position) for j in self.joints), name)

    def start_recording(self, rate_hz: float = 50.0, duration: float | None = None) -> None:
        """Start recording the measured pose continuously at ``rate_hz`` (in teach mode).

        With ``duration`` (s) the loop itself stops sampling once that much is recorded, so the
        path is ``duration`` long and holds ``floor(duration * rate_hz) + 1`` samples however late
        the caller gets round to :meth:`stop_recording`; :attr:`recording_finished` tells when.
        """
        if not (isinstance(rate_hz, int | float) and 0 < rate_hz <= self.config.rate_hz):
            raise ArgumentError(f"rate_hz must be in (0, {self.config.rate_hz:g}] (the loop rate), not {rate_hz!r}")
        if duration is not None and not (isinstance(duration, int | float) and 0 < duration < math.inf):
            raise ArgumentError(f"duration must be a positive number of seconds, not {duration!r}")
        if self._ctl.mode is not Mode.TEACH:
            raise StateError("recording a path needs teach mode", fix="call arm.teach() first")
        self._ctl.start_recording(rate_hz, duration)

    @property
    def recording_finished(self) -> bool:
        """True once a recording started with a ``duration`` has all its samples (False with none)."""
        return self._ctl.recording_finished

    def stop_recording(self) -> rec_mod.PathRecording:
        """Stop the continuous recording and return it (times from 0, s; positions rad)."""
        rec = self._ctl.stop_recording()
        if rec is None or len(rec.times) < 2:
            raise StateError("no path was recorded", fix="call start_recording() and move the arm for a while")
        t = np.array(rec.times) - rec.times[0]
        return rec_mod.PathRecording(self.names, t, np.array(rec.positions))

    def end_teach(self) -> None:
        """Leave teach mode: hold the pose the arm was left in, gains ramping up from zero."""
        self._ctl.end_teach()

    def check_replay(self, recording: rec_mod.Keyframes | rec_mod.PathRecording | str | PathLike[str],
                     speed: float = 1.0) -> rec_mod.Keyframes | rec_mod.PathRecording:
        """Load and check a recording against every limit without moving (nor enabling) the arm.

        Returns the recording. Raises :class:`~akarm.RecordingError` or :class:`~akarm.LimitError`
        exactly as :meth:`replay` would before moving. Keyframes are checked for position and
        planned (from rest at the first keyframe) so a path past a limit is found too.
        """
        rec, speed = self._recording(recording, speed)
        if isinstance(rec, rec_mod.Keyframes):
            qs = self._keyframe_positions(rec)
            self.planner.through((qs[0], np.zeros(self.n), np.zeros(self.n)), qs, 0.0, speed)
        else:
            rec_mod.check_path(rec_mod.PathPlan(rec, 0.0, speed), self.limits)
        return rec

    def _recording(self, recording: rec_mod.Keyframes | rec_mod.PathRecording | str | PathLike[str],
                   speed: object) -> tuple[rec_mod.Keyframes | rec_mod.PathRecording, float]:
        """The recording (read if a file), for this arm's joints and within the sizes of
        :mod:`akarm.motion.bounds` (:class:`~akarm.RecordingError` naming the bound, before anything else),
        and the ``speed`` it is replayed at: a finite factor > 0, at most 1 for keyframes (a fraction of
        the joint limits, as in :meth:`move_to`), else :class:`~akarm.ArgumentError` (before a file is read)."""
        factor = finite_number(speed, "speed", above=0.0, fix="e.g. speed=0.5")
        rec = recording if isinstance(recording, rec_mod.Keyframes | rec_mod.PathRecording) else \
            rec_mod.load(recording, self.names)
        if tuple(rec.joint_names) != tuple(self.names):
            raise LimitError(f"the recording is for joints {list(rec.joint_names)}",
                             fix=f"replay it on an arm with joints {list(self.names)}")
        if isinstance(rec, rec_mod.Keyframes):
            if len(rec.frames) > MAX_KEYFRAMES:
                raise RecordingError(f"the recording has {len(rec.frames)} keyframes, more than the {MAX_KEYFRAMES} a "
                                     "replay takes (akarm.motion.bounds.MAX_KEYFRAMES)", fix="split it into several")
            if factor > 1.0:
                raise ArgumentError(f"keyframes are replayed at a fraction of the joint limits, in (0, 1]; got speed "
                                    f"{speed!r}", fix="give a speed of at most 1 (1: as fast as the limits allow)")
        else:
            if len(rec.t) > MAX_PATH_SAMPLES:
                raise RecordingError(f"the path has {len(rec.t)} samples, more than the {MAX_PATH_SAMPLES} a replay "
                                     "takes (akarm.motion.bounds.MAX_PATH_SAMPLES)", fix="split it into several")
            if not rec.duration / factor <= MAX_DURATION:
                raise RecordingError(f"the path would take {rec.duration / factor:.0f} s at speed {factor:g}, more "
                                     f"than the {MAX_DURATION:g} s a motion may last "
                                     "(akarm.motion.bounds.MAX_DURATION)",
                                     fix="replay it faster, or split it into several")
        return rec, factor

    def _keyframe_positions(self, rec: rec_mod.Keyframes) -> list[np.ndarray]:
        """The keyframes' positions, each checked against the joint ranges (:class:`~akarm.LimitError`)."""
        lim = self.limits
        for k, frame in enumerate(rec.frames):
            for i, q in enumerate(frame.q):
                if not lim.lower[i] - 1e-9 <= q <= lim.upper[i] + 1e-9:
                    label = f" {frame.name!r}" if frame.name else ""
                    raise LimitError(f"keyframe {k}{label} is at {num(q, sign=True)} rad, outside "
                                     f"[{num(lim.lower[i], sign=True)}, {num(lim.upper[i], sign=True)}] rad",
                                     joint=self.names[i],
                                     fix="edit that keyframe or the joint limits")
        return [np.array(f.q) for f in rec.frames]

    def replay(self, recording: rec_mod.Keyframes | rec_mod.PathRecording | str | PathLike[str],
               speed: float = 1.0, wait: bool = True) -> Motion:
        """Replay a recording (or a recording file), checked against every limit before anything moves.

        A soft start first moves, jerk-limited, from wherever the arm is to the first point.
        Keyframes are then passed through as one smooth move (``speed`` as in :meth:`move_to`: a
        fraction of the joint limits, in (0, 1]; more is refused, as a path too fast for the limits is);
        a path is followed at its recorded timing divided by ``speed`` (any finite factor > 0).

        The plan is made in this thread while the arm goes on holding (or moving) under the control
        loop, and takes over when it is ready (a 5000-keyframe or one-hour recording takes seconds).

        Raises:
            ArgumentError: a ``speed`` that is not a finite number > 0, or more than 1 for keyframes.
            RecordingError: an unreadable, truncated or mismatched file, or one past the sizes of
                :mod:`akarm.motion.bounds` (names the bound).
            LimitError: the path breaks a limit after scaling; names the joint and the time, and
                suggests the speed factor that would pass.
        """
        rec, speed = self._recording(recording, speed)
        if isinstance(rec, rec_mod.Keyframes):  # planned once, from where the arm is, through every keyframe
            return self.move_through(self._keyframe_positions(rec), speed=speed, wait=wait)
        path = rec_mod.PathPlan(rec, 0.0, speed)  # made and checked once: taking over only shifts it in time
        rec_mod.check_path(path, self.limits)

        def make(start: State, now: float) -> Timed:
            soft = self.planner.move_from(start, path.q[0], now, min(speed, 1.0))
            return Chain([soft, path.shifted(soft.t_end)])

        return self._run(self._start(make), wait)

    # ------------------------------------------------------------------------------------------
    # state, payload, time
    # ------------------------------------------------------------------------------------------
    def state(self) -> ArmState:
        """The latest feedback of every joint and the commanded position (see :class:`ArmState`)."""
        now = self.clock.now()
        ctl = self._ctl
        with ctl.lock:
            ext = ctl.external_torque()
            reps = tuple(JointReport(j.name, j.state.position, j.state.velocity, j.state.torque,
                                     j.state.temperature, j.state.error, j.state.age(now), float(x))
                         for j, x in zip(self.joints, ext, strict=True))
            q_des = ctl.des[0].copy()
            mode = ctl.mode
            moving = ctl.moving
        return ArmState(now, reps, np.array([r.position for r in reps]), np.array([r.velocity for r in reps]),
                        np.array([r.torque for r in reps]), q_des, mode.enabled, moving, mode, ext)

    def read_state(self, timeout: float = 0.25) -> ArmState:
        """:meth:`state`, with a disabled arm's motors asked first, as ``akarm status`` asks them: its
        silent MIT joints get EXIT (they stay disabled) and up to ``timeout`` s to answer (servo joints
        report on their own). An enabled arm's feedback is fresh every cycle: nothing is sent. A joint
        that did not answer keeps its old reading; its ``age`` says how old
        (:mod:`akarm.control.reading`)."""
        from akarm.control.reading import read_disabled

        if not (isinstance(timeout, int | float) and 0 <= timeout < math.inf):
            raise ArgumentError(f"timeout must be a finite number of seconds ≥ 0, got {timeout!r}")
        if self._ctl.mode is not Mode.CLOSED:
            read_disabled(self._ctl, timeout)
        return self.state()

    def set_payload(self, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Tell the arm about a payload at the tool frame: kg, centre of mass in the tool frame (m).

        The feed-forward carries it and the collision reflex expects it (its external torque
        estimate uses the same model, and starts over: the arm's inertia changed), from the next
        cycle on. A :class:`~akarm.ConfigWarning` says so when the motors cannot hold the arm with it
        everywhere in the joint ranges (:meth:`gravity_check`, as ``akarm check`` does for the file).

        Raises:
            ArgumentError: a mass that is not a number ≥ 0, a centre of mass that is not 3 finite numbers.
        """
        m = finite_number(mass, "payload mass", at_least=0.0, unit="kg", fix="give the mass in kg")
        try:
            if isinstance(com, str | bytes) or len(com) != 3:
                raise TypeError
            c = np.array([finite_number(x, "payload com", unit="m") for x in com])
        except (TypeError, ArgumentError):
            raise ArgumentError(f"payload com must be 3 finite numbers (m, tool frame), got {com!r}",
                                fix="e.g. (0, 0, 0.04)") from None
        self._ctl.set_payload(m, c)
        over = [(p, j) for p, j in zip(self.gravity_check(), self.config.joints, strict=True)
                if p.torque > j.limits.torque]
        if over:
            import warnings

            from akarm.errors import ConfigWarning

            text = "; ".join(f"{j.name} needs up to {p.torque:.1f} N·m (limit {j.limits.torque:g}) at {p.pose()}"
                             for p, j in over)
            warnings.warn(ConfigWarning(f"with a payload of {float(mass):g} kg the motors cannot hold the arm "
                                        f"everywhere in its ranges: {text}"), stacklevel=2)

    def gravity_check(self) -> list[GravityPeak]:
        """``akarm check``'s gravity check with the payload the arm carries now: per joint, the largest
        gravity torque over the joint ranges and where (:func:`akarm.dynamics.gravity.gravity_peaks`)."""
        from dataclasses import replace

        from akarm.config import Payload
        from akarm.dynamics.gravity import gravity_peaks

        p = self.model.payload
        payload = None if p is None else Payload(p[0], (float(p[1][0]), float(p[1][1]), float(p[1][2])))
        return gravity_peaks(replace(self.config, payload=payload))

    def clear_payload(self) -> None:
        """Remove the payload from the model (the feed-forward's and the collision reflex's)."""
        self._ctl.clear_payload()

    @property
    def payload(self) -> tuple[float, np.ndarray] | None:
        """The payload the arm is told about: (kg, centre of mass in the tool frame, m), or ``None``."""
        p = self.model.payload
        return None if p is None else (p[0], p[1].copy())

    def set_friction(self, coulomb: Sequence[float], viscous: Sequence[float],
                     offset: Sequence[float] | None = None, *, torque_scale: Sequence[float] | None = None,
                     load: Sequence[float] | None = None) -> None:
        """Tell the arm each joint's friction (config order): Coulomb N·m, viscous N·m·s/rad and a
        constant torque offset N·m (default 0), e.g. what :func:`akarm.identify.identify` found.

        The collision reflex's estimate uses all three (and starts over); the feed-forward, where it
        compensates friction (``friction_feedforward``), takes Coulomb and viscous, and ``load`` (Coulomb
        friction's load-dependent part, N·m per N·m of the motor's torque). ``torque_scale``: the N·m each
        joint gets per N·m its motor reports (a real unit's, as ``akarm identify`` fits it): the
        feed-forward asks for the model's torque over it, the estimate counts the motors' torque times it.

        Raises:
            ArgumentError: not one finite value per joint, a Coulomb or viscous friction below 0 (as the
                robot file's ``friction:`` refuses it); names the joint.
        """
        c = self._per_joint(coulomb, "coulomb friction", unit="N·m", at_least=0.0)
        b = self._per_joint(viscous, "viscous friction", unit="N·m·s/rad", at_least=0.0)
        o = np.zeros(self.n) if offset is None else self._per_joint(offset, "friction offset", unit="N·m")
        s = None if torque_scale is None else self._per_joint(torque_scale, "torque scale", at_least=0.2)
        m = None if load is None else self._per_joint(load, "friction's load share", at_least=0.0)
        self._ctl.set_friction(c.tolist(), b.tolist(), o.tolist(), None if s is None else s.tolist(),
                               None if m is None else m.tolist())

    @property
    def gains(self) -> tuple[np.ndarray, np.ndarray]:
        """The MIT gains in force: (kp N·m/rad, kd N·m·s/rad) per joint, config order (copies; :meth:`set_gains`)."""
        return self._ctl.gains

    def set_collision(self, thresholds: Mapping[str, float | None] | Sequence[float | None] | None = None,
                      reaction: str | None = None) -> None:
        """Change the collision reflex: ``thresholds`` (N·m; a ``{joint: value}`` mapping for some joints,
        or one per joint in config order; ``None`` for a joint turns its check off) and ``reaction``
        (``"disable"`` or ``"hold"``). The YAML's ``collision: {threshold: ...}`` are the defaults.

        Raises:
            ArgumentError: an unknown joint, the wrong number of thresholds, one that is not a positive
                number, an unknown reaction.
        """
        ctl = self._ctl
        with ctl.lock:
            current: list[float | None] | None = None
            if isinstance(thresholds, Mapping):
                current = ctl.collision_thresholds
                for name, value in thresholds.items():
                    if name not in self.names:
                        raise ArgumentError(f"no joint named {name!r}{did_you_mean(str(name), self.names)}",
                                            fix="joints are: " + ", ".join(self.names))
                    current[self.names.index(name)] = value
            elif thresholds is not None:
                if isinstance(thresholds, str | bytes) or not isinstance(thresholds, Iterable):
                    raise ArgumentError(f"collision thresholds must be one per joint or a {{joint: N·m}} mapping, not "
                                        f"{thresholds!r}", fix="e.g. [10.0, None] in config order, or {'elbow': 10.0}")
                current = list(thresholds)
            ctl.set_collision(current, reaction)

    @property
    def collision_thresholds(self) -> dict[str, float | None]:
        """The collision reflex's threshold per joint, N·m (``None``: not checked)."""
        return dict(zip(self.names, self._ctl.collision_thresholds, strict=True))

    @property
    def collision_reaction(self) -> str:
        """What the collision reflex does when it fires: ``"disable"`` or ``"hold"`` (:meth:`set_collision`)."""
        return self._ctl.collision_reaction

    @property
    def collision_gain(self) -> float:
        """The bandwidth of the external torque estimate in force, 1/s (the ``collision_gain`` asked
        for, at most a quarter of the loop rate)."""
        return self._ctl.collision_gain

    @property
    def last_collision(self) -> CollisionError | None:
        """The collision reflex's last stop (also with the "hold" reaction: the arm stays enabled), or ``None``."""
        return self._ctl.last_collision

    @property
    def collision_peak(self) -> np.ndarray:
        """The largest ``|external torque estimate|`` per joint (N·m, config order) while the reflex
        judged (not in teach mode), since :meth:`reset_collision_peak` (or the Arm was made): how close
        the arm came to its thresholds."""
        return self._ctl.collision_peak

    def reset_collision_peak(self) -> None:
        """Start :attr:`collision_peak` over from zero."""
        self._ctl.reset_collision_peak()

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of the arm's clock while the loop keeps the arm under control.

        With a stepped (simulated) clock this is what advances time. Raises the arm's
        :class:`~akarm.SafetyStop` if it stopped meanwhile, and :class:`~akarm.ArgumentError` for
        ``seconds`` that are not a finite number ≥ 0.
        """
        seconds = finite_number(seconds, "sleep seconds", at_least=0.0, unit="s", fix="e.g. arm.sleep(0.5)")
        end = self.clock.now() + seconds
        self._ctl.wait_for(lambda: self.clock.now() >= end - 1e-12, seconds + 5.0, "time to pass", until=end)

    def telemetry(self, since: float | None = None) -> TelemetryLog:
        """The recorded cycles since ``since`` (clock time, s; default: all kept), oldest first: desired
        and measured q, dq, τ, the feed-forward and the external torque estimate (:attr:`telemetry_seconds`
        of them at most). A ``since`` that is not a finite number: :class:`~akarm.ArgumentError`."""
        if since is not None:
            since = finite_number(since, "telemetry since", unit="s, clock time", fix="e.g. arm.clock.now() - 5")
        return self._ctl.telemetry_log(since)

    @property
    def telemetry_seconds(self) -> float:
        """How much history :meth:`telemetry` keeps, s (the ``telemetry_seconds`` asked for, whole cycles)."""
        return self._ctl.telemetry.capacity / self.config.rate_hz

    def reset_stats(self) -> None:
        """Forget the loop timings measured so far (e.g. to leave start-up out of a benchmark)."""
        self._ctl.reset_stats()

    @property
    def realtime_report(self) -> str:
        """What the loop thread was granted of real-time priority, memory locking and CPU pinning (if it asked)."""
        return "not open" if self._ctl.mode is Mode.CLOSED else self._ctl.loop.realtime_report

    @property
    def fault(self) -> SafetyStop | None:
        """The safety stop that disabled the arm (it is raised by the next call), or ``None``."""
        return self._ctl.fault

    def stats(self) -> StatsSummary:
        """Loop timing: achieved rate, lateness and period percentiles, missed slots, time per stage."""
        return self._ctl.stats()

    @property
    def observe(self) -> ControllerView:
        """Read-only observability of the real-time side (:class:`akarm.control.view.ControllerView`):
        its buses, loop, last feed-forward torque, gain ramp and supervisor limits."""
        return self._observe
