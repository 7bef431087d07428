"""ROS 2 message definitions the tests decode akarm's action with, independently of akarm's own types.

rosbags ships the common ROS 2 messages (``action_msgs``, ``trajectory_msgs``, ``rmw_dds_common``, ...)
but no ``control_msgs`` and no service or action types. Here ``control_msgs``' ``JointTolerance``,
``JointComponentTolerance``, ``GripperCommand``, ``FollowJointTrajectory.action`` and
``GripperCommand.action`` are written out from their definitions (the fields of
ros-controls/control_msgs at humble 4.8.0, jazzy 5.8.0 and master 6.8.0), and the implicit structs
of an action and of ``action_msgs/srv/CancelGoal`` (rosidl) by hand, then registered
in rosbags' typestore of the distribution: :func:`typestore`.
"""

from __future__ import annotations

from functools import cache
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = ["CANCEL", "FJT", "GC", "STORES", "serialize", "typestore"]

#: The typestore each distribution's test uses (rosbags has no rolling: kilted's is the newest).
STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY, "rolling": Stores.ROS2_KILTED}
FJT = "control_msgs/action/FollowJointTrajectory"
GC = "control_msgs/action/GripperCommand"  # the same on every distribution
CANCEL = "action_msgs/msg/CancelGoal"  # action_msgs/srv/CancelGoal's parts (rosbags keys every type as a msg)

JOINT_TOLERANCE = """
string name
float64 position
float64 velocity
float64 acceleration
"""

JOINT_COMPONENT_TOLERANCE = """
uint16 X_AXIS=1
uint16 Y_AXIS=2
uint16 Z_AXIS=3
uint16 TRANSLATION=4
uint16 ROTATION=5
string joint_name
uint16 component
float64 position
float64 velocity
float64 acceleration
"""

GOAL = """
trajectory_msgs/JointTrajectory trajectory
trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory
control_msgs/JointTolerance[] path_tolerance
control_msgs/JointComponentTolerance[] component_path_tolerance
control_msgs/JointTolerance[] goal_tolerance
control_msgs/JointComponentTolerance[] component_goal_tolerance
builtin_interfaces/Duration goal_time_tolerance
"""

RESULT = """
int32 SUCCESSFUL=0
int32 INVALID_GOAL=-1
int32 INVALID_JOINTS=-2
int32 OLD_HEADER_TIMESTAMP=-3
int32 PATH_TOLERANCE_VIOLATED=-4
int32 GOAL_TOLERANCE_VIOLATED=-5
int32 error_code
string error_string
"""

FEEDBACK = {  # humble and jazzy: control_msgs 4.x/5.x; rolling: 6.x adds the two indices
    "humble": """
std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
""",
    "rolling": """
std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
int32 index
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
int32 multi_dof_index
""",
}
FEEDBACK["jazzy"] = FEEDBACK["humble"]

GRIPPER_COMMAND = """
float64 position
float64 max_effort
"""

GRIPPER_STATE = """
float64 position
float64 effort
bool stalled
bool reached_goal
"""

# the implicit structs (rosidl): a service's parts, an action's services and its feedback message
IMPLICIT = {
    f"{FJT}_SendGoal_Request": f"unique_identifier_msgs/UUID goal_id\n{FJT}_Goal goal\n",
    f"{FJT}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp\n",
    f"{FJT}_GetResult_Request": "unique_identifier_msgs/UUID goal_id\n",
    f"{FJT}_GetResult_Response": f"int8 status\n{FJT}_Result result\n",
    f"{FJT}_FeedbackMessage": f"unique_identifier_msgs/UUID goal_id\n{FJT}_Feedback feedback\n",
    f"{GC}_SendGoal_Request": f"unique_identifier_msgs/UUID goal_id\n{GC}_Goal goal\n",
    f"{GC}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp\n",
    f"{GC}_GetResult_Request": "unique_identifier_msgs/UUID goal_id\n",
    f"{GC}_GetResult_Response": f"int8 status\n{GC}_Result result\n",
    f"{GC}_FeedbackMessage": f"unique_identifier_msgs/UUID goal_id\n{GC}_Feedback feedback\n",
    f"{CANCEL}_Request": "action_msgs/GoalInfo goal_info\n",
    f"{CANCEL}_Response": "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
                                           "int8 ERROR_GOAL_TERMINATED=3\nint8 return_code\n"
                                           "action_msgs/GoalInfo[] goals_canceling\n",
}


@cache
def typestore(distro: str) -> Any:
    """rosbags' typestore of ``distro`` with FollowJointTrajectory, its implicit structs and CancelGoal."""
    store = get_typestore(STORES[distro])
    types: dict[str, Any] = {}
    for name, text in (("control_msgs/msg/JointTolerance", JOINT_TOLERANCE),
                       ("control_msgs/msg/JointComponentTolerance", JOINT_COMPONENT_TOLERANCE),
                       (f"{FJT}_Goal", GOAL), (f"{FJT}_Result", RESULT), (f"{FJT}_Feedback", FEEDBACK[distro]),
                       ("control_msgs/msg/GripperCommand", GRIPPER_COMMAND),
                       (f"{GC}_Goal", "control_msgs/GripperCommand command\n"), (f"{GC}_Result", GRIPPER_STATE),
                       (f"{GC}_Feedback", GRIPPER_STATE),
                       *IMPLICIT.items()):
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def serialize(distro: str, msg: Any, name: str) -> bytes:
    """``msg`` (a rosbags message of type ``name``) in CDR, as rosbags writes it."""
    return bytes(typestore(distro).serialize_cdr(msg, name))
