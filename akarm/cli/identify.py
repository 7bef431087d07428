"""``akarm identify ROBOT.yaml``: identify each joint's friction, the payload, and collision thresholds.

::

    akarm identify robots/arm6.yaml                      # print the results as YAML to merge
    akarm identify robots/arm6.yaml --speed 0.5 --save   # write them into the robot file (with a backup)
    akarm identify robots/arm6.yaml --payload-only       # at rest, from a few poses: mass and centre of mass

The arm is enabled where it is and follows a slow multi-sine excitation around that pose (each
joint at most ``--amplitude`` rad, less near its limits), planned and checked against every limit
before anything moves, then comes back to rest (:func:`akarm.identify.identify`). Clear the arm's reach
first: every joint moves. Ctrl-C stops smoothly and disables (exit 130).
"""

from __future__ import annotations

import argparse
import sys

from akarm.cli.common import (
    add_robot_arguments,
    controlled,
    deferred_signals,
    interrupted,
    load_from_args,
    stop_smoothly,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import duration

    add_robot_arguments(parser)
    parser.add_argument("--speed", type=float, metavar="F", help="time scaling of the excitation, 0 < F <= 1 "
                        "(default: as fast as the joint limits and half the torque limits allow)")
    parser.add_argument("--seconds", type=duration, default=30.0, metavar="S",
                        help="excitation length, 8-600 s (default 30)")
    parser.add_argument("--amplitude", type=float, default=0.5, metavar="RAD",
                        help="largest excursion of each joint from where it starts, 0 < RAD <= π (default 0.5)")
    parser.add_argument("--no-payload", action="store_true", help="do not identify a payload (use the file's)")
    parser.add_argument("--no-offsets", action="store_true", help="do not fit a torque offset per joint")
    parser.add_argument("--torque-scale", action="store_true",
                        help="also fit each joint's torque scale (N·m it gets per N·m reported: a real unit's) and "
                             "friction's load share; with nothing at the tool and --no-payload (the excitation "
                             "cannot tell a payload from a stronger motor)")
    parser.add_argument("--payload-only", action="store_true",
                        help="only the payload, at rest in a few poses (no excitation)")
    parser.add_argument("--save", action="store_true",
                        help="write the results into ROBOT.yaml (a copy of it is kept as ROBOT.yaml.DATE.bak)")


def run(args: argparse.Namespace) -> int:
    """Enable, identify, report (or save), disable."""
    from akarm.errors import ArgumentError
    from akarm.identify import Identification, estimate_payload, identify
    from akarm.identify.fit import check_excitation, yaml_payload

    if args.speed is not None and not 0 < args.speed <= 1:
        raise ArgumentError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if args.payload_only and args.no_payload:
        raise ArgumentError("--payload-only and --no-payload contradict each other")
    if not args.payload_only:  # before the arm is enabled, not once the excitation is planned
        check_excitation(args.amplitude, args.seconds, names=("--amplitude", "--seconds"))
    config = load_from_args(args)
    with controlled(config) as arm:
        if not args.no_payload:  # an unknown payload is an external torque: the reflex would stop the arm
            arm.set_collision(thresholds=[None] * arm.n)
            print("collision reflex: watching only (the payload is not known yet)", flush=True)
        try:
            arm.enable()
            if args.payload_only:
                print("estimating the payload at rest from a few poses ...", flush=True)
                payload = estimate_payload(arm)
                result = Identification((), payload, 0, 0.0)
                print(yaml_payload(payload) + f"   # RMS residual {max(payload.rms):.3f} N·m")
            else:
                print(f"identifying {config.name}: a {args.seconds:g} s excitation around where it is; every joint "
                      "moves", flush=True)
                result = identify(arm, args.seconds, args.speed, amplitude=args.amplitude,
                                  payload=not args.no_payload, offsets=not args.no_offsets,
                                  torque_scale=args.torque_scale)
                print(f"excited at speed {result.speed:g} for {result.duration:.1f} s ({result.samples} samples)")
                print()
                print(result.table())
                for note in result.notes:
                    print(f"note: {note}")
                print()
                print("fit quality: RMS residual torque per joint (N·m) above; thresholds: three times the largest "
                      "external-torque estimate seen while nothing touched the arm, at least 6 % of the torque limit")
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            print("interrupted: the arm is disabled", file=sys.stderr)
            return interrupted(e)
        with deferred_signals():
            arm.disable()
    if args.save:
        path, backup = result.save(args.robot)
        print(f"saved into {path} (the previous file is {backup})")
    elif not args.payload_only:
        print()
        print(result.fragment(), end="")
    print("disabled")
    return 0
