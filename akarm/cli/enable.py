"""``akarm enable ROBOT.yaml``: enable the arm without a kick and hold it where it is until Ctrl-C.

::

    akarm enable robots/arm6.yaml               # hold until Ctrl-C, then damp and disable
    akarm enable robots/arm6.yaml --seconds 10  # hold for 10 s
    akarm enable robots/arm6.yaml --accept-position   # after TurnCountLost: the joints were checked by eye

Exit status 0 after ``--seconds``, and after Ctrl-C without ``--seconds`` (the documented way to end
it); 130 when Ctrl-C cuts ``--seconds`` short (the arm is damped and disabled either way); 1 on an
error (a joint that does not answer, a motor fault, ...).

While ``akarm serve`` drives the robot, ``enable`` asks it instead: it acknowledges a latched safety
stop, enables (kick-free) and returns, leaving the arm **held by the server**; with ``--seconds`` it
first watches the arm that long (a safety stop meanwhile is its error, exit status 1). ``akarm
disable`` makes it limp.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from akarm.cli.common import (
    add_profile_argument,
    add_robot_arguments,
    controlled,
    deferred_signals,
    format_q,
    interrupted,
    load_from_args,
    loop_options,
    stop_smoothly,
)

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import delay

    add_robot_arguments(parser)
    parser.add_argument("--seconds", type=delay, metavar="S", help="hold for S seconds, then disable "
                        "(default: until Ctrl-C)")
    parser.add_argument("--accept-position", action="store_true",
                        help="skip the check that each joint reads where it was when the arm last stopped "
                             "(after a TurnCountLost, once you have checked by eye where the joints stand)")
    add_profile_argument(parser)


def run(args: argparse.Namespace) -> int:
    """Enable, hold until Ctrl-C or ``--seconds``, disable."""
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    from akarm.errors import ArgumentError

    if args.seconds is not None and not 0 <= args.seconds < float("inf"):
        raise ArgumentError(f"--seconds {args.seconds} must be a number of seconds, not negative")
    config = load_from_args(args)
    with controlled(config, **loop_options(args)) as arm:
        try:
            arm.enable(accept_position=args.accept_position)
            until = f"for {args.seconds:g} s" if args.seconds is not None else "until Ctrl-C"
            print(f"enabled {config.name}: holding at {format_q(arm.state().q)} ({', '.join(arm.names)}) {until}",
                  flush=True)
            if args.seconds is not None:
                arm.sleep(args.seconds)
            else:
                while True:
                    arm.sleep(1.0)
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            if args.seconds is None and interrupted(e) == 130:  # Ctrl-C is how this is ended
                print("disabled")
                return 0
            print("interrupted: the arm is disabled", file=sys.stderr)
            return interrupted(e)
        with deferred_signals():
            arm.disable()
        print("disabled")
    return 0


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """Acknowledge a latched safety stop, enable, and leave the arm held by the server; with
    ``--seconds``, watch it that long first (a safety stop meanwhile: the error, exit status 1)."""
    from akarm.errors import ArgumentError

    if args.seconds is not None and not 0 <= args.seconds < float("inf"):
        raise ArgumentError(f"--seconds {args.seconds} must be a number of seconds, not negative")
    state = arm.call("enable", accept_position=True) if args.accept_position else arm.call("enable")
    if args.seconds is None:
        print(f"enabled {arm.config.name}: holding at {format_q(state['q'])} ({', '.join(arm.names)}); "
              f"{arm.held} (akarm disable releases it)", flush=True)
        return 0
    print(f"enabled {arm.config.name}: holding at {format_q(state['q'])} ({', '.join(arm.names)}) for "
          f"{args.seconds:g} s", flush=True)
    try:
        arm.call("sleep", seconds=args.seconds)
    except KeyboardInterrupt as e:
        print(f"interrupted: {arm.held}", file=sys.stderr)
        return interrupted(e)
    print(f"{arm.held} (akarm disable releases it)")
    return 0
