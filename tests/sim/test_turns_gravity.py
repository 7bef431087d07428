"""Turn counts lost on joints gravity moves while limp (issue 39): found by the torque that holds the arm
at enable, before anything but holding is commanded. In lock step.

The arms rest where a limp arm comes to rest (tests/limp.py: on a hard stop, or where friction holds
what gravity asks); a driver power-cycled there reads whole rotor turns off. Nothing of the arm's
positions is remembered (``remember_positions=False``): the torque alone must tell.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from akarm.errors import TurnCountLost
from akarm.protocol import mit
from akarm.sim import faults

from ..limp import CASES, max_command_step, resting


@pytest.mark.parametrize(("robot", "joint"), [("planar2", "shoulder"), ("planar2", "elbow"), ("arm6", "elbow")])
def test_a_lost_turn_on_a_joint_gravity_moves_is_refused_before_any_motion_beyond_holding(
        channel: str, robot: str, joint: str) -> None:
    """(arm6 with its collision reflex on: the refusal is the turn check's, never a CollisionError. Its
    other loaded joints: tests/system/test_turns_gravity.py.)"""
    refused_before_any_motion_beyond_holding(robot, joint, channel)


def refused_before_any_motion_beyond_holding(robot: str, joint: str, channel: str) -> None:
    """k = ±1, ±2 on ``joint`` of ``robot`` resting limp: TurnCountLost naming it, the arm held where it
    stood meanwhile; then k = 0 enables."""
    with resting(robot, channel) as (arm, sim, q):
        for k in (1, -1, 2, -2):
            sim.set_state(q, np.zeros(len(q)))
            sim.inject(joint, faults.PowerCycle(turns=k, seconds=0.05))
            arm.sleep(0.1)
            sim.set_state(q, np.zeros(len(q)))  # (fallen back where it rests)
            since, peak = sim.logged_frames()[1], 0.0
            with pytest.raises(TurnCountLost) as e:
                arm.enable()
            assert e.value.joint == joint, (k, e.value)
            assert k == e.value.turns or k in e.value.alternatives, (k, e.value)
            # held where it stood, nothing else commanded; it gave by what the wrong weight asks of its kp
            # (the gravity feed-forward at the reading: up to 85 mrad here)
            assert max_command_step(sim, since) < 1e-3, k
            moved = float(np.max(np.abs(sim.q - q)))
            assert moved < 0.1, (k, moved)
            arm.sleep(0.05)  # lowered (the stop fades the torque that held it), disabled
            assert not arm.enabled and not any(d.enabled for d in sim.driver_states())
            peak = max(peak, moved)
            sim.inject(joint, faults.PowerCycle(turns=-k, seconds=0.05))  # (the count back: the next k)
            arm.sleep(0.1)
        sim.set_state(q, np.zeros(len(q)))
        arm.enable()  # k = 0 enables
        assert arm.enabled


def test_the_error_names_the_torques(channel: str) -> None:
    with resting("arm6", channel) as (arm, sim, q):
        sim.inject("elbow", faults.PowerCycle(turns=-1, seconds=0.05))
        arm.sleep(0.1)
        sim.set_state(q, np.zeros(len(q)))
        with pytest.raises(TurnCountLost) as e:
            arm.enable()
    err = e.value
    assert math.isnan(err.remembered) and err.turns == -1
    # what holds it is what gravity asks a turn back (within its friction band), not at the reading
    assert abs(err.explained - err.measured) < 0.72 and abs(err.expected - err.measured) > 2.0
    text = str(err)
    assert f"{err.measured:+.2f} N·m" in text and f"{err.expected:+.2f} N·m" in text and "-1 rotor turn" in text
    assert "--accept-position" in text


def test_a_reading_past_the_hard_stop_is_refused_before_any_torque(channel: str) -> None:
    """arm6's shoulder_lift rests on its stop (+1.75 rad): a turn more reads +2.38 rad, where it cannot
    stand; refused at contact, when only zero-gain, zero-torque commands went out."""
    with resting("arm6", channel) as (arm, sim, q):
        sim.inject("shoulder_lift", faults.PowerCycle(turns=1, seconds=0.05))
        arm.sleep(0.1)
        since = sim.logged_frames()[1]
        with pytest.raises(TurnCountLost) as e:
            arm.enable()
        assert e.value.joint == "shoulder_lift" and e.value.turns == 1 and "past its hard stop" in str(e.value)
        for cfg in sim.config.joints:
            codec = mit.codec(cfg.motor)
            for f in sim.logged_frames(since)[0]:
                if f.joint == cfg.name and f.to_motor and mit.special_frame(f.data) is None:
                    c = codec.decode_command(f.data)
                    assert c.kp == 0 and abs(c.torque) < 2 * cfg.motor.t_max / 4095


def test_accept_position_skips_the_check(channel: str) -> None:
    with resting("planar2", channel) as (arm, sim, q):
        sim.inject("shoulder", faults.PowerCycle(turns=1, seconds=0.05))
        arm.sleep(0.1)
        sim.set_state(q, np.zeros(len(q)))
        arm.enable(accept_position=True)
        assert arm.enabled


def test_a_joint_whose_torque_a_turn_does_not_change_is_said_to_be_unchecked(
        channel: str, caplog: pytest.LogCaptureFixture) -> None:
    """arm6's wrist_pitch with nothing at the tool: its whole weight (0.44 N·m at most) is within its
    friction band, so a turn cannot show in its torque: the enable passes and the log says so."""
    with resting("arm6", channel, mass=0.0) as (arm, sim, q), caplog.at_level(logging.WARNING, "akarm"):
        sim.inject("wrist_pitch", faults.PowerCycle(turns=1, seconds=0.05))
        arm.sleep(0.1)
        sim.set_state(q, np.zeros(len(q)))
        arm.enable()
    said = [r.getMessage() for r in caplog.records if "turn check" in r.getMessage()]
    assert said and "wrist_pitch" in said[0] and "does not tell a lost rotor turn" in said[0], said


def test_held_by_its_weight_the_arm_enables_without_a_kick(channel: str) -> None:
    """k = 0, at rest limp: its weight is carried where it stands, nothing moves."""
    for robot in CASES:
        with resting(robot, f"{channel}-{robot}") as (arm, sim, q):
            arm.enable()
            assert float(np.max(np.abs(sim.q - q))) < 5e-3
            assert arm.enabled

