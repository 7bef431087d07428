"""``akarm scan [ROBOT.yaml]``: which CAN IDs answer on a bus, and in which mode.

::

    akarm scan -i socketcan -c can0 --ids 1-32     # any bus, no robot file needed
    akarm scan robots/arm6.yaml                    # every bus of the robot; names the joints found

MIT motors are found by sending EXIT to each ID (every MIT frame is answered; EXIT leaves the motor
in rest mode, so scan an arm that is supported or resting). Servo motors are heard from the status
frames they send on their own: ``--listen`` must cover a period of the slowest status rate.
A MIT motor whose replies are already flowing (a controller is driving it) is listed and left alone.

Positions are motor side (rad at the output): decoded with the configured motor model when a robot
file is given, else with the ±12.5 rad MIT range and output-side servo degrees.
Two motors on one ID (more than one reply to one EXIT, or servo status frames at two positions) and,
with a robot file, a motor in the other mode than its joint's are named on stderr ("wiring: ...").

Exit status 0 when something answered (and, with a robot file, every configured joint did, in its
mode, alone on its ID), else 1.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from akarm.cli.common import add_robot_arguments, load_from_args
from akarm.cli.options import delay

if TYPE_CHECKING:
    from akarm.config import BusConfig, JointConfig
    from akarm.control.probe import Found


def parse_ids(text: str) -> list[int]:
    """``"1-32"``, ``"1,3,5-7"`` → the list of IDs; ``argparse.ArgumentTypeError`` if malformed."""
    ids: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                lo, hi = (int(x) for x in part.split("-", 1))
                if lo > hi:
                    raise ValueError
                ids.extend(range(lo, hi + 1))
            else:
                ids.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of IDs like 1-32 or 1,3,5-7") from None
    if not all(1 <= i <= 255 for i in ids):
        raise argparse.ArgumentTypeError(f"{text!r}: CAN IDs are 1-255")
    return ids


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser, robot_required=False)
    parser.add_argument("--ids", type=parse_ids, default=list(range(1, 128)), metavar="IDS",
                        help="CAN IDs to look for, e.g. 1-32 or 1,3,5-7 (default 1-127)")
    parser.add_argument("--listen", type=delay, default=0.3, metavar="S",
                        help="seconds to listen for servo status frames before querying (default 0.3: "
                             "motors sending at 4 Hz or more)")
    parser.add_argument("--timeout", type=delay, default=0.1, metavar="S",
                        help="seconds to wait for MIT replies after the last query (default 0.1)")


def _bus_from_args(args: argparse.Namespace) -> BusConfig:
    """Without a robot file: the bus of ``-i/-c/-b/--bus-kwargs``, completed from python-can's own
    configuration (CAN_INTERFACE, CAN_CHANNEL, can.conf, ...), as python-can's tools do."""
    from akarm.config.canconfig import python_can_settings, resolve_bus
    from akarm.errors import AkarmError, ArgumentError

    if args.channel and "=" in args.channel:
        raise ArgumentError("-c NAME=CHANNEL needs a robot file", fix="give one channel, e.g. -c can0")
    try:
        settings = python_can_settings()
    except ValueError as e:
        raise AkarmError(str(e), fix="fix CAN_CONFIG or the can.conf/.canrc file, or give -i and -c") from None
    given = {k: v for k, v in (("interface", args.interface), ("channel", args.channel), ("bitrate", args.bitrate))
             if v is not None}
    given.update(args.bus_kwargs)
    if not given.get("interface", settings.get("interface")) or not given.get("channel", settings.get("channel")):
        raise ArgumentError("without a robot file, give the bus: -i INTERFACE -c CHANNEL (or configure python-can: "
                            "CAN_INTERFACE and CAN_CHANNEL, or ~/can.conf)", fix="e.g. akarm scan -i socketcan -c can0")
    bus, found = resolve_bus("bus", given, settings)
    if bus is None:
        raise AkarmError("; ".join(message for _, message, _ in found), fix=found[0][2])
    return bus


def _row(bus: BusConfig, f: Found, j: JointConfig | None, wrong: list[str]) -> list[str]:
    """The table's row for what answered, ``j`` the joint configured on its ID; wiring mistakes go to ``wrong``."""
    note = ""
    if j is not None:
        note = j.name
        if j.mode != f.mode:
            note += f" (configured as {j.mode}!)"
            wrong.append(f"joint {j.name!r} is configured as {j.mode}, but the motor on CAN ID {f.can_id} "
                         f"(bus {bus.name!r}) is in {f.mode} mode: switch the motor's mode, or the joint's")
    if f.duplicate:
        note = (note + " " if note else "") + "[TWO MOTORS on this ID]"
        wrong.append(f"two motors answer on CAN ID {f.can_id} (bus {bus.name!r}): give each its own ID")
    if f.active:
        note = (note + " " if note else "") + "[being driven: left alone]"
    temp = "-" if f.temperature is None else f"{f.temperature:.0f}"
    return [bus.channel, str(f.can_id), f.mode, f"0x{f.reply_id:X}", f"{f.position:+.4f}", temp, f.fault_text(), note]


def run(args: argparse.Namespace) -> int:
    """Scan the bus(es); print a table of what answered."""
    from akarm.cli.common import format_table
    from akarm.control.probe import scan
    from akarm.errors import AkarmError

    if args.robot is None:
        buses = [_bus_from_args(args)]
        joints = []
    else:
        config = load_from_args(args)
        buses = [config.buses[name] for name in config.buses if any(j.bus == name for j in config.joints)]
        joints = list(config.joints)

    from akarm.buses.ownership import refuse_if_served

    refuse_if_served(buses, "akarm scan")  # its EXIT frames would disable the arm a running server holds
    rows = [["bus", "CAN ID", "mode", "reply ID", "position (rad)", "temperature (°C)", "fault", "joint"]]
    answered: set[tuple[str, int]] = set()
    wrong: list[str] = []  # wiring mistakes: named, and the exit status is 1
    for bus in buses:
        mine = {j.can_id: j for j in joints if j.bus == bus.name}
        for f in scan(bus, args.ids, timeout=args.timeout, listen=args.listen,
                      models={i: j.motor for i, j in mine.items()}):
            answered.add((bus.name, f.can_id))
            rows.append(_row(bus, f, mine.get(f.can_id), wrong))
    if len(rows) > 1:
        print(format_table(rows, [False, True, False, True, True, True, False, False]))
    lost = [j for j in joints if (j.bus, j.can_id) not in answered and j.can_id in args.ids]
    for j in lost:
        print(f"not found: joint {j.name!r} ({j.mode}, ID {j.can_id} on bus {j.bus!r})", file=sys.stderr)
    if len(rows) == 1:
        from akarm.buses.bus import no_answer_hint

        hints = "; ".join(dict.fromkeys(no_answer_hint(b) for b in buses))
        raise AkarmError("no motor answered", fix=f"{hints}; servo motors must have status frames on (or listen "
                         "longer: --listen 1)")
    for text in wrong:
        print(f"wiring: {text}", file=sys.stderr)
    return 1 if lost or wrong else 0

