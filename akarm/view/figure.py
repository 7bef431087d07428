"""What the view draws of an arm: triangle meshes, each riding on one body of the kinematic tree.

:func:`build_figure` makes a :class:`Figure` for a robot: from the URDF's ``<visual>`` elements
(:mod:`akarm.view.visuals`) when it has some that can be drawn, else from the kinematics alone: a
capsule from each joint to the next (and from the last to its tool frame), its radius growing with
the mass of the link it stands for, and a ball at each joint. Every part is expressed in the frame
of the Pinocchio joint that moves it (links of fixed and locked joints ride on their parent's), so
drawing a pose is placing one frame per joint: :class:`Poser` gives those placements (and the tool
frame's) for joint positions in the robot file's order.

The geometry comes from the same reduced Pinocchio model the controller uses (:class:`akarm.dynamics.model.RobotModel`):
what the view shows is where the controller believes the links are.

A gripper's fingers (the robot file's ``gripper.fingers``: URDF joints the reduced model holds at 0)
slide: :func:`finger_slides` gives, per link a finger joint moves, the direction it slides in its
body's frame per metre of that joint, so the view draws the jaws at the width measured (each finger
joint at half of it, as ``joint_states`` has them).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from akarm.dynamics.fingers import finger_slides
from akarm.dynamics.model import RobotModel
from akarm.errors import ModelError
from akarm.view.visuals import read_visuals, visual_mesh

__all__ = ["LINK_COLOR", "Figure", "Part", "Poser", "build_figure", "capsule", "finger_slides", "link_radius"]

#: colours (RGB 0-255): links of the kinematic figure, its joints, and a URDF visual without a colour
LINK_COLOR = (232, 137, 48)
JOINT_COLOR = (70, 72, 84)
VISUAL_COLOR = (176, 180, 190)


@dataclass(frozen=True)
class Part:
    """A mesh riding on body ``body`` (a Pinocchio joint index; 0 is the fixed base).

    Attributes:
        name: unique among the figure's parts, usable in a scene path.
        vertices: (n, 3) float32, m, in the body's frame. faces: (m, 3) uint32.
        color: RGB 0-255. opacity: 0-1 (a URDF colour's alpha).
        link: the URDF link it draws (``""``: a part of the kinematic figure).
    """

    name: str
    body: int
    vertices: np.ndarray
    faces: np.ndarray
    color: tuple[int, int, int]
    opacity: float = 1.0
    link: str = ""


@dataclass(frozen=True)
class Figure:
    """The parts of a robot, and what became of its visuals.

    Attributes:
        kind: ``"visuals"`` (the URDF's) or ``"kinematics"`` (capsules from joint to joint).
        bodies: the Pinocchio joint names, by body index (``universe`` first).
        parts: the meshes.
        visuals: how many of the URDF's visuals are drawn. problems: each visual that is not, and why.
    """

    kind: str
    bodies: tuple[str, ...]
    parts: tuple[Part, ...]
    visuals: int = 0
    problems: tuple[str, ...] = ()

    @property
    def faces(self) -> int:
        """Triangles in all: what drawing it costs."""
        return sum(len(p.faces) for p in self.parts)


def link_radius(mass: float) -> float:
    """The radius of a capsule standing for a link of ``mass`` kg, m: 30 mm for 1 kg, growing with the
    cube root of the mass (a link's thickness, not its volume), kept within 8-60 mm."""
    return min(0.06, max(0.008, 0.03 * (max(mass, 0.0) ** (1.0 / 3.0))))


def capsule(start: np.ndarray, end: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a capsule from ``start`` to ``end`` (m) of ``radius``."""
    import trimesh

    axis = np.asarray(end, dtype=float) - np.asarray(start, dtype=float)
    length = float(np.linalg.norm(axis))
    if length < 1e-9:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    else:
        mesh = trimesh.creation.capsule(height=length, radius=radius, count=[16, 12])
        mesh.apply_translation((0.0, 0.0, length / 2))
        mesh.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis / length))
    mesh.apply_translation(start)
    return np.asarray(mesh.vertices, dtype=np.float32), np.asarray(mesh.faces, dtype=np.uint32)


def _scene_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", text) or "_"


def _kinematic_parts(model: pin.Model) -> list[Part]:
    parts: list[Part] = []
    children: dict[int, list[int]] = {i: [] for i in range(model.njoints)}
    for j in range(1, model.njoints):
        children[int(model.parents[j])].append(j)
    for i in range(model.njoints):
        radius = link_radius(float(model.inertias[i].mass))
        ends = [np.array(model.jointPlacements[j].translation) for j in children[i]]
        if not ends:  # a last link: to its farthest frame (the tool), else through its centre of mass
            frames = [np.array(f.placement.translation) for f in model.frames if int(f.parentJoint) == i]
            far = max(frames, key=lambda p: float(np.linalg.norm(p)), default=np.zeros(3))
            com = np.array(model.inertias[i].lever)
            ends = [far if np.linalg.norm(far) > 1e-6 else 2 * com]
        for k, end in enumerate(ends):
            if np.linalg.norm(end) > 1e-6:
                v, f = capsule(np.zeros(3), end, radius)
                parts.append(Part(f"link{i}_{k}", i, v, f, LINK_COLOR))
        if i > 0:
            v, f = capsule(np.zeros(3), np.zeros(3), radius * 1.35)
            parts.append(Part(f"joint{i}", i, v, f, JOINT_COLOR))
    return parts


def _visual_parts(model: pin.Model, urdf: str | os.PathLike[str]) -> tuple[list[Part], list[str]]:
    parts: list[Part] = []
    problems: list[str] = []
    for vis in read_visuals(urdf):
        if not model.existFrame(vis.link, pin.FrameType.BODY):  # (a joint may have the link's name)
            problems.append(f"link {vis.link!r} is not in the model (not reached from the root?)")
            continue
        frame = model.frames[model.getFrameId(vis.link, pin.FrameType.BODY)]
        try:
            mesh = visual_mesh(vis, urdf)
        except ModelError as e:
            problems.append(str(e))
            continue
        mesh.apply_transform(frame.placement.homogeneous)
        color = VISUAL_COLOR if vis.rgba is None else tuple(round(255 * min(1.0, max(0.0, c)))
                                                            for c in vis.rgba[:3])
        opacity = 1.0 if vis.rgba is None else min(1.0, max(0.05, vis.rgba[3]))
        parts.append(Part(f"{_scene_name(vis.link)}_{vis.index}", int(frame.parentJoint),
                          np.asarray(mesh.vertices, dtype=np.float32), np.asarray(mesh.faces, dtype=np.uint32),
                          (color[0], color[1], color[2]), opacity, vis.link))
    return parts, problems


def build_figure(model: RobotModel, *, visuals: bool = True) -> Figure:
    """The figure of ``model``'s robot: its URDF's visuals if any can be drawn (and ``visuals``),
    else the kinematic figure (see the module's docstring)."""
    pm = model.pin_model
    bodies = tuple(str(n) for n in pm.names)
    if visuals:
        parts, problems = _visual_parts(pm, model.config.urdf)
        if parts:
            return Figure("visuals", bodies, tuple(parts), len(parts), tuple(problems))
    else:
        problems = []
    return Figure("kinematics", bodies, tuple(_kinematic_parts(pm)), 0, tuple(problems))


class Poser:
    """Where each body of ``model`` is for joint positions ``q`` (rad, the robot file's order).

    Owns Pinocchio data of its own: one thread uses a Poser (the view's).
    """

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self._data = model.pin_model.createData()
        pm = model.pin_model
        if pm.existFrame(model.tool_frame, pin.FrameType.BODY):  # (a joint may have the link's name)
            tool = pm.frames[pm.getFrameId(model.tool_frame, pin.FrameType.BODY)]
        else:
            tool = pm.frames[pm.getFrameId(model.tool_frame)]
        self.tool_body = int(tool.parentJoint)
        self.tool_placement = np.array(tool.placement.homogeneous)

    def poses(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """(bodies, 4, 4): each body's frame in the base frame, m. NaN positions are taken as 0."""
        qa = np.nan_to_num(np.asarray(q, dtype=float), nan=0.0)
        pin.forwardKinematics(self.model.pin_model, self._data, self.model.to_pin_q(qa))
        return np.array([m.homogeneous for m in self._data.oMi])

    def tool(self, poses: np.ndarray) -> np.ndarray:
        """The tool frame in the base frame, from :meth:`poses`' result."""
        return np.asarray(poses[self.tool_body] @ self.tool_placement)


def wxyz(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """A rotation matrix as a unit quaternion (w, x, y, z), w ≥ 0."""
    q = pin.Quaternion(np.asarray(rotation, dtype=float))
    w, x, y, z = float(q.w), float(q.x), float(q.y), float(q.z)
    s = -1.0 if w < 0 else 1.0
    n = math.sqrt(w * w + x * x + y * y + z * z) or 1.0
    return (s * w / n, s * x / n, s * y / n, s * z / n)
