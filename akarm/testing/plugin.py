"""Test your own arm programs against akarm's simulator: a pytest plugin.

Installed with akarm (entry point ``pytest11``), so in any project where akarm is installed::

    pytest --akarm-robot robots/my_arm.yaml                                 # lock step, in the test's process
    pytest --akarm-robot robots/my_arm.yaml --akarm-interface akarm_local   # the simulator in a process of its own
    pytest --akarm-robot robots/my_arm.yaml --akarm-interface socketcan --akarm-profile slow   # on vcan0

and a test asks for the ``akarm_sim`` fixture: a :class:`~akarm.testing.rig.SimulatedArm`, the simulated
drivers of every joint of that YAML on a bus of their own, with the arm at rest::

    def test_my_program(akarm_sim):
        with akarm_sim.arm() as arm:                # an akarm.Arm on the simulated arm's bus
            arm.enable()
            my_program.run(arm)
        akarm_sim.inject("elbow", faults.Unplugged())   # fault injection (akarm.sim.faults)
        akarm_sim.frames(joint="elbow")                 # every CAN frame to and from a joint

Transports (``--akarm-interface``, or ``@pytest.mark.parametrize("akarm_sim", [...], indirect=True)``):

- ``virtual`` (default): a :class:`~akarm.sim.SimulatedRobot` in the test's process, in lock step
  with the arm (``realtime=False``): fast and exactly repeatable, whatever the machine's load.
- ``akarm_local``: ``akarm sim`` in a process of its own on the shared-memory ``akarm_local`` bus,
  in real time, as the motors are hardware of their own.
- ``socketcan``: ``akarm sim`` in a process of its own on a SocketCAN interface (``vcan0``, or
  ``--akarm-channel``; ``left=vcan0,right=vcan1`` for a robot with several buses; by default its
  buses take ``vcan0``, ``vcan1``, ... in order). A test is skipped, saying why, where the
  interface does not exist.

The fixtures ``akarm_lockstep``, ``akarm_local`` and ``akarm_socketcan`` give one transport whatever
the option says. Every fixture ends with the simulated drivers disabled: it closes the arms it made
(damped, then disabled), then switches off any driver still enabled, with a
:class:`LeftEnabledWarning` for a joint no fault explains (on hardware that motor would have stayed
powered). Options (each also an ini setting: ``akarm_robot = robots/my_arm.yaml`` in pytest.ini):
``--akarm-robot``, ``--akarm-interface``, ``--akarm-channel``, ``--akarm-profile`` (the timing
profile, :mod:`akarm.timing`: ``slow`` on slow or shared machines), ``--akarm-pose`` (the pose the
simulated arm starts in; default all zeros), ``--akarm-serial`` (servo joints whose simulated drivers
answer on serial ports, over pseudo-terminal pairs: ``--akarm-serial elbow,wrist``; the arms made by
the fixture drive them over UART). A project can also override the ``akarm_robot`` fixture.

This module is imported by pytest in every run where akarm is installed, akarm's own included: it
adds options and fixtures, nothing runs until a test asks for one, and it imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from akarm.errors import AkarmError
from akarm.testing.rig import TRANSPORTS, Frame, LeftEnabledWarning, SimulatedArm, default_channel, missing_interfaces

if TYPE_CHECKING:
    from akarm.timing import TimingProfile

__all__ = ["TRANSPORTS", "Frame", "LeftEnabledWarning", "SimulatedArm"]


_OPTIONS = {
    "robot": ("ROBOT.yaml", "the robot file the simulated arm is made from"),
    "interface": ("NAME", f"how the simulator is reached: {', '.join(TRANSPORTS)} (default virtual: lock step, "
                          "in the test's process)"),
    "channel": ("CHANNEL", "the bus channel (socketcan: default vcan0, or BUS=vcan0,BUS=vcan1 for several buses)"),
    "profile": ("NAME", "timing profile of the simulator and the arm: normal (default) or slow (slow or shared "
                        "machines)"),
    "pose": ("POSE", "the named pose the simulated arm starts in (default: all joints at zero)"),
    "serial": ("JOINT[,JOINT]", "servo joints driven over UART: their simulated drivers answer on pseudo-terminal "
                                "pairs"),
}


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("akarm", "akarm: test arm programs against a simulated arm")
    for key, (metavar, help_text) in _OPTIONS.items():
        group.addoption(f"--akarm-{key}", dest=f"akarm_{key}", metavar=metavar, help=help_text)
        parser.addini(f"akarm_{key}", help_text)


def _setting(config: pytest.Config, key: str) -> tuple[str | None, Path]:
    """The option's value and the folder a relative path in it is relative to: the command line's
    (from where pytest was started), else the ini file's (next to it)."""
    value = config.getoption(f"akarm_{key}")
    if value:
        return str(value), Path(config.invocation_params.dir)
    value = config.getini(f"akarm_{key}")
    base = config.inipath.parent if config.inipath is not None else config.rootpath
    return (str(value) if value else None), Path(base)


def pytest_report_header(config: pytest.Config) -> str | None:
    robot, _ = _setting(config, "robot")
    if robot is None:
        return None
    parts = [f"robot {robot}"] + [f"{key} {value}" for key in ("interface", "channel", "profile", "pose", "serial")
                                  if (value := _setting(config, key)[0])]
    return "akarm: " + ", ".join(parts)


@pytest.fixture(scope="session")
def akarm_robot(pytestconfig: pytest.Config) -> Path:
    """The robot file (``--akarm-robot`` or the ``akarm_robot`` ini setting); override the fixture to
    choose it in code."""
    value, base = _setting(pytestconfig, "robot")
    if value is None:
        pytest.fail("akarm_sim needs a robot file: give --akarm-robot ROBOT.yaml, set akarm_robot in pytest.ini, "
                    "or override the akarm_robot fixture", pytrace=False)
    return (base / value).resolve()


@pytest.fixture(scope="session")
def akarm_timing(pytestconfig: pytest.Config) -> TimingProfile:
    """The timing profile (``--akarm-profile``; default ``normal``)."""
    from akarm.timing import get_profile

    try:
        return get_profile(_setting(pytestconfig, "profile")[0])
    except AkarmError as e:
        pytest.fail(f"--akarm-profile: {e}", pytrace=False)


def _simulated_arm(request: pytest.FixtureRequest, robot: Path, timing: TimingProfile,
                   transport: str | None) -> Iterator[SimulatedArm]:
    from akarm.config import parse_channel
    from akarm.robotfile.load import load_robot

    if transport is None:
        transport = getattr(request, "param", None) or _setting(request.config, "interface")[0] or "virtual"
    if transport not in TRANSPORTS:
        pytest.fail(f"--akarm-interface {transport!r}: use one of {', '.join(TRANSPORTS)}", pytrace=False)
    channel = parse_channel(_setting(request.config, "channel")[0])
    pose = _setting(request.config, "pose")[0]
    if transport == "socketcan":
        try:
            config = load_robot(robot)
        except AkarmError as e:
            pytest.fail(str(e), pytrace=False)
        if isinstance(channel, str) and len(config.buses) > 1:
            pytest.fail(f"{robot.name} has {len(config.buses)} buses: give each its interface, --akarm-channel "
                        + ",".join(f"{b}=vcan{k}" for k, b in enumerate(config.buses)), pytrace=False)
        why = missing_interfaces(config.with_bus(interface="socketcan",
                                                 channel=channel or default_channel(config, transport)))
        if why:
            pytest.skip(f"{why} (create one: sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && "
                        "sudo ip link set up vcan0)")
    elif transport == "virtual" or channel is None:
        channel = None  # a channel of this test's own, so that parallel runs never meet
    serial = [j.strip() for j in (_setting(request.config, "serial")[0] or "").split(",") if j.strip()]
    sim = SimulatedArm.start(robot, transport, channel=channel, timing=timing, pose=pose, serial=serial)
    try:
        yield sim
    finally:
        sim.close()


@pytest.fixture
def akarm_sim(request: pytest.FixtureRequest, akarm_robot: Path, akarm_timing: TimingProfile) -> Iterator[SimulatedArm]:
    """A :class:`SimulatedArm` on the transport ``--akarm-interface`` names (default: lock step), or the
    one given by ``@pytest.mark.parametrize("akarm_sim", [...], indirect=True)``."""
    yield from _simulated_arm(request, akarm_robot, akarm_timing, None)


@pytest.fixture
def akarm_lockstep(request: pytest.FixtureRequest, akarm_robot: Path,
                   akarm_timing: TimingProfile) -> Iterator[SimulatedArm]:
    """A :class:`SimulatedArm` in lock step in the test's process, whatever ``--akarm-interface`` says."""
    yield from _simulated_arm(request, akarm_robot, akarm_timing, "virtual")


@pytest.fixture
def akarm_local(request: pytest.FixtureRequest, akarm_robot: Path,
                akarm_timing: TimingProfile) -> Iterator[SimulatedArm]:
    """A :class:`SimulatedArm` in a process of its own on ``akarm_local``, whatever ``--akarm-interface`` says."""
    yield from _simulated_arm(request, akarm_robot, akarm_timing, "akarm_local")


@pytest.fixture
def akarm_socketcan(request: pytest.FixtureRequest, akarm_robot: Path,
                    akarm_timing: TimingProfile) -> Iterator[SimulatedArm]:
    """A :class:`SimulatedArm` in a process of its own on SocketCAN (skipped where the interface does not exist)."""
    yield from _simulated_arm(request, akarm_robot, akarm_timing, "socketcan")
