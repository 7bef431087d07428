"""``akarm move ROBOT.yaml TARGET...``: enable, move, optionally hold, disable.

::

    akarm move robots/planar2.yaml home                       # a pose from the YAML's `poses:`
    akarm move robots/planar2.yaml 0.1,-0.2 --speed 0.5       # rad per joint, config order
    akarm move robots/planar2.yaml -0.1 0.2 --speed 0.5       # the same, one value per word
    akarm move robots/arm6.yaml elbow=0.5 wrist_pitch=-0.2    # named joints; the others stay
    akarm move robots/arm6.yaml ready elbow=1.0               # a pose, with some joints changed
    akarm move robots/planar2.yaml up --hold 5 --log up.csv
    akarm move robots/arm6.yaml --xyz 0.45 0.0 0.5 --rpy 0 1.57 0   # the tool frame to a pose
    akarm move robots/arm6.yaml --xyz 0.45 0.1 0.5 --linear         # in a straight line, orientation kept

Negative values need no ``--``. Names of poses and joints are checked (with a did-you-mean), the
``--log`` file's name and folder too, and the motion is planned (jerk-limited, joints arriving
together) and checked against every joint's limits, all before anything is enabled. With ``--xyz``
the joint positions are solved (and the motion checked) once the arm is enabled and its pose known;
``--linear`` keeps the tool on the straight line, jerk-limited along it. Ctrl-C brings the arm to
rest smoothly, then disables it (exit 130).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from akarm.cli.common import add_profile_argument, add_robot_arguments, load_from_args, loop_options

if TYPE_CHECKING:
    import numpy as np

    from akarm.arm import Arm, Motion
    from akarm.cli.served import RemoteArm
    from akarm.config import RobotConfig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import delay, finite, negative_values_are_positional

    add_robot_arguments(parser)
    parser.add_argument("target", metavar="TARGET", nargs="*",
                        help="a pose name from the robot file; or joint positions in rad, config order, comma- or "
                             "space-separated (0.1,-0.2 or 0.1 -0.2); or JOINT=VALUE for some joints (elbow=0.5), "
                             "after a pose name or alone (the other joints stay where they are)")
    negative_values_are_positional(parser)
    _intermixed(parser)
    parser.add_argument("--xyz", type=finite, nargs=3, metavar=("X", "Y", "Z"),
                        help="instead of TARGET: move the tool frame to this position (m, base frame); its "
                             "orientation stays as it is unless --rpy gives one")
    parser.add_argument("--rpy", type=finite, nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                        help="with --xyz: the tool's orientation, rad (URDF convention: Rz(yaw) Ry(pitch) Rx(roll))")
    parser.add_argument("--linear", action="store_true", help="with --xyz: move the tool in a straight line")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="fraction of the joint limits, 0 < F <= 1 (default 1)")
    parser.add_argument("--hold", type=delay, default=0.0, metavar="S", help="hold the target S seconds before "
                        "disabling (default 0; at least the timing profile's lag: slow holds 1 s)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv, .npz or .mcap) for akarm plot")
    add_profile_argument(parser)


def _intermixed(parser: argparse.ArgumentParser) -> None:
    """Let TARGET come after options (``move R.yaml -c can0 home``) now that it may be left out (for
    ``--xyz``): argparse otherwise settles an optional positional, empty, at the first option it
    meets. Its own ``parse_known_intermixed_args`` does it right and calls ``parse_known_args``
    itself, so the instance's ``parse_known_args`` (what the verb's sub-parser is called with) is
    swapped only outside it."""
    plain = parser.parse_known_args

    def parse_known_args(args: Sequence[str] | None = None,
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        parser.parse_known_args = plain  # type: ignore[method-assign,assignment,unused-ignore]
        try:
            return parser.parse_known_intermixed_args(args, namespace)
        finally:
            parser.parse_known_args = parse_known_args  # type: ignore[method-assign,assignment,unused-ignore]

    parser.parse_known_args = parse_known_args  # type: ignore[method-assign,assignment,unused-ignore]


def _number(text: str) -> float | None:
    try:
        x = float(text)
    except ValueError:
        return None
    return x if x == x and abs(x) != float("inf") else None


def parse_target(words: str | Sequence[str], config: object) -> str | list[float] | dict[str, float]:
    """The words of a target → a pose name, a full vector (rad, config order) or {joint: rad}.

    Raises:
        ArgumentError: no such pose or joint (with a did-you-mean), numbers of the wrong count, or words
            that are none of these.
    """
    from akarm.config import RobotConfig
    from akarm.errors import ArgumentError, did_you_mean

    assert isinstance(config, RobotConfig)
    names = config.joint_names
    items = [words] if isinstance(words, str) else list(words)
    parts = [p.strip() for w in items for p in w.split(",") if p.strip()]
    values = [_number(p) for p in parts]
    if parts and all(v is not None for v in values):
        if len(values) != len(names):
            raise ArgumentError(f"{len(values)} value(s) given, the arm has {len(names)} joints",
                                fix="one position in rad per joint, in order: " + ", ".join(names) +
                                "; or JOINT=VALUE for some of them")
        return [float(v) for v in values if v is not None]
    pose: str | None = None
    named: dict[str, float] = {}
    for k, word in enumerate(items):
        if "=" not in word:
            if k == 0:
                pose = word.strip()
                if pose not in config.poses:
                    known = ", ".join(config.poses) or "none defined"
                    raise ArgumentError(f"no pose named {pose!r}{did_you_mean(pose, list(config.poses))}",
                                        fix=f"poses are: {known}; add it under `poses:`")
                continue
            raise ArgumentError(f"{word!r}: after the first word, give JOINT=VALUE", fix="e.g. elbow=0.5")
        name, _, text = word.partition("=")
        name = name.strip()
        if name not in names:
            raise ArgumentError(f"no joint named {name!r}{did_you_mean(name, names)}",
                                fix="joints are: " + ", ".join(names))
        x = _number(text)
        if x is None:
            raise ArgumentError(f"{word!r}: {text!r} is not a number", joint=name, fix="give rad, e.g. elbow=0.5")
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
    from akarm.errors import AkarmError, ArgumentError, num

    if not args.target and args.xyz is None:
        raise ArgumentError("give a TARGET or --xyz X Y Z", fix="e.g. akarm move ROBOT.yaml home")
    if args.target and args.xyz is not None:
        raise ArgumentError("give either a TARGET or --xyz, not both")
    if args.xyz is None and (args.rpy is not None or args.linear):
        raise ArgumentError("--rpy and --linear go with --xyz", fix="add --xyz X Y Z (m)")
    if args.xyz is not None:
        return _move_tool(args)
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    import numpy as np

    from akarm.cli.common import format_q

    config = _checked_config(args)
    target = parse_target(args.target, config)
    wanted = {n: q for n, q in zip(config.joint_names, config.pose(target) if isinstance(target, str) else target,
                                   strict=True)} if not isinstance(target, dict) else dict(target)
    for j in config.joints:  # say it before enabling anything
        q = wanted.get(j.name)
        lo = j.limits
        if q is not None and not lo.lower <= q <= lo.upper:
            raise AkarmError(f"target {num(q, sign=True)} rad is outside [{num(lo.lower, sign=True)}, "
                             f"{num(lo.upper, sign=True)}] rad", joint=j.name,
                             fix="choose a target within the joint's limits")
    label = " ".join(args.target)
    q_target = np.zeros(len(config.joints))

    def start(arm: Arm) -> Motion:
        nonlocal q_target
        motion = arm.move_to(target, speed=args.speed, wait=False)
        q_target = (np.array(config.pose(target) if isinstance(target, str) else target, dtype=float)
                    if not isinstance(target, dict) else motion.plan.sample(motion.plan.t_end)[0])
        print(f"moving to {label} {format_q(q_target)} in {motion.duration:.2f} s", flush=True)
        return motion

    def arrived(arm: Arm) -> str:
        state = arm.state()
        err = np.abs(state.q - q_target)
        return (f"arrived: {format_q(state.q)}, largest error {err.max() * 1e3:.2f} mrad "
                f"({arm.names[int(err.argmax())]})")

    return _session(args, config, start, arrived)


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """The move through ``akarm serve``: as without it, but the server holds the arm afterwards."""
    import numpy as np

    from akarm.cli.common import format_q, interrupted

    check_options(args)
    target = parse_target(args.target, arm.config)  # a pose name, a vector, or {joint: rad}
    if isinstance(target, str):
        target = list(arm.config.pose(target))
    label = " ".join(args.target)
    try:
        arm.call("ready")  # refused while a safety stop is latched; a disabled arm is enabled
        motion = arm.call("move", target=target if isinstance(target, dict) else list(target), speed=args.speed)
        q_target = np.array(motion["target"])
        print(f"moving to {label} {format_q(q_target)} in {motion['duration']:.2f} s", flush=True)
        done = arm.wait(motion)
        if args.hold > 0:
            arm.call("sleep", seconds=args.hold)
    except KeyboardInterrupt as e:  # Ctrl-C, SIGTERM, SIGHUP
        arm.interrupt()
        print(f"interrupted: stopped; {arm.held}", file=sys.stderr)
        return interrupted(e)
    q = np.array(arm.call("state")["q"])
    err = np.abs(q - q_target)
    if done["superseded"]:  # a ROS 2 trajectory or another CLI took over
        print(f"akarm move: another command replaced this motion before it arrived; at {format_q(q)}",
              file=sys.stderr)
    else:
        print(f"arrived: {format_q(q)}, largest error {err.max() * 1e3:.2f} mrad ({arm.names[int(err.argmax())]})")
    if args.log:
        saved = arm.call("telemetry", since=motion["t0"], save=os.path.abspath(args.log))
        print(f"telemetry saved to {saved['path']}")
    print(arm.held)
    return 1 if done["superseded"] else 0


def check_options(args: argparse.Namespace) -> None:
    """The options every move checks before anything is enabled (here or through akarm serve)."""
    from akarm.cli.options import TELEMETRY_SUFFIXES, check_output
    from akarm.errors import ArgumentError

    if not 0 < args.speed <= 1:
        raise ArgumentError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if not args.hold >= 0:
        raise ArgumentError(f"--hold {args.hold} must not be negative")
    check_output(args.log, TELEMETRY_SUFFIXES, "telemetry")


def _checked_config(args: argparse.Namespace) -> RobotConfig:
    """The options every move checks before anything is enabled, and the robot."""
    check_options(args)
    return load_from_args(args)


def _session(args: argparse.Namespace, config: RobotConfig, start: Callable[[Arm], Motion],
             arrived: Callable[[Arm], str]) -> int:
    """Enable, ``start(arm)`` a motion and wait for it (and hold), print ``arrived(arm)``, disable;
    Ctrl-C stops smoothly. Always ends disabled; the telemetry saved with ``--log``."""
    from akarm.cli.common import controlled, deferred_signals, interrupted, stop_smoothly

    code = 0
    with controlled(config, **loop_options(args)) as arm:
        t0 = arm.clock.now()
        try:
            arm.enable()
            start(arm).wait()
            # a reading may trail the commands by the timing profile's lag (a slow machine's simulator):
            # hold that long before saying where the arm arrived
            if max(args.hold, arm.timing.lag) > 0:
                arm.sleep(max(args.hold, arm.timing.lag))
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            print("interrupted: stopped and disabled", file=sys.stderr)
            code = interrupted(e)
        else:
            print(arrived(arm))
            with deferred_signals():
                arm.disable()
        if args.log:
            path = arm.telemetry(since=t0).save(args.log)
            print(f"telemetry saved to {path}")
    if code == 0:
        print("disabled")
    return code


def _move_tool(args: argparse.Namespace) -> int:
    """--xyz [--rpy] [--linear]: solved and checked once the arm's pose is known (after enabling)."""
    import numpy as np

    from akarm.buses.ownership import any_server, find_server
    from akarm.dynamics.ik import make_pose, pose_error
    from akarm.errors import StateError

    config = _checked_config(args)
    if any_server() and find_server(config) is not None:
        raise StateError("akarm serve drives this robot: --xyz moves are not served yet",
                         fix="stop the server, or move to joint positions")
    xyz = np.array(args.xyz)
    target = make_pose(args.xyz, rpy=args.rpy) if args.rpy is not None else None
    start_pose = np.eye(4)

    def _xyz(p: Sequence[float] | np.ndarray) -> str:
        return "(" + ", ".join(f"{x:+.4f}" for x in p) + ") m"

    def start(arm: Arm) -> Motion:
        nonlocal start_pose
        start_pose = arm.tool_pose()
        move = arm.move_linear if args.linear else arm.move_to_pose
        motion = move(target if target is not None else xyz, speed=args.speed, wait=False)
        how = "in a straight line" if args.linear else "(joint-space move)"
        print(f"moving the tool to {_xyz(xyz)} {how} in {motion.duration:.2f} s", flush=True)
        return motion

    def arrived(arm: Arm) -> str:
        reached = arm.tool_pose()
        text = (f"arrived: tool at {_xyz(reached[:3, 3])}, {np.linalg.norm(reached[:3, 3] - xyz) * 1e3:.2f} mm "
                "from the target")
        if target is not None:
            text += f", {pose_error(reached, target)[1] * 1e3:.1f} mrad from the target orientation"
        elif arm.n >= 6:
            text += f", {pose_error(reached, start_pose)[1] * 1e3:.1f} mrad from the orientation it had"
        return text

    return _session(args, config, start, arrived)
