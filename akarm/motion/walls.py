"""Planned paths checked against the robot file's walls (``workspace:``, :mod:`akarm.config.workspace`).

:func:`check_path` samples a plan every :data:`WALL_STEP` s (at most :data:`MAX_WALL_SAMPLES` samples),
puts the tool frame where each sample puts it, and refuses the plan with a
:class:`~akarm.LimitError` when the tool leaves the walls: before anything moves. A path that starts
outside (an arm enabled where it was pushed) may go back in, never further out.
"""

from __future__ import annotations

import math

import numpy as np

from akarm.config.workspace import Workspace
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError
from akarm.motion.trajectory import Timed

__all__ = ["MAX_WALL_SAMPLES", "WALL_STEP", "WALL_TOLERANCE", "check_path", "path_samples"]

#: s between the samples of a plan checked against the walls (the tool moves < 1 m/s: < 5 mm between)
WALL_STEP = 0.005
#: samples of one plan checked at most (a long recording is checked coarser: 20000 FK take ~0.2 s)
MAX_WALL_SAMPLES = 20000
#: m a path may touch past a wall (rounding)
WALL_TOLERANCE = 1e-6


def path_samples(plan: Timed, step: float = 0.01, most: int = 5000) -> list[tuple[float, np.ndarray]]:
    """``(t, q)``: ``plan``'s joint positions every ``step`` s from its start (at most ``most`` of them,
    the ends included); none for a live stream (servoing checks itself every cycle)."""
    if not math.isfinite(plan.duration):
        return []
    n = min(most, max(2, math.ceil(plan.duration / step) + 1))
    return [(float(t) - plan.t0, np.asarray(plan.sample(float(t))[0])) for t in np.linspace(plan.t0, plan.t_end, n)]


def check_path(model: RobotModel, walls: Workspace, plan: Timed) -> None:
    """Refuse ``plan`` (:class:`~akarm.LimitError`) if the tool frame leaves ``walls`` on it: further out than
    it starts. ``model``: a model of the caller's (not the control loop's)."""
    duration = plan.duration
    if not math.isfinite(duration):
        return  # a live stream (servoing) keeps to the walls cycle by cycle
    n = min(MAX_WALL_SAMPLES, max(2, math.ceil(duration / WALL_STEP) + 1))
    times = np.linspace(plan.t0, plan.t_end, n)
    start = walls.outside(model.tool_pose(plan.sample(plan.t0)[0])[:3, 3])
    for t in times:
        q = plan.sample(float(t))[0]
        p = model.tool_pose(q)[:3, 3]
        out = walls.outside(p)
        if out > start + WALL_TOLERANCE:
            raise LimitError(f"the planned path takes the tool {out * 1e3:.1f} mm outside the workspace "
                             f"({walls.describe()}) at [{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}] m, "
                             f"{float(t) - plan.t0:.2f} s into the move; nothing moved",
                             fix="choose a target (and a path) inside the workspace, or widen `workspace:` in the "
                                 "robot file")
