"""``akarm serve``: one long-lived controller that holds the arm (see :mod:`akarm.server.server`).

- :class:`ArmServerCore`: serve an :class:`~akarm.Arm` to the CLI and to its :class:`Frontend`
  objects (the ROS 2 node: :class:`akarm.ArmServer` in :mod:`akarm.serving` puts them together).
- :mod:`akarm.server.socket`: the local control socket the CLI uses.
- :mod:`akarm.buses.ownership` (a layer below): which server controls which bus.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akarm.server.server import ArmServerCore, Frontend, FrontendFactory

__all__ = ["ArmServerCore", "Frontend", "FrontendFactory"]


def __getattr__(name: str) -> Any:  # the CLI's client imports akarm.server.socket: that must not load the server
    if name in __all__:
        from akarm.server import server

        return getattr(server, name)
    raise AttributeError(f"module 'akarm.server' has no attribute {name!r}")
