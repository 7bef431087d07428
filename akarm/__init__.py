"""akarm: trajectory control for robot arms built from CubeMars AK actuators.

Describe the arm in a URDF and a YAML file, then::

    import akarm
    arm = akarm.Arm.from_yaml("robots/arm6.yaml")
    with arm:
        arm.enable()
        arm.move_to("home")

SI units (rad, rad/s, N·m, s) at every public interface. Every error akarm raises on purpose is an
:class:`akarm.AkarmError`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akarm import compiled
from akarm._version import __version__
from akarm.errors import (
    AkarmError,
    ArgumentError,
    BusError,
    BusLost,
    CollisionError,
    ConfigError,
    ConfigProblem,
    ConfigWarning,
    DeviationError,
    DriverReset,
    DuplicateCanId,
    FeedbackTimeout,
    ForeignTraffic,
    FrameError,
    ImplausibleFeedback,
    LimitError,
    LoopCrashed,
    LoopStall,
    ModelError,
    ModeMismatch,
    MotorFault,
    NotSettled,
    OverTemperature,
    ProtocolError,
    RecordingError,
    SafetyStop,
    SelfCollisionStop,
    SingularityError,
    StaleFeedback,
    StateError,
    StatusRateLow,
    StopLatched,
    TrackingError,
    TrajectoryError,
    TurnCountLost,
    UartBadCrc,
    UartError,
    UartNoise,
    UartPartialFrame,
    UartSilent,
    UnknownMotorError,
    UnreachableError,
    WiringError,
    WorkspaceExit,
)

compiled.choose_at_import()  # AKARM_PURE=1, or compiled modules older than their sources: pure Python

if TYPE_CHECKING:
    from akarm.arm import Arm, ArmState
    from akarm.config import RobotConfig
    from akarm.control.gripper import Gripper, GripperLog, GripperState
    from akarm.control.modes import Mode
    from akarm.control.motions import Motion
    from akarm.robotfile.load import load_robot
    from akarm.serving import ArmServer, serve

__all__ = [
    "AkarmError",
    "ArgumentError",
    "Arm",
    "ArmServer",
    "ArmState",
    "BusError",
    "BusLost",
    "CollisionError",
    "ConfigError",
    "ConfigProblem",
    "ConfigWarning",
    "DeviationError",
    "DriverReset",
    "DuplicateCanId",
    "FeedbackTimeout",
    "ForeignTraffic",
    "FrameError",
    "Gripper",
    "GripperLog",
    "GripperState",
    "ImplausibleFeedback",
    "LimitError",
    "LoopCrashed",
    "LoopStall",
    "Mode",
    "ModeMismatch",
    "ModelError",
    "Motion",
    "MotorFault",
    "NotSettled",
    "OverTemperature",
    "ProtocolError",
    "RecordingError",
    "RobotConfig",
    "SafetyStop",
    "SelfCollisionStop",
    "SingularityError",
    "StaleFeedback",
    "StateError",
    "StatusRateLow",
    "StopLatched",
    "TrackingError",
    "TrajectoryError",
    "TurnCountLost",
    "UartBadCrc",
    "UartError",
    "UartNoise",
    "UartPartialFrame",
    "UartSilent",
    "UnknownMotorError",
    "UnreachableError",
    "WiringError",
    "WorkspaceExit",
    "__version__",
    "load_robot",
    "serve",
]

# Heavy parts (Pinocchio, ruckig, python-can) load on first use, so `import akarm` and the codecs stay light.
_LAZY = {
    "Arm": ("akarm.arm", "Arm"),
    "ArmState": ("akarm.arm", "ArmState"),
    "Mode": ("akarm.control.modes", "Mode"),
    "Gripper": ("akarm.control.gripper", "Gripper"),
    "GripperState": ("akarm.control.gripper", "GripperState"),
    "GripperLog": ("akarm.control.gripper", "GripperLog"),
    "Motion": ("akarm.control.motions", "Motion"),
    "ArmServer": ("akarm.serving", "ArmServer"),
    "serve": ("akarm.serving", "serve"),
    "RobotConfig": ("akarm.config", "RobotConfig"),
    "load_robot": ("akarm.robotfile.load", "load_robot"),
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'akarm' has no attribute {name!r}")
