"""What every example shares: the command line, and an Arm on the simulator or on the hardware.

Each example runs against akarm's simulator by default: a :class:`akarm.sim.SimulatedRobot` in the
same process, answering the real CAN protocol of every motor on a python-can *virtual* bus. The
:class:`akarm.Arm` cannot tell it from the hardware. ``--hardware`` uses the buses of the robot's
YAML instead (``-i``/``-c`` override them, as for the ``akarm`` command), and asks before moving.

``--fast`` runs the simulator in lock step with the control loop (``realtime=False``: the loop's
clock is the simulator's), so an example finishes as fast as the CPU allows; the tests use it.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from akarm import Arm
    from akarm.sim import SimulatedRobot

REPO = Path(__file__).resolve().parent.parent
ROBOTS = REPO / "robots"

# A simulator in this process shares the CPU (and Python's GIL) with the control loop, so a busy
# machine can delay its replies by more than the watchdog's 20 ms; hardware keeps the default.
SIM_FEEDBACK_TIMEOUT = 0.25  # s
# For the same reason the collision reflex's thresholds are doubled there: a reply that comes late
# reads like a push to its external torque estimate.
SIM_COLLISION_SCALE = 2.0


def parse_args(description: str, extra: list[tuple[tuple[str, ...], dict]] | None = None) -> argparse.Namespace:
    """The examples' common options (``--hardware``, ``-i``, ``-c``, ``--fast``) plus ``extra`` ones."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--hardware", action="store_true",
                        help="drive the real arm on the YAML's buses (default: the simulator, in this process)")
    parser.add_argument("-i", "--interface", help="with --hardware: python-can interface (e.g. socketcan)")
    parser.add_argument("-c", "--channel",
                        help="with --hardware: channel (e.g. can0, vcan0), or BUS=CHANNEL,... for several buses")
    parser.add_argument("--fast", action="store_true", help="simulator only: lock step, as fast as the CPU allows")
    for flags, kwargs in extra or []:
        parser.add_argument(*flags, **kwargs)
    args = parser.parse_args()
    if args.hardware and args.fast:
        parser.error("--fast is for the simulator; real hardware runs in real time")
    if not args.hardware and (args.interface or args.channel):
        parser.error("-i/-c choose the hardware's bus: add --hardware")
    return args


@contextlib.contextmanager
def open_arm(args: argparse.Namespace, robot: str, **arm_options) -> Iterator[tuple[Arm, SimulatedRobot | None]]:
    """Yield ``(arm, sim)`` for ``robots/<robot>.yaml``: ``sim`` is the SimulatedRobot, or ``None`` on hardware.

    The arm is open (its control loop runs) but not enabled. Leaving the block, by any exit, damps
    and disables it. ``arm_options`` go to :class:`akarm.Arm` (e.g. ``feedforward="gravity"``).
    """
    import akarm
    from akarm.config import parse_channel
    from akarm.sim import SimulatedRobot

    config = akarm.load_robot(ROBOTS / f"{robot}.yaml")
    if args.hardware:
        if args.interface or args.channel:
            config = config.with_bus(interface=args.interface, channel=parse_channel(args.channel))
        buses = ", ".join(f"{b.interface} {b.channel}" for b in config.buses.values())
        print(f"hardware: {config.name} on {buses}. The arm will move: clear its workspace, keep the e-stop in reach.")
        input("Press Enter to start (Ctrl-C to abort) ")
        with akarm.Arm(config, **arm_options) as arm:
            yield arm, None
        return
    # One virtual channel per bus, unique to this process (virtual buses with the same name are connected).
    config = config.with_bus(interface="virtual", channel=f"example-{os.getpid()}")
    mode = "lock step" if args.fast else "real time"
    buses = "a virtual CAN bus" if len(config.buses) == 1 else f"{len(config.buses)} virtual CAN buses"
    print(f"simulator: {config.name} on {buses} in this process ({mode}); --hardware for the real arm")
    with SimulatedRobot(config, realtime=not args.fast) as sim:
        if args.fast:
            arm = akarm.Arm(config, clock=sim.clock, **arm_options)
        else:
            arm = akarm.Arm(config, feedback_timeout=SIM_FEEDBACK_TIMEOUT, **arm_options)
            arm.set_collision(thresholds={n: t * SIM_COLLISION_SCALE
                                          for n, t in arm.collision_thresholds.items() if t is not None})
        with arm:
            yield arm, sim


def run(main: Callable[[], int | None]) -> None:
    """Run an example's ``main()`` and exit with its status: an akarm error is one line, not a traceback.

    Every error akarm raises on purpose says which joint, what went wrong and what to do about it.
    """
    from akarm import AkarmError

    try:
        code = main()
    except AkarmError as e:
        print(f"error: {e}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt:
        print("interrupted: the arm was damped and disabled", file=sys.stderr)
        code = 130
    raise SystemExit(code or 0)
