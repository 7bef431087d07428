"""A teleoperation session: a hand guides the leader, the follower copies it.

::

    from akarm.teleop import Teleop
    with leader, follower:                       # two Arms, each with its own robot file and buses
        leader.enable(); follower.enable()
        with Teleop(leader, follower, force_feedback=0.5) as tele:
            while True:
                tele.step()                      # one follower cycle: read the leader, stream, feed back

It drives both arms through their public API only:

- **Leader**: in teach mode (:meth:`akarm.Arm.teach`): its weight carried, a little damping, no stiffness.
- **Engaging**: the follower first moves to the leader's pose at ``engage_speed`` (a fraction of its
  limits), streamed every cycle, so engaging never makes it jump; it follows once it is there and
  moves as the leader does (:data:`ENGAGE_TOLERANCE`, :data:`ENGAGE_SPEED_TOLERANCE`). A
  pose outside the follower's range is taken to the range's edge, where the follower waits (and
  says so) until the leader comes back.
- **Following**: every cycle (:meth:`Teleop.step`, paced by the follower's loop) the leader's pose,
  mapped (:class:`~akarm.teleop.pairing.Pairing`), goes to :meth:`akarm.Arm.stream_to`'s jerk-limited
  retargeting, each joint on its own (``synchronize=False``): no command step exceeds the follower's
  velocity, acceleration or jerk limit, whatever the leader does, and no command leaves its range. A
  retarget comes to rest at its target; to follow without the lag that would cost, the target is where
  the follower would come to rest if it braked now at its own limits from the leader's velocity
  (the leader's pose plus that stopping distance, :func:`stopping_distance`), within the range.
- **Latency**: per step, from the leader's newest feedback to the follower's command that uses it
  (:attr:`Teleop.latency`); :meth:`Teleop.summary` has the percentiles and the tracking error.
- **Force feedback** (``force_feedback`` > 0): the follower's external torque estimate (its collision
  observer, :attr:`akarm.ArmState.tau_ext`), times the gain, limited to ``force_limit`` (default a fifth
  of each leader joint's torque limit), is the leader's extra torque: the hand feels what the
  follower touches. The follower's collision reflex then reacts by holding: the session holds too
  (and says so) until the leader has been held at the follower for a moment, then engages again.
- **Grippers** (:mod:`akarm.teleop.pairing`): the leader's gripper (let go while the session runs: asked
  no force, the hand moves it freely; it holds again when the session finishes), or a trigger joint of
  the leader named in the mapping file, drives the follower's gripper every cycle (the same fraction of its
  stroke; a new width asked once it differs by :data:`GRIPPER_DEADBAND`, but none further in while the
  jaws are stopped on something: the grasp holds), with the force the mapping
  file or ``gripper_force`` names (default: the gripper's own), never over its ``force_limit``. With
  force feedback, a trigger feels the grasp (a leader gripper does not: the gripper takes no command
  while its arm is in teach mode): while the follower's jaws hold something, the trigger
  joint is pushed open with the torque that does the squeeze's work (``gain · force · stroke / trigger
  span``), within its force limit. Each :class:`Step` carries the follower gripper's width asked and
  measured (a dataset's ``gripper`` column).
- **Safety**: a safety stop of either arm stops both (damped, then disabled) and is raised; without
  force feedback the follower's reflex stays as it was built (armed, "disable" by default).
"""

from __future__ import annotations

import collections
import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from akarm.control.modes import Mode
from akarm.errors import AkarmError, ArgumentError, CollisionError, LimitError, SafetyStop, StateError
from akarm.teleop.pairing import Pairing

if TYPE_CHECKING:
    from akarm.arm import Arm, ArmState
    from akarm.control.gripper import Gripper
    from akarm.motion.trajectory import JointLimits

__all__ = ["DEFAULT_FORCE_SHARE", "ENGAGE_SPEED_TOLERANCE", "ENGAGE_TOLERANCE", "GRIPPER_DEADBAND", "RESUME_DWELL",
           "RESUME_TOLERANCE", "Step", "Summary", "Teleop", "stopping_distance"]

#: rad: engaging ends when every follower joint's command is this close to the leader's pose ...
ENGAGE_TOLERANCE = 0.01
#: rad/s: ... and the follower moves like the leader, each joint within this of its speed.
ENGAGE_SPEED_TOLERANCE = 0.1
#: rad: after a collision hold, the session engages again once the leader has been this close to the
#: follower, and slower than :data:`ENGAGE_SPEED_TOLERANCE`, for :data:`RESUME_DWELL` s.
RESUME_TOLERANCE = 0.05
#: s: how long the hand holds the leader there, still, before the follower engages again.
RESUME_DWELL = 0.5
#: The default force feedback limit: this share of each leader joint's torque limit.
DEFAULT_FORCE_SHARE = 0.2
#: m: the follower's gripper is asked a new width once the leader's differs this much from the last asked.
GRIPPER_DEADBAND = 0.0005
#: m, m/s: jaws at rest (slower than GRIPPER_STILL) further than GRIPPER_SHORT from the width asked
#: are stopped on something: a width further in is not asked (see :meth:`Teleop.step`)
GRIPPER_SHORT = 0.0015
GRIPPER_STILL = 0.005
#: Latencies kept for :meth:`Teleop.summary` (the last ones).
LATENCY_SAMPLES = 100_000


def stopping_distance(velocity: np.ndarray, limits: JointLimits) -> np.ndarray:
    """How far each joint travels braking from ``velocity`` (rad/s, at zero acceleration) to rest at its
    own acceleration and jerk limits, signed like the velocity (rad).

    Jerk ramps the deceleration up and down; the velocity falls point-symmetrically about the middle
    of the brake, so the distance is half the start speed times the brake's duration: ``v·√(v/j)``
    while the deceleration stays under its limit ``a`` (``v ≤ a²/j``), else ``v/2 · (a/j + v/a)``.
    """
    v = np.minimum(np.abs(np.asarray(velocity, dtype=float)), limits.velocity)
    a, j = limits.acceleration, limits.jerk
    short = v * np.sqrt(v / j)
    long = 0.5 * v * (a / j + v / np.where(a > 0, a, 1.0))
    return np.sign(velocity) * np.where(v <= a * a / j, short, long)


@dataclass(frozen=True)
class Step:
    """What one :meth:`Teleop.step` saw and did.

    Attributes:
        t: the follower's clock time, s. phase: ``"engaging"``, ``"following"`` or ``"holding"``.
        leader_q, leader_dq: the leader's measured positions (rad) and velocities (rad/s).
        follower_q, follower_dq, follower_tau: the follower's measured positions, velocities, torques (N·m).
        command: the leader's pose in the follower's joints, within its range (rad): what the follower is
            asked to be at (a dataset's ``action``).
        target: what was streamed to the follower: the command plus the stopping distance from the
            leader's velocity (at the follower's limits, or at ``engage_speed`` of them while engaging).
        feedback: the torque applied to the leader (N·m; zeros without force feedback).
        latency: s from the leader's newest feedback to the follower's command that uses it.
        outside: the follower joints the leader would take past their range (held at its edge).
        gripper_command: the width the follower's gripper is asked (m; None: the follower has none).
        gripper_width, gripper_velocity, gripper_force: its measured width (m), rate (m/s), squeeze (N).
        grasped: its jaws hold something.
    """

    t: float
    phase: str
    leader_q: np.ndarray
    leader_dq: np.ndarray
    follower_q: np.ndarray
    follower_dq: np.ndarray
    follower_tau: np.ndarray
    command: np.ndarray
    target: np.ndarray
    feedback: np.ndarray
    latency: float
    outside: tuple[str, ...]
    gripper_command: float | None = None
    gripper_width: float | None = None
    gripper_velocity: float | None = None
    gripper_force: float | None = None
    grasped: bool = False


@dataclass(frozen=True)
class Summary:
    """A session's figures: steps, steps spent following, latency percentiles (s), and per follower
    joint the largest and RMS distance of its measured position from the command while following (rad)."""

    steps: int
    following: int
    latency_p50: float
    latency_p99: float
    latency_max: float
    error_max: np.ndarray
    error_rms: np.ndarray
    joint_names: tuple[str, ...]

    def __str__(self) -> str:
        ms = 1e3
        text = (f"latency p50 {self.latency_p50 * ms:.1f} ms, p99 {self.latency_p99 * ms:.1f} ms, "
                f"max {self.latency_max * ms:.1f} ms over {self.steps} cycles")
        if self.following:
            text += "; follower - leader while following: " + ", ".join(
                f"{n} max {m * 1e3:.1f} mrad (RMS {r * 1e3:.1f})"
                for n, m, r in zip(self.joint_names, self.error_max, self.error_rms, strict=True))
        return text


class Teleop:
    """A leader :class:`~akarm.Arm` guiding a follower :class:`~akarm.Arm` (see the module's docstring).

    Args:
        leader, follower: two Arms, open and enabled (ACTIVE), on the same kind of clock.
        pairing: which joints pair (default: in order, :meth:`Pairing.in_order`).
        force_feedback: the gain from the follower's external torque to the leader's (0: none).
        force_limit: N·m, the largest feedback torque, one for all or one per leader joint
            (default: :data:`DEFAULT_FORCE_SHARE` of each leader joint's torque limit).
        engage_speed: the fraction of the follower's limits it engages at, in (0, 1].
        damping: the leader's teach-mode damping, N·m·s/rad (see :meth:`akarm.Arm.teach`).
        say: called with a line for the person at the arms (engaged, a range edge, a hold); default none.
        gripper_force: N, the squeeze the follower's gripper grasps with (default: the mapping file's,
            else its gripper's default force).

    Raises:
        ArgumentError: the same Arm twice, arms on different clocks, a bad gain, limit or speed; a
            gripper to drive that is missing, a gripper force past the follower gripper's force_limit.
    """

    @staticmethod
    def _force_limits(force_limit: float | Sequence[float], n: int) -> np.ndarray:
        """``force_limit`` as one limit per leader joint (``n``); ArgumentError unless one number or ``n``."""
        given = None
        if not isinstance(force_limit, str | bytes):
            with contextlib.suppress(TypeError, ValueError):
                given = np.asarray(force_limit, dtype=float)
        if given is None or given.ndim > 1 or (given.ndim == 1 and len(given) != n):
            raise ArgumentError(f"force limit {force_limit!r}: one force limit, or one per leader joint ({n}), "
                                "in N·m", fix="e.g. 1.5, or a list of one per leader joint")
        return np.broadcast_to(given, (n,)).copy()

    def __init__(self, leader: Arm, follower: Arm, pairing: Pairing | None = None, *, force_feedback: float = 0.0,
                 force_limit: float | Sequence[float] | None = None, engage_speed: float = 0.25,
                 damping: float = 0.1, say: Callable[[str], None] | None = None,
                 gripper_force: float | None = None) -> None:
        if leader is follower:
            raise ArgumentError("the leader and the follower are the same Arm", fix="give two arms")
        stepped = leader.clock.stepped
        if stepped != follower.clock.stepped or (stepped and leader.clock is not follower.clock):
            raise ArgumentError("the leader and the follower run on different clocks",
                                fix="in lock step give both arms one SteppedClock (SimulatedRobot(clock=...))")
        self.pairing = pairing if pairing is not None else Pairing.in_order(leader.names, follower.names)
        if self.pairing.leader_names != tuple(leader.names) or self.pairing.follower_names != tuple(follower.names):
            raise ArgumentError("the pairing was made for other arms' joints",
                                fix="build it from the leader's and the follower's joint names")
        if not (isinstance(force_feedback, int | float) and math.isfinite(force_feedback) and force_feedback >= 0):
            raise ArgumentError(f"force feedback gain {force_feedback!r} must be a number ≥ 0", fix="e.g. 0.5")
        if not (isinstance(engage_speed, int | float) and 0 < engage_speed <= 1):
            raise ArgumentError(f"engage_speed {engage_speed!r} must be in (0, 1]", fix="e.g. 0.25")
        torque = np.array([j.limits.torque for j in leader.config.joints], dtype=float)
        limit = DEFAULT_FORCE_SHARE * torque if force_limit is None else self._force_limits(force_limit, len(torque))
        if not np.all(np.isfinite(limit) & (limit >= 0)):
            raise ArgumentError(f"force limit {force_limit!r} must be ≥ 0 N·m, one or one per leader joint",
                                fix="e.g. 1.5")
        self.leader, self.follower = leader, follower
        self.gain = float(force_feedback)
        self.force_limit = np.minimum(limit, torque)
        self.engage_speed = float(engage_speed)
        self.damping = damping
        self.say = say or (lambda line: None)
        self.period = 1.0 / follower.config.rate_hz
        lim = follower.limits
        self._lower, self._upper = lim.lower, lim.upper
        self._engage_limits = lim.scaled(self.engage_speed)
        self._phase = "idle"
        self._held = np.zeros(follower.n)
        self._outside: tuple[str, ...] = ()
        self._collision: CollisionError | None = None
        self._resume_since: float | None = None
        self._reaction: str | None = None
        self.latency: collections.deque[float] = collections.deque(maxlen=LATENCY_SAMPLES)
        self.steps = 0
        self.kept = 0  # retargets refused (a path past the range): the plan in force went on
        self._following = 0
        self._err_max = np.zeros(follower.n)
        self._err_sq = np.zeros(follower.n)
        self.last: Step | None = None
        self._init_gripper(gripper_force)

    def _init_gripper(self, gripper_force: float | None) -> None:
        """What drives the follower's gripper (``_grip_source``: "trigger", "gripper" or None) and with
        what force; ArgumentError when the mapping file asks for a gripper that is missing, or a force
        past the follower gripper's limit."""
        self._leader_gripper: Gripper | None = self.leader.gripper
        self._follower_gripper: Gripper | None = self.follower.gripper
        self._grip_sent: float | None = None
        self._grip_width: float | None = None
        gp = self.pairing.gripper
        fg = self._follower_gripper
        self._grip_source = None if fg is None else (
            "trigger" if gp is not None and gp.trigger is not None else
            ("gripper" if self._leader_gripper is not None else None))
        if gp is not None and fg is None:
            raise ArgumentError("the mapping file's gripper: drives the follower's gripper, but the follower has none",
                                fix="add a gripper: to the follower's robot file, or leave gripper: out of the map")
        if gp is not None and gp.trigger is None and self._leader_gripper is None:
            raise ArgumentError("the mapping file's gripper: names no trigger, and the leader has no gripper",
                                fix="name a leader joint as the trigger: "
                                    "gripper: {trigger: JOINT, closed: 0, open: 0.6}")
        force = gripper_force if gripper_force is not None else (gp.force if gp is not None else None)
        if force is not None and fg is not None and not (math.isfinite(force) and 0.0 <= force <= fg.force_limit):
            raise ArgumentError(f"gripper force {force!r} N is outside the follower gripper's 0..{fg.force_limit:g} N",
                                joint=fg.name, fix=f"ask at most its force_limit, {fg.force_limit:g} N")
        self.gripper_force = force

    # ------------------------------------------------------------------------------------------
    @property
    def phase(self) -> str:
        """``"idle"`` (not started), ``"engaging"``, ``"following"``, ``"holding"``, ``"stopped"`` or ``"finished"``."""
        return self._phase

    def start(self) -> Teleop:
        """Put the leader in teach mode, arm the follower's reflex to hold (with force feedback), and
        start engaging (the next steps move the follower to the leader at ``engage_speed``).

        Raises:
            StateError: an arm is not enabled (ACTIVE).
        """
        for name, arm in (("leader", self.leader), ("follower", self.follower)):
            if arm.mode is not Mode.ACTIVE:
                raise StateError(f"the {name} is {arm.mode}, not enabled", fix="enable both arms first")
        self._free_leader_gripper()
        self.leader.teach(self.damping)
        if self.gain > 0:
            self._reaction = self.follower.collision_reaction
            self.follower.set_collision(reaction="hold")
        self._held = self.follower.state().q_des.copy()
        self._collision = self.follower.last_collision
        self._engage("engaging: the follower moves to the leader's pose at "
                     f"{self.engage_speed * 100:.0f} % of its speed")
        return self

    def _free_leader_gripper(self) -> None:
        """A leader gripper that drives the follower's is let go (asked no force: no stiffness, no
        damping), so the hand opens and closes it freely; :meth:`finish` has it hold again."""
        lg = self._leader_gripper
        if self._grip_source == "gripper" and lg is not None:
            w = float(lg.state().width)
            lg.move_to(min(max(w, 0.0), lg.stroke) if math.isfinite(w) else lg.stroke, 0.0, wait=False)

    def _engage(self, line: str) -> None:
        self._phase = "engaging"
        self.say(line)

    def pause(self) -> None:
        """No feedback torque until the next step, which engages again at ``engage_speed`` (the caller
        leaves the arms alone for a while: saving an episode)."""
        if self._phase in ("following", "engaging"):
            self.leader.set_extra_torque(None)
            self._phase = "engaging"

    # ------------------------------------------------------------------------------------------
    def step(self) -> Step:
        """One follower cycle: wait for it, read both arms, stream the follower's target, apply the
        feedback torque to the leader.

        Raises:
            SafetyStop: either arm stopped for safety; both are damped and disabled.
            StateError: the session is not running, or the leader left teach mode (both are stopped).
        """
        if self._phase not in ("engaging", "following", "holding"):
            raise StateError(f"the session is {self._phase}", fix="call start() first (or use `with Teleop(...)`)")
        leader, follower = self.leader, self.follower
        try:
            follower.sleep(0.5 * self.period)  # until its next cycle: one, however late this call came
        except SafetyStop as e:
            self.stop_both()
            raise e from None
        if leader.fault is not None or leader.mode is not Mode.TEACH:
            cause: AkarmError = leader.fault or StateError(
                f"the leader left teach mode ({leader.mode})", fix="one program drives both arms during teleoperation")
            self.stop_both()
            raise cause
        ls, fs = leader.state(), follower.state()
        if follower.last_collision is not self._collision:  # its reflex stopped it and holds
            self._collision = follower.last_collision
            self._phase = "holding"
            self._resume_since = None
            self._held = fs.q_des.copy()
            self.say(f"the follower touched something ({self._collision}); it holds: bring the leader back "
                     "to it to go on")
        wanted = self.pairing.follower_positions(ls.q, self._held)
        command = np.clip(wanted, self._lower, self._upper)
        self._report_range(wanted)
        target = command
        velocity = self.pairing.follower_velocities(ls.dq)
        if self._phase == "holding":
            self._resume(fs.time, command, velocity, fs.q_des)
        if self._phase != "holding":
            speed = self.engage_speed if self._phase == "engaging" else 1.0
            limits = follower.limits if speed == 1.0 else self._engage_limits
            target = np.clip(command + stopping_distance(velocity, limits), self._lower, self._upper)
            try:
                follower.stream_to(target, speed, synchronize=False)
            except LimitError:  # the plan in force (within the range) goes on; the next cycle tries again
                self.kept += 1
            except SafetyStop as e:
                self.stop_both()
                raise e from None
        if self._phase == "engaging" and np.max(np.abs(fs.q_des - command)) < ENGAGE_TOLERANCE and \
                np.max(np.abs(fs.dq - velocity)) < ENGAGE_SPEED_TOLERANCE:
            self._phase = "following"
            self.say("engaged: the follower follows the leader")
        try:
            grip = self._grip(ls)
        except SafetyStop as e:
            self.stop_both()
            raise e from None
        feedback = self._feedback(fs.tau_ext, grip)
        latency = self._latency(ls)
        self._account(fs.q, command)
        self.last = Step(fs.time, self._phase, ls.q, ls.dq, fs.q, fs.dq, fs.tau, command, target, feedback, latency,
                         self._outside, *grip)
        return self.last

    def _grip(self, ls: ArmState) -> tuple[float | None, float | None, float | None, float | None, bool]:
        """Drive the follower's gripper from the leader's, or its trigger: (width asked, width, rate,
        squeeze, grasped) of the follower's gripper, all None without one."""
        fg = self._follower_gripper
        if fg is None:
            return None, None, None, None, False
        fraction = None
        gp = self.pairing.gripper
        if self._grip_source == "trigger" and gp is not None and gp.trigger is not None:
            fraction = gp.fraction(float(ls.q[gp.trigger]))
        elif self._grip_source == "gripper" and self._leader_gripper is not None:
            lw = float(self._leader_gripper.state().width)
            fraction = min(max(lw / self._leader_gripper.stroke, 0.0), 1.0) if math.isfinite(lw) else None
        s = fg.state()
        if fraction is not None:
            width = fraction * fg.stroke
            # stopped on something (holding it, or about to): a width further in changes nothing (it
            # presses at the force asked), so it is not asked, and the grasp holds; one past the
            # object's opens the jaws
            stopped = s.grasped or (self._grip_sent is not None and s.width - self._grip_sent > GRIPPER_SHORT
                                    and abs(s.velocity) < GRIPPER_STILL)
            squeezing = stopped and width < s.width
            if not squeezing and (self._grip_sent is None or abs(width - self._grip_sent) > GRIPPER_DEADBAND):
                fg.move_to(min(width, fg.stroke), self.gripper_force, wait=False)
                self._grip_sent = width
            self._grip_width = width
        if self._grip_width is None:  # not driven: what it holds at is asked
            self._grip_width = min(max(float(s.target), 0.0), fg.stroke)
        return self._grip_width, float(s.width), float(s.velocity), float(s.force), bool(s.grasped)

    def _resume(self, now: float, command: np.ndarray, velocity: np.ndarray, held: np.ndarray) -> None:
        """Engage again once the hand has held the leader at the follower for :data:`RESUME_DWELL` s."""
        paired = self.pairing.follower_index
        if np.max(np.abs(command[paired] - held[paired])) >= RESUME_TOLERANCE or \
                np.max(np.abs(velocity[paired])) >= ENGAGE_SPEED_TOLERANCE:
            self._resume_since = None
        elif self._resume_since is None:
            self._resume_since = now
        elif now - self._resume_since >= RESUME_DWELL:
            self._resume_since = None
            self._engage("the leader is back at the follower: engaging again")

    def _report_range(self, wanted: np.ndarray) -> None:
        names = self.follower.names
        out = tuple(names[i] for i in np.flatnonzero((wanted < self._lower) | (wanted > self._upper)))
        for name in out:
            if name not in self._outside:
                i = names.index(name)
                edge = self._lower[i] if wanted[i] < self._lower[i] else self._upper[i]
                self.say(f"the leader would take the follower's {name} to {wanted[i]:+.3f} rad, outside its range: "
                         f"it waits at {edge:+.3f} rad")
        if self._outside and not out:
            self.say("the leader is back within the follower's range")
        self._outside = out

    def _feedback(self, tau_ext: np.ndarray | None, grip: tuple[float | None, ...] | None = None) -> np.ndarray:
        if self.gain <= 0.0 or tau_ext is None:
            return np.zeros(self.leader.n)
        tau = self.pairing.leader_torques(np.nan_to_num(tau_ext)) * self.gain
        gp, fg = self.pairing.gripper, self._follower_gripper
        if grip is not None and grip[4] and gp is not None and gp.trigger is not None and fg is not None:
            force = grip[3] if grip[3] is not None and math.isfinite(grip[3]) else 0.0
            span = gp.open - gp.closed  # the squeeze's work over the jaws' stroke, done on the trigger's span
            tau[gp.trigger] += self.gain * max(force, 0.0) * fg.stroke / abs(span) * math.copysign(1.0, span)
        tau = np.clip(tau, -self.force_limit, self.force_limit)
        if self._phase == "holding":
            tau = np.zeros_like(tau)  # the follower rests against what it touched: no push on the hand
        self.leader.set_extra_torque(tau.tolist())
        return tau

    def _latency(self, ls: ArmState) -> float:
        """From the leader's feedback (its oldest joint's) to the follower's next command (its next cycle)."""
        fed = ls.time - max((j.age for j in ls.joints), default=0.0)
        last = self.follower.observe.loop.stats.last_start
        command = (last if last is not None else self.follower.clock.now()) + self.period
        latency = max(0.0, command - fed)
        self.latency.append(latency)
        return latency

    def _account(self, q: np.ndarray, command: np.ndarray) -> None:
        self.steps += 1
        if self._phase == "following":
            e = np.abs(q - command)
            self._following += 1
            self._err_max = np.maximum(self._err_max, e)
            self._err_sq += e * e

    def summary(self) -> Summary:
        """The latency percentiles and the tracking error so far (see :class:`Summary`)."""
        lat = np.array(self.latency) if self.latency else np.zeros(1)
        n = max(self._following, 1)
        return Summary(self.steps, self._following, float(np.percentile(lat, 50)), float(np.percentile(lat, 99)),
                       float(lat.max()), self._err_max.copy(), np.sqrt(self._err_sq / n), tuple(self.follower.names))

    # ------------------------------------------------------------------------------------------
    def stop_both(self) -> None:
        """Damp and disable both arms (a safety stop of one stops the other). Never raises."""
        self._phase = "stopped"
        for arm in (self.leader, self.follower):
            with contextlib.suppress(AkarmError):
                arm.disable(wait=False)
        for arm in (self.leader, self.follower):
            with contextlib.suppress(AkarmError):
                arm.disable()

    def finish(self) -> None:
        """End the session gently: no feedback torque, the follower comes to rest (jerk-limited) and the
        leader holds where the hand left it; the follower's collision reaction is as it was. Both stay
        enabled (the caller disables them). Never raises."""
        if self._phase in ("stopped", "finished", "idle"):
            return
        self._phase = "finished"
        leader, follower = self.leader, self.follower
        with contextlib.suppress(AkarmError):
            leader.set_extra_torque(None)
        with contextlib.suppress(AkarmError):
            if follower.enabled:
                follower.stop(wait=True)
        with contextlib.suppress(AkarmError):
            if self._reaction is not None:
                follower.set_collision(reaction=self._reaction)
        with contextlib.suppress(AkarmError):
            if leader.mode is Mode.TEACH:
                leader.end_teach()
        lg = self._leader_gripper
        with contextlib.suppress(AkarmError):
            if self._grip_source == "gripper" and lg is not None and leader.enabled:  # it holds where it was left
                w = float(lg.state().width)
                if math.isfinite(w):
                    lg.move_to(min(max(w, 0.0), lg.stroke), None, wait=False)

    def __enter__(self) -> Teleop:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        if exc_type is None or issubclass(exc_type, KeyboardInterrupt | SafetyStop):
            self.finish()  # (after a safety stop both are disabled already: nothing to do)
        else:
            self.stop_both()
