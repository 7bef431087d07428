"""``akarm serve``: one long-lived controller that holds the arm (see :mod:`akarm.server.server`).

- :class:`ArmServer`, :func:`serve`: serve an :class:`~akarm.Arm` to the CLI and to ROS 2.
- :mod:`akarm.server.registry`: which server controls which bus (two controllers are refused).
- :mod:`akarm.server.control`: the local control socket the CLI uses.
"""

from .server import ArmServer, serve

__all__ = ["ArmServer", "serve"]
