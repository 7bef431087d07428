"""``akarm view ROBOT.yaml``: see the arm in the browser: a live 3D view, plots, state and controls.

::

    akarm view robots/arm6.yaml                       # the arm a running `akarm serve` drives
    akarm view robots/arm6.yaml --play run.csv        # a recorded run (.csv, .npz), with a time slider
    akarm view robots/arm6.yaml --host 0.0.0.0 --port 8080    # reachable from other machines: see below

The server is found as the other verbs find it (the robot's buses, :mod:`akarm.buses.ownership`);
the page watches it through the server's control socket and its buttons and sliders use the
server's own operations (enable, hold, disable, move). ``akarm serve --view``, ``akarm sim --view``
and ``akarm demo --view`` open the same page in their own process (:func:`add_view_options`).

The page binds 127.0.0.1 (this machine only). ``--host 0.0.0.0`` opens it to the network, and then
anyone who reaches the port sees the arm and can press Enable and Disable and jog it: there is no
login. Runs until Ctrl-C, or until the server it watches stops.
"""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, TypeVar

from akarm.cli.common import add_robot_arguments, load_from_args

if TYPE_CHECKING:
    from akarm.config import RobotConfig
    from akarm.view.page import ViewServer
    from akarm.view.process import ViewProcess
    from akarm.view.sources import Source

_View = TypeVar("_View", "ViewServer", "ViewProcess")

#: s the watched server may stay unreachable before akarm view gives up
LOST_AFTER = 3.0
#: the view's defaults (akarm.view.page's; repeated so that --help does not import viser)
HOST, PORT = "127.0.0.1", 8080


def add_view_options(parser: argparse.ArgumentParser, prefix: str = "--view") -> None:
    """``--view`` (open the page, served by a process of its own that this one feeds) with
    ``--view-host`` and ``--view-port``, for verbs that drive or simulate an arm themselves."""
    parser.add_argument(prefix, action="store_true",
                        help="also serve the live view (3D, plots, state), drawn by a process of its own so that it "
                             "takes nothing from the loop; see akarm view")
    parser.add_argument(f"{prefix}-host", default=HOST, metavar="HOST",
                        help=f"address the view binds (default {HOST}: this machine only; anyone who reaches it can "
                             "press its controls)")
    parser.add_argument(f"{prefix}-port", type=int, default=PORT, metavar="PORT",
                        help=f"port of the view (default {PORT}; 0: any free one; taken: the next free one)")


def make_view(args: argparse.Namespace, config: RobotConfig, source: Source, host: str | None = None,
              port: int | None = None) -> ViewServer:
    """A :class:`~akarm.view.page.ViewServer` in this process for the verb's options, not started yet:
    made first, so that a missing ``view`` extra or a bad option is said first."""
    from akarm.view.page import ViewServer, import_viser

    import_viser()
    return ViewServer(config, source, host=host if host is not None else args.view_host,
                      port=port if port is not None else args.view_port, visuals=not getattr(args, "kinematics", False))


def make_view_process(args: argparse.Namespace, config: RobotConfig, source: Source) -> ViewProcess:
    """A :class:`~akarm.view.process.ViewProcess` for ``--view``: the page drawn by a child process
    that this one feeds snapshots (the loop's process only takes them). Not started yet: made before
    the verb enables anything, so that a missing ``view`` extra or a bad option is said first."""
    from akarm.view.process import ViewProcess

    return ViewProcess(config, source, host=args.view_host, port=args.view_port,
                       visuals=not getattr(args, "kinematics", False))


def show_view(view: _View) -> _View:
    """Start ``view`` and print where it is."""
    view.start()
    print(f"view: {view.url} ({view.source.title}; {_exposure(view.host)})", flush=True)
    return view


def _exposure(host: str) -> str:
    if host in ("127.0.0.1", "localhost", "::1"):
        return "this machine only"
    return f"bound to {host}: anyone who reaches this port can enable, disable and jog the arm"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("--play", metavar="FILE",
                        help="play a recorded run back instead (telemetry .csv or .npz; .mcap where akarm reads it)")
    parser.add_argument("--host", default=HOST,
                        help=f"address to bind (default {HOST}: this machine only; 0.0.0.0: every interface, and "
                             "then anyone who reaches the port can press the controls)")
    parser.add_argument("--port", type=int, default=PORT, help=f"port (default {PORT}; 0: any free one)")
    parser.add_argument("--kinematics", action="store_true",
                        help="draw the figure from the kinematics even when the URDF has visuals")


def run(args: argparse.Namespace) -> int:
    """Serve the page until Ctrl-C/SIGTERM (0), or until the watched server stops (1)."""
    from pathlib import Path

    from akarm.buses.ownership import find_server
    from akarm.errors import StateError
    from akarm.view.recorded import RecordedSource, read_telemetry
    from akarm.view.sources import RemoteSource

    config = load_from_args(args)
    source: Source
    if args.play:
        log = read_telemetry(args.play)
        source = RecordedSource(log, config.joint_names, title=f"recording {Path(args.play).name}")
    else:
        info = find_server(config)
        if info is None:
            raise StateError(f"no akarm serve drives {config.name}'s buses",
                             fix=f"start one (akarm serve {args.robot}, or with --view to have the page in it), "
                                 "or play a recorded run back with --play run.csv")
        source = RemoteSource(config, info)
    try:
        view = show_view(make_view(args, config, source, host=args.host, port=args.port))
        try:
            return _watch(view)
        except KeyboardInterrupt:
            return 0
        finally:
            view.stop()
    finally:
        source.close()


def _watch(view: ViewServer) -> int:
    lost_since: float | None = None
    while True:
        time.sleep(0.25)
        if view.lost is None:
            lost_since = None
            continue
        now = time.monotonic()
        lost_since = lost_since if lost_since is not None else now
        if now - lost_since > LOST_AFTER:
            print(f"akarm view: the server is gone ({view.lost}); the view ends", flush=True)
            return 1
