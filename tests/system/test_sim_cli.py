"""The simulator in real time: in-process threads, and ``akarm sim`` as a command and as a process."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time

import can
import pytest

from akarm.cli import main
from akarm.errors import BusError, StateError
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, ROOT, has_vcan, missing_socketcan_fix

PLANAR2 = str(ROBOTS / "planar2.yaml")


def send(bus: can.BusABC, arbitration_id: int, data: bytes) -> None:
    bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))


def test_realtime_answers_at_once_and_follows_the_wall_clock(channel: str) -> None:
    config = load_robot(ROBOTS / "biarm.yaml")
    sim = SimulatedRobot(config, "virtual", channel)
    start = time.perf_counter()
    with sim, can.Bus(interface="virtual", channel=f"{channel}-left") as left, \
            can.Bus(interface="virtual", channel=f"{channel}-right") as right:
        time.sleep(0.3)
        assert 0.1 < sim.t < 0.3 + 0.1                      # (it may lag on a loaded machine, never lead)
        for bus in (left, right):
            t0 = time.perf_counter()
            send(bus, 2, mit.ENTER)
            reply = bus.recv(timeout=2.0)
            assert reply is not None and reply.data[0] == 2
            assert time.perf_counter() - t0 < 0.5          # typically well under 1 ms
        with pytest.raises(StateError):
            sim.advance_to(5.0)                             # lock step only
        assert sim.thread_error is None
        assert sim.t <= time.perf_counter() - start + 0.01
    assert sim.joint("left_elbow").enabled and sim.joint("right_elbow").enabled


def test_cli_runs_for_its_duration_with_faults_and_status_lines(channel: str,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    result: list[int] = []
    argv = ["sim", PLANAR2, "-i", "virtual", "-c", channel, "--seconds", "1.5", "--fault", "elbow:error:3",
            "--pose", "down"]
    runner = threading.Thread(target=lambda: result.append(main(argv)))
    with can.Bus(interface="virtual", channel=channel) as bus:
        runner.start()
        replies = {}
        for motor_id in (1, 2):
            # ENTER until the driver answers: frames sent before the simulator has opened its bus
            # (it builds the model first) are lost, as on a real bus with the power off
            deadline = time.monotonic() + 10.0
            while motor_id not in replies and time.monotonic() < deadline:
                send(bus, motor_id, mit.ENTER)
                msg = bus.recv(timeout=0.1)
                while msg is not None and motor_id not in replies:
                    replies.setdefault(msg.data[0], msg)
                    msg = bus.recv(timeout=0.0)
            assert motor_id in replies, f"motor {motor_id} never answered"
        runner.join(timeout=10.0)
    assert result == [0]
    assert replies[2].data[7] == 3 and replies[1].data[7] == 0
    model = load_robot(PLANAR2).joints[0].motor
    assert mit.decode_reply(model, replies[1].data).position == pytest.approx(-1.5, abs=0.05)  # --pose down
    out = capsys.readouterr().out
    assert "bus arm: virtual" in out and "fault on elbow: ErrorCode(code=3)" in out
    lines = out.splitlines()
    status = [k for k, line in enumerate(lines) if line.startswith("t=")]
    assert len(status) == 1                                 # not a terminal: one status a second
    # two joints' status does not fit 80 columns: a line for the time, then one per joint
    block = lines[status[0]:status[0] + 3]
    assert block[1].startswith("  shoulder ") and block[2].startswith("  elbow ")
    assert all(len(line) < 80 for line in block)
    assert "rad" in block[1] and "Nm" in block[1] and "C " in block[1] and "E3" in block[2]
    stopped = re.search(r"akarm sim: stopped at t = ([0-9.]+)", out)
    assert stopped and float(stopped.group(1)) == pytest.approx(1.5, abs=0.1)  # simulated time may lag


def test_cli_missing_socketcan_bus_says_how_to_create_it(capsys: pytest.CaptureFixture[str]) -> None:
    if has_vcan("vcan9"):
        pytest.skip("vcan9 exists here")
    assert main(["sim", PLANAR2, "-i", "socketcan", "-c", "vcan9", "--seconds", "0.1"]) == 1
    err = capsys.readouterr().err
    assert "vcan9" in err and missing_socketcan_fix("vcan9") in err
    assert "Traceback" not in err


def test_missing_socketcan_bus_is_a_bus_error_in_python_too() -> None:
    if has_vcan("vcan9"):
        pytest.skip("vcan9 exists here")
    sim = SimulatedRobot(load_robot(PLANAR2), "socketcan", "vcan9", realtime=False)
    with pytest.raises(BusError) as info:
        sim.start()
    assert missing_socketcan_fix("vcan9") in str(info.value)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_cli_process_stops_cleanly_on_a_signal(sig: signal.Signals) -> None:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    argv = [sys.executable, "-m", "akarm", "sim", PLANAR2, "-i", "virtual", "-c", f"sig-{os.getpid()}"]
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 30.0
        lines = []
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if line.startswith("running") or not line:
                break
        assert lines[-1].startswith("running"), lines
        time.sleep(0.3)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "akarm sim: stopped at" in out
    assert "Traceback" not in err


def test_realtime_priority_is_asked_for_before_the_threads_start_and_said() -> None:
    """``akarm sim --realtime-priority``: SCHED_FIFO for the simulator's threads (they inherit it from the
    thread that starts them), granted or refused with the reason, never a failure."""
    argv = [sys.executable, "-m", "akarm", "sim", PLANAR2, "-i", "virtual", "-c", f"rt-{os.getpid()}", "--seconds",
            "0.5", "--realtime-priority", "-q"]
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    line = next(x for x in out.stdout.splitlines() if x.strip().startswith("real time:"))
    assert "SCHED_FIFO priority 80 granted" in line or "real-time priority refused" in line, line
    assert "switch interval 200 µs" in line or "SCHED_FIFO" in line, line
