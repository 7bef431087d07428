"""A script that owns its Arm serves it (ArmServer, akarm.serve); the CLI verbs use the server.

The simulator runs in its own process on `akarm_local`; the server runs here (ROS off); the CLI
verbs run as processes of their own, as a user would start them.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import yaml

import akarm
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot

pytestmark = pytest.mark.slow
PLANAR2 = ROBOTS / "planar2.yaml"


def cli(*args: str, stdin: str | None = None, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "akarm", *args], input=stdin, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture
def local_arm(channel, tmp_path):
    robot = relaxed_robot(PLANAR2, tmp_path)  # real time against another process on a busy machine
    with SimulatorProcess(robot, channel=channel, pose="down"):
        config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
        with akarm.Arm(config) as arm:
            yield arm, [str(robot), "-i", "akarm_local", "-c", channel]


def test_cli_verbs_drive_the_arm_a_script_serves(local_arm, tmp_path):
    arm, bus = local_arm
    with akarm.ArmServer(arm, ros=False) as server:
        assert arm.enabled and server.mode == "holding"
        out = cli("enable", *bus)
        assert out.returncode == 0, out.stderr
        assert f"held by akarm serve (pid {os.getpid()})" in out.stdout

        out = cli("move", *bus, "up", "--speed", "0.5", "--log", str(tmp_path / "up.csv"))
        assert out.returncode == 0, out.stderr
        assert "moving to up" in out.stdout and "arrived" in out.stdout and (tmp_path / "up.csv").is_file()
        assert np.abs(arm.state().q - [1.2, -1.2]).max() < 5e-3 and arm.enabled, "held after the move"

        out = cli("move", *bus, "elbow=-0.9")  # some joints by name: the others stay
        assert out.returncode == 0, out.stderr
        assert "moving to elbow=-0.9 [+1.2000, -0.9000] rad" in out.stdout
        assert np.abs(arm.state().q - [1.2, -0.9]).max() < 5e-3

        out = cli("move", *bus, "9,9")
        assert out.returncode == 1 and "LimitError" not in out.stderr and "outside" in out.stderr
        assert arm.enabled and not arm.moving

        out = cli("teach", *bus, str(tmp_path / "k.yaml"), stdin="first\n\nq\n")
        assert out.returncode == 0, out.stderr
        doc = yaml.safe_load((tmp_path / "k.yaml").read_text())
        assert [k.get("name") for k in doc["keyframes"]] == ["first", None]
        assert arm.enabled and server.mode == "holding", "teach ends holding, not disabled"
        # where the hand left it (the last keyframe, taken just before `q`) is where it is held now
        assert np.abs(np.array(doc["keyframes"][1]["q"]) - arm.state().q).max() < 0.02

        teach = subprocess.Popen([sys.executable, "-m", "akarm", "teach", *bus, str(tmp_path / "p.csv"), "--seconds",
                                  "0.4", "--sample-rate", "50"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                 text=True)
        try:  # stdin stays open: the recording ends by --seconds, not by the end of input
            assert teach.wait(60) == 0
            wrote = re.search(r"wrote (\d+) samples over 0.40 s", teach.stdout.read())
            # 21 on the 50 Hz grid over 0.4 s; a real-time loop on a loaded machine may skip a grid point
            assert wrote and 16 <= int(wrote.group(1)) <= 21
        finally:
            teach.stdin.close()
            teach.stdout.close()

        out = cli("replay", *bus, str(tmp_path / "k.yaml"))
        assert out.returncode == 0, out.stderr
        assert "RMS tracking error" in out.stdout

        out = cli("status", *bus)
        assert out.returncode == 0 and "shoulder" in out.stdout and "holding" in out.stdout

        out = cli("disable", *bus)
        assert out.returncode == 0 and "disabled planar2 through akarm serve" in out.stdout
        assert not arm.enabled and server.mode == "disabled"
        out = cli("status", *bus)
        assert out.returncode == 0 and "disabled" in out.stdout
        out = cli("enable", *bus, "--seconds", "0.3")  # watched that long, then left held by the server
        assert out.returncode == 0 and out.stdout.strip().endswith("(akarm disable releases it)"), out.stdout
        assert arm.enabled and server.mode == "holding"
        assert cli("disable", *bus).returncode == 0 and not arm.enabled
        assert cli("enable", *bus).returncode == 0
        assert arm.enabled
    assert not arm.enabled, "stopping the server damped and disabled the arm"
    arm.enable()  # the script still owns an open arm
    assert arm.enabled


def test_a_teach_client_killed_in_teach_mode_leaves_the_server_holding_not_limp(local_arm, tmp_path):
    """`akarm teach` killed with SIGKILL (or its terminal gone) cannot end teach mode itself: the
    server sees its connection end and ends teach mode, holding where the hand left the arm, so
    moves and trajectories are accepted again."""
    arm, bus = local_arm
    with akarm.ArmServer(arm, ros=False) as server:
        teach = subprocess.Popen([sys.executable, "-m", "akarm", "teach", *bus, str(tmp_path / "k.yaml")],
                                 stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 60
            while server.mode != "teach" and time.monotonic() < deadline and teach.poll() is None:
                time.sleep(0.02)
            assert server.mode == "teach"
            teach.kill()
            teach.wait(10)
        finally:
            teach.stdin.close()  # type: ignore[union-attr]
        deadline = time.monotonic() + 10
        while server.mode == "teach" and time.monotonic() < deadline:
            time.sleep(0.02)
        assert server.mode == "holding" and arm.enabled
        out = cli("move", *bus, "up", "--speed", "0.5")  # commandable again
        assert out.returncode == 0, out.stderr
        assert np.abs(arm.state().q - [1.2, -1.2]).max() < 5e-3


def test_akarm_serve_in_a_script_returns_on_sigterm_and_leaves_the_arm_disabled(local_arm):
    arm, bus = local_arm
    done: list[subprocess.CompletedProcess[str]] = []

    def drive() -> None:
        done.append(cli("move", *bus, "home"))
        os.kill(os.getpid(), signal.SIGTERM)  # what `kill PID` does to the script

    before = signal.getsignal(signal.SIGTERM)  # the open Arm's own (it raises Terminated)
    threading.Timer(0.5, drive).start()
    akarm.serve(arm, ros=False)  # blocks: enables, holds, serves; returns on SIGTERM
    assert done and done[0].returncode == 0 and "arrived" in done[0].stdout
    assert not arm.enabled
    assert signal.getsignal(signal.SIGTERM) is before, "serve put the previous handler back"


def test_without_a_server_the_verbs_open_the_bus_themselves(channel):
    with SimulatorProcess(PLANAR2, channel=channel, pose="down"):
        out = cli("move", str(PLANAR2), "-i", "akarm_local", "-c", channel, "down")
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip().endswith("disabled") and "akarm serve" not in out.stdout


def test_ctrl_c_on_a_served_move_stops_the_arm_and_leaves_it_held(local_arm):
    arm, bus = local_arm
    with akarm.ArmServer(arm, ros=False):
        move = subprocess.Popen([sys.executable, "-m", "akarm", "move", *bus, "up", "--speed", "0.1"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert move.stdout.readline().startswith("moving to up")
            time.sleep(0.5)
            assert arm.moving
            move.send_signal(signal.SIGINT)
            out, err = move.communicate(timeout=60)
        finally:
            if move.poll() is None:
                move.kill()
        assert move.returncode == 130 and "interrupted: stopped" in err
        assert arm.enabled and not arm.moving, "came to rest, held by the server"
        q = arm.state().q
        assert np.abs(q - [1.2, -1.2]).max() > 0.1, "stopped on the way, not at the target"
