"""Timing profiles as a table: by name, what normal and slow change, every verb that runs a loop takes
--profile (in lock step: tests/sim/test_timing.py)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from akarm import AkarmError, load_robot
from akarm.cli import main
from akarm.timing import PROFILES, TimingProfile, get_profile

from .conftest import ROBOTS

PLANAR2 = ROBOTS / "planar2.yaml"
SERVO3 = ROBOTS / "servo3.yaml"


def test_profiles_by_name_and_a_clear_error_for_an_unknown_one() -> None:
    assert get_profile(None) is PROFILES["normal"] and get_profile("Slow") is PROFILES["slow"]
    own = TimingProfile("mine", "", 100.0, 0.1, 0.05, 1.0, 500.0)
    assert get_profile(own) is own
    with pytest.raises(AkarmError, match=r"no timing profile named 'fast' \(fix: use one of: normal \(.*\); slow \("):
        get_profile("fast")


def test_normal_changes_nothing() -> None:
    normal = PROFILES["normal"]
    assert (normal.max_rate_hz, normal.feedback_timeout, normal.min_feedback_timeout, normal.enable_timeout,
            normal.sim_rate_hz) == (None, 0.020, 0.0, 0.5, 2000.0)
    planar2, servo3 = load_robot(PLANAR2), load_robot(SERVO3)
    assert normal.apply(planar2) is planar2 and normal.apply(servo3) is servo3   # servo3's own 15 ms kept


def test_slow_caps_the_rate_and_floors_the_joints_own_watchdogs() -> None:
    slow = PROFILES["slow"]
    planar2, servo3 = load_robot(PLANAR2), load_robot(SERVO3)
    assert slow.apply(planar2).rate_hz == 25.0 and slow.apply(servo3).rate_hz == 25.0
    assert slow.apply(replace(planar2, rate_hz=20.0)).rate_hz == 20.0        # a slower file keeps its rate
    assert [j.feedback_timeout for j in slow.apply(servo3).joints] == [1.0] * 3   # 15 ms of its own: not here
    assert [j.feedback_timeout for j in slow.apply(planar2).joints] == [None, None]  # the Arm's default: 1 s
    longer = replace(planar2, joints=(replace(planar2.joints[0], feedback_timeout=2.0), planar2.joints[1]))
    assert slow.apply(longer).joints[0].feedback_timeout == 2.0


@pytest.mark.parametrize("verb", ["sim", "enable", "move", "replay", "teach", "demo", "bench", "serve"])
def test_every_verb_that_runs_a_loop_or_a_simulator_takes_the_profile(verb: str,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main([verb, "--help"])
    assert "--profile NAME" in capsys.readouterr().out
