"""Our ROS 2 DDS types against rosbags' ROS 2 typestore (an independent CDR implementation), and ROS naming."""

from __future__ import annotations

import struct

import numpy as np
import pytest

pytest.importorskip("cyclonedds")
rosbags_typesys = pytest.importorskip("rosbags.typesys")

from akarm.errors import AkarmError  # noqa: E402
from akarm.ros import msgs  # noqa: E402
from akarm.ros.dds import ros_name, service_topics, topic_name  # noqa: E402
from akarm.ros.trajectory import trajectory_arrays  # noqa: E402

STORE = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_HUMBLE)


def ros(name: str):
    return STORE.types[name]


def header(sec: int, nanosec: int, frame: str):
    return ros("std_msgs/msg/Header")(stamp=ros("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec),
                                       frame_id=frame)


def test_joint_state_bytes_are_what_rosbags_writes_and_reads():
    ours = msgs.JointState(msgs.Header(msgs.Time(12, 345), "base"), ["a", "bc"], [0.5, -1.25], [0.0, 2.0], [3.5, 0.0])
    theirs = ros("sensor_msgs/msg/JointState")(header=header(12, 345, "base"), name=["a", "bc"],
                                               position=np.array([0.5, -1.25]), velocity=np.array([0.0, 2.0]),
                                               effort=np.array([3.5, 0.0]))
    raw = bytes(STORE.serialize_cdr(theirs, "sensor_msgs/msg/JointState"))
    assert ours.serialize() == raw
    back = STORE.deserialize_cdr(ours.serialize(), "sensor_msgs/msg/JointState")
    assert back.name == ["a", "bc"] and list(back.position) == [0.5, -1.25] and back.header.stamp.nanosec == 345


def test_a_joint_trajectory_serialized_by_rosbags_decodes_as_ours():
    P = ros("trajectory_msgs/msg/JointTrajectoryPoint")
    D = ros("builtin_interfaces/msg/Duration")
    msg = ros("trajectory_msgs/msg/JointTrajectory")(
        header=header(0, 0, ""), joint_names=["elbow", "shoulder_pan"],
        points=[P(positions=np.array([0.1, 0.2]), velocities=np.array([], dtype=float),
                  accelerations=np.array([], dtype=float), effort=np.array([], dtype=float),
                  time_from_start=D(sec=1, nanosec=500_000_000)),
                P(positions=np.array([0.3, -0.4]), velocities=np.array([0.0, 0.1]),
                  accelerations=np.array([], dtype=float), effort=np.array([], dtype=float),
                  time_from_start=D(sec=2, nanosec=0))])
    raw = bytes(STORE.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory"))
    ours = msgs.JointTrajectory.deserialize(raw)
    assert ours.joint_names == ["elbow", "shoulder_pan"]
    assert [p.time_from_start.seconds() for p in ours.points] == [1.5, 2.0]
    assert list(ours.points[1].velocities) == [0.0, 0.1]
    times, positions, velocities = trajectory_arrays(ours, now=1000.0)
    assert times == [1.5, 2.0] and positions == [[0.1, 0.2], [0.3, -0.4]]
    assert velocities == [[], [0.0, 0.1]]


def test_a_stamp_in_the_future_delays_and_one_in_the_past_drops_points():
    traj = msgs.JointTrajectory(msgs.Header(msgs.Time.from_seconds(1002.0)), ["a"],
                                [msgs.JointTrajectoryPoint([1.0], time_from_start=msgs.Duration(1, 0))])
    assert trajectory_arrays(traj, now=1000.0)[0] == pytest.approx([3.0])
    traj.header.stamp = msgs.Time.from_seconds(998.5)
    traj.points.append(msgs.JointTrajectoryPoint([2.0], time_from_start=msgs.Duration(3, 0)))
    times, positions, _ = trajectory_arrays(traj, now=1000.0)
    assert times == pytest.approx([1.5]) and positions == [[2.0]]


def test_diagnostics_decode_in_rosbags():
    ours = msgs.DiagnosticArray(msgs.Header(msgs.Time(1, 2)), [msgs.DiagnosticStatus(
        2, "akarm: arm6", "fault: x", "arm6", [msgs.KeyValue("mode", "fault"), msgs.KeyValue("missed_slots", "3")])])
    back = STORE.deserialize_cdr(ours.serialize(), "diagnostic_msgs/msg/DiagnosticArray")
    st = back.status[0]
    assert st.level == 2 and st.name == "akarm: arm6" and [(v.key, v.value) for v in st.values] == [
        ("mode", "fault"), ("missed_slots", "3")]
    assert STORE.serialize_cdr(back, "diagnostic_msgs/msg/DiagnosticArray").tobytes() == ours.serialize()


def test_trigger_request_and_reply_carry_the_rmw_cyclonedds_header_then_the_srv_fields():
    # encapsulation CDR_LE, then guid (uint64) and seq (int64) little-endian, then the .srv fields,
    # aligned from the start of the header (docs/ros2.md)
    req = msgs.TriggerRequest(0x0102030405060708, 7, 0).serialize()
    assert req == bytes([0, 1, 0, 0]) + struct.pack("<Qq", 0x0102030405060708, 7) + b"\x00"
    rep = msgs.TriggerResponse(0x0102030405060708, 7, True, "ok").serialize()
    body = struct.pack("<Qq", 0x0102030405060708, 7) + b"\x01" + b"\x00" * 3 + struct.pack("<I", 3) + b"ok\x00"
    assert rep == bytes([0, 1, 0, 0]) + body
    # the part after the header is the plain ROS 2 message, as rosbags reads it (its 4-byte alignment
    # is the same at offset 16 as at 0); rosbags ships messages, not services: std_srvs/srv/Trigger's
    # reply part is registered from its definition
    store = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_HUMBLE)
    store.register(rosbags_typesys.get_types_from_msg("bool success\nstring message\n",
                                                      "std_srvs/msg/Trigger_Response"))
    theirs = store.deserialize_cdr(bytes([0, 1, 0, 0]) + body[16:], "std_srvs/msg/Trigger_Response")
    assert theirs.success is True and theirs.message == "ok"


def test_ros_names():
    assert topic_name("", "joint_states") == "rt/joint_states"
    assert topic_name("/left/", "joint_states") == "rt/left/joint_states"
    assert topic_name("robot/left", "akarm/status") == "rt/robot/left/akarm/status"
    assert service_topics("left", "akarm/enable") == ("rq/left/akarm/enableRequest", "rr/left/akarm/enableReply")
    assert ros_name("", "x") == "/x"
    for bad in ("1arm", "my-arm", "a b"):
        with pytest.raises(AkarmError, match="not a valid ROS 2 name"):
            ros_name(bad, "joint_states")
