"""The pytest plugin (akarm.testing.plugin) as a user's project meets it: a folder of its own with its own robot
file and the example test of docs/testing.md, run by pytest in a process of its own, on each transport.

The SocketCAN runs are marked vcan: CI runs them inside vcan-vm, where the guest is emulated and
about 15x slower, hence the slow timing profile there.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import ROBOTS, ROOT, has_vcan

GUIDE = (ROOT / "docs" / "testing.md").read_text(encoding="utf-8")  # the plugin's page of the docs

#: the project's own robot: planar2's URDF, other CAN IDs, another bus name and rate, its own poses
MY_ARM = """\
name: my_arm
urdf: my_arm.urdf
rate_hz: 250
buses:
  main: {channel: can3}
defaults:
  limits: {velocity: 3.0, acceleration: 15.0, jerk: 150.0}
poses:
  rest: [-1.5, 0.0]
  ready: [0.4, -0.8]
joints:
  - {name: shoulder, can_id: 11, motor: AK80-9, gains: {kp: 40.0, kd: 1.5}}
  - {name: elbow, can_id: 12, motor: AK60-6, gains: {kp: 20.0, kd: 0.8}}
"""


def readme_example() -> str:
    """The example test of docs/testing.md, "Testing your own arm programs"."""
    m = re.search(r"```python\n(# test_my_arm.py\n.*?)```", GUIDE, re.S)
    assert m, "no example test in docs/testing.md"
    return m.group(1)


def project(tmp_path: Path, tests: dict[str, str], ini: str | None = None) -> Path:
    """A user's project: my_arm.yaml next to its URDF, the test files, optionally a pytest.ini."""
    (tmp_path / "my_arm.urdf").write_text((ROBOTS / "planar2.urdf").read_text())
    (tmp_path / "my_arm.yaml").write_text(MY_ARM)
    for name, text in tests.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    if ini is not None:
        (tmp_path / "pytest.ini").write_text(ini)
    return tmp_path


def pytest_in(folder: Path, *args: str, timeout: float = 600.0) -> subprocess.CompletedProcess[str]:
    """``python -m pytest ARGS`` in ``folder``, as the user would run it there."""
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rs", "-W",
                           "error::akarm.testing.plugin.LeftEnabledWarning", *args],
                          cwd=folder, capture_output=True, text=True, timeout=timeout)


LOCAL = ["virtual", "akarm_local"]
ALL = [*LOCAL, pytest.param("socketcan", marks=[
    pytest.mark.vcan, pytest.mark.skipif(not has_vcan(), reason="no vcan0 on this machine")])]


@pytest.mark.parametrize("transport", ALL)
def test_the_readme_example_passes_in_a_project_of_its_own(tmp_path: Path, transport: str) -> None:
    folder = project(tmp_path, {"test_my_arm.py": readme_example()})
    # slow on SocketCAN (emulated in CI) and on akarm_local (this machine is shared by several test runs)
    profile = [] if transport == "virtual" else ["--akarm-profile", "slow"]
    r = pytest_in(folder, "--akarm-robot", "my_arm.yaml", "--akarm-interface", transport, "--akarm-pose", "rest",
                  *profile)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 passed" in r.stdout
    assert f"akarm: robot my_arm.yaml, interface {transport}" in r.stdout  # the report header


def test_the_robot_and_transport_can_come_from_pytest_ini_and_indirect_parametrization(tmp_path: Path) -> None:
    test = '''
import pytest

@pytest.mark.parametrize("akarm_sim", ["virtual", "akarm_local"], indirect=True)
def test_each(akarm_sim):
    assert akarm_sim.transport in ("virtual", "akarm_local")
    assert akarm_sim.config.name == "my_arm" and akarm_sim.timing.name == "slow"
    assert (akarm_sim.clock is not None) == (akarm_sim.transport == "virtual")

def test_lockstep_whatever_the_option(akarm_lockstep):
    assert akarm_lockstep.transport == "virtual"
'''
    folder = project(tmp_path, {"tests/test_ini.py": test},
                     ini="[pytest]\nakarm_robot = my_arm.yaml\nakarm_interface = akarm_local\nakarm_profile = slow\n")
    r = pytest_in(folder / "tests")  # the robot file is relative to pytest.ini, not to where pytest starts
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 passed" in r.stdout


def test_without_a_robot_the_fixture_says_how_to_give_one(tmp_path: Path) -> None:
    folder = project(tmp_path, {"test_x.py": "def test_x(akarm_sim):\n    pass\n"})
    r = pytest_in(folder)
    assert r.returncode == 1
    assert "akarm_sim needs a robot file: give --akarm-robot ROBOT.yaml" in r.stdout


def test_a_bad_interface_or_profile_is_one_clear_error(tmp_path: Path) -> None:
    folder = project(tmp_path, {"test_x.py": "def test_x(akarm_sim):\n    pass\n"})
    r = pytest_in(folder, "--akarm-robot", "my_arm.yaml", "--akarm-interface", "pcan")
    assert r.returncode == 1
    assert "--akarm-interface 'pcan': use one of virtual, akarm_local, socketcan" in r.stdout
    r = pytest_in(folder, "--akarm-robot", "my_arm.yaml", "--akarm-profile", "fast")
    assert r.returncode == 1
    assert "no timing profile named 'fast'" in r.stdout


@pytest.mark.skipif(has_vcan("vcan7"), reason="this machine has a vcan7")
def test_socketcan_is_skipped_with_the_reason_where_the_interface_does_not_exist(tmp_path: Path) -> None:
    folder = project(tmp_path, {"test_x.py": "def test_x(akarm_socketcan):\n    raise AssertionError\n"})
    r = pytest_in(folder, "--akarm-robot", "my_arm.yaml", "--akarm-channel", "vcan7")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 skipped" in r.stdout
    assert "no SocketCAN interface vcan7 on this machine (create one: sudo modprobe vcan" in r.stdout


def test_a_robot_with_two_buses_needs_a_channel_for_each_on_socketcan(tmp_path: Path) -> None:
    folder = project(tmp_path, {"test_x.py": "def test_x(akarm_socketcan):\n    pass\n"})
    r = pytest_in(folder, "--akarm-robot", str(ROBOTS / "biarm.yaml"), "--akarm-channel", "vcan0")
    assert r.returncode == 1
    assert "biarm.yaml has 2 buses: give each its interface, --akarm-channel left=vcan0,right=vcan1" in r.stdout


def test_a_program_that_leaves_the_arm_enabled_is_warned_about_and_the_drivers_end_disabled(tmp_path: Path) -> None:
    test = '''
import akarm

PROGRAM = []  # the program keeps its Arm (one dropped while enabled is disabled by akarm itself, and warned about)

def test_leaves_it_on(akarm_sim):
    arm = akarm.Arm(akarm_sim.config, clock=akarm_sim.clock)   # an Arm of the program's own, never closed
    PROGRAM.append(arm)
    arm.open()
    arm.enable()
    assert akarm_sim.enabled_joints() == ["shoulder", "elbow"]
'''
    folder = project(tmp_path, {"test_on.py": test})
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--akarm-robot", "my_arm.yaml",
                        "--akarm-pose", "rest"], cwd=folder, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "LeftEnabledWarning: the simulated drivers of shoulder, elbow were still enabled at the end" in r.stdout
