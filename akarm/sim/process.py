"""The simulator in a process of its own, as a real arm's drivers are hardware of their own.

::

    from akarm.sim.process import SimulatorProcess

    with SimulatorProcess("robots/arm6.yaml", channel="bench") as sim:     # akarm_local bus
        config = akarm.load_robot("robots/arm6.yaml").with_bus(interface="akarm_local", channel="bench")
        with akarm.Arm(config) as arm:
            arm.enable()
            ...
        print(sim.cpu_seconds())

It runs ``akarm sim`` (real time) and waits until the simulated drivers are on the bus. With
``control=True`` it opens the simulator's control channel (:attr:`SimulatorProcess.control`, a
:class:`~akarm.sim.channel.SimulatorControl`) to inject faults and read the drivers while it runs. An
in-process :class:`~akarm.sim.SimulatedRobot` shares the controller's interpreter lock, so each
delays the other; in its own process the simulator costs the controller nothing but the bus.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import os
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path

from akarm.errors import StateError
from akarm.sim.channel import SimulatorControl
from akarm.timing import PROFILES, TimingProfile, get_profile

__all__ = ["SimulatorProcess", "stat_cpu_seconds"]

_sockets = itertools.count()


def stat_cpu_seconds(stat_file: str | os.PathLike[str]) -> float:
    """User plus system CPU time, s, from a Linux ``/proc/PID/stat`` or ``/proc/PID/task/TID/stat``
    file; NaN where there is no such file (other systems, a process that has ended)."""
    try:
        fields = Path(stat_file).read_text().rsplit(")", 1)[1].split()  # after the command name
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
    except (OSError, IndexError, ValueError, AttributeError):
        return float("nan")


class SimulatorProcess:
    """``akarm sim ROBOT`` in a child process, for a ``with`` block.

    Args:
        robot: the robot's YAML file.
        interface, channel: the bus to simulate the drivers on (default: ``akarm_local``, ``can0``).
        pose: start the simulated arm at this named pose (default: all joints at zero).
        cpus: pin the simulator to these CPUs (Linux), e.g. to keep it off the control loop's core.
        args: more ``akarm sim`` arguments (``["--fault", "elbow:drop:0.3"]``).
        start_timeout: s to wait for the simulator to come up.
        timing: the simulator's timing profile (:mod:`akarm.timing`; default ``normal``).
        control: ``True`` to open its control channel on a socket of its own (:attr:`control`), or
            the socket's path.

    Attributes:
        control: the :class:`~akarm.sim.channel.SimulatorControl` (``None`` without ``control``).
        serial_ports: per joint given a serial port (``args=["--serial", "elbow=pty"]``), the path the
            simulator printed for it: the line's end a controller opens.

    Raises:
        StateError: the simulator did not start (with what it printed).
    """

    def __init__(self, robot: str | os.PathLike[str], *, interface: str = "akarm_local", channel: str = "can0",
                 pose: str | None = None, cpus: Iterable[int] | None = None, args: Sequence[str] = (),
                 start_timeout: float = 60.0, timing: str | TimingProfile | None = None,
                 control: bool | str | os.PathLike[str] = False) -> None:
        self.robot = Path(robot)
        self.interface = interface
        self.channel = channel
        self.timing = get_profile(timing)
        registered = PROFILES.get(self.timing.name) == self.timing
        timing_args = ["--profile", self.timing.name] if registered else ["--plant-rate", str(self.timing.sim_rate_hz)]
        self.control: SimulatorControl | None = None
        control_args: list[str] = []
        if control:
            path = Path(tempfile.gettempdir()) / f"akarm-sim-{os.getpid()}-{next(_sockets)}.sock" if control is True \
                else Path(control)
            self.control = SimulatorControl(path)
            control_args = ["--control", str(path)]
        self.command = [sys.executable, "-m", "akarm", "sim", str(self.robot), "-i", interface, "-c", channel, "-q",
                        *(["--pose", pose] if pose else []), *timing_args, *control_args, *args]
        self.cpus = set(cpus) if cpus is not None else None
        self.start_timeout = start_timeout
        self.proc: subprocess.Popen[str] | None = None
        self.serial_ports: dict[str, str] = {}
        self._output: collections.deque[str] = collections.deque(maxlen=50)
        self._reader: threading.Thread | None = None

    @property
    def pid(self) -> int:
        """The simulator's process ID."""
        if self.proc is None:
            raise StateError("the simulator process is not running", fix="use it in a `with` block")
        return self.proc.pid

    def __enter__(self) -> SimulatorProcess:
        self.proc = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if self.cpus and hasattr(os, "sched_setaffinity"):
            # at once, while the child is still starting Python: the threads it starts later inherit it
            os.sched_setaffinity(self.proc.pid, self.cpus)
        seen = self._output = collections.deque(maxlen=50)
        done = threading.Event()  # "running" was printed, or the output ended without it
        running = [False]

        def read() -> None:  # to the end, so a full pipe never blocks the simulator
            for line in self.proc.stdout:  # type: ignore[union-attr]
                seen.append(line)
                if not done.is_set() and line.startswith("running"):
                    running[0] = True
                    done.set()
            done.set()

        self._reader = threading.Thread(target=read, name="akarm-sim-output", daemon=True)
        self._reader.start()
        # started only on its own word: a child that closed its output may not have exited yet
        if not done.wait(self.start_timeout) or not running[0] or self.proc.poll() is not None:
            self.__exit__()
            raise StateError(f"the simulator did not start: {' '.join(self.command)}\n{self.output}",
                             fix="run that command yourself to see what is wrong")
        for line in list(seen):  # "  serial JOINT: PATH   (...)", printed before "running"
            if line.startswith("  serial "):
                joint, _, rest = line[len("  serial "):].partition(": ")
                self.serial_ports[joint] = rest.split()[0]
        return self

    @property
    def output(self) -> str:
        """The last 50 lines the simulator printed (what it says when it stops, or why it did not start)."""
        return "".join(self._output)

    def cpu_seconds(self) -> float:
        """CPU time the simulator has used so far, s (Linux; NaN elsewhere)."""
        return stat_cpu_seconds(f"/proc/{self.pid}/stat")

    def __exit__(self, *exc: object) -> None:
        proc, self.proc = self.proc, None
        if proc is None:
            return
        proc.terminate()
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if self._reader is not None:
            self._reader.join(5.0)  # its last words (or a traceback) into output
        if self.control is not None:  # the simulator removes it on a clean stop, not when killed
            with contextlib.suppress(OSError):
                self.control.path.unlink()
