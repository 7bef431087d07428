"""Robot files: reading a robot YAML into a :class:`~akarm.config.RobotConfig`, writing into one.

- :mod:`akarm.robotfile.load`: :func:`load_robot` (every problem at once, with its line and fix).
- :mod:`akarm.robotfile.save`: results (identification, ...) written into a robot YAML with a backup.
- :mod:`akarm.robotfile.starter`: a commented starting robot YAML for a URDF (``akarm init``).
"""

from __future__ import annotations

from akarm.robotfile.load import load_robot

__all__ = ["load_robot"]
