"""``akarm zero ROBOT.yaml JOINT``: make a joint's current position its motor's zero.

::

    akarm zero robots/arm6.yaml elbow               # MIT: ZERO frame, then read it back
    akarm zero robots/servo3.yaml pan --permanent   # servo: origin saved in flash

MIT joints are sent EXIT first (a motor left enabled must not jump to its old target in the new
frame), so the joint is **limp** while its driver is off-line after ZERO (0.5-1.5 s; ``--wait``):
zero a joint resting at its reference, or support the arm. Afterwards the joint reads its
configured ``offset``.
"""

from __future__ import annotations

import argparse
import sys

from akarm.cli.common import add_robot_arguments, load_from_args
from akarm.cli.options import delay, duration


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("joint", metavar="JOINT", help="the joint to zero")
    parser.add_argument("--permanent", action="store_true",
                        help="servo joints: keep the origin across power cycles (saved in flash)")
    parser.add_argument("--wait", type=delay, default=1.5, metavar="S",
                        help="MIT: seconds the driver is left alone after ZERO (default 1.5)")
    parser.add_argument("--timeout", type=duration, default=1.0, metavar="S",
                        help="seconds to wait for an answer (default 1.0)")


def run(args: argparse.Namespace) -> int:
    """Zero the joint; print the motor position read back."""
    from akarm.control.probe import Probe

    config = load_from_args(args)
    from akarm.buses.ownership import refuse_if_served

    refuse_if_served(config, "akarm zero")  # it would make a joint limp under a running server
    j = config.joint(args.joint)
    if args.permanent and j.mode == "mit":
        print("note: --permanent applies to servo joints; whether a MIT driver keeps its zero across power "
              "cycles depends on its firmware", file=sys.stderr)
    with Probe(config, [j.name]) as probe:  # opened first: a bus that will not open is the only message
        if j.mode == "mit":
            print(f"zeroing {j.name} (MIT ID {j.can_id}): the joint is limp for about {args.wait:g} s ...",
                  file=sys.stderr, flush=True)
        p = probe.zero(j.name, args.permanent, wait=args.wait, timeout=args.timeout)
    reads = j.offset + j.direction * p
    from akarm.control.turns import PositionMemory, state_file

    PositionMemory(state_file(config.name), config.joints).update(j.name, reads)  # the turn check's memory
    kind = "" if j.mode == "mit" else (" (permanent)" if args.permanent else " (until power is lost)")
    print(f"zeroed {j.name}{kind}: motor reads {p:+.4f} rad; the joint now reads {reads:+.4f} "
          f"rad (offset {j.offset:+.4f} rad)")
    if abs(p) > 0.02:
        print(f"warning: {j.name} moved {p:+.4f} rad while it was being zeroed; support the arm and zero it again",
              file=sys.stderr)
    return 0
