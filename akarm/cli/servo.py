"""``akarm servo ROBOT.yaml --spacemouse``: steer the tool live with a 3Dconnexion SpaceMouse.

::

    akarm servo robot.yaml --spacemouse                      # 50 mm/s and 0.3 rad/s at full deflection
    akarm servo robot.yaml --spacemouse --speed 0.1 --rotation 0.5 --frame tool

The arm is enabled and servoed (:meth:`akarm.Arm.servo`): the puck's six axes, each in [-1, 1] past a
dead band, are the tool's twist, scaled to ``--speed`` (m/s) and ``--rotation`` (rad/s); letting go
brings it to rest, holding. Near a singularity, a joint limit or a wall of ``workspace:`` it slows and
stops (the status line says why). Ctrl-C, SIGTERM or SIGHUP: it comes to rest, then is damped and
disabled. The SpaceMouse is read through ``pyspacemouse`` (the ``spacemouse`` extra:
``pip install 'akarm[spacemouse]'``; it needs hidapi's library, ``libhidapi-hidraw0`` on Debian).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import Any

from akarm.cli.common import add_profile_argument, add_robot_arguments, interrupted, loop_options

__all__ = ["add_arguments", "run", "twist_from_axes"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("--spacemouse", action="store_true", help="steer with a 3Dconnexion SpaceMouse (pyspacemouse)")
    parser.add_argument("--speed", type=float, default=0.05, metavar="M_S",
                        help="tool speed at full deflection, m/s (default 0.05)")
    parser.add_argument("--rotation", type=float, default=0.3, metavar="RAD_S",
                        help="tool rotation at full deflection, rad/s (default 0.3)")
    parser.add_argument("--deadband", type=float, default=0.1, metavar="F",
                        help="the share of each axis's travel that does nothing (default 0.1)")
    parser.add_argument("--frame", choices=["base", "tool"], default="base", help="the twist's axes (default base)")
    parser.add_argument("--command-rate", type=float, default=100.0, metavar="HZ",
                        help="commands per second (default 100)")
    add_profile_argument(parser)


def twist_from_axes(axes: Sequence[float], speed: float, rotation: float, deadband: float) -> list[float]:
    """The twist ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s) for a puck's six axes (x, y, z, roll, pitch,
    yaw), each in [-1, 1]: nothing within ``deadband``, then linear to ``speed`` / ``rotation`` at full
    deflection (a value outside [-1, 1] counts as the nearest end, NaN as 0)."""
    out = []
    for k, a in enumerate(axes):
        x = float(a)
        x = 0.0 if math.isnan(x) else max(-1.0, min(1.0, x))
        size = max(0.0, abs(x) - deadband) / (1.0 - deadband) if deadband < 1.0 else 0.0
        out.append(math.copysign(size, x) * (speed if k < 3 else rotation))
    return out


def _open_spacemouse() -> Any:
    from akarm.errors import AkarmError

    try:
        import pyspacemouse
    except ImportError:
        raise AkarmError("reading a SpaceMouse needs pyspacemouse", fix="pip install 'akarm[spacemouse]' (and "
                         "hidapi's library: libhidapi-hidraw0 on Debian)") from None
    if not pyspacemouse.open():
        raise AkarmError("no SpaceMouse found", fix="plug it in; on Linux, let your user read it (a udev rule "
                         "for /dev/hidraw*)")
    return pyspacemouse


def run(args: argparse.Namespace) -> int:
    """Enable, servo from the SpaceMouse until Ctrl-C, come to rest, disable."""
    from akarm.cli.common import controlled, load_from_args, stop_smoothly
    from akarm.errors import ArgumentError, finite_number

    if not args.spacemouse:
        raise ArgumentError("say what steers the arm", fix="akarm servo ROBOT.yaml --spacemouse")
    speed = finite_number(args.speed, "--speed", above=0.0, unit="m/s")
    rotation = finite_number(args.rotation, "--rotation", above=0.0, unit="rad/s")
    deadband = finite_number(args.deadband, "--deadband", at_least=0.0, at_most=0.9)
    rate = finite_number(args.command_rate, "--command-rate", above=0.0, at_most=1000.0, unit="Hz")
    mouse = _open_spacemouse()
    config = load_from_args(args)
    try:
        with controlled(config, **loop_options(args)) as arm:
            arm.enable()
            said = ""
            try:
                with arm.servo(timeout=max(0.1, 3.0 / rate), frame=args.frame, max_speed=speed,
                               max_rotation=rotation) as s:
                    while True:
                        st = mouse.read()
                        s.twist(twist_from_axes([st.x, st.y, st.z, st.roll, st.pitch, st.yaw], speed, rotation,
                                                deadband))
                        arm.sleep(1.0 / rate)
                        now = f"{s.status.state} {s.status.reason}".strip()
                        if now != said:
                            print(now, flush=True)
                            said = now
            finally:
                stop_smoothly(arm)
    except KeyboardInterrupt as e:
        return interrupted(e)
    return 0
