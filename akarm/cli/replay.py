"""``akarm replay ROBOT.yaml FILE``: replay a taught recording, checked against the limits first.

::

    akarm replay robots/arm6.yaml pick.yaml              # keyframes: one smooth move through them
    akarm replay robots/arm6.yaml path.csv --speed 0.5   # a path, at half its recorded speed

The whole path is checked (position, velocity, acceleration and jerk of every joint, after the
speed factor) before the arm is even enabled: a violation names the joint, the time and a speed
factor that would pass, and nothing moves (exit 1). A soft start first moves the arm to the
recording's first pose. A progress bar is drawn on stderr when it is a terminal. Ctrl-C brings the
arm to rest smoothly, then disables it (exit 130).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING

from akarm.cli.common import add_profile_argument, add_robot_arguments, load_from_args

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("file", metavar="FILE", help="a recording from akarm teach: keyframes .yaml or path .csv")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="paths: recorded speed × F (any F > 0); keyframes: fraction of the joint limits, "
                             "at most 1 (default 1)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv or .npz) for akarm plot")
    add_profile_argument(parser)


def check_options(args: argparse.Namespace) -> None:
    """The options a replay checks before anything moves (here or through akarm serve)."""
    from akarm.cli.options import TELEMETRY_SUFFIXES, check_output
    from akarm.errors import ArgumentError

    if not args.speed > 0:
        raise ArgumentError(f"--speed {args.speed} must be positive", fix="e.g. --speed 0.5")
    check_output(args.log, TELEMETRY_SUFFIXES, "telemetry")


def run(args: argparse.Namespace) -> int:
    """Load and check the recording, then enable, replay with progress, disable."""
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    from tqdm import tqdm

    from akarm.arm import Arm
    from akarm.cli.common import controlled, deferred_signals, interrupted, stop_smoothly
    from akarm.motion.recording import Keyframes, load

    check_options(args)
    config = load_from_args(args)
    rec = load(args.file, config.joint_names)
    arm = Arm(config, timing=args.profile)
    arm.check_replay(rec, args.speed)  # the whole path, before anything is enabled
    kind = f"{len(rec.frames)} keyframes" if isinstance(rec, Keyframes) else f"a {rec.duration:.2f} s path"
    code = 0
    with controlled(arm):
        t0 = arm.clock.now()
        try:
            arm.enable()
            motion = arm.replay(rec, speed=args.speed, wait=False)
            print(f"replaying {args.file} ({kind}) in {motion.duration:.2f} s at speed {args.speed:g}", flush=True)
            bar = tqdm(total=round(motion.duration, 2), unit="s", file=sys.stderr, disable=not sys.stderr.isatty(),
                       bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s")
            with bar:
                start = arm.clock.now()
                while not motion.done:
                    arm.sleep(0.1)
                    bar.n = round(min(arm.clock.now() - start, motion.duration), 2)
                    bar.refresh()
                bar.n = motion.duration
            motion.wait()
        except KeyboardInterrupt as e:
            stop_smoothly(arm)
            print("interrupted: stopped and disabled", file=sys.stderr)
            code = interrupted(e)
        else:
            rms = arm.telemetry(since=t0).rms_error()
            with deferred_signals():
                arm.disable()
            print("done; RMS tracking error " + ", ".join(f"{n} {e * 1e3:.2f} mrad"
                                                          for n, e in zip(arm.names, rms, strict=True)))
        if args.log:
            print(f"telemetry saved to {arm.telemetry(since=t0).save(args.log)}")
    return code


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """The replay through ``akarm serve``: as without it, but the server holds the arm afterwards."""
    from akarm.cli.common import interrupted

    check_options(args)  # before anything moves
    path = os.path.abspath(args.file)
    arm.call("check_replay", path=path, speed=args.speed)  # the whole path, before anything moves
    try:
        arm.call("ready")  # refused while a safety stop is latched; a disabled arm is enabled
        motion = arm.call("replay", path=path, speed=args.speed)
        print(f"replaying {args.file} ({motion['kind']}) in {motion['duration']:.2f} s at speed {args.speed:g}",
              flush=True)
        arm.wait(motion)
    except KeyboardInterrupt as e:  # Ctrl-C, SIGTERM, SIGHUP
        arm.interrupt()
        print(f"interrupted: stopped; {arm.held}", file=sys.stderr)
        return interrupted(e)
    tel = arm.call("telemetry", since=motion["t0"], save=os.path.abspath(args.log) if args.log else None)
    print("done; RMS tracking error " + ", ".join(f"{n} {e * 1e3:.2f} mrad"
                                                  for n, e in zip(arm.names, tel["rms"], strict=True)))
    if tel["path"]:
        print(f"telemetry saved to {tel['path']}")
    print(arm.held)
    return 0
