"""Servoing: the tool steered live by a twist or a moving target pose (``with arm.servo() as s:``).

:class:`ServoStream` is a live plan: the control loop samples it every cycle like any other
(:class:`~akarm.motion.trajectory.Timed`), and each sample is one step of the Cartesian command in
force, turned into joint motion:

1. the command: a twist ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s of the tool frame's origin, base or
   tool axes) moves a *goal* pose on; a pose command is the goal itself. The Cartesian velocity asked
   for is the twist plus :data:`FEEDBACK_GAIN` times the error between the goal and where the
   command is (the goal leads by at most :data:`GOAL_LEAD`), so a twist held for a second travels
   its distance with no drift from linearisation;
2. joint velocities by damped least squares on the tool Jacobian (rotations weighted
   :data:`~akarm.dynamics.ik.ROTATION_WEIGHT` m/rad, damping :data:`DAMPING`);
3. scaled down, as one vector (the tool keeps its direction), by whatever is near: each joint's
   velocity limit; a singularity approached (the joint speed the command needs per unit of tool speed
   growing toward :data:`STRETCH_STOP`: no faster than the joints can brake before it; a singularity
   in the command's direction, that is: one across it, a wrist's at ``ready``, leaves it alone); a
   joint's range less :data:`RANGE_MARGIN` (braking distance at half its acceleration limit); a wall
   of the robot file's ``workspace:`` (braking at :data:`WALL_DECELERATION`, :data:`WALL_STOP` short of it);
4. each joint follows that velocity jerk-limited (its acceleration and jerk limits).

Commands that stop coming for ``timeout`` s bring the arm to rest, jerk-limited, and hold it there; the
next command resumes from rest. :attr:`ServoStream.status` says ``ok``, ``slowing`` or ``stopped`` and why.
:class:`Servo` is the caller's handle (``arm.servo()``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import pinocchio as pin
import ruckig

from akarm.config.workspace import Workspace
from akarm.dynamics.ik import ROTATION_WEIGHT, as_pose
from akarm.dynamics.model import RobotModel
from akarm.dynamics.selfcollision import SelfCollision
from akarm.errors import ArgumentError, StateError
from akarm.motion.trajectory import JointLimits, State, Timed

__all__ = [
    "COLLISION_LOOK_AHEAD",
    "DAMPING",
    "FEEDBACK_GAIN",
    "GOAL_LEAD",
    "LOOK_STEP",
    "RANGE_MARGIN",
    "STRETCH_LOOK",
    "STRETCH_STOP",
    "WALL_DECELERATION",
    "WALL_STOP",
    "Servo",
    "ServoStatus",
    "ServoStream",
]

#: 1/s: how fast the command closes on the goal pose (a twist's goal leads it by a few mm)
FEEDBACK_GAIN = 20.0
#: 1/s: how fast a pose command closes on its pose (lower: the joints' own lag would make it overshoot)
POSE_GAIN = 8.0
#: m and rad: the most the goal may lead the command (a slowed or stopped arm does not wind it up)
GOAL_LEAD = (0.005, 0.05)
#: the damped least squares' damping (m, weighted; rotations as ROTATION_WEIGHT m/rad)
DAMPING = 0.005
#: rad/m: the joint speed a command needs per (weighted) tool speed (its *stretch*) above which servoing
#: looks for a singularity ahead, and the one at which it stops there (arm6 going out at ``ready``'s
#: height: 4 at ``ready``, 10 with the elbow 0.5 rad from straight, 45 at 0.1 rad)
STRETCH_LOOK = 8.0
STRETCH_STOP = 45.0
#: rad of joint travel over which the stretch's trend is taken
LOOK_STEP = 0.01
#: rad kept from each joint's range
RANGE_MARGIN = 0.05
#: m short of a wall the tool stops, and the deceleration it brakes for a wall with, m/s²
WALL_STOP = 0.002
WALL_DECELERATION = 0.5
#: s ahead servoing looks for the arm colliding with itself (it stops short of that pose)
COLLISION_LOOK_AHEAD = 0.25
#: the fraction of each joint's velocity limit servoing uses (the tracking adds a little)
VELOCITY_SHARE = 0.9

Reason = Literal["", "no command", "singularity", "joint limit", "wall", "collision", "ended"]


@dataclass(frozen=True)
class ServoStatus:
    """What servoing does now: ``state`` ``"ok"``, ``"slowing"`` or ``"stopped"``; ``reason`` why it slows
    or stopped (``"singularity"``, ``"joint limit"``, ``"wall"``, ``"collision"``: the arm against itself,
    ``"no command"``, ``"ended"``; ``""`` when ok); ``scale``: the share of the commanded speed it goes at
    (0..1); ``joint``: the joint at its limit, if that is the reason."""

    state: Literal["ok", "slowing", "stopped"]
    reason: Reason = ""
    scale: float = 1.0
    joint: str | None = None


class _Command:
    __slots__ = ("kind", "stamp", "value")

    def __init__(self, kind: str, value: np.ndarray, stamp: float) -> None:
        self.kind, self.value, self.stamp = kind, value, stamp


def _log3(R: np.ndarray) -> np.ndarray:
    return np.asarray(pin.log3(R))


class ServoStream(Timed):
    """The live plan servoing puts in (see the module). It runs on the control loop's thread, on a
    ``model`` of its own; commands come from the caller's thread (:meth:`command_twist`,
    :meth:`command_pose`, :meth:`finish`), each replacing the last one whole.

    Args:
        model: its own dynamics model (the loop thread uses it).
        limits: the joint limits (velocity, acceleration, jerk, range).
        walls: the robot file's workspace, or ``None``.
        period: the loop's period, s (the stream steps in whole periods).
        timeout: s without a command after which the arm comes to rest and holds.
        frame: ``"base"`` or ``"tool"``: the axes a twist is in.
        max_speed, max_rotation: m/s and rad/s the tool goes at most.
        collision: the arm's self-collision check (its own: the loop's thread uses it), or ``None``.
    """

    def __init__(self, model: RobotModel, limits: JointLimits, walls: Workspace | None, period: float, timeout: float,
                 frame: Literal["base", "tool"], max_speed: float, max_rotation: float,
                 collision: SelfCollision | None = None) -> None:
        self.model, self.limits, self.walls, self.collision = model, limits, walls, collision
        self.period, self.timeout, self.frame = period, timeout, frame
        self.max_speed, self.max_rotation = max_speed, max_rotation
        n = len(limits.names)
        self.t0 = 0.0
        self.t_end = math.inf
        self.q, self.v, self.a = np.zeros(n), np.zeros(n), np.zeros(n)
        self.last = 0.0
        self.command: _Command | None = None
        self.finishing = False
        self.goal: np.ndarray | None = None  # the goal pose (4×4) of the command in force
        self.status = ServoStatus("stopped", "no command", 0.0)
        self.steps = 0  # cycles stepped (a benchmark's count)
        self._weights = np.array([1.0, 1.0, 1.0, ROTATION_WEIGHT, ROTATION_WEIGHT, ROTATION_WEIGHT])
        self._v_cap = VELOCITY_SHARE * limits.velocity
        self._a_brake = float(np.min(limits.acceleration))  # (twice half: sqrt(2 · a/2 · d))
        self._brake_lag = float(np.max(limits.acceleration / limits.jerk))
        self._lower = limits.lower + RANGE_MARGIN
        self._upper = limits.upper - RANGE_MARGIN
        self._lock = threading.Lock()  # commands against the loop's reading of them (a tuple of fields)
        self.first_step: float | None = None  # plan time of the first step that used the latest command
        self._otg = ruckig.Ruckig(n)
        self._traj = ruckig.Trajectory(n)
        inp = self._inp = ruckig.InputParameter(n)
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.synchronization = ruckig.Synchronization.Phase
        inp.max_velocity = limits.velocity.tolist()
        inp.max_acceleration = limits.acceleration.tolist()
        inp.max_jerk = limits.jerk.tolist()
        inp.target_acceleration = [0.0] * n

    # -- the caller's side ---------------------------------------------------------------------
    def begin(self, start: State, t0: float) -> ServoStream:
        """Start from the commanded state ``start`` at plan time ``t0`` (:meth:`Controller.start`'s plan)."""
        self.q = np.array(start[0], dtype=float)
        self.v = np.array(start[1], dtype=float)
        self.a = np.array(start[2], dtype=float)
        self.t0 = self.last = t0
        return self

    def shifted(self, dt: float) -> ServoStream:
        """Start ``dt`` s later (a plan from rest taking over later than planned): the stream itself, its
        start moved (it has not been sampled yet; a wrapper would keep an end time it cannot change)."""
        self.t0 += dt
        self.last += dt
        return self

    def command_twist(self, twist: np.ndarray, stamp: float) -> None:
        with self._lock:
            self.command = _Command("twist", twist, stamp)
            self.first_step = None

    def command_pose(self, pose: np.ndarray, stamp: float) -> None:
        with self._lock:
            self.command = _Command("pose", pose, stamp)
            self.first_step = None

    def finish(self) -> None:
        """Come to rest (jerk-limited), then end: the arm holds there."""
        self.finishing = True

    def clear(self) -> None:
        """Drop the command in force: the arm comes to rest and holds until the next one."""
        with self._lock:
            self.command = None

    # -- the loop's side -----------------------------------------------------------------------
    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if math.isfinite(t) and t > self.last and t < self.t_end:
            steps = max(1, round((t - self.last) / self.period))
            dt = (t - self.last) / steps
            for k in range(steps):
                self._step(dt, self.last + (k + 1) * dt)
            self.last = t
        return self.q.copy(), self.v.copy(), self.a.copy()

    def _step(self, dt: float, t: float) -> None:
        self.steps += 1
        with self._lock:
            cmd = self.command
        T = self.model.tool_pose(self.q)
        live = cmd is not None and not self.finishing and t - cmd.stamp <= self.timeout
        if not live:
            self.goal = None
            target = np.zeros_like(self.v)
            status = ServoStatus("stopped", "ended" if self.finishing else "no command", 0.0)
        else:
            assert cmd is not None
            if self.first_step is None:
                self.first_step = t
            J = self.model.jacobian(self.q)
            target, status = self._velocity(cmd, T, J, dt)
        self._track(target, dt)
        self.status = status
        if self.finishing and not np.any(np.abs(self.v) > 1e-9) and not np.any(np.abs(self.a) > 1e-9):
            self.v[:] = 0.0
            self.a[:] = 0.0
            self.t_end = t  # at rest: the plan ends, the arm holds here

    def _velocity(self, cmd: _Command, T: np.ndarray, J: np.ndarray, dt: float) -> tuple[np.ndarray, ServoStatus]:
        """The joint velocity this step aims at, and the status."""
        twist = np.zeros(6)
        if cmd.kind == "twist":
            twist = cmd.value.copy()
            if self.frame == "tool":
                R = T[:3, :3]
                twist = np.concatenate([R @ twist[:3], R @ twist[3:]])
            twist = self._capped(twist)
            goal = self.goal if self.goal is not None else T.copy()
            scale = self.status.scale if self.status.state != "stopped" or self.status.reason != "no command" else 1.0
            goal = goal.copy()
            goal[:3, 3] += twist[:3] * dt * scale
            goal[:3, :3] = pin.exp3(twist[3:] * dt * scale) @ goal[:3, :3]
        else:
            goal = cmd.value
        # the goal leads the command by GOAL_LEAD at most
        dp = goal[:3, 3] - T[:3, 3]
        dr = _log3(goal[:3, :3] @ T[:3, :3].T)
        lp, lr = float(np.linalg.norm(dp)), float(np.linalg.norm(dr))
        if cmd.kind == "twist":
            if lp > GOAL_LEAD[0]:
                dp *= GOAL_LEAD[0] / lp
            if lr > GOAL_LEAD[1]:
                dr *= GOAL_LEAD[1] / lr
            goal = goal.copy()
            goal[:3, 3] = T[:3, 3] + dp
            goal[:3, :3] = pin.exp3(dr) @ T[:3, :3]
        self.goal = goal
        gain = FEEDBACK_GAIN if cmd.kind == "twist" else POSE_GAIN
        velocity = self._capped(twist + gain * np.concatenate([dp, dr]))
        return self._scaled(self._dls(J, velocity), velocity, T, J)

    def _dls(self, J: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The joint velocity for the tool ``velocity`` (damped least squares, rotations weighted)."""
        w = self._weights
        Jw = J * w[:, None]
        return np.asarray(Jw.T @ np.linalg.solve(Jw @ Jw.T + DAMPING**2 * np.eye(6), velocity * w))

    def _stretch(self, dq: np.ndarray, velocity: np.ndarray) -> float:
        """rad/m: joint speed per (weighted) tool speed for this command: it grows toward a singularity
        in the command's direction (a wrist singularity across it leaves it alone)."""
        size = float(np.linalg.norm(velocity * self._weights))
        return float(np.linalg.norm(dq)) / size if size > 1e-9 else 0.0

    def _capped(self, twist: np.ndarray) -> np.ndarray:
        """``twist`` scaled down (as a whole) to max_speed and max_rotation."""
        s = 1.0
        lin, ang = float(np.linalg.norm(twist[:3])), float(np.linalg.norm(twist[3:]))
        if lin > self.max_speed:
            s = self.max_speed / lin
        if ang * s > self.max_rotation:
            s = self.max_rotation / ang
        return twist * s

    def _singular_scale(self, dq: np.ndarray, velocity: np.ndarray) -> float:
        """The share of ``dq`` the arm may go at for a singularity ahead: the joint speed this command needs
        per tool speed (its stretch r) growing. x = 1/r - 1/STRETCH_STOP falls to 0 at the stop;
        extrapolated along dq, it gets there after D rad of joint travel, and the joints go no faster
        than they can brake in D (at half their acceleration)."""
        stretch = self._stretch(dq, velocity)
        size = float(np.linalg.norm(dq))
        if stretch <= STRETCH_LOOK or size <= 1e-12:
            return 1.0
        ahead = self._stretch(self._dls(self.model.jacobian(self.q + dq * (LOOK_STEP / size)), velocity), velocity)
        x_now, x_ahead = 1.0 / stretch - 1.0 / STRETCH_STOP, 1.0 / max(ahead, 1e-9) - 1.0 / STRETCH_STOP
        if x_ahead >= x_now:  # away from it
            return 1.0
        room = LOOK_STEP * x_now / (x_now - x_ahead) if x_now > 0.0 else 0.0
        room -= float(np.linalg.norm(self.v)) * self._brake_lag
        allowed = math.sqrt(self._a_brake * max(0.0, room))
        return min(1.0, allowed / size)

    def _scaled(self, dq: np.ndarray, velocity: np.ndarray, T: np.ndarray,
                J: np.ndarray) -> tuple[np.ndarray, ServoStatus]:
        """``dq`` scaled down (as one vector) for the velocity limits, a singularity, the ranges and the walls."""
        scale = self._singular_scale(dq, velocity)
        reason, joint = ("singularity" if scale < 1.0 else ""), None
        big = np.abs(dq)
        s_vel = float(np.min(np.where(big > 1e-12, self._v_cap / np.maximum(big, 1e-12), np.inf), initial=1.0))
        dq = dq * min(1.0, s_vel)
        # the ranges, less the margin: each joint can stop before it at half its acceleration limit
        lim = self.limits
        for i, x in enumerate(dq.tolist()):
            if x == 0.0:
                continue
            room = (self._upper[i] - self.q[i]) if x > 0 else (self.q[i] - self._lower[i])
            room -= abs(self.v[i]) * lim.acceleration[i] / lim.jerk[i]
            allowed = math.sqrt(max(0.0, lim.acceleration[i] * room))
            if abs(x) * scale > allowed:
                scale, reason, joint = allowed / abs(x), "joint limit", lim.names[i]
        # the walls
        if self.walls is not None:
            v_tool = J[:3] @ dq
            for depth, normal in self.walls.walls(T[:3, 3]):
                vn = float(normal @ v_tool)
                if vn <= 0.0:
                    continue
                allowed = math.sqrt(2.0 * WALL_DECELERATION * max(0.0, depth - WALL_STOP))
                if vn * scale > allowed:
                    scale, reason, joint = allowed / vn, "wall", None
        # the arm against itself: stop short of a pose that collides a braking time ahead
        sc = self.collision
        if sc is not None and scale > 0.0:
            reach = self.q + dq * scale * COLLISION_LOOK_AHEAD
            if sc.collides(reach) and not sc.collides(self.q):
                scale, reason, joint = 0.0, "collision", None
        if scale >= 0.999:
            return dq, ServoStatus("ok", "", 1.0)
        state: Literal["slowing", "stopped"] = "stopped" if scale < 0.01 else "slowing"
        return dq * scale, ServoStatus(state, reason, scale, joint)  # type: ignore[arg-type]

    def _track(self, target: np.ndarray, dt: float) -> None:
        """Each joint's velocity toward ``target``, within its acceleration and jerk limits: one step of
        ruckig's time-optimal velocity-interface trajectory (phase-synchronised: the joints' velocities
        keep their proportions, so the tool keeps its direction while it speeds up or slows down)."""
        inp = self._inp
        inp.current_position = self.q.tolist()
        inp.current_velocity = self.v.tolist()
        inp.current_acceleration = self.a.tolist()
        inp.target_velocity = target.tolist()
        try:
            self._otg.calculate(inp, self._traj)
            p, v, a = self._traj.at_time(dt)
        except (ruckig.RuckigError, ValueError):  # (not seen) hold the velocity: the next step plans again
            p, v, a = (self.q + self.v * dt).tolist(), self.v.tolist(), [0.0] * len(self.q)
        self.q, self.v, self.a = np.array(p), np.array(v), np.array(a)


class _Motion(Protocol):
    @property
    def done(self) -> bool: ...

    def wait(self, timeout: float | None = None) -> Any: ...


class Servo:
    """The handle of ``arm.servo()``: use it as ``with arm.servo(timeout=0.1) as s:`` and send
    :meth:`twist` or :meth:`pose` commands at any rate; leaving the block brings the arm to rest,
    jerk-limited, and it holds there.

    A safety stop during the block ends servoing; the next command raises it, and so does the block's end
    if nothing else did (an exception leaving the block goes on unchanged).

    Args (from :meth:`akarm.Arm.servo`): the stream, and the arm's ways to start it, to read its plan
    time, to raise its safety stop unless it is enabled (``check``), to raise its safety stop if it
    stopped (``raise_stop``).
    """

    def __init__(self, stream: ServoStream, start: Callable[[ServoStream], _Motion], now: Callable[[], float],
                 check: Callable[[], None], caller_model: RobotModel,
                 raise_stop: Callable[[], None] | None = None) -> None:
        self.stream = stream
        self._start = start
        self._now = now
        self._check = check
        self._model = caller_model
        self._raise_stop = raise_stop
        self.motion: _Motion | None = None

    def __enter__(self) -> Servo:
        self.motion = self._start(self.stream)
        return self

    def __exit__(self, *exc: object) -> None:
        self.stream.finish()
        motion = self.motion
        if exc[0] is not None or motion is None:
            return
        if not motion.done:
            motion.wait(timeout=5.0)  # (a stop in the meantime raises here)
        elif self._raise_stop is not None:
            self._raise_stop()  # a stop that ended servoing in the block: raised here, as promised

    def _live(self) -> None:
        self._check()  # the arm's safety stop, if it stopped
        if self.motion is None:
            raise StateError("servoing has not started", fix="use it as `with arm.servo() as s:`")
        if self.motion.done:
            raise StateError("servoing ended: another motion or a stop replaced it",
                             fix="start servoing again: `with arm.servo() as s:`")

    def twist(self, twist: Sequence[float] | np.ndarray) -> None:
        """Move the tool frame's origin at ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s; in the base frame's
        axes, or the tool's with ``frame="tool"``) until the next command, or ``timeout`` s."""
        try:
            v = np.asarray(twist, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            v = np.full(0, math.nan)
        if v.shape != (6,) or not np.all(np.isfinite(v)):
            raise ArgumentError(f"a twist must be 6 finite numbers [vx, vy, vz, wx, wy, wz] (m/s, rad/s), got "
                                f"{twist!r}", fix="e.g. s.twist([0, 0, 0.05, 0, 0, 0]): 50 mm/s up")
        self._live()
        self.stream.command_twist(v, self._now())

    def pose(self, pose: object) -> None:
        """Track ``pose`` (as :meth:`akarm.Arm.move_to_pose` takes it: a 4×4, ``(xyz, quaternion xyzw)``
        or a position alone), at max_speed and max_rotation at most, until ``timeout`` s without a command."""
        T, _ = as_pose(pose, self._model.tool_pose(self.stream.q.copy()))
        self._live()
        self.stream.command_pose(np.array(T, dtype=float), self._now())

    def stop(self) -> None:
        """Come to rest now (as when commands stop coming); the next command resumes."""
        self._live()
        self.stream.clear()

    @property
    def status(self) -> ServoStatus:
        """What servoing does now (:class:`ServoStatus`): ok, slowing or stopped, and why."""
        return self.stream.status
