"""Episodes of a teleoperation session, sampled at a dataset's fps and committed as LeRobotDataset
v3.0 (:mod:`akarm.datasets`): per frame the follower's measured positions, velocities and torques
(``observation.state``, ``.velocity``, ``.effort``) and the command it was given (``action``: the
leader's pose in the follower's joints, within its range). A follower with a gripper adds its value
last, named ``gripper`` (:data:`akarm.datasets.GRIPPER`): the width measured and asked (m), its rate
(m/s) and squeeze (N): the writer is then made with the follower's joint names and ``gripper``.

Cameras (:class:`akarm.sim.camera.FrameFile`, each drawn by a process of its own): with each frame,
the newest picture of each is copied (a few kB, no drawing here), and the episode's pictures are
stored as video when it is committed (the writer made with the same cameras)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from akarm.datasets import DatasetWriter, EpisodeFrames
from akarm.errors import ArgumentError, StateError
from akarm.motion.bounds import MAX_PATH_SAMPLES
from akarm.teleop.session import Step

if TYPE_CHECKING:
    from akarm.sim.camera import FrameFile

__all__ = ["EpisodeRecorder"]


class EpisodeRecorder:
    """Takes a frame from the first :class:`~akarm.teleop.session.Step` at or after each ``k / fps`` s of
    an episode (the session steps at the follower's loop rate, at least the fps), and commits or
    discards the episode whole.

    Args:
        writer: the dataset the episodes go into (its fps is the recorder's).
        rate_hz: the rate the steps come at (the follower's loop rate): the fps may not exceed it.
        cameras: camera name → its frame file (the writer's cameras, by the same names).
    """

    def __init__(self, writer: DatasetWriter, rate_hz: float, cameras: Mapping[str, FrameFile] | None = None) -> None:
        if writer.fps > rate_hz:
            raise ArgumentError(f"{writer.fps} fps is more frames than the {rate_hz:g} cycles a second the "
                                "follower's loop runs", fix=f"record at most {math.floor(rate_hz)} fps")
        self.writer = writer
        self.cameras = dict(cameras or {})
        if set(self.cameras) != set(writer.cameras):
            raise ArgumentError(f"cameras {sorted(self.cameras)} for a dataset of cameras {sorted(writer.cameras)}",
                                fix="make the writer with the recorder's cameras")
        self._images: dict[str, list[np.ndarray]] = {name: [] for name in self.cameras}
        self.fps = writer.fps
        self.task: str | None = None
        self._t0 = 0.0
        self._rows: list[tuple[np.ndarray, ...]] = []

    @property
    def cameras_ready(self) -> bool:
        """Every camera has drawn a picture (a camera's process takes a second or two to start)."""
        return all(frames.seq > 0 for frames in self.cameras.values())

    @property
    def recording(self) -> bool:
        """True between :meth:`begin` and :meth:`finish` or :meth:`discard`."""
        return self.task is not None

    @property
    def frames(self) -> int:
        """Frames of the episode so far."""
        return len(self._rows)

    @property
    def seconds(self) -> float:
        """The episode's length so far, s (its frames over the fps)."""
        return len(self._rows) / self.fps

    def begin(self, task: str, t0: float) -> None:
        """Start an episode doing ``task`` at clock time ``t0`` (s)."""
        if not isinstance(task, str) or not task.strip():
            raise ArgumentError("an episode needs a task: what is demonstrated", fix='e.g. --task "pick the cube"')
        self.task, self._t0, self._rows = task, t0, []
        self._images = {name: [] for name in self.cameras}

    def _pictures(self) -> None:
        """The newest picture of each camera, for the frame just taken (the last one again if none came
        since, black before the first)."""
        for name, frames in self.cameras.items():
            _, img = frames.latest()
            taken = self._images[name]
            if img is None:
                img = taken[-1] if taken else np.zeros((frames.height, frames.width, 3), np.uint8)
            taken.append(img)

    def add(self, step: Step) -> bool:
        """Take ``step`` as the next frame if its time has come; True if it did."""
        if self.task is None:
            return False
        if step.t + 1e-9 < self._t0 + len(self._rows) / self.fps:
            return False
        if len(self._rows) >= MAX_PATH_SAMPLES:
            return False  # the episode is as long as one may be: the caller ends it (full)
        row: tuple[np.ndarray, ...] = (step.follower_q, step.follower_dq, step.follower_tau, step.command)
        if step.gripper_command is not None:
            grip = (step.gripper_width, step.gripper_velocity, step.gripper_force, step.gripper_command)
            row = tuple(np.append(v, math.nan if g is None else g) for v, g in zip(row, grip, strict=True))
        if len(row[0]) != len(self.writer.joint_names):
            raise ArgumentError(f"a step of {len(row[0])} values for a dataset of {len(self.writer.joint_names)} "
                                f"({', '.join(self.writer.joint_names)})",
                                fix="make the writer with the follower's joints, and gripper if it has one")
        self._rows.append(row)
        self._pictures()
        return True

    @property
    def full(self) -> bool:
        """True when the episode has as many frames as one may (:data:`~akarm.motion.bounds.MAX_PATH_SAMPLES`)."""
        return len(self._rows) >= MAX_PATH_SAMPLES

    def finish(self) -> int | None:
        """Commit the episode (all of it, or nothing: :meth:`DatasetWriter.save_episode`); its index, or
        ``None`` if it has no frame."""
        if self.task is None:
            raise StateError("no episode is being recorded", fix="call begin() first")
        task, rows, images = self.task, self._rows, self._images
        self.task, self._rows, self._images = None, [], {name: [] for name in self.cameras}
        if not rows:
            return None
        cols = [np.array([r[k] for r in rows]) for k in range(4)]
        return self.writer.save_episode(task, EpisodeFrames(*cols), {name: np.stack(v) for name, v in images.items()})

    def discard(self) -> None:
        """Drop the episode being recorded (nothing of it is written)."""
        self.task, self._rows = None, []
        self._images = {name: [] for name in self.cameras}
