"""The server's ``stream`` operation over the control socket, as a LeRobot policy uses it (the rules
themselves, in lock step: tests/sim/test_stream.py): the simulator in its own process on
``akarm_local``, the server here (ROS off), a client on its socket.

- a target past the range is clamped, and the answer says so; ``null`` (a NaN) is refused with the
  joint named, and the arm comes to rest; a client that goes silent leaves the arm at rest within the
  timeout plus the braking time; another command (``move``) ends the stream;
- a latched safety stop refuses the next target with StopLatched, naming the stop.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

import akarm
from akarm.server.socket import SocketClient
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot

pytestmark = pytest.mark.slow
PLANAR2 = ROBOTS / "planar2.yaml"


def stream_for(client: SocketClient, seconds: float, target: object, **args: object) -> dict:
    end = time.monotonic() + seconds
    answer: dict = {}
    while time.monotonic() < end:
        answer = client.call("stream", target=target, **args)
        time.sleep(1 / 30)
    return answer


def test_a_stream_over_the_socket_clamps_refuses_holds_and_ends(channel, tmp_path):
    robot = relaxed_robot(PLANAR2, tmp_path)
    with SimulatorProcess(robot, channel=channel, pose="down", control=True) as sim:
        config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
        with akarm.Arm(config) as arm, akarm.ArmServer(arm, ros=False) as server, \
                SocketClient(server.socket_path, timeout=30) as client:
            answer = stream_for(client, 2.0, {"shoulder": 2.8, "elbow": 0.3})
            assert answer["clamped"] == ["shoulder"] and answer["clamped_total"] >= 30
            assert answer["target"] == [1.8, 0.3]
            assert abs(arm.state().q[0] - 1.8) < 0.02

            stream_for(client, 0.2, [0.0, 0.0])
            with pytest.raises(akarm.ArgumentError, match="not a number") as e:
                client.call("stream", target={"shoulder": None, "elbow": 0.0})
            assert e.value.joint == "shoulder"
            time.sleep(1.0)
            assert not arm.moving
            held = arm.state().q_des[0]
            assert 0.3 < held < 1.7  # at rest short of the target it was heading for

            stream_for(client, 0.1, [-1.5, 0.0])
            time.sleep(1.0)  # silent: at rest within the timeout (0.25 s) and the braking time
            assert not arm.moving and arm.state().q_des[0] > -1.3

            stream_for(client, 0.3, [0.0, 0.0])
            client.call("move", target="down", speed=0.5)  # another command ends the stream
            time.sleep(0.5)
            assert arm.moving  # the move runs: no stream watchdog stops it

            sim.control.inject("elbow", "unplugged")
            deadline = time.monotonic() + 5
            while server.latched is None and time.monotonic() < deadline:
                time.sleep(0.05)
            with pytest.raises(akarm.StopLatched, match="FeedbackTimeout"):
                client.call("stream", target=[0.0, 0.0])
            assert not arm.enabled
            assert np.isfinite(arm.state().q).all()
