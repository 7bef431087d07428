"""Joint ⇄ motor unit conversions, against hand-computed values."""

from __future__ import annotations

import math

import pytest

from akarm import ConfigError
from akarm.protocol import motors, units
from akarm.protocol.motors import Catalogue


def test_erpm_of_the_output_speed() -> None:
    m = motors.get("AK80-9")  # 9:1, 21 pole pairs
    # 1 rad/s at the output = 9 rad/s at the rotor = 85.944 RPM; × 21 pole pairs = 1804.8 ERPM
    assert units.rad_s_to_erpm(m, 1.0) == pytest.approx(60 / (2 * math.pi) * 9 * 21, rel=1e-12)
    assert units.rad_s_to_erpm(m, 1.0) == pytest.approx(1804.817, abs=1e-3)
    assert units.erpm_to_rad_s(m, 1804.817) == pytest.approx(1.0, abs=1e-6)
    assert units.erpm_to_rad_s(m, -units.rad_s_to_erpm(m, 2.5)) == pytest.approx(-2.5)


def test_servo_degrees_at_output_or_rotor() -> None:
    out = motors.get("AK70-10")
    assert out.servo_position == "output"
    assert units.rad_to_servo_deg(out, math.pi / 2) == pytest.approx(90.0)
    rotor = motors.default_catalogue().extended({"R": {"base": "AK70-10", "servo_position": "rotor"}}, "t").get("R")
    assert units.rad_to_servo_deg(rotor, math.pi / 2) == pytest.approx(900.0)  # 10:1 gear
    assert units.servo_deg_to_rad(rotor, 900.0) == pytest.approx(math.pi / 2)


def test_current_and_torque_through_kt_and_gear() -> None:
    m = motors.get("AK80-9")  # kt 0.091 N·m/A at the rotor, 9:1
    assert units.amps_to_torque(m, 10.0) == pytest.approx(10 * 0.091 * 9)
    assert units.torque_to_amps(m, 8.19) == pytest.approx(10.0)
    bare = Catalogue().extended({"B": {"p_max": 12.5, "v_max": 10, "t_max": 5, "gear_ratio": 3,
                                       "pole_pairs": 7}}, "t").get("B")
    with pytest.raises(ConfigError, match="has no torque constant kt"):
        units.torque_to_amps(bare, 1.0)
