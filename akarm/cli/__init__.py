"""The ``akarm`` command line: a thin user of the public API.

Each verb lives in its own module ``akarm.cli.<verb>`` with ``add_arguments(parser)`` and
``run(args) -> int``; modules import heavy libraries inside ``run`` so ``akarm --help`` is fast.
SIGTERM and SIGHUP end every verb as Ctrl-C does (:mod:`akarm.signals`): the arm is damped and
disabled, what was recorded is written, and the exit status is 128 + the signal's number.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from collections.abc import Sequence
from typing import Any

from akarm import signals
from akarm._version import __version__
from akarm.errors import AkarmError

#: verb → (module, one-line description). Verbs whose module is not there yet are not offered.
VERBS: dict[str, tuple[str, str]] = {
    "demo": ("akarm.cli.demo", "run a scripted session on a simulated arm6 (no hardware needed)"),
    "init": ("akarm.cli.init", "write a commented starting robot YAML for a URDF"),
    "check": ("akarm.cli.check", "validate a robot YAML; print its joints, gravity, bus load and rate ceiling"),
    "sim": ("akarm.cli.sim", "simulate a robot's AK drivers on a CAN bus until Ctrl-C"),
    "scan": ("akarm.cli.scan", "list the CAN IDs that answer on a bus, and in which mode"),
    "status": ("akarm.cli.status", "print each joint's position, velocity, torque, temperature, fault"),
    "enable": ("akarm.cli.enable", "enable the arm (no kick) and hold it where it is"),
    "disable": ("akarm.cli.disable", "damp and disable every joint"),
    "zero": ("akarm.cli.zero", "make a joint's current position its zero"),
    "move": ("akarm.cli.move", "move to a named pose or to joint values"),
    "grip": ("akarm.cli.grip", "open, close or move the gripper's jaws (force-limited)"),
    "servo": ("akarm.cli.servo", "steer the tool live with a SpaceMouse (spacemouse extra)"),
    "teach": ("akarm.cli.teach", "hand-guide the arm and record keyframes or a continuous path"),
    "replay": ("akarm.cli.replay", "replay a recording or a dataset's episode, checked against the limits first"),
    "teleop": ("akarm.cli.teleop", "a hand guides a leader arm, a follower copies it; record episodes (LeRobot)"),
    "serve": ("akarm.cli.serve", "hold the arm and serve it to the CLI and to ROS 2 (DDS) until stopped"),
    "ros-config": ("akarm.cli.ros_config", "print or write what MoveIt needs to drive akarm serve for a robot"),
    "plot": ("akarm.cli.plot", "plot a telemetry log: desired vs measured, error, torque"),
    "identify": ("akarm.cli.identify", "identify friction, payload and collision thresholds by a safe excitation"),
    "bench": ("akarm.cli.bench", "measure the control loop's timing against the simulator"),
    "view": ("akarm.cli.view", "see the arm in the browser: live 3D, plots, state and controls (view extra)"),
}


def _available() -> dict[str, tuple[str, str]]:
    return {v: spec for v, spec in VERBS.items() if importlib.util.find_spec(spec[0]) is not None}


class _Version(argparse.Action):
    """``--version``: akarm's version and whether this process runs the cycle compiled (which imports
    the cycle's modules: done only when asked, not for every command)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        from akarm.compiled import status

        print(f"akarm {__version__}\nthe control cycle: {status()}")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="akarm",
        description="Trajectory control for robot arms built from CubeMars AK actuators.",
    )
    parser.add_argument("--version", action=_Version, help="print akarm's version, and whether its control cycle "
                        "runs compiled, and exit")
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    for verb, (module, help_text) in _available().items():
        p = sub.add_parser(verb, help=help_text, description=help_text)
        importlib.import_module(module).add_arguments(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``akarm`` command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.verb is None:
        parser.print_help()
        return 0
    module = importlib.import_module(VERBS[args.verb][0])
    installed = signals.install()  # SIGTERM and SIGHUP end a verb as Ctrl-C does: damped, disabled, saved
    try:
        return int(module.run(args) or 0)
    except AkarmError as e:
        from akarm.errors import SafetyStop

        name = f"{type(e).__name__}: " if isinstance(e, SafetyStop) else ""  # a stop says which one
        print(f"akarm {args.verb}: error: {name}{e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:
        print(f"akarm {args.verb}: interrupted", file=sys.stderr)
        return signals.exit_code(e)
    finally:
        if installed:
            signals.uninstall()
