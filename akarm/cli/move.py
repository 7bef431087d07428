"""``akarm move ROBOT.yaml POSE|VALUES``: enable, move, optionally hold, disable.

::

    akarm move robots/planar2.yaml home                 # a pose from the YAML's `poses:`
    akarm move robots/planar2.yaml 0.1,-0.2 --speed 0.5 # rad per joint, config order
    akarm move robots/planar2.yaml up --hold 5 --log up.csv
    akarm move robots/arm6.yaml --xyz 0.45 0.0 0.5 --rpy 0 1.57 0   # the tool frame to a pose
    akarm move robots/arm6.yaml --xyz 0.45 0.1 0.5 --linear         # in a straight line, orientation kept

The motion is planned (jerk-limited, joints arriving together; with ``--linear`` jerk-limited
along the line) and checked against every joint's limits before anything moves. Ctrl-C brings the
arm to rest smoothly, then disables it (exit 130).
"""

from __future__ import annotations

import argparse
import re
import sys

from .common import add_robot_arguments, load_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("target", metavar="POSE|VALUES", nargs="?",
                        help="a pose name from the robot file, or comma-separated joint positions in rad (config "
                             "order), e.g. 0.1,-0.2,0.3 (-0.1,0.2 works too; else put -- before it)")
    # argparse takes "-0.1,0.2" for an option: it only knows plain negative numbers. The parser has
    # no option that looks like a number, so comma-separated numbers may be read as a positional too.
    if hasattr(parser, "_negative_number_matcher"):
        parser._negative_number_matcher = re.compile(r"^-\.?\d[\d.eE+-]*(,[-+]?\.?\d[\d.eE+-]*)*$")
    _intermixed(parser)
    parser.add_argument("--xyz", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help="instead of POSE|VALUES: move the tool frame to this position (m, base frame); "
                             "its orientation stays as it is unless --rpy gives one")
    parser.add_argument("--rpy", type=float, nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                        help="with --xyz: the tool's orientation, rad (URDF convention: Rz(yaw) Ry(pitch) Rx(roll))")
    parser.add_argument("--linear", action="store_true", help="with --xyz: move the tool in a straight line")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="fraction of the joint limits, 0 < F <= 1 (default 1)")
    parser.add_argument("--hold", type=float, default=0.0, metavar="S", help="hold the target S seconds before "
                        "disabling (default 0)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv or .npz) for akarm plot")


def _intermixed(parser: argparse.ArgumentParser) -> None:
    """Let the optional POSE|VALUES come after options (``move R.yaml -c can0 home``): argparse
    otherwise settles an optional positional at the first option it meets (empty). Its own
    ``parse_known_intermixed_args`` does it right and calls ``parse_known_args`` itself, so the
    instance's ``parse_known_args`` (what the verb's sub-parser is called with) is swapped only outside it."""
    plain = parser.parse_known_args

    def parse_known_args(args=None, namespace=None):
        parser.parse_known_args = plain  # type: ignore[method-assign]
        try:
            return parser.parse_known_intermixed_args(args, namespace)
        finally:
            parser.parse_known_args = parse_known_args  # type: ignore[method-assign]

    parser.parse_known_args = parse_known_args  # type: ignore[method-assign]


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
    from ..errors import AkarmError

    if not 0 < args.speed <= 1:
        raise AkarmError(f"--speed {args.speed} must be in (0, 1]", fix="e.g. --speed 0.5")
    if not args.hold >= 0:
        raise AkarmError(f"--hold {args.hold} must not be negative")
    if (args.target is None) == (args.xyz is None):
        raise AkarmError("give either a target (POSE|VALUES) or --xyz X Y Z", fix="e.g. akarm move ROBOT.yaml home")
    if args.xyz is None and (args.rpy is not None or args.linear):
        raise AkarmError("--rpy and --linear go with --xyz", fix="add --xyz X Y Z (m)")
    config = load_from_args(args)
    move = _ToolMove(args) if args.xyz is not None else _JointMove(args, config)
    return _session(args, config, move)


class _JointMove:
    """POSE|VALUES: checked against the ranges before anything is enabled."""

    def __init__(self, args: argparse.Namespace, config) -> None:
        import numpy as np

        from ..errors import AkarmError

        target = parse_target(args.target, config.joint_names)
        self.label = args.target
        self.q = np.array(config.pose(target) if isinstance(target, str) else target)
        for j, q in zip(config.joints, self.q, strict=True):  # say it before enabling anything
            lo = j.limits
            if not lo.lower <= q <= lo.upper:
                raise AkarmError(f"target {q:+.4f} rad is outside [{lo.lower:+.4f}, {lo.upper:+.4f}] rad", joint=j.name,
                                 fix="choose a target within the joint's limits")

    def start(self, arm, speed: float):
        from .common import format_q

        motion = arm.move_to(self.q, speed=speed, wait=False)
        print(f"moving to {self.label} {format_q(self.q)} in {motion.duration:.2f} s", flush=True)
        return motion

    def arrived(self, arm) -> str:
        import numpy as np

        from .common import format_q

        q = arm.state().q
        err = np.abs(q - self.q)
        return f"arrived: {format_q(q)}, largest error {err.max() * 1e3:.2f} mrad ({arm.names[int(err.argmax())]})"


class _ToolMove:
    """--xyz [--rpy] [--linear]: solved and checked once the arm's pose is known (after enabling)."""

    def __init__(self, args: argparse.Namespace) -> None:
        import numpy as np

        from ..ik import make_pose

        self.xyz = np.array(args.xyz)
        self.target = make_pose(args.xyz, rpy=args.rpy) if args.rpy is not None else None
        self.linear = args.linear
        self.start_pose = None

    def start(self, arm, speed: float):
        self.start_pose = arm.tool_pose()
        pose = self.target if self.target is not None else self.xyz
        move = arm.move_linear if self.linear else arm.move_to_pose
        motion = move(pose, speed=speed, wait=False)
        how = "in a straight line" if self.linear else "(joint-space move)"
        print(f"moving the tool to {_xyz(self.xyz)} {how} in {motion.duration:.2f} s", flush=True)
        return motion

    def arrived(self, arm) -> str:
        import numpy as np

        from ..ik import pose_error

        reached = arm.tool_pose()
        text = (f"arrived: tool at {_xyz(reached[:3, 3])}, "
                f"{np.linalg.norm(reached[:3, 3] - self.xyz) * 1e3:.2f} mm from the target")
        if self.target is not None:
            text += f", {pose_error(reached, self.target)[1] * 1e3:.1f} mrad from the target orientation"
        elif arm.n >= 6:
            text += f", {pose_error(reached, self.start_pose)[1] * 1e3:.1f} mrad from the orientation it had"
        return text


def _xyz(p) -> str:
    return "(" + ", ".join(f"{x:+.4f}" for x in p) + ") m"


def _session(args: argparse.Namespace, config, move: _JointMove | _ToolMove) -> int:
    from .common import controlled, deferred_sigint, stop_smoothly

    code = 0
    with controlled(config) as arm:
        t0 = arm.clock.now()
        try:
            arm.enable()
            move.start(arm, args.speed).wait()
            if args.hold > 0:
                arm.sleep(args.hold)
        except KeyboardInterrupt:
            stop_smoothly(arm)
            print("interrupted: stopped and disabled", file=sys.stderr)
            code = 130
        else:
            print(move.arrived(arm))
            with deferred_sigint():
                arm.disable()
        if args.log:
            path = arm.telemetry(since=t0).save(args.log)
            print(f"telemetry saved to {path}")
    if code == 0:
        print("disabled")
    return code
