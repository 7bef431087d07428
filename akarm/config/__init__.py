"""The description of an arm: validated, immutable types, and what they are read from.

- :mod:`akarm.config.types`: :class:`RobotConfig`, :class:`JointConfig`, :class:`BusConfig` and
  their parts (re-exported here).
- :mod:`akarm.config.urdf`: the URDF's own joints and links, with their lines.
- :mod:`akarm.config.canconfig`: a bus completed from python-can's own configuration.
- :mod:`akarm.config.busload`: how much of a bus's bandwidth a robot's frames take.

Reading a robot file (YAML → :class:`RobotConfig`) is :mod:`akarm.robotfile`, a layer above.
"""

from __future__ import annotations

from akarm.config.types import (
    DEFAULT_FORCE_FRACTION,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    BusConfig,
    Firmware,
    Friction,
    Gains,
    GripperConfig,
    JointConfig,
    Limits,
    Mode,
    Payload,
    RobotConfig,
    SelfCollisionConfig,
    parse_channel,
)

__all__ = [
    "DEFAULT_FORCE_FRACTION",
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "BusConfig",
    "Firmware",
    "Friction",
    "Gains",
    "GripperConfig",
    "JointConfig",
    "Limits",
    "Mode",
    "Payload",
    "RobotConfig",
    "SelfCollisionConfig",
    "parse_channel",
]
