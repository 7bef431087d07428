"""What the verbs share: the robot YAML and python-can style bus overrides, tables, and driving an
Arm so that it always ends damped and disabled (:func:`controlled`, :func:`stop_smoothly`,
:func:`deferred_signals`), and the exit status of an interrupted verb (:func:`interrupted`)."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from akarm.arm import Arm
    from akarm.config import RobotConfig


def add_robot_arguments(parser: argparse.ArgumentParser, robot_required: bool = True) -> None:
    """Add ``ROBOT`` (the YAML) and ``-i/--interface``, ``-c/--channel``, ``-b/--bitrate``, ``--bus-kwargs``."""
    from akarm.cli.options import add_bus_kwargs, bitrate, interface

    parser.add_argument("robot", metavar="ROBOT.yaml", nargs=None if robot_required else "?",
                        help="the robot's YAML configuration")
    parser.add_argument("-i", "--interface", type=interface,
                        help="python-can interface for every bus (e.g. socketcan, virtual)")
    parser.add_argument("-c", "--channel", help="channel (one bus), or NAME=CHANNEL[,NAME=CHANNEL...] per bus")
    parser.add_argument("-b", "--bitrate", type=bitrate, help="bit rate, bit/s (10000-1000000)")
    add_bus_kwargs(parser)


def add_profile_argument(parser: argparse.ArgumentParser, loop: bool = True, arm_id: bool = True) -> None:
    """Add ``--profile NAME``: the timing profile (:mod:`akarm.timing`) of a verb that runs a loop or a
    simulator; and, where the verb runs a control loop (``loop``), ``--stall-limit S`` and (``arm_id``,
    a verb that drives one arm) ``--id ID`` (:func:`loop_options` gives them to the :class:`~akarm.Arm`)."""
    from akarm.cli.options import duration
    from akarm.timing import PROFILES

    parser.add_argument("--profile", default="normal", choices=list(PROFILES), metavar="NAME",
                        help="timing profile: " + "; ".join(f"{p.name}: {p.description}" for p in PROFILES.values()))
    if loop:
        parser.add_argument("--stall-limit", type=duration, metavar="S",
                            help="s the control loop itself may fail to run (this process stopped or starved) and "
                                 "resume without a stop; longer stops the arm with LoopStall (default: the "
                                 "profile's, 0.2 s normally)")
        if arm_id:
            parser.add_argument("--id", dest="arm_id", metavar="ID",
                                help="the physical arm's name (as LeRobot's --robot.id): where each joint stopped "
                                     "is remembered under it (the turn check at enable); default: the robot file's "
                                     "name with its buses, channels and CAN IDs")


def loop_options(args: argparse.Namespace) -> dict[str, Any]:
    """The :class:`~akarm.Arm` options of :func:`add_profile_argument`'s arguments."""
    out = {"timing": args.profile, "stall_limit": args.stall_limit}
    if getattr(args, "arm_id", None) is not None:
        out["arm_id"] = args.arm_id
    return out


def load_from_args(args: argparse.Namespace, rate_hz: float | None = None) -> RobotConfig:
    """The robot config named on the command line, with its bus overrides applied (and the loop rate
    ``rate_hz``, checked against the bus load like the file's own); the loader's ConfigWarnings are
    printed as ``warning: ...`` lines on stderr."""
    import warnings

    from akarm.config import parse_channel
    from akarm.errors import ConfigWarning
    from akarm.robotfile.load import load_robot

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConfigWarning)
        config = load_robot(args.robot, rate_hz=rate_hz)
    for w in caught:
        if issubclass(w.category, ConfigWarning):
            print(f"warning: {w.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    kwargs = getattr(args, "bus_kwargs", None) or None
    if args.interface is not None or args.channel or args.bitrate is not None or kwargs:
        config = config.with_bus(interface=args.interface, channel=parse_channel(args.channel),
                                 bitrate=args.bitrate, options=kwargs)
    return config


def format_table(rows: Sequence[Sequence[str]], right: Sequence[bool] | None = None) -> str:
    """Rows of text as an aligned table; the first row is the header, underlined.

    ``right`` says per column whether to right-align it (numbers); default left.
    """
    n = len(rows[0])
    right = list(right) if right is not None else [False] * n
    widths = [max(len(r[i]) for r in rows) for i in range(n)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) if r else c.ljust(w) for c, w, r in zip(cells, widths, right, strict=True))

    out = [line(rows[0]).rstrip(), "  ".join("-" * w for w in widths)]
    out += [line(r).rstrip() for r in rows[1:]]
    return "\n".join(out)


def deferred_signals(message: str = "stopping the arm safely; please wait") -> contextlib.AbstractContextManager[None]:
    """While inside, Ctrl-C, SIGTERM and SIGHUP do not interrupt (``message`` is printed instead):
    the arm's stop must not be cut short. Main thread only (:func:`akarm.signals.deferred`)."""
    from akarm import signals

    return signals.deferred(message)


@contextlib.contextmanager
def controlled(arm: Arm | RobotConfig, **options: Any) -> Iterator[Arm]:
    """``arm`` (or a new :class:`~akarm.Arm` for a config, with ``options``), opened; on leaving (error
    and Ctrl-C included) it is damped, disabled and closed, and a Ctrl-C meanwhile does not cut that short."""
    from akarm.arm import Arm

    if not isinstance(arm, Arm):
        arm = Arm(arm, **options)
    arm.open()
    try:
        yield arm
    finally:
        with deferred_signals():
            arm.close()


def stop_smoothly(arm: Arm) -> None:
    """Bring a moving arm to rest (jerk-limited), then damp and disable it; Ctrl-C cannot interrupt it.

    Errors while stopping (a joint that faulted meanwhile) are not raised: the arm ends disabled anyway.
    """
    from akarm.errors import AkarmError

    with deferred_signals():
        if arm.enabled and arm.moving:
            with contextlib.suppress(AkarmError):
                arm.stop(wait=True)
        with contextlib.suppress(AkarmError):
            arm.disable()


def interrupted(e: KeyboardInterrupt) -> int:
    """The exit status of a verb ended by Ctrl-C (130) or a signal (128 + its number)."""
    from akarm import signals

    return signals.exit_code(e)


def format_q(q: Sequence[float] | np.ndarray) -> str:
    """Joint positions as ``[+0.1000, -0.2000] rad``."""
    return "[" + ", ".join(f"{x:+.4f}" for x in q) + "] rad"
