"""``type: akarm_sim``: a camera that draws the arm akarm serve drives (akarm.sim.camera's painter)."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.cameras.configs import CameraConfig


@CameraConfig.register_subclass("akarm_sim")
@dataclass
class AkarmSimConfig(CameraConfig):
    """LeRobot's ``width``, ``height`` (pixels, even) and ``fps``; ``robot_file``, ``interface``, ``channel``:
    the arm it draws (the one an ``akarm serve`` drives: the robot's own server); ``control``: the
    simulator's control socket (``akarm sim --control PATH``), to draw the object between the jaws."""

    robot_file: str = ""
    interface: str | None = None
    channel: str | None = None
    control: str | None = None
    fps: int | None = 30
    width: int | None = 96
    height: int | None = 96
