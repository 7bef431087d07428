"""Self-collision (on by default; the robot file's ``self_collision:``, ``Arm(self_collision=...)``): shapes
from the URDF or capsules, neighbours left out, a planned move that folds the arm into itself refused with
nothing moving, servoing stopping short, every named pose, the demo's path and the examples' moves free.

Lock step on arm6. Its URDF's <collision> shapes are the AK housings (AK10-9 120 mm across, AK70-10 90,
AK80-9 98, AK60-6 80) and the tubes with their clamps; its visuals are thinner (they come no closer than
23 mm within the joint ranges, so the fold is only caught with a margin).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.config import SelfCollisionConfig
from akarm.dynamics.selfcollision import SelfCollision
from akarm.errors import ArgumentError, LimitError, SelfCollisionStop
from akarm.sim import faults

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FOLDED = np.array([0.0, 0.3, 2.5, 0.0, 2.0, 0.0])  # the elbow folded to its limit, the wrist folded back


def test_shapes_come_from_the_urdf_else_capsules_and_neighbours_are_left_out() -> None:
    housings = SelfCollision(ARM6, margin=ARM6.self_collision.margin)
    assert housings.source == "collision" and ARM6.self_collision.margin == 0.01
    assert housings.colliding(FOLDED) == [("upper_arm_0", "forearm_tube_0")]  # the tube against the clamp
    for name, q in ARM6.poses.items():
        assert not housings.colliding(q), name
    assert not housings.colliding([0.0, 0.3, 2.3, 0.0, 2.0, 0.0])  # the elbow 0.2 rad short of its limit
    demo = np.loadtxt(Path(akarm.__file__).parent / "data" / "demo_path.csv", delimiter=",", skiprows=1)[:, 1:]
    assert not any(housings.colliding(q) for q in demo)  # the demo's figure eight
    copy, touching = housings.copy(), housings.copy(margin=0.0)  # another thread's: the shapes shared
    assert copy.pairs == housings.pairs and copy.colliding(FOLDED) == housings.colliding(FOLDED)
    assert not touching.colliding(FOLDED)  # 3.8 mm apart: inside the margin, not touching
    visual = SelfCollision(ARM6, "visual")
    assert visual.source == "visual"
    assert not visual.colliding(READY) and not visual.colliding(FOLDED)
    joints = {name.rsplit("_", 1)[0] for pair in visual.pairs for name in pair}
    assert "upper_arm" in joints and ("upper_arm_0", "upper_arm_1") not in visual.pairs
    padded = SelfCollision(ARM6, "visual", margin=0.025)
    assert ("upper_arm_0", "forearm_tube_0") in padded.colliding(FOLDED)
    capsules = SelfCollision(ARM6, "capsules")
    assert capsules.colliding(FOLDED) == [("link2_0", "link4_0")]  # the upper arm and the forearm
    assert not capsules.colliding(READY)
    with pytest.raises(ArgumentError):
        SelfCollision(ARM6, "meshes")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError):
        SelfCollision(ARM6, margin=-0.01)


@pytest.mark.parametrize(("source", "margin"), [(True, None), ("capsules", 0.0), ("visual", 0.025)])
def test_folding_the_wrist_into_the_upper_arm_is_refused_with_nothing_moving(channel: str, source: bool | str,
                                                                             margin: float | None) -> None:
    with lockstep_arm(ARM6, channel, q0=READY, enable=True, self_collision=source,
                      self_collision_margin=margin) as (arm, sim):
        before = arm.state().q_des.copy()
        with pytest.raises(LimitError, match="collide with itself"):
            arm.move_to(FOLDED)
        arm.sleep(0.2)
        assert not arm.moving and np.array_equal(arm.state().q_des, before)
        assert np.allclose(sim.q, READY, atol=3e-3)
        arm.move_to([0.0, 0.3, 1.6, 0.0, 0.5, 0.0])  # a fold short of it goes


def test_servoing_stops_short_of_a_collision(channel: str) -> None:
    start = np.array([0.0, 0.3, 2.0, 0.0, 0.0, 0.0])
    with lockstep_arm(ARM6, channel, q0=start, enable=True) as (arm, sim):
        with arm.servo(timeout=0.1, frame="tool") as s:
            end = arm.clock.now() + 2.0
            while arm.clock.now() < end:
                s.twist([0.0, 0.0, 0.0, 0.0, -0.8, 0.0])  # pitch the tool back: the elbow folds on
                arm.sleep(0.01)
            reason = s.status.reason
        assert not arm.self_collision.colliding(sim.q)
        assert reason in ("collision", "joint limit")
        assert arm.fault is None


def test_an_arm_pushed_into_itself_is_a_named_safety_stop(channel: str) -> None:
    # capsules: arm6's housings touch only past the elbow's range; these at 2.43 rad, 10 mm apart at 2.25
    start = np.array([0.0, 0.3, 2.1, 0.0, 0.0, 0.0])
    with lockstep_arm(ARM6, channel, q0=start, enable=True, self_collision="capsules") as (arm, sim):
        arm.set_collision([None] * 6)  # the push is the point here, not a collision
        arm.set_gains(kp=[20.0] * 6)
        push = np.zeros(6)
        push[2] = 12.0  # the elbow folded on, against its command (0.6 rad at kp 20, less its hold)
        sim.set_external_torque(push)
        with pytest.raises(SelfCollisionStop, match="link2_0 touching link4_0") as info:
            arm.sleep(2.0)
        assert info.value.pair == ("link2_0", "link4_0") and not arm.enabled
        folded = info.value.q[2]
        assert 2.42 < folded < 2.5, folded  # at contact (2.43 rad), a check (8 ms) at most later
        assert arm.self_collision is not None and arm.self_collision.collides(info.value.q)


def test_the_robot_file_and_the_arm_turn_it_on_and_off(channel: str) -> None:
    off = dataclasses.replace(ARM6, self_collision=SelfCollisionConfig("none"))
    with lockstep_arm(off, channel, q0=READY, enable=True) as (arm, _sim):
        assert arm.self_collision is None
        arm.move_to(FOLDED, speed=0.5)  # nothing checks: it goes
    assert akarm.Arm(ARM6, self_collision=False).self_collision is None
    assert akarm.Arm(ARM6, self_collision_margin=0.02).self_collision.margin == 0.02
    one, two = akarm.Arm(ARM6).self_collision, akarm.Arm(ARM6).self_collision  # built once, shared read only
    assert one is not two and one.geom is two.geom and one.margin == two.margin == 0.01
    with pytest.raises(ArgumentError, match="self_collision must be"):
        akarm.Arm(ARM6, self_collision="meshes")
    with pytest.raises(ArgumentError, match="self_collision_margin"):
        akarm.Arm(ARM6, self_collision_margin=-1.0)


def test_an_arm_enabled_folded_into_itself_moves_out_without_a_stop(channel: str) -> None:
    """A limp arm6 falls from `home` onto its elbow's hard stop (2.6 rad, past the robot file's 2.5), where
    its housings touch; enabled there it holds, and a move out must not be taken for a push into itself
    while the measured pose trails the command out of contact (seen in CI: the live view's test stopped)."""
    folded = np.array([0.0, -0.15, 2.58, 0.0, 0.9, 0.0])
    with lockstep_arm(ARM6, channel, q0=folded) as (arm, sim):
        assert arm.self_collision is not None and arm.self_collision.collides(folded)
        arm.enable()
        # the readings 15 ms late (a loaded machine's simulator, a slow bus): the measured pose trails the command
        sim.inject("elbow", faults.DelayReplies(0.015))
        arm.move_to("home")
        assert arm.enabled and arm.fault is None
        arm.sleep(1.0)
        assert np.max(np.abs(sim.q - np.array(ARM6.pose("home")))) < 0.05
        # (that the guard is armed again once the arm was measured clear: tests/unit/test_selfcollision_guard.py)
