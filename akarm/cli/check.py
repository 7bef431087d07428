"""``akarm check ROBOT.yaml``: validate a robot file; print its joints, the largest gravity torque
each motor must hold, the bus load and rate ceiling, and the loader's warnings.

::

    akarm check robots/arm6.yaml
    akarm check robots/arm6.yaml --payload 0.5     # will the motors hold 0.5 kg more at the tool?
    akarm check robots/arm6.yaml --loop-rate 700   # the bus load at another loop rate

Exit code 0 when the file is valid (warnings included), 1 with every problem listed otherwise.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, TextIO

from akarm.cli.common import add_robot_arguments, load_from_args

if TYPE_CHECKING:
    from akarm.errors import ConfigProblem


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from akarm.cli.options import renamed

    add_robot_arguments(parser)
    parser.add_argument("--loop-rate", type=float, metavar="HZ",
                        help="check the bus load at this loop rate instead of the file's rate_hz")
    parser.add_argument("--payload", type=float, metavar="KG", default=0.0,
                        help="also check that the motors hold KG more at the tool (a margin for what the gripper "
                             "may carry): refused when gravity then exceeds a torque limit")
    renamed(parser, "--rate", "--loop-rate", "-r")


def _table(rows: list[list[str]], out: TextIO) -> None:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for k, row in enumerate(rows):
        print("  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip(), file=out)
        if k == 0:
            print("  " + "  ".join("-" * w for w in widths), file=out)


def _hz(x: float) -> str:
    return "unlimited" if math.isinf(x) else f"{math.floor(x)} Hz"


# C901 13 > 12, left as it was: one report, a branch per table column and per kind of warning
def report(config: object, out: TextIO | None = None, extra_payload: float = 0.0) -> list[str]:  # noqa: C901
    """Print the arm's table (gravity included), bus load and the loader's warnings to ``out``
    (default stdout); return the warnings printed."""
    from akarm.config import RobotConfig
    from akarm.config.busload import LOAD_LIMIT, bus_loads
    from akarm.dynamics.gravity import gravity_peaks

    out = out if out is not None else sys.stdout
    assert isinstance(config, RobotConfig)
    peaks = gravity_peaks(config)
    margin = gravity_peaks(config, extra_payload=extra_payload) if extra_payload else None
    print(f"robot {config.name!r}: {len(config.joints)} joints, URDF {config.urdf}", file=out)
    extras = [f"loop {config.rate_hz:g} Hz", f"gravity {tuple(config.gravity)} m/s²"]
    if config.tool_frame:
        extras.append(f"tool frame {config.tool_frame}")
    if config.payload:
        extras.append(f"payload {config.payload.mass:g} kg at {config.payload.com}")
    print("  " + ", ".join(extras), file=out)
    print(file=out)
    rows = [["joint", "motor", "mode", "bus/ID", "position (rad)", "vel/acc/jerk (rad/s, /s², /s³)",
             "torque (N·m)", "kp/kd", "gravity max (N·m)"]]
    if margin is not None:
        rows[0].append(f"+{extra_payload:g} kg")
    for k, j in enumerate(config.joints):
        lim = j.limits
        mode = f"{j.mode} {j.firmware}" if j.mode == "mit" else f"servo {j.status_rate_hz:g}Hz"
        gains = f"{j.gains.kp:g}/{j.gains.kd:g}" if j.mode == "mit" else "-"
        sign = "" if j.direction == 1 else " dir -1"
        offs = f" off {j.offset:g}" if j.offset else ""
        rows.append([j.name, j.motor.name + sign + offs, mode, f"{j.bus}/{j.can_id}",
                     f"[{lim.lower:+.3f}, {lim.upper:+.3f}]", f"{lim.velocity:g} / {lim.acceleration:g} / {lim.jerk:g}",
                     f"{lim.torque:g} of {j.motor.t_max:g}", gains, _gravity_cell(peaks[k].torque, j)])
        if margin is not None:
            rows[-1].append(_gravity_cell(margin[k].torque, j))
    _table(rows, out)
    loaded = [p for p in (margin or peaks) if p.torque > 0.005]
    if loaded:
        what = f"with {extra_payload:g} kg more at the tool" if margin is not None else "over the joint ranges"
        print(f"  gravity max {what}" + (" (payload included)" if config.payload else "") + ", reached at:", file=out)
        width = max(len(p.joint) for p in loaded)
        for p in loaded:
            j = config.joint(p.joint)
            print(f"    {p.joint:<{width}}  gravity max {p.torque:.1f} N·m at {p.pose()} of {j.limits.torque:g} N·m",
                  file=out)
    g = config.gripper
    if g is not None:
        print(file=out)
        law = f"table of {len(g.table)} points" if g.table else "linear"
        print(f"gripper {g.name!r}: {g.motor.name} {g.mode} on {g.bus}/{g.can_id}, stroke {g.stroke * 1e3:g} mm over "
              f"{g.open_angle:g} rad ({law}), force limit {g.force_limit:g} N ({g.torque_limit:.2f} N·m), "
              f"kp/kd {g.kp:g}/{g.kd:g}" + (f", fingers {', '.join(g.fingers)}" if g.fingers else ""), file=out)
    if config.poses:
        print(file=out)
        print("poses: " + ", ".join(config.poses), file=out)
    print(file=out)
    print(f"bus load at {config.rate_hz:g} Hz (worst-case bit stuffing; nominal in brackets), "
          f"limit {100 * LOAD_LIMIT:.0f} %:", file=out)
    warnings = []
    rows = [["bus", "channel", "motors" if g is not None else "joints", "load", "max rate (worst case)",
             "max rate (nominal)"]]
    for name, load in bus_loads(config).items():
        bus = config.buses[name]
        rows.append([name, bus.describe(), str(len(load.joints)),
                     f"{load.percent:.1f} % ({load.percent_nominal:.1f} %)", _hz(load.max_rate_hz),
                     _hz(load.max_rate_hz_nominal)])
        if load.worst_case_over_limit:
            warnings.append(f"bus {name!r}: worst-case load {load.percent:.0f} % is over {100 * LOAD_LIMIT:.0f} % "
                            f"(nominal {load.percent_nominal:.0f} %); below {math.floor(load.max_rate_hz)} Hz "
                            "the bus stays under the limit even with maximal bit stuffing")
    _table(rows, out)
    for cw in config.warnings:
        warnings.append(f"{cw.message} (fix: {cw.fix})" if cw.fix else cw.message)
    for w in warnings:
        print(f"warning: {w}", file=out)
    return warnings


def _gravity_cell(torque: float, joint: object) -> str:
    """``"14.7, above rated 8.3"``: the largest gravity torque against the joint's limit and rated torque."""
    from akarm.config import JointConfig

    assert isinstance(joint, JointConfig)
    if torque > joint.limits.torque:
        return f"{torque:.1f} ABOVE the limit {joint.limits.torque:g}"
    rated = joint.motor.rated_torque
    if rated is None:
        return f"{torque:.1f}"
    return f"{torque:.1f}, {'above' if torque > rated else 'within'} rated {rated:g}"


def print_problems(robot: str, problems: list[ConfigProblem], out: TextIO) -> None:
    """A robot file's problems on ``out``: how many, then each at its line, with its fix (also for ``akarm init``)."""
    n = len(problems)
    print(f"{robot}: {n} problem{'s' if n != 1 else ''}:", file=out)
    for p in problems:
        where = f"line {p.line}" if p.line is not None else "(no line)"
        if p.file != str(robot):
            where = f"{p.file}:{where}"
        print(f"  {where}: {p.message}", file=out)
        if p.fix:
            print(f"      fix: {p.fix}", file=out)


def run(args: argparse.Namespace) -> int:
    import warnings

    from akarm.config.busload import LOAD_LIMIT, bus_loads
    from akarm.dynamics.gravity import gravity_peaks
    from akarm.errors import ArgumentError, ConfigError, ConfigProblem, ConfigWarning

    if not args.payload >= 0:
        raise ArgumentError(f"--payload {args.payload:g} must not be negative", fix="the extra mass in kg, e.g. 0.5")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConfigWarning)  # printed below with the others
            config = load_from_args(args, rate_hz=args.loop_rate)  # the loader checks the bus load at this rate
    except ConfigError as e:
        print_problems(args.robot, e.problems, sys.stderr)
        return 1
    # a --bitrate override changes the load the file was validated with
    over = [load for load in bus_loads(config).values() if load.over_limit]
    if over:
        print_problems(args.robot, [ConfigProblem(
            args.robot, None, f"at {config.rate_hz:g} Hz and {config.buses[load.bus].bitrate} bit/s bus "
            f"{load.bus!r} is {load.percent_nominal:.0f} % busy, over {100 * LOAD_LIMIT:.0f} %",
            f"run at most {math.floor(load.max_rate_hz_nominal)} Hz") for load in over], sys.stderr)
        return 1
    report(config, extra_payload=args.payload)
    if args.payload:
        short = [(j, p) for j, p in zip(config.joints, gravity_peaks(config, extra_payload=args.payload), strict=True)
                 if p.torque > j.limits.torque]
        if short:
            print_problems(args.robot, [ConfigProblem(
                args.robot, None, f"joint {j.name!r}: with {args.payload:g} kg more at the tool, gravity needs up to "
                f"{p.torque:.1f} N·m (at {p.pose()}), above its torque limit {j.limits.torque:g} N·m",
                "a stronger motor for this joint, or less payload") for j, p in short], sys.stderr)
            return 1
    print(f"\n{args.robot}: OK")
    return 0
