"""``akarm move ROBOT.yaml TARGET...``: enable, move, optionally hold, disable.

::

    akarm move robots/planar2.yaml home                       # a pose from the YAML's `poses:`
    akarm move robots/planar2.yaml 0.1,-0.2 --speed 0.5       # rad per joint, config order
    akarm move robots/planar2.yaml -0.1 0.2 --speed 0.5       # the same, one value per word
    akarm move robots/arm6.yaml elbow=0.5 wrist_pitch=-0.2    # named joints; the others stay
    akarm move robots/arm6.yaml ready elbow=1.0               # a pose, with some joints changed
    akarm move robots/planar2.yaml up --hold 5 --log up.csv

Negative values need no ``--``. Names of poses and joints are checked (with a did-you-mean), the
``--log`` file's name and folder too, and the motion is planned (jerk-limited, joints arriving
together) and checked against every joint's limits, all before anything is enabled. Ctrl-C brings
the arm to rest smoothly, then disables it (exit 130).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .common import add_profile_argument, add_robot_arguments, load_from_args

#: telemetry files akarm writes
LOG_SUFFIXES = (".csv", ".npz")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from .options import negative_values_are_positional

    add_robot_arguments(parser)
    parser.add_argument("target", metavar="TARGET", nargs="+",
                        help="a pose name from the robot file; or joint positions in rad, config order, comma- or "
                             "space-separated (0.1,-0.2 or 0.1 -0.2); or JOINT=VALUE for some joints (elbow=0.5), "
                             "after a pose name or alone (the other joints stay where they are)")
    negative_values_are_positional(parser)
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="fraction of the joint limits, 0 < F <= 1 (default 1)")
    parser.add_argument("--hold", type=float, default=0.0, metavar="S", help="hold the target S seconds before "
                        "disabling (default 0)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv or .npz) for akarm plot")
    add_profile_argument(parser)


def _number(text: str) -> float | None:
    try:
        x = float(text)
    except ValueError:
        return None
    return x if x == x and abs(x) != float("inf") else None


def parse_target(words: str | Sequence[str], config: object) -> str | list[float] | dict[str, float]:
    """The words of a target → a pose name, a full vector (rad, config order) or {joint: rad}.

    Raises:
        ConfigError: no such pose or joint (with a did-you-mean).
        LimitError: numbers of the wrong count, or words that are none of these.
    """
    from ..config import RobotConfig
    from ..errors import LimitError
    from ..motors import did_you_mean

    assert isinstance(config, RobotConfig)
    names = config.joint_names
    items = [words] if isinstance(words, str) else list(words)
    parts = [p.strip() for w in items for p in w.split(",") if p.strip()]
    values = [_number(p) for p in parts]
    if parts and all(v is not None for v in values):
        if len(values) != len(names):
            raise LimitError(f"{len(values)} value(s) given, the arm has {len(names)} joints",
                             fix="one position in rad per joint, in order: " + ", ".join(names) +
                             "; or JOINT=VALUE for some of them")
        return [float(v) for v in values if v is not None]
    pose: str | None = None
    named: dict[str, float] = {}
    for k, word in enumerate(items):
        if "=" not in word:
            if k == 0:
                pose = word.strip()
                config.pose(pose)  # ConfigError with did-you-mean when there is no such pose
                continue
            raise LimitError(f"{word!r}: after the first word, give JOINT=VALUE", fix="e.g. elbow=0.5")
        name, _, text = word.partition("=")
        name = name.strip()
        if name not in names:
            raise LimitError(f"no joint named {name!r}{did_you_mean(name, names)}",
                             fix="joints are: " + ", ".join(names))
        x = _number(text)
        if x is None:
            raise LimitError(f"{word!r}: {text!r} is not a number", joint=name, fix="give rad, e.g. elbow=0.5")
        named[name] = x
    if pose is None:
        return named
    if not named:
        return pose
    q = list(config.pose(pose))
    for name, x in named.items():
        q[names.index(name)] = x
    return q


def run(args: argparse.Namespace) -> int:
    """Enable, move (and hold), disable."""
    from .served import via_server

    if (served := via_server(args)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    import numpy as np

    from ..errors import AkarmError
    from .common import controlled, deferred_signals, format_q, interrupted, stop_smoothly
    from .options import check_output

    if not 0 < args.speed <= 1:
        raise AkarmError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if not args.hold >= 0:
        raise AkarmError(f"--hold {args.hold} must not be negative")
    check_output(args.log, LOG_SUFFIXES, "telemetry")
    config = load_from_args(args)
    target = parse_target(args.target, config)
    wanted = {n: q for n, q in zip(config.joint_names, config.pose(target) if isinstance(target, str) else target,
                                   strict=True)} if not isinstance(target, dict) else dict(target)
    for j in config.joints:  # say it before enabling anything
        q = wanted.get(j.name)
        lo = j.limits
        if q is not None and not lo.lower <= q <= lo.upper:
            raise AkarmError(f"target {q:+.4f} rad is outside [{lo.lower:+.4f}, {lo.upper:+.4f}] rad", joint=j.name,
                             fix="choose a target within the joint's limits")
    label = " ".join(args.target)
    code = 0
    with controlled(config, timing=args.profile) as arm:
        t0 = arm.clock.now()
        try:
            arm.enable()
            motion = arm.move_to(target, speed=args.speed, wait=False)
            q_target = (np.array(config.pose(target) if isinstance(target, str) else target, dtype=float)
                        if not isinstance(target, dict) else motion.plan.sample(motion.plan.t_end)[0])
            print(f"moving to {label} {format_q(q_target)} in {motion.duration:.2f} s", flush=True)
            motion.wait()
            if args.hold > 0:
                arm.sleep(args.hold)
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            print("interrupted: stopped and disabled", file=sys.stderr)
            code = interrupted(e)
        else:
            state = arm.state()
            err = np.abs(state.q - q_target)
            print(f"arrived: {format_q(state.q)}, largest error {err.max() * 1e3:.2f} mrad "
                  f"({arm.names[int(err.argmax())]})")
            with deferred_signals():
                arm.disable()
        if args.log:
            path = arm.telemetry(since=t0).save(args.log)
            print(f"telemetry saved to {path}")
    if code == 0:
        print("disabled")
    return code
