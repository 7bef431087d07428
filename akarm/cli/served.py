"""The CLI's side of ``akarm serve``: a verb whose robot a server drives asks the server instead of opening the bus.

Each such verb calls :func:`via_server` first thing in its ``run``, with the function (of the verb's
own module) that does the verb through a :class:`RemoteArm`. It returns ``None`` when no server
drives the robot's buses (the verb then does what it always did), else that function's exit code.
Output is the verb's own, except that the arm is left held by the server instead of disabled, and
the last line says so (:attr:`RemoteArm.held`). A safety stop the server latched while the verb ran
is the verb's error, as without a server (its class and text), with a line saying that only
``akarm enable`` acknowledges it; verbs that move ask the server's ``ready`` first, which refuses
while a stop is latched (the server never re-enables an arm a stop disabled).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akarm.cli.common import load_from_args

if TYPE_CHECKING:
    from akarm.config import RobotConfig
    from akarm.motion.recording import Keyframe, PathRecording
    from akarm.server.socket import SocketClient

__all__ = ["RemoteArm", "via_server"]


class RemoteArm:
    """The part of the :class:`~akarm.Arm` API the CLI verbs use, carried out by a running server."""

    def __init__(self, config: RobotConfig, info: dict[str, Any]) -> None:
        from akarm.server.socket import SocketClient

        self.config = config
        self.names = config.joint_names
        self.info = info
        self.pid = info.get("pid")
        self.client: SocketClient = SocketClient(info["socket"])

    def call(self, op: str, **args: Any) -> Any:
        return self.client.call(op, **args)

    @property
    def held(self) -> str:
        """The last line of a verb that leaves the arm to the server."""
        return f"held by akarm serve (pid {self.pid})"

    def wait(self, motion: dict[str, Any]) -> dict[str, Any]:
        """Wait for a motion the server started (the answer of ``move`` or ``replay``) to end; the
        server's answer: ``superseded`` and the position ``q``."""
        return self.call("wait", id=motion["id"])

    def interrupt(self) -> None:
        """Bring the arm to rest (on a connection of its own: the first may be waiting for a reply)."""
        from akarm.server.socket import SocketClient

        with SocketClient(self.info["socket"], timeout=10.0) as c:
            c.call("stop")

    # what teaching uses (akarm.cli.teach), as an Arm has them
    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)
        self.call("recording_finished")  # raises the arm's safety stop, as Arm.sleep does

    @property
    def recording_finished(self) -> bool:
        return bool(self.call("recording_finished"))

    def keyframe(self, name: str | None = None) -> Keyframe:
        from akarm.motion.recording import Keyframe

        return Keyframe(tuple(self.call("keyframe", name=name)), name)

    def start_recording(self, rate_hz: float = 50.0, duration: float | None = None) -> None:
        self.call("start_recording", rate=rate_hz, seconds=duration)

    def stop_recording(self) -> PathRecording:
        import numpy as np

        from akarm.motion.recording import PathRecording

        doc = self.call("stop_recording")
        return PathRecording(tuple(doc["names"]), np.array(doc["t"]), np.array(doc["q"]))

    def close(self) -> None:
        self.client.close()


def via_server(args: argparse.Namespace, served: Callable[[RemoteArm, argparse.Namespace], int]) -> int | None:
    """``served(arm, args)`` for a :class:`RemoteArm` of the server that drives this robot's buses, and
    its exit code; ``None`` when no server drives them."""
    from akarm.buses.ownership import any_server, find_server
    from akarm.errors import SafetyStop

    if not any_server():  # the common case, decided without loading the robot
        return None
    config = load_from_args(args)
    info = find_server(config)
    if info is None:
        return None
    if not info.get("socket"):
        from akarm.errors import StateError

        raise StateError(f"another controller holds this robot's bus ({info.get('bus')})", fix="stop it first")
    arm = RemoteArm(config, info)
    try:
        return served(arm, args)
    except SafetyStop:  # the stop that ended what this verb did: latched by the server
        print(f"akarm {args.verb}: akarm serve (pid {arm.pid}) stopped the arm for safety and latched the stop: "
              f"nothing moves until `akarm enable {args.robot}` acknowledges it", file=sys.stderr)
        raise
    finally:
        arm.close()
