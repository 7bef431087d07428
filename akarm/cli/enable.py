"""``akarm enable ROBOT.yaml``: enable the arm without a kick and hold it where it is until Ctrl-C.

::

    akarm enable robots/arm6.yaml               # hold until Ctrl-C, then damp and disable
    akarm enable robots/arm6.yaml --seconds 10  # hold for 10 s

Exit status 0 after ``--seconds``, 130 after Ctrl-C (the arm is disabled either way), 1 on an error
(a joint that does not answer, a motor fault, ...).

This module also holds what the verbs that drive the arm share: :func:`controlled` (open an Arm
and always close it, damped and disabled, even through a second Ctrl-C), :func:`stop_smoothly`
and :func:`deferred_sigint`.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

from .common import add_robot_arguments, load_from_args

if TYPE_CHECKING:
    from ..arm import Arm
    from ..config import RobotConfig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("--seconds", type=float, metavar="S", help="hold for S seconds, then disable "
                        "(default: until Ctrl-C)")


@contextlib.contextmanager
def deferred_sigint(message: str = "stopping the arm safely; please wait") -> Iterator[None]:
    """While inside, Ctrl-C does not interrupt (``message`` is printed instead). Main thread only;
    elsewhere (signals cannot be handled there) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    told: list[int] = []

    def handler(signum: int, frame: object) -> None:
        if not told:
            print(message, file=sys.stderr, flush=True)
        told.append(signum)

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def controlled(arm: Arm | RobotConfig) -> Iterator[Arm]:
    """``arm`` (or a new :class:`~akarm.Arm` for a config), opened; on leaving (error and Ctrl-C
    included) it is damped, disabled and closed, and a Ctrl-C meanwhile does not cut that short."""
    from ..arm import Arm

    if not isinstance(arm, Arm):
        arm = Arm(arm)
    arm.open()
    try:
        yield arm
    finally:
        with deferred_sigint():
            arm.close()


def stop_smoothly(arm: Arm) -> None:
    """Bring a moving arm to rest (jerk-limited), then damp and disable it; Ctrl-C cannot interrupt it.

    Errors while stopping (a joint that faulted meanwhile) are not raised: the arm ends disabled anyway.
    """
    from ..errors import AkarmError

    with deferred_sigint():
        if arm.enabled and arm.moving:
            with contextlib.suppress(AkarmError):
                arm.stop(wait=True)
        with contextlib.suppress(AkarmError):
            arm.disable()


def format_q(q: Sequence[float]) -> str:
    """Joint positions as ``[+0.1000, -0.2000] rad``."""
    return "[" + ", ".join(f"{x:+.4f}" for x in q) + "] rad"


def run(args: argparse.Namespace) -> int:
    """Enable, hold until Ctrl-C or ``--seconds``, disable."""
    from ..errors import AkarmError

    if args.seconds is not None and not args.seconds >= 0:
        raise AkarmError(f"--seconds {args.seconds} must not be negative")
    config = load_from_args(args)
    with controlled(config) as arm:
        try:
            arm.enable()
            until = f"for {args.seconds:g} s" if args.seconds is not None else "until Ctrl-C"
            print(f"enabled {config.name}: holding at {format_q(arm.state().q)} ({', '.join(arm.names)}) {until}",
                  flush=True)
            if args.seconds is not None:
                arm.sleep(args.seconds)
            else:
                while True:
                    arm.sleep(1.0)
        except KeyboardInterrupt:
            stop_smoothly(arm)
            print("interrupted: the arm is disabled", file=sys.stderr)
            return 130
        with deferred_sigint():
            arm.disable()
        print("disabled")
    return 0
