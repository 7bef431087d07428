"""The CLI verbs when ``akarm serve`` runs for the robot: they ask the server instead of opening the bus.

Each verb calls :func:`via_server` first thing in its ``run``; it returns ``None`` when no server
drives the robot's buses (the verb then does what it always did), else runs the verb through the
server's control socket and returns the exit code. Output is the verb's own, except that the arm
is left held by the server instead of disabled, and the last line says so.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akarm.cli.common import format_q, interrupted, load_from_args

if TYPE_CHECKING:
    from akarm.config import RobotConfig
    from akarm.motion.recording import Keyframe, PathRecording
    from akarm.server.socket import SocketClient

__all__ = ["RemoteArm", "via_server"]


class RemoteArm:
    """The part of the :class:`~akarm.Arm` API the CLI verbs use, carried out by a running server."""

    def __init__(self, config: RobotConfig, info: dict[str, Any]) -> None:
        from akarm.server.socket import SocketClient

        self.config = config
        self.names = config.joint_names
        self.info = info
        self.pid = info.get("pid")
        self.client: SocketClient = SocketClient(info["socket"])

    def call(self, op: str, **args: Any) -> Any:
        return self.client.call(op, **args)

    def interrupt(self) -> None:
        """Bring the arm to rest (on a connection of its own: the first may be waiting for a reply)."""
        from akarm.server.socket import SocketClient

        with SocketClient(self.info["socket"], timeout=10.0) as c:
            c.call("stop")

    # what teach's helpers use
    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)
        self.call("recording_finished")  # raises the arm's safety stop, as Arm.sleep does

    @property
    def recording_finished(self) -> bool:
        return bool(self.call("recording_finished"))

    def keyframe(self, name: str | None = None) -> Keyframe:
        from akarm.motion.recording import Keyframe

        return Keyframe(tuple(self.call("keyframe", name=name)), name)

    def start_recording(self, rate_hz: float = 50.0, duration: float | None = None) -> None:
        self.call("start_recording", rate=rate_hz, seconds=duration)

    def stop_recording(self) -> PathRecording:
        import numpy as np

        from akarm.motion.recording import PathRecording

        doc = self.call("stop_recording")
        return PathRecording(tuple(doc["names"]), np.array(doc["t"]), np.array(doc["q"]))

    def close(self) -> None:
        self.client.close()


def via_server(args: argparse.Namespace) -> int | None:
    """Run ``args.verb`` through the server that drives this robot's buses; ``None`` when there is none."""
    from akarm.buses.ownership import any_server, find_server

    if not any_server():  # the common case, decided without loading the robot
        return None
    config = load_from_args(args)
    info = find_server(config)
    if info is None:
        return None
    if not info.get("socket"):
        from akarm.errors import StateError

        raise StateError(f"another controller holds this robot's bus ({info.get('bus')})", fix="stop it first")
    arm = RemoteArm(config, info)
    try:
        return _VERBS[args.verb](arm, args)
    finally:
        arm.close()


def _held(arm: RemoteArm) -> str:
    return f"held by akarm serve (pid {arm.pid})"


def _wait(arm: RemoteArm, motion: dict[str, Any]) -> dict[str, Any]:
    return arm.call("wait", id=motion["id"])


def _move(arm: RemoteArm, args: argparse.Namespace) -> int:
    import numpy as np

    from akarm.cli.move import check_options, parse_target

    check_options(args)
    target = parse_target(args.target, arm.config)  # a pose name, a vector, or {joint: rad}
    if isinstance(target, str):
        target = list(arm.config.pose(target))
    label = " ".join(args.target)
    try:
        arm.call("enable")
        motion = arm.call("move", target=target if isinstance(target, dict) else list(target), speed=args.speed)
        q_target = np.array(motion["target"])
        print(f"moving to {label} {format_q(q_target)} in {motion['duration']:.2f} s", flush=True)
        done = _wait(arm, motion)
        if args.hold > 0:
            arm.call("sleep", seconds=args.hold)
    except KeyboardInterrupt as e:  # Ctrl-C, SIGTERM, SIGHUP
        arm.interrupt()
        print(f"interrupted: stopped; {_held(arm)}", file=sys.stderr)
        return interrupted(e)
    q = np.array(arm.call("state")["q"])
    err = np.abs(q - q_target)
    if done["superseded"]:  # a ROS 2 trajectory or another CLI took over
        print(f"akarm move: another command replaced this motion before it arrived; at {format_q(q)}",
              file=sys.stderr)
    else:
        print(f"arrived: {format_q(q)}, largest error {err.max() * 1e3:.2f} mrad ({arm.names[int(err.argmax())]})")
    if args.log:
        saved = arm.call("telemetry", since=motion["t0"], save=os.path.abspath(args.log))
        print(f"telemetry saved to {saved['path']}")
    print(_held(arm))
    return 1 if done["superseded"] else 0


def _enable(arm: RemoteArm, args: argparse.Namespace) -> int:
    """Enable and return: the server holds the arm. With ``--seconds``, as without a server: hold
    that long, then disable."""
    from akarm.errors import AkarmError

    if args.seconds is not None and not args.seconds >= 0:
        raise AkarmError(f"--seconds {args.seconds} must not be negative")
    state = arm.call("enable")
    if args.seconds is None:
        print(f"enabled {arm.config.name}: holding at {format_q(state['q'])} ({', '.join(arm.names)}); "
              f"{_held(arm)} (akarm disable releases it)", flush=True)
        return 0
    print(f"enabled {arm.config.name}: holding at {format_q(state['q'])} ({', '.join(arm.names)}) for "
          f"{args.seconds:g} s", flush=True)
    try:
        arm.call("sleep", seconds=args.seconds)
    except KeyboardInterrupt as e:
        print(f"interrupted: {_held(arm)}", file=sys.stderr)
        return interrupted(e)
    arm.call("disable")
    print("disabled")
    return 0


def _disable(arm: RemoteArm, args: argparse.Namespace) -> int:
    arm.call("disable")
    print(f"disabled {arm.config.name} through akarm serve (pid {arm.pid}): damped, then motor mode exited; "
          "the arm is limp, support it (akarm enable holds it again)")
    return 0


def _status(arm: RemoteArm, args: argparse.Namespace) -> int:
    from akarm.cli.status import check_options, watch
    from akarm.control.probe import JointStatus

    check_options(args)
    last: dict[str, Any] = {}

    def read() -> list[JointStatus]:
        d = last["doc"] = arm.call("state")
        return [JointStatus(name, mode, bus, can_id, q, dq, tau, temp, fault, False)
                for name, mode, bus, can_id, q, dq, tau, temp, fault in
                zip(d["names"], d["modes"], d["buses"], d["can_ids"], d["q"], d["dq"], d["tau"],
                    d["temperature"], d["fault"], strict=True)]

    def first() -> None:
        d = last["doc"]
        if not args.json:
            print(f"({d['mode']}; {_held(arm)})" if d["enabled"] else f"({d['mode']}; read through akarm serve "
                                                                      f"pid {arm.pid})")

    watch(args, read, first)
    return 0


def _teach(arm: RemoteArm, args: argparse.Namespace) -> int:
    from akarm.cli.teach import _reader, _teach_keyframes, _teach_path, default_sample_rate

    out = Path(args.out)  # checked by the verb before it asked the server
    lines = _reader(sys.stdin)
    state = arm.call("enable")
    rate = args.sample_rate if args.sample_rate is not None else default_sample_rate(state["rate_hz"])  # its loop
    try:  # the server ends teach mode itself if this process goes without ending it (killed, hung up)
        arm.call("teach", damping=args.damping)
        if out.suffix == ".csv":
            code = _teach_path(arm, out, lines, rate, args.seconds)  # type: ignore[arg-type]
        else:
            code = _teach_keyframes(arm, out, lines)  # type: ignore[arg-type]
    finally:
        arm.call("end_teach")
    print(_held(arm))
    return code


def _replay(arm: RemoteArm, args: argparse.Namespace) -> int:
    from akarm.cli.replay import check_options

    check_options(args)  # before anything moves
    path = os.path.abspath(args.file)
    arm.call("check_replay", path=path, speed=args.speed)  # the whole path, before anything moves
    try:
        arm.call("enable")
        motion = arm.call("replay", path=path, speed=args.speed)
        print(f"replaying {args.file} ({motion['kind']}) in {motion['duration']:.2f} s at speed {args.speed:g}",
              flush=True)
        _wait(arm, motion)
    except KeyboardInterrupt as e:  # Ctrl-C, SIGTERM, SIGHUP
        arm.interrupt()
        print(f"interrupted: stopped; {_held(arm)}", file=sys.stderr)
        return interrupted(e)
    tel = arm.call("telemetry", since=motion["t0"], save=os.path.abspath(args.log) if args.log else None)
    print("done; RMS tracking error " + ", ".join(f"{n} {e * 1e3:.2f} mrad"
                                                  for n, e in zip(arm.names, tel["rms"], strict=True)))
    if tel["path"]:
        print(f"telemetry saved to {tel['path']}")
    print(_held(arm))
    return 0


_VERBS = {"move": _move, "enable": _enable, "disable": _disable, "status": _status, "teach": _teach,
          "replay": _replay}
