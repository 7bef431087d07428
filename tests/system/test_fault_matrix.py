"""Faults that need real time or other processes: an Arm collected or stalled in its own loop thread,
signals to scripts and CLI verbs (akarm_local), and nothing on the channel (the lock-step matrix:
tests/sim/test_fault_matrix.py)."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

import akarm
from akarm import (
    FeedbackTimeout,
)
from akarm.config import RobotConfig
from akarm.control.exits import UnsafeExitWarning
from akarm.control.modes import Mode
from akarm.motion.recording import load as load_recording
from akarm.sim import SimulatedRobot
from akarm.sim.process import SimulatorProcess
from akarm.telemetry.log import load as load_telemetry

from ..sim.wire import Wire, damping_then_exit
from .conftest import ROBOTS, wait_until


def test_an_arm_collected_in_its_own_loop_thread_is_still_damped_and_disabled(channel: str) -> None:
    """Python's cycle collector runs in whichever thread allocates, often the loop's own: the loop
    cannot wait for its own cycles there. The arm must still be damped and disabled (it was closed with
    the motors enabled: the wait timed out, the buses closed without an EXIT)."""
    cfg = akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, q0=[0.0, 0.0]) as sim, Wire(cfg, background=True) as wire:  # real time
        arm = akarm.Arm(cfg, feedback_timeout=0.25)
        arm.open()
        arm.enable()
        loop = arm.observe.loop
        cycle, collected = loop.cycle, []
        dropped = [arm]
        dropped.append(dropped)  # a reference cycle: only the cycle collector can free the Arm
        del arm

        def collected_here(now, *rest):  # the collector runs inside a cycle, in the loop's own thread
            if not collected:
                collected.append(now)
                gc.collect()
            return cycle(now, *rest)

        def closed() -> bool:
            return not loop.running and not any(t.name == "akarm-close" for t in threading.enumerate())

        gc.disable()  # no collection in this thread meanwhile
        try:
            del dropped
            with pytest.warns(UnsafeExitWarning, match="garbage-collected while enabled"):
                loop.cycle = collected_here
                assert wait_until(closed, 10.0)
        finally:
            gc.enable()
        assert collected and not any(d.enabled for d in sim.drivers)
        assert wait_until(lambda: all(wire.sent_to(j) and wire.sent_to(j)[-1].kind == "exit" for j in cfg.joints), 5)
        damping_then_exit(wire, cfg, damping_time=0.25)  # with its damping, not only the exit


def test_a_loop_that_stopped_running_cannot_keep_close_from_exiting_motor_mode(channel: str) -> None:
    """A loop that no longer runs its cycles (stalled, dead) cannot run the stop sequence: close() gives
    up waiting for it and sends the exit frames itself."""
    cfg = akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, q0=[0.0, 0.0]) as sim, Wire(cfg, background=True) as wire:
        arm = akarm.Arm(cfg, feedback_timeout=0.25, stop_damping_time=0.05)
        arm.open()
        arm.enable()
        stall = threading.Event()
        loop = arm.observe.loop
        cycle = loop.cycle
        loop.cycle = lambda *a: stall.wait(30) or cycle(*a)
        arm.close()
        stall.set()
        assert arm.mode is Mode.CLOSED
        assert wait_until(lambda: not any(d.enabled for d in sim.drivers), 2.0)
        assert all(wire.sent_to(j)[-1].kind == "exit" for j in cfg.joints)


@pytest.fixture
def local_robot(tmp_path: Path) -> Path:
    """planar2 with a 0.25 s feedback watchdog: real processes on a machine that may be busy."""
    doc = yaml.safe_load((ROBOTS / "planar2.yaml").read_text())
    doc["urdf"] = str(ROBOTS / doc["urdf"])
    doc["defaults"]["feedback_timeout"] = 0.25
    path = tmp_path / "planar2.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@contextmanager
def on_akarm_local(robot: Path, channel: str) -> Iterator[tuple[RobotConfig, Wire]]:
    with SimulatorProcess(robot, channel=channel, pose="down"):
        cfg = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
        with Wire(cfg, background=True) as wire:
            yield cfg, wire


def _exit_seen(wire: Wire, cfg) -> bool:
    return all(s and s[-1].kind == "exit" for s in (wire.sent_to(j) for j in cfg.joints))


def _start(argv: list[str], **kwargs) -> subprocess.Popen[str]:
    """``akarm argv`` in a process of its own, with SIGHUP's default action: a child inherits an ignored
    SIGHUP (tests run under ``nohup``), and akarm rightly leaves an ignored signal ignored."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    hup = getattr(signal, "SIGHUP", None)
    before = signal.signal(hup, signal.SIG_DFL) if hup is not None else None
    try:
        return subprocess.Popen([sys.executable, "-m", "akarm", *argv], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=env, **kwargs)
    finally:
        if hup is not None:
            signal.signal(hup, before)


def _wait_for_line(stream, word: str, timeout: float = 60.0) -> str:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        line = stream.readline()
        if word in line:
            return line
        if not line:
            break
    raise AssertionError(f"{word!r} never appeared")


SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT]


def _interrupt(proc: subprocess.Popen[str], ready: str, sig: int, wire: Wire, cfg: RobotConfig,
               after: float) -> tuple[str, str, float]:
    """Once ``ready`` is printed (stdout, or stderr when stdout is not the verb's), wait ``after`` s,
    send ``sig``, wait for the process and for EXIT to every joint. Returns (stdout, stderr, s from
    the signal to the last EXIT)."""
    _wait_for_line(proc.stdout if ready != "recording at" else proc.stderr, ready)
    time.sleep(after)
    t = time.time()
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=30)
    assert wait_until(lambda: _exit_seen(wire, cfg), 5.0)
    return out, err, max(s.t for j in cfg.joints for s in wire.sent_to(j) if s.kind == "exit") - t


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_signal_during_a_move_damps_exits_and_ends_with_its_status(sig: int, local_robot: Path, channel: str,
                                                                      tmp_path: Path) -> None:
    log = tmp_path / "move.npz"
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        proc = _start(["move", str(local_robot), "up", "-i", "akarm_local", "-c", channel, "--speed", "0.3",
                       "--log", str(log)])
        _, err, to_exit = _interrupt(proc, "moving to", sig, wire, cfg, after=0.3)
    assert proc.returncode == 128 + sig, err
    assert "interrupted" in err and "Traceback" not in err
    assert to_exit < 2.0                           # the stop: jerk-limited brake, 0.3 s damping, exit
    damping_then_exit(wire, cfg)
    assert load_telemetry(log).t.size > 100  # the log is whole
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_signal_while_teaching_keeps_the_recording_damps_and_exits(sig: int, local_robot: Path, channel: str,
                                                                      tmp_path: Path) -> None:
    out = tmp_path / "path.csv"
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        proc = _start(["teach", str(local_robot), str(out), "-i", "akarm_local", "-c", channel],
                      stdin=subprocess.PIPE)
        stdout, err, to_exit = _interrupt(proc, "recording at", sig, wire, cfg, after=0.5)
    assert proc.returncode == 128 + sig, err
    assert "wrote" in stdout and "Traceback" not in err
    assert to_exit < 2.0
    damping_then_exit(wire, cfg)
    rec = load_recording(out, cfg.joint_names)
    assert rec.duration > 0.3                      # what was recorded, whole
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=lambda s: signal.Signals(s).name)
def test_a_signal_to_enable_damps_and_exits(sig: int, local_robot: Path, channel: str) -> None:
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        proc = _start(["enable", str(local_robot), "-i", "akarm_local", "-c", channel])
        _, err, to_exit = _interrupt(proc, "enabled planar2", sig, wire, cfg, after=0.2)
    assert proc.returncode in (0, 128 + sig), err  # 0 once Ctrl-C (and its kin) is enable's documented end
    assert "Traceback" not in err and to_exit < 2.0
    damping_then_exit(wire, cfg)


def test_teach_into_a_directory_is_refused_before_anything_is_enabled(local_robot: Path, channel: str,
                                                                      tmp_path: Path) -> None:
    out = tmp_path / "path.csv"
    out.mkdir()
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        r = subprocess.run([sys.executable, "-m", "akarm", "teach", str(local_robot), str(out), "-i",
                            "akarm_local", "-c", channel], capture_output=True, text=True, timeout=60, input="")
        time.sleep(0.1)
        assert all(wire.sent_to(j) == [] for j in cfg.joints)
    assert r.returncode == 1 and "is a directory" in r.stderr and "Traceback" not in r.stderr


def test_a_script_that_ends_without_disabling_leaves_the_arm_damped_and_disabled(local_robot: Path, channel: str,
                                                                                  tmp_path: Path) -> None:
    script = tmp_path / "forgetful.py"
    script.write_text(
        "import akarm\n"
        f"cfg = akarm.load_robot({str(local_robot)!r}).with_bus(interface='akarm_local', channel={channel!r})\n"
        "arm = akarm.Arm(cfg)\n"
        "arm.open()\n"
        "arm.enable()\n"
        "print('enabled', flush=True)\n")
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
        assert wait_until(lambda: _exit_seen(wire, cfg), 5.0)
    assert r.returncode == 0 and "enabled" in r.stdout, r.stderr
    assert "UnsafeExitWarning" in r.stderr and "still enabled when the program ended" in r.stderr
    damping_then_exit(wire, cfg)


def test_sigterm_to_a_script_unwinds_its_with_block(local_robot: Path, channel: str, tmp_path: Path) -> None:
    script = tmp_path / "holder.py"
    script.write_text(
        "import akarm\n"
        f"cfg = akarm.load_robot({str(local_robot)!r}).with_bus(interface='akarm_local', channel={channel!r})\n"
        "with akarm.Arm(cfg) as arm:\n"
        "    arm.enable()\n"
        "    print('enabled', flush=True)\n"
        "    while True:\n"
        "        arm.sleep(1.0)\n")
    with on_akarm_local(local_robot, channel) as (cfg, wire):
        proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        _, err, to_exit = _interrupt(proc, "enabled", signal.SIGTERM, wire, cfg, after=0.0)
    assert to_exit < 2.0
    assert proc.returncode == 1 and "Terminated: terminated by SIGTERM" in err  # Python's KeyboardInterrupt exit
    damping_then_exit(wire, cfg)


def test_enable_with_nothing_on_the_channel_says_no_simulator_is_there(channel: str) -> None:
    cfg = akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface="akarm_local", channel=channel)
    with akarm.Arm(cfg) as arm:
        with pytest.raises(FeedbackTimeout, match="no answer within 500 ms") as info:
            arm.enable()
        assert arm.mode is Mode.DISABLED
    assert "no simulator or motor is on akarm_local channel" in info.value.fix


def test_the_lock_step_matrix_passes_under_the_slow_profile() -> None:
    """Issue 39: the fault matrix passes under both profiles. The README suite runs it under normal
    (and its frozen-encoder, blocked-joint and driver-reset rows under both); the whole of it under slow
    (25 Hz, 1 s watchdog and lag: each row's bound is stated per profile) costs about 15 s more, so here."""
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "AKARM_TEST_TIMING": "slow"}
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
                        str(root / "tests" / "sim" / "test_fault_matrix.py")],
                       cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert " failed" not in r.stdout and " passed" in r.stdout, r.stdout[-2000:]
    assert "xfail" not in r.stdout and "skipped" not in r.stdout, r.stdout[-2000:]  # every row, as strict as normal
