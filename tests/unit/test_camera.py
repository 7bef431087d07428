"""The simulated camera (akarm.sim.camera): what it draws changes as the arm, the jaws and the object
do; its frame and pose files pass whole frames between processes; cameras' frames go into a dataset
as video in LeRobot's layout, and akarm's reader finds them."""

from __future__ import annotations

import json

import numpy as np
import pytest

import akarm
from akarm.errors import ArgumentError
from akarm.sim.camera import ArmPainter, FrameFile, PoseFile

from ..conftest import ROBOTS


def drawn(img: np.ndarray) -> np.ndarray:
    """Pixels unlike their row's background (its first pixel)."""
    return np.abs(img.astype(int) - img[:, :1].astype(int)).max(axis=-1) > 40


def test_the_painter_draws_the_urdf_primitives_the_jaws_and_the_object():
    config = akarm.load_robot(ROBOTS / "arm6g.yaml")
    painter = ArmPainter(config, 96, 72)
    assert painter.drawn == "visuals" and painter.fingers and painter.left_out == []
    ready = np.array(config.poses["ready"])
    img = painter.draw(ready, 0.04)
    assert img.shape == (72, 96, 3) and img.dtype == np.uint8
    assert drawn(img).sum() > 100
    moved = painter.draw(np.array(config.poses["left"]), 0.04)
    assert (np.abs(moved.astype(int) - img).max(axis=-1) > 40).sum() > 30  # the arm turned: the picture changed
    closed = painter.draw(ready, 0.0)
    assert (closed != img).any(axis=-1).sum() > 0  # the fingers slide with the width
    def red(frame: np.ndarray) -> np.ndarray:
        r, g, b = (frame[..., c].astype(int) for c in range(3))
        return (r - g > 80) & (np.abs(g - b) < 10)

    held = painter.draw(ready, 0.04, 0.03)
    assert red(held).sum() >= 4 and not red(img).any()  # the object, between the jaws


def test_a_urdf_without_primitives_is_drawn_as_capsules_and_meshes_are_named(tmp_path):
    urdf = (ROBOTS / "planar2.urdf").read_text()
    start = urdf.index("<geometry>")
    end = urdf.index("</geometry>", start) + len("</geometry>")
    doc = urdf[:start] + '<geometry><mesh filename="link.stl"/></geometry>' + urdf[end:]
    import re

    doc = re.sub(r"<visual>(?:(?!</visual>).)*<(box|cylinder|sphere)[^>]*/>(?:(?!</visual>).)*</visual>", "", doc,
                 flags=re.S)
    (tmp_path / "planar2.urdf").write_text(doc)
    yaml_text = (ROBOTS / "planar2.yaml").read_text()
    (tmp_path / "planar2.yaml").write_text(yaml_text)
    painter = ArmPainter(akarm.load_robot(tmp_path / "planar2.yaml"), 64, 48)
    assert painter.drawn == "capsules" and painter.left_out and painter.left_out[0].endswith(": mesh")
    up, down = painter.draw([0.0, 0.0]), painter.draw([1.5, 0.0])
    assert drawn(up).sum() > 30 and (np.abs(up.astype(int) - down).max(axis=-1) > 40).sum() > 20


def test_frame_and_pose_files_pass_whole_frames():
    frames = FrameFile.create(32, 16)
    poses = PoseFile.create(3)
    try:
        assert frames.latest() == (0, None) and frames.seq == 0 and poses.read() is None
        other = FrameFile(frames.path, 32, 16)  # as the camera's process opens it
        img = np.random.default_rng(0).integers(0, 255, (16, 32, 3), dtype=np.uint8)
        assert other.write(img) == 1
        seq, got = frames.latest()
        assert seq == 1 and np.array_equal(got, img)
        other.close()
        assert frames.path.exists()  # only its maker removes it
        poses.write(np.array([0.1, -0.2, 0.3]), 0.05)
        pose = PoseFile(poses.path, 3).read()
        assert pose is not None and pose.q.tolist() == [0.1, -0.2, 0.3] and pose.gripper == 0.05
        poses.write(np.zeros(3))
        assert np.isnan(poses.read().gripper)  # type: ignore[union-attr]
    finally:
        frames.close()
        poses.close()
    assert not frames.path.exists() and not poses.path.exists()
    for bad in ((7, 16), (33, 16), (32, 0), (True, 16), (5000, 16)):
        with pytest.raises(ArgumentError, match="even number"):
            FrameFile.create(*bad)


def test_camera_frames_go_into_the_dataset_as_video(tmp_path):
    pytest.importorskip("pyarrow")
    pytest.importorskip("av")
    from akarm.datasets import DatasetWriter, EpisodeFrames, read_dataset
    from akarm.datasets.video import decode_video

    writer = DatasetWriter(tmp_path / "d", ["a", "b"], 30, robot_type="planar2", cameras={"front": (32, 24)})
    n = 12
    cols = [np.zeros((n, 2)) for _ in range(4)]
    video = np.zeros((n, 24, 32, 3), np.uint8)
    video[:, :, :16] = 200  # left half bright
    video[6:, 12:] = 90      # the lower half changes halfway
    with pytest.raises(ArgumentError, match="cameras"):
        writer.save_episode("t", EpisodeFrames(*cols))
    with pytest.raises(ArgumentError, match="shape"):
        writer.save_episode("t", EpisodeFrames(*cols), {"front": video[:5]})
    assert writer.save_episode("t", EpisodeFrames(*cols), {"front": video}) == 0
    assert writer.save_episode("t", EpisodeFrames(*cols), {"front": video[::-1].copy()}) == 1
    root = tmp_path / "d"
    info = json.loads((root / "meta/info.json").read_text())
    key = "observation.images.front"
    assert info["features"][key]["dtype"] == "video" and info["features"][key]["shape"] == [24, 32, 3]
    assert info["video_path"].format(video_key=key, chunk_index=0, file_index=1) == \
        f"videos/{key}/chunk-000/file-001.mp4"
    stats = json.loads((root / "meta/stats.json").read_text())[key]
    assert np.array(stats["mean"]).shape == (3, 1, 1) and 0.0 < stats["mean"][0][0][0] < 1.0
    ds = read_dataset(root)
    assert ds.video_keys == (key,)
    path, start, end = ds.video(1, key)
    assert path == root / "videos" / key / "chunk-000" / "file-001.mp4" and (start, end) == (0.0, 12 / 30)
    back = decode_video(path)
    assert back.shape == (n, 24, 32, 3) and np.abs(back.astype(int) - video[::-1]).mean() < 6
    with pytest.raises(akarm.RecordingError, match="other joints, cameras"):
        DatasetWriter(root, ["a", "b"], 30)  # the same dataset without its camera
    DatasetWriter(root, ["a", "b"], 30, cameras={"front": (32, 24)})  # with it: appends
