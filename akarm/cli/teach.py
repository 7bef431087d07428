"""``akarm teach ROBOT.yaml OUT.yaml|OUT.csv``: hand-guide the arm and record where it goes.

The arm is enabled, then made hand-guidable with its weight carried (no stiffness, a little damping).

- **Keyframes** (``OUT.yaml``): each Enter stores the current pose; text typed before Enter names
  it (``pick`` + Enter); ``q`` + Enter, end of input or Ctrl-C finishes. Replay passes through the
  poses in one smooth move.
- **A continuous path** (``OUT.csv``): the pose is recorded ``--sample-rate`` times a second until Enter,
  end of input, Ctrl-C or ``--seconds``. Replay follows it at its recorded timing.

Input is read line by line from stdin, so a script can drive it (``printf 'pick\\nplace\\nq\\n' | akarm teach ...``).
The file is written atomically, also after Ctrl-C (exit 130), SIGTERM or SIGHUP (exit 143, 129) or a
safety stop (exit 1) with what was taught so far; then the arm is damped and disabled, also when the
file cannot be written (a path that cannot be written is refused before anything is enabled).
"""

from __future__ import annotations

import argparse
import contextlib
import queue
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, TextIO

from akarm.cli.common import add_profile_argument, add_robot_arguments, interrupted, load_from_args, loop_options
from akarm.errors import AkarmError

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm
    from akarm.config import RobotConfig
    from akarm.motion.recording import Keyframe, PathRecording


class _Teachable(Protocol):
    """What teaching needs of the arm: an :class:`~akarm.Arm` here, or the
    :class:`~akarm.cli.served.RemoteArm` of an ``akarm serve`` (which is in teach mode already)."""

    config: RobotConfig
    names: tuple[str, ...]

    @property
    def recording_finished(self) -> bool: ...

    def sleep(self, seconds: float) -> None: ...

    def keyframe(self, name: str | None = None) -> Keyframe: ...

    def start_recording(self, rate_hz: float = 50.0, duration: float | None = None) -> None: ...

    def stop_recording(self) -> PathRecording: ...


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import duration, renamed

    add_robot_arguments(parser)
    parser.add_argument("out", metavar="OUT.yaml|OUT.csv", help="keyframes (.yaml) or a continuous path (.csv)")
    parser.add_argument("--sample-rate", type=float, metavar="HZ",
                        help="continuous path: samples per second (default 50, or half the loop rate if lower; "
                             "at most the loop rate)")
    renamed(parser, "--rate", "--sample-rate")
    parser.add_argument("--seconds", type=duration, metavar="S", help="continuous path: stop after S seconds")
    parser.add_argument("--damping", type=float, default=0.1, metavar="D",
                        help="MIT joints: damping while guided, N·m·s/rad (default 0.1, at most the joint's kd)")
    add_profile_argument(parser)


def _reader(stream: TextIO) -> queue.Queue[str | None]:
    """Lines of ``stream`` (without the newline) on a queue, read by a daemon thread; ``None`` at the end."""
    lines: queue.Queue[str | None] = queue.Queue()

    def read() -> None:
        try:
            for line in iter(stream.readline, ""):
                lines.put(line.rstrip("\r\n"))
        except (OSError, ValueError):  # stdin closed under us
            pass
        lines.put(None)

    threading.Thread(target=read, name="akarm-teach-stdin", daemon=True).start()
    return lines


def _next_line(arm: _Teachable, lines: queue.Queue[str | None], timed: bool = False) -> tuple[bool, str | None]:
    """Wait for a line while the arm keeps running (its safety stop is raised here).

    Returns ``(True, line)`` (``line`` None at end of input), or ``(False, None)`` when ``timed``
    and the arm's recording has all the samples its duration asked for.
    """
    while True:
        try:
            return True, lines.get_nowait()
        except queue.Empty:
            pass
        if timed and arm.recording_finished:
            return False, None
        arm.sleep(0.02)


def _teach_keyframes(arm: _Teachable, out: Path, lines: queue.Queue[str | None]) -> int:
    from akarm.cli.common import format_q
    from akarm.errors import RecordingError
    from akarm.motion.recording import Keyframes

    frames: list[Keyframe] = []

    def save() -> bool:  # never raises: a file that cannot be written must not hide why teaching ended
        if not frames:
            print("akarm teach: no keyframe was taught; nothing written", file=sys.stderr)
            return False
        try:
            path = Keyframes(arm.names, tuple(frames), arm.config.name).save(out)
        except RecordingError as e:
            print(f"akarm teach: error: {e}", file=sys.stderr)
            return False
        print(f"wrote {len(frames)} keyframe{'s' if len(frames) != 1 else ''} to {path}", flush=True)
        return True

    print("teach: move the arm by hand; Enter stores the pose (type a name first to name it); q + Enter finishes",
          file=sys.stderr, flush=True)
    try:
        while True:
            _, line = _next_line(arm, lines)
            if line is None or line.strip() == "q":
                break
            name = line.strip() or None
            frame = arm.keyframe(name)
            frames.append(frame)
            label = f" {name!r}" if name else ""
            print(f"stored keyframe {len(frames)}{label}: {format_q(frame.q)}", flush=True)
    except KeyboardInterrupt as e:
        save()
        return interrupted(e)
    except BaseException:
        save()
        raise
    return 0 if save() else 1


def _teach_path(arm: _Teachable, out: Path, lines: queue.Queue[str | None], rate: float, seconds: float | None) -> int:
    from akarm.errors import AkarmError, StateError

    arm.start_recording(rate, seconds)
    what = "Enter" + (f" or {seconds:g} s" if seconds is not None else "")
    print(f"teach: recording at {rate:g} Hz; move the arm by hand; {what} stops", file=sys.stderr, flush=True)
    code = 0
    try:
        _next_line(arm, lines, timed=seconds is not None)
    except KeyboardInterrupt as e:
        code = interrupted(e)
    except AkarmError:  # a safety stop: keep what was recorded up to it, then report the stop
        try:
            rec = arm.stop_recording()
            print(f"wrote {len(rec.t)} samples over {rec.duration:.2f} s (up to the stop) to {rec.save(out)}",
                  flush=True)
        except AkarmError as e:
            print(f"akarm teach: nothing written: {e}", file=sys.stderr)
        raise
    try:
        rec = arm.stop_recording()
    except StateError as e:
        raise StateError("nothing was recorded (stopped at once?); nothing written",
                         fix="record for longer: press Enter after moving the arm, or use --seconds") from e
    path = rec.save(out)
    print(f"wrote {len(rec.t)} samples over {rec.duration:.2f} s to {path}", flush=True)
    return code


def default_sample_rate(loop_rate_hz: float) -> float:
    """Hz: 50, or half the loop rate if that is less (at the loop's own rate, an early cycle misses
    its sample)."""
    return min(50.0, loop_rate_hz / 2)


def run(args: argparse.Namespace) -> int:
    """Enable, teach, write the file, disable."""
    from akarm.cli.common import controlled, deferred_signals
    from akarm.errors import AkarmError
    from akarm.files import check_writable
    from akarm.timing import get_profile

    out = Path(args.out)
    if out.suffix not in (".yaml", ".yml", ".csv"):
        raise AkarmError(f"{out}: unknown recording type {out.suffix!r}",
                         fix="name it .yaml (keyframes) or .csv (a continuous path)")
    if (args.sample_rate is not None and not args.sample_rate > 0) or (args.seconds is not None
                                                                       and not args.seconds > 0):
        raise AkarmError("--sample-rate and --seconds must be positive")
    check_writable(out)  # before anything is enabled: a file that cannot be written is said now, not after
    config = get_profile(args.profile).apply(load_from_args(args))
    from akarm.cli.served import via_server

    # an `akarm serve` drives this robot: ask it (the checks above hold for it too)
    if (served := via_server(args, _served)) is not None:
        return served
    if args.sample_rate is None:
        args.sample_rate = default_sample_rate(config.rate_hz)
    if out.suffix == ".csv" and args.sample_rate > config.rate_hz:
        raise AkarmError(f"--sample-rate {args.sample_rate:g} Hz is above the loop rate {config.rate_hz:g} Hz",
                         fix=f"use at most --sample-rate {config.rate_hz:g}")
    lines = _reader(sys.stdin)
    with controlled(config, **loop_options(args)) as arm:
        arm.enable()
        arm.teach(args.damping)
        if out.suffix == ".csv":
            code = _teach_path(arm, out, lines, args.sample_rate, args.seconds)
        else:
            code = _teach_keyframes(arm, out, lines)
        with deferred_signals():
            arm.end_teach()
            arm.disable()
    return code


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """Teach through ``akarm serve``: as without it, but the server holds the arm afterwards."""
    out = Path(args.out)  # checked by run before it asked the server
    lines = _reader(sys.stdin)
    state = arm.call("ready")  # refused while a safety stop is latched; a disabled arm is enabled
    rate = args.sample_rate if args.sample_rate is not None else default_sample_rate(state["rate_hz"])  # its loop
    try:  # the server ends teach mode itself if this process goes without ending it (killed, hung up)
        arm.call("teach", damping=args.damping)
        if out.suffix == ".csv":
            code = _teach_path(arm, out, lines, rate, args.seconds)
        else:
            code = _teach_keyframes(arm, out, lines)
    except BaseException:  # a safety stop, Ctrl-C: said as it is, not hidden by a failure to end teach mode
        with contextlib.suppress(AkarmError):
            arm.call("end_teach")
        raise
    arm.call("end_teach")
    print(arm.held)
    return code
