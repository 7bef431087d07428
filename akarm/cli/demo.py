"""``akarm demo``: a scripted session on a simulated six-joint arm, with no hardware and no arguments.

::

    akarm demo                     # real time, ~20 s; writes akarm-demo.png
    akarm demo --fast --no-plot    # lock step with the simulator: a few seconds
    akarm demo -o run.png --log run.csv

The simulator (:class:`akarm.sim.SimulatedRobot`) answers the real MIT wire protocol for
``robots/arm6.yaml`` on a python-can *virtual* bus inside this process; the :class:`akarm.Arm` talks
to it exactly as it would to the motors on ``can0``. The session: enable (no kick), moves between
the YAML's named poses, one smooth move through waypoints, a replay of the bundled continuous
recording (``akarm/data/demo_path.csv``, a figure eight), disable. Then it prints the tracking
error per joint (mrad) and the control loop's timing, and plots the telemetry
(:func:`akarm.telemetry.plot.plot_log`).

With ``--view`` the page of :mod:`akarm.cli.view`, drawn by a process of its own, watches the session
live (http://localhost:8080),
then plays it back with a time slider until Ctrl-C.

With ``--fast`` the arm and the simulator run in lock step (``realtime=False``: the loop's clock
*is* the simulator's), so the motion and the tracking are the same but time is simulated: loop
rate, missed slots and lateness are then exact by construction and say nothing about this machine.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import itertools
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from akarm.cli.common import add_profile_argument, loop_options
from akarm.errors import AkarmError, RecordingError

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.config import RobotConfig
    from akarm.errors import SafetyStop
    from akarm.telemetry.log import TelemetryLog
    from akarm.view.process import ViewProcess

#: the bundled recording the demo replays (joints of arm6, rad, 100 Hz)
DEMO_PATH = Path(__file__).resolve().parent.parent / "data" / "demo_path.csv"
#: waypoints of the demo's move_through: names of arm6's poses or joint vectors (rad, config order)
WAYPOINTS: tuple[str | tuple[float, ...], ...] = (
    "ready",
    (0.7, 0.6, 0.9, 0.6, -0.5, 1.0),
    "left",
    (-0.6, 0.1, 1.5, -0.4, 0.6, -0.8),
    "home",
)
#: s; the watchdog's feedback timeout in real time. The simulator shares this process (and its GIL)
#: with the control loop, so a pause of the whole process (a busy machine, a garbage collection)
#: delays the replies by as much as the pause; on hardware the Arm's default, 20 ms, applies.
REALTIME_FEEDBACK_TIMEOUT = 0.25
#: the same reason, for the collision reflex: a reply that comes late reads like a push (the
#: estimate takes the time it did not see for a torque), so in real time its thresholds are doubled
REALTIME_COLLISION_SCALE = 2.0
_channels = itertools.count()


def robots_dir() -> Path:
    """The ``robots/`` folder of akarm's source tree: next to the ``akarm/`` package."""
    return Path(__file__).resolve().parent.parent.parent / "robots"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    parser.add_argument("-o", "--output", default="akarm-demo.png", metavar="PNG",
                        help="where to write the plot (default: akarm-demo.png in the current directory)")
    parser.add_argument("--no-plot", action="store_true", help="do not plot")
    parser.add_argument("--log", metavar="FILE.csv", help="also save the session's telemetry (.csv, .npz or .mcap)")
    parser.add_argument("--fast", action="store_true",
                        help="run in lock step with the simulator (a few seconds; timing statistics are simulated)")
    parser.add_argument("--vary", type=int, metavar="SEED",
                        help="run the session on a simulated real unit, not the robot file's model: torque "
                             "constants, friction, backlash, masses and reply jitter drawn from SEED "
                             "(akarm.sim.Variation); the demo reports the safety stops (none expected)")
    add_profile_argument(parser)
    from akarm.cli.view import add_view_options

    add_view_options(parser)


def _arm6_yaml() -> Path:
    path = robots_dir() / "arm6.yaml"
    if not path.is_file() or not (path.parent / "arm6.urdf").is_file():
        raise AkarmError(f"the demo robot {path} (with arm6.urdf beside it) was not found; this akarm is "
                         "installed without its robots/ folder",
                         fix="clone akarm's source repository and install from it (pip install -e \".[plot]\"): "
                             "robots/ sits next to the akarm/ package, and `akarm demo` finds it there")
    return path


def _check_outputs(args: argparse.Namespace) -> None:
    """Fail before the session, not after it, on an output that cannot be written."""
    from akarm.cli.options import TELEMETRY_SUFFIXES, check_output

    check_output(args.log, TELEMETRY_SUFFIXES, "telemetry")
    if not args.no_plot:
        if Path(args.output).suffix.lower() != ".png":
            raise RecordingError(f"cannot plot to {args.output!r}: only PNG is written", fix="use a .png file name")
        check_output(args.output, (".png",), "the plot")
        from akarm.telemetry.plot import figure_classes

        figure_classes()  # RecordingError naming the `plot` extra when matplotlib is missing


def _step_line(k: int, label: str, seconds: float, log: TelemetryLog) -> str:
    """One line per step: number, what, duration (s), and the worst joint's RMS tracking error (mrad)."""
    text = f"  {k:>2}. {label:<42}{seconds:6.2f} s"
    if len(log) > 1:
        rms = log.rms_error() * 1e3
        worst = int(rms.argmax())
        text += f"   tracking RMS ≤ {rms[worst]:5.2f} mrad ({log.joint_names[worst]})"
    return text


def session_steps(arm: Arm) -> list[tuple[str, str, Callable[[], object]]]:
    """The scripted steps, in order: (what is printed, its label on the plot, what is done)."""
    steps: list[tuple[str, str, Callable[[], object]]] = [
        ("enable (no kick: gains ramp up from zero)", "enable", arm.enable)]
    for pose in ("home", "ready", "left", "reach", "home"):
        steps.append((f"move_to({pose!r})", pose, functools.partial(arm.move_to, pose)))
    steps.append((f"move_through({len(WAYPOINTS)} waypoints, no stops)", "waypoints",
                  lambda: arm.move_through(list(WAYPOINTS))))
    steps.append((f"replay({DEMO_PATH.name!r}): a figure eight", "replay", lambda: arm.replay(DEMO_PATH)))
    return steps


def _run_steps(arm: Arm, varied: bool) -> tuple[list[tuple[float, str]], SafetyStop | None, int]:
    """Run :func:`session_steps`, printing a line per step: the steps' (clock time, label), the safety stop
    that ended the session early on a varied unit (else it propagates), and the number of the last step."""
    from akarm.errors import SafetyStop

    events: list[tuple[float, str]] = []  # (clock time, label) of each step, for the plot
    k = 0
    for k, (label, short, action) in enumerate(session_steps(arm), start=1):
        t0 = arm.clock.now()
        events.append((t0, short))
        try:
            action()
        except SafetyStop as e:  # a varied unit: say what stopped it, and end the session there
            if not varied:
                raise
            print(f"  {k:>2}. {label}: SAFETY STOP {type(e).__name__}: {e}", flush=True)
            return events, e, k
        t1 = arm.clock.now()
        print(_step_line(k, label, t1 - t0, arm.telemetry(since=t0)), flush=True)
    return events, None, k


def _reflex_line(arm: Arm) -> str:
    """The collision reflex over the session: armed on which joints, and how close the estimate came."""
    import numpy as np

    th = arm.collision_thresholds
    log = arm.telemetry()
    watched = [k for k, n in enumerate(arm.names) if th[n] is not None]
    if not watched:
        return "collision reflex: no thresholds in the robot file (akarm identify suggests some)"
    del log
    peak = arm.collision_peak  # what the reflex judges: the estimate's sudden part (the model's error set aside)
    ratio = np.array([peak[k] for k in watched]) / np.array([th[arm.names[k]] for k in watched])
    k = watched[int(np.argmax(ratio))]
    stops = 0 if arm.last_collision is None else 1
    return (f"collision reflex: armed on {len(watched)} joints, {stops} stops; its judged estimate came to "
            f"{ratio.max() * 100:.0f} % of a threshold at most ({arm.names[k]})")


def _tracking_table(log: TelemetryLog) -> str:
    import numpy as np

    err = np.abs(log.tracking_error()) * 1e3
    rms = log.rms_error() * 1e3
    lines = ["tracking error (desired - measured) over the session, mrad:",
             "  (measured = the motors' latest replies, one loop period old: at 2 rad/s that alone reads 4 mrad)",
             f"  {'joint':<16}{'RMS':>8}{'max':>9}"]
    for k, name in enumerate(log.joint_names):
        lines.append(f"  {name:<16}{rms[k]:8.3f}{err[:, k].max():9.3f}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the demo session; 0 on success."""
    import time

    from akarm.arm import Arm
    from akarm.robotfile.load import load_robot
    from akarm.sim import SimulatedRobot
    from akarm.timing import get_profile

    _check_outputs(args)
    if not DEMO_PATH.is_file():
        raise RecordingError(f"the demo recording {DEMO_PATH} is missing",
                             fix="reinstall akarm, or regenerate it with docs/make_demo_path.py")
    channel = f"akarm-demo-{os.getpid()}-{next(_channels)}"
    config = get_profile(args.profile).apply(load_robot(_arm6_yaml()).with_bus(interface="virtual", channel=channel))
    mode = "lock step (--fast)" if args.fast else "real time"
    print(f"akarm demo: simulated {config.name} ({len(config.joints)} MIT joints, {config.rate_hz:g} Hz loop) "
          f"on a virtual CAN bus, {mode}", flush=True)
    wall0 = time.perf_counter()
    from akarm.sim import Variation

    variation = None if args.vary is None else Variation(seed=args.vary)
    with SimulatedRobot(config, realtime=not args.fast, timing=args.profile, variation=variation) as sim:
        if sim.truth is not None:
            print(f"  a varied unit (seed {args.vary}), not the datasheet: per joint the torque it gets per N·m "
                  "reported, and Coulomb friction over the catalogue's:", flush=True)
            print("    " + ", ".join(f"{j.name} x{j.torque_scale:.2f} / x{j.coulomb / f.coulomb:.1f}"
                                     for j, f in zip(sim.truth.joints, (jc.friction_model() for jc in config.joints),
                                                     strict=True) if f.coulomb), flush=True)
        if args.fast:
            # a simulated arm, new each run: no positions to remember (akarm.control.turns) for a real arm6
            arm = Arm(config, clock=sim.clock, telemetry_seconds=120.0, remember_positions=False,
                      **loop_options(args))
        else:
            arm = Arm(config, feedback_timeout=REALTIME_FEEDBACK_TIMEOUT, telemetry_seconds=120.0,
                      remember_positions=False, **loop_options(args))
            arm.set_collision(thresholds={n: t * REALTIME_COLLISION_SCALE
                                          for n, t in arm.collision_thresholds.items() if t is not None})
            watchdog = max(REALTIME_FEEDBACK_TIMEOUT, arm.timing.min_feedback_timeout)  # arm6's joints set none
            print(f"  (watchdog: {watchdog * 1e3:.0f} ms and collision thresholds doubled, as the simulator shares "
                  "this process; on hardware the default is 20 ms and the file's thresholds)", flush=True)
        view = _live_view(args, config, arm)
        with arm, contextlib.ExitStack() as stack:
            if view is not None:  # shown while the arm is open, stopped before it closes
                from akarm.cli.view import show_view

                stack.callback(view.stop)
                show_view(view)
            t_session = arm.clock.now()
            events, stopped, k = _run_steps(arm, varied=variation is not None)
            log = arm.telemetry(since=t_session)
            stats = arm.stats()
            reflex = _reflex_line(arm)
            t0 = arm.clock.now()
            arm.disable()
            print(f"  {k + 1:>2}. {'disable (damping, then exit motor mode)':<42}{arm.clock.now() - t0:6.2f} s",
                  flush=True)
        slip = sim.slip
    wall = time.perf_counter() - wall0

    print()
    if variation is not None:
        print(f"safety stops on the varied unit (seed {args.vary}): "
              + ("none" if stopped is None else f"1, {type(stopped).__name__} on {stopped.joint}"))
    print(reflex)
    print(_tracking_table(log))
    print()
    timing = "simulated time, lock step" if args.fast else "this machine, wall clock"
    print(f"control loop ({timing}): rate {stats.rate:.1f} Hz (target {config.rate_hz:g}), {stats.cycles} cycles, "
          f"missed slots {stats.missed}, lateness p99 {stats.late_p99 * 1e6:.0f} µs "
          f"(max {stats.late_max * 1e6:.0f} µs), compute p99 {stats.compute_p99 * 1e6:.0f} µs")
    if slip > 0.001:
        print(f"simulator: fell {slip:.2f} s behind the wall clock (this machine was busy)")
    if not args.fast and stats.missed > 0.01 * stats.cycles:
        print(f"note: this machine could not keep {config.rate_hz:g} Hz while also simulating six motors in Python; "
              "the tracking suffers with it. Close busy programs, or see the same session in lock step: "
              "akarm demo --fast")
    if args.log is not None:
        print(f"telemetry: {log.save(args.log)} ({len(log)} cycles)")
    if not args.no_plot:
        from akarm.telemetry.plot import plot_log

        print(f"plot: {plot_log(log, args.output, title='akarm demo: simulated arm6', events=events)}")
    print(f"akarm demo: done in {wall:.1f} s. Next: examples/first_move.py, then "
          "docs/sim-to-hardware.md ('From simulator to hardware').")
    if view is not None:
        return _play_back(args, config, log, view.port)
    return 0 if stopped is None else 1


def _live_view(args: argparse.Namespace, config: RobotConfig, arm: Arm) -> ViewProcess | None:
    """With ``--view``: the page watching the session's arm, drawn by a process of its own (made,
    not started)."""
    if not args.view:
        return None
    from akarm.cli.view import make_view_process
    from akarm.view.sources import ArmSource

    return make_view_process(args, config, ArmSource(arm, title="live: the demo session"))


def _play_back(args: argparse.Namespace, config: RobotConfig, log: TelemetryLog, port: int) -> int:
    """The session played back on the same page (the browser reconnects) until Ctrl-C; 0."""
    import time

    from akarm.cli.view import make_view, show_view
    from akarm.view.recorded import RecordedSource

    view = show_view(make_view(args, config, RecordedSource(log, config.joint_names, title="the demo session, played "
                                                                                            "back"), port=port))
    print("akarm demo: the page plays the session back now (its time slider, Play); Ctrl-C ends", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        return 0
    finally:
        view.stop()
