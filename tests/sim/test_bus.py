"""Buses opened in this process as python-can users configure them: keyword arguments reach python-can,
and a bus with nothing on it says why (the configuration alone: tests/unit/test_bus.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from akarm.buses.bus import open_bus
from akarm.cli import main
from akarm.robotfile.load import load_robot

from ..unit.test_bus import robot
from .conftest import ROBOTS


def test_yaml_bus_keys_beyond_interface_channel_bitrate_are_passed_to_python_can(tmp_path: Path,
                                                                                 channel: str) -> None:
    config = load_robot(robot(tmp_path, f"buses:\n  arm: {{interface: virtual, channel: {channel}, "
                                        "preserve_timestamps: true, rx_queue_size: 64}\n"))
    bus = config.buses["arm"]
    assert bus.options == {"preserve_timestamps": True, "rx_queue_size": 64}
    opened = open_bus(bus)
    try:  # python-can's virtual bus took them
        assert opened.preserve_timestamps is True and opened.queue.maxsize == 64
    finally:
        opened.shutdown()


def test_scan_without_a_robot_file_uses_python_can_configuration(monkeypatch: pytest.MonkeyPatch, channel: str,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scan"]) == 1
    assert "give the bus: -i INTERFACE -c CHANNEL (or configure python-can" in capsys.readouterr().err
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", channel)
    assert main(["scan", "--ids", "1-2", "--listen", "0", "--timeout", "0.01"]) == 1
    err = capsys.readouterr().err
    assert "no motor answered" in err and f"virtual channel {channel!r}" in err


def test_status_names_the_cause_when_nothing_answers(tmp_path: Path, channel: str,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["status", str(ROBOTS / "planar2.yaml"), "-i", "akarm_local", "-c", channel, "--timeout",
                 "0.05"]) == 1
    err = capsys.readouterr().err
    assert "no answer from shoulder, elbow" in err and "no simulator or motor is on akarm_local channel" in err
