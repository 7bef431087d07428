"""``akarm sim ROBOT.yaml``: simulate a robot's AK drivers on a CAN bus until Ctrl-C.

Point a controller (or ``candump``) at the bus exactly as at the hardware::

    akarm sim robots/planar2.yaml -i socketcan -c vcan0
    akarm sim robots/arm6.yaml -i socketcan -c vcan0 --fault elbow:drop:0.3 --fault wrist_roll:error:1
    akarm sim robots/arm6.yaml -i socketcan -c vcan0 --profile slow --control /tmp/arm6.sock

``--serial JOINT=PATH`` puts a servo joint's simulated driver on a serial port instead of its CAN bus,
speaking the UART protocol (:mod:`akarm.sim.uart`): ``JOINT=pty`` makes a pseudo-terminal pair and
prints the path a controller opens (``serial JOINT: /dev/pts/N``); a device's path is opened at
``--baudrate`` (e.g. a USB-UART adapter cabled to the controller's, or one end of a ``socat`` pair)::

    akarm sim robots/servo3.yaml -i akarm_local -c can0 --serial elbow=pty

``--profile slow`` integrates at a rate a slow or shared machine keeps up with (see
:mod:`akarm.timing`). ``--control PATH`` serves a control channel on that Unix-domain socket, through
which another program injects and clears faults, reads the drivers and disables them while the
simulator runs (:class:`akarm.sim.channel.SimulatorControl`). ``--view`` serves the live view of the
simulated truth: the plant's positions and torques, the drivers' temperatures (:mod:`akarm.cli.view`).

Runs in real time until SIGINT or SIGTERM (exit status 0), or for ``--seconds``, with a live status
line (per joint position, torque, temperature, state): updated in place a few times a second on a
terminal, one line a second otherwise. A status line wider than the terminal (80 columns when it
cannot tell) is shown one joint per line.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING, Any

from akarm.cli.common import add_profile_argument, add_robot_arguments, load_from_args

if TYPE_CHECKING:
    from akarm.config import RobotConfig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import delay, renamed
    from akarm.sim.faults import KINDS  # light: no numpy, no python-can

    add_robot_arguments(parser)
    parser.add_argument("--fault", action="append", default=[], metavar="JOINT:KIND[:ARG]",
                        help="inject a fault at start (repeatable); KIND: " + "; ".join(KINDS.values()))
    parser.add_argument("--serial", action="append", default=[], metavar="JOINT=PATH",
                        help="the simulated driver of servo joint JOINT answers on this serial port instead of CAN "
                             "(repeatable); PATH 'pty' makes a pseudo-terminal pair and prints the path to open")
    parser.add_argument("--baudrate", type=int, default=921_600, metavar="BAUD",
                        help="bit/s of the --serial devices (default 921600, the AK drivers'; a pty ignores it)")
    parser.add_argument("--seconds", type=delay, metavar="S", help="stop after S seconds (default: run until Ctrl-C)")
    parser.add_argument("--plant-rate", type=float, metavar="HZ",
                        help="plant integration rate, Hz (default: the timing profile's; 2000 normally)")
    renamed(parser, "--duration", "--seconds")
    renamed(parser, "--rate", "--plant-rate")
    add_profile_argument(parser, loop=False)
    parser.add_argument("--control", metavar="PATH",
                        help="serve a control channel on this Unix-domain socket: inject and clear faults, read "
                             "and disable the drivers from another program (akarm.sim.channel)")
    parser.add_argument("--object", type=float, metavar="WIDTH",
                        help="an object WIDTH m wide between the gripper's jaws (a robot with a gripper)")
    parser.add_argument("--object-stiffness", type=float, default=20_000.0, metavar="N/M",
                        help="the object's stiffness (default 20000 N/m)")
    parser.add_argument("--pose", metavar="NAME", help="start the arm at this named pose (default: all zeros)")
    parser.add_argument("--zero-silence", type=delay, default=1.0, metavar="S",
                        help="MIT: seconds off-line after a ZERO frame (default 1.0)")
    parser.add_argument("--servo-release", type=delay, default=1.0, metavar="S",
                        help="servo: seconds after the last command the output is released (default 1.0)")
    parser.add_argument("--status-hz", type=float, default=4.0, metavar="HZ",
                        help="status line updates per second on a terminal (default 4; 1 when not a terminal)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no status line")
    parser.add_argument("--realtime-priority", action="store_true",
                        help="run the simulator's threads at real-time priority (SCHED_FIFO; root or ulimit -r), "
                             "with a 0.2 ms interpreter switch interval: on a loaded machine a simulator at normal "
                             "priority may read its bus tens of ms late, and the controller's watchdog stops the arm")
    parser.add_argument("--vary", type=int, metavar="SEED",
                        help="simulate a real unit, not the robot file's model: torque constants, friction, "
                             "backlash, masses and reply jitter drawn from SEED (akarm.sim.Variation)")
    from akarm.cli.view import add_view_options

    add_view_options(parser)


def _describe(config: RobotConfig, serial: dict[str, str]) -> str:
    lines = [f"akarm sim: simulating {config.name} ({len(config.joints)} joints)"]
    for name, b in config.buses.items():
        joints = ", ".join(f"{j.name} (id {j.can_id}, {j.mode}{' v3' if j.firmware == 'v3' else ''}, {j.motor.name})"
                           for j in config.motors if j.bus == name and j.name not in serial)
        if joints:
            lines.append(f"  bus {name}: {b.interface} {b.channel}: {joints}")
    for joint, path in serial.items():  # SimulatorProcess reads these lines
        j = config.joint(joint)
        lines.append(f"  serial {joint}: {path}   (id {j.can_id}, servo over UART, {j.motor.name})")
    return "\n".join(lines)


def parse_serial(specs: list[str]) -> dict[str, str]:
    """``--serial JOINT=PATH`` options as ``{joint: path}``.

    Raises:
        AkarmError: a spec without ``=``, or a joint given twice.
    """
    from akarm.errors import AkarmError

    out: dict[str, str] = {}
    for spec in specs:
        joint, sep, path = spec.partition("=")
        if not sep or not joint or not path:
            raise AkarmError(f"bad --serial {spec!r}: expected JOINT=PATH", fix="e.g. --serial elbow=pty")
        if joint in out:
            raise AkarmError(f"--serial gives joint {joint!r} twice", fix="one serial port per joint")
        out[joint] = path
    return out


def status_block(line: str, width: int) -> list[str]:
    """The simulator's status line as it fits ``width`` columns: as it is when it fits, else one line
    for the time and one per joint (cut to the width if even that is too wide)."""
    if len(line) < width:
        return [line]
    parts = line.split(" | ")
    return [parts[0]] + ["  " + p[: width - 3] for p in parts[1:]]


# C901 18 > 12, left as it was: the sim verb: a branch per option and per way the simulator stops
def run(args: argparse.Namespace) -> int:  # noqa: C901
    """Run the simulator until SIGINT/SIGTERM or ``--seconds``; 0 on a clean stop."""
    import contextlib
    import shutil
    import signal
    import sys
    import threading
    import time

    from akarm.errors import AkarmError
    from akarm.sim import SimulatedRobot, Variation, faults
    from akarm.sim.channel import ChannelServer

    config = load_from_args(args)
    serial = parse_serial(args.serial)
    injected = [faults.parse(spec) for spec in args.fault]
    for joint, _ in injected:
        config.joint(joint)  # ConfigError naming the joints when there is no such joint
    q0 = config.pose(args.pose) if args.pose else None
    if args.object is not None and config.gripper is None:
        raise AkarmError(f"--object: robot {config.name!r} has no gripper",
                         fix="describe one under `gripper:` in the robot file, or leave --object out")
    if args.plant_rate is not None and not args.plant_rate > 0:
        raise AkarmError(f"--plant-rate {args.plant_rate} must be positive", fix="e.g. --plant-rate 2000")
    if args.seconds is not None and not args.seconds >= 0:
        raise AkarmError(f"--seconds {args.seconds} must not be negative")
    sim = SimulatedRobot(config, realtime=True, dt=1.0 / args.plant_rate if args.plant_rate else None, q0=q0,
                         zero_silence=args.zero_silence, servo_release=args.servo_release, timing=args.profile,
                         log_frames=bool(args.control), serial=serial, baudrate=args.baudrate,
                         variation=None if args.vary is None else Variation(seed=args.vary))
    view = None
    if args.view:  # made first: a missing view extra is said before the simulator starts
        from akarm.cli.view import make_view_process
        from akarm.view.sources import SimSource

        view = make_view_process(args, sim.config, SimSource(sim))

    stop = threading.Event()
    previous: dict[int, Callable[[int, FrameType | None], Any] | int | None] = {}

    def on_signal(signum: int, frame: object) -> None:
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError):  # not the main thread (e.g. run from a test): rely on --seconds
            previous[sig] = signal.signal(sig, on_signal)

    tty = sys.stdout.isatty()
    period = 1.0 / args.status_hz if tty and args.status_hz > 0 else 1.0
    shown = 0  # lines of the status block on screen (a terminal redraws it in place)
    if args.realtime_priority:  # before the simulator's threads start: they inherit the policy
        from akarm.control.loop import request_realtime

        print(f"  real time: {request_realtime(switch_interval=2e-4)}", flush=True)
    try:
        with sim, contextlib.ExitStack() as stack:
            print(_describe(sim.config, sim.serial_ports), flush=True)
            print(f"  integrating at {1.0 / sim.dt:g} Hz (timing profile {sim.timing.name})", flush=True)
            if args.object is not None:
                sim.place_object(args.object, args.object_stiffness)
                print(f"  object {args.object * 1e3:g} mm wide between the gripper's jaws ({args.object_stiffness:g} "
                      "N/m)", flush=True)
            if sim.truth is not None:
                print(f"  a varied unit (seed {args.vary}): per joint torque scale, Coulomb N·m (+N·m/A), "
                      "viscous, backlash mrad", flush=True)
                for j in sim.truth.joints:
                    print(f"    {j.name}: x{j.torque_scale:.2f}, {j.coulomb:.2f} (+{j.coulomb_load:.3f}), "
                          f"{j.viscous:.3f}, {j.backlash * 1e3:.1f}", flush=True)
            for joint, fault in injected:
                sim.inject(joint, fault)
                print(f"  fault on {joint}: {fault}", flush=True)
            if args.control:
                stack.enter_context(ChannelServer(sim, args.control))
                print(f"  control channel: {args.control}", flush=True)
            if view is not None:
                from akarm.cli.view import show_view

                stack.callback(view.stop)
                show_view(view)
            print("running; Ctrl-C to stop", flush=True)
            start = time.monotonic()
            end = start + args.seconds if args.seconds is not None else None
            next_line = start + period
            while not stop.is_set():
                now = time.monotonic()
                wait = next_line - now
                if end is not None:
                    wait = min(wait, end - now)
                if wait > 0 and stop.wait(wait):
                    break
                if sim.thread_error is not None:
                    raise sim.thread_error
                now = time.monotonic()
                if end is not None and now >= end:
                    break
                if now >= next_line:
                    next_line += period
                    if not args.quiet:
                        width = shutil.get_terminal_size((80, 24)).columns if tty else 80
                        block = status_block(sim.status_line(), width)
                        if tty:  # back to the block's first line, then each line cleared and written
                            up = f"\x1b[{shown - 1}F" if shown > 1 else "\r"
                            print(up + "\n".join("\x1b[2K" + s for s in block), end="", flush=True)
                            shown = len(block)
                        else:
                            print("\n".join(block), flush=True)
            if tty and not args.quiet and shown:
                print()
            print(f"akarm sim: stopped at t = {sim.t:.2f} s "
                  f"(frames in {sum(d.frames_received for d in sim.drivers)}, "
                  f"out {sum(d.frames_sent for d in sim.drivers)}"
                  f"{f', send errors {sim.send_errors}' if sim.send_errors else ''})", flush=True)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return 0
