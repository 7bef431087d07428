"""The simulated gripper, frame by frame: its motor is a driver named as in the robot file, its jaws
stop at 0 and the stroke, and an object between them squeezes back (the truth the controller's
estimate is compared with)."""

from __future__ import annotations

from collections.abc import Iterator

import can
import numpy as np
import pytest

from akarm import StateError
from akarm.config import RobotConfig
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.sim import MitDriver, SimulatedRobot

from .conftest import ROBOTS, drain, send

GRIPPER_ID = 7


@pytest.fixture(scope="module")
def arm6g() -> RobotConfig:
    return load_robot(ROBOTS / "arm6g.yaml")


@pytest.fixture
def rig(arm6g: RobotConfig, channel: str) -> Iterator[tuple[SimulatedRobot, can.BusABC]]:
    with SimulatedRobot(arm6g, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        yield sim, bus


def command(sim: SimulatedRobot, bus: can.BusABC, position: float, kp: float, kd: float, torque: float,
            seconds: float) -> None:
    """ENTER, then the command every 2.5 ms for ``seconds`` (the replies drained)."""
    model = sim.config.gripper.motor  # type: ignore[union-attr]
    send(bus, GRIPPER_ID, mit.ENTER)
    for _ in range(round(seconds / 0.0025)):
        send(bus, GRIPPER_ID, mit.encode_command(model, position, 0.0, kp, kd, torque))
        sim.run_for(0.0025)
        drain(bus)


def test_the_gripper_is_a_simulated_joint_named_as_in_the_robot_file(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    d = sim.joint("gripper")
    assert isinstance(d, MitDriver) and d.can_id == GRIPPER_ID
    assert len(sim.drivers) == 6 and sim.all_drivers[-1] is d  # not one of the arm's drivers
    assert sim.gripper_width() == pytest.approx(0.04)  # it starts half open
    send(bus, GRIPPER_ID, mit.encode_command(d.motor, 0.0, 0.0, 0.0, 0.0, 0.0))
    sim.run_for(0.0025)
    (reply,) = drain(bus)
    assert bytes(reply.data) == mit.encode_reply(d.motor, GRIPPER_ID, 1.0, 0.0, 0.0, 25.0, 0)  # 1 rad: 40 mm


def test_position_command_moves_the_jaws(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    command(sim, bus, 1.5, 5.0, 0.2, 0.0, 1.0)
    assert sim.gripper_width() == pytest.approx(0.06, abs=5e-4)


@pytest.mark.parametrize(("target", "stop"), [(-0.5, 0.0), (2.6, 0.08)])
def test_the_jaws_stop_at_closed_and_fully_open(rig: tuple[SimulatedRobot, can.BusABC], target: float,
                                                stop: float) -> None:
    sim, bus = rig
    command(sim, bus, target, 5.0, 0.2, 0.0, 1.0)
    # kp · 0.5 rad = 2.5 N·m presses into a stop of 500 N·m/rad: 5 mrad, 0.2 mm
    assert sim.gripper_width() == pytest.approx(stop, abs=5e-4)


def test_an_object_squeezes_back_with_the_motor_torque(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.place_object(0.03)
    assert sim.object_force() == 0.0
    command(sim, bus, 0.0, 0.0, 0.2, -0.8, 1.0)  # 0.8 N·m closing at 0.04 m/rad: 20 N
    assert sim.object_force() == pytest.approx(20.0, rel=0.02)
    assert sim.gripper_width() == pytest.approx(0.03 - 20.0 / 20_000.0, abs=1e-4)  # 1 mm into it
    sim.remove_object()
    command(sim, bus, 0.0, 0.0, 0.2, -0.8, 1.0)
    assert sim.object_force() == 0.0 and sim.gripper_width() == pytest.approx(0.0, abs=2e-4)


def test_a_placed_object_is_carried_while_squeezed_and_stays_where_let_go(
        rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    tool = sim.model.tool_pose(sim.q)[:3, 3]
    sim.place_object(0.03, position=tool + np.array([0.0, 0.0, 0.01]), mass=0.2)
    command(sim, bus, 0.0, 0.0, 0.2, -0.8, 0.3)
    assert sim.object_held and sim.object_force() > 15.0
    sim.set_state([0.5, 0, 0, 0, 0, 0])
    command(sim, bus, 0.0, 0.0, 0.2, -0.8, 0.01)
    moved = sim.model.tool_pose(sim.q)[:3, 3] + np.array([0.0, 0.0, 0.01])
    assert sim.object_position() == pytest.approx(moved, abs=1e-9)
    command(sim, bus, 2.0, 5.0, 0.2, 0.0, 0.5)  # open: let go
    assert not sim.object_held and sim.object_force() == 0.0
    sim.set_state([0.0] * 6)
    command(sim, bus, 2.0, 5.0, 0.2, 0.0, 0.01)
    assert sim.object_position() == pytest.approx(moved, abs=1e-9)  # it stayed


def test_no_gripper_no_object(planar2: RobotConfig, channel: str) -> None:
    with SimulatedRobot(planar2, "virtual", channel, realtime=False) as sim, pytest.raises(StateError):
        sim.place_object(0.03)


def test_an_object_through_the_control_channel(arm6g: RobotConfig, channel: str, tmp_path) -> None:
    from akarm.sim.channel import ChannelServer, SimulatorControl

    config = arm6g.with_bus(interface="virtual", channel=channel)
    path = tmp_path / "sim.sock"
    with SimulatedRobot(config, realtime=False) as sim, ChannelServer(sim, path), \
            can.Bus(interface="virtual", channel=channel) as bus:
        ctl = SimulatorControl(path)
        ctl.place_object(0.03, 20_000.0)
        command(sim, bus, 0.0, 0.0, 0.2, -0.8, 1.0)
        width, force = ctl.gripper()
        assert force == pytest.approx(20.0, rel=0.02) and width == pytest.approx(0.029, abs=1e-4)
        ctl.remove_object()
        assert ctl.gripper()[1] == 0.0
        with pytest.raises(Exception, match="outside its stroke"):
            ctl.place_object(0.5)
