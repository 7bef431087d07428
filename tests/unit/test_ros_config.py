"""``akarm ros-config``: what MoveIt needs, from the robot file, as YAML that parses."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

pytest.importorskip("cyclonedds")  # the verb is in akarm.ros (the ros extra)

from akarm import load_robot
from akarm.cli import main
from akarm.ros.moveit import FILES, gripper_controller

from .conftest import ROBOTS

ARM6 = str(ROBOTS / "arm6.yaml")
CONFIG = load_robot(ARM6)


def test_the_printed_config_parses_and_names_the_joints_the_action_and_the_limits(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ros-config", ARM6]) == 0
    out = capsys.readouterr().out
    controllers, limits, about = yaml.safe_load_all(out)
    for name in FILES:
        assert f"# {name}\n" in out
    manager = controllers["moveit_simple_controller_manager"]
    assert controllers["moveit_controller_manager"] == "moveit_simple_controller_manager/MoveItSimpleControllerManager"
    assert manager["controller_names"] == ["arm_controller"]
    arm = manager["arm_controller"]
    assert arm["type"] == "FollowJointTrajectory" and arm["action_ns"] == "follow_joint_trajectory"
    assert arm["default"] is True and arm["joints"] == list(CONFIG.joint_names) and len(arm["joints"]) == 6
    for j in CONFIG.joints:
        lim = limits["joint_limits"][j.name]
        assert (lim["max_velocity"], lim["max_acceleration"], lim["max_jerk"]) == (
            j.limits.velocity, j.limits.acceleration, j.limits.jerk)
        assert (lim["min_position"], lim["max_position"]) == (j.limits.lower, j.limits.upper)
        assert lim["has_velocity_limits"] and lim["has_acceleration_limits"] and lim["has_jerk_limits"]
    assert limits["joint_limits"]["elbow"]["max_velocity"] == 2.5  # robots/arm6.yaml's own numbers
    assert about["action"] == "/arm_controller/follow_joint_trajectory"
    assert about["joint_states"] == "/joint_states" and Path(about["urdf"]) == CONFIG.urdf
    assert "move_group_remappings" not in about


def test_a_namespace_gives_the_full_names_and_the_remaps(tmp_path: Path) -> None:
    assert main(["ros-config", ARM6, "--namespace", "left", "--controller", "arm6_controller",
                 "--out", str(tmp_path / "moveit")]) == 0
    written = sorted(p.name for p in (tmp_path / "moveit").iterdir())
    assert written == sorted(FILES)
    about = yaml.safe_load((tmp_path / "moveit" / "akarm_ros.yaml").read_text())
    assert about["action"] == "/left/arm6_controller/follow_joint_trajectory"
    assert about["serve"].endswith("--namespace left --controller arm6_controller")
    remaps = dict(map(tuple, about["move_group_remappings"]))
    assert remaps["joint_states"] == "/left/joint_states"
    assert remaps["/arm6_controller/follow_joint_trajectory/_action/status"] == \
        "/left/arm6_controller/follow_joint_trajectory/_action/status"
    assert len(remaps) == 6
    ctl = yaml.safe_load((tmp_path / "moveit" / "moveit_controllers.yaml").read_text())
    assert ctl["moveit_simple_controller_manager"]["controller_names"] == ["arm6_controller"]


def test_a_name_ros_2_would_refuse_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ros-config", ARM6, "--namespace", "my-arm"]) == 1
    assert "not a valid ROS 2 name" in capsys.readouterr().err


def test_a_gripper_adds_moveits_gripper_command_controller(capsys: pytest.CaptureFixture[str]) -> None:
    arm6g = str(ROBOTS / "arm6g.yaml")
    assert main(["ros-config", arm6g, "--namespace", "left"]) == 0
    controllers, limits, about = yaml.safe_load_all(capsys.readouterr().out)
    manager = controllers["moveit_simple_controller_manager"]
    assert manager["controller_names"] == ["arm_controller", "gripper_controller"]
    # two fingers, each half the width: MoveIt's parallel gripper sends their sum, the width asked
    assert manager["gripper_controller"] == {"type": "GripperCommand", "action_ns": "gripper_cmd", "default": True,
                                             "joints": ["left_finger_joint", "right_finger_joint"], "parallel": True,
                                             "max_effort": 0.0}
    assert "gripper" not in limits["joint_limits"] and len(manager["arm_controller"]["joints"]) == 6
    assert about["gripper_action"] == "/left/gripper_controller/gripper_cmd"
    assert ["/gripper_controller/gripper_cmd/_action/send_goal",
            "/left/gripper_controller/gripper_cmd/_action/send_goal"] in about["move_group_remappings"]
    g = load_robot(arm6g).gripper
    assert g is not None
    one = gripper_controller(dataclasses.replace(load_robot(arm6g), gripper=dataclasses.replace(g, fingers=())))
    assert one is not None and one["joints"] == ["gripper"] and one["command_joint"] == "gripper"
    assert gripper_controller(CONFIG) is None
