"""``--robot.type=akarm``: the configuration of an akarm arm as a LeRobot robot."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.cameras import CameraConfig
from lerobot.robots.config import RobotConfig


@RobotConfig.register_subclass("akarm")
@dataclass
class AkarmConfig(RobotConfig):
    """An akarm arm. Units are SI: positions rad (a gripper's width m), velocities rad/s, torques N·m.

    Attributes:
        robot_file: the robot's YAML file (akarm's robot file).
        interface, channel: the bus, as the akarm CLI's ``-i`` and ``-c`` (default: the robot file's).
        cameras: LeRobot cameras (``opencv``, ``intelrealsense``, ``akarm_sim``).
        profile, stall_limit: akarm serve's timing profile (``normal``; ``slow`` on a VM) and stall limit
            (s), for a server started here.
        stream_timeout: s without an action after which the arm decelerates to a hold.
        speed: the fraction of the joints' velocity, acceleration and jerk limits actions may use.
        strict_actions: refuse an action that names only some joints (default: the others keep their target).
        start_server: start ``akarm serve`` when none drives the robot (it is stopped at disconnect).
        effort: observe ``<joint>.effort`` (and ``gripper.effort``). LeRobot 0.6's ``lerobot-rollout``
            gives a policy only the ``.pos`` and ``.vel`` features as its state, so a policy to be rolled
            out there must be recorded (and rolled out) with ``effort=false``.
    """

    robot_file: str = ""
    interface: str | None = None
    channel: str | None = None
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    profile: str = "normal"
    stall_limit: float | None = None
    stream_timeout: float = 0.25
    speed: float = 1.0
    strict_actions: bool = False
    start_server: bool = True
    effort: bool = True
