"""A FollowJointTrajectory action client for the tests and the benchmark, as a ROS 2 node on
rmw_cyclonedds_cpp would be one, built from the message definitions and not from akarm's codecs.

Payloads are written and read by rosbags (:mod:`tests.rosdefs`: control_msgs' definitions for the
distribution, the implicit structs of an action) and checked byte for byte: every sample received
is decoded by rosbags and serialized again, and must give the same bytes. akarm's DDS types are used
only to name the DDS types of the readers and writers (the bytes they carry are rosbags').

The layout is rcl_action's and rmw_cyclonedds_cpp's: for each service a request writer and a reply
reader carrying USER_DATA ``clientid=...;``, requests and replies led by the 16-byte request header
(``guid``: the request writer's instance handle, ``seq``); the status reader is reliable, transient
local, keep last 1. :meth:`ActionClient.server_ready` is rcl's ``rcl_action_server_is_available``
with rmw_cyclonedds_cpp's ``rmw_service_server_is_available``; the client applies it before sending.
"""

from __future__ import annotations

import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from cyclonedds._clayer import ddspy_take, ddspy_write
from cyclonedds.core import ReadCondition, WaitSet
from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

from akarm.ros import action_types as at
from akarm.ros import dds

from ..rosdefs import CANCEL, FJT, GC, serialize, typestore

__all__ = ["ActionClient", "Received", "roundtrip"]

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little-endian


def roundtrip(distro: str, raw: bytes, name: str, header: bool = False) -> Any:
    """``raw`` decoded by rosbags as ``name`` (after the request header with ``header``); asserts that
    rosbags serializes the decoded message to the very same bytes (but the padding DDS may add)."""
    body = ENCAPSULATION + raw[20:] if header else raw
    msg = typestore(distro).deserialize_cdr(body, name)
    again = serialize(distro, msg, name)
    assert body[:len(again)] == again and not body[len(again):].strip(b"\0"), \
        f"{name}: rosbags writes other bytes than the server sent\n{again.hex()}\n{body.hex()}"
    return msg


def _user_data(q: Qos | None, key: str) -> str | None:
    if q is None:
        return None
    try:
        data = bytes(q[Policy.Userdata].data)
    except (KeyError, AttributeError):
        return None
    for item in data.decode("utf-8", "replace").split(";"):
        k, sep, v = item.partition("=")
        if sep and k == key:
            return v
    return None


class _Service:
    """A service client's request writer and reply reader, as rmw_cyclonedds_cpp's."""

    def __init__(self, node: dds.Node, name: str, request_type: Any, response_type: Any) -> None:
        rq, rr = dds.service_topics(node.namespace, name)
        q = dds.qos(user_data=node.unique_id("clientid"))
        self.writer = node.writer(rq, request_type, q)
        self.reader = node.reader(rr, response_type, q)
        self.guid = self.writer.get_instance_handle() & 0xFFFF_FFFF_FFFF_FFFF
        self.seq = 0
        self.replies: dict[int, tuple[float, bytes]] = {}  # seq → (time.time() received, raw)

    def available(self) -> bool:
        """rmw_cyclonedds_cpp's ``rmw_service_server_is_available``: a request reader and a reply
        writer are matched, and (when the service says who it is) one reply writer carries the
        ``serviceid`` of a matched request reader."""
        readers = self.writer.get_matched_subscriptions()
        writers = self.reader.get_matched_publications()
        if not readers or not writers:
            return False
        needles = {_user_data(d.qos, "serviceid") for d in (self.writer.get_matched_subscription_data(h)
                                                             for h in readers) if d is not None}
        needles.discard(None)
        if not needles:
            return True
        return any(_user_data(d.qos, "serviceid") in needles for d in (self.reader.get_matched_publication_data(h)
                                                                      for h in writers) if d is not None)

    def send(self, payload: bytes) -> int:
        """Send a request: the header, then ``payload`` (rosbags' CDR of the request part, encapsulation
        and all); returns its sequence number."""
        self.seq += 1
        data = ENCAPSULATION + struct.pack("<Qq", self.guid, self.seq) + payload[4:]
        assert ddspy_write(self.writer._ref, data + b"\0" * (-len(data) % 4)) >= 0  # private-ok: cyclonedds
        return self.seq

    def take(self) -> None:
        for data, info in ddspy_take(self.reader._ref, dds.ANY, 64) or []:  # private-ok: cyclonedds
            raw = bytes(data)
            if info.valid_data and len(raw) >= 20:
                guid, seq = struct.unpack_from("<Qq", raw, 4)
                if guid == self.guid:
                    self.replies[seq] = (time.time(), raw)


@dataclass
class Received:
    """What the client has received, with ``time.time()`` on arrival."""

    feedback: list[tuple[float, Any]] = field(default_factory=list)
    status: list[tuple[float, Any]] = field(default_factory=list)


class ActionClient:
    """A client of the action ``name`` (e.g. ``arm_controller/follow_joint_trajectory``) of type ``action``
    (FollowJointTrajectory, or GripperCommand: :data:`~tests.rosdefs.GC`) in ``namespace`` of DDS
    ``domain``, speaking ``distro``'s layouts."""

    def __init__(self, domain: int, namespace: str, name: str, distro: str, action: str = FJT) -> None:
        self.distro = distro
        self.action = action
        self.store = typestore(distro)
        self.node = dds.Node(domain, namespace)
        base = name + "/_action/"
        if action == GC:  # the DDS types name the topics' types; the bytes are rosbags'
            kinds: tuple[Any, ...] = (at.GripperSendGoalRequest, at.GripperSendGoalResponse,
                                      at.GripperGetResultRequest, at.GripperGetResultResponse,
                                      at.GripperFeedbackMessage)
        else:
            kinds = (at.SendGoalRequest, at.SendGoalResponse, at.GetResultRequest, at.GetResultResponse,
                     at.feedback_message_type(distro))
        self.send_goal = _Service(self.node, base + "send_goal", kinds[0], kinds[1])
        self.cancel_goal = _Service(self.node, base + "cancel_goal", at.CancelGoalRequest, at.CancelGoalResponse)
        self.get_result = _Service(self.node, base + "get_result", kinds[2], kinds[3])
        self.services = (self.send_goal, self.cancel_goal, self.get_result)
        fb_type = kinds[4]
        self.feedback = self.node.reader(dds.topic_name(namespace, base + "feedback"), fb_type, dds.qos(100))
        status_qos = Qos(Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
                         Policy.Durability.TransientLocal, Policy.History.KeepLast(1))
        self.status = self.node.reader(dds.topic_name(namespace, base + "status"), at.GoalStatusArray, status_qos)
        self.received = Received()
        self._lock = threading.Lock()
        self._ws = WaitSet(self.node.participant)
        for r in (self.feedback, self.status, *(s.reader for s in self.services)):
            self._ws.attach(ReadCondition(r, dds.ANY))
        self._running = True
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    # -- receiving ----------------------------------------------------------------------------------
    def _run(self) -> None:
        while self._running:
            self._ws.wait(50_000_000)
            with self._lock:
                for s in self.services:
                    s.take()
                for data, info in ddspy_take(self.feedback._ref, dds.ANY, 256) or []:  # private-ok: cyclonedds
                    if info.valid_data:
                        t = time.time()
                        self.received.feedback.append((t, roundtrip(self.distro, bytes(data),
                                                                    f"{self.action}_FeedbackMessage")))
                for data, info in ddspy_take(self.status._ref, dds.ANY, 16) or []:  # private-ok: cyclonedds
                    if info.valid_data:
                        t = time.time()
                        self.received.status.append((t, roundtrip(self.distro, bytes(data),
                                                                  "action_msgs/msg/GoalStatusArray")))

    def server_ready(self) -> bool:
        """rcl_action's ``rcl_action_server_is_available``: the three services available, and the feedback
        and the status topic each with a matched publisher."""
        return all(s.available() for s in self.services) and bool(self.feedback.get_matched_publications()) \
            and bool(self.status.get_matched_publications())

    def wait_ready(self, timeout: float = 20.0) -> None:
        end = time.monotonic() + timeout
        while not self.server_ready():
            assert time.monotonic() < end, "the action server never became ready (rcl's rule)"
            time.sleep(0.01)

    def _call(self, service: _Service, name: str, payload: bytes, timeout: float) -> tuple[float, Any]:
        assert self.server_ready(), "a ROS 2 client sends only to a server that is ready"
        seq = service.send(payload)
        end = time.monotonic() + timeout
        while True:
            with self._lock:
                got = service.replies.pop(seq, None)
            if got is not None:
                return got[0], roundtrip(self.distro, got[1], name, header=True)
            assert time.monotonic() < end, f"no reply to {name} within {timeout} s"
            time.sleep(0.001)

    # -- messages -----------------------------------------------------------------------------------
    def T(self, name: str) -> Any:
        """The rosbags class of message ``name``."""
        return self.store.types[name]

    def goal(self, names: list[str], points: list[tuple[float, list[float]]] | list[tuple[float, list[float],
                                                                                      list[float]]],
             path_tolerance: dict[str, tuple[float, float]] | None = None,
             goal_tolerance: dict[str, tuple[float, float]] | None = None, goal_time: float = 0.0,
             stamp: float = 0.0) -> Any:
        """A FollowJointTrajectory goal: ``points`` as (time_from_start, positions[, velocities]);
        tolerances as {joint: (position, velocity)}."""
        import numpy as np

        T = self.T
        D = T("builtin_interfaces/msg/Duration")
        empty = np.array([], dtype=float)

        def dur(t: float) -> Any:
            ns = round(t * 1e9)
            return D(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

        pts = [T("trajectory_msgs/msg/JointTrajectoryPoint")(
            positions=np.array(p[1], dtype=float), velocities=np.array(p[2], dtype=float) if len(p) > 2 else empty,
            accelerations=empty, effort=empty, time_from_start=dur(p[0])) for p in points]
        ns = round(stamp * 1e9)
        header = T("std_msgs/msg/Header")(stamp=T("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000,
                                                                                nanosec=ns % 1_000_000_000),
                                          frame_id="")
        traj = T("trajectory_msgs/msg/JointTrajectory")(header=header, joint_names=names, points=pts)
        no_header = T("std_msgs/msg/Header")(stamp=T("builtin_interfaces/msg/Time")(sec=0, nanosec=0), frame_id="")
        mdof = T("trajectory_msgs/msg/MultiDOFJointTrajectory")(header=no_header, joint_names=[], points=[])
        JT = T("control_msgs/msg/JointTolerance")

        def tols(d: dict[str, tuple[float, float]] | None) -> list[Any]:
            return [JT(name=n, position=p, velocity=v, acceleration=0.0) for n, (p, v) in (d or {}).items()]

        return T(f"{FJT}_Goal")(trajectory=traj, multi_dof_trajectory=mdof, path_tolerance=tols(path_tolerance),
                                component_path_tolerance=[], goal_tolerance=tols(goal_tolerance),
                                component_goal_tolerance=[], goal_time_tolerance=dur(goal_time))

    def uuid(self, goal_id: bytes) -> Any:
        import numpy as np

        return self.T("unique_identifier_msgs/msg/UUID")(uuid=np.frombuffer(goal_id, dtype=np.uint8).copy())

    # -- the three services ---------------------------------------------------------------------------
    def gripper_goal(self, width: float, max_effort: float = 0.0) -> Any:
        """A GripperCommand goal: ``width`` (m), ``max_effort`` (N)."""
        cmd = self.T("control_msgs/msg/GripperCommand")(position=width, max_effort=max_effort)
        return self.T(f"{GC}_Goal")(command=cmd)

    def send(self, goal_id: bytes, goal: Any, timeout: float = 10.0) -> tuple[float, float, Any]:
        """Send a goal: (time.time() sent, time.time() the reply came, the SendGoal response)."""
        a = self.action
        req = self.T(f"{a}_SendGoal_Request")(goal_id=self.uuid(goal_id), goal=goal)
        payload = serialize(self.distro, req, f"{a}_SendGoal_Request")
        sent = time.time()
        received, reply = self._call(self.send_goal, f"{a}_SendGoal_Response", payload, timeout)
        return sent, received, reply

    def result(self, goal_id: bytes, timeout: float = 30.0) -> tuple[float, Any]:
        """Ask for a goal's result (the server answers when the goal ends): (time.time() it came, the response)."""
        a = self.action
        req = self.T(f"{a}_GetResult_Request")(goal_id=self.uuid(goal_id))
        return self._call(self.get_result, f"{a}_GetResult_Response",
                          serialize(self.distro, req, f"{a}_GetResult_Request"), timeout)

    def cancel(self, goal_id: bytes = bytes(16), stamp: float = 0.0, timeout: float = 10.0) -> Any:
        """Cancel a goal by id, the goals up to a stamp, or (both zero) all of them."""
        T = self.T
        ns = round(stamp * 1e9)
        info = T("action_msgs/msg/GoalInfo")(goal_id=self.uuid(goal_id), stamp=T("builtin_interfaces/msg/Time")(
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000))
        req = T(f"{CANCEL}_Request")(goal_info=info)
        return self._call(self.cancel_goal, f"{CANCEL}_Response", serialize(self.distro, req, f"{CANCEL}_Request"),
                          timeout)[1]

    def feedback_of(self, goal_id: bytes) -> list[tuple[float, Any]]:
        with self._lock:
            return [(t, m) for t, m in self.received.feedback if bytes(m.goal_id.uuid) == goal_id]

    def last_status(self, goal_id: bytes) -> int | None:
        with self._lock:
            if not self.received.status:
                return None
            for s in self.received.status[-1][1].status_list:
                if bytes(s.goal_info.goal_id.uuid) == goal_id:
                    return int(s.status)
        return None

    def close(self) -> None:
        self._running = False
        self._thread.join(2.0)
        self.node.close()
