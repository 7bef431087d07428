"""``--teleop.type=akarm_leader``: an akarm leader arm in teach mode."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.teleoperators.config import TeleoperatorConfig


@TeleoperatorConfig.register_subclass("akarm_leader")
@dataclass
class AkarmLeaderConfig(TeleoperatorConfig):
    """The leader arm (positions rad, a gripper's width m).

    Attributes:
        robot_file, interface, channel, profile, start_server: as ``--robot.type=akarm``'s.
        damping: teach mode's damping, N·m·s/rad (as ``akarm teleop --damping``).
        joint_names: the follower's joint names, in the leader's joint order, when they differ (the
            action's keys are ``<follower joint>.pos``); default: the leader's own names.
    """

    robot_file: str = ""
    interface: str | None = None
    channel: str | None = None
    profile: str = "normal"
    stall_limit: float | None = None
    start_server: bool = True
    damping: float = 0.1
    joint_names: list[str] = field(default_factory=list)
