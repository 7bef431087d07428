"""``Akarm``: an akarm arm as a LeRobot ``Robot`` (a client of ``akarm serve``).

Features (SI units, the order stable: the robot file's joint order):

- actions: ``<joint>.pos`` (rad) per joint, then ``gripper.pos`` (m, jaw width) when the robot file
  has a gripper;
- observations: the same ``.pos``, then ``<joint>.vel`` (rad/s) per joint and ``gripper.vel`` (m/s),
  then ``<joint>.effort`` (N·m) per joint and ``gripper.effort`` (N, the squeeze; none with
  ``effort=false``), then each camera ``(height, width, 3)`` (the gripper's features only when the
  robot file has one).

``send_action`` streams the target into akarm's 500 Hz loop through the jerk-limited retargeting
(the server's ``stream`` operation): no command step above a joint's limits, whatever is sent; a target
past a joint's range (or a gripper width past its stroke) is clamped to it and counted (a warning
once); NaN refuses the action and the
arm holds (``ArgumentError`` raised); 0-d tensors and partial ``.pos`` dicts are taken. A policy that
stops sending leaves the arm decelerating to a hold after ``stream_timeout`` s. A safety stop is
raised from ``get_observation``/``send_action`` as akarm's own error (its name and text); the server has
damped and disabled the arm, and ``disconnect`` stops a server started here.
"""

from __future__ import annotations

import logging
import math
from functools import cached_property
from typing import Any

from lerobot.cameras.utils import make_cameras_from_configs
from lerobot.robots.robot import Robot

from .config_akarm import AkarmConfig
from .served import ServedArm

log = logging.getLogger("akarm.lerobot")

__all__ = ["Akarm", "action_target", "gripper_reading"]


def _number(value: Any) -> float:
    """A float from a float, a numpy scalar or a 0-d tensor (``float()`` takes each); NaN for anything else."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def action_target(action: dict[str, Any], names: tuple[str, ...], gripper: str | None) -> tuple[dict[str, float],
                                                                                                 float | None]:
    """``{joint: rad}`` and the gripper's width (m, or None) from a LeRobot action (``<joint>.pos`` keys;
    others, such as ``.vel``, ignored). A ``.pos`` key of no joint is kept as it is: the server refuses it."""
    target: dict[str, float] = {}
    width = None
    for key, value in action.items():
        if not key.endswith(".pos"):
            continue
        name = key[:-4]
        if name == "gripper" and gripper is not None:
            width = _number(value)
        else:
            target[name] = _number(value)
    return target, width


def gripper_reading(doc: dict[str, Any]) -> tuple[float, float, float]:
    """The gripper's width (m), rate (m/s) and squeeze (N) from the server's ``state`` (NaN for what its
    motor has not told yet)."""
    g = doc.get("gripper") or {}

    def num(key: str) -> float:
        x = g.get(key)
        return math.nan if x is None else float(x)

    return num("width"), num("velocity"), num("force")


class Akarm(Robot):
    """An akarm arm (see the module's docstring)."""

    config_class = AkarmConfig
    name = "akarm"

    def __init__(self, config: AkarmConfig) -> None:
        super().__init__(config)
        self.config = config
        if not config.robot_file:
            raise ValueError("--robot.robot_file is needed: the arm's akarm robot file (YAML)")
        from akarm.robotfile.load import load_robot

        robot = load_robot(config.robot_file)
        self.joint_names: tuple[str, ...] = tuple(robot.joint_names)
        gripper = getattr(robot, "gripper", None)
        self.gripper: str | None = "gripper" if gripper is not None else None
        self.cameras = make_cameras_from_configs(config.cameras)
        self.arm: ServedArm | None = None
        self.clamped_warned = False
        self.last_report: dict[str, Any] = {}

    # -- features ------------------------------------------------------------------------------
    @cached_property
    def action_features(self) -> dict[str, type]:
        keys = [f"{n}.pos" for n in self.joint_names] + (["gripper.pos"] if self.gripper else [])
        return dict.fromkeys(keys, float)

    @cached_property
    def observation_features(self) -> dict[str, Any]:
        feats: dict[str, Any] = dict(self.action_features)
        grip = [self.gripper] if self.gripper else []
        feats.update({f"{n}.vel": float for n in [*self.joint_names, *grip]})
        if self.config.effort:
            feats.update({f"{n}.effort": float for n in [*self.joint_names, *grip]})
        for key, cam in self.config.cameras.items():
            feats[key] = (cam.height, cam.width, 3)
        return feats

    # -- connection ----------------------------------------------------------------------------
    @property
    def is_connected(self) -> bool:
        return self.arm is not None and all(c.is_connected for c in self.cameras.values())

    @property
    def is_calibrated(self) -> bool:
        return True  # akarm's robot file holds each joint's zero and direction (akarm zero)

    def calibrate(self) -> None:
        """Nothing to do here: akarm calibrates with ``akarm zero`` and the robot file."""

    def configure(self) -> None:
        """Nothing to do here: gains and limits are the robot file's."""

    def connect(self, calibrate: bool = True) -> None:
        if self.arm is not None:
            raise RuntimeError(f"{self} is already connected")
        c = self.config
        self.arm = ServedArm(c.robot_file, c.interface, c.channel, profile=c.profile, stall_limit=c.stall_limit,
                              start=c.start_server)
        try:
            self.arm.call("ready")  # refused while a safety stop is latched; enables a disabled arm
            for cam in self.cameras.values():
                cam.connect()
            self.configure()
        except BaseException:
            self.disconnect()
            raise
        started = self.arm.process
        log.info("%s connected to %s", self, f"akarm serve pid {started.pid}, started here" if started
                 else f"the running akarm serve at {self.arm.socket}")

    def disconnect(self) -> None:
        arm, self.arm = self.arm, None
        try:
            for cam in self.cameras.values():
                if cam.is_connected:
                    cam.disconnect()
        finally:
            if arm is not None:
                arm.close()

    def _arm(self) -> ServedArm:
        if self.arm is None:
            raise RuntimeError(f"{self} is not connected")
        return self.arm

    # -- data ----------------------------------------------------------------------------------
    def get_observation(self) -> dict[str, Any]:
        arm = self._arm()
        doc = arm.state()
        obs: dict[str, Any] = {}
        grip = gripper_reading(doc) if self.gripper else None
        for i, n in enumerate(self.joint_names):
            obs[f"{n}.pos"] = float(doc["q"][i])
        if grip is not None:
            obs["gripper.pos"] = grip[0]
        for i, n in enumerate(self.joint_names):
            obs[f"{n}.vel"] = float(doc["dq"][i])
        if grip is not None:
            obs["gripper.vel"] = grip[1]
        if self.config.effort:
            for i, n in enumerate(self.joint_names):
                obs[f"{n}.effort"] = float(doc["tau"][i])
            if grip is not None:
                obs["gripper.effort"] = grip[2]
        for key, cam in self.cameras.items():
            obs[key] = cam.async_read()
        return obs

    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        arm = self._arm()
        target, width = action_target(action, self.joint_names, self.gripper)
        report = arm.stream(target, partial=not self.config.strict_actions, gripper=width,
                            timeout=self.config.stream_timeout, speed=self.config.speed)
        self.last_report = report
        if report["clamped"] and not self.clamped_warned:
            self.clamped_warned = True
            log.warning("akarm: an action past a joint's range or the gripper's stroke was clamped to it (%s); "
                        "counted, said once",
                        ", ".join(report["clamped"]))
        sent = {f"{n}.pos": q for n, q in zip(self.joint_names, report["target"], strict=True)}
        if report.get("gripper") is not None:
            sent["gripper.pos"] = report["gripper"]
        return sent
