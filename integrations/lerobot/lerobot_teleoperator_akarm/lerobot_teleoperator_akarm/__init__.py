"""An akarm leader arm as a LeRobot teleoperator (``--teleop.type=akarm_leader``); see docs/lerobot.md."""

from .akarm_leader import AkarmLeader
from .config_akarm_leader import AkarmLeaderConfig

__all__ = ["AkarmLeader", "AkarmLeaderConfig"]
