"""A simulated camera: pictures of the arm, drawn in a process of its own.

For demonstrations recorded against the simulator (``akarm teleop --record --camera``, LeRobot's
``akarm_sim`` camera): a learning policy needs images, and the simulator has no camera. This one draws
the arm as the controller believes it is, from the joint positions it is told:

- :class:`ArmPainter` draws one frame (RGB, uint8) with numpy alone: the URDF's ``<visual>``
  primitives (boxes, cylinders, spheres) where the URDF has them, each as a filled silhouette in
  an orthographic view from the front left, the far ones first; else capsules from joint to joint.
  A gripper's fingers (``gripper.fingers``) are drawn at the jaws' width (or two jaws at the tool
  frame when the URDF draws no fingers), and an object between the jaws (the simulator's
  ``place_object``) as a red block of its width, drawn over the jaws (a finger would hide it).
  **Not drawn:** the URDF's meshes (STL, OBJ, DAE are left out, listed in :attr:`ArmPainter.left_out`;
  a URDF of meshes alone is drawn as capsules from joint to joint), an object the jaws have not
  reached (placed with a position elsewhere), lighting and shadows (a part farther off is darker).
- :class:`FrameFile` is where the frames go: a memory-mapped file (in ``/dev/shm``) with a 16-byte
  header (``seq`` uint64, ``t`` float64, written after the pixels) and ``height × width × 3`` bytes;
  a reader copies the newest frame and reads the header again to be sure it was whole.
- :class:`PoseFile` is where the positions come from when no server is asked: the process that runs
  the arm (``akarm teleop``) writes them, a few microseconds a step.
- :func:`run` draws at ``fps`` until told to stop; ``python -m akarm.sim.camera`` is that process
  (reading a :class:`PoseFile`, and the simulator's control channel for the object).

Drawing a 96×96 frame of arm6g takes a few milliseconds (``benchmarks/``-free: measured in the
tests' output); it never runs in the control loop's process.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import math
import mmap
import os
import struct
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from akarm.config.frames import MAX_SIZE, check_frame_size
from akarm.errors import ArgumentError

if TYPE_CHECKING:
    from akarm.config import RobotConfig

__all__ = ["HEADER", "MAX_SIZE", "ArmPainter", "FrameFile", "Pose", "PoseFile", "main", "run"]

#: A frame file's header: seq (uint64, 0: no frame yet), t (float64, time.time() of the frame).
HEADER = struct.Struct("<Qd")
#: A pose file's header: seq (uint64), then the joint positions (rad) and the gripper's width (m,
#: NaN: none), float64 each.
POSE_HEADER = struct.Struct("<Q")
#: RGB of what the URDF does not colour, the capsules, the jaws and the object.
GREY = (176, 180, 190)
ORANGE = (232, 137, 48)
JAWS = (200, 202, 208)
OBJECT = (205, 45, 45)
#: pixels: the least width a part is drawn with
MIN_PIXELS = 2.0
#: m: the jaws drawn at the tool frame when the URDF draws no fingers (x, y across, z)
JAW_SIZE = (0.012, 0.008, 0.04)
#: m: the object's size along the tool's x and z (its width is across the jaws)
OBJECT_SIZE = (0.03, 0.03)


class _SharedFile:
    """A memory-mapped file of ``size`` bytes that one process writes and another reads, a sequence number
    first (``header``): made in ``/dev/shm`` where there is one (:meth:`_make`; removed again when the
    maker closes it), or opened by path."""

    def _open(self, path: str | os.PathLike[str], size: int, what: str) -> None:
        self.path = Path(path)
        self.size = size
        with open(self.path, "r+b") as f:
            if os.fstat(f.fileno()).st_size < self.size:
                raise ArgumentError(f"{self.path} is smaller than {what}", fix="open it with the size it was made with")
            self.map = mmap.mmap(f.fileno(), self.size)
        self.owner = False

    @staticmethod
    def _make(prefix: str, size: int) -> str:
        """A new file of ``size`` zero bytes (sequence 0: nothing written yet); its path."""
        shm = "/dev/shm" if os.path.isdir("/dev/shm") else None
        fd, path = tempfile.mkstemp(prefix=prefix, dir=shm)
        try:
            os.ftruncate(fd, size)
        finally:
            os.close(fd)
        return path

    def _consistent(self, header: struct.Struct) -> tuple[int, bytes] | None:
        """The sequence number and a copy of the body, read whole between two writes (five tries), or
        ``None`` (nothing written yet, or writes come faster than a copy)."""
        for _ in range(5):
            seq = header.unpack(self.map[:header.size])[0]
            if seq == 0:
                return None
            body = self.map[header.size:self.size]
            if header.unpack(self.map[:header.size])[0] == seq:
                return int(seq), body
        return None

    def close(self) -> None:
        """Unmap it; the file is removed if this process made it."""
        with contextlib.suppress(ValueError, BufferError):
            self.map.close()
        if self.owner:
            with contextlib.suppress(OSError):
                self.path.unlink()


class FrameFile(_SharedFile):
    """A memory-mapped frame file (see the module's docstring). :meth:`create` makes one (in
    ``/dev/shm`` where there is one); ``FrameFile(path, width, height)`` opens one."""

    def __init__(self, path: str | os.PathLike[str], width: int, height: int) -> None:
        self.width, self.height = check_frame_size(width, height)
        self._open(path, HEADER.size + self.width * self.height * 3, f"a frame of {width} × {height}")

    @classmethod
    def create(cls, width: int, height: int) -> FrameFile:
        width, height = check_frame_size(width, height)
        frames = cls(cls._make("akarm-camera-", HEADER.size + width * height * 3), width, height)
        frames.owner = True
        return frames

    def write(self, frame: np.ndarray) -> int:
        """Publish ``frame`` (height × width × 3 uint8); its seq."""
        seq = HEADER.unpack(self.map[:HEADER.size])[0] + 1
        self.map[HEADER.size:self.size] = np.ascontiguousarray(frame, dtype=np.uint8).tobytes()
        self.map[:HEADER.size] = HEADER.pack(seq, time.time())
        return int(seq)

    @property
    def seq(self) -> int:
        """Frames published so far (0: none yet)."""
        return int(HEADER.unpack(self.map[:HEADER.size])[0])

    def latest(self) -> tuple[int, np.ndarray | None]:
        """The newest frame (a copy) and its seq; ``(0, None)`` before the first, or while frames come
        faster than it can copy one whole (five tries)."""
        got = self._consistent(HEADER)
        if got is None:
            return 0, None
        return got[0], np.frombuffer(got[1], np.uint8).reshape(self.height, self.width, 3).copy()


@dataclass(frozen=True)
class Pose:
    """What a frame draws: joint positions (rad, the robot file's order), the gripper's width (m,
    NaN: none or unknown), the object's width (m, None: none between the jaws)."""

    q: np.ndarray
    gripper: float = math.nan
    object: float | None = None


class PoseFile(_SharedFile):
    """A memory-mapped file of ``joints`` positions and a gripper width, written by the process that
    runs the arm and read by the camera's. :meth:`create` makes one; ``PoseFile(path, joints)`` opens it."""

    def __init__(self, path: str | os.PathLike[str], joints: int) -> None:
        self.joints = int(joints)
        self._open(path, POSE_HEADER.size + 8 * (self.joints + 1), f"a pose of {self.joints} joints")
        self._seq = 0

    @classmethod
    def create(cls, joints: int) -> PoseFile:
        pose = cls(cls._make("akarm-pose-", POSE_HEADER.size + 8 * (joints + 1)), joints)
        pose.owner = True
        return pose

    def write(self, q: np.ndarray, gripper: float | None = None) -> None:
        """Publish ``q`` (rad) and the gripper's width (m; None: none)."""
        self._seq += 1
        values = np.empty(self.joints + 1)
        values[:-1] = q
        values[-1] = math.nan if gripper is None else gripper
        self.map[POSE_HEADER.size:self.size] = values.tobytes()
        self.map[:POSE_HEADER.size] = POSE_HEADER.pack(self._seq)

    def read(self) -> Pose | None:
        """The newest pose, or None before the first (or while it is being written)."""
        got = self._consistent(POSE_HEADER)
        if got is None:
            return None
        values = np.frombuffer(got[1], dtype=np.float64)
        return Pose(values[:-1].copy(), float(values[-1]))


@dataclass(frozen=True)
class _Shape:
    """One thing to draw, in the frame of ``frame`` (a Pinocchio frame id; -1: the tool frame):
    ``points`` (n × 3, m) whose projected hull is filled, or a sphere (``radius`` > 0, one point);
    ``slide``: m per m of the gripper's width it moves, in the frame's parent body (fingers)."""

    frame: int
    points: np.ndarray
    color: tuple[int, int, int]
    radius: float = 0.0
    slide: np.ndarray | None = None
    jaw: bool = False


def _box(size: tuple[float, ...], origin: np.ndarray) -> np.ndarray:
    x, y, z = (0.5 * s for s in size)
    corners = np.array([[sx * x, sy * y, sz * z, 1.0] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return (corners @ origin.T)[:, :3]


def _cylinder(radius: float, length: float, origin: np.ndarray, sides: int = 12) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)
    pts = [[x, y, z, 1.0] for z in (-0.5 * length, 0.5 * length) for x, y in ring]
    return (np.array(pts) @ origin.T)[:, :3]


def _hull(p: np.ndarray) -> np.ndarray:
    """The convex hull of 2-D points, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in p})
    if len(pts) < 3:
        return np.array(pts)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    upper: list[tuple[float, float]] = []
    for pt in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], pt) <= 0:
            lower.pop()
        lower.append(pt)
    for pt in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], pt) <= 0:
            upper.pop()
        upper.append(pt)
    return np.array(lower[:-1] + upper[:-1])


class ArmPainter:
    """Draws ``config``'s arm (see the module's docstring) in ``width × height`` pixels, seen from the
    front left, a little from above (looking along (-0.7, 0.75, -0.45) in the base frame), orthographic,
    the base low in the middle and the arm's reach fitted to the frame; a part thinner than
    :data:`MIN_PIXELS` is drawn that wide.

    Attributes:
        drawn: ``"visuals"`` (the URDF's primitives) or ``"capsules"``. left_out: the URDF visuals not
            drawn (meshes), as ``link: kind``.
    """

    def __init__(self, config: RobotConfig, width: int, height: int, *, visuals: bool = True) -> None:
        import pinocchio as pin

        from akarm.config.visuals import read_visuals
        from akarm.dynamics.fingers import finger_slides
        from akarm.dynamics.model import RobotModel

        self.width, self.height = check_frame_size(width, height)
        self.model = RobotModel(config)
        self.pin = pin
        pm = self.model.pin_model
        look = np.array([-0.7, 0.75, -0.45])  # the camera looks along this (from the front left, above)
        look /= np.linalg.norm(look)
        right = np.cross(look, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, look)
        self.axes = np.stack([right, up])
        self.look = look
        self.left_out: list[str] = []
        slides = finger_slides(self.model)
        shapes: list[_Shape] = []
        for vis in read_visuals(config.urdf) if visuals else []:
            if vis.kind == "mesh" or not pm.existFrame(vis.link, pin.FrameType.BODY):
                self.left_out.append(f"{vis.link}: {vis.kind}")
                continue
            fid = int(pm.getFrameId(vis.link, pin.FrameType.BODY))
            color = GREY if vis.rgba is None else tuple(round(255 * min(1.0, max(0.0, c))) for c in vis.rgba[:3])
            slide = slides.get(vis.link)
            if vis.kind == "box":
                shapes.append(_Shape(fid, _box(vis.size, vis.origin), color, slide=slide))  # type: ignore[arg-type]
            elif vis.kind == "cylinder":
                shapes.append(_Shape(fid, _cylinder(vis.size[0], vis.size[1], vis.origin), color,  # type: ignore[arg-type]
                                     slide=slide))
            elif vis.kind == "sphere":
                shapes.append(_Shape(fid, vis.origin[None, :3, 3], color, radius=vis.size[0],  # type: ignore[arg-type]
                                     slide=slide))
        self.drawn = "visuals" if shapes else "capsules"
        self.fingers = any(s.slide is not None for s in shapes)
        self.shapes = shapes
        zero = self._joint_points(np.zeros(len(self.model.joint_names)))
        reach = float(np.max(np.linalg.norm(zero, axis=1))) or 0.5  # (all zeros: the arm at full stretch here)
        self.scale = 0.7 * min(self.width, self.height) / reach  # px per m
        self.centre = np.array([self.width / 2.0, self.height * 0.78])  # the base: arms mostly reach up
        self.radius = max(1.5, 0.04 * min(self.width, self.height))
        yy, xx = np.mgrid[0:self.height, 0:self.width]
        self.pixels = np.stack([xx, yy], axis=-1).astype(np.float32) + 0.5
        shade = np.linspace(205, 150, self.height, dtype=np.float32)[:, None, None]  # light: dark motors show
        self.background = np.broadcast_to(shade * np.array([0.85, 0.9, 1.0], np.float32),
                                          (self.height, self.width, 3)).astype(np.uint8)
        gripper = config.gripper
        self.stroke = float(gripper.stroke) if gripper is not None else 0.0

    # -- geometry --------------------------------------------------------------------------------
    def _joint_points(self, q: np.ndarray) -> np.ndarray:
        """The base, each joint's origin and the tool frame, m (base frame)."""
        joints = [self.model.frame_pose(q, n)[:3, 3] for n in self.model.joint_names]
        return np.array([np.zeros(3), *joints, self.model.tool_pose(q)[:3, 3]])

    def _project(self, p: np.ndarray) -> np.ndarray:
        xy = p @ self.axes.T * self.scale
        return self.centre + xy * np.array([1.0, -1.0])  # image y points down

    # -- drawing ---------------------------------------------------------------------------------
    def _fill(self, img: np.ndarray, poly: np.ndarray, color: tuple[int, int, int]) -> None:
        """Fill the convex polygon ``poly`` (counter-clockwise in pixel coordinates, as :func:`_hull` gives it)."""
        if len(poly) < 3:
            return
        x0, y0 = np.floor(poly.min(axis=0)).astype(int)
        x1, y1 = np.ceil(poly.max(axis=0)).astype(int)
        x0, y0 = max(x0, 0), max(y0, 0)
        x1, y1 = min(x1, self.width), min(y1, self.height)
        if x0 >= x1 or y0 >= y1:
            return
        px = self.pixels[y0:y1, x0:x1]
        inside = np.ones(px.shape[:2], dtype=bool)
        n = len(poly)
        for k in range(n):
            a, b = poly[k], poly[(k + 1) % n]
            inside &= (b[0] - a[0]) * (px[..., 1] - a[1]) - (b[1] - a[1]) * (px[..., 0] - a[0]) >= 0
        img[y0:y1, x0:x1][inside] = color

    def _disc(self, img: np.ndarray, centre: np.ndarray, radius: float, color: tuple[int, int, int]) -> None:
        x0, y0 = (max(math.floor(c - radius), 0) for c in centre)
        x1 = min(math.ceil(centre[0] + radius) + 1, self.width)
        y1 = min(math.ceil(centre[1] + radius) + 1, self.height)
        if x0 >= x1 or y0 >= y1:
            return
        px = self.pixels[y0:y1, x0:x1]
        inside = np.sum((px - centre) ** 2, axis=-1) <= radius * radius
        img[y0:y1, x0:x1][inside] = color

    def _segment(self, img: np.ndarray, a: np.ndarray, b: np.ndarray, radius: float,
                 color: tuple[int, int, int]) -> None:
        ab = b - a
        t = np.clip(((self.pixels - a) @ ab) / max(float(ab @ ab), 1e-9), 0.0, 1.0)
        d = np.linalg.norm(self.pixels - (a + t[..., None] * ab), axis=-1)
        img[d <= radius] = color

    @staticmethod
    def _shaded(color: tuple[int, int, int], depth: float) -> tuple[int, int, int]:
        f = min(1.0, max(0.6, 1.0 - 0.5 * depth))  # farther: darker (depth in m from the base's plane)
        return (round(color[0] * f), round(color[1] * f), round(color[2] * f))

    def draw(self, q: np.ndarray | list[float], gripper: float = math.nan, obj: float | None = None) -> np.ndarray:
        """An RGB frame (height × width × 3, uint8) of the arm at ``q`` (rad), its jaws ``gripper`` m
        apart (NaN: closed, or no gripper) with an object ``obj`` m wide between them (None: none)."""
        q = np.asarray(q, dtype=float)
        img = self.background.copy()
        pin, pm, data = self.pin, self.model.pin_model, self.model.pin_data
        pin.forwardKinematics(pm, data, self.model.to_pin_q(q))
        pin.updateFramePlacements(pm, data)
        tool = self.model.tool_pose(q)
        width = min(max(gripper, 0.0), self.stroke) if math.isfinite(gripper) else 0.0
        items: list[tuple[float, Callable[[], None]]] = []
        if self.drawn == "visuals":
            for s in self.shapes:
                placement = data.oMf[s.frame]
                rot, pos = np.asarray(placement.rotation), np.asarray(placement.translation)
                pts = s.points @ rot.T + pos
                if s.slide is not None:  # a finger: half the width along its slide, in its body's frame
                    body = data.oMi[pm.frames[s.frame].parentJoint]
                    pts = pts + np.asarray(body.rotation) @ s.slide * (0.5 * width)
                items.append(self._item(img, pts, s.color, s.radius))
        else:
            p = self._joint_points(q)
            for k in range(len(p) - 1):
                a, b = p[k], p[k + 1]
                segment: Callable[[], None] = functools.partial(
                    self._segment, img, self._project(a), self._project(b), self.radius, ORANGE if k % 2 == 0 else GREY)
                items.append((float((a + b) @ self.look) / 2, segment))
        if self.stroke > 0.0 and not self.fingers:  # jaws at the tool frame
            for side in (-1.0, 1.0):
                centre = np.eye(4)
                centre[:3, 3] = [0.0, side * (0.5 * width + 0.5 * JAW_SIZE[1]), 0.0]
                items.append(self._item(img, _box(JAW_SIZE, tool @ centre)[:, :3], JAWS, 0.0))
        if obj is not None and obj > 0.0:  # drawn over the jaws (between them, a finger would hide it here)
            block = _box((OBJECT_SIZE[0], obj, OBJECT_SIZE[1]), tool)
            items.append((-math.inf, self._item(img, block, OBJECT, 0.0)[1]))
        for _depth, paint in sorted(items, key=lambda it: -it[0]):  # the far ones first
            paint()
        return img

    def _item(self, img: np.ndarray, pts: np.ndarray, color: tuple[int, int, int],
              radius: float) -> tuple[float, Callable[[], None]]:
        depth = float(np.mean(pts @ self.look))
        shaded = self._shaded(color, depth)
        if radius > 0.0:
            return depth, lambda: self._disc(img, self._project(pts[0]), radius * self.scale, shaded)
        flat = self._project(pts)
        poly = _hull(flat)
        # thinner than MIN_PIXELS across (a thin link far off): a stroke of that width along its length,
        # so that what the arm is made of shows at any size
        centre = flat.mean(axis=0)
        axes = np.linalg.svd(flat - centre, full_matrices=False)[2]
        along = (flat - centre) @ axes[0]
        across = (flat - centre) @ axes[1] if len(axes) > 1 else np.zeros(len(flat))
        if np.ptp(across) < MIN_PIXELS:
            a, b = centre + along.min() * axes[0], centre + along.max() * axes[0]
            return depth, functools.partial(self._segment, img, a, b, MIN_PIXELS / 2, shaded)
        return depth, functools.partial(self._fill, img, poly, shaded)


def run(painter: ArmPainter, frames: FrameFile, fps: float, pose: Callable[[], Pose | None],
        alive: Callable[[], bool] = lambda: True) -> None:
    """Draw ``pose()`` into ``frames`` ``fps`` times a second while ``alive()`` (a pose of None: not
    yet known, nothing drawn); Ctrl-C (the terminal's, sent to a camera process too) ends it quietly."""
    period = 1.0 / fps
    next_t = time.monotonic()
    try:
        while alive():
            p = pose()
            if p is not None:
                frames.write(painter.draw(p.q, p.gripper, p.object))
            next_t += period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.monotonic()
    except KeyboardInterrupt:
        pass


def parent_alive(pid: int) -> Callable[[], bool]:
    """True while process ``pid`` runs (0: always), for a camera process that must end with its parent."""
    def alive() -> bool:
        return pid == 0 or (Path(f"/proc/{pid}").exists() if os.path.isdir("/proc") else os.getppid() == pid)
    return alive


def object_reader(control: str | None) -> Callable[[], float | None]:
    """The width of the object between the simulator's jaws (None: none), asked on its control
    channel ``control`` at most 10 times a second (None: no channel, no object)."""
    if not control:
        return lambda: None
    from akarm.sim.channel import SimulatorControl

    state: dict[str, object] = {"t": 0.0, "width": None, "client": None}

    def read() -> float | None:
        now = time.monotonic()
        if now - float(state["t"]) < 0.1:  # type: ignore[arg-type]
            return state["width"]  # type: ignore[return-value]
        state["t"] = now
        try:
            if state["client"] is None:
                state["client"] = SimulatorControl(control, timeout=2.0)
            width, between = state["client"].gripper_object()  # type: ignore[attr-defined]
            state["width"] = width if between else None
        except Exception:  # the simulator gone or busy: nothing drawn between the jaws meanwhile
            state["client"] = None
            state["width"] = None
        return state["width"]  # type: ignore[return-value]

    return read


def main(argv: list[str] | None = None) -> int:
    """``python -m akarm.sim.camera ROBOT.yaml FRAMES POSES --width W --height H --fps N``."""
    from akarm.robotfile.load import load_robot

    ap = argparse.ArgumentParser(prog="python -m akarm.sim.camera", description=__doc__.split("\n")[0])
    ap.add_argument("robot_file")
    ap.add_argument("frames", help="the frame file to write (its maker sized it)")
    ap.add_argument("poses", help="the pose file to read (the arm's process writes it)")
    ap.add_argument("--width", type=int, required=True)
    ap.add_argument("--height", type=int, required=True)
    ap.add_argument("--fps", type=float, required=True)
    ap.add_argument("--control", help="the simulator's control socket: the object between the jaws is drawn")
    ap.add_argument("--parent", type=int, default=0, help="end when this process is gone")
    args = ap.parse_args(argv)
    config = load_robot(args.robot_file)
    painter = ArmPainter(config, args.width, args.height)
    frames = FrameFile(args.frames, args.width, args.height)
    poses = PoseFile(args.poses, len(config.joint_names))
    obj = object_reader(args.control)

    def pose() -> Pose | None:
        p = poses.read()
        return None if p is None else Pose(p.q, p.gripper, obj())

    try:
        run(painter, frames, args.fps, pose, parent_alive(args.parent))
    finally:
        frames.close()
        poses.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
