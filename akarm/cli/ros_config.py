"""``akarm ros-config ROBOT.yaml``: what a MoveIt 2 setup needs to drive ``akarm serve`` for this robot.

::

    akarm ros-config robots/arm6.yaml                       # print the three files, one YAML document each
    akarm ros-config robots/arm6.yaml --out moveit/arm6     # write them there
    akarm ros-config robots/arm6.yaml --namespace arm6      # for akarm serve ... --namespace arm6

``moveit_controllers.yaml`` (MoveItSimpleControllerManager, the controller, its ``action_ns`` and
joints), ``joint_limits.yaml`` (each joint's range, velocity, acceleration and jerk from the robot
file) and ``akarm_ros.yaml`` (the URDF, the action and ``joint_states`` topic, the remaps for a
server in a namespace). ``docs/ros2.md`` walks through MoveIt with them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import BinaryIO


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments (the bus overrides too, as every robot verb takes them; they change nothing here)."""
    from akarm.cli.common import add_robot_arguments

    add_robot_arguments(parser)
    parser.add_argument("--out", metavar="DIR", help="write the files into DIR (default: print them)")
    parser.add_argument("--namespace", default="", metavar="NS", help="akarm serve's --namespace (default none)")
    parser.add_argument("--controller", default="arm_controller", metavar="NAME",
                        help="akarm serve's --controller (default arm_controller)")


def writes(data: bytes) -> Callable[[BinaryIO], object]:
    """What writes ``data`` into a file (for :func:`akarm.files.atomic_write`)."""
    return lambda f: f.write(data)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from akarm.cli.common import load_from_args
    from akarm.files import atomic_write
    from akarm.ros.action import action_name
    from akarm.ros.dds import ros_name
    from akarm.ros.moveit import moveit_config

    ros_name(args.namespace, action_name(args.controller))  # names ROS 2 takes, or a clear error
    files = moveit_config(load_from_args(args), namespace=args.namespace, controller=args.controller)
    if args.out is None:
        print("\n---\n".join(f"# {name}\n{text}" for name, text in files.items()), end="")
        return 0
    for name, text in files.items():
        path = atomic_write(Path(args.out) / name, writes(text.encode()))
        print(f"wrote {path}", file=sys.stderr)
    return 0
