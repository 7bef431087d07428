"""MoveIt's way to the gripper: the GripperCommand action of `akarm serve`, driven from another process.

Three processes, as for the FollowJointTrajectory action (tests/system/test_ros_action.py): the
simulator (``akarm sim`` with its control channel, which puts an object between the jaws, takes it
away and says the true squeeze), ``akarm serve`` of arm6g (arm6 with a parallel gripper), and this
one, the ROS 2 client (:mod:`tests.system.action_client`: rosbags' codecs from control_msgs'
definitions, every payload checked byte for byte, rcl's readiness rule before sending). Each goal
is checked on the simulator's own state.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags.typesys")

import akarm
from akarm.buses.ownership import find_server
from akarm.server.socket import SocketClient
from akarm.sim.channel import SimulatorControl
from akarm.sim.process import SimulatorProcess

from ..rosdefs import GC
from .action_client import ActionClient
from .conftest import ROBOTS, relaxed_robot
from .test_serve import DOMAIN, Served, Watch, unique

pytestmark = pytest.mark.slow

ARM6G = ROBOTS / "arm6g.yaml"
ACTION = "gripper_controller/gripper_cmd"
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6


@dataclass
class Rig:
    ns: str
    ctl: SimulatorControl
    server: Served
    client: ActionClient
    config: akarm.RobotConfig

    def goal(self, width: float, max_effort: float = 0.0, timeout: float = 30.0) -> tuple[bytes, Any]:
        """Send a goal and wait for its result: (goal id, the GetResult response)."""
        gid = uuid.uuid4().bytes
        _, _, reply = self.client.send(gid, self.client.gripper_goal(width, max_effort))
        assert reply.accepted  # every goal is accepted (ros2_controllers' gripper controllers)
        return gid, self.client.result(gid, timeout)[1]

    def sim(self) -> tuple[float, float]:
        """The simulator's true squeeze (N) and width between the jaws (m)."""
        width, force = self.ctl.gripper()
        return force, width

    def status(self) -> dict[str, Any]:
        info = find_server(self.config)
        assert info is not None, "akarm serve is not running"
        with SocketClient(str(info["socket"]), timeout=30) as c:
            return c.call("status")


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    robot = relaxed_robot(ARM6G, tmp_path_factory.mktemp("gripper-action"))
    channel, ns = unique("gripcmd"), unique("grip")
    with SimulatorProcess(robot, channel=channel, control=True) as sim, Served(channel, ns, robot) as server:
        assert sim.control is not None
        client = ActionClient(DOMAIN, ns, ACTION, "jazzy", action=GC)
        try:
            client.wait_ready()
            yield Rig(ns, sim.control, server, client,
                      akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel))
        finally:
            client.close()


def test_the_action_is_ready_by_rcls_rule_with_gripper_commands_types(rig: Rig) -> None:
    c = rig.client
    assert c.server_ready()
    fb = c.feedback.get_matched_publication_data(c.feedback.get_matched_publications()[0])
    assert fb.type_name == "control_msgs::action::dds_::GripperCommand_FeedbackMessage_"
    assert fb.topic_name == f"rt/{rig.ns}/{ACTION}/_action/feedback"


def test_open_reaches_the_stroke_with_feedback(rig: Rig) -> None:
    rig.ctl.remove_object()
    gid, res = rig.goal(0.08)
    assert res.status == SUCCEEDED and res.result.reached_goal and not res.result.stalled, \
        "".join(rig.server.lines[-8:])
    assert abs(res.result.position - 0.08) < 0.002
    assert abs(rig.sim()[1] - 0.08) < 0.001  # the simulator's jaws: within 1 mm
    fb = rig.client.feedback_of(gid)
    assert fb and all(0.0 <= m.feedback.position <= 0.0815 for _, m in fb)
    assert rig.client.last_status(gid) == SUCCEEDED


def test_a_close_on_an_object_holds_it_and_succeeds_stalled(rig: Rig) -> None:
    rig.goal(0.08)
    rig.ctl.place_object(0.03)
    gid, res = rig.goal(0.0, max_effort=20.0)
    # parallel_gripper_controller with allow_stalling: stopped on the object, a success, stalled
    assert res.status == SUCCEEDED and res.result.stalled and not res.result.reached_goal
    assert abs(res.result.position - 0.03) < 0.002 and 16.0 <= res.result.effort <= 24.0
    time.sleep(1.0)  # held: the truth, a second later
    force, width = rig.sim()
    assert 16.0 <= force <= 24.0 and abs(width - 0.03) < 0.002
    # over the limit: refused by the gripper (ArgumentError), aborted, nothing squeezes harder
    _, res = rig.goal(0.0, max_effort=60.0)
    assert res.status == ABORTED and not res.result.stalled and not res.result.reached_goal
    assert rig.sim()[0] <= 24.0
    assert "force_limit" in rig.status()["last_refusal"]


def test_an_empty_close_ends_closed_and_reached(rig: Rig) -> None:
    rig.goal(0.08)
    rig.ctl.remove_object()
    _, res = rig.goal(0.0)
    assert res.status == SUCCEEDED and res.result.reached_goal and not res.result.stalled
    assert res.result.position < 0.002 and rig.sim()[1] < 0.002


def test_a_width_past_the_stroke_is_aborted_with_the_reason_and_nothing_moves(rig: Rig) -> None:
    rig.ctl.remove_object()
    rig.goal(0.05)
    before = rig.sim()[1]
    gid, res = rig.goal(0.1)
    assert res.status == ABORTED and not res.result.reached_goal and not res.result.stalled
    assert abs(res.result.position - before) < 0.001  # where it was
    time.sleep(0.3)
    assert abs(rig.sim()[1] - before) < 0.001, "nothing moved"
    text = rig.status()["last_refusal"]
    assert "outside its stroke" in text and "0.1" in text
    assert any("aborted" in line and "outside its stroke" in line for line in rig.server.lines), rig.server.lines[-5:]


def test_joint_states_carry_the_width_and_the_fingers(rig: Rig) -> None:
    rig.ctl.remove_object()
    rig.goal(0.06)
    watch = Watch(rig.ns)
    try:
        watch.wait_states(5)
        msg = watch.states[-1][1]
        names = list(msg.name)
        assert names[:6] == list(rig.config.joint_names)
        assert names[6:] == ["gripper", "left_finger_joint", "right_finger_joint"]
        width = msg.position[6]
        assert abs(width - 0.06) < 0.002 and abs(width - rig.sim()[1]) < 0.002
        assert msg.position[7] == pytest.approx(width / 2) and msg.position[8] == pytest.approx(width / 2)
    finally:
        watch.close()


def test_a_cancel_holds_the_jaws_where_they_are(rig: Rig) -> None:
    rig.ctl.remove_object()
    rig.goal(0.08)
    gid = uuid.uuid4().bytes
    _, _, reply = rig.client.send(gid, rig.client.gripper_goal(0.0))
    assert reply.accepted
    time.sleep(0.15)  # on its way (0.1 m/s)
    rig.client.cancel(gid)
    _, res = rig.client.result(gid)
    assert res.status == CANCELED, "".join(rig.server.lines[-5:])
    time.sleep(0.5)
    held = rig.sim()[1]
    assert 0.01 < held < 0.075  # stopped part way
    time.sleep(0.5)
    assert abs(rig.sim()[1] - held) < 0.001
