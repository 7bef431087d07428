"""`akarm init` then a simulated move, in lock step, for each URDF of the corpus (the file it writes:
tests/unit/test_init.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.cli import main
from akarm.robotfile.load import load_robot
from akarm.sim import SimulatedRobot

from ..unit.test_init import TRIED, init


@pytest.mark.parametrize("stem", TRIED)
def test_init_then_check_then_a_simulated_move(stem: str, tmp_path: Path, channel: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    out, text = init(tmp_path, stem)
    assert f"wrote {out}" in capsys.readouterr().out
    # akarm check passes, without warnings: the suggested motors hold the arm within their rated torque
    assert main(["check", str(out)]) == 0
    report = capsys.readouterr().out
    assert report.rstrip().endswith("OK") and "warning" not in report
    # and the arm moves in the simulator at once: to `rest` and back to `zero`, settling within 5 mrad
    config = load_robot(out).with_bus(interface="virtual", channel=channel)
    assert config.warnings == ()
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        for pose in ("rest", "zero"):
            target = np.array(config.pose(pose))
            arm.move_to(pose)
            arm.sleep(0.5)
            err = np.abs(arm.state().q - target)
            assert err.max() < 5e-3, (pose, err)
        assert np.abs(np.array(config.pose("rest")) - config.pose("zero")).max() > 0.29  # a real move
