"""Robot files: reading a robot YAML into a :class:`~akarm.config.RobotConfig`, writing into one.

- :mod:`akarm.robotfile.load`: :func:`load_robot` (every problem at once, with its line and fix), from
  :mod:`~akarm.robotfile.nodes` (the YAML with its lines), :mod:`~akarm.robotfile.schema` (every key,
  declared once) and :mod:`~akarm.robotfile.checks` (what depends on the URDF, the motors, the bus).
- :mod:`akarm.robotfile.reference`: ``docs/robot-file.md``, written from the schema.
- :mod:`akarm.robotfile.save`: results (identification, ...) written into a robot YAML with a backup.
- :mod:`akarm.robotfile.starter`: a commented starting robot YAML for a URDF (``akarm init``).
"""

from __future__ import annotations

from akarm.robotfile.load import load_robot

__all__ = ["load_robot"]
