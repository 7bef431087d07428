"""The DDS types of ``control_msgs/action/FollowJointTrajectory``, ``control_msgs/action/GripperCommand`` and
of ``action_msgs``, as ROS 2 lays them out.

A ROS 2 action ``pkg/action/Name`` is three services and two topics (rcl_action ``names.c``); their
types are the ``.action`` file's three parts wrapped in implicit structs (rosidl):

=================================  ===============================================================
``Name_SendGoal_Request_``          ``unique_identifier_msgs/UUID goal_id``, ``Name_Goal goal``
``Name_SendGoal_Response_``         ``bool accepted``, ``builtin_interfaces/Time stamp``
``Name_GetResult_Request_``         ``goal_id``
``Name_GetResult_Response_``        ``int8 status``, ``Name_Result result``
``Name_FeedbackMessage_``           ``goal_id``, ``Name_Feedback feedback``
``action_msgs::srv::CancelGoal_*``  the cancel service; ``action_msgs/msg/GoalStatusArray``: the status topic
=================================  ===============================================================

Service parts carry rmw_cyclonedds_cpp's request header (``guid``, ``seq``) first, as
:class:`~akarm.ros.msgs.TriggerRequest` does (``docs/ros2.md``).

control_msgs' goal and result are the same on humble (4.8), jazzy (5.8) and rolling (6.x); rolling's
feedback adds ``int32 index`` after ``error`` and ``int32 multi_dof_index`` at the end
(:func:`feedback_message_type`). ``JointTolerance`` has no ``effort`` on any of them.
"""

# no `from __future__ import annotations`: cyclonedds reads the field types at run time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import cyclonedds.idl.annotations as annotate
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int8, int32, int64, uint16, uint64

from akarm.errors import ArgumentError
from akarm.ros.msgs import Duration, Header, JointTrajectory, JointTrajectoryPoint, Time

if TYPE_CHECKING:  # for a type checker a sequence or an array is a list; cyclonedds reads its own at run time
    sequence = list
    uint8_16 = list[int]
else:
    from cyclonedds.idl.types import array, sequence, uint8

    uint8_16 = array[uint8, 16]

__all__ = [
    "DISTROS",
    "UUID",
    "CancelGoalRequest",
    "CancelGoalResponse",
    "FeedbackHumble",
    "FeedbackMessageHumble",
    "FeedbackMessageRolling",
    "FeedbackRolling",
    "FollowJointTrajectoryGoal",
    "FollowJointTrajectoryResult",
    "GetResultRequest",
    "GetResultResponse",
    "GoalInfo",
    "GoalStatus",
    "GoalStatusArray",
    "GripperCommand",
    "GripperCommandFeedback",
    "GripperCommandGoal",
    "GripperCommandResult",
    "GripperFeedbackMessage",
    "GripperGetResultRequest",
    "GripperGetResultResponse",
    "GripperSendGoalRequest",
    "GripperSendGoalResponse",
    "JointComponentTolerance",
    "JointTolerance",
    "MultiDOFJointTrajectory",
    "MultiDOFJointTrajectoryPoint",
    "Quaternion",
    "SendGoalRequest",
    "SendGoalResponse",
    "Transform",
    "Twist",
    "Vector3",
    "check_distro",
    "feedback_message_type",
]

#: The ROS 2 distributions whose message layouts akarm speaks (``--ros-distro``); jazzy's are humble's.
DISTROS = ("humble", "jazzy", "rolling")
_FJT = "control_msgs::action::dds_::FollowJointTrajectory_"


def check_distro(distro: str) -> str:
    """``distro`` if akarm speaks its layouts, else :class:`~akarm.ArgumentError`."""
    if distro not in DISTROS:
        raise ArgumentError(f"unknown ROS 2 distribution {distro!r}",
                            fix="use humble, jazzy or rolling (--ros-distro; the layouts of kilted are rolling's)")
    return distro


def _zeros16() -> list[int]:
    return [0] * 16


@dataclass
@annotate.final
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: uint8_16 = field(default_factory=_zeros16)


@dataclass
@annotate.final
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID = field(default_factory=UUID)
    stamp: Time = field(default_factory=Time)


@dataclass
@annotate.final
class GoalStatus(IdlStruct, typename="action_msgs::msg::dds_::GoalStatus_"):
    goal_info: GoalInfo = field(default_factory=GoalInfo)
    status: int8 = 0  # UNKNOWN 0, ACCEPTED 1, EXECUTING 2, CANCELING 3, SUCCEEDED 4, CANCELED 5, ABORTED 6


@dataclass
@annotate.final
class GoalStatusArray(IdlStruct, typename="action_msgs::msg::dds_::GoalStatusArray_"):
    status_list: sequence[GoalStatus] = field(default_factory=list)


@dataclass
@annotate.final
class CancelGoalRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    guid: uint64 = 0  # rmw_cyclonedds_cpp's request header
    seq: int64 = 0
    goal_info: GoalInfo = field(default_factory=GoalInfo)


@dataclass
@annotate.final
class CancelGoalResponse(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    guid: uint64 = 0
    seq: int64 = 0
    return_code: int8 = 0  # ERROR_NONE 0, ERROR_REJECTED 1, ERROR_UNKNOWN_GOAL_ID 2, ERROR_GOAL_TERMINATED 3
    goals_canceling: sequence[GoalInfo] = field(default_factory=list)


# -- geometry_msgs, trajectory_msgs: the multi-DOF trajectory of the goal (akarm's arms have no such joint)
@dataclass
@annotate.final
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
@annotate.final
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
@annotate.final
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
@annotate.final
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
@annotate.final
class MultiDOFJointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectoryPoint_"):
    transforms: sequence[Transform] = field(default_factory=list)
    velocities: sequence[Twist] = field(default_factory=list)
    accelerations: sequence[Twist] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
@annotate.final
class MultiDOFJointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: sequence[str] = field(default_factory=list)
    points: sequence[MultiDOFJointTrajectoryPoint] = field(default_factory=list)


# -- control_msgs --------------------------------------------------------------------------------
@dataclass
@annotate.final
class JointTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointTolerance_"):
    name: str = ""
    position: float64 = 0.0  # 0: the server's default; -1: none; rad
    velocity: float64 = 0.0  # rad/s
    acceleration: float64 = 0.0  # rad/s²


@dataclass
@annotate.final
class JointComponentTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointComponentTolerance_"):
    joint_name: str = ""
    component: uint16 = 0  # X_AXIS 1, Y_AXIS 2, Z_AXIS 3, TRANSLATION 4, ROTATION 5
    position: float64 = 0.0
    velocity: float64 = 0.0
    acceleration: float64 = 0.0


@dataclass
@annotate.final
class FollowJointTrajectoryGoal(IdlStruct, typename=_FJT + "Goal_"):
    trajectory: JointTrajectory = field(default_factory=JointTrajectory)
    multi_dof_trajectory: MultiDOFJointTrajectory = field(default_factory=MultiDOFJointTrajectory)
    path_tolerance: sequence[JointTolerance] = field(default_factory=list)
    component_path_tolerance: sequence[JointComponentTolerance] = field(default_factory=list)
    goal_tolerance: sequence[JointTolerance] = field(default_factory=list)
    component_goal_tolerance: sequence[JointComponentTolerance] = field(default_factory=list)
    goal_time_tolerance: Duration = field(default_factory=Duration)


@dataclass
@annotate.final
class FollowJointTrajectoryResult(IdlStruct, typename=_FJT + "Result_"):
    error_code: int32 = 0  # SUCCESSFUL 0, INVALID_GOAL -1, INVALID_JOINTS -2, OLD_HEADER_TIMESTAMP -3,
    error_string: str = ""  # PATH_TOLERANCE_VIOLATED -4, GOAL_TOLERANCE_VIOLATED -5


@dataclass
@annotate.final
class FeedbackHumble(IdlStruct, typename=_FJT + "Feedback_"):
    """Humble's and jazzy's feedback (control_msgs 4.x, 5.x)."""

    header: Header = field(default_factory=Header)
    joint_names: sequence[str] = field(default_factory=list)
    desired: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    actual: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    error: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    multi_dof_joint_names: sequence[str] = field(default_factory=list)
    multi_dof_desired: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_actual: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_error: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)


@dataclass
@annotate.final
class FeedbackRolling(IdlStruct, typename=_FJT + "Feedback_"):
    """Rolling's feedback (control_msgs 6.x): ``index`` and ``multi_dof_index``, the points in use."""

    header: Header = field(default_factory=Header)
    joint_names: sequence[str] = field(default_factory=list)
    desired: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    actual: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    error: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    index: int32 = 0
    multi_dof_joint_names: sequence[str] = field(default_factory=list)
    multi_dof_desired: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_actual: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_error: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_index: int32 = 0


@dataclass
@annotate.final
class FeedbackMessageHumble(IdlStruct, typename=_FJT + "FeedbackMessage_"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: FeedbackHumble = field(default_factory=FeedbackHumble)


@dataclass
@annotate.final
class FeedbackMessageRolling(IdlStruct, typename=_FJT + "FeedbackMessage_"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: FeedbackRolling = field(default_factory=FeedbackRolling)


@dataclass
@annotate.final
class SendGoalRequest(IdlStruct, typename=_FJT + "SendGoal_Request_"):
    guid: uint64 = 0  # rmw_cyclonedds_cpp's request header
    seq: int64 = 0
    goal_id: UUID = field(default_factory=UUID)
    goal: FollowJointTrajectoryGoal = field(default_factory=FollowJointTrajectoryGoal)


@dataclass
@annotate.final
class SendGoalResponse(IdlStruct, typename=_FJT + "SendGoal_Response_"):
    guid: uint64 = 0
    seq: int64 = 0
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
@annotate.final
class GetResultRequest(IdlStruct, typename=_FJT + "GetResult_Request_"):
    guid: uint64 = 0
    seq: int64 = 0
    goal_id: UUID = field(default_factory=UUID)


@dataclass
@annotate.final
class GetResultResponse(IdlStruct, typename=_FJT + "GetResult_Response_"):
    guid: uint64 = 0
    seq: int64 = 0
    status: int8 = 0
    result: FollowJointTrajectoryResult = field(default_factory=FollowJointTrajectoryResult)


def feedback_message_type(distro: str) -> Any:
    """The FeedbackMessage type of ``distro`` (humble and jazzy: one layout; rolling: with the indices)."""
    return FeedbackMessageRolling if check_distro(distro) == "rolling" else FeedbackMessageHumble


# -- control_msgs/action/GripperCommand ------------------------------------------------------------
# The same on humble (4.8), jazzy (5.8) and rolling (6.x): control_msgs/msg/GripperCommand is
# ``float64 position`` (m between the jaws), ``float64 max_effort`` (N); the result and the feedback
# are ``position`` (m), ``effort`` (N), ``stalled``, ``reached_goal``.
_GC = "control_msgs::action::dds_::GripperCommand_"


@dataclass
@annotate.final
class GripperCommand(IdlStruct, typename="control_msgs::msg::dds_::GripperCommand_"):
    position: float64 = 0.0  # m: the width asked
    max_effort: float64 = 0.0  # N: the most the jaws may squeeze (0: the server's default)


@dataclass
@annotate.final
class GripperCommandGoal(IdlStruct, typename=_GC + "Goal_"):
    command: GripperCommand = field(default_factory=GripperCommand)


@dataclass
@annotate.final
class GripperCommandResult(IdlStruct, typename=_GC + "Result_"):
    position: float64 = 0.0  # m
    effort: float64 = 0.0  # N
    stalled: bool = False  # stopped short of the goal (on an object)
    reached_goal: bool = False  # within the goal tolerance of the width asked


@dataclass
@annotate.final
class GripperCommandFeedback(IdlStruct, typename=_GC + "Feedback_"):
    position: float64 = 0.0
    effort: float64 = 0.0
    stalled: bool = False
    reached_goal: bool = False


@dataclass
@annotate.final
class GripperFeedbackMessage(IdlStruct, typename=_GC + "FeedbackMessage_"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: GripperCommandFeedback = field(default_factory=GripperCommandFeedback)


@dataclass
@annotate.final
class GripperSendGoalRequest(IdlStruct, typename=_GC + "SendGoal_Request_"):
    guid: uint64 = 0  # rmw_cyclonedds_cpp's request header
    seq: int64 = 0
    goal_id: UUID = field(default_factory=UUID)
    goal: GripperCommandGoal = field(default_factory=GripperCommandGoal)


@dataclass
@annotate.final
class GripperSendGoalResponse(IdlStruct, typename=_GC + "SendGoal_Response_"):
    guid: uint64 = 0
    seq: int64 = 0
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
@annotate.final
class GripperGetResultRequest(IdlStruct, typename=_GC + "GetResult_Request_"):
    guid: uint64 = 0
    seq: int64 = 0
    goal_id: UUID = field(default_factory=UUID)


@dataclass
@annotate.final
class GripperGetResultResponse(IdlStruct, typename=_GC + "GetResult_Response_"):
    guid: uint64 = 0
    seq: int64 = 0
    status: int8 = 0
    result: GripperCommandResult = field(default_factory=GripperCommandResult)
