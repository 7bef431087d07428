"""The simulated camera's renderer: a process of its own (``python -m lerobot_camera_akarm.render``) that
reads the arm's joint positions and gripper width from ``akarm serve`` (its control socket) at ``fps``
and draws them with akarm's own painter (:class:`akarm.sim.camera.ArmPainter`: the URDF's primitive
visuals, the jaws, the object between them) into a frame file (:class:`akarm.sim.camera.FrameFile`)
the camera maps. ``akarm teleop --record --camera`` draws with the same painter.

Imports neither LeRobot nor torch, and runs in neither LeRobot's process nor the server's: drawing
takes nothing from the arm's control loop.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lerobot_camera_akarm.render")
    ap.add_argument("robot_file")
    ap.add_argument("frames", help="the frame file to write (the camera made it)")
    ap.add_argument("--width", type=int, required=True)
    ap.add_argument("--height", type=int, required=True)
    ap.add_argument("--fps", type=float, required=True)
    ap.add_argument("-i", "--interface")
    ap.add_argument("-c", "--channel")
    ap.add_argument("--control", help="the simulator's control socket: the object between the jaws is drawn")
    ap.add_argument("--parent", type=int, default=0, help="exit when this process is gone")
    args = ap.parse_args(argv)

    import akarm
    from akarm.buses.ownership import find_server
    from akarm.errors import AkarmError
    from akarm.server.socket import SocketClient
    from akarm.sim.camera import ArmPainter, FrameFile, Pose, object_reader, parent_alive, run

    config = akarm.load_robot(args.robot_file)
    if args.interface or args.channel:
        config = config.with_bus(interface=args.interface, channel=args.channel)
    painter = ArmPainter(config, args.width, args.height)
    frames = FrameFile(args.frames, args.width, args.height)
    obj = object_reader(args.control)
    client: list[SocketClient] = []

    def pose() -> Pose | None:
        try:
            if not client:
                info = find_server(config, wait=0.2)
                if not info or not info.get("socket"):
                    time.sleep(0.1)
                    return None
                client.append(SocketClient(info["socket"], timeout=5.0))
            doc = client[0].call("state", read=False)
        except (AkarmError, OSError, KeyError):
            if client:
                client.pop().close()
            time.sleep(0.1)
            return None
        g = doc.get("gripper") or {}
        width = math.nan if g.get("width") is None else float(g["width"])
        return Pose(np.array(doc["q"], dtype=float), width, obj())

    try:
        run(painter, frames, args.fps, pose, parent_alive(args.parent))
    finally:
        frames.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
