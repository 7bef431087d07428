"""``type: akarm_sim``: a camera that draws the arm akarm serve drives, as capsules."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.cameras.configs import CameraConfig


@CameraConfig.register_subclass("akarm_sim")
@dataclass
class AkarmSimConfig(CameraConfig):
    """LeRobot's ``width``, ``height`` (pixels) and ``fps``; ``robot_file``, ``interface``, ``channel``:
    the arm it draws (the one an ``akarm serve`` drives: the robot's own server)."""

    robot_file: str = ""
    interface: str | None = None
    channel: str | None = None
    fps: int | None = 30
    width: int | None = 96
    height: int | None = 96
