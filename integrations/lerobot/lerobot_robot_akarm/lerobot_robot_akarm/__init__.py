"""akarm arms as LeRobot robots (``--robot.type=akarm``); see docs/lerobot.md."""

from .config_akarm import AkarmConfig
from .robot_akarm import Akarm

__all__ = ["Akarm", "AkarmConfig"]
