"""The gripper served (akarm serve's control socket: gripper_state, gripper_move) and the CLI's
`akarm grip` and `akarm status` through it, against a simulator process with an object between the
jaws."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import akarm
from akarm.robotfile.load import load_robot
from akarm.server.socket import SocketClient
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot
from .test_serve import unique


def akarm_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "akarm", *args], capture_output=True, text=True, timeout=120)


def test_the_gripper_served_to_the_control_socket_and_the_cli(tmp_path: Path) -> None:
    robot = relaxed_robot(ROBOTS / "arm6g.yaml", tmp_path)
    channel = unique("grip")
    with SimulatorProcess(robot, channel=channel, args=["--object", "0.03"]), \
            akarm.Arm(load_robot(robot).with_bus(interface="akarm_local", channel=channel)) as arm, \
            akarm.ArmServer(arm, ros=False, log=lambda text: None) as server:
        socket = server.socket_path
        assert socket is not None
        with SocketClient(socket, timeout=60) as c:
            s = c.call("gripper_move", width=0.0, force=20.0)
            assert s["grasped"] and abs(s["width"] - 0.03) < 0.002 and 16.0 < s["force"] < 24.0
            with pytest.raises(akarm.ArgumentError):
                c.call("gripper_move", width=0.1)
            assert c.call("gripper_state")["grasped"]
            g = c.call("state", read=False)["gripper"]  # the arm's state carries the gripper's reading too
            assert abs(g["width"] - 0.03) < 0.002 and g["grasped"] and 16.0 < g["force"] < 24.0
        status = akarm_cli("status", str(robot), "-i", "akarm_local", "-c", channel)
        assert status.returncode == 0, status.stderr
        assert "gripper 'gripper': width 29." in status.stdout, status.stdout
        grip = akarm_cli("grip", str(robot), "open", "-i", "akarm_local", "-c", channel)
        assert grip.returncode == 0, grip.stderr
        assert "at its target" in grip.stdout and "held by akarm serve" in grip.stdout, grip.stdout
        assert abs(arm.gripper.state().width - 0.08) < 0.001  # type: ignore[union-attr]


def test_akarm_grip_without_a_server(tmp_path: Path) -> None:
    robot = relaxed_robot(ROBOTS / "arm6g.yaml", tmp_path)
    channel = unique("grip-local")
    with SimulatorProcess(robot, channel=channel, args=["--object", "0.03"], control=True) as sim:
        bad = akarm_cli("grip", str(robot), "0.09", "-i", "akarm_local", "-c", channel)
        assert bad.returncode == 1 and "outside its stroke 0..0.08 m" in bad.stderr, bad.stderr
        assert not any(s.enabled for s in sim.control.state())  # type: ignore[union-attr]  # nothing was enabled
        grip = akarm_cli("grip", str(robot), "close", "--force", "20", "-i", "akarm_local", "-c", channel)
        assert grip.returncode == 0, grip.stderr
        assert "grasped, force" in grip.stdout and grip.stdout.rstrip().endswith("limp)"), grip.stdout
        width, force = sim.control.gripper()  # type: ignore[union-attr]
        assert force < 3.0 and width > 0.029  # limp: the object springs the jaws back, but for what friction holds
        assert sim.control.gripper_object() == (0.03, True)  # type: ignore[union-attr]  # (what a camera draws)
        sim.control.set_gripper_width(0.06)  # type: ignore[union-attr]  # a hand opens the limp jaws
        assert abs(sim.control.gripper()[0] - 0.06) < 0.001  # type: ignore[union-attr]
        sim.control.remove_object()  # type: ignore[union-attr]
        assert sim.control.gripper_object() == (None, False)  # type: ignore[union-attr]
