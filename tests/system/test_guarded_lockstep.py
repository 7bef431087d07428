"""Guarded moves (``arm.move_until_contact``): down onto a simulated surface (a stiff external force that
starts at a height), stopped at the contact with the force near its threshold.

Lock step on arm6; the tool is measured with the test's own forward kinematics from the joint angles
the telemetry recorded every cycle.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

import akarm
from akarm.control.guard import Contact
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, StateError

from ..conftest import ROBOTS, lockstep_arm, wait_until

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FK = RobotModel(ARM6)
STIFFNESS = 2e4  # N/m: the simulated surface's


def lowest(arm: akarm.Arm, since: float) -> float:
    """The lowest the tool went (m, base z) in the cycles since ``since``, from the measured joint angles."""
    log = arm.telemetry(since)
    return min(float(FK.tool_pose(q)[2, 3]) for q in log.q)


def test_a_guarded_move_down_stops_at_the_surface_with_about_its_force(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        surface = FK.tool_pose(READY)[2, 3] - 0.03
        sim.set_surface(surface, stiffness=STIFFNESS)
        t0 = arm.clock.now()
        contact = arm.move_until_contact([0.0, 0.0, -1.0], speed=0.02, force=5.0)
        depth = surface - lowest(arm, t0)  # (the replies' angles: ±0.3 mm at the tool)
        assert contact.touched and 5.0 <= contact.force <= 7.5
        assert depth < 0.003, f"{depth * 1e3:.2f} mm into the surface"
        assert 5.0 <= sim.contact_peak <= 7.5  # the surface's push, at most 1.5 × the threshold
        assert abs(contact.position[2] - surface) < 0.003 and 0.027 < contact.distance < 0.033
        # it holds at the contact without pressing, the collision reflex armed again
        arm.sleep(0.5)
        assert sim.contact_force < 2.0 and arm.enabled and arm.fault is None
        assert arm.collision_thresholds["elbow"] == pytest.approx(ARM6.joint("elbow").collision_threshold)
        # back off: from the contact, 10 mm up
        contact = arm.move_until_contact([0.0, 0.0, -1.0], speed=0.02, force=5.0, back_off=0.01)
        assert contact.touched
        assert abs(FK.tool_pose(sim.q)[2, 3] - (contact.position[2] + 0.01)) < 0.002


def test_a_guarded_move_that_touches_nothing_goes_its_whole_way(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        z = FK.tool_pose(sim.q)[2, 3]
        contact = arm.move_until_contact([0.0, 0.0, -1.0], speed=0.05, force=8.0, max_distance=0.04)
        assert not contact.touched and contact.force < 8.0
        assert abs(FK.tool_pose(sim.q)[2, 3] - (z - 0.04)) < 0.002
        for bad in ({"direction": [0, 0, 0]}, {"direction": [0, 1]}, {"direction": [0, 0, -1], "speed": 0.0},
                    {"direction": [0, 0, -1], "force": -1.0}, {"direction": [0, 0, -1], "back_off": -0.1}):
            with pytest.raises(ArgumentError):
                arm.move_until_contact(**bad)


def test_impedance_and_a_guarded_move_refuse_each_other_and_thresholds_set_meanwhile_stay(channel: str) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True) as (arm, sim):
        yaml = arm.collision_thresholds
        with arm.impedance(stiffness=[500.0] * 3 + [30.0] * 3):
            with pytest.raises(StateError, match="under impedance control") as info:
                arm.move_until_contact([0.0, 0.0, -1.0])
            assert "leave the impedance block" in info.value.fix
            arm.set_collision({"elbow": 2.0})  # made during it: kept after it
            assert arm.collision_thresholds == {**yaml, "elbow": 2.0}
        assert arm.collision_thresholds == {**yaml, "elbow": 2.0} and arm.enabled
        # the other way round: a guarded move on another thread (its sleeps step the lock-step clock)
        found: list[object] = []
        mover = threading.Thread(target=lambda: found.append(
            arm.move_until_contact([0.0, 0.0, -1.0], speed=0.02, force=5.0, max_distance=0.02)))
        z = FK.tool_pose(sim.q)[2, 3]
        mover.start()
        try:
            assert wait_until(lambda: arm.moving, 10.0)
            with pytest.raises(StateError, match="while a guarded move"):
                arm.impedance(stiffness=[500.0] * 3 + [30.0] * 3)
            arm.set_collision({"elbow": 3.0})
            assert arm.moving  # the refusal stopped nothing
        finally:
            mover.join(60.0)
        (contact,) = found
        assert isinstance(contact, Contact) and not contact.touched
        assert abs(FK.tool_pose(sim.q)[2, 3] - (z - 0.02)) < 0.002  # it went its whole way
        assert arm.collision_thresholds == {**yaml, "elbow": 3.0} and arm.fault is None
        with arm.impedance(stiffness=[500.0] * 3 + [30.0] * 3):  # nothing left suspended or refused
            pass
        assert arm.collision_thresholds == {**yaml, "elbow": 3.0}
