"""Conversions between joint-side SI units and a motor's own units.

Used by both sides of the wire: the controller's joints and the simulator's drivers, so the two can
never disagree. ``joint = direction * motor + offset`` for positions; velocities and torques scale
by ``direction`` only. Servo-mode units: degrees (at the output or at the rotor, per the catalogue's
``servo_position``), ERPM (rotor RPM × pole pairs), amps of Iq.
"""

from __future__ import annotations

import math

from akarm.protocol.motors import MotorModel

__all__ = [
    "amps_to_torque",
    "erpm_to_rad_s",
    "rad_s_to_erpm",
    "rad_to_servo_deg",
    "servo_deg_to_rad",
    "torque_to_amps",
]

_RAD_PER_DEG = math.pi / 180.0


def rad_s_to_erpm(motor: MotorModel, omega: float) -> float:
    """Output-shaft speed (rad/s) to electrical RPM at the rotor."""
    return omega * 60.0 / (2.0 * math.pi) * motor.gear_ratio * motor.pole_pairs


def erpm_to_rad_s(motor: MotorModel, erpm: float) -> float:
    """Electrical RPM at the rotor to output-shaft speed (rad/s)."""
    return erpm * 2.0 * math.pi / (60.0 * motor.pole_pairs * motor.gear_ratio)


def rad_to_servo_deg(motor: MotorModel, angle: float) -> float:
    """Output-shaft angle (rad) to the degrees the servo firmware uses (output or rotor side)."""
    deg = angle / _RAD_PER_DEG
    return deg * motor.gear_ratio if motor.servo_position == "rotor" else deg


def servo_deg_to_rad(motor: MotorModel, deg: float) -> float:
    """Servo-firmware degrees (output or rotor side) to output-shaft angle (rad)."""
    if motor.servo_position == "rotor":
        deg = deg / motor.gear_ratio
    return deg * _RAD_PER_DEG


def _output_kt(motor: MotorModel) -> float:
    kt = motor.output_kt
    if kt is None:
        from akarm.errors import ConfigError, ConfigProblem

        raise ConfigError([ConfigProblem("<motors>", None, f"motor {motor.name!r} has no torque constant kt",
                                         "set kt (N·m/A at the rotor) for it under `motors:`")])
    return kt


def torque_to_amps(motor: MotorModel, torque: float) -> float:
    """Output torque (N·m) to Iq (A): ``τ / (kt · gear_ratio)``."""
    return torque / _output_kt(motor)


def amps_to_torque(motor: MotorModel, amps: float) -> float:
    """Iq (A) to output torque (N·m): ``I · kt · gear_ratio``."""
    return amps * _output_kt(motor)
