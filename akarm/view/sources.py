"""Where a view's snapshots come from, and the controls it may offer.

Every source gives :class:`~akarm.server.snapshot.Snapshot` objects when asked (the view asks
about 30 times a second, from a thread of its own, never the loop's):

- :class:`ServerSource`: an :class:`~akarm.server.server.ArmServerCore` in this process
  (``akarm serve --view``), with :class:`Controls`;
- :class:`RemoteSource`: a running ``akarm serve`` reached through its control socket
  (``akarm view ROBOT.yaml``), with :class:`Controls` over the same socket;
- :class:`ArmSource`: an :class:`~akarm.Arm` in this process (``akarm demo --view``), to watch only;
- :class:`SimSource`: a :class:`~akarm.sim.SimulatedRobot`'s simulated truth (``akarm sim --view``);
- :class:`akarm.view.recorded.RecordedSource`: a telemetry file played back.

:class:`Controls` are enable, hold, disable and a jog of one joint, carried out by the server's own
operations (``enable``, ``hold``, ``disable``, ``move`` with ``{joint: angle}``: jerk-limited,
checked against the limits by the Arm before anything moves). A jog is refused here first when it
is past the joint's range.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from akarm.errors import ArgumentError, LimitError, StateError
from akarm.server.snapshot import Snapshot, take

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.config import RobotConfig
    from akarm.server.server import ArmServerCore
    from akarm.sim import SimulatedRobot

__all__ = ["ArmSource", "Controls", "RemoteSource", "ServerSource", "SimSource", "Source"]


class Source(Protocol):
    """What a view watches. ``title`` says what it is; ``controls`` is ``None`` for a source that
    can only be watched."""

    title: str
    controls: Controls | None

    def snapshot(self) -> Snapshot:
        """The arm now. Raises :class:`~akarm.AkarmError` when the source is gone (a server that stopped)."""
        ...

    def close(self) -> None:
        """Let go of what the source holds (a socket); the arm is left as it is."""
        ...


class Controls:
    """Enable, hold, disable and jog, through a server's operations ``call(op, args)``.

    Args:
        call: runs a server operation (:meth:`ArmServerCore.dispatch
            <akarm.server.server.ArmServerCore.dispatch>`, or a control socket's call), raising its errors.
        config: the robot (each joint's range).
    """

    def __init__(self, call: Callable[[str, dict[str, Any]], Any], config: RobotConfig) -> None:
        self._call = call
        self.config = config

    #: the server operations the page's controls use, and the only ones :meth:`call` runs
    OPS = ("enable", "hold", "disable", "move")

    def call(self, op: str, args: dict[str, Any]) -> Any:
        """Run one of :attr:`OPS` as given (the view's process sends its controls' operations here,
        :mod:`akarm.view.process`); a ``move`` is checked as :meth:`jog` checks it.

        Raises:
            ArgumentError: another operation, or a move that is not one joint's jog.
            LimitError, StateError: as :meth:`jog` and the server's operations.
        """
        if op not in self.OPS or not isinstance(args, dict):
            raise ArgumentError(f"the view's controls do not run {op!r}", fix="one of: " + ", ".join(self.OPS))
        if op == "move":
            target, speed = args.get("target"), args.get("speed", 0.3)
            if not isinstance(speed, int | float) or isinstance(speed, bool):
                raise ArgumentError(f"jog speed {speed!r} is not a number", fix="a fraction of the joint limits")
            if not (isinstance(target, dict) and len(target) == 1) or set(args) - {"target", "speed"}:
                raise ArgumentError("a jog moves one joint: {'target': {joint: angle}, 'speed': s}",
                                    fix="jog one joint at a time")
            ((joint, value),) = target.items()
            self.jog(joint, value, speed)
            return None
        if args:
            raise ArgumentError(f"{op} takes no arguments, got {sorted(args)}", fix=f"call {op} with none")
        return self._call(op, {})

    def enable(self) -> None:
        """Enable the arm without a kick and hold it (as ``akarm enable``)."""
        self._call("enable", {})

    def hold(self) -> None:
        """Stop a motion (jerk-limited) and hold, or end teach mode."""
        self._call("hold", {})

    def disable(self) -> None:
        """Damp, then disable every joint."""
        self._call("disable", {})

    def check_jog(self, joint: str, value: float) -> float:
        """``value`` as a jog target of ``joint``, or the error saying why not.

        Raises:
            ArgumentError: no such joint, or not a finite number.
            LimitError: past the joint's range (the robot file's limits).
        """
        if joint not in self.config.joint_names:
            raise ArgumentError(f"no joint named {joint!r}", fix="joints are: " + ", ".join(self.config.joint_names))
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ArgumentError(f"jog target {value!r} is not a number", joint=joint,
                                fix="give an angle in rad") from None
        if not math.isfinite(x):
            raise ArgumentError(f"jog target {x} is not a finite angle", joint=joint, fix="give an angle in rad")
        lim = self.config.joint(joint).limits
        if not lim.lower <= x <= lim.upper:
            side = "upper" if x > lim.upper else "lower"
            raise LimitError(f"jog to {x:+.4f} rad is past the {side} limit: the range is "
                             f"[{lim.lower:+.4f}, {lim.upper:+.4f}] rad", joint=joint,
                             fix="jog within the range (the robot file's limits)")
        return x

    def jog(self, joint: str, value: float, speed: float = 0.3) -> None:
        """Move ``joint`` to ``value`` rad (the others keep their commanded position), jerk-limited at
        ``speed`` (a fraction of the joint limits, (0, 1]); a jog replaces a running one smoothly.

        Raises:
            LimitError: past the joint's range (nothing is sent), or refused by the Arm's planner.
            ArgumentError, StateError: as the server's ``move`` (the arm is not enabled ...).
        """
        x = self.check_jog(joint, value)
        if not 0 < speed <= 1:
            raise ArgumentError(f"jog speed {speed} must be in (0, 1]", fix="a fraction of the joint limits")
        self._call("move", {"target": {joint: x}, "speed": float(speed)})


class ServerSource:
    """An :class:`~akarm.server.server.ArmServerCore` in this process, with controls."""

    def __init__(self, server: ArmServerCore, title: str = "") -> None:
        self.server = server
        self.title = title or f"live: akarm serve in this process (pid {_pid()})"
        self.controls: Controls | None = Controls(lambda op, args: server.dispatch(op, args), server.arm.config)

    def snapshot(self) -> Snapshot:
        return self.server.snapshot()

    def close(self) -> None:
        pass


class ArmSource:
    """An :class:`~akarm.Arm` in this process, to watch (no controls: its own program drives it)."""

    def __init__(self, arm: Arm, title: str = "") -> None:
        self.arm = arm
        self.title = title or "live: this program's arm"
        self.controls: Controls | None = None

    def snapshot(self) -> Snapshot:
        return take(self.arm)

    def close(self) -> None:
        pass


class RemoteSource:
    """A running ``akarm serve`` found by :func:`akarm.buses.ownership.find_server` (``info``: what its
    bus lock says, with its ``socket``), watched and controlled through that socket. Snapshots and
    commands use connections of their own, so a command that takes time (enabling) does not hold
    the view up."""

    def __init__(self, config: RobotConfig, info: dict[str, Any], timeout: float = 5.0) -> None:
        from akarm.server.socket import SocketClient

        path = info.get("socket")
        if not path:
            raise StateError(f"another controller holds this robot's bus ({info.get('bus')}), not akarm serve",
                             fix="akarm view watches a robot served by akarm serve; stop the other controller")
        self.info = info
        self.title = f"live: akarm serve (pid {info.get('pid', '?')})"
        self._snap = SocketClient(path, timeout=timeout)
        self._cmd = SocketClient(path, timeout=None)  # enabling and disabling take a while
        self._snap_lock = threading.Lock()
        self._cmd_lock = threading.Lock()
        self.controls: Controls | None = Controls(self._command, config)

    def _command(self, op: str, args: dict[str, Any]) -> Any:
        with self._cmd_lock:
            return self._cmd.call(op, **args)

    def snapshot(self) -> Snapshot:
        with self._snap_lock:
            return Snapshot.from_doc(self._snap.call("snapshot"))

    def close(self) -> None:
        self._snap.close()
        self._cmd.close()


class SimSource:
    """A :class:`~akarm.sim.SimulatedRobot`'s simulated truth: the plant's positions and torques and
    the drivers' temperatures and error codes. Nothing here is commanded (``q_des`` is NaN); the
    mode says how many drivers drive their output."""

    def __init__(self, sim: SimulatedRobot, title: str = "") -> None:
        self.sim = sim
        self.title = title or "simulator: the simulated truth"
        self.controls: Controls | None = None

    def snapshot(self) -> Snapshot:
        states = self.sim.driver_states()
        n = len(states)
        nan = (math.nan,) * n
        on = sum(1 for s in states if s.enabled)
        faults = [f"{s.name}: {', '.join(s.faults)}" for s in states if s.faults]
        return Snapshot(t=self.sim.t, names=tuple(s.name for s in states), q=tuple(s.position for s in states),
                        q_des=nan, error=nan, tau=tuple(s.torque for s in states), tau_ff=nan,
                        temperature=tuple(s.temperature for s in states), age=nan,
                        fault=tuple(s.error for s in states), mode=f"{on} of {n} drivers on", enabled=on > 0,
                        moving=any(abs(s.velocity) > 1e-3 for s in states),
                        stop=("faults injected: " + "; ".join(faults)) if faults else "",
                        rate_hz=1.0 / self.sim.dt, loop_rate_hz=0.0, cycles=0, missed_slots=0)

    def close(self) -> None:
        pass


def _pid() -> int:
    import os

    return os.getpid()
