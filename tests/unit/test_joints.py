"""The controller's joints: unit conversion and turn counting on MIT replies."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from akarm import load_robot
from akarm.control.joints import MitJoint, ServoJoint, make_joint

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


@pytest.mark.parametrize("direction, offset", [(1, 0.0), (-1, 0.3)])
def test_replies_across_the_p_max_wrap_count_turns(direction: int, offset: float) -> None:
    cfg = load_robot(ROBOTS / "planar2.yaml").joints[0]
    joint = make_joint(0, replace(cfg, direction=direction, offset=offset))
    assert isinstance(joint, MitJoint)
    p_max = joint.motor.p_max
    # the motor turns forward through +P_MAX and on past 3 P_MAX, then back past -P_MAX, a rad per
    # reply: the 16-bit field wraps four times, and the joint must count each
    motor = [*np.arange(p_max - 0.5, 3 * p_max + 0.6, 1.0), *np.arange(3 * p_max, -p_max - 1.6, -1.0)]
    for k, m in enumerate(motor):
        wrapped = (m + p_max) % (2 * p_max) - p_max  # what the 16-bit field can carry
        data = joint.codec.encode_reply(cfg.can_id, wrapped, 1.5, -2.0, 40.0, 0)
        joint.handle_reply(data, now=0.01 * k)
        step = 2 * p_max / 65535  # the field's resolution
        assert joint.state.position == pytest.approx(direction * m + offset, abs=step)
    s = joint.state
    assert s.velocity == pytest.approx(direction * 1.5, abs=0.01)
    assert s.torque == pytest.approx(direction * -2.0, abs=0.02)
    assert s.temperature == pytest.approx(40.0) and s.error == 0 and s.stamp == pytest.approx(0.01 * (len(motor) - 1))
    assert joint.frames_received == len(motor) and not math.isnan(s.position)


@pytest.mark.parametrize("direction", [1, -1])
def test_servo_current_frame_is_the_torque_through_kt(direction: int) -> None:
    """The servo-mode gripper's frame: SET_CURRENT (packet 1, int32 mA), ``τ / (kt · GR)`` on the motor side."""
    g = load_robot(ROBOTS / "arm6g.yaml").gripper
    assert g is not None
    joint = make_joint(7, replace(g, mode="servo", direction=direction).joint)
    assert isinstance(joint, ServoJoint)
    amps = -0.8 / (g.motor.kt * g.motor.gear_ratio)  # 0.8 N·m closing: 20 N at 40 mm/rad
    aid, extended, data = joint.current_frame(-0.8)
    assert (aid, extended) == ((1 << 8) | g.can_id, True)
    assert data == round(direction * amps * 1000).to_bytes(4, "big", signed=True)
    assert data.hex() == ("fffffa6b" if direction == 1 else "00000595")  # -1429 mA, +1429 mA
