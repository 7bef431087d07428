"""ROS 2 servoing: geometry_msgs/TwistStamped on ``NS/servo/twist`` (as MoveIt Servo takes it) steers a
served arm6 (an in-process simulator in real time) through Cyclone DDS."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

import akarm
from akarm.dynamics.model import RobotModel
from akarm.ros import dds, msgs
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, relaxed_robot, wait_until

DOMAIN = 100 + os.getpid() % 40


def test_twist_stamped_messages_steer_the_tool_up(tmp_path) -> None:
    robot = relaxed_robot(ROBOTS / "arm6.yaml", tmp_path)
    ns = f"rosservo{os.getpid()}"
    config = akarm.load_robot(robot).with_bus(interface="virtual", channel=ns)
    fk = RobotModel(config)
    log: list[str] = []
    with SimulatedRobot(config, q0=config.pose("ready")) as sim, akarm.Arm(config, stall_limit=1.0) as arm, \
            akarm.ArmServer(arm, domain=DOMAIN, namespace=ns, log=log.append):
        node = dds.Node(DOMAIN, ns)
        try:
            pub = node.publisher("servo/twist", msgs.TwistStamped)
            assert wait_until(lambda: bool(pub.get_matched_subscriptions()), 20)
            z0 = fk.tool_pose(sim.q)[2, 3]
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                pub.write(msgs.TwistStamped(msgs.Header(frame_id="base_link"),
                                            msgs.Twist(msgs.Vector3(0.0, 0.0, 0.04), msgs.Vector3())))
                time.sleep(0.02)
            time.sleep(0.6)  # the timeout, then at rest
            rise = fk.tool_pose(sim.q)[2, 3] - z0
            assert 0.01 < rise < 0.065, f"rose {rise * 1e3:.1f} mm; {log[-5:]}"  # less on a loaded machine
            assert arm.enabled and np.max(np.abs(sim.dq)) < 0.05
        finally:
            node.close()
