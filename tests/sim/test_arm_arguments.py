"""The Arm's boundary: a bad argument (the wrong type, NaN, out of its range) is an ArgumentError naming
it, raised before anything is sent or any mode changes; never a raw TypeError, a hang or a motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm import ArgumentError
from akarm.control.modes import Mode

NAN = math.nan


@pytest.mark.parametrize("timeout", [NAN, math.inf, -1.0, "x", True])
def test_enable_refuses_a_bad_timeout_before_the_mode_changes(lockstep, timeout) -> None:
    with lockstep("planar2") as (arm, sim):
        with pytest.raises(ArgumentError, match=r"enable timeout must be a finite number \(s\), at least 0, got") as e:
            arm.enable(timeout=timeout)
        assert e.value.fix and arm.mode is Mode.DISABLED
        arm.enable(timeout=0.5)  # nothing was left half-done: a good enable still works
        assert arm.enabled
        assert np.all(np.isfinite(arm.state().q))


SPEED = r"speed must be a finite number, at least 0.0001 and at most 1, got "


@pytest.mark.parametrize("speed", ["1", None, True, NAN, 0, 1e-300, 2.0])
def test_a_move_refuses_a_speed_that_is_not_a_fraction_of_the_limits(lockstep, speed) -> None:
    with lockstep("planar2", enable=True) as (arm, sim):
        q = arm.state().q_des.copy()
        for move in (lambda: arm.move_to("up", speed=speed), lambda: arm.stream_to("up", speed=speed),
                     lambda: arm.move_through(["up", "home"], speed=speed),
                     lambda: arm.move_to_pose(arm.tool_pose(), speed=speed)):
            with pytest.raises(ArgumentError, match=SPEED) as e:
                move()
            assert "fraction of the joint limits" in e.value.fix
        assert not arm.moving and np.array_equal(arm.state().q_des, q)


@pytest.mark.parametrize("seconds", ["1", None, -1.0, NAN, math.inf])
def test_sleep_refuses_what_is_not_a_finite_number_of_seconds(lockstep, seconds) -> None:
    with lockstep("planar2") as (arm, sim):
        t = arm.clock.now()
        with pytest.raises(ArgumentError, match=r"sleep seconds must be a finite number \(s\), at least 0, got "):
            arm.sleep(seconds)
        assert arm.clock.now() == t


def test_keyframes_replay_at_a_fraction_of_the_limits_as_the_docs_say(lockstep) -> None:
    """Keyframes were replayed at min(speed, 1): speed=5 silently as 1 (a path takes any factor > 0)."""
    from akarm.motion import recording as rec_mod

    with lockstep("planar2", enable=True) as (arm, sim):
        kf = rec_mod.Keyframes(arm.names, [rec_mod.Keyframe((0.0, 0.0)), rec_mod.Keyframe((0.3, 0.2))])
        for replay in (arm.check_replay, arm.replay):
            with pytest.raises(ArgumentError, match=r"keyframes are replayed at a fraction of the joint limits, in "
                                                    r"\(0, 1\]; got speed 5"):
                replay(kf, speed=5)
            with pytest.raises(ArgumentError, match=r"speed must be a finite number, more than 0, got 'x'"):
                replay(kf, speed="x")
        path = rec_mod.PathRecording(arm.names, np.linspace(0, 1, 11), np.zeros((11, 2)))
        assert arm.check_replay(path, speed=2.0) is path  # a path: its recorded timing, twice as fast
        with pytest.raises(ArgumentError, match=r"speed must be a finite number, more than 0, got inf"):
            arm.check_replay(path, speed=math.inf)
        assert not arm.moving


@pytest.mark.parametrize(("call", "message"), [
    (lambda arm: arm.set_collision(5), r"collision thresholds must be one per joint or a \{joint: N·m\} mapping, "
                                       r"not 5"),
    (lambda arm: arm.set_collision("ab"), r"collision thresholds must be one per joint"),
    (lambda arm: arm.follow(["a"], [[0.0, 0.0]]), r"the points' times must be numbers, got \['a'\]"),
    (lambda arm: arm.follow([1.0], [["a", 0.0]]), r"a timed trajectory needs points of 2 positions, got"),
    (lambda arm: arm.follow([1.0], [[0.0, 0.0]], velocities="ab"), r"velocities must be numbers, got 'ab'"),
    (lambda arm: arm.tool_pose("home"), r"tool_pose q must be one value per joint, not 'home'"),
    (lambda arm: arm.tool_pose([0.0]), r"tool_pose q has 1 values, the arm has 2 joints"),
    (lambda arm: arm.tool_pose([NAN, 0.0]), r"joint 'shoulder': tool_pose q must be a finite number \(rad\), got nan"),
    (lambda arm: arm.tool_pose([0.0, "x"]), r"joint 'elbow': tool_pose q must be a finite number \(rad\), got 'x'"),
    (lambda arm: arm.telemetry(since="x"), r"telemetry since must be a finite number \(s, clock time\), got 'x'"),
    (lambda arm: arm.telemetry(since=NAN), r"telemetry since must be a finite number"),
    (lambda arm: arm.set_gains(kp="10"), r"kp must be one value per joint, not '10'"),
    (lambda arm: arm.set_gains(kp=[1.0]), r"kp has 1 values, the arm has 2 joints"),  # (was one for both)
    (lambda arm: arm.set_gains(kd=True), r"kd must be one value per joint, not True"),
    (lambda arm: arm.set_gains(kp=NAN), r"kp must be a finite number \(N·m/rad\), at least 0, got nan"),
    (lambda arm: arm.set_payload("1"), r"payload mass must be a finite number \(kg\), at least 0, got '1'"),
    (lambda arm: arm.set_payload(True), r"payload mass must be a finite number \(kg\), at least 0, got True"),
    (lambda arm: arm.set_payload(1.0, "abc"), r"payload com must be 3 finite numbers \(m, tool frame\), got 'abc'"),
    (lambda arm: arm.set_payload(1.0, [0.0, NAN, 0.0]), r"payload com must be 3 finite numbers"),
    (lambda arm: arm.keyframe(5), r"a keyframe's name must be text or None, got 5"),
])
def test_arm_calls_refuse_bad_arguments_with_an_argument_error(lockstep, call, message) -> None:
    with lockstep("planar2", enable=True) as (arm, sim):
        thresholds = arm.collision_thresholds
        with pytest.raises(ArgumentError, match=message) as e:
            call(arm)
        assert e.value.fix and not arm.moving and arm.collision_thresholds == thresholds


@pytest.mark.parametrize(("coulomb", "viscous", "offset", "message"), [
    ([-0.1, 0.0], [0.0, 0.0], None, r"joint 'shoulder': coulomb friction must be a finite number \(N·m\), at least 0, "
                                     r"got -0.1"),
    ([0.1, 0.1], [0.0, -0.01], None, r"joint 'elbow': viscous friction must be a finite number \(N·m·s/rad\), at "
                                      r"least 0, got -0.01"),
    ([NAN, 0.0], [0.0, 0.0], None, r"joint 'shoulder': coulomb friction must be a finite number"),
    ("ab", [0.0, 0.0], None, r"coulomb friction must be one value per joint, not 'ab'"),
    ([0.1], [0.0, 0.0], None, r"coulomb friction has 1 values, the arm has 2 joints"),
    ([0.1, 0.1], [0.0, 0.0], [NAN, 0.0], r"joint 'shoulder': friction offset must be a finite number \(N·m\), got nan"),
])
def test_set_friction_refuses_what_the_robot_file_refuses(lockstep, coulomb, viscous, offset, message) -> None:
    with lockstep("planar2", enable=True) as (arm, sim):
        with pytest.raises(ArgumentError, match=message) as e:
            arm.set_friction(coulomb, viscous, offset)
        assert e.value.fix
        arm.set_friction([0.2, 0.1], [0.05, 0.02], [0.01, -0.01])  # a negative offset is a torque, not a friction
        arm.sleep(0.05)
        assert arm.enabled


@pytest.mark.parametrize(("options", "message"), [
    ({"telemetry_seconds": 1e12}, r"telemetry_seconds 1e\+12 is more than the telemetry ring holds: \d+ s of 2 joints "
                                  r"at 500 Hz"),
    ({"clock": "x"}, r"clock must be a clock \(now\(\), sleep_until\(t\), stepped\), got 'x'"),
    ({"timing": "bogus"}, r"no timing profile named 'bogus'"),
    ({"realtime_priority": "no"}, r"realtime_priority must be True or False, got 'no'"),
    ({"friction_feedforward": "no"}, r"friction_feedforward must be True or False, got 'no'"),
    ({"busy_wait": 1}, r"busy_wait must be True or False, got 1"),
    # (a stop that damps for ever never sends its exit frames)
    ({"stop_damping_time": 1e9}, r"stop_damping_time must be a finite number, at least 0 and at most 10 s, got "
                                 r"1000000000\.0"),
    ({"enable_ramp": 11.0}, r"enable_ramp must be a finite number, at least 0 and at most 10 s, got 11"),
    ({"range_margin": 100.0}, r"range_margin 100.0 must be a distance from 0 to 0.5 rad"),
    ({"loop_cpu": 9999}, r"loop_cpu must be a CPU number \(0-\d+ here\) or None, got 9999"),
    ({"loop_cpu": True}, r"loop_cpu must be a CPU number"),
])
def test_arm_options_of_the_wrong_kind_are_argument_errors(planar2, channel, options, message) -> None:
    from akarm import Arm

    with pytest.raises(ArgumentError, match=message) as e:
        Arm(planar2.with_bus(interface="virtual", channel=channel), **options)
    assert e.value.fix


def test_a_can_log_that_cannot_be_written_closes_the_buses_it_opened(planar2, channel, tmp_path) -> None:
    from akarm import Arm, RecordingError

    arm = Arm(planar2.with_bus(interface="virtual", channel=channel), can_log=tmp_path / "missing" / "x.log")
    with pytest.raises(RecordingError, match=r"cannot write the CAN log '.*/missing/x.log': .*No such file") as e:
        arm.open()
    assert "directory that exists" in e.value.fix
    assert arm.mode is Mode.CLOSED and dict(arm.observe.buses) == {}
    arm.close()
