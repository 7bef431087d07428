"""The ROS 2 messages akarm speaks, as Cyclone DDS types named the way ROS 2 names them on DDS.

ROS 2 type ``pkg/msg/Name`` is the DDS type ``pkg::msg::dds_::Name_``; fields, their order and
their types are those of the ``.msg`` files (final extensibility, plain CDR, XCDR1), so these
serialize to the bytes rmw_cyclonedds_cpp writes (``tests/unit/test_ros_msgs.py`` checks them against
rosbags' ROS 2 typestore).

Service requests and replies carry rmw_cyclonedds_cpp's request header in front of the fields of
the ``.srv`` part: ``guid`` (uint64) and ``seq`` (int64); see ``docs/ros2.md``.
"""

# no `from __future__ import annotations`: cyclonedds reads the field types at run time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cyclonedds.idl.annotations as annotate
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import byte, float64, int32, int64, uint8, uint32, uint64

if TYPE_CHECKING:  # for a type checker a sequence is a list; cyclonedds reads its own at run time
    sequence = list
else:
    from cyclonedds.idl.types import sequence

__all__ = [
    "DiagnosticArray",
    "DiagnosticStatus",
    "Duration",
    "Header",
    "JointState",
    "JointTrajectory",
    "JointTrajectoryPoint",
    "KeyValue",
    "Time",
    "TriggerRequest",
    "TriggerResponse",
    "Twist",
    "TwistStamped",
    "Vector3",
]


@dataclass
@annotate.final
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0

    @classmethod
    def from_seconds(cls, t: float) -> "Time":
        """Seconds (e.g. ``time.time()``) as a Time."""
        ns = round(t * 1e9)
        return cls(ns // 1_000_000_000, ns % 1_000_000_000)

    def seconds(self) -> float:
        return self.sec + self.nanosec * 1e-9


@dataclass
@annotate.final
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: int32 = 0
    nanosec: uint32 = 0

    def seconds(self) -> float:
        return self.sec + self.nanosec * 1e-9


@dataclass
@annotate.final
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
@annotate.final
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)


@dataclass
@annotate.final
class JointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectoryPoint_"):
    positions: sequence[float64] = field(default_factory=list)
    velocities: sequence[float64] = field(default_factory=list)
    accelerations: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
@annotate.final
class JointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: sequence[str] = field(default_factory=list)
    points: sequence[JointTrajectoryPoint] = field(default_factory=list)


@dataclass
@annotate.final
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str = ""
    value: str = ""


@dataclass
@annotate.final
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: byte = 0  # OK 0, WARN 1, ERROR 2, STALE 3
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)


@dataclass
@annotate.final
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)


@dataclass
@annotate.final
class TriggerRequest(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    guid: uint64 = 0  # rmw_cyclonedds_cpp's request header: the client's request writer ...
    seq: int64 = 0  # ... and its request number
    structure_needs_at_least_one_member: uint8 = 0  # an empty ROS 2 message has this one field


@dataclass
@annotate.final
class TriggerResponse(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    guid: uint64 = 0  # copied from the request it answers
    seq: int64 = 0
    success: bool = False
    message: str = ""


@dataclass
@annotate.final
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
@annotate.final
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
@annotate.final
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    """What MoveIt Servo takes on its twist topic: m/s and rad/s, in ``header.frame_id``'s axes."""

    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)
