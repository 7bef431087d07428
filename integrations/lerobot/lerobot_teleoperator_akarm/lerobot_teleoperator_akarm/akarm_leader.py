"""``AkarmLeader``: an akarm arm in teach mode (its weight carried, a little damping, no stiffness), as
``akarm teleop`` uses its leader; a hand guides it and its joint positions are the action.

Its control loop runs in ``akarm serve``'s process (started here when none drives the leader's buses).
Teach mode belongs to this connection: if LeRobot exits or is killed, the server ends it and holds the
arm where the hand left it. A safety stop of the leader is raised from ``get_action`` (akarm's error,
its name and text).
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Any

from lerobot.teleoperators.teleoperator import Teleoperator
from lerobot_robot_akarm.robot_akarm import gripper_reading
from lerobot_robot_akarm.served import ServedArm

from .config_akarm_leader import AkarmLeaderConfig

__all__ = ["AkarmLeader"]


class AkarmLeader(Teleoperator):
    config_class = AkarmLeaderConfig
    name = "akarm_leader"

    def __init__(self, config: AkarmLeaderConfig) -> None:
        super().__init__(config)
        self.config = config
        if not config.robot_file:
            raise ValueError("--teleop.robot_file is needed: the leader's akarm robot file (YAML)")
        from akarm.robotfile.load import load_robot

        robot = load_robot(config.robot_file)
        own = tuple(robot.joint_names)
        names = tuple(config.joint_names) or own
        if len(names) != len(own):
            raise ValueError(f"--teleop.joint_names has {len(names)} names for the leader's {len(own)} joints")
        self.joint_names: tuple[str, ...] = names
        self.gripper = getattr(robot, "gripper", None) is not None
        self.arm: ServedArm | None = None

    @cached_property
    def action_features(self) -> dict[str, type]:
        keys = [f"{n}.pos" for n in self.joint_names] + (["gripper.pos"] if self.gripper else [])
        return dict.fromkeys(keys, float)

    @cached_property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self.arm is not None

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """Nothing to do: the robot file holds the zeros (``akarm zero``)."""

    def configure(self) -> None:
        """Nothing to do: teach mode starts at connect."""

    def connect(self, calibrate: bool = True) -> None:
        c = self.config
        self.arm = ServedArm(c.robot_file, c.interface, c.channel, profile=c.profile, stall_limit=c.stall_limit,
                              start=c.start_server)
        try:
            self.arm.call("ready")
            if self.gripper:  # let go (asked no force), so the hand opens and closes it, as akarm teleop does
                width = gripper_reading(self.arm.state())[0]
                stroke = float(self.arm.config.gripper.stroke)  # type: ignore[union-attr]
                self.arm.call("gripper_move", width=min(max(width, 0.0), stroke) if math.isfinite(width) else stroke,
                              force=0.0, wait=False)
            self.arm.call("teach", damping=c.damping)
        except BaseException:
            self.disconnect()
            raise

    def get_action(self) -> dict[str, Any]:
        if self.arm is None:
            raise RuntimeError(f"{self} is not connected")
        doc = self.arm.state()
        action: dict[str, Any] = {f"{n}.pos": float(q) for n, q in zip(self.joint_names, doc["q"], strict=True)}
        if self.gripper:
            action["gripper.pos"] = gripper_reading(doc)[0]  # its width, m (the follower clamps it to its stroke)
        return action

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """No feedback (akarm teleop's force feedback needs both arms in one session)."""

    def disconnect(self) -> None:
        arm, self.arm = self.arm, None
        if arm is not None:
            try:
                import contextlib

                from akarm.errors import AkarmError

                with contextlib.suppress(AkarmError, OSError):
                    arm.call("end_teach")
                    if self.gripper:  # the gripper holds again where the hand left it
                        width = gripper_reading(arm.state())[0]
                        if math.isfinite(width):
                            arm.call("gripper_move", width=min(max(width, 0.0), float(arm.config.gripper.stroke)),  # type: ignore[union-attr]
                                      wait=False)
            finally:
                arm.close()
