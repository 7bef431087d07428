"""Arguments every robot verb shares: the robot YAML and python-can style bus overrides."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..config import RobotConfig


def add_robot_arguments(parser: argparse.ArgumentParser, robot_required: bool = True) -> None:
    """Add ``ROBOT`` (the YAML) and ``-i/--interface``, ``-c/--channel``, ``-b/--bitrate``."""
    parser.add_argument("robot", metavar="ROBOT.yaml", nargs=None if robot_required else "?",
                        help="the robot's YAML configuration")
    parser.add_argument("-i", "--interface", help="python-can interface for every bus (e.g. socketcan, virtual)")
    parser.add_argument("-c", "--channel", help="channel (one bus), or NAME=CHANNEL[,NAME=CHANNEL...] per bus")
    parser.add_argument("-b", "--bitrate", type=int, help="bit rate, bit/s")


def parse_channel(text: str | None) -> str | dict[str, str] | None:
    """``vcan0`` → ``"vcan0"``; ``arm=vcan0,aux=vcan1`` → ``{"arm": "vcan0", "aux": "vcan1"}``."""
    if text is None or "=" not in text:
        return text
    return dict(part.split("=", 1) for part in text.split(","))


def load_from_args(args: argparse.Namespace) -> RobotConfig:
    """The robot config named on the command line, with its bus overrides applied."""
    from ..config_loader import load_robot

    config = load_robot(args.robot)
    if args.interface or args.channel or args.bitrate:
        config = config.with_bus(interface=args.interface, channel=parse_channel(args.channel),
                                 bitrate=args.bitrate)
    return config
