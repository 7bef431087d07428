"""The simulated camera's renderer: a process of its own (``python -m lerobot_camera_akarm.render``) that
reads the arm's joint positions from ``akarm serve`` (its control socket) at ``fps`` and draws the arm as
capsules (from the URDF's joint origins to the tool frame) into a frame file the camera maps.

Imports neither LeRobot nor torch, and runs in neither LeRobot's process nor the server's: drawing
takes nothing from the arm's control loop.

The frame file: a 16-byte header (``seq`` uint64, ``t`` float64, written after the pixels) then
``height × width × 3`` RGB bytes.
"""

from __future__ import annotations

import argparse
import mmap
import struct
import sys
import time
from pathlib import Path

import numpy as np

HEADER = struct.Struct("<Qd")

__all__ = ["HEADER", "Capsules", "main"]


class Capsules:
    """Draws ``robot_file``'s arm at ``q`` as capsules, seen from the side (the base frame's -y axis, a
    little from above), orthographic, fitted to the arm's reach."""

    def __init__(self, robot_file: str, width: int, height: int) -> None:
        import akarm
        from akarm.dynamics.model import RobotModel

        self.model = RobotModel(akarm.load_robot(robot_file))
        self.names = self.model.joint_names
        self.width, self.height = width, height
        view = np.array([0.25, -1.0, 0.35])
        view /= np.linalg.norm(view)
        right = np.cross(view, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, view)
        self.axes = np.stack([right, up])
        zero = self.points(np.zeros(len(self.names)))
        reach = float(np.sum(np.linalg.norm(np.diff(zero, axis=0), axis=1))) or 0.5
        self.scale = 0.45 * min(width, height) / reach  # px per m
        self.centre = np.array([width / 2.0, height / 2.0])
        self.radius = max(1.5, 0.04 * min(width, height))
        yy, xx = np.mgrid[0:height, 0:width]
        self.pixels = np.stack([xx, yy], axis=-1).astype(np.float32) + 0.5
        shade = np.linspace(70, 30, height, dtype=np.float32)[:, None, None]
        self.background = np.broadcast_to(shade * np.array([1.0, 1.1, 1.3], np.float32), (height, width, 3)).copy()

    def points(self, q: np.ndarray) -> np.ndarray:
        """The base, each joint's origin and the tool frame, m (base frame)."""
        joints = [self.model.frame_pose(q, n)[:3, 3] for n in self.names]
        return np.array([np.zeros(3), *joints, self.model.tool_pose(q)[:3, 3]])

    def draw(self, q: np.ndarray) -> np.ndarray:
        """An RGB frame (height × width × 3, uint8) of the arm at ``q`` (rad)."""
        p = self.points(q) @ self.axes.T * self.scale
        p = self.centre + p * np.array([1.0, -1.0])  # image y points down
        img = self.background.copy()
        colours = [(230, 120, 40), (60, 170, 230), (120, 220, 90), (230, 210, 60), (200, 90, 200), (240, 240, 240)]
        for k in range(len(p) - 1):
            a, b = p[k].astype(np.float32), p[k + 1].astype(np.float32)
            ab = b - a
            t = np.clip(((self.pixels - a) @ ab) / max(float(ab @ ab), 1e-9), 0.0, 1.0)
            d = np.linalg.norm(self.pixels - (a + t[..., None] * ab), axis=-1)
            inside = np.clip(self.radius + 0.5 - d, 0.0, 1.0)[..., None]  # antialiased edge
            img = img * (1.0 - inside) + inside * np.array(colours[k % len(colours)], np.float32)
        return img.clip(0, 255).astype(np.uint8)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lerobot_camera_akarm.render")
    ap.add_argument("robot_file")
    ap.add_argument("frames", help="the frame file to write (the camera made it)")
    ap.add_argument("--width", type=int, required=True)
    ap.add_argument("--height", type=int, required=True)
    ap.add_argument("--fps", type=float, required=True)
    ap.add_argument("-i", "--interface")
    ap.add_argument("-c", "--channel")
    ap.add_argument("--parent", type=int, default=0, help="exit when this process is gone")
    args = ap.parse_args(argv)

    import os

    import akarm
    from akarm.buses.ownership import find_server
    from akarm.errors import AkarmError
    from akarm.server.socket import SocketClient

    config = akarm.load_robot(args.robot_file)
    if args.interface or args.channel:
        config = config.with_bus(interface=args.interface, channel=args.channel)
    painter = Capsules(args.robot_file, args.width, args.height)
    size = HEADER.size + args.width * args.height * 3
    with open(args.frames, "r+b") as f:
        buf = mmap.mmap(f.fileno(), size)
    client = None
    seq = 0
    period = 1.0 / args.fps
    next_t = time.monotonic()
    while True:
        if args.parent and not Path(f"/proc/{args.parent}").exists() and os.getppid() != args.parent:
            return 0
        try:
            if client is None:
                info = find_server(config, wait=0.2)
                if not info or not info.get("socket"):
                    time.sleep(0.1)
                    continue
                client = SocketClient(info["socket"], timeout=5.0)
            q = np.array(client.call("state", read=False)["q"], dtype=float)
        except (AkarmError, OSError, KeyError):
            if client is not None:
                client.close()
            client = None
            time.sleep(0.1)
            continue
        frame = painter.draw(q)
        buf[HEADER.size:size] = frame.tobytes()
        seq += 1
        buf[:HEADER.size] = HEADER.pack(seq, time.time())
        next_t += period
        delay = next_t - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:
            next_t = time.monotonic()


if __name__ == "__main__":
    sys.exit(main())
