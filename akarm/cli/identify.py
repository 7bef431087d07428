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
from collections.abc import Callable

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
                        help="identify the unit: each joint's torque scale (N·m it gets per N·m reported) and "
                             "friction with its load share, from two runs, the second with a known weight at the "
                             "tool (--weight; the program asks you to hang it); nothing else at the tool")
    parser.add_argument("--weight", type=float, metavar="KG",
                        help="with --torque-scale: the known weight's mass, kg (e.g. 0.5)")
    parser.add_argument("--weight-com", default="0.1,0,0.05", metavar="X,Y,Z",
                        help="with --torque-scale: where the weight's centre of mass is in the tool frame, m "
                             "(default 0.1,0,0.05: 10 cm off the tool's axis, so the roll joints feel it)")
    parser.add_argument("--center", metavar="POSE",
                        help="excite around this named pose or comma-separated joint positions, rad (default: "
                             "where the arm is)")
    parser.add_argument("--reach", metavar="POSE",
                        help="with --torque-scale: where a joint the weight loads only through inertia (a vertical "
                             "axis) is excited alone, the others held: a named pose or joint positions, rad, the "
                             "arm leaning out as far as its torque allows (default: --center)")
    parser.add_argument("--payload-only", action="store_true",
                        help="only the payload, at rest in a few poses (no excitation)")
    parser.add_argument("--save", action="store_true",
                        help="write the results into ROBOT.yaml (a copy of it is kept as ROBOT.yaml.DATE.bak)")


def run(args: argparse.Namespace) -> int:
    """Enable, identify, report (or save), disable."""
    from akarm.errors import ArgumentError
    from akarm.identify import Identification, estimate_payload, identify, identify_unit
    from akarm.identify.fit import check_excitation, yaml_payload

    if args.speed is not None and not 0 < args.speed <= 1:
        raise ArgumentError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if args.payload_only and args.no_payload:
        raise ArgumentError("--payload-only and --no-payload contradict each other")
    if args.payload_only and args.torque_scale:
        raise ArgumentError("--payload-only and --torque-scale are two steps", fix="the unit first (--torque-scale "
                            "--weight KG, nothing else at the tool), then the tool (--payload-only)")
    if not args.payload_only:  # before the arm is enabled, not once the excitation is planned
        check_excitation(args.amplitude, args.seconds, names=("--amplitude", "--seconds"))
    weight = _weight(args)
    center, reach = _center(args.center), _center(args.reach, "--reach")  # (a typo refused before the arm opens)
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
                if weight is not None:
                    result = identify_unit(arm, weight, _ask_to_hang(weight), args.seconds, args.speed,
                                           amplitude=args.amplitude, center=center,
                                           reach=reach, offsets=not args.no_offsets)
                else:
                    result = identify(arm, args.seconds, args.speed, amplitude=args.amplitude, center=center,
                                      payload=not args.no_payload, offsets=not args.no_offsets)
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


def _weight(args: argparse.Namespace) -> tuple[float, tuple[float, float, float]] | None:
    """``--weight`` and ``--weight-com`` checked (before anything moves; ``--reach`` needs them): the weight, or
    ``None``."""
    from akarm.errors import ArgumentError, finite_number

    if not args.torque_scale:
        if args.weight is not None:
            raise ArgumentError("--weight is for --torque-scale", fix="add --torque-scale")
        if args.reach is not None:
            raise ArgumentError("--reach is for --torque-scale (where a vertical axis is excited alone)",
                                fix="add --torque-scale --weight KG")
        return None
    if args.weight is None:
        raise ArgumentError("--torque-scale needs a known weight: without one a 20 % lighter arm and a 20 % "
                            "stronger motor are the same data", fix="e.g. --torque-scale --weight 0.5 (kg)")
    mass = finite_number(args.weight, "--weight", above=0.0, at_most=5.0, unit="kg", fix="e.g. --weight 0.5")
    try:
        x, y, z = (float(v) for v in args.weight_com.split(","))
    except ValueError:
        raise ArgumentError(f"--weight-com must be three numbers X,Y,Z (m, tool frame), got {args.weight_com!r}",
                            fix="e.g. --weight-com 0.1,0,0.05") from None
    for v in (x, y, z):
        finite_number(v, "--weight-com", at_least=-1.0, at_most=1.0, unit="m", fix="e.g. --weight-com 0.1,0,0.05")
    return mass, (x, y, z)


def _center(text: str | None, option: str = "--center") -> str | list[float] | None:
    """``--center`` (or ``option``): a pose's name, or joint positions."""
    if text is None or "," not in text:
        return text
    from akarm.errors import ArgumentError

    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise ArgumentError(f"{option} must be a pose's name or joint positions (rad), got {text!r}",
                            fix=f"e.g. {option} home") from None


def _ask_to_hang(weight: tuple[float, tuple[float, float, float]]) -> Callable[[bool], None]:
    """Between the runs: ask the user to hang the weight (and to take it off at the end), wait for Enter."""

    def hang(on: bool) -> None:
        if on:
            x, y, z = weight[1]
            input(f"hang the {weight[0]:g} kg weight at the tool, its centre of mass at ({x:g}, {y:g}, {z:g}) m in "
                  "the tool frame; keep clear; then press Enter (the arm holds still meanwhile) ")
        else:
            print("take the weight off the tool before the next step", flush=True)

    return hang
