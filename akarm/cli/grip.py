"""``akarm grip ROBOT.yaml open|close|WIDTH [--force N]``: open, close or move the gripper's jaws.

::

    akarm grip robots/arm6g.yaml open                  # fully open
    akarm grip robots/arm6g.yaml close --force 15      # close; on an object, hold it at 15 N
    akarm grip robots/arm6g.yaml 0.03                  # 30 mm apart (metres, as everywhere)
    akarm grip robots/arm6g.yaml close --seconds 5     # hold what it grasped 5 s, then disable

WIDTH is in metres, within 0..stroke; the force in newtons, 0..the gripper's ``force_limit``
(default: half of it). Anything else is refused before the arm is enabled. Without ``akarm serve``
the arm is enabled for the command and disabled after it (``--seconds`` first holds that long): a
disabled gripper's motor is limp, so what it held is free again. While ``akarm serve`` drives the
robot the server moves the jaws and keeps holding.

Exit status 0 when the jaws reached the width or grasped something, 1 on an error.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from akarm.cli.common import (
    add_profile_argument,
    add_robot_arguments,
    controlled,
    deferred_signals,
    interrupted,
    load_from_args,
    loop_options,
    stop_smoothly,
)

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm
    from akarm.config import GripperConfig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import delay

    add_robot_arguments(parser)
    parser.add_argument("what", metavar="open|close|WIDTH", help="open, close, or a width in metres")
    parser.add_argument("--force", type=float, metavar="N",
                        help="the most the jaws press with, N (default: half the gripper's force_limit)")
    parser.add_argument("--seconds", type=delay, metavar="S",
                        help="hold S seconds before disabling (without akarm serve)")
    add_profile_argument(parser)


def target(config: GripperConfig, what: str, force: float | None) -> tuple[float, float]:
    """The width (m) and force (N) asked, checked; :class:`~akarm.ArgumentError` otherwise."""
    from akarm.errors import ArgumentError

    if what == "open":
        width = config.stroke
    elif what == "close":
        width = 0.0
    else:
        try:
            width = float(what)
        except ValueError:
            raise ArgumentError(f"{what!r} is not open, close or a width in metres", joint=config.name,
                                fix=f"e.g. akarm grip ROBOT.yaml 0.03 (0..{config.stroke:g} m)") from None
    return config.check_width(width), config.check_force(force)


def describe(doc: dict[str, Any]) -> str:
    """One line: the state of the gripper (a :class:`~akarm.GripperState` as a dict)."""
    def mm(x: float | None) -> str:
        return "?" if x is None else f"{x * 1e3:.1f} mm"

    what = "grasped" if doc["grasped"] else "moving" if doc["moving"] else "at its target"
    force = "?" if doc["force"] is None else f"{doc['force']:.1f} N"
    temp = "?" if doc["temperature"] is None else f"{doc['temperature']:.1f} °C"
    return f"width {mm(doc['width'])} (asked {mm(doc['target'])}), {what}, force {force}, motor {temp}"


def _gripper_config(args: argparse.Namespace) -> GripperConfig:
    from akarm.errors import ConfigError, ConfigProblem

    config = args.config = load_from_args(args)
    if config.gripper is None:
        raise ConfigError([ConfigProblem(str(config.source or config.name), None, f"robot {config.name!r} has no "
                                         "gripper", "describe one under `gripper:` (docs/gripper.md)")])
    return config.gripper


def run(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:
        return served
    gconf = _gripper_config(args)
    width, force = target(gconf, args.what, args.force)
    config = args.config
    with controlled(config, **loop_options(args)) as arm:
        assert arm.gripper is not None
        try:
            arm.enable()
            state = arm.gripper.move_to(width, force)
            print(f"gripper {gconf.name!r}: " + describe(asdict(state)), flush=True)
            if args.seconds is not None:
                arm.sleep(args.seconds)
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            print("interrupted: the arm is disabled", file=sys.stderr)
            return interrupted(e)
        with deferred_signals():
            arm.disable()
        print("disabled (the gripper's motor is limp)")
    return 0


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    gconf = _gripper_config(args)
    width, force = target(gconf, args.what, args.force)
    arm.call("ready")
    doc = arm.call("gripper_move", width=width, force=force, wait=True)
    print(f"gripper {gconf.name!r}: " + describe(doc) + f"; {arm.held}", flush=True)
    return 0
