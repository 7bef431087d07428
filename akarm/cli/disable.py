"""``akarm disable ROBOT.yaml``: make every joint limp.

For an arm this process did not enable (a controller that crashed, a motor left in motor mode):
MIT joints get a zero-gain, zero-torque command (so the driver forgets its last command and the
next enable cannot kick) and EXIT; servo joints get zero current. **The arm is not held afterwards:
support it.** (Verbs that enable the arm themselves damp it before disabling it.)

Exit status 0 when every joint answered, 1 when one did not (its frames were sent anyway).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from akarm.cli.common import add_robot_arguments, load_from_args
from akarm.cli.options import duration

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("--timeout", type=duration, metavar="S",
                        help="seconds to wait for the joints to answer (default: 0.25, or 2.5 periods of the "
                             "slowest servo status rate)")


def run(args: argparse.Namespace) -> int:
    """Send the exit frames; list per joint what was sent and whether it answered."""
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    from akarm.cli.common import format_table
    from akarm.control.probe import release

    config = load_from_args(args)
    states = release(config, args.timeout)
    rows = [["joint", "mode", "bus/ID", "sent", "answer", "position (rad)"]]
    for s in states:
        sent = "zero-gain command + EXIT" if s.mode == "mit" else "zero current"
        if s.missing:
            answer = "none"
        else:
            answer = "disabled" if s.mode == "mit" else "status seen"
            if s.fault:
                answer += f", fault {s.fault_text()}"
        pos = "-" if s.position is None else f"{s.position:+.4f}"
        rows.append([s.name, s.mode, f"{s.bus}/{s.can_id}", sent, answer, pos])
    print(format_table(rows, [False, False, False, False, False, True]))
    missing = [s.name for s in states if s.missing]
    if missing:
        from akarm.buses.bus import no_answer_hint

        print(f"akarm disable: no answer from {', '.join(missing)} (its frames were sent; do not trust that it is "
              "off before it answers)", file=sys.stderr)
        for bus in dict.fromkeys(config.joint(name).bus for name in missing):
            print(f"  bus {bus!r}: {no_answer_hint(config.buses[bus])}", file=sys.stderr)
        return 1
    return 0


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """Ask the server to damp and disable the arm (it goes on serving)."""
    arm.call("disable")
    print(f"disabled {arm.config.name} through akarm serve (pid {arm.pid}): damped, then motor mode exited; "
          "the arm is limp, support it (akarm enable holds it again)")
    return 0
