"""``akarm serve``: one long-lived controller that holds the arm (see :mod:`akarm.server.server`).

- :class:`ArmServer`, :func:`serve`: serve an :class:`~akarm.Arm` to the CLI and to ROS 2.
- :mod:`akarm.buses.ownership`: which server controls which bus (two controllers are refused).
- :mod:`akarm.server.socket`: the local control socket the CLI uses.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akarm.server.server import ArmServer, serve

__all__ = ["ArmServer", "serve"]


def __getattr__(name: str) -> Any:  # the registry is checked by every CLI verb: it must not load the server
    if name in __all__:
        from akarm.server import server

        return getattr(server, name)
    raise AttributeError(f"module 'akarm.server' has no attribute {name!r}")
