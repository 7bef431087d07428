"""``akarm sim`` as its own process on SocketCAN vcan0, talked to through python-can's socketcan interface.

Run inside ``../shared/tools/vcan-vm`` (CI's vcan stage); skipped where there is no vcan0. The VM is
5-20x slower than a real machine: bounds are generous and the plant runs at 500 Hz.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

import can
import pytest

from akarm.protocol import mit, servo
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS, ROOT, has_vcan

if TYPE_CHECKING:
    from akarm.protocol.motors import MotorModel

pytestmark = [pytest.mark.vcan, pytest.mark.skipif(not has_vcan(), reason="no vcan0 on this machine")]


def launch(robot: str) -> subprocess.Popen[str]:
    """Start ``akarm sim ROBOT -i socketcan -c vcan0`` (without waiting for it)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    argv = [sys.executable, "-m", "akarm", "sim", str(ROBOTS / robot), "-i", "socketcan", "-c", "vcan0",
            "--seconds", "600", "--plant-rate", "500", "--quiet"]
    return subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def wait_running(proc: subprocess.Popen[str]) -> None:
    """Wait until the simulator says it is running (a minute or more in the emulated VM)."""
    assert proc.stdout is not None
    seen = []
    deadline = time.monotonic() + 300.0
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        seen.append(line)
        if line.startswith("running"):
            return
    proc.kill()
    raise AssertionError(f"akarm sim did not start: {''.join(seen)}{proc.stderr.read() if proc.stderr else ''}")


def stop_sim(proc: subprocess.Popen[str]) -> str:
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120.0)
    assert proc.returncode == 0, err
    return out


@pytest.fixture(scope="module")
def sims() -> Iterator[dict[str, subprocess.Popen[str]]]:
    """Both simulators, started together (their start-up, mostly imports, dominates in the VM).

    They share vcan0 without clashing: planar2's MIT drivers use standard IDs 1-2 (replies on 0),
    servo3's servo drivers extended IDs (commands (packet << 8) | 1-3, status 0x2901-0x2903).
    """
    procs = {"planar2": launch("planar2.yaml"), "servo3": launch("servo3.yaml")}
    try:
        yield procs
    finally:
        outs = {name: stop_sim(p) for name, p in procs.items() if p.poll() is None}
        for out in outs.values():
            assert "stopped at" in out


def open_vcan0(arbitration_id: int, extended: bool) -> can.BusABC:
    """A socketcan bus on vcan0 that receives only frames with this ID (filtered in the kernel)."""
    mask = 0x1FFFFFFF if extended else 0x7FF
    return can.Bus(interface="socketcan", channel="vcan0",
                   can_filters=[{"can_id": arbitration_id, "can_mask": mask, "extended": extended}])


def test_mit_enter_command_and_replies_over_vcan0(sims: dict[str, subprocess.Popen[str]]) -> None:
    config = load_robot(ROBOTS / "planar2.yaml")
    model = config.joints[0].motor
    wait_running(sims["planar2"])
    with open_vcan0(0, extended=False) as bus:              # MIT replies come on ID 0
        mit_exchange(bus, model)


def mit_exchange(bus: can.BusABC, model: MotorModel) -> None:
    def exchange(data: bytes) -> mit.MitReply:
        bus.send(can.Message(arbitration_id=1, data=data, is_extended_id=False))
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            msg = bus.recv(timeout=1.0)
            if msg is not None and not msg.is_extended_id and msg.data[0] == 1:
                assert msg.arbitration_id == 0                  # the firmware's master ID
                return mit.decode_reply(model, msg.data)
        raise AssertionError("no reply from the simulated shoulder on vcan0")

    first = exchange(mit.ENTER)
    assert first.error == 0 and first.temperature == 25.0
    assert first.torque == pytest.approx(0.0, abs=0.01)         # stored command is zero: limp
    hold = exchange(mit.encode_command(model, 0.0, 0.0, 30.0, 1.0, 0.0))
    # the command is applied: kp·(0 - p) + kd·(0 - v) (the arm had fallen), within the AK80-9's ±18 N·m
    assert hold.torque == pytest.approx(max(-18.0, min(18.0, -30.0 * hold.position - 1.0 * hold.velocity)), abs=0.5)
    assert hold.torque > 5.0
    # held near 0 against gravity (2.2 N·m / 30); the simulator may run slower than the wall clock
    # in the emulated VM, so ask (ENTER only reads the state) until it has settled, for up to 20 s
    deadline = time.monotonic() + 20.0
    settled = exchange(mit.ENTER)
    while abs(settled.position) >= 0.15 and time.monotonic() < deadline:
        time.sleep(0.2)
        settled = exchange(mit.ENTER)
    assert abs(settled.position) < 0.15, settled


def test_servo_status_frames_over_vcan0_at_about_their_rate(sims: dict[str, subprocess.Popen[str]]) -> None:
    wait_running(sims["servo3"])
    with open_vcan0(0x2901, extended=True) as bus:          # pan's status frames
        servo_exchange(bus)


def servo_exchange(bus: can.BusABC) -> None:
    # count pan's status frames (200 Hz configured) over 2 s of wall time
    start = time.monotonic()
    stamps = []
    while time.monotonic() - start < 2.0:
        msg = bus.recv(timeout=0.5)
        if msg is not None and msg.is_extended_id and msg.arbitration_id == 0x2901:
            stamps.append(msg.timestamp)
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    # 200 Hz on a real machine; the simulator slips (runs slower than the wall clock) when the machine
    # cannot keep up, as the emulated VM sometimes cannot: the bound is wide on the slow side
    assert 20.0 < rate < 230.0, rate
    aid, data = servo.encode_position_speed(1, 20.0, 3000.0, 20000.0)
    bus.send(can.Message(arbitration_id=aid, data=data, is_extended_id=True))
    deadline = time.monotonic() + 20.0
    position = 0.0
    while time.monotonic() < deadline:
        msg = bus.recv(timeout=0.5)
        if msg is not None and msg.arbitration_id == 0x2901:
            position = servo.decode_status(msg.arbitration_id, msg.data).position_deg
            if abs(position - 20.0) < 0.5:
                break
    assert position == pytest.approx(20.0, abs=0.5)             # it moved there
