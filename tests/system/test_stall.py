"""SIGSTOP of `akarm serve`: the loop's own stalls, in real time, against a simulator in another process.

The simulator runs on `akarm_local` with its control channel (which keeps a log of the frames its
drivers took in); `akarm serve` (ROS off) holds the arm and is stopped and continued with SIGSTOP and
SIGCONT; moves come from `akarm move` through it. What the motors were told is read back from the
simulator's log: no command steps further than the joint's velocity limit × one period.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import akarm
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, command_steps, relaxed_robot

#: real time: on a machine this loaded (1-minute load average per core) a process continued after
#: SIGCONT waits for a core longer than any stall limit (seen here at 14-19 on 2 cores: a 150 ms SIGSTOP
#: became 586-823 ms without a cycle), which tests the scheduler, not the controller
TOO_LOADED = 3.0
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(os.getloadavg()[0] > TOO_LOADED * (os.cpu_count() or 1),
                                 reason="the machine is too loaded for a real-time SIGSTOP test")]
PLANAR2 = ROBOTS / "planar2.yaml"
PAUSES = (0.05, 0.10, 0.15)
REPEATS = 20
#: s: the default 0.2 s and the scheduler's share on a busy machine: a 150 ms SIGSTOP was seen as 251 ms
#: without a cycle. The lock-step tests (tests/sim/test_watchdog.py) hold the default exactly.
STALL_LIMIT = 0.5


class Served:
    """``akarm serve ROBOT --no-ros`` in a child process; its stderr lines kept in :attr:`log`."""

    def __init__(self, robot: Path, channel: str) -> None:
        self.command = [sys.executable, "-m", "akarm", "serve", str(robot), "-i", "akarm_local", "-c", channel,
                        "--no-ros", "--stall-limit", str(STALL_LIMIT)]
        self.log: list[str] = []
        self.proc = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self._ready = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()
        if not self._ready.wait(60.0):
            self.close()
            raise AssertionError("akarm serve did not start: " + "".join(self.log))

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.log.append(line)
            if line.startswith("serving "):
                self._ready.set()

    def pause(self, seconds: float) -> None:
        os.kill(self.proc.pid, signal.SIGSTOP)
        try:
            time.sleep(seconds)
        finally:
            os.kill(self.proc.pid, signal.SIGCONT)

    def stops(self) -> list[str]:
        return [line for line in self.log if "safety stop" in line]

    def close(self) -> None:
        os.kill(self.proc.pid, signal.SIGCONT)
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(30.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def test_sigstop_of_akarm_serve_holding_and_moving(channel, tmp_path) -> None:
    """50, 100 and 150 ms SIGSTOPs, 20 times each while holding and 20 times each while moving: no stop,
    no command step; then 1 s: LoopStall, not FeedbackTimeout."""
    robot = relaxed_robot(PLANAR2, tmp_path)  # (only the watchdog's and tracking's slack: real time on a busy box)
    config = akarm.load_robot(robot)
    bus = [str(robot), "-i", "akarm_local", "-c", channel]
    with SimulatorProcess(robot, channel=channel, pose="down", control=True) as sim:
        assert sim.control is not None
        served = Served(robot, channel)
        try:
            for seconds in PAUSES * REPEATS:  # holding
                served.pause(seconds)
                time.sleep(0.05)
            assert served.stops() == [], served.stops()

            paused_moving = 0
            targets = ["up", "down"]
            while paused_moving < len(PAUSES) * REPEATS:
                move = subprocess.Popen([sys.executable, "-m", "akarm", "move", *bus, targets[0], "--speed", "0.3"],
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                targets.reverse()
                assert move.stdout is not None
                first = move.stdout.readline()  # "moving to up [...] rad in 3.29 s": under way from now
                duration = float(first.rsplit(" in ", 1)[1].split()[0]) if " in " in first else 0.0
                began = time.monotonic()
                # (the simulator's own state is not polled meanwhile: its control channel pauses it)
                while time.monotonic() - began < 0.8 * duration and paused_moving < len(PAUSES) * REPEATS:
                    served.pause(PAUSES[paused_moving % len(PAUSES)])
                    paused_moving += 1
                    time.sleep(0.05)
                out = first + move.communicate(timeout=120)[0]
                assert move.returncode == 0 and duration > 1.0, out
            assert served.stops() == [], served.stops()
            assert served.proc.poll() is None

            frames, _ = sim.control.frames()
            steps = command_steps(frames, config)
            assert max(steps.values()) <= 1.0 + 1e-6, steps  # no command stepped past v_max · period
            assert max(steps.values()) > 0.1, steps  # (the moves were seen)

            served.pause(1.0)
            deadline = time.monotonic() + 10.0
            while not served.stops() and time.monotonic() < deadline:
                time.sleep(0.05)
            stops = served.stops()
            assert len(stops) == 1 and "the control loop did not run for" in stops[0], stops
            assert "no reply" not in stops[0] and "FeedbackTimeout" not in stops[0]
            deadline = time.monotonic() + 10.0  # (the stop damps the arm first, then disables it)
            while any(d.enabled for d in sim.control.state()) and time.monotonic() < deadline:
                time.sleep(0.1)
            assert not any(d.enabled for d in sim.control.state())
        finally:
            served.close()
