"""A remote client's stream of joint targets (a policy's actions), with the safety rules it needs.

A learning policy (LeRobot's ``send_action``) sends a target every frame (30 Hz) from a process of its
own. :class:`TargetStream` takes each one into the arm's 500 Hz loop through the jerk-limited
retargeting (:meth:`akarm.Arm.stream_to`, each joint on its own), so that:

- **no command step exceeds a joint's limits**, whatever is sent: the retargeting starts from the
  commanded position, velocity and acceleration, within each joint's velocity, acceleration and jerk
  limits;
- **a target past a joint's range is clamped** to the range's edge and counted (:attr:`clamped`; the
  log gets one line per joint, the first time); so is a gripper width past its stroke (0 to the
  stroke, m), counted and reported under the gripper's name;
- **a target that is not a number** (NaN, ``None``), an unknown joint, or a missing joint (unless
  ``partial``) is **refused**: nothing of it is used, the arm comes to rest where it is going
  (jerk-limited) and holds, and :class:`~akarm.ArgumentError` says which joint and why;
- **targets that move are led**, as :mod:`akarm.teleop` leads its follower: a retarget comes to rest
  at its target, so a moving stream would be trailed by a braking distance; the target taken is the
  one sent plus the distance the arm needs to brake from the targets' own velocity (the last two
  targets' difference over their interval, within the joint's velocity limit) at its limits
  (:func:`akarm.teleop.stopping_distance`), within the range; a stream that stops moving is then
  reached and held (``lead=False``: each target as sent);
- **a client that stops sending** (a stalled or crashed policy) leaves the arm decelerating to a hold
  once :attr:`timeout` s have passed since its last target (:meth:`check`, which the server calls
  every few ms); the next target resumes from there, smoothly (retargeting from the braking state).

It runs on the arm's own clock, so the sim tests drive it in lock step (tests/sim/test_stream.py);
:class:`~akarm.server.server.ArmServerCore` serves it as the ``stream`` operation.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm.errors import ArgumentError, finite_number
from akarm.teleop import stopping_distance

if TYPE_CHECKING:
    from akarm.arm import Arm

__all__ = ["DEFAULT_TIMEOUT", "MAX_TIMEOUT", "MIN_TIMEOUT", "StreamReport", "TargetStream"]

#: s without a new target after which the arm decelerates to a hold (7.5 frames at 30 Hz)
DEFAULT_TIMEOUT = 0.25
MIN_TIMEOUT = 0.02  #: s: the shortest timeout a client may ask (the server looks every few ms)
MAX_TIMEOUT = 5.0  #: s: the longest (a policy that stalls longer must not keep the arm heading for a stale target)


@dataclass(frozen=True)
class StreamReport:
    """What one target did (the ``stream`` operation's answer).

    Attributes:
        target: the positions streamed, rad, config order (clamped to the range).
        clamped: the joints of this target that were past their range (taken to its edge), and the
            gripper's name if its width was past its stroke (taken to 0 or the stroke).
        clamped_total: targets' joints (and gripper widths) clamped since the stream began.
        timeouts: times the arm was brought to a hold for want of a target since the stream began.
        gripper: the gripper width asked, m (clamped to its stroke), or ``None``.
    """

    target: tuple[float, ...]
    clamped: tuple[str, ...]
    clamped_total: int
    timeouts: int
    gripper: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"target": list(self.target), "clamped": list(self.clamped), "clamped_total": self.clamped_total,
                "timeouts": self.timeouts, "gripper": self.gripper}


def check_timeout(timeout: object) -> float:
    """``timeout`` as a float of s within [:data:`MIN_TIMEOUT`, :data:`MAX_TIMEOUT`], else ArgumentError."""
    return finite_number(timeout, "a stream's timeout", at_least=MIN_TIMEOUT, at_most=MAX_TIMEOUT, unit="s",
                         fix=f"e.g. timeout={DEFAULT_TIMEOUT}")


class TargetStream:
    """Streams targets into ``arm`` (enabled) with the rules of the module's docstring.

    Args:
        arm: the arm, enabled.
        timeout: s without a target after which :meth:`check` brings the arm to a hold.
        speed: the fraction of the joint limits the retargeting may use, in (0, 1].
        log: where the one-line reports go (a joint clamped the first time, a hold for want of targets).
        lead: lead moving targets by their braking distance (see the module's docstring).
    """

    def __init__(self, arm: Arm, *, timeout: float = DEFAULT_TIMEOUT, speed: float = 1.0,
                 log: Callable[[str], None] | None = None, lead: bool = True) -> None:
        self.arm = arm
        self.timeout = check_timeout(timeout)
        self.speed = finite_number(speed, "a stream's speed", at_least=0.01, at_most=1.0,
                                   fix="give a fraction of the joint limits, e.g. speed=1.0")
        self.log = log or (lambda text: None)
        self.names: tuple[str, ...] = tuple(arm.names)
        self.clamped = 0  #: joints clamped to their range, summed over the targets
        self.refused = 0  #: targets refused (not a number, unknown or missing joint)
        self.timeouts = 0  #: holds for want of a target
        self.sent = 0  #: targets taken
        self._warned: set[str] = set()
        self._last: float | None = None  # clock time of the last target taken (None: holding, none pending)
        self.lead = bool(lead)
        self._previous: np.ndarray | None = None  # the last target taken, as sent (clamped), for its velocity
        self._limits = arm.limits.scaled(self.speed)
        self._lock = threading.Lock()

    @property
    def last(self) -> float | None:
        """Clock time of the last target taken, while the stream is live (``None`` once it timed out)."""
        return self._last

    def _gripper(self, width: object) -> float | None:
        """The gripper width asked (m, finite, not yet clamped), or None; ArgumentError as documented."""
        if width is None:
            return None
        gripper = self.arm.gripper
        if gripper is None:
            raise ArgumentError("this arm has no gripper, but the target has a gripper width",
                                fix="leave 'gripper' out, or add a gripper to the robot file")
        return self._finite(width, gripper.name, "m")

    def _clamp_gripper(self, width: float) -> tuple[float, bool]:
        """``width`` within the gripper's stroke (0 to the stroke, m), and whether it was outside (said
        once)."""
        gripper = self.arm.gripper
        assert gripper is not None  # (a width without a gripper was refused)
        w = min(max(width, 0.0), gripper.stroke)
        if w == width:
            return w, False
        if gripper.name not in self._warned:
            self._warned.add(gripper.name)
            self.log(f"akarm stream: a gripper width of {width:+.4f} m is past its stroke [0, {gripper.stroke:g}] m: "
                     "taken to its edge (counted; said once)")
        return w, True

    @staticmethod
    def _finite(value: object, joint: str, unit: str = "rad") -> float:
        if value is None or isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
            raise ArgumentError(f"target {value!r} is not a number: the target is refused, the arm holds",
                                joint=joint, fix=f"send a finite number ({unit}) for every joint")
        x = float(value)
        if not math.isfinite(x):
            raise ArgumentError(f"target {x} is not a finite number: the target is refused, the arm holds",
                                joint=joint, fix=f"send a finite number ({unit}) for every joint")
        return x

    def _positions(self, target: Mapping[str, object] | Sequence[object], partial: bool) -> np.ndarray:
        """``target`` as one position per joint (config order), unclamped; ArgumentError as documented."""
        n = len(self.names)
        if isinstance(target, Mapping):
            unknown = [str(k) for k in target if k not in self.names]
            if unknown:
                raise ArgumentError(f"no joint named {unknown[0][:40]!r}: the target is refused, the arm holds",
                                    fix="joints are: " + ", ".join(self.names))
            missing = [name for name in self.names if name not in target]
            if missing and not partial:
                raise ArgumentError("the target has no position for this joint: it is refused, the arm holds",
                                    joint=missing[0], fix="send every joint's position (rad), or partial=True")
            if len(missing) == n:
                raise ArgumentError("the target names no joint: it is refused, the arm holds",
                                    fix="joints are: " + ", ".join(self.names))
            q = self.arm.state().q_des.copy() if missing else np.empty(n)
            for name in self.names:
                if name in target:
                    q[self.names.index(name)] = self._finite(target[name], name)
            return q
        values: list[object] = list(target)
        if len(values) != n:
            raise ArgumentError(f"the target has {len(values)} positions, the arm has {n} joints: it is refused, "
                                "the arm holds", fix="give one position (rad) per joint: " + ", ".join(self.names))
        return np.array([self._finite(v, name) for v, name in zip(values, self.names, strict=True)])

    def send(self, target: Mapping[str, object] | Sequence[object], *, partial: bool = False,
             gripper: object = None) -> StreamReport:
        """Stream ``target`` (``{joint: rad}`` or one position per joint; ``partial``: joints left out
        keep their commanded position) and, if given, the gripper's width (m).

        Raises:
            ArgumentError: a target refused (not a number, an unknown or missing joint, a gripper width
                for an arm without one): the arm was brought to a hold, jerk-limited, first.
            StateError, SafetyStop: what :meth:`akarm.Arm.stream_to` raises (a disabled arm, a stop).
        """
        with self._lock:
            try:
                q = self._positions(target, partial)
                width = self._gripper(gripper)
            except ArgumentError:
                self.refused += 1
                self._hold()
                raise
            lim = self.arm.limits
            outside = (q < lim.lower) | (q > lim.upper)
            clamped = tuple(name for name, out in zip(self.names, outside, strict=True) if out)
            if clamped:
                self.clamped += len(clamped)
                for name in clamped:
                    if name not in self._warned:
                        self._warned.add(name)
                        i = self.names.index(name)
                        self.log(f"akarm stream: a target of joint {name} ({q[i]:+.3f} rad) is past its range "
                                 f"[{lim.lower[i]:+.3f}, {lim.upper[i]:+.3f}] rad: taken to its edge (counted; "
                                 "said once per joint)")
                q = np.clip(q, lim.lower, lim.upper)
            if width is not None:
                width, outside_stroke = self._clamp_gripper(width)
                if outside_stroke:
                    self.clamped += 1
                    clamped = (*clamped, str(self.arm.gripper.name))  # type: ignore[union-attr]
            now = self.arm.clock.now()
            goal = q
            if self.lead and self._previous is not None and self._last is not None and now - self._last > 0.0:
                velocity = np.clip((q - self._previous) / (now - self._last), -self._limits.velocity,
                                   self._limits.velocity)
                goal = np.clip(q + stopping_distance(velocity, self._limits), lim.lower, lim.upper)
            self._previous = q
            self.arm.stream_to(goal, self.speed, synchronize=False)
            grip = self.arm.gripper
            if width is not None and grip is not None:  # (a width without a gripper was refused above)
                grip.move_to(width, wait=False)
            self._last = now
            self.sent += 1
            return StreamReport(tuple(float(x) for x in q), clamped, self.clamped, self.timeouts, width)

    def _hold(self) -> None:
        """Bring the arm to rest (jerk-limited) where it is going, and hold; the stream waits for a target."""
        self._last = None
        self._previous = None
        if self.arm.enabled and self.arm.moving:
            self.arm.stop(wait=False)

    def check(self) -> bool:
        """If the last target is older than :attr:`timeout`: bring the arm to a hold (jerk-limited) and
        return True (once per silence); else False. The server calls it every few ms."""
        with self._lock:
            last = self._last
            if last is None or self.arm.clock.now() - last < self.timeout:
                return False
            self.timeouts += 1
            moving = self.arm.enabled and self.arm.moving
            self._hold()
        if moving:
            self.log(f"akarm stream: no target for {self.timeout:g} s: the arm decelerates to a hold "
                     "(the next target resumes it)")
        return True
