"""Teleoperation's acceptance: two simulated arms, the leader pushed by the simulator's external torque
as a hand would push it. The long lock-step runs (a leader and a follower on one clock,
tests/teleop_rig.py), then ``akarm teleop`` and ``akarm replay DIR --episode K`` as a person runs them:
two simulators in processes of their own, keys on stdin, a LeRobot dataset and an MCAP log."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from akarm import SafetyStop
from akarm.sim import faults
from akarm.teleop import Teleop

from ..teleop_rig import Hand, leader_follower, run, smooth
from .conftest import ROBOTS, relaxed_robot, wait_until

HOME = [-0.5, 0.3]


def lag_of(t: np.ndarray, leader: np.ndarray, follower: np.ndarray, longest: float = 0.2) -> float:
    """The delay (s, on the grid of ``t``) that best lays the follower's path on the leader's."""
    dt = float(np.median(np.diff(t)))
    shifts = range(int(longest / dt))
    rms = [np.sqrt(np.mean((follower[s:] - leader[:len(leader) - s]) ** 2)) for s in shifts]
    return dt * int(np.argmin(rms))


def test_after_engaging_the_follower_tracks_the_leader_within_20_mrad_and_the_lag_is_small(
        channel: str, record_property: pytest.RecordPropertyFixture) -> None:
    with leader_follower(channel, leader_q0=HOME, follower_q0=[-0.2, 0.1]) as (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        # 0.6 rad and 0.3 rad swings at 0.4 Hz: up to 0.75 and 0.38 rad/s, moderate for a hand
        hand = Hand(lsim, smooth(HOME, [0.6, -0.3], 0.4, start=t0 + 1.5))  # once engaged
        with Teleop(leader, follower) as tele:
            steps = run(tele, 4.5, hand)
    engaged = next(k for k, s in enumerate(steps) if s.phase == "following")
    after = steps[engaged + 100:]                                         # 0.2 s after engaging, on
    err = np.array([s.follower_q - s.command for s in after])
    speed = np.abs(np.array([s.leader_dq for s in after])).max(axis=0)
    assert speed[0] > 0.7 and speed[1] > 0.3
    assert np.abs(err).max() < 0.020, np.abs(err).max(axis=0)
    t = np.array([s.t for s in after])
    lags = [lag_of(t, np.array([s.command[j] for s in after]), np.array([s.follower_q[j] for s in after]))
            for j in range(2)]
    record_property("teleop_lag_ms", [round(x * 1e3, 1) for x in lags])
    record_property("teleop_max_error_mrad", np.round(np.abs(err).max(axis=0) * 1e3, 1).tolist())
    print(f"lag {[round(x * 1e3, 1) for x in lags]} ms, max error {np.abs(err).max(axis=0) * 1e3} mrad")
    assert max(lags) <= 0.030


def test_engaging_one_radian_apart_makes_no_command_step_above_the_velocity_limit(channel: str) -> None:
    with leader_follower(channel, leader_q0=HOME, follower_q0=[0.5, -0.7]) as (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        with Teleop(leader, follower, engage_speed=1.0) as tele:   # even at full speed
            lsim.set_external_torque([2.0, -1.0])                  # and a hand that shoves the leader meanwhile
            steps = run(tele, 0.6)
            lsim.set_external_torque(None)
            steps += run(tele, 1.4)
        log = follower.telemetry(since=t0)
    assert abs(follower.state().q_des[0] - 0.5) > 0.9 or steps[0].phase == "engaging"
    step = np.abs(np.diff(log.q_des, axis=0))
    period = 1.0 / follower.config.rate_hz
    assert np.all(step <= follower.limits.velocity * period + 1e-12), step.max(axis=0)
    assert any(s.phase == "following" for s in steps)
    assert step.max(axis=0)[0] > 0.9 * follower.limits.velocity[0] * period  # (it did move at its limit)


def test_a_leader_pose_past_a_follower_limit_never_gives_a_command_past_it(channel: str) -> None:
    def narrow(config):  # the follower's elbow may go only to +0.4 rad
        joints = list(config.joints)
        joints[1] = replace(joints[1], limits=replace(joints[1].limits, upper=0.4))
        return replace(config, joints=tuple(joints))

    said: list[str] = []
    with leader_follower(channel, leader_q0=HOME, follower_q0=HOME, follower_edit=narrow) as \
            (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        hand = Hand(lsim, smooth(HOME, [0.0, 0.8], 0.5, start=t0 + 0.3))   # the elbow to 1.1 rad and back
        with Teleop(leader, follower, say=said.append) as tele:
            steps = run(tele, 2.6, hand)
        log = follower.telemetry(since=t0)
    assert max(s.leader_q[1] for s in steps) > 1.0
    assert log.q_des[:, 1].max() <= 0.4 + 1e-12                            # never a command past the limit
    assert log.q_des[:, 1].max() > 0.4 - 2e-3                              # it waited at the edge
    assert any("outside its range: it waits at +0.400 rad" in line and "elbow" in line for line in said)
    assert any("back within the follower's range" in line for line in said)
    assert steps[-1].phase == "following" and abs(steps[-1].follower_q[1] - steps[-1].command[1]) < 0.02


def test_with_force_feedback_a_blocked_follower_joint_is_felt_at_the_leader_within_50_ms(channel: str) -> None:
    with leader_follower(channel, leader_q0=HOME, follower_q0=HOME) as (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        hand = Hand(lsim, smooth(HOME, [0.0, 0.6], 0.4, start=t0 + 0.3))  # the elbow turning, 0.75 rad/s at most
        with Teleop(leader, follower, force_feedback=1.0) as tele:
            before = run(tele, 0.8, hand)
            quiet = np.abs([s.feedback[1] for s in before[-100:]]).max()
            t_block = leader.clock.now()
            fsim.inject("elbow", faults.Blocked())              # a block in front of the follower's elbow
            with pytest.raises(SafetyStop):                     # (its stuck-joint check then stops both)
                run(tele, 1.0, hand)
            leader_log = leader.telemetry(since=t_block - 0.1)
    base = leader_log.tau_ff[leader_log.t <= t_block, 1][-1]    # the leader's torque: its weight + the feedback
    felt = leader_log.t[(np.abs(leader_log.tau_ff[:, 1] - base) > 0.2) & (leader_log.t > t_block)]
    assert quiet < 0.05
    assert felt.size and felt[0] - t_block <= 0.050, felt[:1] - t_block
    assert not leader.enabled and not follower.enabled


@pytest.mark.parametrize(("arm", "fault"), [("leader", faults.Unplugged()), ("follower", faults.Unplugged()),
                                            ("leader", faults.FaultAfter(0.2, 1)), ("follower", faults.ErrorCode(5))])
def test_a_fault_on_either_arm_while_following_stops_both(channel: str, arm: str, fault: faults.Fault) -> None:
    with leader_follower(channel, leader_q0=HOME, follower_q0=HOME) as (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        hand = Hand(lsim, smooth(HOME, [0.4, 0.3], 0.5, start=t0))
        with Teleop(leader, follower, force_feedback=0.5) as tele:
            run(tele, 0.5, hand)
            (lsim if arm == "leader" else fsim).inject("shoulder", fault)
            with pytest.raises(SafetyStop):
                run(tele, 2.0, hand)
        assert tele.phase == "stopped" and not leader.enabled and not follower.enabled
        lsim.set_external_torque(None)
        leader.clock.sleep_until(leader.clock.now() + 0.05)
        faulty = (lsim if arm == "leader" else fsim).joint("shoulder")
        unreachable = [faulty] if isinstance(fault, faults.Unplugged) else []  # (it cannot hear the exit)
        assert not any(d.enabled for d in (*lsim.drivers, *fsim.drivers) if d not in unreachable)


def test_a_session_log_holds_both_arms_bit_for_bit(channel: str, tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    from akarm.telemetry.log import load_mcap
    from akarm.telemetry.mcap import save_mcap

    with leader_follower(channel, leader_q0=HOME, follower_q0=HOME) as (leader, lsim, follower, fsim):
        t0 = leader.clock.now()
        with Teleop(leader, follower) as tele:
            lsim.set_external_torque([0.4, 0.1])
            run(tele, 0.5)
        logs = {"leader": leader.telemetry(since=t0), "follower": follower.telemetry(since=t0)}
    path = save_mcap(tmp_path / "session.mcap", logs)
    back = load_mcap(path)
    for name, log in logs.items():
        for field in ("q", "dq", "tau", "q_des", "dq_des", "tau_ff", "tau_ext"):
            np.testing.assert_array_equal(getattr(back[name], field), getattr(log, field))
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == "/follower/joint_states"]
        rows = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    np.testing.assert_array_equal(np.array([m.position for m in rows]), logs["follower"].q)
    np.testing.assert_array_equal(np.array([m.effort for m in rows]), logs["follower"].tau)


# ------------------------------------------------------------------------------------------------
# akarm teleop and akarm replay DIR --episode K, as a person runs them
# ------------------------------------------------------------------------------------------------
def _akarm(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", "import sys; from akarm.cli import main; sys.exit(main())", *args],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


class _Lines:
    """A process's stderr lines as they come (a thread reads them)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[str] = []
        self.seen = 0  # lines before this one were matched already
        assert proc.stderr is not None
        self.proc = proc
        stream = proc.stderr
        self.reader = threading.Thread(target=lambda: self.lines.extend(iter(stream.readline, "")), daemon=True)
        self.reader.start()

    def finish(self, timeout: float = 30.0) -> str:
        """Wait for the process to end; its stdout, and every stderr line read (the reader is the only
        one to read stderr: ``communicate()`` would race it for the last lines)."""
        proc = self.proc
        assert proc.stdin is not None and proc.stdout is not None
        with contextlib.suppress(OSError):
            proc.stdin.close()
        proc.wait(timeout)
        out = proc.stdout.read()
        self.reader.join(timeout)
        return out

    def wait_for(self, text: str, timeout: float = 30.0) -> bool:
        """Wait for a line with ``text`` after the last one matched."""

        def found() -> bool:
            for k in range(self.seen, len(self.lines)):
                if text in self.lines[k]:
                    self.seen = k + 1
                    return True
            return False

        return wait_until(found, timeout)

    def __str__(self) -> str:
        return "".join(self.lines)

    __repr__ = __str__


def test_akarm_teleop_records_three_episodes_and_logs_both_arms(tmp_path: Path) -> None:
    from akarm.datasets import read_dataset
    from akarm.sim.process import SimulatorProcess
    from akarm.telemetry.log import load_mcap

    pq = pytest.importorskip("pyarrow.parquet")
    robot = str(relaxed_robot(ROBOTS / "planar2.yaml", tmp_path))
    tag = f"{os.getpid()}-{time.monotonic_ns() % 10**6}"
    data, log = tmp_path / "demos", tmp_path / "session.mcap"
    with SimulatorProcess(robot, channel=f"lead-{tag}", control=True, pose="down") as lead, \
            SimulatorProcess(robot, channel=f"foll-{tag}", control=True, pose="down") as foll:
        proc = _akarm("teleop", robot, robot, "-i", "akarm_local", "--leader-channel", f"lead-{tag}",
                      "--follower-channel", f"foll-{tag}", "--record", str(data), "--task", "wave",
                      "--fps", "30", "--log", str(log), "--force-feedback", "0.3", "--damping", "1.0")
        assert proc.stdin is not None
        err = _Lines(proc)
        try:
            for k, (keys, then) in enumerate([("\n", "episode 0 saved"), ("r\n", "episode 1 dropped"),
                                               ("\n", "episode 1 saved"), ("q\n", "episode 2 saved")]):
                assert err.wait_for(f"recording episode {[0, 1, 1, 2][k]}"), err
                for push in ([0.4, 0.15], [-0.4, -0.15]):   # the hand moves the leader a little, and back
                    lead.control.push(push)
                    time.sleep(0.4)
                lead.control.push(None)
                proc.stdin.write(keys)
                proc.stdin.flush()
                assert err.wait_for(then), err
            out = err.finish()
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 0, err
        err = str(err)
        assert not any(s.enabled for s in foll.control.state()) and not any(s.enabled for s in lead.control.state())
    assert "engaged" in err and "episode 1 dropped: recording it again" in err and "episode 2 saved" in err
    assert "3 episodes saved" in out and "latency p50" in out
    ds = read_dataset(data)
    assert (ds.total_episodes, ds.fps, ds.tasks, ds.joint_names) == (3, 30, ["wave"], ("shoulder", "elbow"))
    table = pq.read_table(data / "data/chunk-000/file-000.parquet")
    assert {"timestamp", "frame_index", "episode_index", "index", "task_index", "observation.state",
            "observation.velocity", "observation.effort", "action"} <= set(table.column_names)
    index = table.column("episode_index").to_numpy()
    assert sorted(set(index.tolist())) == [0, 1, 2]
    for k in range(3):
        ep = ds.episode(k)
        assert len(ep) >= 15                                   # (each lasted about a second)
        np.testing.assert_allclose(ep.timestamp, np.arange(len(ep)) / 30, atol=1e-6)
    assert table.column("index").to_numpy().tolist() == list(range(ds.total_frames))
    arms = load_mcap(log)
    assert set(arms) == {"leader", "follower"} and len(arms["follower"]) > 500

    # SIGTERM in the middle of an episode: both arms damped and disabled, that episode dropped whole
    with SimulatorProcess(robot, channel=f"lead-{tag}", control=True, pose="down") as lead, \
            SimulatorProcess(robot, channel=f"foll-{tag}", control=True, pose="down") as foll:
        proc = _akarm("teleop", robot, robot, "-i", "akarm_local", "--leader-channel", f"lead-{tag}",
                      "--follower-channel", f"foll-{tag}", "--record", str(data), "--task", "wave", "--fps", "30")
        lines = _Lines(proc)
        try:
            assert lines.wait_for("recording episode 3"), lines
            lead.control.push([0.4, 0.15])
            time.sleep(0.5)
            proc.terminate()
            out = lines.finish()
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 143, lines
        assert not any(s.enabled for s in foll.control.state()) and not any(s.enabled for s in lead.control.state())
    assert "episode 3 dropped (interrupted)" in str(lines) and "0 episodes saved" in out
    assert read_dataset(data).total_episodes == 3 and not list(data.rglob("*.tmp"))

    # and an episode replays on the follower (checked against every limit first)
    with SimulatorProcess(robot, channel=f"foll-{tag}") as foll:
        proc = _akarm("replay", robot, str(data), "--episode", "1", "-i", "akarm_local", "-c", f"foll-{tag}")
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "replaying" in out and "episode 1" in out and "done; RMS tracking error" in out


def test_lerobots_own_loader_reads_a_recorded_dataset(tmp_path: Path) -> None:
    """Where the ``lerobot`` package is installed (optional and heavy: it brings torch)."""
    pytest.importorskip("lerobot")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from akarm.datasets import DatasetWriter, EpisodeFrames

    w = DatasetWriter(tmp_path / "ds", ("shoulder", "elbow"), 30, robot_type="planar2")
    rng = np.random.default_rng(0)
    eps = [rng.normal(size=(n, 2)) for n in (40, 55, 31)]
    for k, x in enumerate(eps):
        w.save_episode("wave" if k != 1 else "point", EpisodeFrames(x, x, x, x + 1))
    ds = LeRobotDataset("local/akarm-test", root=tmp_path / "ds")
    assert (ds.num_episodes, ds.num_frames, ds.fps) == (3, 126, 30)
    item = ds[40 + 7]
    assert int(item["episode_index"]) == 1 and int(item["frame_index"]) == 7 and item["task"] == "point"
    assert float(item["timestamp"]) == pytest.approx(7 / 30, abs=1e-6)
    np.testing.assert_allclose(item["action"].numpy(), eps[1][7] + 1, rtol=1e-6)


@pytest.mark.parametrize("feedback", [0.0, 0.5])
def test_the_followers_collision_reflex_stays_armed_or_with_force_feedback_holds(channel: str,
                                                                                  feedback: float) -> None:
    from akarm import CollisionError
    from akarm.config import RobotConfig

    def sensitive(config: RobotConfig) -> RobotConfig:  # the follower's elbow judges a collision past 1 N·m
        joints = list(config.joints)
        joints[1] = replace(joints[1], collision_threshold=1.0)
        return replace(config, joints=tuple(joints))

    said: list[str] = []
    with leader_follower(channel, leader_q0=HOME, follower_q0=HOME, follower_edit=sensitive) as \
            (leader, lsim, follower, fsim):
        with Teleop(leader, follower, force_feedback=feedback, say=said.append) as tele:
            run(tele, 0.4)
            assert tele.phase == "following"
            fsim.set_external_torque([0.0, 3.0])          # something pushes the follower's elbow hard
            if feedback == 0.0:                           # armed as its file says: a stop, of both arms
                with pytest.raises(CollisionError):
                    run(tele, 0.5)
                assert not leader.enabled and not follower.enabled
                return
            steps = run(tele, 0.5)
            assert tele.phase == "holding" and follower.enabled and leader.mode.name == "TEACH"
            assert any("touched something" in line for line in said)
            assert np.all(steps[-1].feedback == 0.0)       # resting against it: no push on the hand
            fsim.set_external_torque(None)                # it goes away; the leader is near the follower
            steps = run(tele, 1.5)
        assert "engaging again" in " ".join(said) and steps[-1].phase == "following"
        assert follower.collision_reaction == "disable"   # as it was before the session


def test_akarm_teleop_of_arms_with_grippers_records_the_gripper_column(tmp_path: Path) -> None:
    """`akarm teleop --record` with a follower that has a gripper: the dataset's vectors end with
    `gripper`, the follower's width (measured and asked), read back with pyarrow. A simulated camera
    (`--camera front`) is recorded as video in LeRobot's layout, the object between the follower's
    jaws drawn; akarm's reader finds it."""
    import json

    from akarm.datasets import read_dataset
    from akarm.datasets.video import decode_video
    from akarm.sim.process import SimulatorProcess

    pq = pytest.importorskip("pyarrow.parquet")
    pytest.importorskip("av")
    robot = relaxed_robot(ROBOTS / "arm6g.yaml", tmp_path)
    tag = f"{os.getpid()}-{time.monotonic_ns() % 10**6}"
    data = tmp_path / "grasps"
    with SimulatorProcess(robot, channel=f"gl-{tag}", control=True) as lead, \
            SimulatorProcess(robot, channel=f"gf-{tag}", control=True) as foll:
        assert lead.control is not None and foll.control is not None
        foll.control.place_object(0.02)  # narrower than the jaws open: between them, untouched
        proc = _akarm("teleop", str(robot), str(robot), "-i", "akarm_local", "--leader-channel", f"gl-{tag}",
                      "--follower-channel", f"gf-{tag}", "--record", str(data), "--task", "grasp", "--fps", "30",
                      "--episodes", "1", "--episode-time", "1.0", "--camera", "front", "--camera-size", "96x72",
                      "--sim-control", str(foll.control.path))
        err = _Lines(proc)
        out = err.finish(timeout=120)
        assert proc.returncode == 0, str(err)
        assert "1 episode saved" in out, out
        leader_width, _ = lead.control.gripper()
    info = json.loads((data / "meta/info.json").read_text())
    for key in ("observation.state", "action", "observation.effort"):
        assert info["features"][key]["names"][-1] == "gripper" and info["features"][key]["shape"] == [7]
    table = pq.read_table(data / "data/chunk-000/file-000.parquet")
    state = np.array(table.column("observation.state").to_pylist())
    action = np.array(table.column("action").to_pylist())
    assert len(state) == 30 and np.all(np.isfinite(state[:, 6])) and np.all((state[:, 6] >= 0) & (state[:, 6] <= 0.081))
    # the follower's jaws are asked the leader's width (the same stroke), and are there
    assert action[-1, 6] == pytest.approx(leader_width, abs=0.001)
    assert state[-1, 6] == pytest.approx(action[-1, 6], abs=0.002)
    # the camera: LeRobot's layout and info, one frame per frame, the arm and the object drawn
    key = "observation.images.front"
    assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    assert info["features"][key]["dtype"] == "video" and info["features"][key]["shape"] == [72, 96, 3]
    assert info["features"][key]["info"]["video.codec"] == "av1"
    ds = read_dataset(data)
    path, start, end = ds.video(0, key)
    assert ds.video_keys == (key,) and path == data / "videos" / key / "chunk-000" / "file-000.mp4"
    assert (start, end) == (0.0, pytest.approx(1.0))
    frames = decode_video(path)
    # the object: red, its green and blue alike (the links' orange has far more green than blue; AV1's
    # 4:2:0 colour at this size pales both): 8 such pixels a frame with the object, 0 without, here
    r, g, b = (frames[..., c].astype(int) for c in range(3))
    red = (r - g > 35) & (np.abs(g - b) < 25)
    drawn = np.abs(frames.astype(int) - frames[:, :, :1].astype(int)).max(axis=-1) > 40  # unlike the row's background
    print(f"camera: {frames.shape}, {red.sum(axis=(1, 2)).mean():.1f} object pixels, "
          f"{drawn.sum(axis=(1, 2)).mean():.1f} pixels of the arm a frame")
    assert frames.shape == (30, 72, 96, 3) and red.sum(axis=(1, 2)).min() >= 4 and drawn.sum(axis=(1, 2)).min() > 60
    assert len(ds.episode(0)) == 30  # the reader takes the dataset as before
