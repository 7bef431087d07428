"""Telemetry as MCAP: ROS 2 JointState in CDR, byte for byte as ROS 2 writes it (rosbags' own CDR),
read back bit for bit with the mcap package and independently with rosbags' AnyReader."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap")

from akarm.errors import RecordingError
from akarm.telemetry import mcap as tm
from akarm.telemetry.log import TelemetryLog, load, load_mcap

FIELDS = ("q", "dq", "tau", "q_des", "dq_des", "tau_ff", "tau_ext")


def telemetry(n: int = 300, names: tuple[str, ...] = ("shoulder", "elbow", "wrist"), seed: int = 0,
              t0: float = 1234.5678) -> TelemetryLog:
    rng = np.random.default_rng(seed)
    return TelemetryLog(names, t0 + np.arange(n) * 0.002, *(rng.normal(size=(n, len(names))) for _ in FIELDS))


def test_joint_state_cdr_is_byte_for_byte_what_ros2_writes() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    for position, velocity, effort in (([0.5, -1.25], [0.0, 3.0], [1e-9, -7.5]), ([1.0, 2.0], [], [3.0, 4.0]),
                                       ([], [], [0.125, 0.25])):
        msg = types["sensor_msgs/msg/JointState"](
            header=types["std_msgs/msg/Header"](
                stamp=types["builtin_interfaces/msg/Time"](sec=1234, nanosec=567_000_001), frame_id="base"),
            name=["shoulder", "elbow"], position=np.array(position, dtype=float),
            velocity=np.array(velocity, dtype=float), effort=np.array(effort, dtype=float))
        ours = tm.encode_joint_state(1234_567_000_001, ["shoulder", "elbow"], position, velocity, effort, "base")
        assert ours == bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
        stamp, frame, names, p, v, e = tm.decode_joint_state(ours)
        assert (stamp, frame, names) == (1234_567_000_001, "base", ["shoulder", "elbow"])
        assert p.tolist() == position and v.tolist() == velocity and e.tolist() == effort


def test_a_log_reads_back_bit_for_bit_with_mcap_and_with_rosbags(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    log = telemetry()
    path = log.save(tmp_path / "run.mcap")
    back = load(path)
    assert back.joint_names == log.joint_names
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(back, f), getattr(log, f))   # to the last bit
    np.testing.assert_allclose(back.t, log.t, rtol=0, atol=1e-9)          # to the nanosecond

    with path.open("rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        schemas = reader.get_summary().schemas
        assert [(s.name, s.encoding) for s in schemas.values()] == [("sensor_msgs/msg/JointState", "ros2msg")]
        topics = {c.topic: c.message_encoding for c in reader.get_summary().channels.values()}
        assert topics == {"/joint_states": "cdr", "/joint_states/desired": "cdr", "/feedforward": "cdr",
                          "/external_torque": "cdr"}
        assert reader.get_summary().statistics.message_count == 4 * len(log)

    seen: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            seen.setdefault(conn.topic, []).append((stamp, msg))
    states = seen["/joint_states"]
    assert [m.name for _, m in states[:1]] == [["shoulder", "elbow", "wrist"]]
    np.testing.assert_array_equal(np.array([m.position for _, m in states]), log.q)
    np.testing.assert_array_equal(np.array([m.velocity for _, m in states]), log.dq)
    np.testing.assert_array_equal(np.array([m.effort for _, m in states]), log.tau)
    np.testing.assert_array_equal(np.array([m.position for _, m in seen["/joint_states/desired"]]), log.q_des)
    np.testing.assert_array_equal(np.array([m.effort for _, m in seen["/feedforward"]]), log.tau_ff)
    np.testing.assert_array_equal(np.array([m.effort for _, m in seen["/external_torque"]]), log.tau_ext)
    assert [s for s, _ in states] == [round(t * 1e9) for t in log.t]
    assert states[0][1].header.stamp.sec == 1234 and len(seen["/feedforward"][0][1].position) == 0


def test_two_arms_go_under_their_names_and_plot_as_two_figures(tmp_path: Path) -> None:
    leader, follower = telemetry(seed=1, names=("a", "b")), telemetry(n=250, seed=2, t0=1234.5689)
    path = tm.save_mcap(tmp_path / "teleop.mcap", {"leader": leader, "follower": follower})
    arms = load_mcap(path)
    assert set(arms) == {"leader", "follower"}
    np.testing.assert_array_equal(arms["follower"].tau_ext, follower.tau_ext)
    np.testing.assert_array_equal(arms["leader"].q, leader.q)
    with pytest.raises(RecordingError, match="holds the telemetry of 2 arms"):
        load(path)
    pytest.importorskip("matplotlib")
    from akarm.cli import main

    assert main(["plot", str(path)]) == 0
    assert (tmp_path / "teleop-leader.png").stat().st_size > 0 and (tmp_path / "teleop-follower.png").exists()


def test_damaged_or_oversized_files_are_refused_by_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = telemetry(n=50).save(tmp_path / "run.mcap")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    with pytest.raises(RecordingError, match=r"cannot read .* as MCAP"):
        load_mcap(cut)
    (tmp_path / "not.mcap").write_text("hello")
    with pytest.raises(RecordingError, match="as MCAP"):
        load_mcap(tmp_path / "not.mcap")
    monkeypatch.setattr(tm, "MAX_CYCLES", 10)
    with pytest.raises(RecordingError, match=r"more than 10 (cycles|messages)"):
        load_mcap(path)
    wide = tm.encode_joint_state(0, ["j"] * 2, [0.0] * 2, [], [])
    huge = wide[:4] + wide[4:].replace(struct.pack("<I", 2), struct.pack("<I", 10**6), 1)
    with pytest.raises(RecordingError, match=r"joints, over 64"):
        tm.decode_joint_state(huge)
    with pytest.raises(RecordingError, match="not little-endian CDR"):
        tm.decode_joint_state(b"\x00\x00\x00\x00" + wide[4:])


def write_mcap(path: Path, data: bytes, compression: str = "zstd") -> Path:
    """One JointState message of ``data`` (its bytes as they are) in one chunk compressed with ``compression``."""
    from mcap.writer import CompressionType, Writer

    with path.open("wb") as f:
        w = Writer(f, compression=CompressionType[compression.upper()], chunk_size=1 << 30)
        w.start(profile="ros2", library="test")
        schema = w.register_schema(name=tm.JOINT_STATE, encoding="ros2msg", data=tm.JOINT_STATE_SCHEMA.encode())
        channel = w.register_channel("/joint_states", "cdr", schema)
        w.add_message(channel, log_time=0, data=data, publish_time=0)
        w.finish()
    return path


def test_a_compressed_chunk_or_a_file_past_its_limit_is_refused_before_decompressing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tm, "MAX_MCAP_CHUNK_BYTES", 1 << 20)
    for compression in ("zstd", "lz4"):
        bomb = write_mcap(tmp_path / f"bomb-{compression}.mcap", b"\x00\x01\x00\x00" + bytes(4 << 20), compression)
        assert bomb.stat().st_size < 100_000  # 4 MiB of zeros, compressed
        with pytest.raises(RecordingError, match=r"has a chunk of 4 194 [\d ]+ bytes uncompressed, over the limit of "
                                                 r"1 048 576 bytes \(MAX_MCAP_CHUNK_BYTES\)"):
            load_mcap(bomb)
        state = tm.encode_joint_state(2_000_000, ["j"], [0.5], [0.25], [1.0])
        log = load_mcap(write_mcap(tmp_path / f"one-{compression}.mcap", state, compression))[""]
        assert log.joint_names == ("j",) and log.q.tolist() == [[0.5]] and log.t.tolist() == [0.002]
    path = telemetry(n=50).save(tmp_path / "run.mcap")
    monkeypatch.setattr(tm, "MAX_MCAP_BYTES", 1000)
    with pytest.raises(RecordingError, match=r"run\.mcap is [\d ]+ bytes, over the limit of 1 000 bytes "
                                             r"\(MAX_MCAP_BYTES\)"):
        load_mcap(path)


def test_an_mcap_of_no_joints_or_an_arm_name_that_is_not_a_topic_prefix_is_refused(tmp_path: Path) -> None:
    z = np.zeros((3, 0))
    path = tm.save_mcap(tmp_path / "zero.mcap", TelemetryLog((), np.arange(3) * 0.002, z, z, z, z, z, z, z))
    with pytest.raises(RecordingError, match=r"zero\.mcap: the telemetry file has no joints"):
        load_mcap(path)
    from mcap.writer import Writer

    path = tmp_path / "nul.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        schema = w.register_schema(name=tm.JOINT_STATE, encoding="ros2msg", data=tm.JOINT_STATE_SCHEMA.encode())
        channel = w.register_channel("/a\x00b/joint_states", "cdr", schema)
        w.add_message(channel, log_time=0, publish_time=0, data=tm.encode_joint_state(0, ["j"], [0.0], [0.0], [0.0]))
        w.finish()
    with pytest.raises(RecordingError, match=r"nul\.mcap: arm name 'a\\x00b' cannot be a topic prefix"):
        load_mcap(path)
