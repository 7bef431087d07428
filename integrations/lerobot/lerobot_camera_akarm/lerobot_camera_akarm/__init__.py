"""A simulated camera that draws an akarm arm (cameras ``type: akarm_sim``); see docs/lerobot.md."""

from .akarm_sim import AkarmSim
from .config_akarm_sim import AkarmSimConfig

__all__ = ["AkarmSim", "AkarmSimConfig"]
