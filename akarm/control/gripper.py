"""The gripper: its motor driven every cycle like a joint's, and the force-limited grasp.

Two halves, as the arm's controller and :class:`~akarm.Arm` are:

- :class:`GripperDrive` is the loop's side. The controller owns it, supervises its motor (a
  :class:`~akarm.control.joints.Joint` after the arm's, in the same :class:`~akarm.control.safety.Supervisor`,
  enabler and bus set) and asks it for one frame a cycle (:meth:`GripperDrive.frame`).
- :class:`Gripper` is the caller's (``arm.gripper``): it checks what it is asked, hands it to the
  drive under the controller's lock, and waits in the controller's way (lock step included).

The MIT law, chosen every cycle from the last feedback (angles past closed; ``τF`` the closing torque of
the force asked at the present angle, ``force · dwidth/dangle``):

- **approach** (further than ``band = τF / kp`` from the target): no stiffness, the velocity toward
  the target through the damping gain ``kd = τF / speed``: the jaws go at about ``speed`` when
  free, and pressing on anything at rest the motor gives exactly ``τF``, never more;
- **settle** (within the band): the position target with the configured kp and kd, whose torque at
  rest, ``kp · error``, is at most ``τF`` too;
- **grasp**: stopped short of the target (slower than :data:`STALL_SPEED` for :data:`STALL_TIME`,
  more than :data:`SHORT_OF` from it), the jaws hold the object at the asked force and no longer at a
  position: no stiffness, damping, ``τF`` toward the target. After :data:`RELAX_AFTER` s of holding,
  the torque goes down to :data:`HOLD_FRACTION` of it over :data:`RELAX_TIME` s: what holding needs,
  less heat in the motor. An object that slips or goes (the jaws move on towards the target by more
  than :data:`SLIP`) ends the grasp: the jaws approach the target again.

A servo-mode motor (``mode: servo``) gets the same moves, stall, grasp and relaxation through
:meth:`GripperDrive.servo_frame`: only currents, each clamped to ``τF``, the law worked out here from
the last status frame (the firmware's position loop would push with whatever current it takes).

So the squeeze is the asked force at rest, at most ``force_limit`` (the torque is clamped to its
value at every angle), and the stall on an object is a grasp, never a fault: the gripper's guard has
no following-error or stuck check (silence, motor errors, implausible readings and temperature are
supervised as a joint's). A stop (``disable()``, a safety stop) damps the arm while the gripper goes
on holding what it holds; the exit frames then leave its motor limp: nothing is opened.
"""

from __future__ import annotations

import math
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from akarm.buses.frames import Frame
from akarm.control.joints import ServoJoint
from akarm.errors import StateError

if TYPE_CHECKING:
    from akarm.config import GripperConfig
    from akarm.control.joints import Joint
    from akarm.control.safety import Guard

__all__ = ["HOLD_FRACTION", "RELAX_AFTER", "RELAX_TIME", "SERVO_BRAKING", "SHORT_OF", "SLIP", "STALL_SPEED",
           "STALL_TIME", "Gripper", "GripperDrive", "GripperLog", "GripperState", "Host"]

#: rad/s: slower than this the jaws are at rest
STALL_SPEED = 0.05
#: s at rest short of the target that make a grasp
STALL_TIME = 0.04
#: m: at rest further than this from the target is "short of it" (a grasp); nearer, the target is reached
SHORT_OF = 0.0015
#: m: this near the target (and slow), a move has ended
REACHED = 0.0002
#: m the jaws may move on toward the target while holding before the object counts as lost
SLIP = 0.003
#: s of holding before the torque goes down to what holding needs
RELAX_AFTER = 1.0
#: s over which it goes down
RELAX_TIME = 0.5
#: rad/s²: how fast the servo law's velocity toward the target brakes near it
SERVO_BRAKING = 25.0
#: what a long hold keeps of the asked force (the asked force, less 15 %: within the 20 % a grasp allows)
HOLD_FRACTION = 0.85


@dataclass(frozen=True)
class GripperLog:
    """The gripper's per-cycle record (arrays, oldest first; SI): clock time (s), width (m), velocity
    (m/s), squeeze estimate (N), target width (m)."""

    t: np.ndarray
    width: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    target: np.ndarray


@dataclass(frozen=True)
class GripperState:
    """The gripper now (SI units).

    Attributes:
        width: m between the jaws. velocity: m/s (opening is positive).
        force: N, the squeeze estimated from the motor's torque and the transmission (0 while opening).
        grasped: it stopped short of the target on something and presses on it.
        target: m, the width asked last.
        moving: a move is under way (not yet at its target, nor grasping).
        temperature: °C, the motor's (``nan`` before its first reply).
    """

    width: float
    velocity: float
    force: float
    grasped: bool
    target: float
    moving: bool
    temperature: float


class GripperDrive:
    """The gripper's loop side (see the module's docstring): its joint, its target, its law.

    Args:
        config: the gripper.
        joint: its motor, a joint of the controller's bus set and supervisor (index after the arm's).
        period: the loop's period, s.
    """

    def __init__(self, config: GripperConfig, joint: Joint, period: float) -> None:
        self.config = config
        self.joint = joint
        self.period = period
        c = config
        self._kp, self._kd = c.kp, c.kd
        self.speed = c.speed / c.max_slope  # rad/s toward the target
        self._short = SHORT_OF / c.max_slope
        self._reached = REACHED / c.max_slope
        # N·m: the motor's Coulomb friction, made up for near the target (else it stops short by coulomb / kp)
        friction = joint.config.friction_model()
        self._coulomb = friction.coulomb
        self._viscous = friction.viscous
        self._slip = SLIP / c.max_slope
        self._t_max = joint.motor.t_max * 0.999
        self.target = c.open_angle  # rad
        self.force = c.default_force  # N
        self.active = False  # a target is in force (after enable); else the motor is held limp
        self.moving = False
        self.grasped = False
        self._still = 0.0  # s at rest short of the target
        self._slowed = 0.0  # s (servo) slower than half the speed since last free
        self._hold_from = 0.0  # s of plan time the grasp began
        self._held_at = 0.0  # rad where the grasp began
        self.servo = c.mode == "servo"
        if self.servo:  # the servo law's numbers (see servo_frame)
            jc = joint.config
            inertia = c.motor.reflected_inertia + 0.1 * c.max_slope ** 2  # (the jaws' mass, about 0.1 kg)
            # the feedback is a status frame up to a period old: the damping stays stable over that delay
            delay = 1.0 / jc.status_rate_hz + period
            self._kd_servo = inertia / (2.0 * delay)
        self.mode = "idle"  # idle | approach | settle | grasp: the law of the last command
        self.sequence = 0  # moves asked: a waiter knows its own move ended
        # the per-cycle record: a ring of (t, angle, velocity, torque, target angle), preallocated
        self._ring = np.zeros((1, 5))
        self._rows = 0

    def keep(self, cycles: int) -> None:
        """Keep the last ``cycles`` cycles of the per-cycle record (the arm's telemetry's length)."""
        self._ring = np.zeros((max(1, cycles), 5))
        self._rows = 0

    def record(self, now: float) -> None:
        """(Loop) This cycle in the per-cycle record: the feedback the command was made from."""
        s = self.joint.state
        row = self._ring[self._rows % len(self._ring)]
        row[0], row[1], row[2], row[3], row[4] = now, s.position, s.velocity, s.torque, self.target
        self._rows += 1

    def log(self, since: float | None = None) -> GripperLog:
        """(Caller, under the lock) The per-cycle record since ``since`` (clock time, s)."""
        n = len(self._ring)
        rows = self._ring[:self._rows] if self._rows <= n else np.roll(self._ring, -(self._rows % n), axis=0)
        if since is not None:
            rows = rows[rows[:, 0] >= since]
        c = self.config
        q = rows[:, 1]
        width = np.array([c.width_at(x) for x in q.tolist()])
        slope = np.array([c.slope_at(x) for x in q.tolist()])
        return GripperLog(rows[:, 0].copy(), width, rows[:, 2] * slope, np.maximum(0.0, -rows[:, 3]) / slope,
                          np.array([c.width_at(x) for x in rows[:, 4].tolist()]))

    def guard(self, timeout: float) -> Guard:
        """The gripper's safety limits: silence and temperature as a joint's; no following-error or stuck
        check (a stall on an object is a grasp, never a fault)."""
        from akarm.control.safety import Guard

        return Guard(timeout, self.config.max_temperature)

    # ------------------------------------------------------------------ caller side (under the lock)
    def hold_here(self) -> None:
        """(Enable) Hold where the jaws are, as a move that has ended."""
        s = self.joint.state
        q = s.position if math.isfinite(s.position) else self.target
        self.target = min(max(q, 0.0), self.config.open_angle)
        self.active = True
        self.moving = False
        self.grasped = False
        self.mode = "settle"

    def move(self, angle: float, force: float) -> int:
        """A new target (rad) and force (N); returns the move's number."""
        self.target = angle
        self.force = force
        self.moving = True
        self.grasped = False
        self._still = 0.0
        self._slowed = 0.0
        self.sequence += 1
        return self.sequence

    def rezero_here(self) -> float:
        """(Calibration, at closed) Take the present reading as closed from now on; the reading it was (rad)."""
        j = self.joint
        found = j.state.position
        j.offset -= found
        j.state.position -= found
        self.hold_here()
        return found

    def stop_moving(self) -> None:
        """(A stop) No move is under way any more (the jaws keep holding until the motor is limp)."""
        self.moving = False
        self.active = False

    # ------------------------------------------------------------------ loop side
    def command(self, t: float) -> tuple[float, float, float, float, float]:
        """This cycle's MIT command (position, velocity, kp, kd, torque), joint side; ``t`` plan time, s."""
        c = self.config
        s = self.joint.state
        q, v = s.position, s.velocity
        if not self.active or not math.isfinite(q):
            return (0.0, 0.0, 0.0, 0.0, 0.0)
        target = self.target
        err = target - q
        toward = 1.0 if err > 0.0 else -1.0
        tau_f = min(self.force * c.slope_at(q), c.torque_limit, self._t_max)
        if self.grasped and self._holds(q, toward):
            return (q, 0.0, 0.0, self._kd, toward * self._relaxed(t, tau_f))
        if self.moving and self._stalled(t, q, v, err):  # stopped short: hold it at the force asked
            return (q, 0.0, 0.0, self._kd, toward * tau_f)
        coulomb = min(self._coulomb, 0.5 * tau_f)
        band = (tau_f - coulomb) / self._kp if self._kp > 0.0 else 0.0
        if abs(err) > band:
            self.mode = "approach"
            kd = min(tau_f / self.speed, self.joint.motor.kd_max)
            return (q, toward * self.speed, 0.0, kd, 0.0)
        self.mode = "settle"
        # the friction made up for, fading out at the target: kp · band + coulomb is τF at most
        return (target, 0.0, self._kp, self._kd, coulomb * max(-1.0, min(1.0, err / self._reached)))

    def frame(self, t: float) -> Frame:
        """This cycle's frame (its fields): the MIT law's :meth:`command`, or the servo law's."""
        if self.servo:
            return self.servo_frame(t)
        return self.joint.track_frame(*self.command(t))

    def servo_frame(self, t: float) -> Frame:
        """This cycle's servo-mode frame; ``t`` plan time, s. Always a current (SET_CURRENT) whose torque
        is clamped to ``τF``, worked out here from the last status frame: the firmware's position loop
        is never used, as it pushes with whatever current it takes until the stall is seen (see
        docs/gripper.md). The same moves, grasp and relaxation as the MIT law's; its own law:

        - **approach** and **settle**: a velocity toward the target, the speed the MIT law's damping
          reaches against the motor's friction (``speed`` less for a low force) far from it, braking
          at :data:`SERVO_BRAKING` near it, through damping ``kd`` (at most what stays stable on
          feedback a status period old, ``J / 2·delay``), plus the motor's friction (``τc``, fading
          out within :data:`REACHED` of the target, and ``b·v``). Held back short of the target
          (slower than half that velocity), the torque goes up to ``τF`` over :data:`STALL_TIME`, as
          pressing at rest under the MIT law does;
        - **grasp**: ``τF`` toward the target, damped.
        """
        c = self.config
        j = self.joint
        assert isinstance(j, ServoJoint)
        s = j.state
        q, v = s.position, s.velocity
        if not self.active or not math.isfinite(q):
            return j.current_frame(0.0)  # zero current: limp
        err = self.target - q
        toward = 1.0 if err > 0.0 else -1.0
        tau_f = min(self.force * c.slope_at(q), c.torque_limit, self._t_max)
        kd = min(self._kd, self._kd_servo)
        if self.grasped and self._holds(q, toward):
            return j.current_frame(max(-tau_f, min(tau_f, toward * self._relaxed(t, tau_f) - kd * v)))
        if self.moving and self._stalled(t, q, v, err):
            return j.current_frame(toward * tau_f)
        far = abs(err) > self._short
        self.mode = "approach" if far else "settle"
        # the speed the MIT law's damping reaches against the friction (slower at a low force: a softer impact)
        free = self.speed * max(0.1, (tau_f - self._coulomb) / (tau_f + self._viscous * self.speed))
        vd = toward * min(free, math.sqrt(2.0 * SERVO_BRAKING * abs(err)))
        kd = min(tau_f / self.speed, kd)
        tau = (kd * (vd - v) + self._viscous * vd
               + min(self._coulomb, 0.5 * tau_f) * max(-1.0, min(1.0, err / self._reached)))
        if not (self.moving and far) or abs(v) >= 0.9 * abs(vd):  # free again (a margin: no chatter)
            self._slowed = 0.0
        elif abs(v) < 0.5 * abs(vd):
            self._slowed += self.period
        if self._slowed > 0.0:  # held back: up to τF over the stall time, as a grasp will press
            tau += (toward * tau_f - tau) * min(1.0, self._slowed / STALL_TIME)
        return j.current_frame(max(-tau_f, min(tau_f, tau)))

    def _stalled(self, t: float, q: float, v: float, err: float) -> bool:
        """(A move) The stall check of this cycle: whether a grasp began (else the move may have ended)."""
        if abs(v) >= STALL_SPEED:
            self._still = 0.0
        elif abs(err) <= self._reached:
            self.moving = False  # at the target
        else:
            self._still += self.period
            if self._still >= STALL_TIME:
                self.moving = False
                if abs(err) > self._short:  # stopped short on something: hold it at the force asked
                    self._grasp(t, q)
                    return True
        return False

    def _grasp(self, t: float, q: float) -> None:
        """A grasp begins at plan time ``t`` and angle ``q``."""
        self.grasped = True
        self._hold_from = t
        self._held_at = q
        self.mode = "grasp"
        self.moving = False
        self._still = 0.0

    def _holds(self, q: float, toward: float) -> bool:
        """Whether the grasp still holds at ``q`` (rad; ``toward``: the sign of the way to the target):
        jaws that slipped or went past the slip allowance start a new approach."""
        if toward * (q - self._held_at) > self._slip:
            self.grasped = False
            self.moving = True
            self._still = 0.0
            return False
        self.mode = "grasp"
        return True

    def _relaxed(self, t: float, tau_f: float) -> float:
        """``τF`` after the grasp's relaxation (:data:`RELAX_AFTER`, :data:`RELAX_TIME`, :data:`HOLD_FRACTION`)."""
        held = t - self._hold_from
        if held > RELAX_AFTER:
            tau_f *= 1.0 - (1.0 - HOLD_FRACTION) * min(1.0, (held - RELAX_AFTER) / RELAX_TIME)
        return tau_f

    def state(self) -> GripperState:
        c = self.config
        s = self.joint.state
        q = s.position
        if not math.isfinite(q):
            return GripperState(math.nan, math.nan, math.nan, False, c.width_at(self.target), self.moving, math.nan)
        slope = c.slope_at(q)
        squeeze = max(0.0, -s.torque) / slope  # closing torque (toward 0) squeezes
        temp = s.temperature if s.temperature is not None else math.nan
        return GripperState(c.width_at(q), s.velocity * slope, squeeze, self.grasped, c.width_at(self.target),
                            self.moving, float(temp))


class Host(Protocol):
    """What :class:`Gripper` needs of the controller (:class:`~akarm.control.controller.Controller`)."""

    @property
    def lock(self) -> threading.RLock: ...

    def require_enabled(self) -> None: ...

    def wait_for(self, done: Callable[[], object], timeout: float, what: str) -> None: ...


class Gripper:
    """``arm.gripper``: open, close and move the jaws, force-limited (see :mod:`akarm.control.gripper`).

    Every call checks its arguments first (a width outside 0..stroke, a negative, NaN or too large
    force: :class:`~akarm.ArgumentError`, nothing moves), then needs the arm enabled.
    """

    def __init__(self, controller: Host, drive: GripperDrive) -> None:
        self._ctl = controller
        self._drive = drive
        self._config = drive.config
        self._wait_lock = threading.Lock()

    @property
    def name(self) -> str:
        return self._config.name

    @property
    def stroke(self) -> float:
        """m between the jaws fully open."""
        return self._config.stroke

    @property
    def force_limit(self) -> float:
        """N, the most the jaws ever squeeze."""
        return self._config.force_limit

    @property
    def config(self) -> GripperConfig:
        return self._config

    def state(self) -> GripperState:
        """Width, velocity, squeeze, grasped, target, moving, temperature, as of the last reply."""
        with self._ctl.lock:
            return self._drive.state()

    def telemetry(self, since: float | None = None) -> GripperLog:
        """The per-cycle record (as long as the arm's telemetry) since ``since`` (clock time, s):
        width, velocity, squeeze estimate and target width, beside ``arm.telemetry()``."""
        with self._ctl.lock:
            return self._drive.log(since)

    def open(self, wait: bool = True) -> GripperState:
        """Open fully (at the default force)."""
        return self.move_to(self._config.stroke, None, wait)

    def close(self, force: float | None = None, wait: bool = True) -> GripperState:
        """Close: on an object, hold it at ``force`` N (``None``: half the limit); on nothing, end closed."""
        return self.move_to(0.0, force, wait)

    def move_to(self, width: float, force: float | None = None, wait: bool = True) -> GripperState:
        """Move the jaws ``width`` m apart, pressing with at most ``force`` N (``None``: half the limit)
        on what is in the way; what stops them short is grasped and held at that force.

        Raises:
            ArgumentError: width outside 0..stroke; force negative, not a number or over force_limit.
            StateError: the arm is not enabled. A safety stop meanwhile (``wait``): that stop.
        """
        c = self._config
        w = c.check_width(width)
        f = c.check_force(force)
        ctl = self._ctl
        ctl.require_enabled()
        with ctl.lock:
            if not self._drive.active:
                raise StateError("the gripper is not enabled", joint=c.name, fix="call arm.enable() first")
            ticket = self._drive.move(c.angle_at(w), f)
        if wait:
            self.wait(ticket)
        return self.state()

    def wait(self, ticket: int | None = None, timeout: float | None = None) -> GripperState:
        """Wait until the move in force (or move ``ticket``) reached its target or grasped."""
        d = self._drive
        c = self._config
        if timeout is None:
            timeout = 2.0 * c.stroke / c.speed + 2.0
        self._ctl.wait_for(lambda: (ticket is not None and d.sequence != ticket) or not d.moving, timeout,
                           f"the gripper {c.name!r} to reach its target")
        return self.state()

    def calibrate(self, force: float | None = None) -> float:
        """Find closed: close slowly at low force (``force`` N, default a tenth of the limit) until the jaws
        stop, and take that as closed (width 0) from now on, as ``akarm zero`` does for a joint. Returns
        the offset found (rad: the angle the motor read there, past the closed it assumed). Put it in the
        robot file as the gripper's ``offset:`` to keep it.

        Nothing may be between the jaws.
        """
        c = self._config
        f = c.check_force(force if force is not None else 0.1 * c.force_limit)
        ctl = self._ctl
        ctl.require_enabled()
        with ctl.lock:
            d = self._drive
            ticket = d.move(-c.open_angle, f)  # past closed: the jaws stop on their end stop
        try:
            ctl.wait_for(lambda: d.sequence != ticket or d.grasped, 4.0 * c.open_angle / d.speed + 2.0,
                         f"the gripper {c.name!r} to close on its end stop")
        except StateError:
            with ctl.lock:
                d.move(d.joint.state.position, f)
            raise
        with ctl.lock:
            found = d.rezero_here()
        if abs(found) > 0.05 * c.open_angle:
            warnings.warn(f"gripper {c.name!r}: closed is {found:+.3f} rad from where the robot file puts it; "
                          f"set `offset: {c.offset - found:.4f}` under gripper: to keep it", stacklevel=2)
        return found
