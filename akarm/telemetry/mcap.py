"""Telemetry as MCAP, the log format Foxglove, PlotJuggler, the ``mcap`` tools and ``ros2 bag`` open.

Each arm's cycles go in as ROS 2 messages, ``sensor_msgs/msg/JointState`` in CDR with its ROS 2
schema (``ros2msg``), one message per cycle on each of four topics (``/NAME/...`` for a named arm,
e.g. a teleoperation session's ``leader`` and ``follower``; no prefix for a single arm):

- ``joint_states``: the measured positions, velocities and torques (``q``, ``dq``, ``tau``);
- ``joint_states/desired``: the commanded positions and velocities (``q_des``, ``dq_des``);
- ``feedforward``: the feed-forward torque (``tau_ff``) as the effort;
- ``external_torque``: the collision observer's estimate (``tau_ext``) as the effort.

The header's stamp is the cycle's clock time (s, to the nanosecond; a monotonic clock's, not the
time of day), which is also the message's log time. Values are float64 as the telemetry holds them:
they read back to the last bit. Written with the ``mcap`` package (the ``data`` extra), atomically
(:mod:`akarm.files`); the CDR of JointState is encoded here (a fixed layout: little-endian XCDR1,
aligned from after its 4-byte encapsulation header).

Read back within bounds (:data:`MAX_CYCLES` cycles per arm, :data:`MAX_JOINTS` joints, names of
:data:`MAX_NAME_BYTES`, a file of :data:`MAX_MCAP_BYTES`, a chunk or record of :data:`MAX_MCAP_CHUNK_BYTES`
uncompressed), refused by name before anything past them is decoded or decompressed.
"""

from __future__ import annotations

import importlib
import io
import math
import os
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from akarm.errors import RecordingError
from akarm.files import atomic_write, number, over

__all__ = ["FIELDS", "JOINT_STATE", "JOINT_STATE_SCHEMA", "MAX_CYCLES", "MAX_JOINTS", "MAX_MCAP_BYTES",
           "MAX_MCAP_CHUNK_BYTES", "MAX_NAME_BYTES", "TOPICS", "ArmLog", "Cycles", "check_arm_name",
           "decode_joint_state", "encode_joint_state", "read_mcap", "save_mcap", "topic"]

JOINT_STATE = "sensor_msgs/msg/JointState"
#: sensor_msgs/msg/JointState with its dependencies, as ROS 2 writes a ``ros2msg`` schema.
JOINT_STATE_SCHEMA = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
#: topic (after the arm's prefix) → the telemetry fields in its position, velocity and effort.
TOPICS: dict[str, tuple[str | None, str | None, str | None]] = {
    "joint_states": ("q", "dq", "tau"),
    "joint_states/desired": ("q_des", "dq_des", None),
    "feedforward": (None, None, "tau_ff"),
    "external_torque": (None, None, "tau_ext"),
}
#: The telemetry fields the topics carry (:data:`akarm.telemetry.log.FIELDS`).
FIELDS = ("q_des", "dq_des", "q", "dq", "tau", "tau_ff", "tau_ext")


class Cycles(Protocol):
    """What is written of an arm: a :class:`~akarm.telemetry.log.TelemetryLog` (``t`` s, and each of
    :data:`FIELDS` as cycles × joints)."""

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    @property
    def t(self) -> np.ndarray: ...

    @property
    def q_des(self) -> np.ndarray: ...

    @property
    def dq_des(self) -> np.ndarray: ...

    @property
    def q(self) -> np.ndarray: ...

    @property
    def dq(self) -> np.ndarray: ...

    @property
    def tau(self) -> np.ndarray: ...

    @property
    def tau_ff(self) -> np.ndarray: ...

    @property
    def tau_ext(self) -> np.ndarray: ...


@dataclass(frozen=True)
class ArmLog:
    """One arm's cycles read from a file: joint names, times (s) and each of :data:`FIELDS` (NaN where
    the file has none); :func:`akarm.telemetry.log.load_mcap` makes TelemetryLogs of them."""

    joint_names: tuple[str, ...]
    t: np.ndarray
    fields: Mapping[str, np.ndarray]


#: Cycles per arm a file may hold when read (a one-hour run at 500 Hz is 1 800 000; the same bound as a
#: recorded path's, akarm.motion.bounds.MAX_PATH_SAMPLES, which this layer sits below).
MAX_CYCLES = 2_000_000
#: Joints per message.
MAX_JOINTS = 64
#: Bytes per joint name or frame id.
MAX_NAME_BYTES = 256
#: Bytes of an MCAP file (an hour at 500 Hz of one 6-joint arm, as akarm writes it, is about 170 MB).
MAX_MCAP_BYTES = 1 << 30
#: Bytes of one chunk uncompressed, or of one record (the mcap writer's chunks are 1 MiB, ROS 2's a few).
MAX_MCAP_CHUNK_BYTES = 64 << 20
_HEADER = b"\x00\x01\x00\x00"  # CDR, little endian


def topic(arm: str, name: str) -> str:
    """The topic of ``name`` (a key of :data:`TOPICS`) for ``arm`` (``""``: a single arm, no prefix)."""
    return f"/{arm}/{name}" if arm else f"/{name}"


class _Cdr:
    """A little-endian CDR buffer, aligned from the start of the payload (after the encapsulation header)."""

    def __init__(self) -> None:
        self.buf = bytearray()

    def align(self, n: int) -> None:
        self.buf += b"\x00" * (-len(self.buf) % n)

    def u32(self, x: int) -> None:
        self.align(4)
        self.buf += struct.pack("<I", x)

    def string(self, s: str) -> None:
        raw = s.encode("utf-8") + b"\x00"
        self.u32(len(raw))
        self.buf += raw

    def doubles(self, xs: np.ndarray) -> None:
        self.u32(len(xs))
        if len(xs):
            self.align(8)
            self.buf += np.asarray(xs, dtype="<f8").tobytes()


def encode_joint_state(stamp_ns: int, names: Sequence[str], position: Sequence[float] | np.ndarray,
                       velocity: Sequence[float] | np.ndarray, effort: Sequence[float] | np.ndarray,
                       frame_id: str = "") -> bytes:
    """A ``sensor_msgs/msg/JointState`` in ROS 2 CDR (with its encapsulation header); stamp in ns."""
    c = _Cdr()
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    c.buf += struct.pack("<iI", sec, nsec)
    c.string(frame_id)
    c.u32(len(names))
    for n in names:
        c.string(n)
    for values in (position, velocity, effort):
        c.doubles(np.asarray(values, dtype=float))
    return _HEADER + bytes(c.buf)


def decode_joint_state(data: bytes) -> tuple[int, str, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(stamp ns, frame_id, names, position, velocity, effort) of a CDR ``JointState``.

    Raises:
        RecordingError: not little-endian CDR, truncated, or past a bound (joints, name length).
    """
    if len(data) < 12 or data[:2] != b"\x00\x01":
        raise RecordingError("a JointState message is not little-endian CDR",
                             fix="pass an MCAP written by ROS 2 or akarm")
    body = memoryview(data)[4:]
    pos = 0

    def u32() -> int:
        nonlocal pos
        pos += -pos % 4
        if pos + 4 > len(body):
            raise RecordingError("a JointState message is truncated", fix="the file is damaged")
        (x,) = struct.unpack_from("<I", body, pos)
        pos += 4
        return int(x)

    def string() -> str:
        nonlocal pos
        n = u32()
        if not 0 < n <= MAX_NAME_BYTES + 1 or pos + n > len(body):
            raise RecordingError(f"a JointState string of {n} bytes (at most {MAX_NAME_BYTES})",
                                 fix="the file is damaged, or not joint states")
        s = bytes(body[pos:pos + n - 1]).decode("utf-8", errors="replace")
        pos += n
        return s

    def doubles() -> np.ndarray:
        nonlocal pos
        n = u32()
        if n > MAX_JOINTS:
            raise RecordingError(f"a JointState of {n} values, over {MAX_JOINTS}", fix="the file is damaged")
        if n == 0:
            return np.zeros(0)
        pos += -pos % 8
        if pos + 8 * n > len(body):
            raise RecordingError("a JointState message is truncated", fix="the file is damaged")
        out = np.frombuffer(body, dtype="<f8", count=n, offset=pos).astype(float)
        pos += 8 * n
        return out

    sec, nsec = struct.unpack_from("<iI", body, 0)
    pos = 8
    frame_id = string()
    count = u32()
    if count > MAX_JOINTS:
        raise RecordingError(f"a JointState of {count} joints, over {MAX_JOINTS}", fix="the file is damaged")
    names = [string() for _ in range(count)]
    return sec * 1_000_000_000 + nsec, frame_id, names, doubles(), doubles(), doubles()


def _mcap() -> tuple[Any, Any]:
    try:
        from mcap import reader, writer
    except ImportError:
        raise RecordingError("MCAP files need the mcap package, which is not installed",
                             fix='pip install "akarm[data]" (or pip install mcap)') from None
    return reader, writer


def save_mcap(path: str | os.PathLike[str], logs: Cycles | Mapping[str, Cycles]) -> Path:
    """Write one arm's telemetry (a :class:`~akarm.telemetry.log.TelemetryLog`) or several (``{name: log}``,
    each under ``/name/``) as MCAP at ``path``, atomically; their cycles interleaved in time order."""
    _, writer_mod = _mcap()
    arms: dict[str, Cycles] = dict(logs) if isinstance(logs, Mapping) else {"": logs}
    for name in arms:
        check_arm_name(name)
    events: list[tuple[int, int, int]] = []  # (stamp ns, arm number, cycle)
    for a, log in enumerate(arms.values()):
        stamps = np.round(np.asarray(log.t, dtype=float) * 1e9).astype(np.int64)
        events += [(int(s), a, k) for k, s in enumerate(stamps)]
    events.sort()

    def write(f: io.BufferedWriter) -> None:
        w = writer_mod.Writer(f)
        w.start(profile="ros2", library="akarm")
        schema = w.register_schema(name=JOINT_STATE, encoding="ros2msg", data=JOINT_STATE_SCHEMA.encode())
        channels = [{name: w.register_channel(topic(arm, name), "cdr", schema) for name in TOPICS} for arm in arms]
        logs_list = list(arms.values())
        fields = {f: [np.asarray(getattr(log, f), dtype=float) for log in logs_list] for f in FIELDS}
        names = [list(log.joint_names) for log in logs_list]
        seq = 0
        empty = np.zeros(0)
        for stamp, a, k in events:
            for name, spec in TOPICS.items():
                p, v, e = (fields[x][a][k] if x else empty for x in spec)
                data = encode_joint_state(stamp, names[a], p, v, e)
                w.add_message(channels[a][name], log_time=stamp, data=data, publish_time=stamp, sequence=seq)
                seq += 1
        w.finish()

    return atomic_write(path, write)


def check_arm_name(name: str, where: str = "") -> None:
    """Refuse (RecordingError) an arm name that cannot be a topic prefix: letters, digits and _ (or ``""``)."""
    if name and not name.replace("_", "").isalnum():
        raise RecordingError(f"{where}arm name {name!r} cannot be a topic prefix", fix="use letters, digits and _")


def read_mcap(path: str | os.PathLike[str]) -> dict[str, ArmLog]:
    """Read the arms' cycles from an MCAP file: ``{arm name: ArmLog}`` (``""`` for a file of one unnamed
    arm). A file of joint states from elsewhere (``ros2 bag``) reads too: what it lacks is NaN.

    Raises:
        RecordingError: not an MCAP file, no joint states in it, past a bound, or messages that disagree
            (joint names, lengths, a topic with other stamps than its arm's joint_states).
    """
    _mcap()
    p = Path(path)
    per: dict[str, dict[str, list[tuple[int, list[str], tuple[np.ndarray, ...]]]]] = {}
    try:
        with p.open("rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > MAX_MCAP_BYTES:
                raise RecordingError(over(f"{p} is {number(size)} bytes", MAX_MCAP_BYTES, "bytes", "MAX_MCAP_BYTES"),
                                     fix="split the log")
            kept = 0
            for schema, channel, message in _messages(p, f):
                if schema is None or schema.name != JOINT_STATE or channel.message_encoding != "cdr":
                    continue
                kept += 1
                if kept > MAX_CYCLES * len(TOPICS) * 4:
                    raise RecordingError(f"{p} holds more than {number(MAX_CYCLES * len(TOPICS) * 4)} joint states: "
                                         f"more than {number(MAX_CYCLES)} cycles of 4 arms", fix="split the log")
                arm, name = _split(channel.topic)
                if name is None:
                    continue
                check_arm_name(arm, f"{p}: ")
                rows = per.setdefault(arm, {}).setdefault(name, [])
                if len(rows) >= MAX_CYCLES:
                    raise RecordingError(f"{p}: {channel.topic} has more than {MAX_CYCLES} messages",
                                         fix="split the log")
                stamp, _, names, *values = decode_joint_state(message.data)
                rows.append((stamp, names, tuple(values)))
    except RecordingError:
        raise
    except Exception as e:  # the mcap package's own errors (bad magic, truncated records, CRC)
        raise RecordingError(f"cannot read {p} as MCAP: {type(e).__name__}: {e}",
                             fix="pass an .mcap written by akarm or ROS 2") from None
    if not any("joint_states" in topics for topics in per.values()):
        raise RecordingError(f"{p} has no sensor_msgs/msg/JointState on a joint_states topic",
                             fix="pass an .mcap written by --log or ros2 bag record /joint_states")
    return {arm: _log(p, arm, topics) for arm, topics in sorted(per.items()) if "joint_states" in topics}


def _messages(p: Path, f: Any) -> Any:
    """(schema, channel, message) of every message in the MCAP file ``f``, in file order; each chunk's
    size uncompressed checked against :data:`MAX_MCAP_CHUNK_BYTES` before it is decompressed (and its
    decompression stopped there whatever its data says), every record's before it is read."""
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    schemas: dict[int, Any] = {}
    channels: dict[int, Any] = {}

    def records(chunk: Any) -> list[Any]:
        if chunk.uncompressed_size > MAX_MCAP_CHUNK_BYTES:
            raise RecordingError(over(f"{p} has a chunk of {number(chunk.uncompressed_size)} bytes uncompressed",
                                      MAX_MCAP_CHUNK_BYTES, "bytes", "MAX_MCAP_CHUNK_BYTES"),
                                 fix="is it the right file? write it with smaller chunks")
        data = _decompress(p, chunk.compression, chunk.data)
        if len(data) != chunk.uncompressed_size:
            raise RecordingError(f"{p} has a chunk of {number(len(data))} bytes that says it has "
                                 f"{number(chunk.uncompressed_size)}", fix="the file is damaged")
        plain = Chunk(compression="", data=data, message_end_time=chunk.message_end_time,
                      message_start_time=chunk.message_start_time, uncompressed_crc=0,
                      uncompressed_size=len(data))
        return list(breakup_chunk(plain))

    def flat() -> Any:
        for record in StreamReader(f, emit_chunks=True, record_size_limit=MAX_MCAP_CHUNK_BYTES).records:
            if isinstance(record, Chunk):
                yield from records(record)
            else:
                yield record

    for record in flat():
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None:
                raise RecordingError(f"{p} has a message on channel {record.channel_id}, which it does not define",
                                     fix="the file is damaged")
            yield schemas.get(channel.schema_id), channel, record


def _decompress(p: Path, compression: str, data: bytes) -> bytes:
    """A chunk's records: at most :data:`MAX_MCAP_CHUNK_BYTES` + 1 bytes of them are ever decompressed."""
    limit = MAX_MCAP_CHUNK_BYTES + 1
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        out = bytearray()
        with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data), read_across_frames=True) as r:
            while len(out) < limit:
                part = r.read(limit - len(out))
                if not part:
                    break
                out += part
        return bytes(out)
    if compression == "lz4":
        lz4_frame: Any = importlib.import_module("lz4.frame")  # (a dependency of mcap, without type hints)

        return bytes(lz4_frame.LZ4FrameDecompressor().decompress(data, max_length=limit))
    raise RecordingError(f"{p} has a chunk compressed with {compression!r}", fix="write it with zstd or lz4")


def _split(name: str) -> tuple[str, str | None]:
    """(arm, topic name) of a topic: ``/leader/joint_states`` → ("leader", "joint_states")."""
    parts = name.strip("/").split("/", 1)
    for key in TOPICS:
        if name.strip("/") == key:
            return "", key
        if len(parts) == 2 and parts[1] == key:
            return parts[0], key
    return "", None


def _log(p: Path, arm: str, topics: Mapping[str, list[tuple[int, list[str], tuple[np.ndarray, ...]]]]) -> ArmLog:
    base = sorted(topics["joint_states"], key=lambda r: r[0])
    names = base[0][1]
    n, j = len(base), len(names)
    stamps = np.array([r[0] for r in base], dtype=np.int64)
    out: dict[str, np.ndarray] = {f: np.full((n, j), np.nan) for f in FIELDS}
    for name, spec in TOPICS.items():
        rows = sorted(topics.get(name, []), key=lambda r: r[0])
        if not rows:
            continue
        if len(rows) != n or any(r[1] != names for r in rows) or \
                not np.array_equal(np.array([r[0] for r in rows], dtype=np.int64), stamps):
            raise RecordingError(f"{p}: {topic(arm, name)} does not match {topic(arm, 'joint_states')} "
                                 "(cycles, stamps or joint names)", fix="pass an .mcap written by akarm --log")
        for k, field in enumerate(spec):
            if field is None:
                continue
            values = [r[2][k] for r in rows]
            if any(len(v) not in (0, j) for v in values):
                raise RecordingError(f"{p}: {topic(arm, name)} has values for other than its {j} joints",
                                     fix="the file is damaged")
            out[field] = np.array([v if len(v) == j else np.full(j, math.nan) for v in values])
    return ArmLog(tuple(names), stamps / 1e9, out)
