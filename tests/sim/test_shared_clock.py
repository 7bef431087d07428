"""Two arms in one process in lock step: one stepped clock drives both simulators and both loops."""

from __future__ import annotations

import numpy as np
import pytest

from akarm.clock import SteppedClock
from akarm.errors import StateError
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, lockstep_arm


def test_two_arms_on_one_clock_both_run_every_cycle_whichever_is_waited_on(channel: str) -> None:
    clock = SteppedClock()
    with lockstep_arm("planar2", channel + "-a", clock=clock, q0=[-0.5, 0.2], enable=True) as (a, sim_a), \
            lockstep_arm("planar2", channel + "-b", clock=clock, q0=[-0.4, 0.1], enable=True) as (b, sim_b):
        assert a.clock is b.clock is clock
        t = clock.now()
        a.move_to([-0.2, 0.4], wait=False)
        b.move_to([-0.1, 0.3], wait=False)
        a.sleep(1.5)                      # only a is waited on: b moves all the same, on its own cycles
        assert sim_a.t == sim_b.t == pytest.approx(clock.now())
        la, lb = a.telemetry(since=t), b.telemetry(since=t)
        assert np.diff(la.t) == pytest.approx(np.full(len(la) - 1, 0.002))  # every cycle, none missed
        assert np.diff(lb.t) == pytest.approx(np.full(len(lb) - 1, 0.002))
        assert a.stats().missed == b.stats().missed == 0
        np.testing.assert_allclose(b.state().q, [-0.1, 0.3], atol=2e-3)
        np.testing.assert_allclose(a.state().q, [-0.2, 0.4], atol=2e-3)


def test_a_simulator_joining_a_clock_starts_at_its_time_and_leaves_it_when_closed(channel: str) -> None:
    from akarm.robotfile.load import load_robot

    clock = SteppedClock(1.0)
    config = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False, clock=clock) as sim:
        assert sim.clock is clock and sim.t == pytest.approx(1.0)
        clock.sleep_until(1.5)
        assert sim.t == pytest.approx(1.5)
    clock.sleep_until(2.0)                # closed: it left the clock (no error from its closed buses)
    assert sim.t == pytest.approx(1.5)
    with pytest.raises(StateError, match="real time"):
        SimulatedRobot(config, clock=clock)
