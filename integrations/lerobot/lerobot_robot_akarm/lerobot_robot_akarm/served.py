"""An akarm arm served by ``akarm serve`` in a process of its own, as LeRobot's plugins use it.

This module imports neither LeRobot nor torch: the arm's 500 Hz loop runs in the server's process,
never in LeRobot's interpreter (whose imports, dataset and video work and inference hold it for tens of
milliseconds). :class:`ServedArm` finds the server that drives the robot's buses, or starts one
(``akarm serve ROBOT.yaml --no-ros``), and talks to it over its control socket:

- :meth:`ServedArm.state`: every joint's position (rad), velocity (rad/s) and torque (N·m); a safety
  stop the server latched is raised as the stop itself (its akarm class and text);
- :meth:`ServedArm.stream`: a target into the loop through the jerk-limited retargeting (the server's
  ``stream`` operation, :mod:`akarm.server.streaming`); a stream refused because a stop is latched
  raises the stop itself, as :meth:`ServedArm.state` does;
- :meth:`ServedArm.close`: a server it started is stopped (SIGTERM: the arm damped, then disabled);
  one that ran before is asked to hold.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from akarm.buses.ownership import find_server
from akarm.errors import AkarmError, StateError, StopLatched
from akarm.robotfile.load import load_robot
from akarm.server.socket import SocketClient, rebuild_error

__all__ = ["ServedArm", "stop_error"]

log = logging.getLogger("akarm.lerobot")


def stop_error(stop: Mapping[str, Any]) -> AkarmError:
    """The latched stop the server reports (``state``'s ``stop``) as its own akarm exception."""
    return rebuild_error({"type": stop.get("error"), "what": stop.get("what"), "joint": stop.get("joint"),
                          "fix": stop.get("fix"), "text": stop.get("text")})


class ServedArm:
    """The arm of ``robot_file`` (on ``interface``/``channel``, as the CLI's ``-i``/``-c``), served.

    Args:
        start: start ``akarm serve`` when none drives the robot's buses (else: StateError).
        profile: the server's timing profile (``normal``, ``slow``), when it is started here.
        stall_limit: s the server's loop may fail to run before it stops the arm (default: the profile's).
        start_timeout: s to wait for a server started here to hold the arm.
    """

    def __init__(self, robot_file: str | os.PathLike[str], interface: str | None = None, channel: str | None = None,
                 *, profile: str = "normal", stall_limit: float | None = None, start: bool = True,
                 start_timeout: float = 60.0) -> None:
        self.robot_file = Path(robot_file)
        self.interface, self.channel, self.profile, self.stall_limit = interface, channel, profile, stall_limit
        config = load_robot(self.robot_file)
        if interface or channel:
            config = config.with_bus(interface=interface, channel=channel)
        self.config = config
        self.names: tuple[str, ...] = tuple(config.joint_names)
        gripper = getattr(config, "gripper", None)  # the gripper issue's GripperConfig, when the robot has one
        self.gripper_name: str | None = getattr(gripper, "name", None) if gripper is not None else None
        self.process: subprocess.Popen[bytes] | None = None
        info = find_server(config)
        if info is None:
            if not start:
                raise StateError(f"no akarm serve drives {self.robot_file}", fix=f"akarm serve {self.robot_file}")
            info = self._start(start_timeout)
        if not info.get("socket"):
            raise StateError(f"another controller holds this robot's bus ({info.get('bus')})", fix="stop it first")
        self.socket = str(info["socket"])
        self.client = SocketClient(self.socket, timeout=30.0)
        # one request at a time on the connection: LeRobot's async robot_client observes and acts from
        # two threads, and each answer must go to the call that asked
        self._lock = threading.Lock()

    def _start(self, timeout: float) -> dict[str, Any]:
        cmd = [sys.executable, "-m", "akarm", "serve", str(self.robot_file), "--no-ros", "--profile", self.profile]
        if self.stall_limit is not None:
            cmd += ["--stall-limit", str(self.stall_limit)]
        if self.interface:
            cmd += ["-i", self.interface]
        if self.channel:
            cmd += ["-c", self.channel]
        log.info("starting %s", " ".join(cmd))
        self.process = subprocess.Popen(cmd, start_new_session=True)  # its own session: LeRobot's Ctrl-C is ours
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            code = self.process.poll()
            if code is not None:
                raise StateError(f"akarm serve {self.robot_file} exited ({code}) before it held the arm",
                                 fix="see its output above")
            info = find_server(self.config, wait=0.2)
            if info and info.get("socket") and info.get("pid") == self.process.pid and Path(info["socket"]).exists():
                return info
            time.sleep(0.1)
        self._end_process()
        raise StateError(f"akarm serve {self.robot_file} did not hold the arm within {timeout:g} s",
                         fix="see its output above")

    def call(self, op: str, **args: Any) -> Any:
        with self._lock:
            return self.client.call(op, **args)

    def state(self) -> dict[str, Any]:
        """The server's ``state`` (``q``, ``dq``, ``tau``, ``stop``, ...); a latched stop is raised."""
        doc = self.call("state", read=False)
        if doc.get("stop"):
            raise stop_error(doc["stop"])
        return dict(doc)

    def stream(self, target: Mapping[str, float] | Sequence[float], *, partial: bool = False,
               gripper: float | None = None, timeout: float = 0.25, speed: float = 1.0) -> dict[str, Any]:
        """Stream a target (rad; NaN sent as ``null``: refused, the arm holds); see the server's ``stream``."""
        def clean(x: float) -> float | None:
            return x if math.isfinite(x) else None

        if isinstance(target, Mapping):
            body: Any = {k: clean(float(v)) for k, v in target.items()}
        else:
            body = [clean(float(v)) for v in target]
        args: dict[str, Any] = {"target": body, "partial": partial, "timeout": timeout, "speed": speed}
        if gripper is not None:
            args["gripper"] = clean(float(gripper))
        try:
            return dict(self.call("stream", **args))
        except StopLatched as refused:
            # The stop came between two actions: the session ends with the stop itself (its class, the
            # joint and what to do), not with the refusal that names it.
            doc = self.call("state", read=False)
            if doc.get("stop"):
                raise stop_error(doc["stop"]) from refused
            raise

    def close(self) -> None:
        """Stop a server started here (the arm damped, then disabled), else leave the arm held."""
        try:
            if self.process is None:
                with contextlib.suppress(AkarmError, OSError):
                    self.call("hold")
        finally:
            self.client.close()
            self._end_process()

    def _end_process(self) -> None:
        p, self.process = self.process, None
        if p is None or p.poll() is not None:
            return
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(20.0)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(5.0)

