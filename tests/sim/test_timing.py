"""Timing profiles (akarm.timing): what normal keeps and what slow changes, in the Arm, the simulator
and the verbs. In lock step, so the watchdog's and the enable's limits show exactly."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from akarm import AkarmError, Arm, FeedbackTimeout, load_robot
from akarm.cli import main
from akarm.sim import SimulatedRobot, faults
from akarm.telemetry.log import load as load_telemetry
from akarm.timing import PROFILES, TimingProfile, get_profile

from .conftest import ROBOTS

PLANAR2 = ROBOTS / "planar2.yaml"
SERVO3 = ROBOTS / "servo3.yaml"
HANGING = [-math.pi / 2, 0.0]


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


@pytest.mark.parametrize(("robot", "joint", "profile", "options", "limit_ms"), [
    (PLANAR2, "elbow", "normal", {}, 20), (PLANAR2, "elbow", "slow", {}, 1000),
    (SERVO3, "pan", "normal", {}, 15), (SERVO3, "pan", "slow", {}, 1000),         # the file's own 15 ms
    (PLANAR2, "elbow", "normal", {"feedback_timeout": 0.1}, 100),
    (PLANAR2, "elbow", "slow", {"feedback_timeout": 0.1}, 1000),                  # not below the profile's
], ids=["planar2-normal", "planar2-slow", "servo3-normal", "servo3-slow", "arg-normal", "arg-slow"])
def test_the_watchdog_of_each_profile_stops_the_arm_at_its_limit(channel: str, robot: Path, joint: str, profile: str,
                                                                  options: dict, limit_ms: int) -> None:
    config = load_robot(robot).with_bus(interface="virtual", channel=channel)
    q0 = HANGING if robot == PLANAR2 else None
    with SimulatedRobot(config, realtime=False, q0=q0, timing=profile) as sim, \
            Arm(config, clock=sim.clock, timing=profile, **options) as arm:
        assert arm.timing is PROFILES[profile]
        assert arm.config.rate_hz == (config.rate_hz if profile == "normal" else 25.0)
        arm.enable()
        sim.inject(joint, faults.Unplugged())
        t0 = arm.clock.now()
        with pytest.raises(FeedbackTimeout, match=f"{joint}.*limit {limit_ms} ms") as stop:
            arm.sleep(3.0)
        assert limit_ms / 1e3 < stop.value.age <= limit_ms / 1e3 + 2.0 / arm.config.rate_hz
        assert arm.clock.now() - t0 < limit_ms / 1e3 + 0.3 + 0.1               # then the 0.3 s stop


@pytest.mark.parametrize(("profile", "wait_ms"), [("normal", 500), ("slow", 5000)])
def test_enable_waits_for_the_first_answers_as_long_as_the_profile_says(channel: str, profile: str,
                                                                          wait_ms: int) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False, q0=HANGING) as sim, Arm(config, clock=sim.clock, timing=profile) as arm:
        sim.inject("shoulder", faults.Unplugged())
        with pytest.raises(FeedbackTimeout, match=f"no answer within {wait_ms} ms from: shoulder"):
            arm.enable()
        assert not sim.joint("elbow").enabled                 # nothing was enabled


def test_the_slow_profile_still_tracks(channel: str) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=False, q0=HANGING, timing="slow") as sim, \
            Arm(config, clock=sim.clock, timing="slow") as arm:
        assert sim.dt == pytest.approx(1 / 250)
        arm.enable()
        arm.move_to("up")
        arm.sleep(0.5)
        assert np.allclose(sim.q, config.pose("up"), atol=5e-3)
        log = arm.telemetry()
        assert np.diff(log.t).max() == pytest.approx(0.04)   # 25 Hz


def test_the_simulator_integrates_at_the_profiles_rate_unless_told(channel: str) -> None:
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    assert SimulatedRobot(config, realtime=False).dt == pytest.approx(0.0005)
    assert SimulatedRobot(config, realtime=False, timing="slow").dt == pytest.approx(0.004)
    assert SimulatedRobot(config, realtime=False, timing="slow", dt=0.001).dt == pytest.approx(0.001)


def test_akarm_sim_takes_the_profile(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", str(PLANAR2), "-i", "virtual", "-c", channel, "--seconds", "0.2", "-q",
                 "--profile", "slow"]) == 0
    assert "integrating at 250 Hz (timing profile slow)" in capsys.readouterr().out
    assert main(["sim", str(PLANAR2), "-i", "virtual", "-c", channel, "--seconds", "0.2", "-q",
                 "--profile", "slow", "--plant-rate", "1000"]) == 0
    assert "integrating at 1000 Hz (timing profile slow)" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main(["sim", str(PLANAR2), "--profile", "fast"])
    assert e.value.code == 2
    assert "invalid choice: 'fast'" in capsys.readouterr().err


@pytest.mark.parametrize("verb", ["sim", "enable", "move", "replay", "teach", "demo", "bench", "serve"])
def test_every_verb_that_runs_a_loop_or_a_simulator_takes_the_profile(verb: str,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main([verb, "--help"])
    assert "--profile NAME" in capsys.readouterr().out


def test_akarm_move_with_the_slow_profile_runs_its_loop_at_25_hz(channel: str, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "move.csv"
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=True, q0=HANGING, timing="slow"):
        code = main(["move", str(PLANAR2), "-i", "virtual", "-c", channel, "down", "--speed", "0.5",
                     "--profile", "slow", "--log", str(log)])
    assert code == 0, capsys.readouterr().err
    assert "arrived:" in capsys.readouterr().out
    t = load_telemetry(log).t
    assert np.median(np.diff(t)) == pytest.approx(0.04, rel=0.05)


def test_akarm_teach_with_the_slow_profile_samples_at_the_loop_rate(channel: str, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    from akarm.motion.recording import load_path

    out = tmp_path / "path.csv"
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    r, w = os.pipe()                                   # stdin that stays open: --seconds ends it
    with os.fdopen(r) as stdin, os.fdopen(w, "w"):
        monkeypatch.setattr("sys.stdin", stdin)
        with SimulatedRobot(config, realtime=True, q0=HANGING, timing="slow"):
            assert main(["teach", str(PLANAR2), "-i", "virtual", "-c", channel, str(out), "--seconds", "1",
                         "--profile", "slow"]) == 0
    # 50 samples a second by default, but at most half the loop's 25
    assert np.diff(load_path(out, ("shoulder", "elbow")).t).mean() == pytest.approx(0.08, rel=0.05)


@pytest.mark.parametrize(("lag", "stops"), [(0.25, False), (0.0, True)])
def test_the_slow_profiles_lag_lets_a_late_simulator_run_a_fast_move(channel: str, lag: float, stops: bool) -> None:
    """Replies 0.15 s late read as a joint still at rest while its command is under way (planar2's shoulder:
    stuck travel 27 mrad), then as one up to 0.6 rad behind at 4 rad/s (following-error limit 18 N·m /
    40 N·m/rad = 0.45 rad); the profile's lag (0.25 s × 4 rad/s) widens both."""
    from akarm import TrackingError

    profile = replace(PROFILES["slow"], lag=lag)
    config = load_robot(PLANAR2).with_bus(interface="virtual", channel=channel)
    late = {name: faults.DelayReplies(0.15) for name in config.joint_names}
    with SimulatedRobot(config, realtime=False, q0=HANGING, timing=profile, faults=late) as sim, \
            Arm(config, clock=sim.clock, timing=profile) as arm:
        arm.enable()
        if stops:
            with pytest.raises(TrackingError, match="shoulder"):
                arm.move_to("up")
        else:
            arm.move_to("up")
            arm.sleep(1.0)
            assert np.allclose(sim.q, config.pose("up"), atol=0.01)
