"""The supervisor's wall check: the tool measured outside the robot file's ``workspace:``.

Every cycle of an active arm, :class:`WallGuard` puts the tool frame where the *measured* joint
positions put it; outside the workspace by more than its margin (and further out than the command,
which the planner and servoing keep inside: an arm enabled outside may move back in) is a
:class:`~akarm.WorkspaceExit` safety stop.
"""

from __future__ import annotations

from collections.abc import Sequence

from akarm.config.workspace import Workspace
from akarm.dynamics.model import RobotModel
from akarm.errors import WorkspaceExit

__all__ = ["WallGuard"]


class WallGuard:
    """The wall check of one arm (loop thread: ``model`` is the loop's)."""

    def __init__(self, model: RobotModel, walls: Workspace) -> None:
        self.model = model
        self.walls = walls
        self.worst = 0.0  # m: the furthest outside the tool was measured (past the command's)

    def check(self, now: float, q: Sequence[float], q_des: Sequence[float]) -> WorkspaceExit | None:
        walls = self.walls
        p = self.model.tool_pose(q)[:3, 3]
        out = walls.outside(p)
        if out <= walls.margin:
            return None
        past = out - walls.outside(self.model.tool_pose(q_des)[:3, 3])
        self.worst = max(self.worst, past)
        if past <= walls.margin:
            return None
        stop = WorkspaceExit(
            f"the tool was measured {out * 1e3:.0f} mm outside the workspace ({walls.describe()}), more than its "
            f"margin of {walls.margin * 1e3:.0f} mm, at [{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}] m: pushed out, or far "
            "behind its command; the arm was damped and disabled",
            distance=out, margin=walls.margin, position=(float(p[0]), float(p[1]), float(p[2])),
            fix="find what pushed the arm (or what it hit), enable it again and move it back inside; widen "
                "`workspace:` or its `margin` if the walls are too tight")
        stop.at = now
        return stop
