"""LeRobotDataset v3.0: what the writer puts on disk (LeRobot's layout, read back with pyarrow alone),
its commits (an episode is in or out, never half), and the reader's checks and bounds."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

from akarm.datasets import DatasetWriter, EpisodeFrames, read_dataset  # noqa: E402
from akarm.datasets import lerobot as lr  # noqa: E402
from akarm.errors import ArgumentError, RecordingError  # noqa: E402

JOINTS = ("shoulder", "elbow")


def frames(n: int, seed: int = 0) -> EpisodeFrames:
    x = np.random.default_rng(seed).normal(size=(n, len(JOINTS)))
    return EpisodeFrames(x, 2 * x, 3 * x, x + 0.5)


def three_episodes(root: Path, fps: int = 30) -> list[EpisodeFrames]:
    w = DatasetWriter(root, JOINTS, fps, robot_type="planar2")
    eps = [frames(40, 1), frames(55, 2), frames(31, 3)]
    for k, (ep, task) in enumerate(zip(eps, ["pick", "place", "pick"], strict=True)):
        assert w.save_episode(task, ep) == k
    return eps


def test_three_episodes_read_back_with_pyarrow_alone_in_lerobots_layout(tmp_path: Path) -> None:
    eps = three_episodes(tmp_path)
    files = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    assert files == ["data/chunk-000/file-000.parquet", "meta/episodes/chunk-000/file-000.parquet",
                     "meta/info.json", "meta/stats.json", "meta/tasks.parquet"]
    info = json.loads((tmp_path / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 30 and info["robot_type"] == "planar2"
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (3, 126, 2)
    assert info["features"]["action"] == {"dtype": "float32", "shape": [2], "names": list(JOINTS)}
    assert info["features"]["timestamp"] == {"dtype": "float32", "shape": [1], "names": None}

    data = pq.read_table(tmp_path / "data/chunk-000/file-000.parquet")
    assert set(data.column_names) == {"timestamp", "frame_index", "episode_index", "index", "task_index",
                                      "observation.state", "observation.velocity", "observation.effort", "action"}
    assert data.schema.field("action").type == pa.list_(pa.float32(), 2)
    ep_index = data.column("episode_index").to_numpy()
    assert ep_index.tolist() == [0] * 40 + [1] * 55 + [2] * 31
    assert data.column("index").to_numpy().tolist() == list(range(126))
    assert data.column("task_index").to_numpy().tolist() == [0] * 40 + [1] * 55 + [0] * 31
    t = data.column("timestamp").to_numpy()
    np.testing.assert_array_equal(t[ep_index == 1], (np.arange(55) / 30).astype(np.float32))  # fps matches
    np.testing.assert_array_equal(data.column("frame_index").to_numpy()[ep_index == 2], np.arange(31))
    action = np.array(data.column("action").to_pylist(), dtype=np.float32)
    np.testing.assert_array_equal(action[ep_index == 1], lr.to_float32(eps[1].action))
    state = np.array(data.column("observation.state").to_pylist(), dtype=np.float32)
    np.testing.assert_array_equal(state[:40], lr.to_float32(eps[0].state))
    assert pq.ParquetFile(tmp_path / "data/chunk-000/file-000.parquet").metadata.num_row_groups == 3

    episodes = pq.read_table(tmp_path / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert [(e["episode_index"], e["length"], e["tasks"], e["dataset_from_index"], e["dataset_to_index"])
            for e in episodes] == [(0, 40, ["pick"], 0, 40), (1, 55, ["place"], 40, 95), (2, 31, ["pick"], 95, 126)]
    tasks = pq.read_table(tmp_path / "meta/tasks.parquet")
    assert tasks.column("task").to_pylist() == ["pick", "place"] and tasks.column("task_index").to_pylist() == [0, 1]
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]  # pandas (LeRobot) sees the index
    stats = json.loads((tmp_path / "meta/stats.json").read_text())
    everything = lr.to_float32(np.concatenate([e.action for e in eps])).astype(float)
    np.testing.assert_allclose(stats["action"]["mean"], everything.mean(axis=0), rtol=1e-6)
    np.testing.assert_allclose(stats["action"]["std"], everything.std(axis=0), rtol=1e-6)
    np.testing.assert_allclose(stats["action"]["min"], everything.min(axis=0))
    assert stats["action"]["count"] == [126] and set(stats) >= {"timestamp", "index", "observation.effort"}


def test_the_reader_gives_an_episode_and_its_path_to_replay(tmp_path: Path) -> None:
    eps = three_episodes(tmp_path, fps=50)
    ds = read_dataset(tmp_path)
    assert (ds.total_episodes, ds.fps, ds.joint_names, ds.tasks) == (3, 50, JOINTS, ["pick", "place"])
    e = ds.episode(1)
    assert (e.index, e.task, len(e)) == (1, "place", 55)
    np.testing.assert_array_equal(e.features["observation.velocity"], lr.to_float32(eps[1].velocity))
    path = e.path()
    assert path.joint_names == JOINTS and path.duration == pytest.approx(54 / 50, abs=1e-6)
    np.testing.assert_array_equal(path.q, lr.to_float32(eps[1].action).astype(float))
    with pytest.raises(RecordingError, match="no episode 3: it has 3"):
        ds.episode(3)


def test_appending_later_continues_the_indices_and_refuses_other_joints_or_fps(tmp_path: Path) -> None:
    three_episodes(tmp_path)
    w = DatasetWriter(tmp_path, JOINTS, 30)
    assert w.save_episode("wave", frames(10)) == 3
    ds = read_dataset(tmp_path)
    assert ds.total_frames == 136 and ds.tasks == ["pick", "place", "wave"] and ds.episode(3).global_index[0] == 126
    with pytest.raises(RecordingError, match="other joints, cameras or fps"):
        DatasetWriter(tmp_path, JOINTS, 50)
    with pytest.raises(RecordingError, match="other joints, cameras or fps"):
        DatasetWriter(tmp_path, ("a", "b"), 30)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x.txt").write_text("x")
    with pytest.raises(RecordingError, match="not empty and holds no LeRobot dataset"):
        DatasetWriter(tmp_path / "other", JOINTS, 30)


def test_an_episode_cut_short_before_its_commit_is_not_in_the_dataset_and_is_dropped_on_reopening(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    three_episodes(tmp_path)
    before = (tmp_path / "meta/info.json").read_bytes()
    real = lr._write_json

    def crash_at_the_commit(path: Path, doc: object) -> Path:
        if path.name == "info.json":
            raise KeyboardInterrupt  # the process dies between the data files and the commit
        return real(path, doc)

    monkeypatch.setattr(lr, "_write_json", crash_at_the_commit)
    with pytest.raises(KeyboardInterrupt):
        DatasetWriter(tmp_path, JOINTS, 30).save_episode("pick", frames(20))
    monkeypatch.undo()
    assert (tmp_path / "meta/info.json").read_bytes() == before
    assert pq.read_metadata(tmp_path / "data/chunk-000/file-000.parquet").num_rows == 146  # its rows are there ...
    ds = read_dataset(tmp_path)
    assert (ds.total_episodes, ds.total_frames) == (3, 126)                                  # ... but not in it
    assert len(ds.episode(2)) == 31
    DatasetWriter(tmp_path, JOINTS, 30)                                   # reopening drops them
    assert pq.read_metadata(tmp_path / "data/chunk-000/file-000.parquet").num_rows == 126
    assert pq.read_metadata(tmp_path / "meta/episodes/chunk-000/file-000.parquet").num_rows == 3
    assert not list(tmp_path.rglob("*.tmp"))                               # and no temporary file was left


def test_bad_episodes_and_bad_datasets_are_refused_by_name(tmp_path: Path) -> None:
    w = DatasetWriter(tmp_path / "ds", JOINTS, 30)
    with pytest.raises(ArgumentError, match="at least one frame"):
        w.save_episode("pick", frames(0))
    bad = frames(5)
    bad.action[2, 1] = np.nan
    with pytest.raises(ArgumentError, match="finite"):
        w.save_episode("pick", bad)
    with pytest.raises(ArgumentError, match="a task"):
        w.save_episode(" ", frames(5))
    with pytest.raises(ArgumentError, match="fps"):
        DatasetWriter(tmp_path / "x", JOINTS, 29.97)  # type: ignore[arg-type]
    with pytest.raises(RecordingError, match="not a LeRobot dataset"):
        read_dataset(tmp_path / "nothing")
    three_episodes(tmp_path / "old")
    info = json.loads((tmp_path / "old/meta/info.json").read_text())
    (tmp_path / "old/meta/info.json").write_text(json.dumps(info | {"codebase_version": "v2.1"}))
    with pytest.raises(RecordingError, match=r"version 'v2\.1', not v3\.0"):
        read_dataset(tmp_path / "old")
    (tmp_path / "old/meta/info.json").write_text(json.dumps(info | {"total_episodes": 10**9}))
    with pytest.raises(RecordingError, match="at most 100000 episodes"):
        read_dataset(tmp_path / "old")
    (tmp_path / "old/meta/info.json").write_text(json.dumps(info))
    assert read_dataset(tmp_path / "old").episode(0).task == "pick"


def test_a_data_file_past_its_size_starts_the_next(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lr, "DATA_FILE_MB", 1e-6)  # every episode fills a file
    three_episodes(tmp_path)
    ds = read_dataset(tmp_path)
    assert [r["data/file_index"] for r in ds.episodes] == [0, 1, 2]
    assert len(ds.episode(2)) == 31 and ds.episode(1).global_index[0] == 40


def rewrite_column(root: Path, key: str, values: object, type_: object = None) -> None:
    """Replace column ``key`` of the first data file (a damaged or hand-edited dataset)."""
    path = root / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    table = table.set_column(table.column_names.index(key), key, pa.array(values, type_))
    pq.write_table(table, path)


@pytest.mark.parametrize(("action", "message"), [
    ([[0.0, 0.1, 0.2]] * 20, "has 3 values at frame 0; the dataset's joints are 2"),
    ([[0.0, 0.1]] * 19 + [[0.0]], "has 1 values at frame 19; the dataset's joints are 2"),
    ([[0.0, None]] * 20, "has 20 values that are null"),
    ([[0.0, 0.1]] * 10 + [None] * 10, "has 10 frames without a value"),
    ([[0.0, 0.1]] * 5 + [[0.0, float("nan")]] * 15, "has a value that is not finite at frame 5"),
    ([[0.0, 0.1]] * 7 + [[float("inf"), 0.0]] * 13, "has a value that is not finite at frame 7"),
])
def test_an_episodes_vectors_of_the_wrong_width_null_or_not_finite_are_refused(
        tmp_path: Path, action: list[list[float | None] | None], message: str) -> None:
    DatasetWriter(tmp_path, JOINTS, 30).save_episode("pick", frames(20))
    rewrite_column(tmp_path, "action", action, pa.list_(pa.float32()))
    data = tmp_path / "data/chunk-000/file-000.parquet"
    with pytest.raises(RecordingError, match="^" + re.escape(f"episode 0's action in {data} {message}")):
        read_dataset(tmp_path).episode(0)


def test_an_episode_built_with_values_that_are_not_finite_gives_no_path() -> None:
    q = np.zeros((4, 2))
    q[2, 1] = np.nan
    e = lr.Episode(0, "pick", 30, JOINTS, np.arange(4) / 30, np.arange(4), np.arange(4), {"action": q})
    with pytest.raises(RecordingError, match=r"^episode 0: action has a value that is not finite at frame 2"):
        e.path()
    e = lr.Episode(0, "pick", 30, JOINTS, np.arange(4) / 30, np.arange(4), np.arange(4), {"action": np.zeros((4, 3))})
    with pytest.raises(RecordingError, match=r"^episode 0: action is 4 × 3 values, not one per frame \(4\) and joint"):
        e.path()


def damage(root: Path, name: str, change: Callable[[Any], Any]) -> None:
    """Rewrite the parquet file ``name`` (``data`` or ``episodes``) with ``change(table)``."""
    path = root / ("data/chunk-000/file-000.parquet" if name == "data" else "meta/episodes/chunk-000/file-000.parquet")
    pq.write_table(change(pq.read_table(path)), path)


def set_column(key: str, values: list[Any], type_: object) -> Callable[[Any], Any]:
    return lambda t: t.set_column(t.column_names.index(key), key, pa.array(values * t.num_rows, type_))


@pytest.mark.parametrize(("name", "change", "message"), [
    ("data", lambda t: t.drop_columns(["timestamp"]), "data/chunk-000/file-000.parquet has no column 'timestamp'"),
    ("data", lambda t: t.drop_columns(["frame_index"]), "file-000.parquet has no column 'frame_index'"),
    ("data", set_column("episode_index", ["0"], pa.string()),
     "file-000.parquet: column 'episode_index' is of type string, not integers"),
    ("data", set_column("task_index", [None], pa.int64()), "file-000.parquet: column 'task_index' has 20 null values"),
    ("episodes", set_column("length", [None], pa.int64()), "file-000.parquet: column 'length' has 1 null values"),
    ("episodes", set_column("length", ["20"], pa.string()),
     "file-000.parquet: column 'length' is of type string, not integers"),
    ("episodes", set_column("episode_index", [None], pa.int64()),
     "file-000.parquet: column 'episode_index' has 1 null values"),
    ("episodes", set_column("episode_index", ["0"], pa.string()),
     "file-000.parquet: column 'episode_index' is of type string, not integers"),
])
def test_a_damaged_data_or_episodes_file_is_refused_by_name(tmp_path: Path, name: str, change: Callable[[Any], Any],
                                                            message: str) -> None:
    DatasetWriter(tmp_path, JOINTS, 30).save_episode("pick", frames(20))
    damage(tmp_path, name, change)
    with pytest.raises(RecordingError, match=re.escape(message)):
        read_dataset(tmp_path).episode(0)


def test_a_damaged_info_json_or_truncated_data_file_is_refused_by_name(tmp_path: Path) -> None:
    DatasetWriter(tmp_path, JOINTS, 30).save_episode("pick", frames(20))
    info = tmp_path / "meta/info.json"
    good = info.read_text()
    info.write_text("[" * 200_000)  # deeper than Python's JSON parser goes
    with pytest.raises(RecordingError, match=r"info\.json: its JSON is nested too deep"):
        read_dataset(tmp_path)
    doc = json.loads(good)
    doc["features"]["action"]["shape"] = [True]
    info.write_text(json.dumps(doc))
    with pytest.raises(RecordingError, match=r"the action's shape \[True\] is not a vector"):
        read_dataset(tmp_path)
    info.write_text(good)
    data = tmp_path / "data/chunk-000/file-000.parquet"
    with data.open("r+b") as f:
        f.truncate(200)
    with pytest.raises(RecordingError, match="^" + re.escape(f"cannot read {data}: ")):
        DatasetWriter(tmp_path, JOINTS, 30)
    with pytest.raises(RecordingError, match="^" + re.escape(f"cannot read {data}: ")):
        read_dataset(tmp_path).episode(0)


def test_only_the_columns_akarm_uses_are_read_within_max_parquet_bytes(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    DatasetWriter(tmp_path, JOINTS, 30).save_episode("pick", frames(20))
    data = tmp_path / "data/chunk-000/file-000.parquet"
    table = pq.read_table(data)
    junk = pa.array([bytes(1 << 20)] * table.num_rows, pa.binary())  # 20 MiB of zeros: a few kB in zstd
    pq.write_table(table.append_column("junk", junk), data, compression="zstd", use_dictionary=False)
    assert data.stat().st_size < 100_000
    monkeypatch.setattr(lr, "MAX_PARQUET_BYTES", 1 << 20)
    assert len(read_dataset(tmp_path).episode(0)) == 20  # the junk column is not read, nor counted

    def message(limit: str) -> str:
        return re.escape(f"{data}: what akarm reads of it is ") + r"[\d ]+" + re.escape(
            f" bytes uncompressed, over the limit of {limit} bytes (MAX_PARQUET_BYTES)")

    with pytest.raises(RecordingError, match=message("1 048 576")):
        DatasetWriter(tmp_path, JOINTS, 30)  # the writer rewrites every column: it reads them all
    ds = read_dataset(tmp_path)
    monkeypatch.setattr(lr, "MAX_PARQUET_BYTES", 1000)  # now the episode's own columns are past it
    with pytest.raises(RecordingError, match=message("1 000")):
        ds.episode(0)


def test_an_episode_held_at_a_joints_limit_reads_back_within_it_and_replays(tmp_path: Path) -> None:
    from akarm import load_robot
    from akarm.motion.recording import PathPlan, check_path
    from akarm.motion.trajectory import JointLimits

    from ..conftest import ROBOTS

    config = load_robot(ROBOTS / "planar2.yaml")
    limits = JointLimits(config.joint_names, *(np.array([getattr(j.limits, k) for j in config.joints]) for k in
                                               ("lower", "upper", "velocity", "acceleration", "jerk")))
    upper, lower = limits.upper[1], limits.lower[0]
    assert float(np.float32(upper)) > upper  # 2.4 rad: its nearest float32 is past the limit
    t = np.arange(120) / 30
    elbow = np.minimum(upper, upper - 0.05 + 0.025 * t)  # teleop's np.clip at the edge: exactly the limit
    shoulder = np.maximum(lower, lower + 0.05 - 0.025 * t)
    action = np.column_stack([shoulder, elbow])
    DatasetWriter(tmp_path, config.joint_names, 30).save_episode("edge", EpisodeFrames(action, action, 0 * action,
                                                                                       action))
    path = read_dataset(tmp_path).episode(0).path()
    assert path.q[:, 1].max() <= upper and path.q[:, 0].min() >= lower
    assert path.q[:, 1].max() == pytest.approx(upper, abs=1e-6)
    check_path(PathPlan(path, 0.0, 1.0), limits)  # refused (2.4000000954 rad) before


def test_to_float32_rounds_toward_zero_only_where_the_cast_grew_the_value() -> None:
    x = np.array([2.4, -2.4, 0.1, -0.1, 0.5, 0.0, 1e39, np.nan])
    with np.errstate(over="ignore"):
        y = lr.to_float32(x)
    assert y.dtype == np.float32
    assert np.all(np.abs(y[:6].astype(float)) <= np.abs(x[:6]))
    assert y[4] == np.float32(0.5) and y[5] == 0.0                  # exact values are kept
    assert np.all(np.abs(y[:4].astype(float) - x[:4]) <= np.spacing(np.abs(y[:4])))  # one float32 step at most
    assert np.isinf(y[6]) and np.isnan(y[7])                          # still refused as not finite


def test_a_crash_in_the_first_episodes_commit_leaves_a_dataset_of_none_that_reopens(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    w = DatasetWriter(tmp_path, JOINTS, 30)
    ds = read_dataset(tmp_path)  # a new writer commits a dataset of no episodes at once
    assert (ds.total_episodes, ds.total_frames, ds.joint_names, ds.episodes) == (0, 0, JOINTS, [])
    real = lr._write_json

    def crash_at_the_commit(path: Path, doc: object) -> Path:
        if path.name == "info.json":
            raise KeyboardInterrupt  # the power is cut between the data files and the first commit
        return real(path, doc)

    monkeypatch.setattr(lr, "_write_json", crash_at_the_commit)
    with pytest.raises(KeyboardInterrupt):
        w.save_episode("pick", frames(20))
    monkeypatch.undo()
    assert (tmp_path / "data/chunk-000/file-000.parquet").exists()
    assert read_dataset(tmp_path).total_episodes == 0
    w = DatasetWriter(tmp_path, JOINTS, 30)  # refused before: "is not empty and holds no LeRobot dataset"
    assert w.total_episodes == 0
    assert not (tmp_path / "data/chunk-000/file-000.parquet").exists()  # the cut episode's rows are dropped
    assert not (tmp_path / "meta/episodes/chunk-000/file-000.parquet").exists()
    assert w.save_episode("place", frames(15)) == 0
    ds = read_dataset(tmp_path)
    assert (ds.total_episodes, len(ds.episode(0)), ds.episode(0).task) == (1, 15, "place")


def test_a_gripper_is_the_last_value_named_gripper_and_stays_out_of_the_replayed_path(tmp_path: Path) -> None:
    n = 20
    q = np.random.default_rng(7).normal(size=(n, len(JOINTS)))
    width = np.linspace(0.08, 0.03, n)[:, None]  # m: closing on something
    asked = np.linspace(0.08, 0.0, n)[:, None]
    names = (*JOINTS, lr.GRIPPER)
    DatasetWriter(tmp_path, names, 30).save_episode("grasp", EpisodeFrames(
        np.hstack([q, width]), np.hstack([2 * q, np.gradient(width, axis=0) * 30]), np.hstack([3 * q, 0 * width + 20]),
        np.hstack([q + 0.5, asked])))
    info = json.loads((tmp_path / "meta/info.json").read_text())
    for key in ("observation.state", "action"):
        assert info["features"][key]["names"] == ["shoulder", "elbow", "gripper"]
    data = pq.read_table(tmp_path / "data/chunk-000/file-000.parquet")
    state = np.array(data.column("observation.state").to_pylist())
    np.testing.assert_allclose(state[:, 2], width[:, 0], rtol=1e-6)
    e = read_dataset(tmp_path).episode(0)
    assert e.has_gripper and e.arm_names == JOINTS
    path = e.path()
    assert path.joint_names == JOINTS and path.q.shape == (n, 2)
    np.testing.assert_allclose(e.gripper(), asked[:, 0], rtol=1e-6)
    np.testing.assert_allclose(e.gripper("observation.state"), width[:, 0], rtol=1e-6)
    plain = tmp_path / "plain"
    three_episodes(plain)
    assert read_dataset(plain).episode(0).gripper() is None
