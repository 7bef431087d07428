"""Shared test fixtures and helpers, and the tiers.

The tests are in three folders, one per tier, and each test gets its folder's marker (``-m unit``,
``-m sim``, ``-m system``):

- ``tests/unit``: pure logic: no simulator, no CAN bus, no threads, no processes.
- ``tests/sim``: the simulator or a bus in this process, in lock step with the controller where a
  loop runs (SteppedClock): nothing waits on the wall clock for more than a few milliseconds.
- ``tests/system``: other processes (``akarm sim``, the CLI as a command, scripts), real-time loops
  and simulators, akarm_local across processes, ROS 2 over DDS, SocketCAN (``vcan``); and the few
  lock-step files whose runs take seconds each (the whole demo, init then a move on every example
  robot, teach and replay, Cartesian moves, teleoperation), which would take the README's test
  command past its 90 s.

- ``tests/docs``: the fenced ``python`` blocks of README.md and docs/, each run in lock step (CI runs
  them in a step of their own, after building the site).

``python -m pytest`` runs unit and sim (pyproject's testpaths); ``python -m pytest tests/system``
runs the system tier. The helpers below are imported by the tests as ``from .conftest import ...``:
each tier's conftest re-exports them (``__all__``).
"""

from __future__ import annotations

import itertools
import os
import signal
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can
import pytest

from akarm.buses.bus import drain as _drain
from akarm.errors import AkarmError
from akarm.protocol import mit

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.clock import SteppedClock
    from akarm.config import RobotConfig
    from akarm.sim import SimulatedRobot
    from akarm.sim.records import Frame
    from akarm.timing import TimingProfile

# DDS (akarm serve, ROS 2 tests) stays on the loopback interface: no multicast onto the network, and
# test runs see nothing but their own participants (each also uses a domain and namespace of its own)
try:
    from akarm.ros.dds import LOOPBACK_CONFIG

    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
except AkarmError:  # no ros extra (akarm.ros says so): the ROS tests skip
    pass

__all__ = ["ROBOTS", "ROOT", "URDFS", "command_steps", "drain", "has_can_sockets", "has_vcan", "lockstep_arm",
           "missing_socketcan_fix", "relaxed_robot", "send", "wait_until"]

ROOT = Path(__file__).resolve().parent.parent
TIERS = ("unit", "sim", "system", "docs")  # docs: the documentation's code blocks (tests/docs)


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: without xdist (-p no:xdist) nobody calls it
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto`` (pyproject's addopts): a worker per core for the README's plain ``python -m pytest``
    (unit and sim: lock step, so no test depends on how fast its process runs), and none when paths or
    tests are named (the system tier runs in real time and must not share the cores with itself; a
    single test starts at once). ``-n NUMBER`` on the command line still wins."""
    return 0 if config.args_source is pytest.Config.ArgsSource.ARGS else None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test with its tier, the folder it is in (tests/unit, tests/sim, tests/system)."""
    here = Path(__file__).parent
    for item in items:
        parts = item.path.relative_to(here).parts if item.path.is_relative_to(here) else ()
        if parts and parts[0] in TIERS:
            item.add_marker(parts[0])


if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    # Started in the background by a non-interactive shell (`cmd &` in a script), a process ignores
    # Ctrl-C, and Python then leaves it ignored: the tests that press Ctrl-C on a verb would wait forever.
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(autouse=True)
def _no_python_can_configuration(monkeypatch: pytest.MonkeyPatch) -> None:
    """Robot files are read as python-can users configure their buses (CAN_* variables, can.conf,
    .canrc): a developer's own configuration must not change what the tests see."""
    import can.util

    for name in list(os.environ):
        if name.startswith(("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG")):
            monkeypatch.delenv(name)
    monkeypatch.setattr(can.util, "CONFIG_FILES", [])
    monkeypatch.setattr(can, "rc", {})


# module- and session-scoped fixtures run before the per-test state directory below: never the developer's
os.environ["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="akarm-test-state-")


@pytest.fixture(autouse=True, scope="module")
def _module_state_in_tmp(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The same for each module's module-scoped fixtures (a server or simulator a module shares): they
    start before the per-test directory below, and must not see what an earlier module's arm of the
    same name remembered (another simulator, started at another pose)."""
    previous = os.environ.get("XDG_STATE_HOME")
    os.environ["XDG_STATE_HOME"] = str(tmp_path_factory.mktemp("module-state"))
    yield
    if previous is not None:
        os.environ["XDG_STATE_HOME"] = previous


@pytest.fixture(autouse=True)
def _state_in_tmp(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> None:
    """The joints' remembered positions (akarm.control.turns) go to a state directory of each test's
    own: nothing of the developer's, and no test sees what another one remembered."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.mktemp("state")))


ROBOTS = ROOT / "robots"
URDFS = ROOT / "tests" / "urdfs"  # the exporter-style URDF corpus (tests/unit/test_urdf.py)
_counter = itertools.count()


@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    """A virtual-bus channel name unique to this test (python-can virtual buses share by name)."""
    return f"akarm-test-{os.getpid()}-{next(_counter)}-{request.node.name}"


def has_vcan(name: str = "vcan0") -> bool:
    """True when a SocketCAN interface ``name`` exists on this machine."""
    return Path(f"/sys/class/net/{name}").exists()


def has_can_sockets() -> bool:
    """True when this kernel supports CAN sockets (AF_CAN); without, SocketCAN buses fail with errno 97."""
    import socket

    try:
        socket.socket(socket.PF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except (OSError, AttributeError):
        return False
    return True


def missing_socketcan_fix(channel: str) -> str:
    """What the error for a missing SocketCAN ``channel`` must say here: how to create the interface
    where the kernel has CAN support, that it has none (not "bring the link up") where it has not."""
    if not has_can_sockets():
        return "this kernel has no CAN support"
    if channel.startswith("vcan"):
        return f"sudo ip link add dev {channel} type vcan && sudo ip link set up {channel}"
    return f"sudo ip link set {channel} up type can"


def wait_until(cond: Callable[[], bool], timeout: float) -> bool:
    """Poll ``cond`` every 5 ms for up to ``timeout`` s (simulators and CLIs run on threads of their
    own: a test waits for what it checks, with a deadline, instead of sleeping a fixed time)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return bool(cond())


def send(bus: can.BusABC, arbitration_id: int, data: bytes, extended: bool = False) -> None:
    """Send one frame on ``bus`` (a test playing the host or another node)."""
    bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=extended))


def drain(bus: can.BusABC) -> list[can.Message]:
    """Every frame already waiting on ``bus``."""
    return list(_drain(bus, limit=1 << 20))


@pytest.fixture(scope="module")
def planar2():
    """robots/planar2.yaml, loaded once per module."""
    from akarm.robotfile.load import load_robot

    return load_robot(ROBOTS / "planar2.yaml")


@contextmanager
def lockstep_arm(robot: str | Path | RobotConfig, channel: str, *, q0: Any = None,
                 config_edit: Callable[[RobotConfig], RobotConfig] | None = None, enable: bool = False,
                 timing: str | TimingProfile | None = None, sim_options: Mapping[str, Any] | None = None,
                 clock: SteppedClock | None = None, **arm_options: Any) -> Iterator[tuple[Arm, SimulatedRobot]]:
    """The lock-step arm the sim tests share: a :class:`~akarm.sim.SimulatedRobot` in this process on
    the virtual channel ``channel`` and an :class:`~akarm.Arm` on its clock, open (enabled with
    ``enable``); leaving the block closes the arm (damped, disabled), then the simulator.

    ``robot``: a name in robots/ (``"arm6"``), a robot file (a Path) or a loaded config, put on
    ``channel``, then passed through ``config_edit``. ``q0``: the simulator's start position
    (default all zeros); ``timing``: the profile of both; ``sim_options`` go to the simulator
    (``faults``, ``dt``, ...), ``arm_options`` to the Arm (``feedforward``, ``telemetry_seconds``, ...).
    ``clock``: a stepped clock shared with other lock-step arms (two arms in one test: one clock drives
    both simulators and both loops); default: the simulator's own.
    """
    from akarm.arm import Arm
    from akarm.robotfile.load import load_robot
    from akarm.sim import SimulatedRobot

    if isinstance(robot, str | Path):
        robot = load_robot(ROBOTS / f"{robot}.yaml" if isinstance(robot, str) else robot)
    config = robot.with_bus(interface="virtual", channel=channel)
    if config_edit is not None:
        config = config_edit(config)
    if timing is None:  # (AKARM_TEST_TIMING: run lock-step tests under another timing profile)
        timing = os.environ.get("AKARM_TEST_TIMING") or None
    if timing is not None:
        arm_options.setdefault("timing", timing)
    # a new simulated arm: positions remembered (akarm.control.turns) are this arm's, not the last test arm's
    arm_options.setdefault("remember_positions", Path(os.environ["XDG_STATE_HOME"]) / f"lockstep-{next(_counter)}.json")
    with SimulatedRobot(config, realtime=False, q0=q0, timing=timing, clock=clock, **(sim_options or {})) as sim, \
            Arm(config, clock=sim.clock, **arm_options) as arm:
        if enable:
            arm.enable()
        yield arm, sim


@pytest.fixture
def lockstep(channel: str) -> Callable[..., AbstractContextManager[tuple[Arm, SimulatedRobot]]]:
    """:func:`lockstep_arm` on this test's channel: ``with lockstep("arm6", enable=True) as (arm, sim):``
    (a test with several arms gives each its own: ``lockstep("arm6", channel=channel + "-b")``)."""

    def make(robot: str | Path | RobotConfig, **options: Any) -> AbstractContextManager[tuple[Arm, SimulatedRobot]]:
        return lockstep_arm(robot, options.pop("channel", channel), **options)

    return make


def relaxed_robot(robot: Path, directory: Path) -> Path:
    """A copy of ``robot`` whose supervisor tolerates a loaded machine: for a controller running in
    real time against a simulator in another process, which the OS may pause or slow down (a
    real-time simulation falls behind the wall clock when its process gets too little CPU: seen here,
    elbow 0.7 rad behind its command with other test runs and a VM on the 2 cores). Feedback may be
    0.5 s old, and the reading may lag the command by up to 3 rad, before the supervisor stops the
    arm; the tests' own checks of where the arm is stay as they are. A gripper's motor gets the same
    0.5 s (its watchdog is its own, not the defaults')."""
    import yaml

    doc = yaml.safe_load(robot.read_text())
    doc["urdf"] = str(robot.parent / doc["urdf"])
    doc.setdefault("defaults", {}).update(feedback_timeout=0.5, stuck_travel=3.0, following_error=3.0)
    if isinstance(doc.get("gripper"), dict):  # the gripper's motor has a watchdog of its own
        doc["gripper"]["feedback_timeout"] = 0.5
    path = directory / f"{robot.stem}-relaxed.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def command_steps(frames: list[Frame], config: RobotConfig) -> dict[str, float]:
    """Per MIT joint, the largest step between consecutive commands with kp > 0 it took in, as a share of
    what its velocity limit allows in one period (1.0: exactly that; position quantisation aside)."""
    joints = {j.name: j for j in config.joints if j.mode == "mit"}
    last: dict[str, float] = {}
    worst = dict.fromkeys(joints, 0.0)
    period = 1.0 / config.rate_hz
    for f in frames:
        j = joints.get(f.joint or "")
        if j is None or not f.to_motor or mit.special_frame(f.data) is not None:
            continue
        cmd = mit.codec(j.motor).decode_command(f.data, firmware=j.firmware)
        if cmd.kp <= 0.0:
            last.pop(j.name, None)  # damping or a neutral command: the next held position starts afresh
            continue
        lsb = 2.0 * j.motor.p_max / 65535.0
        if j.name in last and abs(cmd.position - last[j.name]) < j.motor.p_max:  # (not across the field's wrap)
            step = max(0.0, abs(cmd.position - last[j.name]) - 2.0 * lsb)
            worst[j.name] = max(worst[j.name], step / (j.limits.velocity * period))
        last[j.name] = cmd.position
    return worst
