"""How a controller runs: one immutable record of the :class:`~akarm.Arm`'s keyword arguments that
are the controller's, checked when it is made.

The Arm builds it from its keywords (see :class:`~akarm.Arm` for what each means); the
:class:`~akarm.control.controller.Controller` is built complete from it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from os import PathLike
from typing import TYPE_CHECKING

from akarm.control.collision import DEFAULT_GAIN, Reaction
from akarm.control.feedforward import FeedForwardKind
from akarm.errors import ArgumentError
from akarm.timing import TimingProfile, get_profile

if TYPE_CHECKING:
    from akarm.dynamics.selfcollision import SelfCollision

__all__ = ["MAX_PHASE", "ControllerOptions"]

#: s, the longest a stop may damp before its exit frames, or an enable ramp up its gains.
MAX_PHASE = 10.0


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class ControllerOptions:
    """The controller's settings (times in s, speeds in rad/s; see :class:`~akarm.Arm`).

    ``feedback_timeout`` ``None`` takes the timing profile's; :attr:`watchdog` is the one in force.
    ``stall_limit`` ``None`` takes the timing profile's; :attr:`loop_stall_limit` is the one in force.
    ``position_file``: the state file where the joints' positions are remembered when the arm stops
    and compared at the next enable (:mod:`akarm.control.turns`); ``None``: nothing is remembered.
    ``self_collision``: the planner's self-collision check; the supervisor checks the measured pose with a
    copy of its own (:mod:`akarm.control.selfcollision`); ``None``: no check.

    Raises:
        ArgumentError: a value of the wrong kind or out of its range (names it).
    """

    timing: TimingProfile = field(default_factory=lambda: get_profile(None))
    feedforward: FeedForwardKind = "full"
    friction_feedforward: bool = True
    hold_integral: float = 3.0
    feedback_timeout: float | None = None
    stall_limit: float | None = None
    enable_ramp: float = 0.3
    stop_damping_time: float = 0.3
    settle_speed: float = 0.1
    settle_timeout: float = 3.0
    implausible_limit: int = 3
    telemetry_seconds: float = 60.0
    can_log: str | PathLike[str] | None = None
    realtime_priority: bool = False
    loop_cpu: int | None = None
    collision_reaction: Reaction = "disable"
    collision_gain: float = DEFAULT_GAIN
    position_file: str | PathLike[str] | None = None
    self_collision: SelfCollision | None = None

    def __post_init__(self) -> None:
        if self.feedforward not in ("full", "gravity", "none"):
            raise ArgumentError(f"feedforward must be 'full', 'gravity' or 'none', got {self.feedforward!r}")
        if self.collision_reaction not in ("disable", "hold"):
            raise ArgumentError(f"collision_reaction must be 'disable' or 'hold', got {self.collision_reaction!r}")
        positive = [("settle_speed", self.settle_speed), ("settle_timeout", self.settle_timeout),
                    ("telemetry_seconds", self.telemetry_seconds), ("collision_gain", self.collision_gain)]
        if self.feedback_timeout is not None:
            positive.insert(0, ("feedback_timeout", self.feedback_timeout))
        if self.stall_limit is not None:
            positive.insert(0, ("stall_limit", self.stall_limit))
        for name, value in positive:
            if not (_number(value) and value > 0):
                raise ArgumentError(f"{name} must be a positive number, got {value!r}")
        # (a stop that damps for ever never sends its exit frames: the motors stay powered)
        for name, value, top in (("enable_ramp", self.enable_ramp, MAX_PHASE),
                                 ("stop_damping_time", self.stop_damping_time, MAX_PHASE),
                                 ("hold_integral", self.hold_integral, math.inf)):
            if not (_number(value) and 0 <= value <= top):
                raise ArgumentError(f"{name} must be a finite number, at least 0" +
                                    (f" and at most {top:g} s" if top < math.inf else "") + f", got {value!r}",
                                    fix=f"leave it at its default, {getattr(ControllerOptions, name):g}")
        if not (isinstance(self.implausible_limit, int) and self.implausible_limit >= 1):
            raise ArgumentError(f"implausible_limit must be a whole number, at least 1, got {self.implausible_limit!r}")
        cpus = os.cpu_count() or 1
        if self.loop_cpu is not None and not (isinstance(self.loop_cpu, int) and not isinstance(self.loop_cpu, bool)
                                              and 0 <= self.loop_cpu < cpus):
            raise ArgumentError(f"loop_cpu must be a CPU number (0-{cpus - 1} here) or None, got {self.loop_cpu!r}",
                                fix="pick a core the rest of the system leaves alone")

    @property
    def watchdog(self) -> float:
        """The feedback timeout in force, s: the given one (else the profile's), at least the
        profile's ``min_feedback_timeout``."""
        given = self.timing.feedback_timeout if self.feedback_timeout is None else self.feedback_timeout
        return max(given, self.timing.min_feedback_timeout)

    @property
    def loop_stall_limit(self) -> float:
        """The stall limit in force, s: the given one, else the profile's."""
        return self.timing.stall_limit if self.stall_limit is None else float(self.stall_limit)

    @property
    def friction_compensated(self) -> bool:
        """Whether the feed-forward carries each joint's friction."""
        return self.friction_feedforward and self.feedforward != "none"
