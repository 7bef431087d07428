"""The GripperCommand action's types against rosbags (control_msgs' definitions, tests/rosdefs.py): the
goal, the result, the feedback and the services' parts, byte for byte, both ways; and how a goal ends."""

from __future__ import annotations

import struct

import numpy as np
import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags.typesys")

from akarm.control.gripper import GripperState
from akarm.ros import action_types as at
from akarm.ros import msgs
from akarm.ros.action import ABORTED, SUCCEEDED
from akarm.ros.gripper import GOAL_TOLERANCE, STALL_TIMEOUT, gripper_action_name, outcome

from ..rosdefs import GC, serialize, typestore

HEADER = struct.pack("<Qq", 0x0123456789ABCDEF, 42)  # rmw_cyclonedds_cpp's request header: guid, seq


@pytest.mark.parametrize("distro", ["humble", "jazzy", "rolling"])
def test_a_gripper_goal_request_is_the_header_then_what_rosbags_writes(distro: str) -> None:
    ours = at.GripperSendGoalRequest(0x0123456789ABCDEF, 42, at.UUID(list(range(16))),
                                     at.GripperCommandGoal(at.GripperCommand(0.03, 20.0))).serialize()
    assert ours[:20] == b"\x00\x01\x00\x00" + HEADER
    # goal_id (16 bytes), then position and max_effort, 8-aligned from the payload's start (after the header)
    assert ours[20:] == bytes(range(16)) + struct.pack("<dd", 0.03, 20.0)
    store = typestore(distro)
    theirs = store.deserialize_cdr(ours[:4] + ours[20:], f"{GC}_SendGoal_Request")
    assert bytes(theirs.goal_id.uuid) == bytes(range(16))
    assert theirs.goal.command.position == 0.03 and theirs.goal.command.max_effort == 20.0
    assert serialize(distro, theirs, f"{GC}_SendGoal_Request") == ours[:4] + ours[20:]
    back = at.GripperSendGoalRequest.deserialize(ours)  # and ours reads what rosbags writes
    assert back.goal.command.position == 0.03 and back.seq == 42


@pytest.mark.parametrize("distro", ["humble", "jazzy", "rolling"])
def test_the_gripper_replies_and_feedback_are_what_rosbags_writes(distro: str) -> None:
    store = typestore(distro)
    T = store.types
    cases = [
        (at.GripperSendGoalResponse(1, 2, True, msgs.Time(5, 6)), f"{GC}_SendGoal_Response",
         T[f"{GC}_SendGoal_Response"](accepted=True, stamp=T["builtin_interfaces/msg/Time"](sec=5, nanosec=6))),
        (at.GripperGetResultResponse(1, 2, 4, at.GripperCommandResult(0.0301, 19.5, True, False)),
         f"{GC}_GetResult_Response",
         T[f"{GC}_GetResult_Response"](status=4, result=T[f"{GC}_Result"](position=0.0301, effort=19.5,
                                                                         stalled=True, reached_goal=False))),
    ]
    for ours, name, theirs in cases:
        raw = ours.serialize()
        assert raw[4:20] == struct.pack("<Qq", 1, 2)
        assert raw[:4] + raw[20:] == serialize(distro, theirs, name), name
        assert store.deserialize_cdr(raw[:4] + raw[20:], name) == theirs
    req = at.GripperGetResultRequest(1, 2, at.UUID(list(range(16)))).serialize()
    assert bytes(store.deserialize_cdr(req[:4] + req[20:], f"{GC}_GetResult_Request").goal_id.uuid) == bytes(range(16))
    fb = at.GripperFeedbackMessage(at.UUID([9] * 16), at.GripperCommandFeedback(0.08, 0.25, False, True)).serialize()
    theirs_fb = T[f"{GC}_FeedbackMessage"](
        goal_id=T["unique_identifier_msgs/msg/UUID"](uuid=np.full(16, 9, dtype=np.uint8)),
        feedback=T[f"{GC}_Feedback"](position=0.08, effort=0.25, stalled=False, reached_goal=True))
    assert fb == serialize(distro, theirs_fb, f"{GC}_FeedbackMessage")
    # uuid, then 8-aligned position and effort, then the two bools
    assert fb[4:] == bytes([9] * 16) + struct.pack("<dd??", 0.08, 0.25, False, True)


def test_the_gripper_types_are_named_as_rmw_cyclonedds_cpp_names_them() -> None:
    assert at.GripperSendGoalRequest.__idl_typename__ == "control_msgs::action::dds_::GripperCommand_SendGoal_Request_"
    assert at.GripperFeedbackMessage.__idl_typename__ == "control_msgs::action::dds_::GripperCommand_FeedbackMessage_"
    assert at.GripperCommand.__idl_typename__ == "control_msgs::msg::dds_::GripperCommand_"


# -- how a goal ends -----------------------------------------------------------------------------------
def reading(width: float, velocity: float = 0.0, force: float = 0.0, grasped: bool = False,
            moving: bool = False) -> GripperState:
    return GripperState(width, velocity, force, grasped, 0.0, moving, 30.0)


def test_a_goal_is_reached_when_the_jaws_rest_within_the_tolerance() -> None:
    assert outcome(reading(0.0795), 0.08, 5.0, 5.0) == (SUCCEEDED, False, True)
    assert outcome(reading(0.0795, 0.02, moving=True), 0.08, None, 5.0) is None  # still on its way
    assert outcome(reading(0.08 - GOAL_TOLERANCE * 1.01), 0.08, None, 5.0) is None
    # still reading "moving" but at rest for the stall timeout within the tolerance: reached
    assert outcome(reading(0.0799, moving=True), 0.08, 1.0, 1.0 + STALL_TIMEOUT) == (SUCCEEDED, False, True)


def test_a_grasp_succeeds_stalled_and_a_jam_aborts_stalled() -> None:
    on_object = reading(0.0301, force=19.0, grasped=True)
    assert outcome(on_object, 0.0, 2.0, 2.0) == (SUCCEEDED, True, False)  # allow_stalling: the grasp is the goal
    jam = reading(0.05)
    assert outcome(jam, 0.0, 2.0, 2.0 + STALL_TIMEOUT * 0.99) is None
    assert outcome(jam, 0.0, 2.0, 2.0 + STALL_TIMEOUT) == (ABORTED, True, False)


def test_the_action_is_named_as_ros2_controllers_names_it() -> None:
    assert gripper_action_name("/gripper_controller/") == "gripper_controller/gripper_cmd"
