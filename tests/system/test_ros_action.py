"""MoveIt's way in: the FollowJointTrajectory action of `akarm serve`, driven from another process.

Three processes: the simulator (``akarm sim`` with its control channel, which records every frame
and pushes the arm), ``akarm serve``, and this one, the ROS 2 action client
(:mod:`tests.system.action_client`: rosbags' codecs from control_msgs' definitions, every payload
checked byte for byte, rcl's readiness rule before sending). The module runs twice: the server and
the client speaking humble's layouts, then rolling's (whose feedback has two more fields). Each case
is checked on the simulator's own state and on the command frames it received.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
import yaml

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags.typesys")

from cyclonedds._clayer import ddspy_take, ddspy_write
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.core import Qos
from cyclonedds.qos import Policy
from cyclonedds.util import duration

import akarm
from akarm.buses.ownership import find_server
from akarm.protocol import mit
from akarm.ros import dds, msgs
from akarm.ros.graph import DISCOVERY_TOPIC, participant_info_type
from akarm.server.socket import SocketClient
from akarm.sim import faults
from akarm.sim.channel import SimulatorControl
from akarm.sim.process import SimulatorProcess

from ..rosdefs import typestore
from .action_client import ActionClient, roundtrip
from .conftest import ROBOTS, relaxed_robot
from .test_serve import DOMAIN, Served, rosbags_trajectory, unique

pytestmark = pytest.mark.slow

ARM6 = ROBOTS / "arm6.yaml"
CONFIG = akarm.load_robot(ARM6)
NAMES = list(CONFIG.joint_names)
ACTION = "arm_controller/follow_joint_trajectory"
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6
INVALID_GOAL, INVALID_JOINTS, PATH_TOLERANCE_VIOLATED = -1, -2, -4


@dataclass
class Commands:
    """The command frames the simulated drivers received, per joint: simulated time and the decoded command."""

    t: dict[str, np.ndarray]
    q: dict[str, np.ndarray]
    v: dict[str, np.ndarray]
    kp: dict[str, np.ndarray]
    specials: list[tuple[float, str, str]]  # (t, joint, "enter" | "exit" | "zero")


def commands(ctl: SimulatorControl, since: int) -> Commands:
    frames, _ = ctl.frames(since)
    models = {j.name: j.motor for j in CONFIG.joints}
    rows: dict[str, list[tuple[float, Any]]] = {n: [] for n in NAMES}
    specials = []
    for f in frames:
        if not f.to_motor or f.joint not in models or len(f.data) != 8:
            continue
        kind = mit.special_frame(f.data)
        if kind is not None:
            specials.append((f.t, f.joint, kind))
        else:
            rows[f.joint].append((f.t, mit.decode_command(models[f.joint], f.data)))

    def arr(n: str, k: int) -> np.ndarray:
        return np.array([r[1][k] for r in rows[n]])

    return Commands({n: np.array([r[0] for r in rows[n]]) for n in NAMES}, {n: arr(n, 0) for n in NAMES},
                    {n: arr(n, 1) for n in NAMES}, {n: arr(n, 2) for n in NAMES}, specials)


@dataclass
class Rig:
    distro: str
    ns: str
    sim: SimulatorProcess
    ctl: SimulatorControl
    server: Served
    client: ActionClient
    config: akarm.RobotConfig  # the robot served, on its bus

    def latched(self) -> bool:
        """True while the server holds a safety stop no enable has acknowledged (asked over its socket)."""
        info = find_server(self.config)
        assert info is not None, "akarm serve is not running"
        with SocketClient(str(info["socket"]), timeout=30) as c:
            return c.call("status").get("stop") is not None

    def missed_slots(self) -> int:
        """The slots the server's loop missed so far (each one delays the plan's time by a period)."""
        info = find_server(self.config)
        assert info is not None, "akarm serve is not running"
        with SocketClient(str(info["socket"]), timeout=30) as c:
            return int(c.call("status").get("missed_slots", 0))

    def mark(self) -> int:
        """The index of the next frame the simulator logs (the frames a test looks at start there)."""
        return int(self.ctl.request(cmd="frames", since=1 << 62)["next"])

    def q(self) -> np.ndarray:
        return np.array([s.position for s in self.ctl.state()])

    def run(self, names: list[str], points: list[Any], **kw: Any) -> tuple[bytes, float, Any]:
        """Send a goal and wait for its result: (goal id, time.time() sent, the GetResult response)."""
        gid = uuid.uuid4().bytes
        sent, _, reply = self.client.send(gid, self.client.goal(names, points, **kw))
        assert reply.accepted
        return gid, sent, self.client.result(gid)[1]

    def settle(self, target: dict[str, float] | None = None) -> None:
        """Bring the arm (or the joints of ``target``) to rest where a goal puts it, successfully."""
        names = list(target) if target else NAMES
        values = list(target.values()) if target else [0.0] * 6
        _, _, res = self.run(names, [(1.5, values)])
        assert res.status == SUCCEEDED, res.result.error_string


@pytest.fixture(scope="module", params=["humble", "rolling"])
def rig(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    distro = request.param
    robot = relaxed_robot(ARM6, tmp_path_factory.mktemp(f"action-{distro}"))
    # in real time, the simulator in a process of its own on 2 shared cores lags its commands at times,
    # which the collision observer takes for a push: thresholds doubled, as akarm demo does in real time
    doc = yaml.safe_load(robot.read_text())
    for joint in doc["joints"]:
        if "collision" in joint:
            joint["collision"]["threshold"] *= 2.0
    robot.write_text(yaml.safe_dump(doc))
    channel, ns = unique(f"action{distro}"), unique("moveit")
    with SimulatorProcess(robot, channel=channel, control=True) as sim, \
            Served(channel, ns, robot, args=("--ros-distro", distro)) as server:
        assert sim.control is not None
        client = ActionClient(DOMAIN, ns, ACTION, distro)
        try:
            client.wait_ready()
            yield Rig(distro, ns, sim, sim.control, server, client,
                      akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel))
        finally:
            client.close()


@pytest.fixture(autouse=True)
def enabled(rig: Rig) -> None:
    """Each test starts with the arm held: a stop an earlier test left (or the loaded machine caused:
    see the report of a ForeignTraffic stop under load) is acknowledged first, the arm brought
    upright, and said."""
    if rig.latched() or not all(s.enabled for s in rig.ctl.state()):  # (a stop's damping: still enabled)
        print(f"the arm was stopped before this test; enabling it. Server:\n{''.join(rig.server.lines[-5:])}")
        assert dds.TriggerClient(rig.client.node, "akarm/enable").call(timeout=30).success
        rig.settle()  # limp, the arm may have sagged anywhere (past a joint's range, which goals refuse)


def assert_no_velocity_step(t: np.ndarray, v: np.ndarray, joint: str) -> None:
    """Jerk-limited: from one command to the next the commanded velocity changes by at most what the
    acceleration limit allows in a few loop periods (a stop or a start without a ramp would jump by
    the whole velocity)."""
    limit = 4.0 * CONFIG.joints[NAMES.index(joint)].limits.acceleration / CONFIG.rate_hz
    steps = np.abs(np.diff(v))
    assert steps.max() < limit, f"{joint}: the commanded velocity stepped by {steps.max():.3f} rad/s at " \
                                f"t = {t[1:][steps.argmax()]:.3f} s (limit {limit:.3f})"


def held_still(c: Commands, names: list[str] | None = None, tol: float = 1e-3) -> bool:
    """True when every command of the joints stayed within ``tol`` of the first (nothing moved)."""
    return all(len(c.q[n]) > 10 and np.ptp(c.q[n]) < tol for n in (names or NAMES))


# -----------------------------------------------------------------------------------------------
def test_the_server_is_ready_by_rcls_rule_with_the_qos_rcl_action_gives(rig: Rig) -> None:
    c = rig.client
    assert c.server_ready()
    pub = c.status.get_matched_publication_data(c.status.get_matched_publications()[0])
    assert pub.qos[Policy.Durability] == Policy.Durability.TransientLocal
    assert pub.qos[Policy.History] == Policy.History.KeepLast(1)
    assert isinstance(pub.qos[Policy.Reliability], Policy.Reliability.Reliable)
    assert pub.topic_name == f"rt/{rig.ns}/{ACTION}/_action/status"
    for s, name in ((c.send_goal, "send_goal"), (c.cancel_goal, "cancel_goal"), (c.get_result, "get_result")):
        for h in s.reader.get_matched_publications():  # the reply writer says which service it is
            d = s.reader.get_matched_publication_data(h)
            assert d.topic_name == f"rr/{rig.ns}/{ACTION}/_action/{name}Reply"
            assert bytes(d.qos[Policy.Userdata].data).startswith(b"serviceid=")
    fb = c.feedback.get_matched_publication_data(c.feedback.get_matched_publications()[0])
    assert fb.type_name == "control_msgs::action::dds_::FollowJointTrajectory_FeedbackMessage_"


def test_a_goal_moves_a_subset_of_the_joints_through_its_points_with_feedback(rig: Rig) -> None:
    c = rig.client
    start = rig.q()
    since = rig.mark()
    missed = rig.missed_slots()
    points = [(1.0, [0.5, 0.3]), (2.0, [0.8, -0.2])]  # elbow, shoulder_pan: a subset, in another order
    gid = uuid.uuid4().bytes
    _, _, reply = c.send(gid, c.goal(["elbow", "shoulder_pan"], points))
    assert reply.accepted
    _, res = c.result(gid)
    assert res.status == SUCCEEDED and res.result.error_code == 0, res.result.error_string
    q = rig.q()
    i_elbow, i_pan = NAMES.index("elbow"), NAMES.index("shoulder_pan")
    assert abs(q[i_elbow] - 0.8) < 3e-3 and abs(q[i_pan] + 0.2) < 3e-3
    others = [i for i in range(6) if i not in (i_elbow, i_pan)]
    assert np.abs(q[others] - start[others]).max() < 3e-3, "the joints the goal does not name keep their place"
    cmd = commands(rig.ctl, since)  # the commands pass through each point
    for _, (elbow, pan) in points:
        assert np.abs(cmd.q["elbow"] - elbow).min() < 0.01 and np.abs(cmd.q["shoulder_pan"] - pan).min() < 0.01
    # feedback at 20 Hz or more, each with every joint, the error its desired minus its actual; the
    # desired state passes each point at its time (from the goal's acceptance, the reply's stamp)
    fb = c.feedback_of(gid)
    t = np.array([f[0] for f in fb])
    assert len(fb) >= 2.0 * 20 and (len(t) - 1) / (t[-1] - t[0]) >= 20.0
    assert max(np.diff(t)) < 0.25, "no long gap in the feedback"
    stamps = np.array([m.feedback.header.stamp.sec + m.feedback.header.stamp.nanosec * 1e-9 for _, m in fb])
    accepted = reply.stamp.sec + reply.stamp.nanosec * 1e-9
    # (a slot the loop misses delays the plan by a period: the motors are not asked to jump; on a
    # loaded machine the points come that much later)
    late = max(0, rig.missed_slots() - missed) / rig.config.rate_hz
    desired = np.array([m.feedback.desired.positions for _, m in fb])
    for tk, (elbow, pan) in points:
        near = (stamps > accepted + tk - 0.05) & (stamps < accepted + tk + 0.05 + late)
        assert near.any(), (tk, late, stamps - accepted)
        off = np.abs(desired[near][:, i_elbow] - elbow) + np.abs(desired[near][:, i_pan] - pan)
        assert off.min() < 0.02, (tk, late, off.min())
    for _, m in fb:
        f = m.feedback
        assert list(f.joint_names) == NAMES
        assert np.allclose(f.error.positions, f.desired.positions - f.actual.positions, atol=1e-12)
    last = fb[-1][1].feedback
    assert abs(last.desired.positions[i_elbow] - 0.8) < 1e-6
    if rig.distro == "rolling":  # the point in use: 0 while heading for the first, 1 after it
        idx = [(st - accepted, m.feedback.index) for st, (_, m) in zip(stamps, fb, strict=True)]
        assert all(i == 0 for dt, i in idx if dt < 0.95) and all(i == 1 for dt, i in idx if dt > 1.05)
    else:
        assert not hasattr(last, "index")
    assert c.last_status(gid) == SUCCEEDED


def test_a_late_status_reader_gets_the_last_status(rig: Rig) -> None:
    gid, _, res = rig.run(["wrist_roll"], [(0.5, [0.2])])
    assert res.status == SUCCEEDED
    late = ActionClient(DOMAIN, rig.ns, ACTION, rig.distro)  # joins after the status was published
    try:
        late.wait_ready()
        end = time.monotonic() + 5.0
        while late.last_status(gid) is None:
            assert time.monotonic() < end, "the status was not delivered to a reader that joined late"
            time.sleep(0.02)
        assert late.last_status(gid) == SUCCEEDED and len(late.received.status) == 1
    finally:
        late.close()


def test_cancel_mid_move_stops_jerk_limited_and_reports_canceled(rig: Rig) -> None:
    rig.settle({"elbow": 0.3})
    c = rig.client
    since = rig.mark()
    gid = uuid.uuid4().bytes
    _, _, reply = c.send(gid, c.goal(["elbow"], [(3.0, [1.5])]))
    assert reply.accepted
    time.sleep(1.2)
    answer = c.cancel(gid)
    assert answer.return_code == 0 and [bytes(g.goal_id.uuid) for g in answer.goals_canceling] == [gid]
    _, res = c.result(gid)
    assert res.status == CANCELED
    assert c.cancel(gid).return_code == 3, "ERROR_GOAL_TERMINATED for a goal already canceled"
    time.sleep(1.0)
    cmd = commands(rig.ctl, since)
    t, q, v = cmd.t["elbow"], cmd.q["elbow"], cmd.v["elbow"]
    assert 0.5 < q[-1] < 1.3, "stopped well short of the target"
    assert np.ptp(q[-100:]) < 1e-4 and abs(v[-1]) < 0.025, "then held (a zero velocity is half a step)"
    assert v.max() > 0.3
    assert_no_velocity_step(t, v, "elbow")
    assert np.abs(rig.q()[NAMES.index("elbow")] - q[-1]) < 5e-3


def test_a_new_goal_preempts_the_running_one_and_the_motion_blends_without_a_stop(rig: Rig) -> None:
    rig.settle({"elbow": 0.2})
    c = rig.client
    since = rig.mark()
    first, second = uuid.uuid4().bytes, uuid.uuid4().bytes
    assert c.send(first, c.goal(["elbow"], [(3.0, [1.2])]))[2].accepted
    time.sleep(1.0)
    assert c.send(second, c.goal(["elbow"], [(1.5, [1.6])]))[2].accepted
    _, res1 = c.result(first)
    assert res1.status == ABORTED and res1.result.error_code == INVALID_GOAL
    assert "preempted" in res1.result.error_string
    _, res2 = c.result(second)
    assert res2.status == SUCCEEDED, res2.result.error_string
    assert abs(rig.q()[NAMES.index("elbow")] - 1.6) < 3e-3
    cmd = commands(rig.ctl, since)
    t, v = cmd.t["elbow"], cmd.v["elbow"]
    moving = np.nonzero(v > 0.1)[0]  # from the first goal's start to the second goal's end
    assert v[moving[0]:moving[-1]].min() > 0.05, "no stop between the two goals: the motion blends"
    assert_no_velocity_step(t, v, "elbow")


@pytest.mark.parametrize(("names", "points", "code", "text"), [
    (["elbow", "elbowx"], [(1.0, [0.1, 0.1])], INVALID_JOINTS, "'elbowx', which is not a joint of this arm"),
    (["elbow", "elbow"], [(1.0, [0.1, 0.1])], INVALID_JOINTS, "names 'elbow' twice"),
    (["shoulder_pan"], [(1.0, [0.4]), (2.0, [5.0])], INVALID_GOAL, "outside the joint's range"),
    (["shoulder_pan"], [(1.0, [0.4]), (1.0, [0.5])], INVALID_GOAL, "is not after point 0's"),
    (["shoulder_pan"], [(1.0, [0.4]), (0.5, [0.5])], INVALID_GOAL, "is not after point 0's"),
    (["shoulder_pan"], [(1.0, [0.1], [1e6]), (2.0, [0.2], [0.0])], INVALID_GOAL, "beyond the joint's limit"),
], ids=["unknown-joint", "duplicate-joint", "past-a-limit", "equal-times", "decreasing-times", "velocity-1e6"])
def test_a_bad_goal_is_aborted_with_its_code_and_reason_and_nothing_moves(rig: Rig, names: list[str],
                                                                          points: list[Any], code: int,
                                                                          text: str) -> None:
    q0 = rig.q()
    since = rig.mark()
    gid, _, res = rig.run(names, points)
    assert res.status == ABORTED and res.result.error_code == code and text in res.result.error_string
    time.sleep(0.5)
    assert held_still(commands(rig.ctl, since)), "no command moved"
    assert np.abs(rig.q() - q0).max() < 3e-3


@pytest.mark.parametrize(("points", "text"), [
    ([(1.0, [0.4]), (1.0, [0.5])], "is not after point 0's"),
    ([(1.0, [0.1], [1e6]), (2.0, [0.2], [0.0])], "beyond the joint's limit"),
], ids=["equal-times", "velocity-1e6"])
def test_the_joint_trajectory_topic_refuses_them_too(rig: Rig, points: list[Any], text: str) -> None:
    node = dds.Node(DOMAIN, rig.ns)
    try:
        pub = node.publisher("joint_trajectory", msgs.JointTrajectory)
        status = node.subscription("akarm/status", msgs.DiagnosticArray)
        end = time.monotonic() + 10
        while not pub.get_matched_subscriptions():
            assert time.monotonic() < end
            time.sleep(0.01)
        since = rig.mark()
        q0 = rig.q()
        raw = velocities_trajectory(["shoulder_pan"], points) if len(points[0]) > 2 else \
            rosbags_trajectory(["shoulder_pan"], points)
        assert ddspy_write(pub._ref, raw + b"\0" * (-len(raw) % 4)) >= 0
        end = time.monotonic() + 5
        refusal = ""
        while text not in refusal:
            assert time.monotonic() < end, f"akarm/status reports the refusal ({refusal!r})"
            for m in status.take(16):
                refusal = {kv.key: kv.value for kv in m.status[0].values}.get("last_refusal", "")
            time.sleep(0.05)
        time.sleep(0.3)
        assert held_still(commands(rig.ctl, since)) and np.abs(rig.q() - q0).max() < 3e-3
    finally:
        node.close()


def velocities_trajectory(names: list[str], points: list[Any]) -> bytes:
    """A JointTrajectory with velocities, serialized by rosbags."""
    store = typestore("humble")
    T = store.types
    empty = np.array([], dtype=float)
    pts = [T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=np.array(q, dtype=float), velocities=np.array(v, dtype=float), accelerations=empty, effort=empty,
        time_from_start=T["builtin_interfaces/msg/Duration"](sec=int(t), nanosec=round((t % 1) * 1e9)))
        for t, q, v in points]
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="")
    return bytes(store.serialize_cdr(T["trajectory_msgs/msg/JointTrajectory"](header=header, joint_names=names,
                                                                              points=pts),
                                     "trajectory_msgs/msg/JointTrajectory"))


def test_a_push_past_the_path_tolerance_aborts_the_goal_and_stops_the_arm(rig: Rig) -> None:
    rig.settle({"elbow": 0.3, "wrist_roll": 0.0})
    c = rig.client
    since = rig.mark()
    gid = uuid.uuid4().bytes
    goal = c.goal(["elbow", "wrist_roll"], [(3.0, [0.9, 0.0])], path_tolerance={"wrist_roll": (0.01, 0.0)})
    assert c.send(gid, goal)[2].accepted
    time.sleep(0.8)
    pushed = time.time()
    rig.ctl.push([0.0, 0.0, 0.0, 0.0, 0.0, 0.6])  # 0.6 N·m against kp 30: 0.02 rad; under its collision threshold
    try:
        ended, res = c.result(gid, timeout=10)
    finally:
        rig.ctl.push(None)
    assert res.status == ABORTED and res.result.error_code == PATH_TOLERANCE_VIOLATED, res.result.error_string
    assert "wrist_roll" in res.result.error_string and "path tolerance" in res.result.error_string
    assert ended - pushed < 1.0
    time.sleep(1.0)
    cmd = commands(rig.ctl, since)
    q = cmd.q["elbow"]
    assert 0.35 < q[-1] < 0.85, "the elbow stopped on its way"
    assert np.ptp(q[cmd.t["elbow"] > cmd.t["elbow"][-1] - 0.4]) < 1e-4, "and holds"
    assert not cmd.specials, "a stop of the action, not a safety stop: no EXIT, no ENTER"
    assert all(s.enabled for s in rig.ctl.state())
    rig.settle({"wrist_roll": 0.0})  # the server still takes goals


def test_the_topic_and_the_action_share_one_motion_the_last_one_wins(rig: Rig) -> None:
    c = rig.client
    rig.settle({"forearm_roll": 0.0})
    node = dds.Node(DOMAIN, rig.ns)
    try:
        pub = node.publisher("joint_trajectory", msgs.JointTrajectory)
        while not pub.get_matched_subscriptions():
            time.sleep(0.01)
        gid = uuid.uuid4().bytes
        assert c.send(gid, c.goal(["forearm_roll"], [(3.0, [1.0])]))[2].accepted
        time.sleep(0.8)
        pub.write(msgs.JointTrajectory(msgs.Header(), ["forearm_roll"], [msgs.JointTrajectoryPoint(
            [-0.3], time_from_start=msgs.Duration(1, 500_000_000))]))
        _, res = c.result(gid)
        assert res.status == ABORTED and "replaced" in res.result.error_string
        j = NAMES.index("forearm_roll")
        end = time.monotonic() + 6.0  # the topic's 1.5 s, from wherever the action had the joint, and settling
        while abs(rig.q()[j] + 0.3) > 3e-3:
            assert time.monotonic() < end, f"the topic's trajectory won: forearm_roll at {rig.q()[j]:.4f}"
            time.sleep(0.05)
    finally:
        node.close()
    rig.settle({"forearm_roll": 0.0})  # and a goal after it wins in turn


def test_ros_discovery_info_names_the_node_and_every_endpoint_it_opens(rig: Rig) -> None:
    node = dds.Node(DOMAIN, "")
    try:
        q = Qos(Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
                Policy.Durability.TransientLocal, Policy.History.KeepLast(1))
        reader = node.reader(DISCOVERY_TOPIC, participant_info_type(rig.distro), q)
        info = None
        end = time.monotonic() + 10
        while info is None:
            assert time.monotonic() < end, "no ros_discovery_info from the server"
            for data, si in ddspy_take(reader._ref, dds.ANY, 64) or []:
                if si.valid_data:
                    m = roundtrip(rig.distro, bytes(data), "rmw_dds_common/msg/ParticipantEntitiesInfo")
                    if [n.node_namespace for n in m.node_entities_info_seq] == [f"/{rig.ns}"]:
                        info = m
            time.sleep(0.02)
        size = 24 if rig.distro == "humble" else 16
        assert len(info.gid.data) == size and not bytes(info.gid.data[16:]).strip(b"\0")
        (entry,) = info.node_entities_info_seq
        assert entry.node_name == "akarm"
        server = bytes(info.gid.data[:16])
        # every reader and writer of the server's participant, from DDS discovery (the builtin topics)
        readers: set[bytes] = set()
        writers: set[bytes] = set()
        pubs: dict[str, str] = {}
        builtins = [(BuiltinDataReader(node.participant, kind), kind, found) for kind, found in
                    ((BuiltinTopicDcpsPublication, writers), (BuiltinTopicDcpsSubscription, readers))]
        end = time.monotonic() + 10
        # readers: the trajectory and servo twist topics, Trigger services, action; writers: topics, services, action
        while len(readers) < 2 + 3 + 3 or len(writers) < 2 + 3 + 3 + 2:
            assert time.monotonic() < end, f"discovered {len(readers)} readers, {len(writers)} writers"
            for builtin, kind, found in builtins:
                for s in builtin.take(N=500):
                    if s.participant_key.bytes == server and s.topic_name != DISCOVERY_TOPIC:
                        found.add(s.key.bytes)
                        if kind is BuiltinTopicDcpsPublication:
                            pubs[s.topic_name] = s.type_name
            time.sleep(0.05)
        assert len(readers) == 8 and len(writers) == 10
        listed_r = {bytes(g.data[:16]) for g in entry.reader_gid_seq}
        listed_w = {bytes(g.data[:16]) for g in entry.writer_gid_seq}
        assert listed_r == readers and listed_w == writers
        assert all(not bytes(g.data[16:]).strip(b"\0") for g in [*entry.reader_gid_seq, *entry.writer_gid_seq])
        # what `ros2 action list -t` derives from discovery alone
        fb = f"rt/{rig.ns}/{ACTION}/_action/feedback"
        assert pubs[fb] == "control_msgs::action::dds_::FollowJointTrajectory_FeedbackMessage_"
        assert pubs[f"rt/{rig.ns}/{ACTION}/_action/status"] == "action_msgs::msg::dds_::GoalStatusArray_"
        assert f"rr/{rig.ns}/{ACTION}/_action/send_goalReply" in pubs
    finally:
        node.close()


def test_a_safety_stop_aborts_the_goal_with_its_text_and_latches(rig: Rig) -> None:
    """Last in the module: the arm is disabled by the stop (upright first: arm6 stays put when limp)."""
    rig.settle()
    c = rig.client
    gid = uuid.uuid4().bytes
    assert c.send(gid, c.goal(["wrist_roll"], [(4.0, [1.0])]))[2].accepted
    time.sleep(0.5)
    rig.ctl.inject("wrist_roll", faults.Unplugged(power_lost=True))
    _, res = c.result(gid, timeout=15)
    assert res.status == ABORTED and res.result.error_code == PATH_TOLERANCE_VIOLATED
    assert "safety stop: FeedbackTimeout" in res.result.error_string and "wrist_roll" in res.result.error_string
    rig.ctl.clear_faults()
    time.sleep(0.5)
    since = rig.mark()
    # latched: the next goal is refused with the stop's text, and nothing is enabled or moved
    gid2, _, res2 = rig.run(["elbow"], [(1.0, [0.3])])
    assert res2.status == ABORTED and res2.result.error_code == INVALID_GOAL
    assert "wrist_roll" in res2.result.error_string
    time.sleep(0.5)
    cmd = commands(rig.ctl, since)
    assert not [s for s in cmd.specials if s[2] == "enter"], "no ENTER"
    assert all((cmd.kp[n] == 0).all() for n in NAMES), "no command with kp > 0"
    assert not any(s.enabled for s in rig.ctl.state())
    # an explicit enable acknowledges it; then goals move the arm again
    enable = dds.TriggerClient(c.node, "akarm/enable")
    assert enable.call(timeout=30).success
    rig.settle({"elbow": 0.3})
    assert abs(rig.q()[NAMES.index("elbow")] - 0.3) < 3e-3
