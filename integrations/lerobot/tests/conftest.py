"""The LeRobot plugins against akarm's simulator: simulators and servers in processes of their own,
LeRobot's scripts as the user runs them. Needs the LeRobot venv (.ci/run's "lerobot" stage)."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

ROBOTS = Path(__file__).resolve().parents[3] / "robots"
BIN = Path(sys.executable).parent
_counter = itertools.count()


@pytest.fixture(autouse=True)
def offline_hf(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Nothing downloaded; calibration and the hub's cache in this test's folder."""
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "calibration"))
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf"))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))  # akarm's remembered positions: this test's


@pytest.fixture
def robot(tmp_path: Path) -> Path:
    """planar2 with a supervisor that tolerates this loaded 2-core machine (feedback 1 s old, the
    reading 3 rad behind the command): a real-time loop against simulators in other processes (a
    simulator starved for 0.5 s while torch loaded stopped an arm here, at a load average of 12-15)."""
    doc = yaml.safe_load((ROBOTS / "planar2.yaml").read_text())
    doc["urdf"] = str(ROBOTS / doc["urdf"])
    doc.setdefault("defaults", {}).update(feedback_timeout=1.0, stuck_travel=3.0, following_error=3.0)
    path = tmp_path / "planar2.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture
def robot6g(tmp_path: Path) -> Path:
    """arm6g (six joints and a parallel gripper, 80 mm stroke) with the same tolerant supervisor, its
    gripper's motor too."""
    doc = yaml.safe_load((ROBOTS / "arm6g.yaml").read_text())
    doc["urdf"] = str(ROBOTS / doc["urdf"])
    doc.setdefault("defaults", {}).update(feedback_timeout=1.0, stuck_travel=3.0, following_error=3.0)
    doc["gripper"]["feedback_timeout"] = 1.0
    # collision thresholds 3x: a simulator starved on this loaded machine lags its arm, and the model's
    # torque then misses the reading by several N·m while the follower moves fast (7.5 N·m on the
    # shoulder_lift's 2.1 once, at a load average of 9)
    for joint in doc["joints"]:
        if "collision" in joint:
            joint["collision"]["threshold"] = 3 * float(joint["collision"]["threshold"])
    path = tmp_path / "arm6g.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    return f"lr-{os.getpid()}-{next(_counter)}"


@contextmanager
def served(robot: Path, channel: str) -> Iterator[Any]:
    """``akarm serve`` (ROS off) on ``channel``, held, and a control connection to it. Its stall limit is
    3 s: on this shared 2-core machine (load average 12-15) a server's loop was starved 1.1-1.2 s while
    LeRobot started or trained, and stopped the arm with LoopStall, as it should; the tests are about the
    plugins (a real arm keeps the profile's 0.2 s)."""
    import akarm
    from akarm.buses.ownership import find_server
    from akarm.server.socket import SocketClient

    cmd = [sys.executable, "-m", "akarm", "serve", str(robot), "--no-ros", "--stall-limit", "3.0",
           "-i", "akarm_local", "-c", channel]
    p = subprocess.Popen(cmd, start_new_session=True)
    config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
    try:
        end = time.monotonic() + 60
        info = None
        while time.monotonic() < end and p.poll() is None:
            info = find_server(config, wait=0.2)
            if info and info.get("socket") and info.get("pid") == p.pid and Path(info["socket"]).exists():
                break
            time.sleep(0.1)
        assert info and p.poll() is None, "akarm serve did not start"
        client = SocketClient(info["socket"], timeout=30)
        try:
            yield client
        finally:
            client.close()
    finally:
        p.terminate()
        p.wait(30)


class Hand:
    """A hand guiding a simulated arm in another process (its control channel): a spring and damper
    pulling the joints along ``path(t)``, pushed at about 50 Hz from a thread (soft: a stiffer spring,
    pushed every 20 ms against planar2's light elbow, oscillates)."""

    def __init__(self, control: Any, path: Callable[[float], np.ndarray], k: Any = (3.0, 1.0),
                 d: Any = (0.4, 0.1), grip: Callable[[float], float] | None = None,
                 teaching: Any = None) -> None:
        self.control, self.path, self.grip = control, path, grip  # grip: the free gripper's width at t, m
        # teaching: the leader's server (a control connection): the hand waits for its teach mode and
        # then moves the arm by path(t) - path(0) from where it is (an arm that sagged before its server
        # held it is not pulled back: a held arm pushed hard stops for a collision, as it should)
        self.teaching = teaching
        self.start: np.ndarray | None = None
        self.grip_start = 0.0
        self.width: float | None = None  # the jaws' width the hand holds them at, m
        self.last: np.ndarray | None = None  # the last push, N·m
        self.released = False
        self.k, self.d = np.asarray(k, float), np.asarray(d, float)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self.t0 = time.monotonic()

    def _run(self) -> None:
        while not self._stop.wait(0.02):
            try:
                joints = self.control.state()
            except Exception:
                continue
            q = np.array([j.position for j in joints])[:len(self.k)]  # (not a gripper's motor)
            dq = np.array([j.velocity for j in joints])[:len(self.k)]
            if self.teaching is not None:
                try:
                    teach = self.teaching.call("state", read=False)["mode"] == "teach"
                except Exception:
                    teach = False
                if not teach:  # not yet, or no more (the session ended): the hand lets go
                    if self.start is not None:
                        self._let_go(self.last if self.last is not None else np.zeros(len(self.k)))
                        return
                    continue
            if self.teaching is not None and self.start is None:
                self.start, self.t0 = q - self.path(0.0), time.monotonic()
                if self.grip is not None:  # the jaws too, from where they are (a jump is implausible feedback)
                    with suppress(Exception):
                        self.width = self.control.gripper()[0]
                        self.grip_start = self.width - self.grip(0.0)
            t = time.monotonic() - self.t0
            want = self.path(t) if self.start is None else self.start + self.path(t)
            tau = self.k * (want - q) - self.d * dq
            self.last = tau
            with suppress(Exception):
                self.control.push([float(x) for x in tau])
            if self.grip is not None:  # at most 1.5 mm a push (75 mm/s): a starved thread must not make the
                # jaws jump (the leader's server stops for implausible feedback, as it should)
                want_w = min(max(self.grip(t) + self.grip_start, 0.0), 0.08)
                if self.width is None:
                    self.width = want_w
                self.width += min(max(want_w - self.width, -0.0015), 0.0015)
                with suppress(Exception):
                    self.control.set_gripper_width(self.width)

    def _let_go(self, tau: np.ndarray) -> None:
        """Release the push over 1 s (a held arm whose push vanishes at once feels a sudden torque: a
        collision, as it should)."""
        for k in range(50, -1, -1):
            with suppress(Exception):
                self.control.push([float(x) * k / 50 for x in tau] if k else None)
            time.sleep(0.02)
        self.released = True

    def __enter__(self) -> Hand:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.teaching is not None and self.start is not None:  # it lets go by itself once teach mode ends
            self._thread.join(10)
        self._stop.set()
        self._thread.join(2)
        if not self.released:
            with suppress(Exception):
                self.control.push(None)


def sway(q0: Any, amplitude: Any, period: float) -> Callable[[float], np.ndarray]:
    q0, amplitude = np.asarray(q0, float), np.asarray(amplitude, float)
    return lambda t: q0 + amplitude * 0.5 * (1.0 - math.cos(2.0 * math.pi * t / period))


class Poller:
    """Polls a server (``state`` and ``status``) at about 100 Hz from a thread: the arm's measured path
    and the loop's lateness and missed slots while LeRobot runs."""

    def __init__(self, client: Any, period: float = 0.01) -> None:
        self.client, self.period = client, period
        self.t: list[float] = []
        self.q: list[list[float]] = []
        self.grip: list[float] = []  # the gripper's width, m (NaN: none, or not heard)
        self.status: list[dict[str, Any]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        k = 0
        while not self._stop.wait(self.period):
            try:
                doc = self.client.call("state", read=False)
                self.t.append(time.monotonic())
                self.q.append(doc["q"])
                g = doc.get("gripper") or {}
                self.grip.append(math.nan if g.get("width") is None else float(g["width"]))
                k += 1
                if k % 50 == 0:
                    self.status.append(self.client.call("status"))
            except Exception:
                return

    def __enter__(self) -> Poller:
        self.status.append(self.client.call("status"))
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        self.status.append(self.client.call("status"))

    @property
    def path(self) -> np.ndarray:
        return np.array(self.q)


def run_script(name: str, *args: str, timeout: float = 600, during: Callable[[], None] | None = None,
               ) -> subprocess.CompletedProcess[str]:
    """A LeRobot console script of this venv, as the user runs it; its output kept."""
    p = subprocess.Popen([str(BIN / name), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out: list[str] = []
    reader = threading.Thread(target=lambda: out.extend(p.stdout), daemon=True)  # type: ignore[arg-type]
    reader.start()
    try:
        p.wait(timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    reader.join(5)
    text = "".join(out)
    print(text[-6000:])
    return subprocess.CompletedProcess(p.args, p.returncode, text, "")
