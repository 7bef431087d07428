"""``akarm teleop LEADER.yaml FOLLOWER.yaml``: a hand guides the leader arm, the follower copies it.

::

    akarm teleop leader.yaml follower.yaml                       # follow until q, Ctrl-C or SIGTERM
    akarm teleop leader.yaml follower.yaml --force-feedback 0.5  # feel what the follower touches
    akarm teleop leader.yaml follower.yaml --map pairs.yaml --record demos --task "pick the cube" --fps 30
    akarm teleop leader.yaml follower.yaml --record demos --task "wave" --camera front --camera-size 96x96
    akarm teleop leader.yaml follower.yaml --log run.mcap        # both arms' telemetry, for Foxglove or akarm plot
    akarm teleop leader.yaml follower.yaml -i socketcan --leader-channel can0 --follower-channel can1

Both arms are enabled; the leader goes into teach mode (its weight carried, a little damping); the
follower moves to the leader's pose at ``--engage-speed`` of its limits, then follows it every cycle,
jerk-limited within its own limits and range (:mod:`akarm.teleop`). A safety stop of either arm stops
both (exit 1).

Keys (as ``lerobot record`` has them; stdin, so a script can send them as lines): **Enter** ends the
episode being recorded (it is saved, and the next begins), **r** records it again (it is dropped),
**q** quits (the episode is saved first). A progress line shows the episode, its time and frames.
Ctrl-C, SIGTERM or SIGHUP end the session: the follower comes to rest, both arms are damped and
disabled, and the episode being recorded is dropped, never written in part (the ones before it are
in the dataset). ``--log`` keeps each arm's last ``--log-seconds``.

``--camera NAME`` (with ``--record``, again for more) records a simulated camera that draws the
follower (:mod:`akarm.sim.camera`: the URDF's primitive visuals, the jaws, and with ``--sim-control``
the object between them), ``--camera-size`` pixels, at the dataset's fps: each draws in a process of
its own from the positions this process publishes (a few microseconds a cycle), and the episode's
pictures are stored as video (``observation.images.NAME``, as LeRobot stores a camera; PyAV: the
``video`` extra).
"""

from __future__ import annotations

import argparse
import os
import queue
import sys
import threading
from typing import TYPE_CHECKING, TextIO

from akarm.cli.common import add_profile_argument, interrupted, loop_options

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.config import RobotConfig
    from akarm.sim.camera import PoseFile
    from akarm.teleop import Pairing, Step, Teleop
    from akarm.teleop.recording import EpisodeRecorder


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import add_bus_kwargs, bitrate, interface

    parser.add_argument("leader", metavar="LEADER.yaml", help="the leader's robot file (the arm a hand guides)")
    parser.add_argument("follower", metavar="FOLLOWER.yaml", help="the follower's robot file (the arm that copies)")
    parser.add_argument("--map", metavar="FILE", help="which joints pair, with scale and offset (default: in order)")
    parser.add_argument("--force-feedback", type=float, default=0.0, metavar="GAIN",
                        help="apply the follower's external torque × GAIN to the leader (default 0: none)")
    parser.add_argument("--force-limit", type=float, metavar="NM",
                        help="the largest feedback torque, N·m (default: a fifth of each leader joint's limit)")
    parser.add_argument("--engage-speed", type=float, default=0.25, metavar="F",
                        help="the fraction of the follower's limits it moves to the leader at (default 0.25)")
    parser.add_argument("--damping", type=float, default=0.1, metavar="D",
                        help="the leader's damping in teach mode, N·m·s/rad (default 0.1)")
    parser.add_argument("--record", metavar="DIR", help="record episodes into this LeRobot v3.0 dataset folder")
    parser.add_argument("--task", metavar="TEXT", help="what the episodes demonstrate (needed with --record)")
    parser.add_argument("--fps", type=int, default=30, metavar="N", help="frames per second recorded (default 30)")
    parser.add_argument("--camera", action="append", default=[], metavar="NAME",
                        help="record a simulated camera drawing the follower, as observation.images.NAME (again for "
                             "more; needs --record and the video extra)")
    parser.add_argument("--camera-size", default="96x96", metavar="WxH", help="the cameras' pixels (default 96x96)")
    parser.add_argument("--sim-control", metavar="PATH",
                        help="the follower simulator's control socket (akarm sim --control): the cameras draw the "
                             "object between its jaws")
    parser.add_argument("--episodes", type=int, metavar="N", help="quit after N episodes")
    parser.add_argument("--episode-time", type=float, metavar="S", help="end each episode after S seconds")
    parser.add_argument("--seconds", type=float, metavar="S", help="end the session after S seconds")
    parser.add_argument("--log", metavar="FILE.mcap", help="save both arms' telemetry as MCAP (for akarm plot)")
    parser.add_argument("--log-seconds", type=float, default=300.0, metavar="S",
                        help="how much of each arm's telemetry --log keeps, the last S seconds (default 300)")
    parser.add_argument("-i", "--interface", type=interface, help="python-can interface for both arms' buses")
    parser.add_argument("-c", "--channel", help="both arms' channel (two arms on one bus), or NAME=CHANNEL,...")
    parser.add_argument("--leader-channel", metavar="C", help="the leader's channel (or NAME=CHANNEL,...), over -c")
    parser.add_argument("--follower-channel", metavar="C", help="the follower's channel (or NAME=CHANNEL,...), over -c")
    parser.add_argument("-b", "--bitrate", type=bitrate, help="bit rate of both arms' buses, bit/s (10000-1000000)")
    add_bus_kwargs(parser)
    add_profile_argument(parser, arm_id=False)  # (two arms: each keyed by its own buses and channels)


def _check(args: argparse.Namespace) -> None:
    """What is checked before anything moves."""
    from akarm.cli.options import check_output
    from akarm.errors import ArgumentError

    if args.record is not None and not (args.task and args.task.strip()):
        raise ArgumentError("--record needs --task: what the episodes demonstrate", fix='e.g. --task "pick the cube"')
    if args.task is not None and args.record is None:
        raise ArgumentError("--task is for --record", fix="add --record DIR")
    for name in ("episode_time", "seconds", "log_seconds"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise ArgumentError(f"--{name.replace('_', '-')} must be positive, not {value}")
    if args.episodes is not None and args.episodes < 1:
        raise ArgumentError(f"--episodes must be at least 1, not {args.episodes}")
    if args.fps < 1:
        raise ArgumentError(f"--fps must be at least 1, not {args.fps}")
    if (args.camera or args.sim_control) and args.record is None:
        raise ArgumentError("--camera and --sim-control are for --record", fix="add --record DIR --task TEXT")
    if len(set(args.camera)) != len(args.camera) or len(args.camera) > 4:
        raise ArgumentError(f"--camera names {args.camera}: at most 4 cameras, each named once")
    camera_size(args.camera_size)
    check_output(args.log, (".mcap",), "the session's telemetry (both arms)")


def camera_size(text: str) -> tuple[int, int]:
    """``WxH`` as (width, height) pixels: even numbers of 8 to 4096 (what video takes)."""
    from akarm.datasets.video import check_frame_size
    from akarm.errors import ArgumentError

    w, sep, h = str(text).lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit()):
        raise ArgumentError(f"--camera-size {text!r} is not WIDTHxHEIGHT", fix="e.g. --camera-size 96x96")
    return check_frame_size(int(w), int(h))


class _Cameras:
    """The simulated cameras of ``--camera``: a pose file this process writes each cycle, and per
    camera a frame file and the process that draws into it (ended, and the files removed, at close)."""

    def __init__(self, args: argparse.Namespace, follower: RobotConfig) -> None:
        import subprocess

        from akarm.sim.camera import FrameFile, PoseFile

        self.width, self.height = camera_size(args.camera_size)
        self.pose = PoseFile.create(len(follower.joint_names))
        self.frames: dict[str, FrameFile] = {}
        self.processes: list[subprocess.Popen[bytes]] = []
        try:
            for name in args.camera:
                frames = self.frames[name] = FrameFile.create(self.width, self.height)
                cmd = [sys.executable, "-m", "akarm.sim.camera", args.follower, str(frames.path), str(self.pose.path),
                       "--width", str(self.width), "--height", str(self.height), "--fps", str(args.fps),
                       "--parent", str(os.getpid())]
                if args.sim_control:
                    cmd += ["--control", args.sim_control]
                # its own session: Ctrl-C is this process's to handle; it ends with its parent anyway
                self.processes.append(subprocess.Popen(cmd, start_new_session=True))
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        import subprocess

        for p in self.processes:
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(5.0)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(5.0)
        for frames in self.frames.values():
            frames.close()
        self.pose.close()


def _config(path: str, args: argparse.Namespace, channel: str | None) -> RobotConfig:
    from akarm.config import parse_channel
    from akarm.robotfile.load import load_robot
    from akarm.timing import get_profile

    config = load_robot(path)
    kwargs = args.bus_kwargs or None
    parsed = parse_channel(channel or args.channel)
    if isinstance(parsed, dict) and not channel:  # -c NAME=CHANNEL,... names both arms' buses: this arm's
        parsed = {k: v for k, v in parsed.items() if k in config.buses}
    if args.interface is not None or parsed or args.bitrate is not None or kwargs:
        config = config.with_bus(interface=args.interface, channel=parsed, bitrate=args.bitrate, options=kwargs)
    return get_profile(args.profile).apply(config)


def _check_shared_channels(args: argparse.Namespace, *configs: RobotConfig) -> None:
    """-c NAME=CHANNEL,... (both arms' buses in one mapping) names no bus that neither arm has."""
    from akarm.config import parse_channel
    from akarm.errors import ArgumentError, did_you_mean

    parsed = parse_channel(args.channel) if not (args.leader_channel and args.follower_channel) else None
    if isinstance(parsed, dict):
        known = [name for c in configs for name in c.buses]
        for name in parsed:
            if name not in known:
                raise ArgumentError(f"-c names bus {name!r}, which neither arm has{did_you_mean(name, known)}",
                                    fix=f"their buses are: {', '.join(known)}")


def _keys(stream: TextIO) -> queue.Queue[str]:
    """Keys on a queue, read by a daemon thread: each character at once from a terminal (cbreak mode,
    restored at exit), else whole lines (a script's ``\\n``, ``r\\n``, ``q\\n``); Enter is ``"\\n"``."""
    keys: queue.Queue[str] = queue.Queue()
    fd = stream.fileno() if hasattr(stream, "fileno") else -1
    if fd >= 0 and os.isatty(fd):
        import atexit
        import termios
        import tty

        saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        atexit.register(termios.tcsetattr, fd, termios.TCSADRAIN, saved)

        def read_chars() -> None:
            while True:
                try:
                    c = os.read(fd, 1).decode(errors="ignore")
                except OSError:
                    return
                if not c:
                    return
                keys.put("\n" if c == "\r" else c)

        threading.Thread(target=read_chars, name="akarm-teleop-keys", daemon=True).start()
        return keys

    def read_lines() -> None:
        try:
            for line in iter(stream.readline, ""):
                keys.put(line.strip()[:1] or "\n")
        except (OSError, ValueError):
            pass

    threading.Thread(target=read_lines, name="akarm-teleop-keys", daemon=True).start()
    return keys


class _Session:
    """The verb's loop: steps, keys, episodes, the progress line."""

    def __init__(self, tele: Teleop, recorder: EpisodeRecorder | None, args: argparse.Namespace,
                 pose: PoseFile | None = None) -> None:
        self.tele, self.recorder, self.args = tele, recorder, args
        self.pose = pose  # where the cameras' processes read the follower's pose
        self.saved = 0
        self.progress = sys.stderr.isatty()
        self.keys = _keys(sys.stdin)
        self.t_start = tele.follower.clock.now()

    def say(self, line: str) -> None:
        print(("\r\033[K" if self.progress else "") + line, file=sys.stderr, flush=True)

    def run(self) -> None:
        """Until q, --seconds or --episodes (a safety stop or Ctrl-C raises)."""
        shown = 0.0
        while True:
            step = self.tele.step()
            if self.pose is not None:
                self.pose.write(step.follower_q, step.gripper_width)
            if self._record(step) or self._keyed():
                return
            if self.args.seconds is not None and step.t - self.t_start >= self.args.seconds:
                self._save()
                return
            if self.progress and step.t - shown >= 0.1:
                shown = step.t
                self._progress(step.phase, step.latency)

    def _record(self, step: Step) -> bool:
        """Begin an episode once following, take the step's frame, end the episode at --episode-time;
        True when that was the last episode wanted."""
        rec, args = self.recorder, self.args
        if rec is None:
            return False
        if step.phase == "following" and not rec.recording and rec.cameras_ready:
            rec.begin(args.task, step.t)
            self.say(f"recording episode {rec.writer.total_episodes}: Enter ends it, r records it again, q quits")
        if rec.recording:
            rec.add(step)
            if (args.episode_time is not None and rec.seconds >= args.episode_time) or rec.full:
                return self._save()
        return False

    def _keyed(self) -> bool:
        """Act on a key; True to quit."""
        rec = self.recorder
        key = self._key()
        if key == "q":
            self._save()
            return True
        if rec is None or not rec.recording:
            return False
        if key == "\n":
            return self._save()
        if key == "r":
            rec.discard()
            self.say(f"episode {rec.writer.total_episodes} dropped: recording it again")
        return False

    def _key(self) -> str | None:
        try:
            return self.keys.get_nowait()
        except queue.Empty:
            return None

    def _save(self) -> bool:
        """Commit the episode being recorded, if any (Ctrl-C held back meanwhile); True when that was the
        last one wanted."""
        from akarm.cli.common import deferred_signals

        rec = self.recorder
        if rec is None or not rec.recording:
            return False
        self.tele.pause()
        frames, seconds = rec.frames, rec.seconds
        with deferred_signals("saving the episode; please wait"):
            k = rec.finish()
        if k is not None:
            self.saved += 1
            self.say(f"episode {k} saved: {frames} frames, {seconds:.1f} s")
        return self.args.episodes is not None and self.saved >= self.args.episodes

    def _progress(self, phase: str, latency: float) -> None:
        rec = self.recorder
        if rec is not None and rec.recording:
            text = f"episode {rec.writer.total_episodes}  {rec.seconds:6.1f} s  {rec.frames:6d} frames"
        else:
            text = f"{self.tele.follower.clock.now() - self.t_start:6.1f} s"
        print(f"\r\033[K{text}  {phase}  latency {latency * 1e3:.1f} ms", end="", file=sys.stderr, flush=True)

    def discard(self) -> None:
        rec = self.recorder
        if rec is not None and rec.recording:
            k = rec.writer.total_episodes
            rec.discard()
            self.say(f"episode {k} dropped (interrupted): nothing of it written")


def run(args: argparse.Namespace) -> int:
    """Enable both arms, teleoperate until q, Ctrl-C, a stop or --seconds; save; disable."""
    from akarm.teleop import Pairing

    _check(args)
    leader_config = _config(args.leader, args, args.leader_channel)
    follower_config = _config(args.follower, args, args.follower_channel)
    _check_shared_channels(args, leader_config, follower_config)
    pairing = Pairing.load(args.map, leader_config.joint_names, follower_config.joint_names) if args.map else \
        Pairing.in_order(leader_config.joint_names, follower_config.joint_names)
    cameras = _Cameras(args, follower_config) if args.camera else None
    try:
        return _run(args, leader_config, follower_config, pairing, cameras)
    finally:
        if cameras is not None:
            cameras.close()


def _run(args: argparse.Namespace, leader_config: RobotConfig, follower_config: RobotConfig, pairing: Pairing,
         cameras: _Cameras | None) -> int:
    from akarm.arm import Arm
    from akarm.cli.common import controlled, deferred_signals
    from akarm.errors import SafetyStop
    from akarm.teleop import Teleop

    recorder = _recorder(args, follower_config, cameras)
    seconds = args.log_seconds if args.log else 60.0
    leader = Arm(leader_config, telemetry_seconds=seconds, **loop_options(args))
    follower = Arm(follower_config, telemetry_seconds=seconds, **loop_options(args))
    code = 0
    with controlled(leader), controlled(follower):
        t0 = follower.clock.now()
        tele = Teleop(leader, follower, pairing, force_feedback=args.force_feedback, force_limit=args.force_limit,
                      engage_speed=args.engage_speed, damping=args.damping)
        session = _Session(tele, recorder, args, cameras.pose if cameras is not None else None)
        tele.say = session.say
        try:
            leader.enable()
            follower.enable()
            with tele:
                session.run()
        except KeyboardInterrupt as e:
            session.discard()
            session.say("interrupted: the follower comes to rest; both arms are damped and disabled")
            code = interrupted(e)
        except SafetyStop:
            session.discard()
            raise
        finally:
            if args.log:
                _save_log(args.log, leader, follower, t0)
            print(f"\n{tele.summary()}" if session.progress else str(tele.summary()), flush=True)
        with deferred_signals():
            leader.disable()
            follower.disable()
    if recorder is not None:
        print(f"{session.saved} episode{'s' if session.saved != 1 else ''} saved in {args.record} "
              f"({recorder.writer.total_episodes} in all)")
    return code


def _recorder(args: argparse.Namespace, follower: RobotConfig, cameras: _Cameras | None) -> EpisodeRecorder | None:
    """The dataset writer and its recorder (the folder checked before anything is enabled), or None."""
    if args.record is None:
        return None
    from akarm.datasets import GRIPPER, DatasetWriter
    from akarm.teleop.recording import EpisodeRecorder

    names = (*follower.joint_names, GRIPPER) if follower.gripper is not None else follower.joint_names
    frames = cameras.frames if cameras is not None else {}
    if frames:
        from akarm.datasets.video import require_av

        require_av()  # PyAV missing: said now, before anything moves
    writer = DatasetWriter(args.record, names, args.fps, robot_type=follower.name,
                           cameras={name: (f.width, f.height) for name, f in frames.items()})
    return EpisodeRecorder(writer, follower.rate_hz, frames)


def _save_log(path: str, leader: Arm, follower: Arm, since: float) -> None:
    from akarm.errors import AkarmError
    from akarm.telemetry.mcap import save_mcap

    try:
        out = save_mcap(path, {"leader": leader.telemetry(since=since), "follower": follower.telemetry(since=since)})
        print(f"telemetry of both arms saved to {out}", flush=True)
    except AkarmError as e:  # the session's own outcome is what the exit status says
        print(f"akarm teleop: telemetry not saved: {e}", file=sys.stderr)
