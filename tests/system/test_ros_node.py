"""The ROS 2 node against what a participant may send it: the simulator (a virtual bus), ``ArmServer``
with its node, and a DDS participant, all in this process (the server's log and counts read directly).

- A trajectory or a goal too big for akarm is refused from its bytes, before it is decoded:
  joint_states go on, the arm stays held, the refusal is counted.
- A sample that does not decode (a name that is not UTF-8) is refused alone: the samples taken with it
  are followed, a goal gets its answer, and a stream of them does not slow joint_states down.
- What a participant names is logged escaped: it cannot forge the server's log lines.
- A goal refused because the arm is disabled is counted in the server's refusals, as a message is.
- A goal or a message that arrives during an enable or a disable (the server's command lock held
  throughout) waits for it, in order, and joint_states go on meanwhile.
"""

from __future__ import annotations

import itertools
import os
import struct
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

pytest.importorskip("cyclonedds")

from cyclonedds._clayer import ddspy_write

import akarm
from akarm.ros import action_types as at
from akarm.ros import dds, msgs
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, relaxed_robot, wait_until

pytestmark = pytest.mark.slow

DOMAIN = 150 + os.getpid() % 80
_count = itertools.count()
ACTION = "arm_controller/follow_joint_trajectory/_action/"


def point(q: list[float], t: float) -> msgs.JointTrajectoryPoint:
    ns = round(t * 1e9)
    return msgs.JointTrajectoryPoint(q, [], [], [], msgs.Duration(ns // 1_000_000_000, ns % 1_000_000_000))


def trajectory(names: list[str], points: list[msgs.JointTrajectoryPoint]) -> msgs.JointTrajectory:
    return msgs.JointTrajectory(msgs.Header(), names, points)


def many_points(n: int) -> bytes:
    """A JointTrajectory for ``elbow`` of ``n`` empty points (24 bytes each): 1 s to decode per 100 000."""
    head = trajectory(["elbow"], []).serialize()
    return head[:-4] + struct.pack("<I", n) + struct.pack("<IIIIiI", 0, 0, 0, 0, 0, 0) * n


class Client:
    """A ROS 2 participant: records when joint_states arrive, publishes trajectories, calls the action's services."""

    def __init__(self, namespace: str) -> None:
        self.node = dds.Node(DOMAIN, namespace)
        self.js = self.node.subscription("joint_states", msgs.JointState, depth=1000)
        self.trajectory = self.node.publisher("joint_trajectory", msgs.JointTrajectory)
        self.services = {}
        for name, rq, rp in (("send_goal", at.SendGoalRequest, at.SendGoalResponse),
                             ("get_result", at.GetResultRequest, at.GetResultResponse)):
            q = dds.qos(user_data=self.node.unique_id("clientid"))
            rqt, rrt = dds.service_topics(namespace, ACTION + name)
            w, r = self.node.writer(rqt, rq, q), self.node.reader(rrt, rp, q)
            self.services[name] = (w, r, w.get_instance_handle() & 0xFFFF_FFFF_FFFF_FFFF)
        self.js_times: list[float] = []
        self.replies: dict[tuple[str, int], object] = {}
        self.seq = 1000
        self._running = True
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()
        assert wait_until(lambda: bool(self.trajectory.get_matched_subscriptions()) and all(
            w.get_matched_subscriptions() and r.get_matched_publications() for w, r, _ in self.services.values()), 20)

    def _poll(self) -> None:
        while self._running:
            for m in self.js.take(100):
                if dds.sample_info(m).valid_data:
                    self.js_times.append(time.monotonic())
            for name, (_, r, guid) in self.services.items():
                for rep in r.take(16):
                    if dds.sample_info(rep).valid_data and rep.guid == guid:
                        self.replies[(name, rep.seq)] = rep
            time.sleep(0.002)

    def write_raw(self, writer: object, data: bytes) -> None:
        assert ddspy_write(writer._ref, data + b"\0" * (-len(data) % 4)) >= 0  # type: ignore[attr-defined]

    def request(self, name: str, req: object) -> bytes:
        """``req`` (of the service ``name``) serialized with this client's request header."""
        self.seq += 1
        req.guid, req.seq = self.services[name][2], self.seq  # type: ignore[attr-defined]
        return req.serialize()  # type: ignore[attr-defined,no-any-return]

    def reply(self, name: str, seq: int, timeout: float = 10.0) -> object:
        assert wait_until(lambda: (name, seq) in self.replies, timeout), f"no {name} reply"
        return self.replies.pop((name, seq))

    def result(self, goal_id: bytes, timeout: float = 10.0) -> at.GetResultResponse:
        data = self.request("get_result", at.GetResultRequest(0, 0, at.UUID(list(goal_id))))
        self.write_raw(self.services["get_result"][0], data)
        return self.reply("get_result", self.seq, timeout)  # type: ignore[return-value]

    def max_gap(self, since: float, until: float) -> float:
        ts = [since] + [t for t in self.js_times if since <= t <= until] + [until]
        return max(b - a for a, b in itertools.pairwise(ts))

    def close(self) -> None:
        self._running = False
        self._thread.join(2.0)
        self.node.close()


@dataclass
class Rig:
    sim: SimulatedRobot
    arm: akarm.Arm
    server: akarm.ArmServer
    client: Client
    log: list[str]


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    robot = relaxed_robot(ROBOTS / "arm6.yaml", tmp_path_factory.mktemp("ros-node"))
    n = next(_count)
    config = akarm.load_robot(robot).with_bus(interface="virtual", channel=f"rosnode{os.getpid()}_{n}")
    log: list[str] = []
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm, \
            akarm.ArmServer(arm, domain=DOMAIN, namespace=f"rosnode{os.getpid()}_{n}", log=log.append) as server:
        client = Client(f"rosnode{os.getpid()}_{n}")
        try:
            yield Rig(sim, arm, server, client, log)
        finally:
            client.close()


@pytest.fixture(autouse=True)
def held(rig: Rig) -> None:
    if rig.server.latched is not None or not rig.arm.enabled:
        rig.server.enable()
    assert wait_until(lambda: len(rig.client.js_times) > 5, 20)


def test_a_huge_trajectory_is_refused_from_its_size_before_it_is_decoded(rig: Rig) -> None:
    refused = rig.server.counts["refused"]
    data = many_points(100_000)  # 2.4 MB, within the byte bound: 1 s to decode, and 400 000 objects
    t0 = time.monotonic()
    rig.client.write_raw(rig.client.trajectory, data)
    assert wait_until(lambda: rig.server.counts["refused"] > refused, 10)
    t1 = time.monotonic()
    time.sleep(0.3)
    assert t1 - t0 < 1.0, f"{t1 - t0:.2f} s to refuse it"
    assert "100000 points, more than the 10000" in rig.server.last_refusal
    assert rig.client.max_gap(t0, t1) < 0.3, "joint_states stopped meanwhile"
    assert rig.arm.enabled and rig.server.latched is None


def test_a_huge_goal_is_aborted_from_its_size_before_it_is_decoded(rig: Rig) -> None:
    c = rig.client
    refused = rig.server.counts["refused"]
    gid = uuid.uuid4().bytes
    head = c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(gid)),
                                                     at.FollowJointTrajectoryGoal(trajectory(["elbow"], []))))
    seq = c.seq
    traj = many_points(300_000)[4:]  # 7 MB: 3 s to decode; then the goal's other fields, all empty
    data = head[:36] + traj + head[36 + len(trajectory(["elbow"], []).serialize()) - 4:]
    t0 = time.monotonic()
    c.write_raw(c.services["send_goal"][0], data)
    assert c.reply("send_goal", seq).accepted  # type: ignore[attr-defined]
    res = c.result(gid)
    t1 = time.monotonic()
    assert t1 - t0 < 2.0, f"{t1 - t0:.2f} s to refuse it"
    assert res.status == 6 and res.result.error_code == -1, res  # ABORTED, INVALID_GOAL
    assert "bytes, more than the 2465536 that a trajectory of 10000 points" in res.result.error_string
    assert rig.server.counts["refused"] == refused + 1
    assert c.max_gap(t0, t1) < 0.3, "joint_states stopped meanwhile"
    assert rig.arm.enabled and rig.server.latched is None


def test_a_message_of_more_bytes_than_any_trajectory_akarm_takes_is_refused(rig: Rig) -> None:
    refused = rig.server.counts["refused"]
    big = trajectory(["elbow"], [point([0.0], 1.0)])
    big.header.frame_id = "x" * 3_000_000
    rig.client.write_raw(rig.client.trajectory, big.serialize())
    assert wait_until(lambda: rig.server.counts["refused"] > refused, 10)
    assert "bytes, more than the" in rig.server.last_refusal


def not_utf8(data: bytes) -> bytes:
    return data.replace(b"elbow", b"\xff\xfe\xfd\xfc\xfb")


def test_a_message_that_does_not_decode_is_refused_alone_and_the_others_are_followed(rig: Rig) -> None:
    c, counts = rig.client, dict(rig.server.counts)
    for k in range(5):  # each valid one taken in a batch with a bad one, mostly (keep last 10: no more at once)
        c.write_raw(c.trajectory, not_utf8(trajectory(["elbow"], [point([0.1], 1.0)]).serialize()))
        c.trajectory.write(trajectory(["elbow"], [point([0.01 * k], 1.0)]))
        time.sleep(0.05)
    assert wait_until(lambda: rig.server.counts["accepted"] >= counts["accepted"] + 5, 10), rig.server.counts
    assert rig.server.counts["refused"] == counts["refused"] + 5
    assert "JointTrajectory of 72 bytes that does not decode (UnicodeDecodeError" in rig.server.last_refusal
    assert any("joint_trajectory from participant" in line and "does not decode" in line for line in rig.log)


def test_a_stream_of_samples_that_do_not_decode_leaves_joint_states_at_their_rate(rig: Rig) -> None:
    c, refused = rig.client, rig.server.counts["refused"]
    bad = not_utf8(trajectory(["elbow"], [point([0.1], 1.0)]).serialize())
    t0 = time.monotonic()
    for _ in range(50):
        c.write_raw(c.trajectory, bad)
        time.sleep(0.02)
    t1 = time.monotonic()
    time.sleep(0.2)
    rate = len([t for t in c.js_times if t0 <= t <= t1]) / (t1 - t0)
    assert rate > 80, f"joint_states at {rate:.0f} Hz (100 without the stream)"
    assert wait_until(lambda: rig.server.counts["refused"] == refused + 50, 5), rig.server.counts


def test_a_goal_that_does_not_decode_is_aborted_and_the_next_one_taken(rig: Rig) -> None:
    c = rig.client
    send = c.services["send_goal"][0]
    bad_id, good_id = uuid.uuid4().bytes, uuid.uuid4().bytes
    goal = at.FollowJointTrajectoryGoal(trajectory(["elbow"], [point([0.05], 0.5)]))
    c.write_raw(send, not_utf8(c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(bad_id)), goal))))
    bad_seq = c.seq
    c.write_raw(send, c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(good_id)), goal)))
    assert c.reply("send_goal", bad_seq).accepted  # type: ignore[attr-defined]
    assert c.reply("send_goal", c.seq).accepted  # type: ignore[attr-defined]
    res = c.result(bad_id)
    assert res.status == 6 and res.result.error_code == -1, res  # ABORTED, INVALID_GOAL
    assert "does not decode (UnicodeDecodeError" in res.result.error_string
    res = c.result(good_id)
    assert res.status == 4, res  # SUCCEEDED


def test_a_joint_name_with_a_line_break_or_an_escape_is_logged_escaped(rig: Rig) -> None:
    time.sleep(1.1)  # the node's command log says five a second in full: a second of its own
    start = len(rig.log)
    forged = "x\nakarm serve: safety stop acknowledged by operator; all clear\x1b[2K"
    rig.client.trajectory.write(trajectory([forged], [point([0.1], 1.0)]))
    assert wait_until(lambda: any("joint_trajectory from" in line for line in rig.log[start:]), 10), rig.log[start:]
    lines = rig.log[start:]
    assert any(repr(forged) in line for line in lines), lines
    assert not any("\n" in line or "\x1b" in line for line in lines), lines


def test_a_goal_refused_because_the_arm_is_disabled_is_counted_as_a_refusal(rig: Rig) -> None:
    c = rig.client
    rig.server.disable()
    refused = rig.server.counts["refused"]
    gid = uuid.uuid4().bytes
    goal = at.FollowJointTrajectoryGoal(trajectory(["elbow"], [point([0.05], 0.5)]))
    c.write_raw(c.services["send_goal"][0], c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(gid)), goal)))
    res = c.result(gid)
    assert res.status == 6 and res.result.error_code == -1, res  # ABORTED, INVALID_GOAL
    assert "the arm is disabled" in res.result.error_string
    assert rig.server.counts["refused"] == refused + 1
    assert rig.server.last_refusal.startswith("the arm is disabled")
    assert rig.server.status()["trajectories_refused"] == refused + 1


def busy(server: akarm.ArmServer) -> bool:
    with server.try_command() as free:
        return not free


@pytest.mark.parametrize("service", ["akarm/disable", "akarm/enable"])
def test_a_goal_and_a_message_during_an_enable_or_disable_wait_for_it_and_joint_states_go_on(
        rig: Rig, service: str) -> None:
    c = rig.client
    if service == "akarm/enable":
        rig.server.disable()
    trigger = dds.TriggerClient(c.node, service)
    replies: list[msgs.TriggerResponse] = []
    t0 = time.monotonic()
    called = threading.Thread(target=lambda: replies.append(trigger.call(timeout=20)))
    called.start()
    assert wait_until(lambda: busy(rig.server), 10), "the service did not start"  # it holds the command lock
    counts = dict(rig.server.counts)
    c.trajectory.write(trajectory(["wrist_roll"], [point([0.05], 0.5)]))
    time.sleep(0.01)
    gid = uuid.uuid4().bytes
    goal = at.FollowJointTrajectoryGoal(trajectory(["elbow"], [point([0.05], 0.5)]))
    c.write_raw(c.services["send_goal"][0], c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(gid)), goal)))
    seq = c.seq
    called.join(30)
    t1 = time.monotonic()
    assert replies and replies[0].success, replies
    assert c.reply("send_goal", seq).accepted  # type: ignore[attr-defined]
    res = c.result(gid)
    gap = c.max_gap(t0, t1)
    print(f"{service}: {t1 - t0:.3f} s; joint_states' longest gap in it {gap:.3f} s")
    assert gap < 0.1, f"joint_states stopped for {gap:.3f} s of the {t1 - t0:.3f} s {service} took"
    if service == "akarm/disable":  # after the disable, in order: refused, and nothing moved
        assert res.status == 6 and "the arm is disabled" in res.result.error_string, res
        assert rig.server.counts["refused"] == counts["refused"] + 2 and not rig.arm.enabled, "\n".join(rig.log[-6:])
    else:  # after the enable, in order: the message, then the goal that replaced it
        assert res.status == 4, res
        assert rig.server.counts["accepted"] == counts["accepted"] + 2 and rig.arm.enabled


def test_a_goal_canceled_while_it_waits_for_an_enable_never_starts(rig: Rig) -> None:
    c = rig.client
    rig.server.disable()
    cancel_q = dds.qos(user_data=c.node.unique_id("clientid"))
    rq, rr = dds.service_topics(c.node.namespace, ACTION + "cancel_goal")
    cancel_w = c.node.writer(rq, at.CancelGoalRequest, cancel_q)
    assert wait_until(lambda: bool(cancel_w.get_matched_subscriptions()), 10)
    trigger = dds.TriggerClient(c.node, "akarm/enable")
    accepted = rig.server.counts["accepted"]
    called = threading.Thread(target=trigger.call, kwargs={"timeout": 20})
    called.start()
    assert wait_until(lambda: busy(rig.server), 10), "the enable did not start"
    gid = uuid.uuid4().bytes
    goal = at.FollowJointTrajectoryGoal(trajectory(["elbow"], [point([0.3], 0.5)]))
    c.write_raw(c.services["send_goal"][0], c.request("send_goal", at.SendGoalRequest(0, 0, at.UUID(list(gid)), goal)))
    assert c.reply("send_goal", c.seq).accepted  # type: ignore[attr-defined]
    cancel_w.write(at.CancelGoalRequest(1, 1, at.GoalInfo(at.UUID(list(gid)), msgs.Time())))
    called.join(30)
    res = c.result(gid)
    assert res.status == 5, res  # CANCELED
    time.sleep(0.3)
    assert rig.server.counts["accepted"] == accepted and rig.arm.enabled
