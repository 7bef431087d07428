"""Teleoperation's pure parts: which joints pair and how, and the brake point a follower streams to."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ruckig

from akarm.errors import ArgumentError, ConfigError
from akarm.motion.trajectory import JointLimits
from akarm.teleop import Pair, Pairing, stopping_distance
from akarm.teleop.pairing import GripperPair

LEADER = ("shoulder", "elbow", "wrist")
FOLLOWER = ("left_shoulder", "left_elbow", "left_wrist", "left_roll")


def test_joints_pair_in_order_or_as_a_mapping_file_says(tmp_path: Path) -> None:
    same = Pairing.in_order(LEADER, ("a", "b", "c"))
    np.testing.assert_array_equal(same.follower_positions(np.array([0.1, 0.2, 0.3]), np.zeros(3)), [0.1, 0.2, 0.3])
    with pytest.raises(ArgumentError, match="the leader has 3 joints, the follower 4"):
        Pairing.in_order(LEADER, FOLLOWER)
    path = tmp_path / "map.yaml"
    path.write_text("pairs:\n  - {leader: shoulder, follower: left_shoulder}\n"
                    "  - {leader: elbow, follower: left_elbow, scale: -2.0, offset: 0.1}\n")
    p = Pairing.load(path, LEADER, FOLLOWER)
    held = np.array([9.0, 9.0, 0.7, -0.4])
    # unpaired follower joints hold where they were; the wrist of the leader drives nothing
    np.testing.assert_allclose(p.follower_positions(np.array([0.5, 0.25, 3.0]), held), [0.5, -0.4, 0.7, -0.4])
    np.testing.assert_allclose(p.follower_velocities(np.array([1.0, 1.0, 1.0])), [1.0, -2.0, 0.0, 0.0])
    # torques go back by the same scale: equal work on both sides
    np.testing.assert_allclose(p.leader_torques(np.array([0.3, 0.5, 7.0, 7.0])), [0.3, -1.0, 0.0])


@pytest.mark.parametrize(("text", "match"), [
    ("pairs:\n  - {leader: shoulder, follower: left_sholder}\n",
     r"no joint 'left_sholder' \(did you mean 'left_shoulder'"),
    ("pairs:\n  - {leader: shoulder, follower: left_elbow}\n  - {leader: elbow, follower: left_elbow}\n",
     "follower joint 'left_elbow' is paired twice"),
    ("pairs:\n  - {leader: shoulder, follower: left_elbow, scale: 0}\n", "the scale not 0"),
    ("pairs:\n  - {leader: shoulder, follower: left_elbow, scale: x}\n", "must be numbers"),
    ("pairs:\n  - {leader: shoulder}\n", "each pair is"),
    ("pairs: []\n", "no `pairs:` list"),
    ("pairs: [\n", "map.yaml:2: not valid YAML"),
    ("pairs:\n  - {leader: 1, follower: left_elbow}\n", "pair 1: the leader joint 1 is not a joint name"),
    ("pairs:\n  - {leader: shoulder, follower: [left_elbow]}\n",
     r"pair 1: the follower joint \['left_elbow'\] is not a joint name"),
    ("x: " + "[" * 40 + "]" * 40 + "\n", r"over the limit of 32 levels \(MAX_YAML_DEPTH\)"),
    ("a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]\n"
                                                     for k in range(1, 6)),
     r"over the limit of 100 000 values \(MAX_MAP_NODES\)"),
    ("# " + "x" * (1 << 20) + "\n", r"over the limit of 1 048 576 bytes \(MAX_MAP_BYTES\)"),
])
def test_a_bad_mapping_file_is_refused_naming_the_pair(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "map.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        Pairing.load(path, LEADER, FOLLOWER)


def test_a_pairing_checks_its_pairs() -> None:
    with pytest.raises(ArgumentError, match="leader joint 'shoulder' is paired twice"):
        Pairing(LEADER, FOLLOWER, [Pair(0, 0), Pair(0, 1)])
    with pytest.raises(ArgumentError, match="at least one pair"):
        Pairing(LEADER, FOLLOWER, [])


def test_a_trigger_joint_named_in_the_mapping_file_opens_the_follower_gripper(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("pairs:\n  - {leader: shoulder, follower: left_shoulder}\n"
                    "gripper: {trigger: wrist, closed: 0.6, open: 0.0, force: 15}\n")
    g = Pairing.load(path, LEADER, FOLLOWER).gripper
    assert g == GripperPair(2, 0.6, 0.0, 15.0)
    assert [g.fraction(a) for a in (0.6, 0.3, 0.0, -1.0, 2.0)] == pytest.approx([0.0, 0.5, 1.0, 1.0, 0.0])
    path.write_text("pairs:\n  - {leader: shoulder, follower: left_shoulder}\ngripper: {}\n")
    assert Pairing.load(path, LEADER, FOLLOWER).gripper == GripperPair()  # the leader's own gripper drives it


@pytest.mark.parametrize(("text", "match"), [
    ("gripper: {trigger: wirst}\n", r"gripper: the leader has no joint 'wirst' \(did you mean 'wrist'"),
    ("gripper: {trigger: shoulder}\n", "the trigger joint 'shoulder' also drives a follower joint"),
    ("gripper: {trigger: wrist, closed: 0.5, open: 0.5}\n", "two different numbers"),
    ("gripper: {trigger: wrist, force: -3}\n", "must be a number ≥ 0 N"),
    ("gripper: {trigger: wrist, open: x}\n", "closed, open and force must be numbers"),
    ("gripper: {trigger: wrist, squeeze: 3}\n", "gripper: is"),
])
def test_a_bad_gripper_section_is_refused(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("pairs:\n  - {leader: shoulder, follower: left_shoulder}\n" + text)
    with pytest.raises(ConfigError, match=match):
        Pairing.load(path, LEADER, FOLLOWER)


@pytest.mark.parametrize("v", [0.05, 0.5, 1.0, 2.0, 3.9, -1.5])
def test_the_stopping_distance_is_where_ruckig_brings_a_joint_to_rest(v: float) -> None:
    limits = JointLimits(("j",), np.array([-10.0]), np.array([10.0]), np.array([4.0]), np.array([20.0]),
                         np.array([200.0]))
    r, inp, traj = ruckig.Ruckig(1), ruckig.InputParameter(1), ruckig.Trajectory(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v], [0.0]
    inp.control_interface = ruckig.ControlInterface.Velocity
    inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [4.0], [20.0], [200.0]
    r.calculate(inp, traj)
    rest = traj.at_time(traj.duration)[0][0]
    assert stopping_distance(np.array([v]), limits)[0] == pytest.approx(rest, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize(("args", "said"), [
    (["--record", "DIR"], "--record needs --task"),
    (["--task", "wave"], "--task is for --record"),
    (["--log", "run.csv"], "must end in .mcap"),
    (["--seconds", "0"], "--seconds must be positive"),
    (["--record", "DIR", "--task", "wave", "--fps", "0"], "--fps must be at least 1"),
    (["-i", "virtual", "-c", "arm=x,amr=y"], "-c names bus 'amr', which neither arm has (did you mean 'arm'?)"),
    (["--camera", "front"], "--camera and --sim-control are for --record"),
    (["--record", "DIR", "--task", "wave", "--camera", "front", "--camera", "front"], "each named once"),
    (["--record", "DIR", "--task", "wave", "--camera", "front", "--camera-size", "97x96"], "even number"),
    (["--record", "DIR", "--task", "wave", "--camera", "front", "--camera-size", "96"], "is not WIDTHxHEIGHT"),
])
def test_akarm_teleop_checks_its_options_before_anything_is_opened(args: list[str], said: str, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from akarm.cli import main

    from .conftest import ROBOTS

    robot = str(ROBOTS / "planar2.yaml")
    argv = ["teleop", robot, robot, *[str(tmp_path / a) if a in ("DIR", "run.csv") else a for a in args]]
    assert main(argv) == 1
    assert said in capsys.readouterr().err


def test_akarm_replay_of_a_dataset_needs_its_episode(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from akarm.cli import main

    from .conftest import ROBOTS

    assert main(["replay", str(ROBOTS / "planar2.yaml"), str(tmp_path)]) == 1
    assert "is a folder: which of its episodes?" in capsys.readouterr().err
    assert main(["replay", str(ROBOTS / "planar2.yaml"), str(tmp_path / "x.csv"), "--episode", "1"]) == 1
    assert "--episode is for a dataset folder" in capsys.readouterr().err


def test_the_recorder_takes_a_frame_per_fps_tick_and_commits_an_episode_whole(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from akarm.datasets import DatasetWriter, read_dataset
    from akarm.teleop import Step
    from akarm.teleop.recording import EpisodeRecorder

    def step(t: float) -> Step:
        q = np.array([t, -t])
        return Step(t, "following", q, q, q, 2 * q, 3 * q, q + 1, q, np.zeros(2), 0.002, ())

    rec = EpisodeRecorder(DatasetWriter(tmp_path, ("a", "b"), 50), rate_hz=500.0)
    with pytest.raises(ArgumentError, match="600 fps is more frames"):
        EpisodeRecorder(DatasetWriter(tmp_path / "x", ("a", "b"), 600), rate_hz=500.0)
    rec.begin("wave", 10.0)
    taken = [rec.add(step(10.0 + k * 0.002)) for k in range(250)]   # 0.5 s of steps at 500 Hz
    assert sum(taken) == 25 and rec.frames == 25 and rec.seconds == pytest.approx(0.5)
    assert [k for k, x in enumerate(taken) if x][:3] == [0, 10, 20]  # the step at each 1/50 s
    rec.discard()                                                    # r: nothing of it written
    assert not rec.recording and read_dataset(tmp_path).total_episodes == 0 and not (tmp_path / "data").exists()
    rec.begin("wave", 20.0)
    for k in range(100):
        rec.add(step(20.0 + k * 0.002))
    assert rec.finish() == 0
    ep = read_dataset(tmp_path).episode(0)
    assert len(ep) == 10 and ep.task == "wave"
    np.testing.assert_allclose(ep.features["action"][:, 0], 20.0 + np.arange(10) * 0.02 + 1, rtol=1e-6)
    np.testing.assert_allclose(ep.features["observation.effort"][:, 1], -3 * (20.0 + np.arange(10) * 0.02), rtol=1e-6)


def test_the_recorder_puts_the_gripper_last_in_every_vector(tmp_path: Path) -> None:
    pa = pytest.importorskip("pyarrow.parquet")
    from akarm.datasets import GRIPPER, DatasetWriter
    from akarm.teleop import Step
    from akarm.teleop.recording import EpisodeRecorder

    def step(t: float) -> Step:
        q = np.array([t, -t])
        return Step(t, "following", q, q, q, 2 * q, 3 * q, q + 1, q, np.zeros(2), 0.002, (),
                    gripper_command=0.01, gripper_width=0.03, gripper_velocity=0.0, gripper_force=19.5, grasped=True)

    rec = EpisodeRecorder(DatasetWriter(tmp_path, ("a", "b", GRIPPER), 50), rate_hz=500.0)
    rec.begin("grasp", 0.0)
    for k in range(50):
        rec.add(step(k * 0.002))
    assert rec.finish() == 0
    table = pa.read_table(tmp_path / "data/chunk-000/file-000.parquet")
    state = np.array(table.column("observation.state").to_pylist())
    action = np.array(table.column("action").to_pylist())
    effort = np.array(table.column("observation.effort").to_pylist())
    np.testing.assert_allclose((state[:, 2], action[:, 2], effort[:, 2]), ([0.03] * 5, [0.01] * 5, [19.5] * 5),
                               rtol=1e-6)
    plain = EpisodeRecorder(DatasetWriter(tmp_path / "plain", ("a", "b"), 50), rate_hz=500.0)
    plain.begin("grasp", 0.0)
    with pytest.raises(ArgumentError, match="a step of 3 values for a dataset of 2"):
        plain.add(step(0.0))


@pytest.mark.parametrize("force_limit", [[1.0, 2.0, 3.0], "strong", "1.5", [[1.0]], [[1.0, 2.0]], None])
def test_a_bad_force_limit_is_an_argument_error(force_limit: object) -> None:
    import akarm
    from akarm.teleop import Teleop

    from .conftest import ROBOTS

    config = akarm.load_robot(ROBOTS / "planar2.yaml")
    leader = akarm.Arm(config.with_bus(interface="virtual", channel="unit-force-limit-l"))
    follower = akarm.Arm(config.with_bus(interface="virtual", channel="unit-force-limit-f"))
    if force_limit is None:  # one, or one per leader joint: accepted
        assert Teleop(leader, follower, force_limit=0.5).force_limit.tolist() == [0.5, 0.5]
        assert Teleop(leader, follower, force_limit=[0.5, 0.25]).force_limit.tolist() == [0.5, 0.25]
        return
    with pytest.raises(ArgumentError, match=r"one force limit, or one per leader joint \(2\), in N·m"):
        Teleop(leader, follower, force_limit=force_limit)  # type: ignore[arg-type]
