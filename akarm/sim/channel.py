"""A control channel into a simulator running in another process: inject faults, read the drivers, disable them.

``akarm sim ROBOT.yaml ... --control PATH`` serves it on a Unix-domain socket at ``PATH``;
:class:`SimulatorControl` is the client (and :class:`~akarm.sim.process.SimulatorProcess` opens one
for you with ``control=True``)::

    from akarm.sim import faults
    from akarm.sim.channel import SimulatorControl

    sim = SimulatorControl("/tmp/arm6-sim.sock")
    sim.inject("elbow", faults.Unplugged())      # or sim.inject("elbow", "drop:0.3"), as --fault spells it
    sim.state()                                  # per joint: enabled, position, error, faults, ...
    frames, _ = sim.frames()                     # every frame the drivers took in and sent
    sim.clear_faults()
    sim.push([0, 0, 0, 0, 0, 0.5])              # an external torque on the joints (N·m), until pushed again
    sim.disable_drivers()                        # every output limp; returns the joints that were enabled

The protocol is one JSON object per line each way, so any language (or ``socat``) can use it:

- ``{"cmd": "inject", "joint": "elbow", "fault": {"type": "DropReplies", "fraction": 0.3, "seed": 0}}``
  (a class of :mod:`akarm.sim.faults` and its fields), or ``{"cmd": "inject", "spec": "elbow:drop:0.3"}``
  (the ``--fault`` form);
- ``{"cmd": "clear"}`` or ``{"cmd": "clear", "joint": "elbow"}``;
- ``{"cmd": "push", "tau": [0, 0, 0.5]}`` (N·m per joint, config order) or ``{"cmd": "push", "tau": null}``:
  push the arm from outside, as a hand would, until changed (:meth:`~akarm.sim.SimulatedRobot.set_external_torque`);
- ``{"cmd": "state"}`` → ``{"ok": true, "t": ..., "slip": ..., "joints": [{"name": ..., "enabled": ...}, ...]}``;
- ``{"cmd": "late"}`` → ``{"ok": true, "late": s}``: the longest a frame waited before the simulator took
  it in, since the last such request (:meth:`~akarm.sim.SimulatedRobot.take_late`);
- ``{"cmd": "disable"}`` → ``{"ok": true, "joints": [names that were enabled]}``;
- ``{"cmd": "place_object", "width": 0.03, "stiffness": 20000}``, ``{"cmd": "remove_object"}``: an object
  between the gripper's jaws (:meth:`~akarm.sim.SimulatedRobot.place_object`), or none;
- ``{"cmd": "gripper"}`` → ``{"ok": true, "width": m, "force": N, "object": m or null, "between": bool}``:
  the jaws' width, their true squeeze, the placed object's width (null: none) and whether it is between
  the jaws now; ``{"cmd": "gripper", "width": 0.05}`` puts the jaws that far apart, at rest, first (a
  hand opening or closing a leader's free gripper);
- ``{"cmd": "frames", "since": 0}`` → ``{"ok": true, "next": N, "frames": [[t, bus, id, extended,
  data as hex, joint, to_motor], ...]}``: the frames the drivers took in and sent.

``state``, ``disable`` and ``frames`` first take in every frame already sent to the simulator, so
what a program sent before asking counts.

Every answer has ``"ok"``; a refused request answers ``{"ok": false, "error": "..."}`` and changes nothing.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import socket
import socketserver
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akarm.errors import AkarmError, StateError
from akarm.sim import faults as _faults
from akarm.sim.gripper import DEFAULT_OBJECT_STIFFNESS
from akarm.sim.records import DriverState, Frame

#: s a request that reads the drivers waits for the simulator to take in every frame sent before it
#: (less than :class:`SimulatorControl`'s 30 s, so the refusal arrives, not a time-out)
CATCH_UP = 20.0

if TYPE_CHECKING:
    from akarm.sim.robot import SimulatedRobot

__all__ = ["CATCH_UP", "ChannelServer", "SimulatorControl", "fault_from_json", "fault_to_json"]


def fault_to_json(fault: _faults.Fault) -> dict[str, Any]:
    """A fault as a JSON object: its class name under ``"type"`` and its fields."""
    if not dataclasses.is_dataclass(fault) or not isinstance(fault, _faults.Fault):
        raise AkarmError(f"{fault!r} is not a fault", fix="use a fault from akarm.sim.faults, e.g. faults.Unplugged()")
    return {"type": type(fault).__name__, **dataclasses.asdict(fault)}


def fault_from_json(obj: Any) -> _faults.Fault:
    """The fault a JSON object of :func:`fault_to_json` describes.

    Raises:
        AkarmError: not a fault of :mod:`akarm.sim.faults`, or fields it does not take.
    """
    name = obj.get("type") if isinstance(obj, dict) else None
    cls = getattr(_faults, name, None) if isinstance(name, str) and name in _faults.__all__ else None
    if not (isinstance(cls, type) and issubclass(cls, _faults.Fault) and dataclasses.is_dataclass(cls)):
        kinds = ", ".join(n for n in _faults.__all__ if dataclasses.is_dataclass(getattr(_faults, n)))
        raise AkarmError(f"unknown fault {obj!r}", fix=f'give {{"type": KIND, ...fields}}, KIND one of: {kinds}')
    try:
        return cls(**{k: v for k, v in obj.items() if k != "type"})
    except TypeError as e:
        raise AkarmError(f"bad fault {obj!r}: {e}", fix=f"the fields of {name} are: "
                         + ", ".join(f.name for f in dataclasses.fields(cls))) from None


# --------------------------------------------------------------------------- server (in the simulator)

class _Server(socketserver.ThreadingMixIn, socketserver.UnixStreamServer):
    daemon_threads = True
    sim: SimulatedRobot


class _Handler(socketserver.StreamRequestHandler):
    server: _Server

    def handle(self) -> None:
        for line in self.rfile:
            if not line.strip():
                continue
            try:
                answer = {"ok": True, **_serve(self.server.sim, json.loads(line))}
            except AkarmError as e:
                answer = {"ok": False, "error": str(e)}
            except Exception as e:  # a malformed request must not end the simulator
                answer = {"ok": False, "error": f"{type(e).__name__}: {e}"}
            self.wfile.write(json.dumps(answer).encode() + b"\n")
            self.wfile.flush()


def _serve(sim: SimulatedRobot, req: Any) -> dict[str, Any]:
    cmd = req.get("cmd") if isinstance(req, dict) else None
    if cmd == "inject":
        if "spec" in req:
            joint, fault = _faults.parse(str(req["spec"]))
        else:
            joint, fault = str(req.get("joint")), fault_from_json(req.get("fault"))
        sim.inject(joint, fault)
        return {}
    if cmd == "clear":
        sim.clear_faults(req.get("joint"))
        return {}
    if cmd == "push":
        sim.set_external_torque(req.get("tau"))  # the plant says what is wrong with a bad one
        return {}
    if cmd == "late":
        return {"late": sim.take_late()}
    if cmd in ("place_object", "remove_object", "gripper"):
        return _object(sim, cmd, req)
    if cmd in ("state", "disable", "frames"):
        # what was sent to the drivers before the request counts: an answer without it would be stale
        # (drivers still on whose EXIT waits in the queue), so none then, but why
        if not sim.wait_received(CATCH_UP):
            raise StateError(f"the simulator has not taken in the frames sent to it within {CATCH_UP:g} s: "
                             "it cannot keep up in real time on this machine",
                             fix="run it with the slow timing profile (--profile slow), or on a less busy machine")
        if cmd == "state":
            return {"t": sim.t, "slip": sim.slip, "joints": [dataclasses.asdict(s) for s in sim.driver_states()]}
        if cmd == "disable":
            return {"joints": sim.disable_drivers()}
        frames, next_index = sim.logged_frames(int(req.get("since", 0)))
        return {"next": next_index, "frames": [[f.t, f.bus, f.arbitration_id, f.is_extended, f.data.hex(), f.joint,
                                                 f.to_motor] for f in frames]}
    raise AkarmError(f"unknown request {req!r}",
                     fix='send {"cmd": "inject" | "clear" | "push" | "state" | "late" | "disable" | "frames" | '
                         '"place_object" | "remove_object" | "gripper", ...}')


def _object(sim: SimulatedRobot, cmd: str, req: dict[str, Any]) -> dict[str, Any]:
    """The gripper's object: placed, removed, or how the jaws are (width, true squeeze)."""
    if cmd == "place_object":
        sim.place_object(float(req["width"]), float(req.get("stiffness", DEFAULT_OBJECT_STIFFNESS)))
        return {}
    if cmd == "remove_object":
        sim.remove_object()
        return {}
    if req.get("width") is not None:
        sim.set_gripper_width(float(req["width"]))
    return {"width": sim.gripper_width(), "force": sim.object_force(), **sim.object_doc()}


class ChannelServer:
    """Serves :class:`SimulatorControl` requests for ``sim`` on the Unix-domain socket ``path`` (threads
    of its own; :meth:`close` stops them and removes the socket).

    Raises:
        StateError: the socket cannot be created (no Unix sockets here, a path too long, another
            simulator serving it).
    """

    def __init__(self, sim: SimulatedRobot, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not hasattr(socket, "AF_UNIX"):
            raise StateError("the simulator's control channel needs Unix-domain sockets, which this system lacks",
                             fix="inject faults at start instead: akarm sim --fault JOINT:KIND[:ARG]")
        if self.path.exists():
            if _answers(self.path):
                raise StateError(f"another simulator serves {self.path}", fix="give --control another path")
            with contextlib.suppress(OSError):
                self.path.unlink()  # left behind by a simulator that was killed
        try:
            self._server = _Server(str(self.path), _Handler)
        except OSError as e:
            raise StateError(f"cannot create the control socket {self.path}: {e}",
                             fix="give --control a short path in a directory you can write, e.g. /tmp/sim.sock") \
                from None
        self._server.sim = sim
        os.chmod(self.path, 0o600)  # only this user may inject faults
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.1},
                                        name="akarm-sim-control", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop serving and remove the socket. Safe to call twice."""
        if self._thread.is_alive():
            self._server.shutdown()
            self._thread.join(2.0)
        self._server.server_close()
        with contextlib.suppress(OSError):
            self.path.unlink()

    def __enter__(self) -> ChannelServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _answers(path: Path) -> bool:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        try:
            s.connect(str(path))
        except OSError:
            return False
        return True


# --------------------------------------------------------------------------- client

class SimulatorControl:
    """The client of a simulator's control channel (``akarm sim --control PATH``).

    Args:
        path: the socket. timeout: s to wait for an answer (a simulator in an emulated machine is slow).
    """

    def __init__(self, path: str | os.PathLike[str], timeout: float = 30.0) -> None:
        self.path = Path(path)
        self.timeout = timeout

    def request(self, **req: Any) -> dict[str, Any]:
        """Send one request; its answer.

        Raises:
            StateError: the simulator cannot be reached. AkarmError: it refused the request (its reason).
        """
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.settimeout(self.timeout)
                s.connect(str(self.path))
                s.sendall(json.dumps(req).encode() + b"\n")
                with s.makefile("rb") as f:
                    line = f.readline()
        except OSError as e:
            raise StateError(f"cannot reach the simulator's control channel {self.path}: {e}",
                             fix="is the simulator running, with --control at this path?") from None
        if not line:
            raise StateError(f"the simulator at {self.path} closed the control channel without answering",
                             fix="see the simulator's output: it may have stopped")
        answer = json.loads(line)
        if not answer.get("ok"):
            raise AkarmError(f"the simulator refused {req!r}: {answer.get('error')}")
        return answer

    def inject(self, joint: str, fault: _faults.Fault | str) -> None:
        """Start ``fault`` on ``joint`` now: a fault of :mod:`akarm.sim.faults`, or the ``--fault`` text
        after the joint (``"drop:0.3"``, ``"unplugged"``)."""
        if isinstance(fault, str):
            self.request(cmd="inject", spec=f"{joint}:{fault}")
        else:
            self.request(cmd="inject", joint=joint, fault=fault_to_json(fault))

    def clear_faults(self, joint: str | None = None) -> None:
        """End the faults of ``joint`` (default: of every joint)."""
        self.request(cmd="clear", joint=joint)

    def push(self, tau: list[float] | None) -> None:
        """Push the arm with joint torques ``tau`` (N·m, config order) from outside, until pushed again;
        ``None`` stops pushing (:meth:`~akarm.sim.SimulatedRobot.set_external_torque`)."""
        self.request(cmd="push", tau=None if tau is None else [float(x) for x in tau])

    def state(self) -> list[DriverState]:
        """Every driver as it is now, config order."""
        return [DriverState(**{**j, "faults": tuple(j["faults"])}) for j in self.request(cmd="state")["joints"]]

    def late(self) -> float:
        """The longest a frame waited before the simulator took it in, s, since the last call
        (:meth:`SimulatedRobot.take_late <akarm.sim.SimulatedRobot.take_late>`)."""
        return float(self.request(cmd="late")["late"])

    def disable_drivers(self) -> list[str]:
        """Every driver's output off now (see :meth:`~akarm.sim.SimulatedRobot.disable_drivers`); the
        joints that were enabled."""
        return list(self.request(cmd="disable")["joints"])

    def place_object(self, width: float, stiffness: float = DEFAULT_OBJECT_STIFFNESS) -> None:
        """An object ``width`` m wide between the gripper's jaws (:meth:`SimulatedRobot.place_object
        <akarm.sim.SimulatedRobot.place_object>`)."""
        self.request(cmd="place_object", width=float(width), stiffness=float(stiffness))

    def remove_object(self) -> None:
        self.request(cmd="remove_object")

    def gripper(self) -> tuple[float, float]:
        """The jaws' width (m) and their true squeeze on the object (N)."""
        answer = self.request(cmd="gripper")
        return float(answer["width"]), float(answer["force"])

    def set_gripper_width(self, width: float) -> None:
        """Put the jaws ``width`` m apart, at rest (a hand moving a free gripper)."""
        self.request(cmd="gripper", width=float(width))

    def gripper_object(self) -> tuple[float | None, bool]:
        """The placed object's width (m; None: none) and whether it is between the jaws now."""
        answer = self.request(cmd="gripper")
        width = answer.get("object")
        return (None if width is None else float(width)), bool(answer.get("between"))

    def frames(self, since: int = 0) -> tuple[list[Frame], int]:
        """The frames the drivers took in and sent from the ``since``-th on, and the index to ask from next
        (see :meth:`~akarm.sim.SimulatedRobot.logged_frames`)."""
        answer = self.request(cmd="frames", since=since)
        return [Frame(t, bus, aid, ext, bytes.fromhex(data), joint, to_motor)
                for t, bus, aid, ext, data, joint, to_motor in answer["frames"]], int(answer["next"])
