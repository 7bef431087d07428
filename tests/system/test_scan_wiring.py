"""``akarm scan`` names wiring mistakes and exits 1 (issue 26): two motors on one CAN ID, a motor in
the other mode than its joint's. Scan listens in real time, so these run against a real-time simulator."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import pytest

from akarm.cli import main
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS

PLANAR2 = str(ROBOTS / "planar2.yaml")
SERVO3 = str(ROBOTS / "servo3.yaml")


@contextmanager
def simulated(robot: str, channel: str, joint: str | None = None, **changes: object) -> Iterator[SimulatedRobot]:
    cfg = load_robot(robot).with_bus(interface="virtual", channel=channel)
    if joint is not None:
        cfg = replace(cfg, joints=tuple(replace(j, **changes) if j.name == joint else j  # type: ignore[arg-type]
                                        for j in cfg.joints))
    with SimulatedRobot(cfg, realtime=True) as sim:
        yield sim


def scan(robot: str, channel: str) -> int:
    return main(["scan", robot, "-i", "virtual", "-c", channel, "--ids", "1-4", "--listen", "0.1", "--timeout", "0.3"])


def test_scan_names_two_mit_motors_on_one_id_and_exits_1(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel) as sim:
        sim.inject("elbow", faults.Twin(0.7))
        assert scan(PLANAR2, channel) == 1
    cap = capsys.readouterr()
    assert "two motors answer on CAN ID 2" in cap.err and "TWO MOTORS" in cap.out
    assert "CAN ID 1" not in cap.err


def test_scan_names_two_servo_motors_on_one_id(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(SERVO3, channel) as sim:
        sim.inject("pan", faults.Twin(0.7))
        assert scan(SERVO3, channel) == 1
    can_id = load_robot(SERVO3).joint("pan").can_id
    assert f"two motors answer on CAN ID {can_id}" in capsys.readouterr().err


def test_scan_names_a_motor_in_the_other_mode_and_exits_1(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(PLANAR2, channel, "elbow", mode="servo", status_rate_hz=100.0):
        assert scan(PLANAR2, channel) == 1
    err = capsys.readouterr().err
    assert "joint 'elbow' is configured as mit, but the motor on CAN ID 2" in err and "servo mode" in err
