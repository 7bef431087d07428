"""The ROS 2 node's commands for the server, in order, each run when the server's command lock is free.

An enable or a disable (the ``akarm/enable`` and ``akarm/disable`` services, ``akarm enable``) holds
the server's command lock for as long as it takes: 0.3 s on the simulator, longer on motors. The
node's one thread publishes ``joint_states`` and checks the running goal's tolerances: it must never
wait for that lock. So the goals' starts, the topic's messages and the stops the action makes wait
here, in the order they came, and each runs when :meth:`ArmServerCore.try_command
<akarm.server.server.ArmServerCore.try_command>` finds the lock free (the node tries again every few
ms). What waits is bounded (:data:`MAX_WAITING`, :data:`MAX_WAITING_POINTS`): past it, a command is
refused.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

from akarm.errors import StateError
from akarm.motion.bounds import MAX_TRAJECTORY_POINTS

if TYPE_CHECKING:
    from akarm.server.server import ArmServerCore

__all__ = ["MAX_WAITING", "MAX_WAITING_POINTS", "RETRY", "CommandQueue"]

#: commands that may wait for the server at once
MAX_WAITING = 64
#: trajectory points that may wait for the server at once (a decoded point is some hundred bytes)
MAX_WAITING_POINTS = 2 * MAX_TRAJECTORY_POINTS
#: s between two tries while commands wait
RETRY = 0.005


class CommandQueue:
    """Commands (callables that report their own refusals) for ``server``, run in order, each while
    this thread holds the server's command lock, without ever waiting for it."""

    def __init__(self, server: ArmServerCore) -> None:
        self.server = server
        self._queue: deque[tuple[Callable[[], None], int]] = deque()
        self._points = 0

    def __len__(self) -> int:
        return len(self._queue)

    def add(self, command: Callable[[], None], points: int = 0, *, always: bool = False) -> None:
        """Run ``command`` (of ``points`` trajectory points) after those waiting: now, if the server is free.
        ``always``: past the bounds too (a stop: never refused).

        Raises:
            StateError: too much waits already (nothing was queued).
        """
        full = len(self._queue) >= MAX_WAITING or (self._queue and self._points + points > MAX_WAITING_POINTS)
        if full and not always:
            raise StateError(f"the server is busy (an enable or a disable runs): {len(self._queue)} commands of "
                             f"{self._points} points wait for it already",
                             fix="wait for the enable or disable to end before sending more")
        self._queue.append((command, points))
        self._points += points
        self.run()

    def run(self) -> None:
        """Run the commands waiting, in order, as long as the server's command lock is free."""
        while self._queue:
            with self.server.try_command() as free:
                if not free:
                    return
                command, points = self._queue.popleft()
                self._points -= points
                command()
