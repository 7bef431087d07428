"""``AkarmSim``: a LeRobot camera that draws the arm (:mod:`.render`, in a process of its own)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from typing import Any

import numpy as np
from lerobot.cameras.camera import Camera

from .config_akarm_sim import AkarmSimConfig

__all__ = ["AkarmSim"]


class AkarmSim(Camera):
    """Frames ``(height, width, 3)`` RGB uint8 of the arm akarm serve drives, drawn at ``fps``."""

    def __init__(self, config: AkarmSimConfig) -> None:
        super().__init__(config)
        self.config = config
        if not config.robot_file:
            raise ValueError("an akarm_sim camera needs robot_file: the arm it draws")
        self.process: subprocess.Popen[bytes] | None = None
        self.path: str | None = None
        self._map: Any = None
        self._seen = 0

    @property
    def is_connected(self) -> bool:
        return self.process is not None and self.process.poll() is None

    @staticmethod
    def find_cameras() -> list[dict[str, Any]]:
        return []

    def connect(self, warmup: bool = True) -> None:
        from akarm.sim.camera import FrameFile

        c = self.config
        self._map = FrameFile.create(c.width, c.height)
        self.path = str(self._map.path)
        cmd = [sys.executable, "-m", "lerobot_camera_akarm.render", c.robot_file, self.path, "--width", str(c.width),
               "--height", str(c.height), "--fps", str(c.fps), "--parent", str(os.getpid())]
        if c.interface:
            cmd += ["-i", c.interface]
        if c.channel:
            cmd += ["-c", c.channel]
        if c.control:
            cmd += ["--control", c.control]
        self.process = subprocess.Popen(cmd, start_new_session=True)
        if warmup:
            self.read()

    def _latest(self) -> tuple[int, np.ndarray | None]:
        return self._map.latest()

    def read(self, color_mode: Any = None) -> np.ndarray:
        return self.async_read(timeout_ms=30000)

    def async_read(self, timeout_ms: float = 200) -> np.ndarray:
        """The newest frame not returned before, waiting for it at most ``timeout_ms`` (then the newest)."""
        if not self.is_connected:
            raise RuntimeError(f"{self} is not connected (its renderer is not running)")
        end = time.monotonic() + timeout_ms / 1000.0
        while True:
            seq, frame = self._latest()
            if frame is not None and (seq != self._seen or time.monotonic() >= end):
                self._seen = seq
                return frame
            if time.monotonic() >= end:
                raise TimeoutError(f"{self}: no frame within {timeout_ms} ms")
            time.sleep(0.002)

    def disconnect(self) -> None:
        p, self.process = self.process, None
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(5.0)
            except subprocess.TimeoutExpired:
                p.kill()
        if self._map is not None:
            self._map.close()  # (its file removed: it was made here)
            self._map = None
        self.path = None
