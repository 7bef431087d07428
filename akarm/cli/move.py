"""``akarm move ROBOT.yaml POSE|VALUES``: enable, move, optionally hold, disable.

::

    akarm move robots/planar2.yaml home                 # a pose from the YAML's `poses:`
    akarm move robots/planar2.yaml 0.1,-0.2 --speed 0.5 # rad per joint, config order
    akarm move robots/planar2.yaml up --hold 5 --log up.csv

The motion is planned (jerk-limited, joints arriving together) and checked against every joint's
limits before anything moves. Ctrl-C brings the arm to rest smoothly, then disables it (exit 130).
"""

from __future__ import annotations

import argparse
import re
import sys

from .common import add_profile_argument, add_robot_arguments, load_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("target", metavar="POSE|VALUES",
                        help="a pose name from the robot file, or comma-separated joint positions in rad (config "
                             "order), e.g. 0.1,-0.2,0.3 (-0.1,0.2 works too; else put -- before it)")
    # argparse takes "-0.1,0.2" for an option: it only knows plain negative numbers. The parser has
    # no option that looks like a number, so comma-separated numbers may be read as a positional too.
    if hasattr(parser, "_negative_number_matcher"):
        parser._negative_number_matcher = re.compile(r"^-\.?\d[\d.eE+-]*(,[-+]?\.?\d[\d.eE+-]*)*$")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="fraction of the joint limits, 0 < F <= 1 (default 1)")
    parser.add_argument("--hold", type=float, default=0.0, metavar="S", help="hold the target S seconds before "
                        "disabling (default 0)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv or .npz) for akarm plot")
    add_profile_argument(parser)


def parse_target(text: str, joint_names: tuple[str, ...]) -> str | list[float]:
    """A pose name, or comma-separated rad values (one per joint) → a list of floats.

    Raises:
        LimitError: numbers of the wrong count.
    """
    from ..errors import LimitError

    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        if len(parts) == 1:
            return text  # a pose name; the Arm says if there is no such pose
        raise LimitError(f"{text!r} is neither a pose name nor comma-separated numbers",
                         fix="give rad values like 0.1,-0.2 or a pose from the robot file") from None
    if len(values) != len(joint_names):
        raise LimitError(f"{len(values)} value(s) given, the arm has {len(joint_names)} joints",
                         fix="one position in rad per joint, in order: " + ", ".join(joint_names))
    return values


def run(args: argparse.Namespace) -> int:
    """Enable, move (and hold), disable."""
    import numpy as np

    from ..errors import AkarmError
    from .common import controlled, deferred_sigint, format_q, stop_smoothly

    if not 0 < args.speed <= 1:
        raise AkarmError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if not args.hold >= 0:
        raise AkarmError(f"--hold {args.hold} must not be negative")
    config = load_from_args(args)
    target = parse_target(args.target, config.joint_names)
    q_target = np.array(config.pose(target) if isinstance(target, str) else target)
    lim = [j.limits for j in config.joints]
    for j, q, lo in zip(config.joints, q_target, lim, strict=True):  # say it before enabling anything
        if not lo.lower <= q <= lo.upper:
            raise AkarmError(f"target {q:+.4f} rad is outside [{lo.lower:+.4f}, {lo.upper:+.4f}] rad", joint=j.name,
                             fix="choose a target within the joint's limits")
    code = 0
    with controlled(config, timing=args.profile) as arm:
        t0 = arm.clock.now()
        try:
            arm.enable()
            motion = arm.move_to(q_target, speed=args.speed, wait=False)
            print(f"moving to {args.target} {format_q(q_target)} in {motion.duration:.2f} s", flush=True)
            motion.wait()
            if args.hold > 0:
                arm.sleep(args.hold)
        except KeyboardInterrupt:
            stop_smoothly(arm)
            print("interrupted: stopped and disabled", file=sys.stderr)
            code = 130
        else:
            state = arm.state()
            err = np.abs(state.q - q_target)
            print(f"arrived: {format_q(state.q)}, largest error {err.max() * 1e3:.2f} mrad "
                  f"({arm.names[int(err.argmax())]})")
            with deferred_sigint():
                arm.disable()
        if args.log:
            path = arm.telemetry(since=t0).save(args.log)
            print(f"telemetry saved to {path}")
    if code == 0:
        print("disabled")
    return code
