"""Servoing through the control socket (``servo_twist``, ``servo_stop``): a served arm6 on an
in-process simulator in real time, steered up by twists sent at 50 Hz."""

from __future__ import annotations

import time

import numpy as np

import akarm
from akarm.dynamics.model import RobotModel
from akarm.server.server import ArmServerCore
from akarm.server.socket import SocketClient
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, relaxed_robot, wait_until


def test_twists_over_the_socket_steer_the_tool_and_servo_stop_holds_it(channel, tmp_path) -> None:
    config = akarm.load_robot(relaxed_robot(ROBOTS / "arm6.yaml", tmp_path)).with_bus(interface="virtual",
                                                                                      channel=channel)
    fk = RobotModel(config)
    with SimulatedRobot(config, q0=config.pose("ready")) as sim, akarm.Arm(config, stall_limit=1.0) as arm, \
            ArmServerCore(arm) as server:
        assert wait_until(lambda: arm.observe.loop.stats.cycles > 50, 10)
        z0 = fk.tool_pose(sim.q)[2, 3]
        with SocketClient(server.socket_path, timeout=10) as c:
            end = time.monotonic() + 1.0
            docs = []
            while time.monotonic() < end:
                docs.append(c.call("servo_twist", twist=[0.0, 0.0, 0.04, 0.0, 0.0, 0.0], timeout=0.2))
                time.sleep(0.02)
            assert docs[-1]["state"] == "ok"
            c.call("servo_stop")
            time.sleep(0.5)
            rise = fk.tool_pose(sim.q)[2, 3] - z0
            # 40 mm/s for 1 s; less on a loaded machine (the loop skips slots: plan time trails the clock)
            assert 0.01 < rise < 0.06, f"rose {rise * 1e3:.1f} mm"
            assert not arm.moving and arm.enabled
            assert np.max(np.abs(sim.dq)) < 0.05
            c.call("move", target="ready")  # an ordinary move afterwards
