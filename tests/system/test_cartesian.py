"""`akarm move --xyz` against the real-time simulator: a straight line to the point, and an unreachable
point refused before anything moves."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import akarm
from akarm.cli import main
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, relaxed_robot, wait_until
from .test_cartesian_lockstep import PLANAR2, sim_pose

BENT = [-0.5, 1.2]  # planar2, elbow bent (stretched out straight, it is at a singularity)


@pytest.fixture
def relaxed_planar2(tmp_path: Path) -> str:
    """planar2.yaml lying flat (gravity along its joint axes: a limp arm stays where it is), its
    supervisor relaxed (the real-time simulator shares this process)."""
    path = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["gravity"] = [0.0, -9.81, 0.0]
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def _cli_move(robot: str, channel: str, q0, argv: list[str]) -> tuple[int, np.ndarray]:
    cfg = akarm.load_robot(robot).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=True, q0=q0) as sim:
        result: list[int] = []
        th = threading.Thread(target=lambda: result.append(main(["move", robot, "-i", "virtual", "-c", channel,
                                                                  *argv])), daemon=True)
        th.start()
        th.join(20.0)
        assert result, "akarm move did not end"
        assert wait_until(lambda: not any(d.enabled for d in sim.drivers), 2.0)
        time.sleep(0.05)
        return result[0], sim_pose(sim)


def test_cli_move_xyz_linear_reaches_the_point(relaxed_planar2: str, channel: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    code, _ = _cli_move(relaxed_planar2, channel, BENT, ["--xyz", "0.40", "0", "0.30", "--linear"])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    assert "in a straight line" in out and "disabled" in out
    mm = float(out.split("arrived: tool at")[1].split(" m, ")[1].split(" mm")[0])
    assert mm < 2.0


def test_cli_move_refuses_an_unreachable_point_before_moving(relaxed_planar2: str, channel: str,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    code, pose = _cli_move(relaxed_planar2, channel, BENT, ["--xyz", "0.9", "0", "0.3"])
    err = capsys.readouterr().err
    assert code == 1 and "out of reach" in err
    bent = akarm.dynamics.model.RobotModel(PLANAR2).tool_pose(BENT)
    assert np.linalg.norm(pose[:3, 3] - bent[:3, 3]) < 2e-3
