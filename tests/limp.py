"""Where a limp arm comes to rest, for the turn check's tests (issue 39): each joint either where its
friction holds what gravity asks (``|g| <= coulomb``) or on a hard stop that gravity presses it onto.

:func:`rest_pose` lets a pose "fall" quasi-statically (steps along ``-g``, the joints clipped to their
mechanical range) until it is such a pose: the poses a real arm dropped limp from anywhere ends in,
held by its static friction. The simulator's friction is smooth (no stiction), so a joint at such a
pose creeps there at under ``coulomb_eps`` rad/s: slower than the enable's settle speed, at rest for
the enable.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from akarm import Arm
from akarm.config import Friction, Payload, RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, lockstep_arm

__all__ = ["CASES", "PAYLOAD", "loaded", "max_command_step", "rest_pose", "resting"]



def rest_pose(config: RobotConfig, model: Any, q: Any, *, share: float = 0.8, steps: int = 4000) -> np.ndarray | None:
    """A rest pose of ``config``'s limp arm reached from ``q`` (rad; ``model``: its
    :class:`~akarm.dynamics.model.RobotModel`, with the payload; its ``lower``/``upper`` are the URDF's
    limits, where the simulator's hard stops are), each free joint's gravity within ``share`` of its
    Coulomb friction; ``None`` if it does not come to rest in ``steps`` steps."""
    gravity = model.gravity
    lo, hi = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    c = np.array([j.friction_model().coulomb for j in config.joints])
    q = np.clip(np.asarray(q, dtype=float), lo, hi)
    for _ in range(steps):
        g = np.asarray(gravity(q))
        pressed = ((q <= lo) & (g > 0)) | ((q >= hi) & (g < 0))  # gravity pushes it onto its stop
        if np.all(pressed | (np.abs(g) <= share * c)):
            return q
        q = np.clip(q - 0.02 * np.clip(g, -5.0, 5.0) / np.maximum(c, 0.1) * 0.05, lo, hi)
    return None


# a vertical two-joint arm (AK80-9 shoulder, AK60-6 elbow) carrying 0.5 kg, and arm6 with 0.5 kg; where
# each comes to rest limp: planar2 hanging, arm6 with its shoulder on its hard stop and its forearm hanging
CASES = {"planar2": ([-1.5, 0.0], ["shoulder", "elbow"]),
         "arm6": ([0.0, 0.3, 1.3, 0.0, 0.0, 0.0], ["shoulder_lift", "elbow", "wrist_pitch"])}
PAYLOAD = 0.5


def loaded(robot: str, mass: float = PAYLOAD) -> tuple[RobotConfig, np.ndarray]:
    """The robot's config with ``mass`` kg at its tool, and where it rests limp from its case's pose; its
    friction identified (the catalogue's, as `akarm identify` saves it): the turn check by physics
    allows an unidentified joint the model's whole uncertainty (a real unit's torque constant and
    masses), where a lost turn is seldom clear (docs/turn-counts.md)."""
    config = load_robot(ROBOTS / f"{robot}.yaml")
    config = dataclasses.replace(config, joints=tuple(
        dataclasses.replace(j, friction=Friction(j.friction_model().coulomb, j.friction_model().viscous))
        for j in config.joints))
    if mass:
        config = dataclasses.replace(config, payload=Payload(mass))
    q = rest_pose(config, RobotModel(config), CASES[robot][0])
    assert q is not None
    return config, q


def max_command_step(sim: SimulatedRobot, since: int) -> float:
    """rad: how far apart the positions commanded to any one joint (MIT, kp > 0) lie since frame
    ``since``: a held arm is commanded one position per joint."""
    spread = 0.0
    for cfg in sim.config.joints:
        codec = mit.codec(cfg.motor)
        ps = [codec.decode_command(f.data).position for f in sim.logged_frames(since)[0]
              if f.joint == cfg.name and f.to_motor and mit.special_frame(f.data) is None
              and codec.decode_command(f.data).kp > 0]
        if ps:
            spread = max(spread, max(ps) - min(ps))
    return spread


@contextmanager
def resting(robot: str, channel: str, mass: float = PAYLOAD) -> Iterator[tuple[Arm, SimulatedRobot, np.ndarray]]:
    """A lock-step ``robot`` with ``mass`` kg at its tool resting limp (:func:`loaded`), nothing remembered,
    its frames logged: ``(arm, sim, q)``."""
    config, q = loaded(robot, mass)
    with lockstep_arm(config, channel, q0=q, remember_positions=False, sim_options={"log_frames": True}) as (arm, sim):
        yield arm, sim, q
