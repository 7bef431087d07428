"""A ROS 2 ``JointTrajectory`` checked as ros2_control's JointTrajectoryController checks it, for the
``joint_trajectory`` topic and the ``follow_joint_trajectory`` action alike.

:func:`check_trajectory` refuses, before anything moves, what JointTrajectoryController refuses
(``validate_trajectory_msg`` in ros2_controllers' ``joint_trajectory_controller.cpp``), each with
the result code the action reports (:class:`TrajectoryRefused`):

- ``INVALID_JOINTS``: no joint names, a name that is not a joint of the arm, a name given twice;
- ``INVALID_GOAL``: ``time_from_start`` that does not increase strictly from point to point (equal
  times too), a point without one position per joint, a position past a joint's range, a velocity
  past a joint's limit, velocities on some points and not on others, a last point that is not at
  rest, more points than :data:`akarm.motion.bounds.MAX_TRAJECTORY_POINTS`;
- ``OLD_HEADER_TIMESTAMP``: a stamped trajectory whose every point is already in the past.

:func:`check_size` refuses a message too big for those limits from its bytes, before it is decoded.

Accelerations are checked for their count only (the jerk-limited planner makes its own); efforts
are not used.
"""

from __future__ import annotations

import bisect
import contextlib
import math
import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from akarm.errors import ArgumentError, did_you_mean, num
from akarm.motion.bounds import MAX_TRAJECTORY_POINTS
from akarm.motion.trajectory import JointLimits
from akarm.ros import msgs

if TYPE_CHECKING:
    from akarm.server.server import ArmServerCore

__all__ = ["GOAL_TOLERANCE_VIOLATED", "INVALID_GOAL", "INVALID_JOINTS", "OLD_HEADER_TIMESTAMP",
           "PATH_TOLERANCE_VIOLATED", "SUCCESSFUL", "TimedPoints", "TrajectoryRefused", "check_joint_names",
           "check_size", "check_trajectory", "max_message_bytes", "refusal", "trajectory_arrays"]

# control_msgs/action/FollowJointTrajectory's result codes
SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5

_AT_REST = 1.1920929e-07  # JointTrajectoryController: a last point's velocity above float epsilon is not rest


class TrajectoryRefused(ArgumentError):
    """A trajectory refused before anything moved, with the FollowJointTrajectory result ``code``."""

    def __init__(self, what: str, code: int, *, joint: str | None = None, fix: str = "") -> None:
        self.code = code
        super().__init__(what, joint=joint, fix=fix)

    def report(self, server: ArmServerCore) -> None:
        """Count and report it as the server does the trajectories it refuses (its log, ``akarm/status``)."""
        with contextlib.suppress(ArgumentError):
            server.refuse(self.what if self.joint is None else f"joint {self.joint!r}: {self.what}", fix=self.fix)


@dataclass(frozen=True)
class TimedPoints:
    """A checked trajectory, ready for :meth:`ArmServerCore.follow <akarm.server.server.ArmServerCore.follow>`.

    Attributes:
        joint_names: the joints it names, in its order.
        times: s from now of the points still ahead; positions, velocities: theirs (velocities
            ``None`` when the message gave none).
        start: wall-clock time (``time.time()``) its ``time_from_start`` counts from.
        time_from_start: every point's, s (for the feedback's ``index``).
    """

    joint_names: list[str]
    times: list[float]
    positions: list[list[float]]
    velocities: list[list[float]] | None
    start: float
    time_from_start: list[float]

    @property
    def end(self) -> float:
        """Wall-clock time of the last point (``start`` for no points)."""
        return self.start + (self.time_from_start[-1] if self.time_from_start else 0.0)

    def index(self, now: float) -> int:
        """The point the trajectory is heading for at wall-clock ``now`` (the last once past it)."""
        k = bisect.bisect_right(self.time_from_start, now - self.start)
        return min(k, max(0, len(self.time_from_start) - 1))


def trajectory_arrays(msg: msgs.JointTrajectory, now: float | None = None) -> tuple[list[float], list[list[float]],
                                                                                    list[list[float]] | None]:
    """Times (s from now), positions and velocities of a JointTrajectory's points, unchecked.

    A zero ``header.stamp`` means "start now"; a later one shifts every point by the wait until
    then; points whose time has already passed are dropped (as JointTrajectoryController does).
    """
    now = time.time() if now is None else now
    stamp = msg.header.stamp.seconds()
    offset = stamp - now if stamp > 0 else 0.0
    times, positions, velocities = [], [], []
    for p in msg.points:
        t = p.time_from_start.seconds() + offset
        if t < 0.0:
            continue
        times.append(t)
        positions.append(list(p.positions))
        velocities.append(list(p.velocities))
    return times, positions, (velocities if any(velocities) else None)


def check_joint_names(joint_names: Sequence[str], names: Sequence[str], what: str = "joint_names") -> None:
    """Refuse (``INVALID_JOINTS``) names that are not joints of the arm (``names``), or named twice."""
    seen: set[str] = set()
    for n in joint_names:
        if n not in names:
            raise TrajectoryRefused(f"{what} names {n!r}, which is not a joint of this arm{did_you_mean(n, names)}",
                                    INVALID_JOINTS, fix="the joints are: " + ", ".join(names))
        if n in seen:
            raise TrajectoryRefused(f"{what} names {n!r} twice", INVALID_JOINTS, fix="name each joint once")
        seen.add(n)


def _check_point(k: int, p: msgs.JointTrajectoryPoint, names: list[str], index: list[int],
                 limits: JointLimits) -> None:
    n = len(names)
    if len(p.positions) != n:
        raise TrajectoryRefused(f"point {k} has {len(p.positions)} positions for {n} joint_names", INVALID_GOAL,
                                fix="give one position (rad) per name in joint_names")
    for field, one, unit, values, allow_empty in (
            ("positions", "position", "rad", p.positions, False),
            ("velocities", "velocity", "rad/s", p.velocities, True),
            ("accelerations", "acceleration", "rad/s²", p.accelerations, True)):
        if len(values) != n and not (allow_empty and len(values) == 0):
            raise TrajectoryRefused(f"point {k} has {len(values)} {field} for {n} joint_names", INVALID_GOAL,
                                    fix=f"give one {one} ({unit}) per name in joint_names"
                                        + ("" if not allow_empty else ", or none"))
        for name, x in zip(names, values, strict=False):
            if not math.isfinite(x):
                raise TrajectoryRefused(f"point {k}: {one} {x} is not a number", INVALID_GOAL, joint=name,
                                        fix=f"give a finite {one} in {unit}")
    for name, i, q in zip(names, index, p.positions, strict=True):
        lo, hi = float(limits.lower[i]), float(limits.upper[i])
        if not lo - 1e-9 <= q <= hi + 1e-9:
            raise TrajectoryRefused(f"point {k}: position {num(q)} rad is outside the joint's range [{num(lo)}, "
                                    f"{num(hi)}] rad", INVALID_GOAL, joint=name,
                                    fix="keep every point inside the joint's range (the robot file's limits)")
    for name, i, v in zip(names, index, p.velocities, strict=False):
        vmax = float(limits.velocity[i])
        if abs(v) > vmax * (1 + 1e-9):
            raise TrajectoryRefused(f"point {k}: velocity {num(v)} rad/s is beyond the joint's limit {vmax:g} rad/s",
                                    INVALID_GOAL, joint=name,
                                    fix="time the trajectory within the joint limits (akarm ros-config writes "
                                        "them for MoveIt: joint_limits.yaml)")


def max_message_bytes(joints: int) -> int:
    """The most bytes a ``JointTrajectory`` (or a FollowJointTrajectory goal) that akarm takes for an arm of
    ``joints`` joints can have: :data:`~akarm.motion.bounds.MAX_TRAJECTORY_POINTS` points, each with four
    sequences of ``joints`` doubles (positions, velocities, accelerations, efforts: a length, padding,
    the values) and its time, and 64 KiB for the rest (joint names, ``frame_id``, a goal's tolerances)."""
    return MAX_TRAJECTORY_POINTS * (4 * (8 + 8 * joints) + 16) + 65536


def refusal(e: ArgumentError) -> TrajectoryRefused:
    """``e`` as a trajectory's refusal: itself if it is one, else ``INVALID_GOAL`` (a message that does not
    decode)."""
    return e if isinstance(e, TrajectoryRefused) else TrajectoryRefused(e.what, INVALID_GOAL, fix=e.fix)


def _too_many_points(n: int) -> TrajectoryRefused:
    return TrajectoryRefused(f"the trajectory has {n} points, more than the {MAX_TRAJECTORY_POINTS} akarm takes",
                             INVALID_GOAL, fix="send it in parts, or with fewer points")


def check_size(data: bytes, offset: int, names: Sequence[str]) -> None:
    """Refuse, from its CDR bytes and before decoding it, a ``JointTrajectory`` that starts at ``offset`` of
    the sample ``data`` (4 on a topic, after the encapsulation) and that :func:`check_trajectory` would
    refuse for its size, for an arm whose joints are ``names``: more bytes than :func:`max_message_bytes`,
    more joint names than the arm has joints (``INVALID_JOINTS``), more points than
    :data:`~akarm.motion.bounds.MAX_TRAJECTORY_POINTS` (read from the sequence's length). Decoding
    a message costs about 1 s per 100 000 points in pure Python, and millions of objects (whose
    garbage collections stopped the control loop). A sample cut short is left to the decoder.

    Raises:
        TrajectoryRefused: what is too big (``INVALID_GOAL``, ``INVALID_JOINTS``). Nothing is decoded.
    """
    limit = max_message_bytes(len(names))
    if len(data) > limit:
        raise TrajectoryRefused(f"the message is {len(data)} bytes, more than the {limit} that a trajectory of "
                                f"{MAX_TRAJECTORY_POINTS} points for this arm's {len(names)} joints takes",
                                INVALID_GOAL, fix="send it in parts, or with fewer points")
    try:  # CDR: alignment counts from the end of the encapsulation (4: a multiple of 4 already)
        pos = offset + 8  # header.stamp (sec, nanosec)
        pos += 4 + struct.unpack_from("<I", data, pos)[0]  # header.frame_id
        pos = (pos + 3) & ~3
        count = struct.unpack_from("<I", data, pos)[0]
        if count > len(names):
            raise TrajectoryRefused(f"the trajectory names {count} joints; this arm has {len(names)}", INVALID_JOINTS,
                                    fix="name each joint once: " + ", ".join(names))
        pos += 4
        for _ in range(count):
            pos = (pos + 4 + struct.unpack_from("<I", data, pos)[0] + 3) & ~3
        points = struct.unpack_from("<I", data, pos)[0]
    except struct.error:
        return  # cut short: the decoder refuses it
    if points > MAX_TRAJECTORY_POINTS:
        raise _too_many_points(points)


def check_trajectory(msg: msgs.JointTrajectory, names: Sequence[str], limits: JointLimits,
                     now: float | None = None) -> TimedPoints:
    """Check ``msg`` for the arm whose joints are ``names`` (config order) with ``limits``, as
    JointTrajectoryController does (see the module's docstring), and return its points.

    ``now``: wall-clock time (default ``time.time()``). A message with no points is returned as
    one without times (the topic stops the arm for it; the action refuses it).

    Raises:
        TrajectoryRefused: what is wrong, with the action's result code. Nothing has moved.
    """
    now = time.time() if now is None else now
    names = list(names)
    joint_names = list(msg.joint_names)
    if not joint_names:
        raise TrajectoryRefused("the trajectory names no joints", INVALID_JOINTS,
                                fix="fill joint_names: " + ", ".join(names))
    check_joint_names(joint_names, names)
    points = list(msg.points)
    if len(points) > MAX_TRAJECTORY_POINTS:
        raise _too_many_points(len(points))
    index = [names.index(n) for n in joint_names]
    tfs: list[float] = []
    for k, p in enumerate(points):
        t = p.time_from_start.seconds()
        if t < 0.0:
            raise TrajectoryRefused(f"point {k}'s time_from_start is negative ({t:g} s)", INVALID_GOAL,
                                    fix="time_from_start counts from the trajectory's start: 0 or more")
        if tfs and t <= tfs[-1]:
            raise TrajectoryRefused(f"point {k}'s time_from_start ({t:g} s) is not after point {k - 1}'s "
                                    f"({tfs[-1]:g} s)", INVALID_GOAL,
                                    fix="time_from_start must increase strictly from point to point")
        tfs.append(t)
        _check_point(k, p, joint_names, index, limits)
    if points:
        given = [len(p.velocities) > 0 for p in points]
        if any(given) and not all(given):
            raise TrajectoryRefused("some points have velocities and others none", INVALID_GOAL,
                                    fix="give velocities for every point, or for none")
        last = points[-1]
        moving = [(n, v) for n, v in zip(joint_names, last.velocities, strict=False) if abs(v) > _AT_REST]
        if moving:
            raise TrajectoryRefused(f"the last point is not at rest: velocity {moving[0][1]:g} rad/s", INVALID_GOAL,
                                    joint=moving[0][0], fix="end the trajectory with zero velocities")
    stamp = msg.header.stamp.seconds()
    start = stamp if stamp > 0 else now
    if points and start + tfs[-1] < now:
        raise TrajectoryRefused(f"every point of the trajectory is already in the past (header.stamp + "
                                f"time_from_start ends {now - start - tfs[-1]:.3f} s ago)", OLD_HEADER_TIMESTAMP,
                                fix="stamp it with the current time, or leave the stamp zero")
    times, positions, velocities = trajectory_arrays(msg, now=now)
    return TimedPoints(joint_names, times, positions, velocities, start, tfs)
