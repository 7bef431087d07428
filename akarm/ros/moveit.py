"""What a MoveIt 2 setup needs to drive ``akarm serve``: ``akarm ros-config ROBOT.yaml``.

- ``moveit_controllers.yaml``: ``MoveItSimpleControllerManager`` with one controller of type
  ``FollowJointTrajectory``, its ``action_ns`` and the arm's joints: MoveIt's action client is then
  ``CONTROLLER/follow_joint_trajectory``, the server's action (moveit2's
  ``moveit_simple_controller_manager``: the action name is the controller's name, ``/``, ``action_ns``);
  and, for a robot with a gripper, ``gripper_controller`` of type ``GripperCommand`` (``action_ns``
  ``gripper_cmd``): with two finger joints in the robot file, ``parallel: true`` and those two (MoveIt
  sends the sum of their positions, each half the width: the width), else the gripper's own name
  (``joint_states``' width, m) as its one joint;
- ``joint_limits.yaml``: each joint's position range, velocity, acceleration and jerk from the robot
  file, so that MoveIt times its plans within the limits the server's planner keeps (a point past
  them is refused);
- ``akarm_ros.yaml``: the URDF, the action's and ``joint_states``' full names, and, for a server in
  a namespace, the remaps a ``move_group`` in the root namespace needs (or run ``move_group`` in the
  same namespace: then it needs none).

Text only: this module imports nothing of DDS.
"""

from __future__ import annotations

from typing import Any

import yaml

from akarm.config import RobotConfig

__all__ = ["FILES", "GRIPPER_CONTROLLER", "gripper_controller", "moveit_config"]

#: The files :func:`moveit_config` makes, in order.
FILES = ("moveit_controllers.yaml", "joint_limits.yaml", "akarm_ros.yaml")


def _full(namespace: str, name: str) -> str:
    return "/" + "/".join(p for p in (*namespace.strip("/").split("/"), *name.strip("/").split("/")) if p)


def _dump(comment: str, doc: dict[str, Any]) -> str:
    head = "".join(f"# {line}\n" if line else "#\n" for line in comment.splitlines())
    return head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=False)


#: The gripper's controller (its action: ``gripper_controller/gripper_cmd``, :mod:`akarm.ros.gripper`).
GRIPPER_CONTROLLER = "gripper_controller"


def gripper_controller(config: RobotConfig) -> dict[str, Any] | None:
    """moveit_simple_controller_manager's entry for ``config``'s gripper (None without one)."""
    g = config.gripper
    if g is None:
        return None
    entry: dict[str, Any] = {"type": "GripperCommand", "action_ns": "gripper_cmd", "default": True}
    if len(g.fingers) == 2:
        entry.update(joints=list(g.fingers), parallel=True)
    else:
        entry.update(joints=[g.name], command_joint=g.name)
    entry["max_effort"] = 0.0  # the server's default force (a fraction of the robot file's force_limit)
    return entry


def moveit_config(config: RobotConfig, *, namespace: str = "", controller: str = "arm_controller") -> dict[str, str]:
    """The files of :data:`FILES` (name → YAML text) for ``config`` served by ``akarm serve`` with
    ``--namespace namespace --controller controller``."""
    names = list(config.joint_names)
    source = str(config.source) if config.source else config.name
    controllers: dict[str, Any] = {
        "moveit_controller_manager": "moveit_simple_controller_manager/MoveItSimpleControllerManager",
        "moveit_simple_controller_manager": {
            "controller_names": [controller],
            controller: {"type": "FollowJointTrajectory", "action_ns": "follow_joint_trajectory", "default": True,
                         "joints": names},
        },
    }
    gripper = gripper_controller(config)
    if gripper is not None:
        manager = controllers["moveit_simple_controller_manager"]
        manager["controller_names"].append(GRIPPER_CONTROLLER)
        manager[GRIPPER_CONTROLLER] = gripper
    limits: dict[str, Any] = {}
    for j in config.joints:
        lim = j.limits
        limits[j.name] = {"has_position_limits": True, "min_position": float(lim.lower),
                          "max_position": float(lim.upper), "has_velocity_limits": True,
                          "max_velocity": float(lim.velocity), "has_acceleration_limits": True,
                          "max_acceleration": float(lim.acceleration), "has_jerk_limits": True,
                          "max_jerk": float(lim.jerk)}
    joint_limits = {"default_velocity_scaling_factor": 0.1, "default_acceleration_scaling_factor": 0.1,
                    "joint_limits": limits}
    action = _full(namespace, f"{controller}/follow_joint_trajectory")
    states = _full(namespace, "joint_states")
    serve = f"akarm serve {source}" + (f" --namespace {namespace.strip('/')}" if namespace.strip("/") else "") + \
        (f" --controller {controller}" if controller != "arm_controller" else "")
    about: dict[str, Any] = {"robot": config.name, "urdf": str(config.urdf), "serve": serve, "action": action,
                             "action_type": "control_msgs/action/FollowJointTrajectory", "joint_states": states,
                             "joints": names}
    bases = [f"/{controller}/follow_joint_trajectory/_action/"]
    if gripper is not None:
        about["gripper_action"] = _full(namespace, f"{GRIPPER_CONTROLLER}/gripper_cmd")
        about["gripper_action_type"] = "control_msgs/action/GripperCommand"
        about["gripper_joints"] = gripper["joints"]
        bases.append(f"/{GRIPPER_CONTROLLER}/gripper_cmd/_action/")
    if namespace.strip("/"):
        about["move_group_remappings"] = [["joint_states", states]] + [
            [base + part, _full(namespace, base + part)] for base in bases
            for part in ("send_goal", "cancel_goal", "get_result", "feedback", "status")]
    return {
        "moveit_controllers.yaml": _dump(
            f"MoveIt's controllers for {config.name}, served by `{serve}` (akarm ros-config).\n"
            f"The action MoveIt sends plans to: {action}", controllers),
        "joint_limits.yaml": _dump(
            f"Joint limits of {config.name} for MoveIt, from {source} (rad, rad/s, rad/s², rad/s³; akarm ros-config).\n"
            "akarm serve refuses a trajectory with a point or a velocity past them. The scaling factors are\n"
            "MoveIt's defaults for a plan: raise them toward 1.0 once the arm moves as it should.", joint_limits),
        "akarm_ros.yaml": _dump(
            f"How MoveIt reaches akarm serve for {config.name} (akarm ros-config).\n"
            "robot_description: the URDF below. joint_states: the topic the server publishes.\n"
            "move_group_remappings (a server in a namespace): for a move_group in the root namespace\n"
            "(a launch file's remappings=[...], or -r FROM:=TO); a move_group in the server's namespace needs none.",
            about),
    }
