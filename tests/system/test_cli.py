"""Every ``akarm`` verb end to end, in-process, against the real-time simulator on a virtual bus.

The simulator runs in this process (python-can's virtual bus does not cross processes) and the
verbs are called through :func:`akarm.cli.main`, the way the ``akarm`` command calls them. planar2
starts hanging straight down (shoulder -π/2, elbow 0), where it stays when its motors are limp.

Verbs that run a control loop (enable, move, teach, replay) use a copy of planar2.yaml whose
feedback watchdog allows 0.25 s instead of 20 ms: the simulator shares this process and the
machine with other work, and a 20 ms watchdog would make these tests depend on the machine's load.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml

from akarm import load_robot
from akarm.cli import main
from akarm.motion.recording import Keyframe, Keyframes, PathRecording, load_keyframes, load_path
from akarm.sim import SimulatedRobot, faults
from akarm.telemetry.log import load as load_telemetry

from .conftest import ROBOTS, missing_socketcan_fix, wait_until

PLANAR2 = str(ROBOTS / "planar2.yaml")
SERVO3 = str(ROBOTS / "servo3.yaml")
HANGING = [-math.pi / 2, 0.0]


@pytest.fixture
def relaxed(tmp_path: Path) -> str:
    """planar2.yaml with a 0.25 s feedback watchdog (see the module docstring)."""
    doc = yaml.safe_load(Path(PLANAR2).read_text())
    doc["urdf"] = str(ROBOTS / doc["urdf"])
    doc["defaults"]["feedback_timeout"] = 0.25
    path = tmp_path / "planar2-relaxed.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


@contextmanager
def simulated(robot: str, channel: str, **kwargs) -> Iterator[SimulatedRobot]:
    cfg = load_robot(robot).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=True, **kwargs) as sim:
        yield sim


def bus(channel: str) -> list[str]:
    return ["-i", "virtual", "-c", channel]


def in_thread(argv: list[str]) -> tuple[threading.Thread, list[int]]:
    """Run ``main(argv)`` in a thread; the list gets its exit code."""
    result: list[int] = []
    th = threading.Thread(target=lambda: result.append(main(argv)), daemon=True)
    th.start()
    return th, result


def interrupt_when(cond: Callable[[], bool], after: float = 0.0) -> threading.Thread:
    """Send this process SIGINT (Ctrl-C) once ``cond()`` holds, ``after`` s later."""

    def run() -> None:  # after 10 s without ``cond``, at once: a test that fails must not hang
        if wait_until(cond, 10.0):
            time.sleep(after)
        os.kill(os.getpid(), signal.SIGINT)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th


def all_disabled(sim: SimulatedRobot) -> bool:
    """True once no simulated driver is enabled (the simulator takes in frames on its own threads)."""
    return wait_until(lambda: not any(d.enabled for d in sim.drivers), 2.0)


def frames_received(sim: SimulatedRobot) -> int:
    return sum(d.frames_received for d in sim.drivers)


# ------------------------------------------------------------------------------------------------
# help, bus errors
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("verb", [["status"], ["enable", "--seconds", "0"], ["zero", "--wait", "0", "elbow"],
                                  ["scan"], ["disable"], ["move", "home"]])
def test_a_missing_socketcan_device_says_how_to_bring_it_up(verb: list[str],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    argv = [verb[0], PLANAR2, "-i", "socketcan", "-c", "akarmnope0", *verb[1:]]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert f"akarm {verb[0]}: error: cannot open CAN bus" in err and missing_socketcan_fix("akarmnope0") in err
    assert len(err.strip().splitlines()) == 1


# ------------------------------------------------------------------------------------------------
# scan
# ------------------------------------------------------------------------------------------------
def test_scan_finds_the_mit_joints_of_planar2(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING) as sim:
        assert main(["scan", PLANAR2, *bus(channel), "--ids", "1-16", "--listen", "0.05", "--timeout", "0.3"]) == 0
        assert all_disabled(sim)
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[2:]]
    assert [(r[1], r[2], r[-1]) for r in rows] == [("1", "mit", "shoulder"), ("2", "mit", "elbow")]
    assert float(rows[0][4]) == pytest.approx(-math.pi / 2, abs=2e-3)


def test_scan_without_a_robot_file_finds_servo_ids(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(SERVO3, channel):
        assert main(["scan", *bus(channel), "--ids", "1-8"]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines()[2:]]
    assert [(r[1], r[2], r[3]) for r in rows] == [("1", "servo", "0x2901"), ("2", "servo", "0x2902"),
                                                  ("3", "servo", "0x2903")]
    assert "position (rad)" in out and "temperature (°C)" in out


def test_scan_reports_a_configured_joint_that_does_not_answer(channel: str,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING) as sim:
        sim.inject("elbow", faults.Unplugged())
        assert main(["scan", PLANAR2, *bus(channel), "--ids", "1-4", "--listen", "0", "--timeout", "0.3"]) == 1
    cap = capsys.readouterr()
    assert "shoulder" in cap.out and "not found: joint 'elbow' (mit, ID 2" in cap.err


def test_scan_needs_a_bus_and_says_when_nothing_answers(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scan"]) == 1
    assert "give the bus: -i INTERFACE -c CHANNEL" in capsys.readouterr().err
    assert main(["scan", *bus(channel), "--ids", "1-4", "--listen", "0.02", "--timeout", "0.02"]) == 1
    assert "error: no motor answered" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["scan", *bus(channel), "--ids", "1-300"])


# ------------------------------------------------------------------------------------------------
# status
# ------------------------------------------------------------------------------------------------
def test_status_table_has_every_joint_with_units(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING) as sim:
        sim.inject("elbow", faults.ErrorCode(2))
        assert main(["status", PLANAR2, *bus(channel)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    for unit in ("position (rad)", "velocity (rad/s)", "torque (N·m)", "temperature (°C)", "fault"):
        assert unit in lines[0]
    shoulder = next(line for line in lines if line.startswith("shoulder"))
    assert float(shoulder.split()[3]) == pytest.approx(-math.pi / 2, abs=2e-3)
    # the last column: the reading's age (s), fresh as the motors were just asked
    assert re.search(r" 0 no fault +0\.0\d\d$", shoulder), shoulder
    assert re.search(r" 2 over-current +0\.0\d\d$", next(line for line in lines if line.startswith("elbow")))
    assert "asked with EXIT, so now disabled: shoulder, elbow" in out


def test_status_json_parses_and_matches_the_simulator(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(SERVO3, channel, q0=[0.4, -0.3, 0.2]) as sim:
        assert main(["status", SERVO3, *bus(channel), "--json"]) == 0
        q = sim.q
    doc = json.loads(capsys.readouterr().out)
    joints = {j["name"]: j for j in doc["joints"]}
    assert list(joints) == ["pan", "shoulder", "elbow"]
    assert joints["pan"]["position"] == pytest.approx(0.4, abs=0.01)
    for name, qi in zip(joints, q, strict=True):
        j = joints[name]
        assert j["position"] == pytest.approx(qi, abs=0.03)
        assert j["missing"] is False and j["fault"] == 0 and j["fault_text"] == "no fault"
        assert isinstance(j["velocity"], float) and isinstance(j["temperature"], float)


def test_status_watch_repeats(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING):
        t0 = time.monotonic()
        assert main(["status", PLANAR2, *bus(channel), "--json", "--watch", "--interval", "0.1", "--count", "3"]) == 0
        assert time.monotonic() - t0 >= 0.2
    docs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(docs) == 3 and docs[0]["time"] < docs[1]["time"] < docs[2]["time"]


def test_status_lists_a_silent_joint_and_exits_1(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING) as sim:
        sim.inject("elbow", faults.Unplugged())
        assert main(["status", PLANAR2, *bus(channel), "--json"]) == 1
        cap = capsys.readouterr()
        elbow = json.loads(cap.out)["joints"][1]
        assert elbow["missing"] is True and elbow["position"] is None and elbow["fault"] is None
        assert "no answer from elbow" in cap.err
        assert main(["status", PLANAR2, *bus(channel)]) == 1
        assert "no answer" in next(line for line in capsys.readouterr().out.splitlines() if line.startswith("elbow"))


# ------------------------------------------------------------------------------------------------
# enable, disable, zero
# ------------------------------------------------------------------------------------------------
def test_enable_holds_for_its_seconds_then_disables(channel: str, relaxed: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=[-1.2, 0.3]) as sim:  # gravity pulls both links away from here
        th, result = in_thread(["enable", relaxed, *bus(channel), "--seconds", "1.5"])
        # enabled, damped until at rest (it was falling), then held: stiffness in the stored command
        assert wait_until(lambda: sim.joint("shoulder").stored_command.kp > 0, 5.0)
        held = sim.q
        time.sleep(0.5)
        assert np.allclose(sim.q, held, atol=0.01)               # held against gravity
        th.join(10.0)
        assert result == [0]
        assert all_disabled(sim)
    out = capsys.readouterr().out
    assert "enabled planar2: holding at [" in out and out.rstrip().endswith("disabled")


def test_enable_until_ctrl_c_disables_and_exits_0(channel: str, relaxed: str,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C is how `akarm enable` without --seconds is ended: a success."""
    with simulated(relaxed, channel, q0=HANGING) as sim:
        interrupt_when(lambda: sim.joint("shoulder").enabled, after=0.3)
        t0 = time.monotonic()
        assert main(["enable", relaxed, *bus(channel)]) == 0
        assert time.monotonic() - t0 < 5.0
        assert all_disabled(sim)
    captured = capsys.readouterr()
    assert captured.out.rstrip().endswith("disabled") and "interrupted" not in captured.err


def test_enable_ctrl_c_before_its_seconds_are_up_exits_130(channel: str, relaxed: str,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=HANGING) as sim:
        interrupt_when(lambda: sim.joint("shoulder").enabled, after=0.3)
        t0 = time.monotonic()
        assert main(["enable", relaxed, *bus(channel), "--seconds", "30"]) == 130
        assert time.monotonic() - t0 < 5.0
        assert all_disabled(sim)
    assert "interrupted: the arm is disabled" in capsys.readouterr().err


def test_disable_sends_exit_frames_to_every_joint(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    import can

    from akarm.protocol import mit

    with simulated(PLANAR2, channel, q0=HANGING) as sim, can.Bus(interface="virtual", channel=channel) as raw:
        for can_id in (1, 2):
            raw.send(can.Message(arbitration_id=can_id, data=mit.ENTER, is_extended_id=False))
        assert wait_until(lambda: all(d.enabled for d in sim.drivers), 1.0)
        assert main(["disable", PLANAR2, *bus(channel)]) == 0
        assert all_disabled(sim)
    rows = capsys.readouterr().out.splitlines()[2:]
    assert len(rows) == 2 and all("zero-gain command + EXIT" in r and "disabled" in r for r in rows)


def test_zero_a_mit_joint(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, q0=HANGING, zero_silence=0.3) as sim:
        assert main(["zero", PLANAR2, *bus(channel), "shoulder", "--wait", "0.35"]) == 0
        assert sim.joint("shoulder").zero == pytest.approx(-math.pi / 2, abs=2e-3)
        assert sim.joint("elbow").zero == 0.0
        capsys.readouterr()
        assert main(["status", PLANAR2, *bus(channel), "--json"]) == 0
        shoulder = json.loads(capsys.readouterr().out)["joints"][0]
        assert shoulder["position"] == pytest.approx(0.0, abs=2e-3)


def test_zero_a_servo_joint_permanently(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(SERVO3, channel, q0=[0.4, 0.0, 0.0]) as sim:
        assert main(["zero", SERVO3, *bus(channel), "pan", "--permanent"]) == 0
        assert sim.joint("pan").permanent_origin == pytest.approx(0.4, abs=0.01)
    out = capsys.readouterr().out
    assert "zeroed pan (permanent): motor reads" in out
    assert abs(float(out.split("motor reads ")[1].split()[0])) < 0.01


# ------------------------------------------------------------------------------------------------
# move
# ------------------------------------------------------------------------------------------------
def test_move_to_values_holds_there_then_disables_and_logs(channel: str, relaxed: str, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    target = np.array([-1.2, 0.4])
    log = tmp_path / "move.csv"
    with simulated(relaxed, channel, q0=HANGING) as sim:
        th, result = in_thread(["move", relaxed, *bus(channel), "-1.2,0.4", "--hold", "1.5", "--log", str(log)])
        assert wait_until(lambda: np.allclose(sim.q, target, atol=0.01), 5.0)
        time.sleep(0.3)
        assert np.allclose(sim.q, target, atol=0.01)               # holding at the target, against gravity
        th.join(10.0)
        assert result == [0]
        assert all_disabled(sim)
    out = capsys.readouterr().out
    assert "moving to -1.2,0.4 [-1.2000, +0.4000] rad" in out and "arrived:" in out
    telemetry = load_telemetry(log)
    assert telemetry.joint_names == ("shoulder", "elbow")
    assert np.abs(telemetry.q_des - target).min(axis=0).max() < 1e-6     # it commanded the target


def test_move_to_a_pose_name(channel: str, relaxed: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=HANGING) as sim:
        th, result = in_thread(["move", relaxed, *bus(channel), "down", "--speed", "0.8"])
        th.join(10.0)
        assert result == [0]
        assert all_disabled(sim)
    assert "moving to down [-1.5000, +0.0000] rad" in capsys.readouterr().out


def test_move_checks_the_target_before_enabling(channel: str, relaxed: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["move", relaxed, *bus(channel), "3.0,0"]) == 1
        assert "joint 'shoulder': target +3.0000 rad is outside [-1.8000, +1.8000] rad" in capsys.readouterr().err
        assert main(["move", relaxed, *bus(channel), "0.1"]) == 1
        assert "1 value(s) given, the arm has 2 joints" in capsys.readouterr().err
        assert main(["move", relaxed, *bus(channel), "nowhere"]) == 1
        assert "no pose named 'nowhere'" in capsys.readouterr().err
        assert frames_received(sim) == 0


# ------------------------------------------------------------------------------------------------
# teach
# ------------------------------------------------------------------------------------------------
def test_teach_keyframes_from_stdin(channel: str, relaxed: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "taught.yaml"
    monkeypatch.setattr("sys.stdin", io.StringIO("pick\n\nq\nignored\n"))
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["teach", relaxed, *bus(channel), str(out)]) == 0
        assert all_disabled(sim)
    kf = load_keyframes(out, ("shoulder", "elbow"))
    assert [f.name for f in kf.frames] == ["pick", None] and kf.robot == "planar2"
    for f in kf.frames:
        assert np.allclose(f.q, HANGING, atol=0.02)
    text = capsys.readouterr().out
    assert "stored keyframe 1 'pick': [" in text and "wrote 2 keyframes" in text


def test_teach_a_path_for_some_seconds(channel: str, relaxed: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "path.csv"
    r, w = os.pipe()                                   # stdin that stays open: --seconds ends it
    with os.fdopen(r) as stdin, os.fdopen(w, "w"):
        monkeypatch.setattr("sys.stdin", stdin)
        with simulated(relaxed, channel, q0=HANGING):
            assert main(["teach", relaxed, *bus(channel), str(out), "--sample-rate", "100", "--seconds", "0.5"]) == 0
    path = load_path(out, ("shoulder", "elbow"))
    # the loop stops sampling on its own at 0.5 s, however late the waiting thread wakes: 51
    # samples on the 100 Hz grid (exactly so in lock step, test_teach), fewer only if a stall of
    # the loop skipped grid points, none past 0.5 s but for a late last cycle
    assert 46 <= len(path.t) <= 51 and 0.48 <= path.duration <= 0.52
    assert np.all(np.diff(path.t) > 0)
    assert np.diff(path.t).mean() == pytest.approx(0.01, abs=1e-3)
    assert "wrote" in capsys.readouterr().out


# ------------------------------------------------------------------------------------------------
# replay
# ------------------------------------------------------------------------------------------------
def smooth_path(q0: list[float], q1: list[float], seconds: float, rate: float = 100.0) -> PathRecording:
    t = np.arange(0.0, seconds + 1e-9, 1.0 / rate)
    s = (1 - np.cos(np.pi * t / seconds)) / 2
    q = np.array(q0) + np.outer(s, np.array(q1) - np.array(q0))
    return PathRecording(("shoulder", "elbow"), t, q)


def test_replay_a_too_fast_path_says_why_and_nothing_moves(channel: str, relaxed: str, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = smooth_path(HANGING, [1.0, 0.0], 0.3).save(tmp_path / "fast.csv")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["replay", relaxed, *bus(channel), str(path)]) == 1
        assert frames_received(sim) == 0                         # not even enabled
    err = capsys.readouterr().err
    assert "joint 'shoulder'" in err and "at t = " in err and "--speed 0." in err


def test_replay_keyframes_outside_the_limits_before_enabling(channel: str, relaxed: str, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    kf = Keyframes(("shoulder", "elbow"), (Keyframe((-1.5, 0.0), "ok"), Keyframe((-1.5, 2.6), "bad")))
    path = kf.save(tmp_path / "bad.yaml")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["replay", relaxed, *bus(channel), str(path)]) == 1
        assert frames_received(sim) == 0
    assert "joint 'elbow': keyframe 1 'bad' is at +2.6000 rad" in capsys.readouterr().err


def test_replay_a_path_follows_it(channel: str, relaxed: str, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    end = [-1.2, 0.3]
    path = smooth_path(HANGING, end, 0.8).save(tmp_path / "slow.csv")
    log = tmp_path / "replay.npz"
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["replay", relaxed, *bus(channel), str(path), "--log", str(log)]) == 0
        assert all_disabled(sim)
    out = capsys.readouterr().out
    assert "replaying" in out and "done; RMS tracking error shoulder" in out
    telemetry = load_telemetry(log)
    reached = np.abs(telemetry.q - np.array(end)).max(axis=1) < 0.01
    assert reached.any()                                         # the arm got to the path's end


def test_replay_ctrl_c_stops_smoothly_and_exits_130(channel: str, relaxed: str, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    path = smooth_path(HANGING, [-0.6, 0.5], 3.0).save(tmp_path / "long.csv")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        interrupt_when(lambda: sim.q[0] > -1.5, after=0.2)        # once the path is under way
        log = tmp_path / "interrupted.npz"
        assert main(["replay", relaxed, *bus(channel), str(path), "--log", str(log)]) == 130
        assert all_disabled(sim)
    assert "interrupted: stopped and disabled" in capsys.readouterr().err
    q_des = load_telemetry(log).q_des[:, 0]
    assert q_des.max() > -1.5 and q_des.max() < -0.9  # under way, stopped well before the end (-0.6)


# ------------------------------------------------------------------------------------------------
# plot, bench
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("where", ["own", "in-process"])
def test_bench_prints_loop_statistics_and_cpu(where: str, capsys: pytest.CaptureFixture[str]) -> None:
    extra = ["--in-process"] if where == "in-process" else []
    assert main(["bench", PLANAR2, "--seconds", "1", "--loop-rate", "250", *extra]) == 0
    out = capsys.readouterr().out
    assert "bench: planar2, 2 joints at 250 Hz" in out
    assert ("in this process" if extra else "in its own process") in out
    cycles = int(out.split("cycles ")[1].split(",")[0])
    assert cycles > 100
    assert "feedforward" in out and "CPU: " in out and "% of one core" in out
    assert re.search(r"simulator \d+ %", out)


def _gripper_episode(tmp_path: Path) -> tuple[Path, Path]:
    """arm6g relaxed for a loaded machine (its gripper's watchdog too), and a dataset of one 2 s episode
    at 30 fps: the arm still at zero, the gripper asked open, then closed from 0.5 s to 1 s; with a
    camera (as `akarm teleop --record --camera` writes one), which replay leaves alone."""
    pytest.importorskip("av")
    from akarm.datasets import GRIPPER, DatasetWriter, EpisodeFrames

    from .conftest import relaxed_robot

    robot = relaxed_robot(ROBOTS / "arm6g.yaml", tmp_path)
    n = 60
    t = np.arange(n) / 30
    vec = np.hstack([np.zeros((n, 6)), np.interp(t, [0.0, 0.5, 1.0, 2.0], [0.08, 0.08, 0.0, 0.0])[:, None]])
    DatasetWriter(tmp_path / "data", (*load_robot(robot).joint_names, GRIPPER), 30,
                  cameras={"front": (32, 24)}).save_episode(
        "close on the part", EpisodeFrames(vec, 0 * vec, 0 * vec, vec), {"front": np.zeros((n, 24, 32, 3), np.uint8)})
    return robot, tmp_path / "data"


def test_replay_of_an_episode_with_a_gripper_column_drives_the_gripper(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from akarm.sim.process import SimulatorProcess

    from .test_serve import unique

    robot, data = _gripper_episode(tmp_path)
    channel = unique("replaygrip")
    seen: list[tuple[float, float]] = []
    with SimulatorProcess(robot, channel=channel, control=True) as sim:
        ctl = sim.control
        assert ctl is not None
        ctl.place_object(0.03)
        done = threading.Event()

        def watch() -> None:
            while not done.is_set():
                seen.append(ctl.gripper())  # (width, force)
                time.sleep(0.02)

        th = threading.Thread(target=watch, daemon=True)
        th.start()
        try:
            assert main(["replay", str(robot), "-i", "akarm_local", "-c", channel, str(data), "--episode", "0"]) == 0
        finally:
            done.set()
            th.join()
    width = np.array([s[0] for s in seen])
    force = np.array([s[1] for s in seen])
    opened = int(np.argmax(width > 0.079))
    assert width[opened] > 0.079, "the jaws first went to the episode's first width, open"
    held = force[opened:] > 10.0
    assert held.any(), "then closed on the part"
    assert np.all(np.abs(width[opened:][held] - 0.03) < 0.003) and force.max() <= 24.0


def test_replay_through_akarm_serve_drives_the_gripper_over_the_socket(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    import subprocess
    import sys

    import akarm
    from akarm.sim.process import SimulatorProcess

    from .test_serve import unique

    robot, data = _gripper_episode(tmp_path)
    channel = unique("replaygrip")
    with SimulatorProcess(robot, channel=channel, control=True, args=["--object", "0.03"]) as sim, \
            akarm.Arm(load_robot(robot).with_bus(interface="akarm_local", channel=channel)) as arm, \
            akarm.ArmServer(arm, ros=False, log=lambda text: None):
        assert sim.control is not None
        run = subprocess.run([sys.executable, "-m", "akarm", "replay", str(robot), "-i", "akarm_local", "-c", channel,
                              str(data), "--episode", "0"], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
        assert "held by akarm serve" in run.stdout, run.stdout
        assert arm.gripper is not None
        s = arm.gripper.state()
        assert s.grasped and abs(s.width - 0.03) < 0.002 and s.target == pytest.approx(0.0, abs=1e-6)
        width, force = sim.control.gripper()
        assert 16.0 <= force <= 24.0 and abs(width - 0.03) < 0.002
