"""``akarm plot LOG``: a PNG of a telemetry log: per joint, desired vs measured position, tracking
error and torque (measured and feed-forward).

::

    akarm move robots/planar2.yaml up --log up.csv
    akarm plot up.csv                  # writes up.png
    akarm plot up.npz -o /tmp/up.png

Logs come from ``--log`` of ``akarm move`` / ``akarm replay`` / ``akarm teleop`` or
``Arm.telemetry().save()`` (``.csv``, ``.npz`` or ``.mcap``). An MCAP file of several arms (a
teleoperation session's leader and follower) gives one PNG per arm, ``LOG-ARM.png``. Needs matplotlib
(``pip install "akarm[plot]"``).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    parser.add_argument("log", metavar="LOG", help="a telemetry log, .csv, .npz or .mcap")
    parser.add_argument("-o", "--output", metavar="OUT.png", help="the PNG to write (default: LOG with .png)")
    parser.add_argument("--title", help="the figure's title (default: cycles and duration)")


def run(args: argparse.Namespace) -> int:
    """Load the log, draw it, print where the PNG went."""
    from akarm.telemetry.log import TelemetryLog, load
    from akarm.telemetry.plot import plot_log

    out = Path(args.output) if args.output else Path(args.log).with_suffix(".png")
    logs: dict[str, TelemetryLog]
    if Path(args.log).suffix == ".mcap":
        from akarm.telemetry.log import load_mcap

        logs = load_mcap(args.log)
    else:
        logs = {"": load(args.log)}
    for arm, log in logs.items():
        target = out if len(logs) == 1 else out.with_name(f"{out.stem}-{arm}{out.suffix}")
        title = args.title if args.title is None or len(logs) == 1 else f"{args.title} ({arm})"
        if title is None and arm:
            duration = float(log.t[-1] - log.t[0]) if len(log) else 0.0
            title = f"akarm telemetry, {arm}: {len(log)} cycles, {duration:.2f} s"
        path = plot_log(log, target, title=title)
        duration = float(log.t[-1] - log.t[0]) if len(log) else 0.0
        print(f"wrote {path} ({len(log.joint_names)} joints, {len(log)} cycles, {duration:.2f} s)")
    return 0
