"""Physical parameters of a simulated actuator that the motor catalogue does not carry.

Friction, winding resistance, thermal constants and supply voltage are not in the CubeMars data
sheets the catalogue is built from; :func:`default_params` derives plausible values from what the
catalogue does give (torque range, rated current, mass). Override any of them per joint with
``SimulatedRobot(config, params={"elbow": MotorSimParams(...)})`` or ``dataclasses.replace``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from akarm.protocol.motors import MotorModel

__all__ = ["MotorSimParams", "default_params"]


@dataclass(frozen=True)
class MotorSimParams:
    """Simulation constants of one actuator (SI units, at the output shaft unless said otherwise).

    Attributes:
        viscous: viscous friction, N·m·s/rad.
        coulomb: Coulomb (dry) friction, N·m; applied smoothly as ``coulomb · tanh(v / coulomb_eps)``.
        coulomb_eps: rad/s, the speed over which the smooth Coulomb term reaches 76 % of its value.
        resistance: winding resistance seen by Iq, Ω (copper loss I²R; the duty mode's DC model).
        bus_voltage: supply voltage, V (servo duty mode).
        thermal_capacity: heat capacity of the winding and stator, J/K.
        thermal_resistance: winding to ambient, K/W.
        ambient: ambient temperature, °C (also the temperature at start).
        limit_stiffness: N·m/rad of the hard stop past the URDF limits.
        torque_scale: the torque the joint gets per N·m the motor reports (a real unit's torque
            constant and gearbox: :class:`~akarm.sim.variation.Variation`); 1: the catalogue's.
        coulomb_load: N·m of Coulomb friction more per A of Iq (the load-dependent part).
        backlash: rad of play between the motor's encoder and the link.
        reply_jitter: s, the most each reply is delayed at random (uniformly, 0 to this).
    """

    viscous: float
    coulomb: float
    coulomb_eps: float
    resistance: float
    bus_voltage: float
    thermal_capacity: float
    thermal_resistance: float
    ambient: float
    limit_stiffness: float
    torque_scale: float = 1.0
    coulomb_load: float = 0.0
    backlash: float = 0.0
    reply_jitter: float = 0.0


def default_params(motor: MotorModel) -> MotorSimParams:
    """Plausible constants for ``motor`` (the catalogue's figures scaled; see the code for each rule).

    - friction: Coulomb 2 % of the MIT torque range (AK80-9: 0.36 N·m, about what backdriving one
      takes), viscous 0.2 % of it per rad/s (AK80-9: 0.036 N·m·s/rad), smoothed over 0.02 rad/s;
    - resistance: such that the rated current held forever warms the winding 50 K over ambient
      with 1.5 K/W to ambient, to 75 °C: rated is what a motor holds for good, below the default
      80 °C limit (AK80-9: 0.28 Ω; 0.3 Ω when the rated current is unknown);
    - heat capacity: 200 J/(kg·K) of the actuator's mass (AK80-9: 97 J/K, a time constant of
      about 2.5 min), 100 J/K when the mass is unknown;
    - supply 24 V, ambient 25 °C, hard stop 100 · t_max N·m/rad (the full torque presses 10 mrad in).
    """
    r_th = 1.5
    rated = motor.rated_current
    resistance = 50.0 / (r_th * rated * rated) if rated else 0.3
    capacity = 200.0 * motor.mass if motor.mass else 100.0
    return MotorSimParams(
        viscous=0.002 * motor.t_max,
        coulomb=0.02 * motor.t_max,
        coulomb_eps=0.02,
        resistance=resistance,
        bus_voltage=24.0,
        thermal_capacity=capacity,
        thermal_resistance=r_th,
        ambient=25.0,
        limit_stiffness=100.0 * motor.t_max,
    )
