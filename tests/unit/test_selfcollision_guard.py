"""The supervisor's self-collision check (akarm.control.selfcollision): decimated, a stop only where the
command is clear, named and carrying the pair (lock step in tests/system/test_self_collision_lockstep.py)."""

from __future__ import annotations

import akarm
from akarm.control.selfcollision import SelfCollisionGuard
from akarm.dynamics.selfcollision import SelfCollision
from akarm.errors import SelfCollisionStop

from ..conftest import ROBOTS

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
READY = list(ARM6.pose("ready"))
FOLDED = [0.0, 0.3, 2.5, 0.0, 2.0, 0.0]  # capsules: the upper arm and the forearm overlap


def test_a_measured_collision_is_a_stop_every_fourth_cycle_at_480_hz_and_only_past_the_command() -> None:
    guard = SelfCollisionGuard(SelfCollision(ARM6, "capsules"), 480.0, 0.01)
    assert guard.every == 4
    seen = [guard.step(k / 480, FOLDED, READY) for k in range(8)]
    assert [s is not None for s in seen] == [False, False, False, True] * 2 and guard.checks == 2
    stop = seen[3]
    assert isinstance(stop, SelfCollisionStop) and isinstance(stop, akarm.SafetyStop)
    assert stop.pair == ("link2_0", "link4_0") and stop.q == tuple(FOLDED) and stop.at == 3 / 480
    assert "10 mm apart" in str(stop) and stop.fix
    # enabled folded: the command collides too, so it may move out
    assert all(guard.step(0.0, FOLDED, FOLDED) is None for _ in range(8))
    assert all(guard.step(0.0, READY, READY) is None for _ in range(8))
    assert SelfCollisionGuard(SelfCollision(ARM6, "capsules"), 50.0, 0.01).every == 1


def test_from_an_enable_a_contact_is_judged_only_once_the_arm_was_measured_clear() -> None:
    guard = SelfCollisionGuard(SelfCollision(ARM6, "capsules"), 480.0, 0.01)
    guard.disarm()  # enabled folded: moving out, the reading trails the command (clear already)
    assert all(guard.step(k / 480, FOLDED, READY) is None for k in range(8)) and not guard.armed
    assert all(guard.step(k / 480, READY, READY) is None for k in range(4)) and guard.armed
    assert any(isinstance(guard.step(k / 480, FOLDED, READY), SelfCollisionStop) for k in range(4))
