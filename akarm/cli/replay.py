"""``akarm replay ROBOT.yaml FILE``: replay a taught recording, checked against the limits first.

::

    akarm replay robots/arm6.yaml pick.yaml              # keyframes: one smooth move through them
    akarm replay robots/arm6.yaml path.csv --speed 0.5   # a path, at half its recorded speed
    akarm replay follower.yaml demos --episode 2         # a LeRobot dataset's episode: its action column

The whole path is checked (position, velocity, acceleration and jerk of every joint, after the
speed factor) before the arm is even enabled: a violation names the joint, the time and a speed
factor that would pass, and nothing moves (exit 1). A soft start first moves the arm to the
recording's first pose. A progress bar is drawn on stderr when it is a terminal. Ctrl-C brings the
arm to rest smoothly, then disables it (exit 130).

A LeRobot v3.0 dataset folder (``akarm teleop --record``) replays one episode's commanded positions
(``action``) at its recorded timing, on any robot with the same joints (in the same order). An
episode with a ``gripper`` column drives the robot's gripper too: the width asked at each frame (m,
within its stroke), at the same timing (after the jaws first go to the episode's first width); a
robot without a gripper replays the arm alone and says so. Through ``akarm serve`` the gripper is
asked its widths over the control socket (``gripper_move``) while the server replays the path.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, Any

from akarm.cli.common import add_profile_argument, add_robot_arguments, load_from_args, loop_options

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm
    from akarm.motion.recording import Keyframes, PathRecording


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("file", metavar="FILE",
                        help="a recording from akarm teach (keyframes .yaml or path .csv), or a LeRobot dataset folder")
    parser.add_argument("--episode", type=int, metavar="K", help="the episode of a dataset folder to replay")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="paths: recorded speed × F (any F > 0); keyframes: fraction of the joint limits, "
                             "at most 1 (default 1)")
    parser.add_argument("--log", metavar="FILE", help="save the telemetry (.csv, .npz or .mcap) for akarm plot")
    add_profile_argument(parser)


def check_options(args: argparse.Namespace) -> None:
    """The options a replay checks before anything moves (here or through akarm serve)."""
    from akarm.cli.options import TELEMETRY_SUFFIXES, check_output
    from akarm.errors import ArgumentError

    if not args.speed > 0:
        raise ArgumentError(f"--speed {args.speed} must be positive", fix="e.g. --speed 0.5")
    if os.path.isdir(args.file) and args.episode is None:
        raise ArgumentError(f"{args.file} is a folder: which of its episodes?", fix="add --episode K")
    if args.episode is not None and not os.path.isdir(args.file):
        raise ArgumentError("--episode is for a dataset folder", fix="pass the folder given to akarm teleop --record")
    check_output(args.log, TELEMETRY_SUFFIXES, "telemetry")


def load_recording(args: argparse.Namespace, joint_names: tuple[str, ...]) -> Keyframes | PathRecording:
    """The recording FILE names: keyframes, a path, or a dataset's episode (its commanded positions)."""
    from akarm.errors import LimitError
    from akarm.motion.recording import load

    if args.episode is None:
        return load(args.file, joint_names)
    from akarm.datasets import read_dataset

    path = read_dataset(args.file).episode(args.episode).path("action")
    if path.joint_names != tuple(joint_names):
        raise LimitError(f"episode {args.episode} is for joints {list(path.joint_names)}",
                         fix=f"replay it on a robot with joints {list(joint_names)}")
    return path


class GripperTrack:
    """An episode's gripper column: the width asked (m) at each of its times (s from its start)."""

    def __init__(self, times: Any, widths: Any, stroke: float) -> None:
        import numpy as np

        self.times = np.asarray(times, dtype=float)
        self.widths = np.clip(np.asarray(widths, dtype=float), 0.0, stroke)
        self.sent: float | None = None

    def at(self, t: float) -> float:
        """The width asked at episode time ``t`` (the frame at or before it)."""
        import numpy as np

        k = int(np.searchsorted(self.times, t, side="right")) - 1
        return float(self.widths[min(max(k, 0), len(self.widths) - 1)])

    def due(self, t: float, deadband: float = 0.0005) -> float | None:
        """The width to ask at ``t`` if it changed by more than ``deadband`` m since the last asked."""
        w = self.at(t)
        if self.sent is not None and abs(w - self.sent) <= deadband:
            return None
        self.sent = w
        return w


def load_gripper(args: argparse.Namespace, stroke: float | None) -> GripperTrack | None:
    """The gripper column of the dataset episode FILE names, for a gripper of ``stroke`` m (None: the
    robot has none; the column, if any, is said to be left out); None without one."""
    if args.episode is None:
        return None
    from akarm.datasets import read_dataset

    episode = read_dataset(args.file).episode(args.episode)
    widths = episode.gripper("action")
    if widths is None:
        return None
    if stroke is None:
        print(f"episode {args.episode} has a gripper column; this robot has no gripper: the arm alone is replayed",
              file=sys.stderr)
        return None
    return GripperTrack(episode.timestamp, widths, stroke)


def run(args: argparse.Namespace) -> int:
    """Load and check the recording, then enable, replay with progress, disable."""
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    from tqdm import tqdm

    from akarm.arm import Arm
    from akarm.cli.common import controlled, deferred_signals, interrupted, stop_smoothly
    from akarm.motion.recording import Keyframes, PathRecording

    check_options(args)
    config = load_from_args(args)
    rec = load_recording(args, config.joint_names)
    track = load_gripper(args, config.gripper.stroke if config.gripper is not None else None)
    arm = Arm(config, **loop_options(args))
    arm.check_replay(rec, args.speed)  # the whole path, before anything is enabled
    kind = f"{len(rec.frames)} keyframes" if isinstance(rec, Keyframes) else f"a {rec.duration:.2f} s path"
    if args.episode is not None:
        kind = f"episode {args.episode}, {kind}"
    code = 0
    with controlled(arm):
        t0 = arm.clock.now()
        try:
            arm.enable()
            if track is not None and arm.gripper is not None:  # the jaws where the episode starts
                arm.gripper.move_to(track.due(0.0) or 0.0)
            motion = arm.replay(rec, speed=args.speed, wait=False)
            # the episode's time is the motion's, less its soft start to the first pose
            lead = motion.duration - rec.duration / args.speed if isinstance(rec, PathRecording) else 0.0
            print(f"replaying {args.file} ({kind}) in {motion.duration:.2f} s at speed {args.speed:g}", flush=True)
            bar = tqdm(total=round(motion.duration, 2), unit="s", file=sys.stderr, disable=not sys.stderr.isatty(),
                       bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s")
            with bar:
                start = arm.clock.now()
                tick = 0.1 if track is None else 0.01
                while not motion.done:
                    arm.sleep(tick)
                    elapsed = arm.clock.now() - start
                    if track is not None and arm.gripper is not None:
                        width = track.due((elapsed - lead) * args.speed)
                        if width is not None:
                            arm.gripper.move_to(width, wait=False)
                    bar.n = round(min(elapsed, motion.duration), 2)
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


def _served_gripper(arm: RemoteArm, track: GripperTrack, duration: float, lead: float, speed: float) -> None:
    """While the server replays the arm's path (``duration`` s, the episode's from ``lead`` s on), ask
    its gripper each frame's width (``gripper_move``, not waiting), at the replay's ``speed``."""
    import time

    start = time.monotonic()
    while (elapsed := time.monotonic() - start) < duration:
        width = track.due((elapsed - lead) * speed)
        if width is not None:
            arm.call("gripper_move", width=width, wait=False)
        time.sleep(0.01)


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """The replay through ``akarm serve``: as without it, but the server holds the arm afterwards."""
    from akarm.cli.common import interrupted
    from akarm.motion.recording import PathRecording

    check_options(args)  # before anything moves
    path = os.path.abspath(args.file)
    track, seconds = None, 0.0
    if args.episode is not None:  # the server replays files: the episode's commanded positions as a path file
        import tempfile
        from pathlib import Path

        folder = tempfile.mkdtemp(prefix="akarm-replay-")
        rec = load_recording(args, tuple(arm.names))
        seconds = rec.duration if isinstance(rec, PathRecording) else 0.0
        path = str(rec.save(Path(folder) / f"episode-{args.episode}.csv"))
        gripper = arm.config.gripper
        track = load_gripper(args, gripper.stroke if gripper is not None else None)
    arm.call("check_replay", path=path, speed=args.speed)  # the whole path, before anything moves
    try:
        arm.call("ready")  # refused while a safety stop is latched; a disabled arm is enabled
        if track is not None:  # the jaws where the episode starts
            arm.call("gripper_move", width=track.due(0.0) or 0.0)
        motion = arm.call("replay", path=path, speed=args.speed)
        print(f"replaying {args.file} ({motion['kind']}) in {motion['duration']:.2f} s at speed {args.speed:g}",
              flush=True)
        if track is not None:
            _served_gripper(arm, track, motion["duration"], motion["duration"] - seconds / args.speed, args.speed)
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
