"""LeRobot 0.4.4's own scripts against akarm's simulator, through the plugins: every arm's loop in an
``akarm serve`` process of its own, every simulator in another, LeRobot in a third.

Numbers each test prints (and checks): frames and episodes recorded, how much the camera's frames
change when the arm moves, the replay's tracking error, the largest command step against the limits,
the loop's lateness and missed slots while LeRobot records, and zero safety stops."""

from __future__ import annotations

import importlib.metadata
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import Hand, Poller, run_script, served, sway

from akarm.sim.process import SimulatorProcess

FPS = 30
#: LeRobot's version (major, minor): 0.4.4 in CI; 0.6 runs a policy with lerobot-rollout, not lerobot-record
LEROBOT = tuple(int(x) for x in importlib.metadata.version("lerobot").split(".")[:2])
EPISODE_S = 4.0
RESET_S = 1.0


def bus(prefix: str, robot: Path, channel: str) -> list[str]:
    return [f"--{prefix}.robot_file={robot}", f"--{prefix}.interface=akarm_local", f"--{prefix}.channel={channel}"]


def camera(robot: Path, channel: str, size: tuple[int, int] = (64, 48)) -> str:
    return "--robot.cameras=" + json.dumps({"front": {"type": "akarm_sim", "robot_file": str(robot),
                                                      "interface": "akarm_local", "channel": channel,
                                                      "width": size[0], "height": size[1], "fps": FPS}})


def test_the_plugins_appear_in_lerobots_scripts():
    for script in ("lerobot-teleoperate", "lerobot-replay", "lerobot-record"):  # each imports torch: ~30 s here
        out = run_script(script, "--help", timeout=240)
        assert "akarm" in out.stdout, script
    assert "akarm_leader" in out.stdout
    if LEROBOT < (0, 6):  # (0.6's --help lists the types, not each type's fields, nor the cameras')
        for name in ("--robot.robot_file", "--teleop.robot_file", "--robot.stream_timeout"):
            assert name in out.stdout, name
        assert "akarm_sim" in out.stdout


def command_steps(log: dict[str, np.ndarray], vmax: float, amax: float, rate: float = 500.0) -> tuple[float, float]:
    """The largest command step of position and of velocity, as shares of what the limits allow in a period."""
    dt = 1.0 / rate
    dq = np.abs(np.diff(log["q_des"], axis=0)).max() / (vmax * dt)
    ddq = np.abs(np.diff(log["dq_des"], axis=0)).max() / (amax * dt)
    return float(dq), float(ddq)


def telemetry(client, path: Path, since: float = 0.0) -> dict[str, np.ndarray]:
    client.call("telemetry", since=since, save=str(path))
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def jaws(t: float) -> float:
    """The hand on the leader's free gripper (from half open, 40 mm): closed to 10 mm, opened to 70 mm and
    back every 4 s, at most 47 mm/s."""
    return 0.04 - 0.03 * math.sin(2.0 * math.pi * t / 4.0)


def test_record_two_episodes_with_a_camera_then_replay_one(robot6g, channel, tmp_path):
    """Leader and follower arm6g, each with a gripper: the hand sways two joints and opens and closes
    the leader's gripper; the dataset has ``gripper.pos`` (m) in its actions and state; the replay
    tracks the joints and the gripper; a gripper width past the stroke is clamped and counted."""
    robot = robot6g
    root = tmp_path / "dataset"
    lead, follow = channel + "-lead", channel + "-follow"
    # both start upright (all zeros, balanced: a limp arm elsewhere sags before its server holds it)
    with SimulatorProcess(robot, channel=lead, control=True) as lead_sim, SimulatorProcess(robot, channel=follow), \
            served(robot, lead) as leader, served(robot, follow) as follower:
        follower.call("status")
        # soft, and none on the light wrist joints: a spring pushed every 20 ms against little inertia (the
        # pan, upright) oscillates and went unstable here
        hand = Hand(lead_sim.control, sway([0.0] * 6, [-0.8, 0.0, 0.6, 0.0, 0.0, 0.0], 4.0),
                    k=(4.0, 6.0, 5.0, 0.0, 0.0, 0.0), d=(0.4, 0.6, 0.5, 0.0, 0.0, 0.0), grip=jaws, teaching=leader)
        with hand, Poller(follower) as poll:
            out = run_script("lerobot-record", "--robot.type=akarm", *bus("robot", robot, follow),
                             "--robot.id=follower", camera(robot, follow), "--teleop.type=akarm_leader",
                             *bus("teleop", robot, lead),
                             "--teleop.id=leader", "--dataset.repo_id=local/akarm_sim", f"--dataset.root={root}",
                             "--dataset.num_episodes=2", f"--dataset.episode_time_s={EPISODE_S}",
                             f"--dataset.reset_time_s={RESET_S}", f"--dataset.fps={FPS}",
                             "--dataset.single_task=sway", "--dataset.push_to_hub=false", "--display_data=false",
                             "--play_sounds=false")
        assert out.returncode == 0
        before, after = poll.status[0], poll.status[-1]
        missed = after["missed_slots"] - before["missed_slots"]
        late = max(s["late_p99_us"] for s in poll.status)
        print(f"follower loop while recording: {after['loop_rate_hz']} Hz of {after.get('rate_hz', 400)}, "
              f"{missed} missed slots, late p99 up to {late} us; stop: {after['stop_error'] or 'none'}")
        assert after["stop_error"] == "" and leader.call("status")["stop_error"] == ""

        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        ds = LeRobotDataset("local/akarm_sim", root=root, video_backend="pyav")
        expected = round(EPISODE_S * FPS)
        print(f"dataset: {ds.num_episodes} episodes, {ds.num_frames} frames (of {2 * expected} asked), "
              f"videos {ds.meta.video_keys}")
        assert ds.num_episodes == 2
        # LeRobot's 30 Hz loop runs late on a loaded machine: 193-237 of 240 frames with two arm6g here
        assert 0.75 * 2 * expected <= ds.num_frames <= 2 * expected
        assert ds.meta.video_keys == ["observation.images.front"]
        names = ["shoulder_pan", "shoulder_lift", "elbow", "forearm_roll", "wrist_pitch", "wrist_roll", "gripper"]
        assert list(ds.meta.features["action"]["names"]) == [f"{n}.pos" for n in names]
        assert list(ds.meta.features["observation.state"]["names"]) == [
            f"{n}.{x}" for x in ("pos", "vel", "effort") for n in names]
        # the camera: frames differ as much as the arm moved between them
        ends = [int(x) for x in ds.meta.episodes["dataset_from_index"]]
        frames = [ds[i] for i in range(ends[0], ends[0] + expected - 5, 10)]
        images = np.stack([f["observation.images.front"].numpy() for f in frames])
        states = np.stack([f["observation.state"].numpy()[:6] for f in frames])
        moved = np.abs(states - states[0]).max(axis=1)
        change = np.abs(images - images[0]).mean(axis=(1, 2, 3))
        print("arm moved (rad):", np.round(moved, 3), "image change:", np.round(change, 4))
        assert moved.max() > 0.3
        assert change[moved.argmax()] > 5 * max(change[moved < 0.01].max(initial=0.0), 1e-4)
        stop = int(ds.meta.episodes["dataset_to_index"][0])  # episode 0's own frames (one may be short)
        actions = np.stack([ds[i]["action"].numpy() for i in range(ends[0], stop)])
        widths = np.stack([ds[i]["observation.state"].numpy()[6] for i in range(ends[0], stop)])
        print("actions (rad, m): from", np.round(actions.min(axis=0), 3), "to", np.round(actions.max(axis=0), 3))
        print(f"gripper: asked {actions[:, 6].min() * 1e3:.1f} to {actions[:, 6].max() * 1e3:.1f} mm, measured "
              f"{widths.min() * 1e3:.1f} to {widths.max() * 1e3:.1f} mm")
        assert actions[:, 6].min() < 0.02 and actions[:, 6].max() > 0.06  # the hand's 10 to 70 mm
        assert widths.max() - widths.min() > 0.04  # the follower's jaws followed

        # lerobot-replay of episode 0 on the follower, from the episode's start (lerobot-replay starts
        # wherever the arm is): the follower's measured path passes each recorded action
        follower.call("wait", id=follower.call("move", target=[float(x) for x in actions[0, :6]], speed=0.5)["id"])
        follower.call("gripper_move", width=float(actions[0, 6]))
        started = time.monotonic()
        with Poller(follower) as replayed:
            out = run_script("lerobot-replay", "--robot.type=akarm", *bus("robot", robot, follow),
                             "--robot.id=follower", "--dataset.repo_id=local/akarm_sim", f"--dataset.root={root}",
                             "--dataset.episode=0", f"--dataset.fps={FPS}", "--play_sounds=false")
        took = time.monotonic() - started
        assert out.returncode == 0
        log = telemetry(follower, tmp_path / "replay.npz")  # the loop's own record: every cycle measured
        path = log["q"][log["t"] >= log["t"][-1] - took - 0.5]
        error = np.array([np.abs(path - a[:6]).max(axis=1).min() for a in actions])
        end_error = np.abs(path[-1] - actions[-1, :6]).max()
        grip = np.array(replayed.grip)
        grip = grip[np.isfinite(grip)]
        grip_error = np.array([np.abs(grip - a[6]).min() for a in actions])
        settle = round(0.5 * FPS)  # the episode begins mid-motion; the follower, from rest, takes ~0.3 s to join it
        print(f"replay: {len(actions)} actions; after the first 0.5 s the follower passed each within "
              f"{error[settle:].max():.4f} rad (median {np.median(error[settle:]):.4f}); in the first 0.5 s within "
              f"{error[:settle].max():.4f} rad; at the end {end_error:.4f} rad from the last; the gripper passed "
              f"each width within {grip_error.max() * 1e3:.2f} mm (median {np.median(grip_error) * 1e3:.2f} mm), "
              f"{len(grip)} widths polled")
        assert error[settle:].max() < 0.05 and error[:settle].max() < 0.4 and end_error < 0.05
        assert grip_error[settle:].max() < 0.004
        assert follower.call("status")["stop_error"] == ""

        # a gripper target past the stroke (and below closed), through the Robot: clamped and counted
        from lerobot_robot_akarm import Akarm, AkarmConfig

        arm = Akarm(AkarmConfig(robot_file=str(robot), interface="akarm_local", channel=follow, id="g"))
        arm.connect()
        try:
            pose = {f"{n}.pos": float(x) for n, x in zip(names, actions[-1, :6], strict=False)}
            for width, edge in ((0.12, 0.08), (-0.03, 0.0)):
                for _ in range(30):
                    sent = arm.send_action({**pose, "gripper.pos": width})
                    time.sleep(1 / FPS)
                time.sleep(0.5)
                measured = arm.get_observation()["gripper.pos"]
                print(f"gripper asked {width * 1e3:+.0f} mm: sent {sent['gripper.pos'] * 1e3:.1f} mm, at "
                      f"{measured * 1e3:.2f} mm; {arm.last_report['clamped_total']} targets clamped")
                assert sent["gripper.pos"] == pytest.approx(edge) and abs(measured - edge) < 0.003
                assert arm.last_report["clamped"] == ["gripper"]
            assert arm.last_report["clamped_total"] == 60
        finally:
            arm.disconnect()
        assert follower.call("status")["stop_error"] == "" and leader.call("status")["stop_error"] == ""


def test_lerobot_loads_a_dataset_that_akarm_teleop_recorded_with_a_camera(robot, channel, tmp_path):
    """`akarm teleop --record --camera` (no LeRobot in its process): LeRobot's own LeRobotDataset loads
    the episodes, the camera's frames decoded from the video as akarm wrote them."""
    import subprocess
    import sys

    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from akarm.datasets import read_dataset
    from akarm.datasets.video import decode_video

    root = tmp_path / "demos"
    lead, follow = channel + "-lead", channel + "-follow"
    with SimulatorProcess(robot, channel=lead, control=True) as lead_sim, SimulatorProcess(robot, channel=follow), \
            Hand(lead_sim.control, sway([0.0, 0.0], [-0.4, 0.3], 4.0)):  # slow: the follower engages at 25 % speed
        out = subprocess.run([sys.executable, "-m", "akarm", "teleop", str(robot), str(robot), "-i", "akarm_local",
                              "--leader-channel", lead, "--follower-channel", follow, "--record", str(root),
                              "--task", "sway", "--fps", str(FPS), "--episodes", "2", "--episode-time", "1.0",
                              "--camera", "front", "--camera-size", "64x48",
                              # as the servers here: a loop starved 0.4 s on this loaded machine stopped it
                              "--stall-limit", "3.0"],
                             capture_output=True, text=True, timeout=180, stdin=subprocess.DEVNULL)
    print(out.stdout[-2000:], out.stderr[-3000:])
    assert out.returncode == 0 and "2 episodes saved" in out.stdout
    ds = LeRobotDataset("local/akarm_teleop", root=root, video_backend="pyav")
    key = "observation.images.front"
    print(f"LeRobot loads akarm's dataset: {ds.num_episodes} episodes, {ds.num_frames} frames, videos "
          f"{ds.meta.video_keys}, features {list(ds.meta.features)}")
    assert ds.num_episodes == 2 and ds.num_frames == 2 * FPS and ds.meta.video_keys == [key]
    ours = read_dataset(root)
    for k in (0, 1):
        path, _, _ = ours.video(k, key)
        frames = decode_video(path)  # as akarm wrote them
        start = int(ds.meta.episodes["dataset_from_index"][k])
        for i in (0, FPS // 2, FPS - 1):
            item = ds[start + i]
            img = item[key].numpy()  # (3, H, W), 0-1
            assert img.shape == (3, 48, 64) and int(item["frame_index"]) == i
            diff = np.abs(img.transpose(1, 2, 0) * 255 - frames[i]).mean()
            assert diff < 2.0, (k, i, diff)  # the same frame, decoded by LeRobot
    states = np.stack([ds[i]["observation.state"].numpy()[:2] for i in range(ds.num_frames)])
    far = int(np.abs(states - states[0]).max(axis=1).argmax())  # the frame where the arm is farthest from frame 0
    moved = float(np.abs(states[far] - states[0]).max())
    change = float(np.abs(ds[0][key].numpy() - ds[far][key].numpy()).mean())
    print(f"the camera's picture changed by {change:.4f} (0-1) as the arm moved {moved:.3f} rad (frame {far})")
    assert moved > 0.03 and change > 0.02 * moved  # here: 0.07 per rad


def test_a_safety_stop_ends_the_session_with_its_name_and_the_arm_disabled(robot, channel):
    lead, follow = channel + "-lead", channel + "-follow"
    with SimulatorProcess(robot, channel=lead), SimulatorProcess(robot, channel=follow, control=True) as sim, \
            served(robot, lead) as leader, served(robot, follow) as follower:
        def unplug() -> None:  # once the session runs: the leader in teach mode, 2 s more
            end = time.monotonic() + 90
            while leader.call("status")["mode"] != "teach" and time.monotonic() < end:
                time.sleep(0.1)
            time.sleep(2.0)
            sim.control.inject("elbow", "unplugged")

        import threading

        threading.Thread(target=unplug, daemon=True).start()
        out = run_script("lerobot-teleoperate", "--robot.type=akarm", *bus("robot", robot, follow),
                         "--teleop.type=akarm_leader", *bus("teleop", robot, lead), f"--fps={FPS}",
                         "--teleop_time_s=30", timeout=120)
        status = follower.call("status")
        state = follower.call("state", read=False)
        print("stop:", status["stop_error"], status["fault"])
        assert out.returncode != 0
        assert status["stop_error"] and f"akarm.errors.{status['stop_error']}: " in out.stdout
        assert status["fault"][:60] in out.stdout
        assert not state["enabled"] and state["mode"] == "fault"


def test_a_stream_refused_for_a_latched_stop_raises_the_stop_itself(robot, channel):
    """The stop that comes between two of LeRobot's actions: the next action's stream is refused
    (StopLatched), and the plugin raises the stop itself (its class, joint and fix), the refusal chained."""
    from lerobot_robot_akarm.served import ServedArm

    from akarm.errors import FeedbackTimeout, StopLatched

    with SimulatorProcess(robot, channel=channel, control=True) as sim, served(robot, channel) as server:
        arm = ServedArm(robot, "akarm_local", channel, start=False)
        try:
            q = [float(x) for x in arm.state()["q"]]
            assert arm.stream(q)["target"] == pytest.approx(q)
            sim.control.inject("elbow", "unplugged")
            end = time.monotonic() + 10
            while not server.call("status")["stop_error"] and time.monotonic() < end:
                time.sleep(0.05)
            assert server.call("status")["stop_error"] == "FeedbackTimeout"
            with pytest.raises(StopLatched):
                server.call("stream", target=q)  # what the server answers
            with pytest.raises(FeedbackTimeout) as raised:
                arm.stream(q)  # what the plugin raises
            assert raised.value.joint == "elbow" and raised.value.fix
            assert isinstance(raised.value.__cause__, StopLatched)
        finally:
            arm.close()


def test_a_policy_past_the_limit_nan_or_silent(robot, channel, tmp_path):
    """A "policy" through the Robot's send_action at 30 Hz: 1 rad past the shoulder's limit (clamped),
    NaN (refused, the arm holds), nothing for 1 s (decelerates to a hold), then resumed."""
    import torch
    from lerobot_robot_akarm import Akarm, AkarmConfig

    from akarm.errors import ArgumentError

    with SimulatorProcess(robot, channel=channel, pose="down"), served(robot, channel) as server:
        arm = Akarm(AkarmConfig(robot_file=str(robot), interface="akarm_local", channel=channel, id="p"))
        arm.connect()
        try:
            upper = 1.8
            t0 = time.monotonic()
            q_trace: list[tuple[float, float]] = []

            def frames(seconds: float, action: dict | None) -> None:
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    tick = time.monotonic()
                    if action is not None:
                        arm.send_action(action)
                    obs = arm.get_observation()
                    q_trace.append((tick - t0, obs["shoulder.pos"]))
                    time.sleep(max(0.0, 1 / FPS - (time.monotonic() - tick)))

            # 1 rad past the limit, sent as 0-d tensors (as lerobot-replay sends them)
            frames(3.0, {"shoulder.pos": torch.tensor(upper + 1.0), "elbow.pos": torch.tensor(0.3)})
            q = arm.get_observation()["shoulder.pos"]
            clamped_total = arm.last_report["clamped_total"]
            print(f"past the limit: shoulder at {q:+.4f} rad (limit {upper}); {clamped_total} targets clamped")
            assert abs(q - upper) < 0.02 and max(x for _, x in q_trace) <= upper + 0.01 and clamped_total >= 60

            # NaN while moving: refused, the arm holds
            frames(0.3, {"shoulder.pos": -1.5, "elbow.pos": 0.0})
            with pytest.raises(ArgumentError, match="is not a number") as refused:
                arm.send_action({"shoulder.pos": math.nan, "elbow.pos": 0.0})
            assert refused.value.joint == "shoulder"
            t_nan = time.monotonic() - t0
            frames(1.0, None)
            held = [x for t, x in q_trace if t > t_nan + 0.6]
            print(f"NaN: refused; the shoulder came to rest at {held[-1]:+.4f} rad, "
                  f"moving {np.ptp(held):.5f} rad over its last 0.4 s (target was -1.5)")
            assert np.ptp(held) < 0.005 and held[-1] > -1.3

            # silent for 1 s while heading for a far target
            frames(0.1, {"shoulder.pos": -1.7, "elbow.pos": 0.0})
            t_quiet = time.monotonic() - t0
            frames(1.0, None)
            quiet = [x for t, x in q_trace if t > t_quiet + 0.6]
            print(f"silent 1 s: the shoulder decelerated to a hold at {quiet[-1]:+.4f} rad "
                  f"(moving {np.ptp(quiet):.5f} rad over its last 0.4 s; target was -1.7)")
            assert np.ptp(quiet) < 0.005 and quiet[-1] > -1.6
            frames(1.5, {"shoulder.pos": 0.0, "elbow.pos": 0.0})  # resumed
            assert abs(arm.get_observation()["shoulder.pos"]) < 0.02
            # a partial .pos dict: the elbow alone
            frames(1.0, {"elbow.pos": 0.5})
            obs = arm.get_observation()
            assert abs(obs["elbow.pos"] - 0.5) < 0.02 and abs(obs["shoulder.pos"]) < 0.02

            log = telemetry(server, tmp_path / "t.npz")
            steps = command_steps(log, 4.0, 20.0)
            print(f"largest command step: {steps[0]:.3f} of the velocity limit's, {steps[1]:.3f} of the "
                  "acceleration limit's, per period")
            assert steps[0] <= 1.001 and steps[1] <= 1.001
            assert log["q_des"][:, 0].max() <= upper + 1e-9
            assert server.call("status")["stop_error"] == ""
        finally:
            arm.disconnect()


# LeRobot 0.6's lerobot-rollout gives the policy only the .pos and .vel features as its state: the
# episodes it is trained on are recorded without .effort there (the plugin's effort=false)
NO_EFFORT = ["--robot.effort=false"] if LEROBOT >= (0, 6) else []
ACT = ["--policy.type=act", "--policy.pretrained_backbone_weights=null", "--policy.device=cpu",
       "--policy.push_to_hub=false", "--policy.chunk_size=10", "--policy.n_action_steps=10", "--policy.dim_model=64",
       "--policy.n_heads=2", "--policy.dim_feedforward=128", "--policy.n_encoder_layers=1",
       "--policy.n_decoder_layers=1", "--policy.use_vae=false"]


def test_act_trained_on_recorded_episodes_runs_on_the_follower(robot, channel, tmp_path):
    """The plumbing, not the skill: 2 episodes recorded, a small ACT (random initialisation, no download)
    trained a few steps on CPU, then rolled out with lerobot-record --policy.path on the follower: no
    safety stop, no command step above the limits, the arm's motion measured."""
    root, lead, follow = tmp_path / "dataset", channel + "-lead", channel + "-follow"
    with SimulatorProcess(robot, channel=lead, control=True) as lead_sim, \
            SimulatorProcess(robot, channel=follow, pose="down"), served(robot, lead), \
            served(robot, follow) as follower:
        with Hand(lead_sim.control, sway([0.0, 0.0], [-1.0, 0.8], 4.0)):
            out = run_script("lerobot-record", "--robot.type=akarm", *bus("robot", robot, follow),
                             "--robot.id=follower", *NO_EFFORT, camera(robot, follow), "--teleop.type=akarm_leader",
                             *bus("teleop", robot, lead), "--teleop.id=leader", "--dataset.repo_id=local/akarm_act",
                             f"--dataset.root={root}", "--dataset.num_episodes=2", "--dataset.episode_time_s=3",
                             "--dataset.reset_time_s=1", f"--dataset.fps={FPS}", "--dataset.single_task=sway",
                             "--dataset.push_to_hub=false", "--display_data=false", "--play_sounds=false")
        assert out.returncode == 0

    # trained with no arm running: training takes both cores (on this shared machine it starved a
    # server's loop past its 1 s stall limit once); a robot's computer is not where one trains
    started = time.monotonic()
    out = run_script("lerobot-train", "--dataset.repo_id=local/akarm_act", f"--dataset.root={root}",
                     "--dataset.video_backend=pyav", *ACT, "--steps=20", "--batch_size=4", "--num_workers=0",
                     "--wandb.enable=false", f"--output_dir={tmp_path / 'train'}", "--save_freq=20",
                     "--log_freq=10", timeout=1800)
    assert out.returncode == 0
    model = tmp_path / "train" / "checkpoints" / "last" / "pretrained_model"
    assert (model / "model.safetensors").is_file()
    print(f"ACT: 20 steps trained in {time.monotonic() - started:.0f} s")

    with SimulatorProcess(robot, channel=follow, pose="down"), served(robot, follow) as follower:
        since = follower.call("state", read=False)
        with Poller(follower) as poll:
            if LEROBOT >= (0, 6):  # 0.6 rolls a policy out with lerobot-rollout (no dataset: the base strategy)
                out = run_script("lerobot-rollout", "--strategy.type=base", "--robot.type=akarm",
                                 *bus("robot", robot, follow), "--robot.id=follower", *NO_EFFORT, camera(robot, follow),
                                 f"--policy.path={model}", "--task=sway", "--duration=4", f"--fps={FPS}",
                                 "--display_data=false", "--play_sounds=false")
            else:
                out = run_script("lerobot-record", "--robot.type=akarm", *bus("robot", robot, follow),
                                 "--robot.id=follower", *NO_EFFORT, camera(robot, follow), f"--policy.path={model}",
                                 "--dataset.repo_id=local/eval_akarm_act", f"--dataset.root={tmp_path / 'eval'}",
                                 "--dataset.num_episodes=1", "--dataset.episode_time_s=4", "--dataset.reset_time_s=0",
                                 f"--dataset.fps={FPS}", "--dataset.single_task=sway", "--dataset.push_to_hub=false",
                                 "--display_data=false", "--play_sounds=false")
        assert out.returncode == 0
        path = poll.path
        moved = np.abs(path - np.array(since["q"])).max(axis=0)
        before, after = poll.status[0], poll.status[-1]
        log = telemetry(follower, tmp_path / "rollout.npz")
        steps = command_steps(log, 4.0, 20.0)
        print(f"rollout: the follower moved up to {np.round(moved, 3)} rad per joint; largest command step "
              f"{steps[0]:.3f} of the velocity limit's, {steps[1]:.3f} of the acceleration limit's; loop "
              f"{after['loop_rate_hz']} Hz, {after['missed_slots'] - before['missed_slots']} missed slots, late p99 "
              f"{after['late_p99_us']} us; stop: {after['stop_error'] or 'none'}")
        assert after["stop_error"] == ""
        assert steps[0] <= 1.001 and steps[1] <= 1.001
        assert moved.max() > 0.05  # the policy's actions moved the arm

        # the same policy by async inference: policy_server and robot_client, each a process of its own
        import signal
        import socket
        import subprocess
        import sys

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        follower.call("wait", id=follower.call("move", target="down", speed=0.5)["id"])
        since = follower.call("state", read=False)
        server = subprocess.Popen([sys.executable, "-m", "lerobot.async_inference.policy_server", "--host=127.0.0.1",
                                   f"--port={port}"], cwd=tmp_path)  # (not this folder: python -m puts the
        # working directory first on the path, where the plugins' project folders would shadow the packages)
        try:
            with Poller(follower) as poll:
                client = subprocess.Popen([sys.executable, "-m", "lerobot.async_inference.robot_client",
                                           "--robot.type=akarm", *bus("robot", robot, follow), "--robot.id=follower",
                                           *NO_EFFORT, camera(robot, follow), "--task=sway",
                                           f"--server_address=127.0.0.1:{port}",
                                           "--policy_type=act", f"--pretrained_name_or_path={model}",
                                           "--policy_device=cpu", "--client_device=cpu", "--actions_per_chunk=10",
                                           "--chunk_size_threshold=0.5", f"--fps={FPS}"], cwd=tmp_path)
                end = time.monotonic() + 240  # imports and the model's load, on a busy machine
                while time.monotonic() < end and client.poll() is None:
                    if poll.q and np.abs(np.array(poll.q[-1]) - since["q"]).max() > 0.05:
                        break
                    time.sleep(0.5)
                time.sleep(10.0)  # 10 s of the policy driving the arm
                running = client.poll() is None
                client.send_signal(signal.SIGINT)
                try:
                    client.wait(30)
                except subprocess.TimeoutExpired:
                    client.kill()
                    client.wait()
        finally:
            server.send_signal(signal.SIGINT)
            try:
                server.wait(30)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()
        moved = np.abs(poll.path - np.array(since["q"])).max(axis=0)
        after = poll.status[-1]
        log = telemetry(follower, tmp_path / "async.npz")
        steps = command_steps(log, 4.0, 20.0)
        print(f"async inference: the follower moved up to {np.round(moved, 3)} rad per joint; largest command step "
              f"{steps[0]:.3f} of the velocity limit's, {steps[1]:.3f} of the acceleration limit's; "
              f"stop: {after['stop_error'] or 'none'}")
        assert running, "robot_client ended before it was stopped"
        assert after["stop_error"] == ""
        assert steps[0] <= 1.001 and steps[1] <= 1.001
        assert moved.max() > 0.05
