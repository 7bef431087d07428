"""A leader and a follower in lock step on one clock, and a hand that pushes the leader: the rig of
the teleoperation tests (tests/system/test_teleop_lockstep.py, tests/system/test_teleop.py)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm.clock import SteppedClock

from .conftest import lockstep_arm

if TYPE_CHECKING:
    from akarm.arm import Arm
    from akarm.config import RobotConfig
    from akarm.sim import SimulatedRobot
    from akarm.teleop import Step, Teleop


@contextmanager
def leader_follower(channel: str, robot: str = "planar2", *, leader_q0: Any = None, follower_q0: Any = None,
                    follower_edit: Callable[[RobotConfig], RobotConfig] | None = None, same_bus: bool = False,
                    follower_sim: Mapping[str, Any] | None = None,
                    **arm_options: Any) -> Iterator[tuple[Arm, SimulatedRobot, Arm, SimulatedRobot]]:
    """Two simulated arms of ``robot``, enabled, on one stepped clock: (leader, its sim, follower, its sim).
    ``same_bus``: both on one channel (the follower's CAN IDs moved up by 8)."""
    clock = SteppedClock()

    def moved_ids(config: RobotConfig) -> RobotConfig:
        from dataclasses import replace

        config = replace(config, joints=tuple(replace(j, can_id=j.can_id + 8) for j in config.joints))
        return follower_edit(config) if follower_edit is not None else config

    with ExitStack() as stack:
        leader, leader_sim = stack.enter_context(lockstep_arm(robot, channel + "-leader", clock=clock, q0=leader_q0,
                                                              enable=True, **arm_options))
        follower, follower_sim_ = stack.enter_context(lockstep_arm(
            robot, channel + ("-leader" if same_bus else "-follower"), clock=clock, q0=follower_q0, enable=True,
            config_edit=moved_ids if same_bus else follower_edit, sim_options=follower_sim, **arm_options))
        yield leader, leader_sim, follower, follower_sim_


def smooth(q0: Any, amplitude: Any, frequency: float, start: float = 0.0) -> Callable[[float], np.ndarray]:
    """A hand's path from rest at ``q0``: ``q0 + amplitude · (1 − cos 2πf(t − start)) / 2`` (peak speed
    ``π·f·amplitude``), still before ``start``."""
    q0, amplitude = np.asarray(q0, dtype=float), np.asarray(amplitude, dtype=float)
    return lambda t: q0 + amplitude * 0.5 * (1.0 - math.cos(2.0 * math.pi * frequency * max(0.0, t - start)))


class Hand:
    """A hand on the leader: a spring and damper pulling it along ``path(t)`` through the simulator's
    external torque (N·m per joint), as a person guiding it would."""

    def __init__(self, sim: SimulatedRobot, path: Callable[[float], np.ndarray], stiffness: float = 60.0,
                 damping: float = 4.0) -> None:
        self.sim, self.path, self.k, self.d = sim, path, stiffness, damping

    def push(self, t: float) -> None:
        self.sim.set_external_torque(self.k * (self.path(t) - self.sim.q) - self.d * self.sim.dq)


def run(tele: Teleop, seconds: float, hand: Hand | None = None) -> list[Step]:
    """Step the session ``seconds`` of simulated time, the hand pushing before each step; the steps."""
    clock = tele.follower.clock
    t0 = clock.now()
    steps = []
    while clock.now() - t0 < seconds - 1e-9:
        if hand is not None:
            hand.push(clock.now())
        steps.append(tele.step())
    return steps
