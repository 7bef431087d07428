"""Self-collision (``Arm(self_collision=...)``): shapes from the URDF or capsules, neighbours left out,
a planned move that folds the arm into itself refused with nothing moving, servoing stopping short.

Lock step on arm6. Its URDF has visuals and no <collision> shapes: "auto" takes the visuals; their thin
tubes come no closer than 23 mm within the joint ranges, so a margin (or capsules) makes a fold collide.
"""

from __future__ import annotations

import numpy as np
import pytest

import akarm
from akarm.dynamics.selfcollision import SelfCollision
from akarm.errors import ArgumentError, LimitError

from ..conftest import ROBOTS, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = np.array(ARM6.pose("ready"))
FOLDED = np.array([0.0, 0.3, 2.5, 0.0, 2.0, 0.0])  # the elbow folded to its limit, the wrist folded back


def test_shapes_come_from_the_urdf_else_capsules_and_neighbours_are_left_out() -> None:
    visual = SelfCollision(ARM6)
    assert visual.source == "visual"
    assert not visual.colliding(READY) and not visual.colliding(FOLDED)
    joints = {name.rsplit("_", 1)[0] for pair in visual.pairs for name in pair}
    assert "upper_arm" in joints and ("upper_arm_0", "upper_arm_1") not in visual.pairs
    padded = SelfCollision(ARM6, margin=0.025)
    assert ("upper_arm_0", "forearm_tube_0") in padded.colliding(FOLDED)
    capsules = SelfCollision(ARM6, "capsules")
    assert capsules.colliding(FOLDED) == [("link2_0", "link4_0")]  # the upper arm and the forearm
    assert not capsules.colliding(READY)
    with pytest.raises(ArgumentError):
        SelfCollision(ARM6, "meshes")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError):
        SelfCollision(ARM6, margin=-0.01)


@pytest.mark.parametrize(("source", "margin"), [("capsules", 0.0), ("auto", 0.025)])
def test_folding_the_wrist_into_the_upper_arm_is_refused_with_nothing_moving(channel: str, source: str,
                                                                             margin: float) -> None:
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
    with lockstep_arm(ARM6, channel, q0=start, enable=True, self_collision="capsules") as (arm, sim):
        with arm.servo(timeout=0.1, frame="tool") as s:
            end = arm.clock.now() + 2.0
            while arm.clock.now() < end:
                s.twist([0.0, 0.0, 0.0, 0.0, -0.8, 0.0])  # pitch the tool back: the elbow folds on
                arm.sleep(0.01)
            reason = s.status.reason
        assert not arm.self_collision.colliding(sim.q)
        assert reason in ("collision", "joint limit")
        assert arm.fault is None
