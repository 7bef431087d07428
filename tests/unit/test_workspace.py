"""Walls (the robot file's ``workspace:``) read from the file: boxes, planes, a margin; bad ones refused
at their lines (the arm against them: tests/system/test_walls_lockstep.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

import akarm
from akarm.errors import ConfigError

from ..conftest import ROBOTS


def write_robot(tmp_path: Path, workspace_yaml: str) -> Path:
    text = (ROBOTS / "arm6.yaml").read_text().replace("urdf: arm6.urdf", f"urdf: {ROBOTS / 'arm6.urdf'}")
    path = tmp_path / "arm6.yaml"
    path.write_text(text + "\n" + workspace_yaml)
    return path


def test_the_robot_file_gives_boxes_and_planes(tmp_path: Path) -> None:
    config = akarm.load_robot(write_robot(tmp_path, """workspace:
  min: [-0.5, -0.5, 0.0]
  max: [0.5, 0.5, 0.8]
  boxes: [{min: [0.5, -0.1, 0.0], max: [0.9, 0.1, 0.3]}]
  planes: [{normal: [0, 0, -2], offset: -0.1}]
  margin: 0.01
"""))
    w = config.workspace
    assert w is not None and len(w.boxes) == 2 and w.margin == 0.01
    assert w.planes[0].normal == (0.0, 0.0, -1.0) and w.planes[0].offset == pytest.approx(-0.05)
    assert w.outside([0.0, 0.0, 0.4]) == 0.0
    assert w.outside([0.7, 0.0, 0.2]) == 0.0  # in the second box
    assert w.outside([0.0, 0.0, 0.9]) == pytest.approx(0.1)
    assert w.outside([0.0, 0.0, 0.02]) == pytest.approx(0.03)  # below the plane z >= 0.05
    assert akarm.load_robot(ROBOTS / "arm6.yaml").workspace is None


@pytest.mark.parametrize(("text", "says"), [
    ("workspace:\n  min: [0, 0, 0]\n", "one of min and max"),
    ("workspace:\n  min: [0, 0, 1]\n  max: [1, 1, 0]\n", "is not below max"),
    ("workspace:\n  planes: [{normal: [0, 0, 0], offset: 1}]\n", "not all zero"),
    ("workspace:\n  boxes: [{min: [0, 0, 0]}]\n", "boxes[0] must be"),
    ("workspace:\n  margin: 0.01\n", "no box and no plane"),
    ("workspace:\n  min: [0, 0]\n  max: [1, 1, 1]\n", "must have 3 numbers"),
])
def test_a_bad_workspace_is_refused_at_its_line(tmp_path: Path, text: str, says: str) -> None:
    with pytest.raises(ConfigError, match=says.replace("[", r"\[").replace("]", r"\]")) as info:
        akarm.load_robot(write_robot(tmp_path, text))
    assert all(p.line is not None for p in info.value.problems)
