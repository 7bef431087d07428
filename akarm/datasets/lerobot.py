"""Episodes as a LeRobotDataset v3.0: the layout LeRobot's own ``lerobot record`` writes and its
``LeRobotDataset`` loads, so that what a teleoperation session recorded trains a policy as it is.

::

    DIR/meta/info.json                          codebase_version "v3.0", fps, features, totals, paths
    DIR/meta/stats.json                         per feature: min, max, mean, std, count, q01 ... q99
    DIR/meta/tasks.parquet                      task (the index, as pandas writes it) → task_index
    DIR/meta/episodes/chunk-000/file-000.parquet  one row per episode: length, tasks, where its frames are,
                                                its own stats (``stats/<feature>/<stat>``)
    DIR/data/chunk-000/file-000.parquet         one row per frame, one row group per episode:
        timestamp (s from the episode's start, frame_index / fps), frame_index, episode_index,
        index (across the dataset), task_index, observation.state (measured positions, rad),
        observation.velocity (rad/s), observation.effort (N·m), action (the commanded positions, rad)

Cameras (a writer made with ``cameras``) add a feature ``observation.images.<name>`` each, of dtype
``video``, stored as LeRobot stores them: ``DIR/videos/observation.images.<name>/chunk-000/file-NNN.mp4``
(one file per episode here; LeRobot's own may hold several, the episodes file says where each
episode is: ``videos/<key>/chunk_index``, ``file_index``, ``from_timestamp``, ``to_timestamp``),
encoded by :mod:`akarm.datasets.video` (the ``video`` extra; in a process of its own), with the
video's ``info`` in info.json and per-channel stats (0-1) in stats.json, so LeRobot's
``LeRobotDataset`` loads the frames.

The vector features are float32 lists of one value per joint; their ``names`` in info.json are the
joint names. A robot with a gripper has one more value, last, named :data:`GRIPPER` (``gripper``):
the width between the jaws (m) in ``observation.state`` and ``action`` (measured, asked), its rate
(m/s) in ``observation.velocity`` and the squeeze (N) in ``observation.effort``, as LeRobot's robots
put their gripper last in the same vectors. Written with pyarrow (the ``data`` extra).

**Never half-written.** An episode is committed by rewriting, each atomically (:mod:`akarm.files`),
the data file it goes into, the episodes file, the tasks file, stats.json, and last info.json, whose
totals are the commit: a reader believes info.json (a new dataset's, of no episodes, is written when
its writer is made, so that the first episode is no different). An episode cut short (Ctrl-C, a crash) before its
info.json was written is not in the dataset; the rows it may have left in a data or episodes file are
dropped when a writer opens the dataset again (before anything else is written). A data file grows
to :data:`DATA_FILE_MB` (as LeRobot's own), then the next one starts.

**Bounds.** A reader refuses, naming the bound, before reading in full: JSON files over
:data:`MAX_JSON_BYTES`, more than :data:`MAX_EPISODES` episodes, vectors wider than
:data:`MAX_JOINTS`, an episode longer than :data:`~akarm.motion.bounds.MAX_PATH_SAMPLES` frames or
:data:`~akarm.motion.bounds.MAX_DURATION` s, a data file of more than :data:`MAX_FILE_ROWS` rows,
more than :data:`MAX_PARQUET_BYTES` uncompressed of a Parquet file's columns that are read (only the
columns akarm uses are read: a column of anything else costs nothing).
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm.errors import ArgumentError, RecordingError
from akarm.files import atomic_write, check_writable, number, over
from akarm.motion.bounds import MAX_DURATION, MAX_PATH_SAMPLES
from akarm.motion.recording import PathRecording

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = ["CODEBASE_VERSION", "DATA_FILE_MB", "GRIPPER", "IMAGES", "MAX_EPISODES", "MAX_FILE_ROWS", "MAX_JOINTS",
           "MAX_JSON_BYTES", "MAX_PARQUET_BYTES", "VECTORS", "DatasetWriter", "Episode", "EpisodeFrames",
           "LeRobotDataset", "read_dataset", "to_float32"]

CODEBASE_VERSION = "v3.0"
#: The per-joint features of a frame: key → what it holds (info.json's features, float32 per joint).
VECTORS = {
    "observation.state": "measured positions, rad",
    "observation.velocity": "measured velocities, rad/s",
    "observation.effort": "measured torques, N·m",
    "action": "commanded positions, rad",
}
#: The name of the gripper's value in the vector features (its width, m, in ``observation.state`` and
#: ``action``), whatever the robot file names the gripper: what LeRobot's policies look for.
GRIPPER = "gripper"
#: A data file is closed and the next one started past this size (LeRobot's own default).
DATA_FILE_MB = 100
#: Files per chunk folder (LeRobot's default).
CHUNKS_SIZE = 1000
#: JSON files (info.json, stats.json) larger than this are refused unread.
MAX_JSON_BYTES = 16 << 20
#: Episodes in one dataset.
MAX_EPISODES = 100_000
#: Values in one vector feature (joints).
MAX_JOINTS = 64
#: Rows in one data file (a LeRobot data file of 100 MB holds a few million).
MAX_FILE_ROWS = 4 * MAX_PATH_SAMPLES
#: Bytes, uncompressed, of what is read of one Parquet file: the columns akarm reads, in the row groups
#: it reads (an episode of 2 000 000 frames of 6 joints is about 300 MB; a data file is 100 MB compressed).
MAX_PARQUET_BYTES = 512 << 20
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  # the quantiles LeRobot's stats carry (q01 ... q99)
SCALARS = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64", "index": "int64",
           "task_index": "int64"}
INFO = "meta/info.json"
STATS = "meta/stats.json"
TASKS = "meta/tasks.parquet"
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"
#: A camera's feature key is this and its name (LeRobot's robots' cameras are "observation.images.<name>").
IMAGES = "observation.images."
EPISODES_PATH = "meta/episodes/" + CHUNK_FILE + ".parquet"


def _arrow() -> tuple[Any, Any]:
    """pyarrow and pyarrow.parquet, or a RecordingError saying how to install them."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise RecordingError("LeRobot datasets need pyarrow, which is not installed",
                             fix='pip install "akarm[data]" (or pip install pyarrow)') from None
    return pa, pq


@dataclass(frozen=True)
class EpisodeFrames:
    """One episode's frames, one row per frame (taken at the dataset's fps), one column per joint:
    measured positions (rad), velocities (rad/s), torques (N·m) and the commanded positions (rad)."""

    state: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    action: np.ndarray

    def __post_init__(self) -> None:
        shapes = {np.shape(getattr(self, f)) for f in ("state", "velocity", "effort", "action")}
        if len(shapes) != 1 or len(next(iter(shapes))) != 2:
            raise ArgumentError(f"an episode's state, velocity, effort and action must be arrays of one shape "
                                f"(frames × joints), got {sorted(shapes)}",
                                fix="one row per frame, one column per joint")

    def __len__(self) -> int:
        return int(np.shape(self.state)[0])

    def columns(self) -> dict[str, np.ndarray]:
        """The vector features by key (:data:`VECTORS`), float32 (:func:`to_float32`)."""
        return {key: to_float32(v) for key, v in
                zip(VECTORS, (self.state, self.velocity, self.effort, self.action), strict=True)}


def to_float32(values: Any) -> np.ndarray:
    """``values`` as float32, each rounded toward zero where the nearest float32 is farther from zero:
    a value within a range that contains 0 stays within it (a joint held at its limit, 2.4 rad, would
    read back as 2.4000000954 and be refused by the replay's limit check)."""
    exact = np.asarray(values, dtype=np.float64)
    out = exact.astype(np.float32)
    with np.errstate(invalid="ignore"):
        grown = np.isfinite(out) & (np.abs(out.astype(np.float64)) > np.abs(exact))
    out[grown] = np.nextafter(out[grown], np.float32(0))
    return out


@dataclass(frozen=True)
class Episode:
    """One episode read back: its index, task, fps, and per frame ``timestamp`` (s), ``frame_index``,
    ``index`` and each vector feature (frames × joints, float32) by key."""

    index: int
    task: str
    fps: int
    joint_names: tuple[str, ...]
    timestamp: np.ndarray
    frame_index: np.ndarray
    global_index: np.ndarray
    features: Mapping[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.timestamp)

    @property
    def has_gripper(self) -> bool:
        """True if the vectors end with the gripper's value (named :data:`GRIPPER`)."""
        return bool(self.joint_names) and self.joint_names[-1] == GRIPPER

    @property
    def arm_names(self) -> tuple[str, ...]:
        """The arm's joints: :attr:`joint_names` without the gripper's."""
        return self.joint_names[:-1] if self.has_gripper else self.joint_names

    def _values(self, key: str) -> np.ndarray:
        if key not in self.features:
            raise RecordingError(f"episode {self.index} has no feature {key!r}",
                                 fix="features are: " + ", ".join(self.features))
        q = np.asarray(self.features[key], dtype=float)
        if q.shape != (len(self.timestamp), len(self.joint_names)):
            raise RecordingError(f"episode {self.index}: {key} is {' × '.join(map(str, q.shape))} values, not one per "
                                 f"frame ({len(self.timestamp)}) and joint ({len(self.joint_names)})",
                                 fix="the dataset is damaged; record it again")
        bad = ~np.isfinite(q).all(axis=1)
        if bad.any():
            raise RecordingError(f"episode {self.index}: {key} has a value that is not finite at frame "
                                 f"{int(np.argmax(bad))}", fix="the dataset is damaged; record it again")
        return q

    def path(self, key: str = "action") -> PathRecording:
        """The feature ``key`` (default: the commanded positions) of the arm's joints (the gripper's
        value left out: :meth:`gripper`) as a path to replay (:meth:`akarm.Arm.replay`), at its recorded timing."""
        q = self._values(key)
        return PathRecording(self.arm_names, self.timestamp.astype(float), q[:, :len(self.arm_names)])

    def gripper(self, key: str = "action") -> np.ndarray | None:
        """The gripper's value of the feature ``key`` per frame (default: the width asked, m), or None
        if the episode has no gripper."""
        return self._values(key)[:, -1].copy() if self.has_gripper else None


def _feature_spec(names: Sequence[str], cameras: Mapping[str, tuple[int, int]] | None = None,
                  fps: int = 30) -> dict[str, Any]:
    spec: dict[str, Any] = {key: {"dtype": "float32", "shape": [len(names)], "names": list(names)} for key in VECTORS}
    for name, (width, height) in (cameras or {}).items():
        from akarm.datasets.video import video_info

        spec[IMAGES + name] = {"dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channels"],
                               "info": video_info(height, width, fps)}
    spec.update({key: {"dtype": dtype, "shape": [1], "names": None} for key, dtype in SCALARS.items()})
    return spec


def _stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """min, max, mean, std, count and the quantiles of a (frames × width) array, per column."""
    x = np.asarray(values, dtype=np.float64)
    out = {"min": x.min(axis=0), "max": x.max(axis=0), "mean": x.mean(axis=0), "std": x.std(axis=0),
           "count": np.array([len(x)])}
    for q in QUANTILES:
        out[f"q{round(q * 100):02d}"] = np.quantile(x, q, axis=0)
    return out


def _aggregate(parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Stats of several episodes together: exact count, min, max, mean and std; the quantiles as the
    count-weighted mean of the episodes' (as LeRobot aggregates them)."""
    counts = np.array([float(p["count"][0]) for p in parts])
    w = counts / counts.sum()
    mean = sum(wi * np.asarray(p["mean"], dtype=float) for wi, p in zip(w, parts, strict=True))
    second = sum(wi * (np.asarray(p["std"], dtype=float) ** 2 + np.asarray(p["mean"], dtype=float) ** 2)
                 for wi, p in zip(w, parts, strict=True))
    out = {"min": np.min([p["min"] for p in parts], axis=0), "max": np.max([p["max"] for p in parts], axis=0),
           "mean": np.asarray(mean), "std": np.sqrt(np.maximum(np.asarray(second) - np.asarray(mean) ** 2, 0.0)),
           "count": np.array([int(counts.sum())])}
    for key in parts[0]:
        if key.startswith("q"):
            out[key] = np.asarray(sum(wi * np.asarray(p[key], dtype=float) for wi, p in zip(w, parts, strict=True)))
    return out


def _read_json(path: Path) -> Any:
    try:
        size = path.stat().st_size
        if size > MAX_JSON_BYTES:
            raise RecordingError(f"{path} is {size} bytes, over the {MAX_JSON_BYTES} bytes a dataset's JSON may have",
                                 fix="is this a LeRobot dataset's meta folder?")
        return json.loads(path.read_text(encoding="utf-8"))
    except RecursionError:  # JSON nested deeper than Python's parser goes ([[[[...)
        raise RecordingError(f"cannot read {path}: its JSON is nested too deep",
                             fix="pass a LeRobot v3.0 dataset folder") from None
    except (OSError, ValueError, UnicodeDecodeError) as e:
        raise RecordingError(f"cannot read {path}: {e}", fix="pass a LeRobot v3.0 dataset folder") from None


def _is_integers(t: pa.DataType) -> bool:
    pa, _ = _arrow()
    return bool(pa.types.is_integer(t))


def _is_numbers(t: pa.DataType) -> bool:
    pa, _ = _arrow()
    return bool(pa.types.is_integer(t) or pa.types.is_floating(t))


def _is_texts(t: pa.DataType) -> bool:
    pa, _ = _arrow()
    return bool((pa.types.is_list(t) or pa.types.is_large_list(t))
                and (pa.types.is_string(t.value_type) or pa.types.is_large_string(t.value_type)))


#: The columns of a data file akarm reads besides the vector features, and the types they must have.
DATA_COLUMNS = {"timestamp": _is_numbers, "frame_index": _is_integers, "episode_index": _is_integers,
                "index": _is_integers, "task_index": _is_integers}
#: The columns of an episodes file akarm reads, and the types they must have.
EPISODE_COLUMNS = {"episode_index": _is_integers, "tasks": _is_texts, "length": _is_integers,
                   "dataset_from_index": _is_integers, "dataset_to_index": _is_integers,
                   "data/chunk_index": _is_integers, "data/file_index": _is_integers}


def _check_schema(schema: pa.Schema, path: Path, columns: Mapping[str, Any]) -> None:
    """Refuse a file without one of ``columns`` (name → a check of its Arrow type) or with another type."""
    for name, check in columns.items():
        if name not in schema.names:
            raise RecordingError(f"{path} has no column {name!r}", fix="the dataset is damaged; record it again")
        t = schema.field(name).type
        if not check(t):
            raise RecordingError(f"{path}: column {name!r} is of type {t}, not {check.__name__[4:]}",
                                 fix="the dataset is damaged; record it again")


def _check_nulls(table: pa.Table, path: Path, columns: Sequence[str]) -> None:
    for name in columns:
        nulls = table.column(name).null_count
        if nulls:
            raise RecordingError(f"{path}: column {name!r} has {nulls} null values",
                                 fix="the dataset is damaged; record it again")


def _check_bytes(meta: Any, path: Path, columns: Sequence[str] | None, groups: Sequence[int] | None = None) -> None:
    """Refuse a Parquet file (its metadata ``meta``) whose ``columns`` (``None``: all) in its row groups
    ``groups`` (``None``: all) hold more than :data:`MAX_PARQUET_BYTES` uncompressed."""
    total = 0
    for g in range(meta.num_row_groups) if groups is None else groups:
        group = meta.row_group(g)
        for i in range(group.num_columns):
            column = group.column(i)
            leaf = column.path_in_schema  # "action.list.element" of column "action"
            if columns is None or any(leaf == name or leaf.startswith(name + ".") for name in columns):
                total += column.total_uncompressed_size
    if total > MAX_PARQUET_BYTES:
        raise RecordingError(over(f"{path}: what akarm reads of it is {number(total)} bytes uncompressed",
                                  MAX_PARQUET_BYTES, "bytes", "MAX_PARQUET_BYTES"),
                             fix="is it the right file? a LeRobot data file holds 100 MB")


def _read_table(path: Path, columns: Sequence[str] | None = None) -> pa.Table:
    """A parquet file (only ``columns``, if given) within :data:`MAX_PARQUET_BYTES`, a RecordingError
    if it cannot be read."""
    pa, pq = _arrow()
    try:
        f = pq.ParquetFile(path)
        _check_bytes(f.metadata, path, columns)
        return f.read(columns=None if columns is None else list(columns))
    except (OSError, ValueError, KeyError, pa.ArrowException) as e:
        raise RecordingError(f"cannot read {path}: {e}", fix="the dataset is damaged; record it again") from None


def _vectors(column: pa.ChunkedArray, width: int, what: str) -> np.ndarray:
    """A vector feature's column as a (frames × ``width``) float32 array: lists of ``width`` numbers,
    none of them null nor NaN nor infinite (a RecordingError saying ``what`` otherwise)."""
    pa, _ = _arrow()
    import pyarrow.compute as pc

    damaged = "the dataset is damaged; record it again"
    t = column.type
    if not ((pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t))
            and (pa.types.is_floating(t.value_type) or pa.types.is_integer(t.value_type))):
        raise RecordingError(f"{what} is of type {t}, not a list of numbers per frame", fix=damaged)
    if column.null_count:
        raise RecordingError(f"{what} has {column.null_count} frames without a value", fix=damaged)
    lengths = pc.list_value_length(column).to_numpy(zero_copy_only=False)
    if len(lengths) and (lengths.min() != width or lengths.max() != width):
        odd = int(np.argmax(lengths != width))
        raise RecordingError(f"{what} has {int(lengths[odd])} values at frame {odd}; the dataset's joints are {width}",
                             fix=damaged)
    flat = pc.list_flatten(column)
    if flat.null_count:
        raise RecordingError(f"{what} has {flat.null_count} values that are null", fix=damaged)
    values = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=np.float32).reshape(len(lengths), width)
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise RecordingError(f"{what} has a value that is not finite at frame {int(np.argmax(bad))}", fix=damaged)
    return values


def _write_parquet(path: Path, table: pa.Table) -> Path:
    _, pq = _arrow()
    return atomic_write(path, lambda f: pq.write_table(table, f, compression="snappy"))


def _write_json(path: Path, doc: Any) -> Path:
    text = json.dumps(doc, indent=4) + "\n"
    return atomic_write(path, lambda f: f.write(text.encode("utf-8")))


def _tasks_table(tasks: Sequence[str]) -> pa.Table:
    """meta/tasks.parquet as pandas writes a DataFrame indexed by task (LeRobot reads it with pandas)."""
    pa, _ = _arrow()
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()),
                      "task": pa.array(list(tasks), pa.string())})
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                            "metadata": {"encoding": "UTF-8"}}],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
                     "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
                     "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()})


class LeRobotDataset:
    """A LeRobot v3.0 dataset on disk, read within bounds (see the module's docstring).

    Attributes:
        root: its folder. info: meta/info.json. fps, total_episodes, total_frames, joint_names.
        video_keys: its cameras' features (``observation.images.<name>``, stored as video; :meth:`video`).
        tasks: the task texts by task_index. episodes: one dict per episode (episode_index, tasks,
            length, dataset_from_index, dataset_to_index, data/chunk_index, data/file_index).
    """

    def __init__(self, root: str | os.PathLike[str]) -> None:
        pa, pq = _arrow()
        self.root = Path(root)
        if not (self.root / INFO).is_file():
            raise RecordingError(f"{self.root} is not a LeRobot dataset (no {INFO})",
                                 fix="pass the folder given to --record (it holds meta/ and data/)")
        info = _read_json(self.root / INFO)
        if not isinstance(info, dict) or info.get("codebase_version") != CODEBASE_VERSION:
            version = info.get("codebase_version") if isinstance(info, dict) else None
            raise RecordingError(f"{self.root} is a LeRobot dataset of version {version!r}, not {CODEBASE_VERSION}",
                                 fix="convert it with LeRobot's convert_dataset_v21_to_v30, or record it again")
        self.info = info
        fps, episodes, frames = info.get("fps"), info.get("total_episodes"), info.get("total_frames")
        if not (isinstance(fps, int) and fps > 0 and isinstance(episodes, int) and isinstance(frames, int)
                and 0 <= episodes <= MAX_EPISODES and frames >= 0):
            raise RecordingError(f"{self.root / INFO}: fps {fps!r}, total_episodes {episodes!r}, total_frames "
                                 f"{frames!r} are not a dataset's (at most {MAX_EPISODES} episodes)",
                                 fix="pass a LeRobot v3.0 dataset folder")
        self.fps: int = fps
        self.total_episodes: int = episodes
        self.total_frames: int = frames
        features = info.get("features")
        if not isinstance(features, dict):
            raise RecordingError(f"{self.root / INFO} has no features", fix="pass a LeRobot v3.0 dataset folder")
        self.features: dict[str, Any] = features
        self.video_keys: tuple[str, ...] = tuple(k for k, v in features.items()
                                                 if isinstance(v, dict) and v.get("dtype") == "video")
        self.joint_names = self._names()
        self.tasks = self._tasks(pa, pq)
        self.episodes = self._episodes(pa, pq)

    def _names(self) -> tuple[str, ...]:
        spec = self.features.get("action") or self.features.get("observation.state")
        names = spec.get("names") if isinstance(spec, dict) else None
        shape = spec.get("shape") if isinstance(spec, dict) else None
        if isinstance(names, dict):  # LeRobot's older {"motors": [...]} form
            names = next(iter(names.values()), None)
        if not (isinstance(shape, list) and len(shape) == 1 and isinstance(shape[0], int)
                and not isinstance(shape[0], bool) and 0 < shape[0] <= MAX_JOINTS):
            raise RecordingError(f"{self.root / INFO}: the action's shape {shape!r} is not a vector of at most "
                                 f"{MAX_JOINTS} values", fix="pass a dataset of joint positions")
        if not (isinstance(names, list) and len(names) == shape[0] and all(isinstance(n, str) for n in names)):
            return tuple(f"joint_{k}" for k in range(shape[0]))
        # LeRobot's robots name positions "<motor>.pos": the joint is the motor
        return tuple(n[:-4] if n.endswith(".pos") else n for n in names)

    def _tasks(self, pa: Any, pq: Any) -> list[str]:
        path = self.root / TASKS
        if not path.is_file():
            return []
        try:
            f = pq.ParquetFile(path)
            if f.metadata.num_rows > MAX_EPISODES:
                raise RecordingError(f"{path} has {f.metadata.num_rows} tasks, over {MAX_EPISODES}",
                                     fix="pass a LeRobot v3.0 dataset folder")
            if "task" not in f.schema_arrow.names or "task_index" not in f.schema_arrow.names:
                raise RecordingError(f"{path} has no task and task_index columns",
                                     fix="pass a LeRobot v3.0 dataset folder")
            _check_bytes(f.metadata, path, ["task", "task_index"])
            table = f.read(columns=["task", "task_index"])
        except (OSError, ValueError, KeyError, pa.ArrowException) as e:
            raise RecordingError(f"cannot read {path}: {e}", fix="pass a LeRobot v3.0 dataset folder") from None
        by_index = dict(zip(table.column("task_index").to_pylist(), table.column("task").to_pylist(), strict=True))
        return [str(by_index.get(k, "")) for k in range(len(by_index))]

    def _episodes(self, pa: Any, pq: Any) -> list[dict[str, Any]]:
        rows: list[dict[str, Any]] = []
        folder = self.root / "meta" / "episodes"
        keys = tuple(EPISODE_COLUMNS)
        for path in sorted(folder.glob("*/*.parquet")) if folder.is_dir() else []:
            try:
                f = pq.ParquetFile(path)
                if f.metadata.num_rows > MAX_EPISODES:
                    raise RecordingError(f"{path} lists more than {MAX_EPISODES} episodes",
                                         fix="pass a LeRobot v3.0 dataset folder")
                _check_schema(f.schema_arrow, path, EPISODE_COLUMNS)
                _check_bytes(f.metadata, path, keys)
                table = f.read(columns=list(keys))
            except (OSError, ValueError, KeyError, pa.ArrowException) as e:
                raise RecordingError(f"cannot read {path}: {e}", fix="pass a LeRobot v3.0 dataset folder") from None
            _check_nulls(table, path, [key for key in keys if key != "tasks"])
            rows += table.to_pylist()
        rows = sorted((r for r in rows if r["episode_index"] < self.total_episodes), key=lambda r: r["episode_index"])
        if [r["episode_index"] for r in rows] != list(range(self.total_episodes)):
            raise RecordingError(f"{self.root}: meta/episodes does not list episodes 0 to {self.total_episodes - 1}",
                                 fix="the dataset is damaged; record it again")
        return rows

    def episode(self, k: int) -> Episode:
        """Episode ``k``'s frames, read from its data file alone (its row group where there is one).

        Raises:
            RecordingError: no such episode, its frames are missing or past a bound, its timestamps
                do not follow the fps.
        """
        pa, pq = _arrow()
        if not (isinstance(k, int) and 0 <= k < self.total_episodes):
            raise RecordingError(f"{self.root} has no episode {k!r}: it has {self.total_episodes} "
                                 f"(0 to {self.total_episodes - 1})", fix="pass --episode within them")
        row = self.episodes[k]
        length = row["length"]
        if not 0 < length <= MAX_PATH_SAMPLES or length / self.fps > MAX_DURATION:
            raise RecordingError(f"episode {k} has {length} frames at {self.fps} fps: more than the "
                                 f"{MAX_PATH_SAMPLES} frames or {MAX_DURATION:.0f} s an episode may have",
                                 fix="split the episode, or record it again")
        path = self.root / DATA_PATH.format(chunk_index=row["data/chunk_index"], file_index=row["data/file_index"])
        try:
            f = pq.ParquetFile(path)
            if f.metadata.num_rows > MAX_FILE_ROWS:
                raise RecordingError(f"{path} has {f.metadata.num_rows} rows, over {MAX_FILE_ROWS}",
                                     fix="split the dataset's data files")
            _check_schema(f.schema_arrow, path, DATA_COLUMNS)
            width = len(self.joint_names)
            vectors = [key for key in self.features if key in f.schema_arrow.names and key not in SCALARS
                       and isinstance(self.features[key], dict) and self.features[key].get("shape") == [width]]
            columns = [*DATA_COLUMNS, *vectors]  # only these: another column (images, anything) is not read
            groups = self._row_groups(f, k)
            _check_bytes(f.metadata, path, columns, groups)
            table = f.read_row_groups(groups, columns=columns) if groups is not None else f.read(columns=columns)
        except (OSError, ValueError, pa.ArrowException) as e:
            raise RecordingError(f"cannot read {path}: {e}", fix="the dataset is damaged; record it again") from None
        _check_nulls(table, path, list(DATA_COLUMNS))
        index = np.asarray(table.column("episode_index").to_numpy(zero_copy_only=False))
        table = table.filter(pa.array(index == k))
        if table.num_rows != length:
            raise RecordingError(f"episode {k} has {table.num_rows} frames in {path}, its metadata says {length}",
                                 fix="the dataset is damaged; record it again")
        frame_index = table.column("frame_index").to_numpy(zero_copy_only=False)
        order = np.argsort(frame_index, kind="stable")
        timestamp = table.column("timestamp").to_numpy(zero_copy_only=False)[order].astype(np.float64)
        expected = np.arange(length) / self.fps
        if not np.allclose(timestamp, expected, atol=1e-4, rtol=0):
            raise RecordingError(f"episode {k}'s timestamps do not follow {self.fps} fps", fix="record it again")
        features = {key: _vectors(table.column(key), width, f"episode {k}'s {key} in {path}")[order]
                    for key in vectors}
        tasks = row.get("tasks") or []
        task_index = table.column("task_index").to_numpy(zero_copy_only=False)
        task = tasks[0] if tasks else (self.tasks[int(task_index[0])] if len(self.tasks) > int(task_index[0]) else "")
        return Episode(k, str(task), self.fps, self.joint_names, timestamp, frame_index[order],
                       table.column("index").to_numpy(zero_copy_only=False)[order], features)

    def video(self, k: int, key: str) -> tuple[Path, float, float]:
        """Where episode ``k``'s frames of camera feature ``key`` (one of :attr:`video_keys`) are: the
        video file, and the episode's first and end timestamps in it (s).

        Raises:
            RecordingError: no such episode or camera, or the episodes file does not say.
        """
        pa, pq = _arrow()
        if key not in self.video_keys:
            raise RecordingError(f"{self.root} has no camera {key!r}", fix="its cameras: " + ", ".join(self.video_keys))
        if not (isinstance(k, int) and 0 <= k < self.total_episodes):
            raise RecordingError(f"{self.root} has no episode {k!r}",
                                 fix=f"episodes are 0 to {self.total_episodes - 1}")
        cols = [f"videos/{key}/{c}" for c in ("chunk_index", "file_index", "from_timestamp", "to_timestamp")]
        folder = self.root / "meta" / "episodes"
        for path in sorted(folder.glob("*/*.parquet")):
            try:
                f = pq.ParquetFile(path)
                if not all(c in f.schema_arrow.names for c in cols):
                    continue
                _check_bytes(f.metadata, path, ["episode_index", *cols])
                table = f.read(columns=["episode_index", *cols])
            except (OSError, ValueError, KeyError, pa.ArrowException) as e:
                raise RecordingError(f"cannot read {path}: {e}",
                                     fix="the dataset is damaged; record it again") from None
            for row in table.to_pylist():
                if row["episode_index"] == k and None not in row.values():
                    file = self.root / VIDEO_PATH.format(video_key=key, chunk_index=int(row[cols[0]]),
                                                         file_index=int(row[cols[1]]))
                    return file, float(row[cols[2]]), float(row[cols[3]])
        raise RecordingError(f"{self.root}: the episodes file does not say where episode {k} of {key} is",
                             fix="the dataset is damaged; record it again")

    @staticmethod
    def _row_groups(f: Any, k: int) -> list[int] | None:
        """The row groups that may hold episode ``k`` by their statistics, or ``None`` (read the file)."""
        names = f.schema_arrow.names
        if "episode_index" not in names:
            return None
        col = names.index("episode_index")
        out = []
        for g in range(f.metadata.num_row_groups):
            stats = f.metadata.row_group(g).column(col).statistics
            if stats is None or not stats.has_min_max:
                return None
            if stats.min <= k <= stats.max:
                out.append(g)
        return out


def read_dataset(root: str | os.PathLike[str]) -> LeRobotDataset:
    """Open the LeRobot v3.0 dataset in ``root`` (see :class:`LeRobotDataset`)."""
    return LeRobotDataset(root)


class DatasetWriter:
    """Appends episodes to the LeRobot v3.0 dataset in ``root`` (made if missing), one commit each.

    Args:
        root: the dataset's folder: missing or empty (a new dataset), or a dataset this writer can
            append to (same joints and fps; an episode cut short before its commit is dropped first).
        joint_names: the joints of every vector feature, in order.
        fps: frames per second (an integer, as LeRobot's).
        robot_type: info.json's ``robot_type`` (the robot's name).
        cameras: camera name → (width, height) pixels: each episode then needs their frames
            (:meth:`save_episode`'s ``images``), stored as video.

    Raises:
        RecordingError: ``root`` holds something else, or a dataset of other joints, cameras or fps; it
            cannot be written.
        ArgumentError: a bad fps or joint list.
    """

    def __init__(self, root: str | os.PathLike[str], joint_names: Sequence[str], fps: int,
                 robot_type: str | None = None, cameras: Mapping[str, tuple[int, int]] | None = None) -> None:
        self.pa, self.pq = _arrow()
        if not (isinstance(fps, int) and not isinstance(fps, bool) and 0 < fps <= 10_000):
            raise ArgumentError(f"fps must be a whole number of frames per second (1 to 10000), not {fps!r}",
                                fix="e.g. --fps 30")
        names = tuple(str(n) for n in joint_names)
        if not 0 < len(names) <= MAX_JOINTS or len(set(names)) != len(names):
            raise ArgumentError(f"a dataset needs 1 to {MAX_JOINTS} distinct joint names, got {list(names)}",
                                fix="name each joint once")
        self.root = Path(root)
        self.joint_names = names
        self.fps = fps
        self.cameras: dict[str, tuple[int, int]] = {}
        for name, size in (cameras or {}).items():
            from akarm.datasets.video import check_frame_size

            if not (isinstance(name, str) and name.replace("_", "").isalnum()):
                raise ArgumentError(f"a camera's name must be letters, digits and _, not {name!r}", fix="e.g. front")
            self.cameras[name] = check_frame_size(*size)
        check_writable(self.root / INFO)
        if (self.root / INFO).exists():
            self._open_existing(robot_type)
        else:
            if self.root.is_dir() and any(self.root.iterdir()):
                raise RecordingError(f"{self.root} is not empty and holds no LeRobot dataset",
                                     fix="record into a new or empty folder, or into a dataset recorded before")
            self.info: dict[str, Any] = {
                         "codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": 0,
                         "total_frames": 0, "total_tasks": 0, "chunks_size": CHUNKS_SIZE,
                         "data_files_size_in_mb": DATA_FILE_MB, "video_files_size_in_mb": 200, "fps": fps,
                         "splits": {}, "data_path": DATA_PATH, "video_path": VIDEO_PATH if self.cameras else None,
                         "features": _feature_spec(names, self.cameras, fps)}
            self.tasks: list[str] = []
            self.episode_rows: list[dict[str, Any]] = []
            # a dataset of no episodes, committed now: an episode cut short before its own commit (the
            # first one too) leaves rows that reopening drops, never a folder of files without info.json
            _write_json(self.root / INFO, self.info)

    def _open_existing(self, robot_type: str | None) -> None:
        ds = LeRobotDataset(self.root)
        if ds.fps != self.fps or ds.features != _feature_spec(self.joint_names, self.cameras, self.fps):
            raise RecordingError(f"{self.root} holds a dataset of other joints, cameras or fps ({ds.fps} fps, joints "
                                 f"{list(ds.joint_names)}, cameras {list(ds.video_keys)}; this recording: {self.fps} "
                                 f"fps, joints {list(self.joint_names)}, cameras "
                                 f"{[IMAGES + c for c in self.cameras]})",
                                 fix="record into a new folder, or with the same robot, cameras and --fps")
        self.info = dict(ds.info)
        self.tasks = list(ds.tasks)
        episodes = self.root / EPISODES_PATH.format(chunk_index=0, file_index=0)
        table = _read_table(episodes) if ds.total_episodes or episodes.exists() else None
        rows = table.to_pylist() if table is not None else []
        self.episode_rows = [r for r in rows if r["episode_index"] < ds.total_episodes]
        # an episode cut short before its commit: its rows go before anything else is written
        if len(self.episode_rows) != len(rows):
            self._write_episodes()
        last = self.episode_rows[-1] if self.episode_rows else None
        if last is not None:
            path = self._data_path(last)
            data = _read_table(path)
            _check_schema(data.schema, path, DATA_COLUMNS)
            if data.num_rows != last["dataset_to_index"] - self._file_start(last):
                self._write_data(path, self._committed(data))
        for stray in sorted((self.root / "data").glob("*/*.parquet")):  # a new file of an episode never committed
            if last is None or stray > self._data_path(last):
                stray.unlink()

    def _data_path(self, row: Mapping[str, Any]) -> Path:
        return self.root / DATA_PATH.format(chunk_index=row["data/chunk_index"], file_index=row["data/file_index"])

    def _file_start(self, row: Mapping[str, Any]) -> int:
        """The dataset index of the first frame in ``row``'s data file."""
        same = [r for r in self.episode_rows
                if (r["data/chunk_index"], r["data/file_index"]) == (row["data/chunk_index"], row["data/file_index"])]
        return int(min(r["dataset_from_index"] for r in same))

    def _committed(self, data: pa.Table) -> pa.Table:
        index = data.column("index").to_numpy(zero_copy_only=False)
        return data.filter(self.pa.array(index < self.info["total_frames"]))

    @property
    def total_episodes(self) -> int:
        """Episodes committed so far."""
        return int(self.info["total_episodes"])

    def save_episode(self, task: str, frames: EpisodeFrames, images: Mapping[str, np.ndarray] | None = None) -> int:
        """Commit ``frames`` as the next episode, doing ``task``; returns its episode_index. ``images``:
        each camera's frames (name → n × height × width × 3 RGB uint8, one per frame), when the writer
        has cameras.

        Call it with Ctrl-C held back (:func:`akarm.signals.deferred`): each file is written
        atomically, and info.json, written last, is the commit.

        Raises:
            ArgumentError: no frames, the wrong number of joints, a value that is not finite, a
                camera's frames missing or of another size or count.
            RecordingError: the episode is past a bound, or a file cannot be written.
        """
        pa = self.pa
        n = len(frames)
        if n == 0:
            raise ArgumentError("an episode needs at least one frame", fix="record for longer")
        images = self._check_images(images, n)
        cols = frames.columns()
        for key, v in cols.items():
            if v.shape[1] != len(self.joint_names) or not np.all(np.isfinite(v)):
                raise ArgumentError(f"{key}: {v.shape[1]} values per frame, finite ones, are needed for "
                                    f"joints {list(self.joint_names)}", fix="one finite value per joint")
        if n > MAX_PATH_SAMPLES or n / self.fps > MAX_DURATION:
            raise RecordingError(f"an episode of {n} frames at {self.fps} fps is over the {MAX_PATH_SAMPLES} frames "
                                 f"or {MAX_DURATION:.0f} s one may have", fix="record shorter episodes")
        if self.total_episodes >= MAX_EPISODES:
            raise RecordingError(f"{self.root} has {MAX_EPISODES} episodes already", fix="record into a new folder")
        if not isinstance(task, str) or not task.strip():
            raise ArgumentError("an episode needs a task: what was demonstrated", fix='e.g. --task "pick the cube"')
        k, start = self.total_episodes, int(self.info["total_frames"])
        if task not in self.tasks:
            self.tasks.append(task)
        task_index = self.tasks.index(task)
        table = pa.table({
            **{key: pa.array(list(v), type=pa.list_(pa.float32(), v.shape[1])) for key, v in cols.items()},
            "timestamp": pa.array((np.arange(n) / self.fps).astype(np.float32), pa.float32()),
            "frame_index": pa.array(np.arange(n), pa.int64()),
            "episode_index": pa.array(np.full(n, k), pa.int64()),
            "index": pa.array(np.arange(start, start + n), pa.int64()),
            "task_index": pa.array(np.full(n, task_index), pa.int64()),
        })
        chunk, file, before = self._data_file_for(table)
        path = self.root / DATA_PATH.format(chunk_index=chunk, file_index=file)
        self._write_data(path, table if before is None else pa.concat_tables([before, table]))
        stats = {key: _stats(v) for key, v in cols.items()}
        stats.update({key: _stats(np.asarray(table.column(key).to_numpy(zero_copy_only=False)).reshape(-1, 1))
                      for key in SCALARS})
        row: dict[str, Any] = {"episode_index": k, "tasks": [task], "length": n, "data/chunk_index": chunk,
                               "data/file_index": file, "dataset_from_index": start, "dataset_to_index": start + n,
                               "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0}
        self._write_videos(k, images, row, stats)  # before the episode's commit
        row.update({f"stats/{key}/{name}": np.asarray(v).tolist() for key, s in stats.items() for name, v in s.items()})
        self.episode_rows.append(row)
        self._write_episodes()
        if task_index == len(self.tasks) - 1 and self.info["total_tasks"] < len(self.tasks):
            _write_parquet(self.root / TASKS, _tasks_table(self.tasks))
        _write_json(self.root / STATS, self._dataset_stats())
        info = dict(self.info)
        info.update(total_episodes=k + 1, total_frames=start + n, total_tasks=len(self.tasks),
                    splits={"train": f"0:{k + 1}"})
        _write_json(self.root / INFO, info)  # the commit
        self.info = info
        return k

    def _check_images(self, images: Mapping[str, np.ndarray] | None, n: int) -> dict[str, np.ndarray]:
        """Every camera's ``n`` frames, of its size, or ArgumentError."""
        images = dict(images or {})
        if set(images) != set(self.cameras):
            raise ArgumentError(f"the episode has frames of cameras {sorted(images)}, the dataset's are "
                                f"{sorted(self.cameras)}", fix="give every camera's frames, and only theirs")
        for name, (width, height) in self.cameras.items():
            shape = getattr(images[name], "shape", None)
            if shape != (n, height, width, 3) or images[name].dtype != np.uint8:
                raise ArgumentError(f"camera {name}: frames of shape {shape}, ({n}, {height}, {width}, 3) uint8 "
                                    "are needed (one per frame)", fix="take one camera frame with each frame")
        return images

    def _write_videos(self, k: int, images: Mapping[str, np.ndarray], row: dict[str, Any],
                      stats: dict[str, dict[str, np.ndarray]]) -> None:
        """Episode ``k``'s video of each camera, one file each; where it is goes into ``row``, its stats
        into ``stats``."""
        from akarm.datasets.video import encode_episode

        for name, video in images.items():
            key = IMAGES + name
            chunk, file = divmod(k, CHUNKS_SIZE)
            stats[key] = encode_episode(self.root / VIDEO_PATH.format(video_key=key, chunk_index=chunk,
                                                                      file_index=file), video, self.fps)
            row.update({f"videos/{key}/chunk_index": chunk, f"videos/{key}/file_index": file,
                        f"videos/{key}/from_timestamp": 0.0, f"videos/{key}/to_timestamp": len(video) / self.fps})

    def _data_file_for(self, table: pa.Table) -> tuple[int, int, pa.Table | None]:
        """(chunk, file) the episode goes into, and the rows already there (``None``: a new file)."""
        if not self.episode_rows:
            return 0, 0, None
        last = self.episode_rows[-1]
        chunk, file = int(last["data/chunk_index"]), int(last["data/file_index"])
        path = self.root / DATA_PATH.format(chunk_index=chunk, file_index=file)
        rows = int(last["dataset_to_index"]) - self._file_start(last)
        if path.stat().st_size >= DATA_FILE_MB * 1e6 or rows + table.num_rows > MAX_FILE_ROWS:
            file += 1
            if file == CHUNKS_SIZE:
                chunk, file = chunk + 1, 0
            return chunk, file, None
        return chunk, file, self._committed(_read_table(path))

    def _write_data(self, path: Path, table: pa.Table) -> None:
        """The data file, one row group per episode (a reader of one episode reads its group alone)."""
        pq = self.pq
        index = table.column("episode_index").to_numpy(zero_copy_only=False)
        bounds = np.flatnonzero(np.diff(index)) + 1
        starts = [0, *bounds.tolist()]
        ends = [*bounds.tolist(), table.num_rows]

        def write(f: io.BufferedWriter) -> None:
            with pq.ParquetWriter(f, table.schema, compression="snappy") as w:
                for a, b in zip(starts, ends, strict=True):
                    w.write_table(table.slice(a, b - a))

        atomic_write(path, write)

    def _write_episodes(self) -> None:
        path = self.root / EPISODES_PATH.format(chunk_index=0, file_index=0)
        if not self.episode_rows:  # the first episode was cut short: a dataset of none has no episodes file
            path.unlink(missing_ok=True)
            return
        _write_parquet(path, self.pa.Table.from_pylist(self.episode_rows))

    def _dataset_stats(self) -> dict[str, dict[str, list[Any]]]:
        out: dict[str, dict[str, list[Any]]] = {}
        keys = [*VECTORS, *(IMAGES + c for c in self.cameras), *SCALARS]
        for key in keys:
            parts = []
            for r in self.episode_rows:
                parts.append({name[len(f"stats/{key}/"):]: np.asarray(v) for name, v in r.items()
                              if name.startswith(f"stats/{key}/")})
            agg = _aggregate(parts)
            out[key] = {name: np.nan_to_num(np.asarray(v, dtype=float), nan=0.0, posinf=0.0, neginf=0.0).tolist()
                        for name, v in agg.items()}
            out[key]["count"] = [int(agg["count"][0])]
        return out
