"""``akarm init ROBOT.urdf [-o ROBOT.yaml]``: write a complete, commented starting robot file for a URDF.

::

    akarm init my_arm.urdf                       # writes my_arm.yaml next to it
    akarm init my_arm.urdf -o robots/arm.yaml --payload 0.5 --margin 2

Every movable joint in chain order with CAN IDs 1..n on one bus, a suggested motor per joint (the
smallest catalogue model whose rated torque covers the joint's gravity maximum with the margin),
conservative limits, gains scaled to each joint's inertia, poses ``zero`` and ``rest``, the bus load
at the chosen rate: every suggestion commented as one (see :mod:`akarm.robotfile.starter`). The file is then
loaded as ``akarm check`` would load it. Exit status 0 when it loads; 1 when a joint is short of torque
(no catalogue motor holds it, with ``--payload``: the file is written anyway, the joint marked), or on
a URDF problem (nothing is written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    parser.add_argument("urdf", metavar="ROBOT.urdf", help="the robot's URDF (as exported; meshes are not needed)")
    parser.add_argument("-o", "--output", metavar="ROBOT.yaml",
                        help="the robot file to write (default: the URDF's name with .yaml, beside it)")
    parser.add_argument("--payload", type=float, default=0.0, metavar="KG",
                        help="size the motors for KG at the tool too (default 0)")
    parser.add_argument("--margin", type=float, default=1.5, metavar="F",
                        help="motors' rated torque >= F x the largest gravity torque (default 1.5)")
    parser.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    parser.add_argument("--gripper", action="store_true", help="add a `gripper:` entry: the URDF's prismatic "
                        "joints no arm motor drives as its fingers (docs/gripper.md)")


def run(args: argparse.Namespace) -> int:
    """Suggest, write atomically, load it back; print what was chosen."""
    import warnings

    from akarm.cli.check import print_problems
    from akarm.errors import AkarmError, ArgumentError, ConfigError, ConfigWarning
    from akarm.files import atomic_write, check_writable
    from akarm.robotfile.load import load_robot
    from akarm.robotfile.starter import suggest

    urdf = Path(args.urdf)
    out = Path(args.output) if args.output else urdf.with_suffix(".yaml")
    if out.suffix.lower() not in (".yaml", ".yml"):
        raise ArgumentError(f"{out}: a robot file's name ends in .yaml", fix="e.g. -o my_arm.yaml")
    if out.exists() and not args.force:
        raise AkarmError(f"{out} exists; not overwritten", fix="choose another name with -o, or add --force")
    if not args.payload >= 0 or not args.margin >= 1:
        raise ArgumentError(f"--payload {args.payload:g} and --margin {args.margin:g} must be >= 0 and >= 1",
                            fix="e.g. --payload 0.5 --margin 1.5")
    check_writable(out)
    try:
        s = suggest(urdf, out, payload=args.payload, margin=args.margin, gripper=args.gripper)
    except ConfigError as e:
        print_problems(str(urdf), e.problems, sys.stderr)
        return 1
    try:
        atomic_write(out, lambda f: f.write(s.text.encode("utf-8")))
    except OSError as e:
        raise AkarmError(f"cannot write {out}: {e.strerror or e}", fix="choose a path you can write to") from None
    print(f"wrote {out}: {len(s.joints)} joints at {s.rate_hz:g} Hz" +
          (f", {len(s.locked)} held (locked)" if s.locked else "") + ":")
    width = max(len(j.urdf.name) for j in s.joints)
    for j in s.joints:
        print(f"  {j.urdf.name:<{width}}  {j.motor.name:<8} gravity max {j.gravity.torque:6.2f} N·m, "
              f"rated {j.motor.rated_torque:g} N·m, kp/kd {j.kp:g}/{j.kd:g}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConfigWarning)
            config = load_robot(out)
    except ConfigError as e:
        print_problems(str(out), e.problems, sys.stderr)
        print(f"akarm init: {out} was written but does not load yet: see above (every value in it is a "
              "suggestion to edit)", file=sys.stderr)
        return 1
    for w in config.warnings:
        print(f"warning: {w.message}" + (f" (fix: {w.fix})" if w.fix else ""))
    if s.short:
        with_payload = f" with {args.payload:g} kg at the tool" if args.payload else ""
        print(f"akarm init: no catalogue motor holds {', '.join(s.short)}{with_payload} (marked NO in {out}; "
              f"`akarm check {out} --payload {args.payload:g}` refuses it): more reduction, a lighter arm, or a motor "
              "of your own under `motors:`", file=sys.stderr)
        return 1
    print(f"every value marked `suggested` in {out} is a suggestion: check them. Next: akarm check {out}; "
          f"akarm sim {out} -i akarm_local -c try, and in another terminal akarm move {out} rest -i akarm_local "
          "-c try")
    return 0
