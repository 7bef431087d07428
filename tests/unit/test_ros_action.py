"""The FollowJointTrajectory action's types against rosbags (control_msgs' definitions, tests/rosdefs.py),
ros_discovery_info's per distribution, and the checks of JointTrajectoryController: pure logic."""

from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags.typesys")

from akarm import ArgumentError, load_robot
from akarm.motion.bounds import MAX_TRAJECTORY_POINTS
from akarm.motion.trajectory import JointLimits
from akarm.ros import action_types as at
from akarm.ros import graph, msgs
from akarm.ros.action import STOPPED_VELOCITY, Tolerances, action_name, goal_tolerances, violation
from akarm.ros.graph import participant_info_type
from akarm.ros.trajectory import (
    INVALID_GOAL,
    INVALID_JOINTS,
    OLD_HEADER_TIMESTAMP,
    TrajectoryRefused,
    check_size,
    check_trajectory,
    max_message_bytes,
)

from ..rosdefs import CANCEL, FJT, serialize, typestore
from .conftest import ROBOTS

CONFIG = load_robot(ROBOTS / "arm6.yaml")
NAMES = list(CONFIG.joint_names)
LIMITS = JointLimits(tuple(NAMES), *(np.array([getattr(j.limits, k) for j in CONFIG.joints]) for k in
                                     ("lower", "upper", "velocity", "acceleration", "jerk")))
HEADER = struct.pack("<Qq", 0x0123456789ABCDEF, 42)  # rmw_cyclonedds_cpp's request header: guid, seq


def point(q: list[float], t: float, v: list[float] | None = None) -> msgs.JointTrajectoryPoint:
    ns = round(t * 1e9)
    return msgs.JointTrajectoryPoint(q, v or [], [], [], msgs.Duration(ns // 1_000_000_000, ns % 1_000_000_000))


def traj(names: list[str], points: list[msgs.JointTrajectoryPoint], stamp: float = 0.0) -> msgs.JointTrajectory:
    return msgs.JointTrajectory(msgs.Header(msgs.Time.from_seconds(stamp) if stamp else msgs.Time()), names, points)


def ours_goal() -> at.FollowJointTrajectoryGoal:
    return at.FollowJointTrajectoryGoal(
        traj(["elbow", "wrist_roll"], [point([0.1, 0.2], 0.5), point([0.3, -0.4], 1.25, [0.0, 0.0])], stamp=12.5),
        path_tolerance=[at.JointTolerance("elbow", 0.05, -1.0, 0.0)],
        goal_tolerance=[at.JointTolerance("wrist_roll", 0.01, 0.02, 0.0)],
        goal_time_tolerance=msgs.Duration(0, 500_000_000))


# -- the bytes ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("distro", ["humble", "jazzy", "rolling"])
def test_a_send_goal_request_is_the_header_then_what_rosbags_writes(distro: str) -> None:
    ours = at.SendGoalRequest(0x0123456789ABCDEF, 42, at.UUID(list(range(16))), ours_goal()).serialize()
    assert ours[:20] == b"\x00\x01\x00\x00" + HEADER
    store = typestore(distro)
    theirs = store.deserialize_cdr(ours[:4] + ours[20:], f"{FJT}_SendGoal_Request")
    assert bytes(theirs.goal_id.uuid) == bytes(range(16))
    g = theirs.goal
    assert list(g.trajectory.joint_names) == ["elbow", "wrist_roll"] and g.trajectory.header.stamp.sec == 12
    assert list(g.trajectory.points[1].positions) == [0.3, -0.4] and g.trajectory.points[1].time_from_start.nanosec \
        == 250_000_000
    assert g.path_tolerance[0].name == "elbow" and g.path_tolerance[0].velocity == -1.0
    assert g.goal_time_tolerance.nanosec == 500_000_000
    assert serialize(distro, theirs, f"{FJT}_SendGoal_Request") == ours[:4] + ours[20:]
    back = at.SendGoalRequest.deserialize(ours)  # and ours reads what rosbags writes
    assert back.goal.trajectory.joint_names == ["elbow", "wrist_roll"] and back.seq == 42


def test_the_replies_and_the_status_are_what_rosbags_writes() -> None:
    store = typestore("jazzy")
    T = store.types
    cases = [
        (at.SendGoalResponse(1, 2, True, msgs.Time(5, 6)), f"{FJT}_SendGoal_Response",
         T[f"{FJT}_SendGoal_Response"](accepted=True, stamp=T["builtin_interfaces/msg/Time"](sec=5, nanosec=6))),
        (at.GetResultResponse(1, 2, 6, at.FollowJointTrajectoryResult(-4, "path tolerance violated")),
         f"{FJT}_GetResult_Response",
         T[f"{FJT}_GetResult_Response"](status=6, result=T[f"{FJT}_Result"](error_code=-4,
                                                                            error_string="path tolerance violated"))),
    ]
    info = T["action_msgs/msg/GoalInfo"](goal_id=T["unique_identifier_msgs/msg/UUID"](
        uuid=np.arange(16, dtype=np.uint8)), stamp=T["builtin_interfaces/msg/Time"](sec=7, nanosec=8))
    our_info = at.GoalInfo(at.UUID(list(range(16))), msgs.Time(7, 8))
    cases.append((at.CancelGoalResponse(1, 2, 0, [our_info]), f"{CANCEL}_Response",
                  T[f"{CANCEL}_Response"](return_code=0, goals_canceling=[info])))
    for ours, name, theirs in cases:
        raw = ours.serialize()
        assert raw[4:20] == struct.pack("<Qq", 1, 2)
        assert raw[:4] + raw[20:] == serialize("jazzy", theirs, name), name
    status = at.GoalStatusArray([at.GoalStatus(our_info, 2), at.GoalStatus(our_info, 4)])
    theirs_status = T["action_msgs/msg/GoalStatusArray"](status_list=[
        T["action_msgs/msg/GoalStatus"](goal_info=info, status=2), T["action_msgs/msg/GoalStatus"](goal_info=info,
                                                                                                  status=4)])
    assert status.serialize() == serialize("jazzy", theirs_status, "action_msgs/msg/GoalStatusArray")
    req = at.CancelGoalRequest(1, 2, our_info).serialize()
    assert store.deserialize_cdr(req[:4] + req[20:], f"{CANCEL}_Request").goal_info.stamp.sec == 7
    req = at.GetResultRequest(1, 2, at.UUID(list(range(16)))).serialize()
    assert bytes(store.deserialize_cdr(req[:4] + req[20:], f"{FJT}_GetResult_Request").goal_id.uuid) == \
        bytes(range(16))


@pytest.mark.parametrize("distro", ["humble", "jazzy", "rolling"])
def test_the_feedback_has_the_layout_of_its_distribution(distro: str) -> None:
    kind = at.feedback_message_type(distro)
    fb = (at.FeedbackRolling if distro == "rolling" else at.FeedbackHumble)(
        msgs.Header(msgs.Time(3, 4), ""), ["a", "b"], point([1.0, 2.0], 0.25, [0.5, 0.0]), point([1.01, 1.99], 0.25),
        point([-0.01, 0.01], 0.25))
    if distro == "rolling":
        fb.index = 3
    raw = kind(at.UUID([9] * 16), fb).serialize()
    store = typestore(distro)
    theirs = store.deserialize_cdr(raw, f"{FJT}_FeedbackMessage")
    assert list(theirs.feedback.actual.positions) == [1.01, 1.99] and list(theirs.feedback.joint_names) == ["a", "b"]
    assert serialize(distro, theirs, f"{FJT}_FeedbackMessage") == raw
    assert (theirs.feedback.index == 3) if distro == "rolling" else not hasattr(theirs.feedback, "index")
    other = "humble" if distro == "rolling" else "rolling"  # the other layout is 8 bytes longer or shorter
    with pytest.raises(Exception):  # noqa: B017 - rosbags raises its own errors for bytes of another layout
        theirs_other = typestore(other).deserialize_cdr(raw, f"{FJT}_FeedbackMessage")
        assert serialize(other, theirs_other, f"{FJT}_FeedbackMessage") == raw


@pytest.mark.parametrize(("distro", "size"), [("humble", 24), ("jazzy", 16), ("rolling", 16)])
def test_ros_discovery_info_has_the_gid_size_of_its_distribution(distro: str, size: int) -> None:
    info = participant_info_type(distro)()
    gid, entry = type(info.gid), graph.NodeEntitiesInfoHumble if size == 24 else graph.NodeEntitiesInfoJazzy
    info.gid = gid(list(range(16)) + [0] * (size - 16))
    info.node_entities_info_seq = [entry("/arm6", "akarm", [gid(list(range(1, 17)) + [0] * (size - 16))], [])]
    raw = info.serialize()
    theirs = typestore(distro).deserialize_cdr(raw, "rmw_dds_common/msg/ParticipantEntitiesInfo")
    assert len(theirs.gid.data) == size and bytes(theirs.gid.data[:16]) == bytes(range(16))
    e = theirs.node_entities_info_seq[0]
    assert e.node_namespace == "/arm6" and e.node_name == "akarm" and bytes(e.reader_gid_seq[0].data[:2]) == b"\1\2"
    assert serialize(distro, theirs, "rmw_dds_common/msg/ParticipantEntitiesInfo") == raw


def test_only_the_three_distributions_are_spoken() -> None:
    assert at.check_distro("jazzy") == "jazzy"
    with pytest.raises(ArgumentError, match="unknown ROS 2 distribution 'iron'"):
        at.feedback_message_type("iron")
    assert action_name("arm_controller") == "arm_controller/follow_joint_trajectory"


# -- JointTrajectoryController's checks ------------------------------------------------------------
@pytest.mark.parametrize(("names", "points", "code", "text"), [
    ([], [point([], 1.0)], INVALID_JOINTS, "names no joints"),
    (["elbow", "elbo"], [point([0.1, 0.1], 1.0)], INVALID_JOINTS, "'elbo', which is not a joint of this arm (did you "
                                                                 "mean 'elbow'?)"),
    (["elbow", "elbow"], [point([0.1, 0.1], 1.0)], INVALID_JOINTS, "names 'elbow' twice"),
    (["elbow"], [point([0.1], 1.0), point([0.2], 1.0)], INVALID_GOAL, "point 1's time_from_start (1 s) is not after"),
    (["elbow"], [point([0.1], 1.0), point([0.2], 0.5)], INVALID_GOAL, "is not after point 0's (1 s)"),
    (["elbow"], [point([0.1, 0.2], 1.0)], INVALID_GOAL, "point 0 has 2 positions for 1 joint_names"),
    (["elbow", "wrist_roll"], [point([0.1, 0.1], 1.0), point([0.1, float("nan")], 2.0)], INVALID_GOAL,
     "joint 'wrist_roll': point 1: position nan is not a number"),
    (["elbow"], [point([0.1], 1.0, [0.3, 0.1]), point([0.2], 2.0)], INVALID_GOAL, "point 0 has 2 velocities for 1"),
    (["elbow"], [point([0.1], 1.0, [float("inf")]), point([0.2], 2.0, [0.0])], INVALID_GOAL,
     "joint 'elbow': point 0: velocity inf is not a number"),
    (["elbow"], [point([2.6], 1.0)], INVALID_GOAL, "position 2.6000 rad is outside the joint's range"),
    (["elbow"], [point([1e308], 1.0)], INVALID_GOAL, "position 1e+308 rad is outside the joint's range [-2.5000, "
                                                     "2.5000] rad"),
    (["elbow"], [point([0.1], 1.0, [1e6]), point([0.2], 2.0, [0.0])], INVALID_GOAL,
     "velocity 1e+06 rad/s is beyond the joint's limit 2.5 rad/s"),
    (["elbow"], [point([0.1], 1.0, [0.3]), point([0.2], 2.0)], INVALID_GOAL, "some points have velocities"),
    (["elbow"], [point([0.1], 1.0, [0.3])], INVALID_GOAL, "the last point is not at rest"),
])
def test_what_joint_trajectory_controller_refuses_is_refused_with_its_code(names: list[str], points: list,
                                                                          code: int, text: str) -> None:
    with pytest.raises(TrajectoryRefused) as e:
        check_trajectory(traj(names, points), NAMES, LIMITS, now=1000.0)
    assert e.value.code == code and text in str(e.value)
    assert isinstance(e.value, ArgumentError) and e.value.fix
    assert "velocitie " not in e.value.fix and len(str(e.value)) < 400  # no 309 digits of a huge value


def test_the_fix_for_a_count_of_velocities_is_grammatical() -> None:
    with pytest.raises(TrajectoryRefused) as e:
        check_trajectory(traj(["elbow"], [point([0.1], 1.0, [0.3, 0.1]), point([0.2], 2.0)]), NAMES, LIMITS, now=0.0)
    assert e.value.fix == "give one velocity (rad/s) per name in joint_names, or none"


def test_a_velocity_at_the_limit_is_taken_and_one_past_it_refused() -> None:
    ok = traj(["elbow"], [point([0.1], 1.0, [2.5]), point([0.2], 2.0, [0.0])])
    assert check_trajectory(ok, NAMES, LIMITS, now=0.0).velocities == [[2.5], [0.0]]
    ok.points[0].velocities = [2.5001]
    with pytest.raises(TrajectoryRefused, match="beyond the joint's limit"):
        check_trajectory(ok, NAMES, LIMITS, now=0.0)


def test_too_many_points_are_refused_before_anything_is_looked_at() -> None:
    msg = traj(["elbow"], [point([0.0], 0.0)] * (MAX_TRAJECTORY_POINTS + 1))
    with pytest.raises(TrajectoryRefused, match=f"more than the {MAX_TRAJECTORY_POINTS}") as e:
        check_trajectory(msg, NAMES, LIMITS, now=0.0)
    assert e.value.code == INVALID_GOAL


def test_a_stamp_shifts_the_points_and_one_wholly_past_is_old() -> None:
    msg = traj(["elbow", "shoulder_pan"], [point([0.1, 0.2], 1.0), point([0.3, 0.4], 3.0)], stamp=1001.0)
    p = check_trajectory(msg, NAMES, LIMITS, now=1000.0)
    assert p.times == pytest.approx([2.0, 4.0]) and p.positions == [[0.1, 0.2], [0.3, 0.4]] and p.velocities is None
    assert p.start == pytest.approx(1001.0) and p.end == pytest.approx(1004.0)
    assert [p.index(t) for t in (1001.5, 1002.5, 1004.5)] == [0, 1, 1]
    p = check_trajectory(traj(["elbow"], [point([0.1], 1.0), point([0.3], 3.0)], stamp=998.5), NAMES, LIMITS,
                         now=1000.0)
    assert p.times == pytest.approx([1.5]) and p.positions == [[0.3]], "the point already past is dropped"
    with pytest.raises(TrajectoryRefused, match="already in the past") as e:
        check_trajectory(traj(["elbow"], [point([0.1], 1.0)], stamp=990.0), NAMES, LIMITS, now=1000.0)
    assert e.value.code == OLD_HEADER_TIMESTAMP
    assert check_trajectory(traj(["elbow"], []), NAMES, LIMITS, now=0.0).times == []  # a stop, for the topic


# -- tolerances --------------------------------------------------------------------------------------
def test_tolerances_take_the_default_for_0_none_for_minus_1_and_a_value_above_0() -> None:
    defaults = Tolerances(np.full(6, 0.1), np.zeros(6), np.zeros(6), np.full(6, STOPPED_VELOCITY), 0.0)
    tol = goal_tolerances(ours_goal(), NAMES, defaults)
    e, w = NAMES.index("elbow"), NAMES.index("wrist_roll")
    assert tol.path_position[e] == 0.05 and tol.path_position[w] == 0.1  # the goal's, the default
    assert tol.path_velocity[e] == 0.0  # -1: erased
    assert tol.goal_position[w] == 0.01 and tol.goal_velocity[w] == 0.02 and tol.goal_velocity[e] == STOPPED_VELOCITY
    assert tol.goal_time == 0.5
    goal = ours_goal()
    goal.goal_time_tolerance = msgs.Duration(-1, 0)  # -1 s: no limit, whatever the default
    assert goal_tolerances(goal, NAMES, dataclasses.replace(defaults, goal_time=3.0)).goal_time == 0.0
    goal.goal_time_tolerance = msgs.Duration(0, 0)
    assert goal_tolerances(goal, NAMES, dataclasses.replace(defaults, goal_time=3.0)).goal_time == 3.0


@pytest.mark.parametrize(("edit", "code", "text"), [
    (lambda g: g.path_tolerance.append(at.JointTolerance("wrist", 0.1)), INVALID_JOINTS, "path_tolerance names "
                                                                                        "'wrist'"),
    (lambda g: g.goal_tolerance.append(at.JointTolerance("elbow", -2.0)), INVALID_GOAL, "goal_tolerance position of "
                                                                                       "'elbow' is -2"),
    (lambda g: g.component_path_tolerance.append(at.JointComponentTolerance("base", 4, 0.1)), INVALID_JOINTS,
     "no multi-DOF joints"),
    (lambda g: setattr(g, "goal_time_tolerance", msgs.Duration(-3, 0)), INVALID_GOAL, "goal_time_tolerance is -3"),
])
def test_bad_tolerances_are_refused(edit: object, code: int, text: str) -> None:
    goal = ours_goal()
    edit(goal)  # type: ignore[operator]
    with pytest.raises(TrajectoryRefused) as e:
        goal_tolerances(goal, NAMES, Tolerances.defaults(6))
    assert e.value.code == code and text in str(e.value)


def test_a_violation_names_the_first_joint_past_its_tolerance_and_0_is_not_checked() -> None:
    pos, vel = np.array([0.0, 0.01, 0.0]), np.array([0.0, 0.0, 0.1])
    names = ["a", "b", "c"]
    assert violation(names, np.array([5.0, 0.005, 0.0]), np.zeros(3), pos, vel) is None
    assert violation(names, np.array([0.0, -0.02, 0.0]), np.zeros(3), pos, vel) == \
        "joint 'b': position error -0.0200 rad is past the tolerance 0.01 rad"
    assert "joint 'c': velocity error +0.2000 rad/s" in violation(names, np.zeros(3), np.array([0, 0, 0.2]), pos, vel)


# -- sizes, from the bytes ---------------------------------------------------------------------------
def full_points(n: int, joints: int) -> list[msgs.JointTrajectoryPoint]:
    """``n`` points with every field filled (the most bytes a trajectory akarm takes can have)."""
    return [msgs.JointTrajectoryPoint([0.1] * joints, [0.0] * joints, [0.0] * joints, [0.0] * joints,
                                      msgs.Duration(k + 1, 0)) for k in range(n)]


def test_the_largest_trajectory_akarm_takes_passes_the_size_check_and_one_more_point_does_not() -> None:
    msg = traj(NAMES, full_points(MAX_TRAJECTORY_POINTS, len(NAMES)))
    msg.header.frame_id = "world" * 1000
    data = msg.serialize()
    assert len(data) <= max_message_bytes(len(NAMES))
    check_size(data, 4, NAMES)
    msg.points.append(msg.points[-1])
    with pytest.raises(TrajectoryRefused, match="10001 points, more than the 10000") as e:
        check_size(msg.serialize(), 4, NAMES)
    assert e.value.code == INVALID_GOAL


@pytest.mark.parametrize("frame_id", ["", "a", "ab", "abc", "abcd", "map" * 7])
@pytest.mark.parametrize("names", [["elbow"], ["wrist_roll", "elbow", "shoulder_pan"], NAMES])
def test_the_points_are_counted_from_the_bytes_after_any_frame_id_and_names(frame_id: str, names: list[str]) -> None:
    n = MAX_TRAJECTORY_POINTS + 1
    msg = msgs.JointTrajectory(msgs.Header(msgs.Time(3, 4), frame_id), names,
                               [point([0.0] * len(names), 1.0)] * n)
    with pytest.raises(TrajectoryRefused, match=f"{n} points"):
        check_size(msg.serialize(), 4, NAMES)
    goal = at.SendGoalRequest(1, 2, at.UUID(list(range(16))), at.FollowJointTrajectoryGoal(msg)).serialize()
    with pytest.raises(TrajectoryRefused, match=f"{n} points"):
        check_size(goal, 36, NAMES)  # the trajectory after the request header and the goal ID
    msg.points = msg.points[:3]
    check_size(msg.serialize(), 4, NAMES)


def test_too_many_bytes_or_names_are_refused_from_the_size_alone() -> None:
    limit = max_message_bytes(len(NAMES))
    with pytest.raises(TrajectoryRefused, match=f"{limit + 4} bytes, more than the {limit}") as e:
        check_size(bytes(limit + 4), 4, NAMES)
    assert e.value.code == INVALID_GOAL and e.value.fix
    msg = traj([f"j{k}" for k in range(100_000)], [])
    with pytest.raises(TrajectoryRefused, match="names 100000 joints; this arm has 6") as e:
        check_size(msg.serialize(), 4, NAMES)
    assert e.value.code == INVALID_JOINTS
    check_size(traj(NAMES, [point([0.0] * 6, 1.0)]).serialize()[:30], 4, NAMES)  # cut short: the decoder's
