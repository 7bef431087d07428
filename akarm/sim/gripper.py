"""The simulated gripper: its motor's output, the jaws it moves, and an object between them.

One degree of freedom, the motor's output angle past closed (rad, as
:class:`~akarm.config.GripperConfig` defines it): width ``w = width_at(angle)`` (a rack and pinion,
or the table's linkage). Its inertia is the rotor's reflected inertia plus the jaws' mass through
the transmission (``m · (dw/dangle)²``); friction as a joint's (the motor's
:class:`~akarm.sim.params.MotorSimParams`); hard stops at closed (0) and fully open (the jaws' own
end stops, stiff springs that only push).

An object (:meth:`SimGripper.place_object`) of width ``W`` (placed while the jaws are closer than
that, it goes between them once they open that wide) is a spring of ``stiffness`` N/m with
damping between the jaws: while ``w < W`` it pushes them apart with ``F = k·(W - w) - c·dw/dt``
(never pulling), which the motor feels as ``F · dw/dangle``. :attr:`SimGripper.object_force` is
that squeeze: the truth a test compares the controller's estimate with.

The step is the plant's (:mod:`akarm.sim.plant`): linearly implicit Euler with the stiff terms'
stiffness and damping, so a 20 kN/m object and the end stops stay stable at 2 kHz.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from akarm.errors import ArgumentError
from akarm.sim.params import MotorSimParams

if TYPE_CHECKING:
    from akarm.config import GripperConfig
    from akarm.sim.drivers import SimulatedDriver

__all__ = ["DEFAULT_OBJECT_STIFFNESS", "JAW_MASS", "SimGripper"]

#: N/m: an object's stiffness when none is given (a firm plastic part: 1 mm in at 20 N)
DEFAULT_OBJECT_STIFFNESS = 20_000.0
#: kg: both jaws and their rack, moving with the width
JAW_MASS = 0.1


class SimGripper:
    """The gripper's motor output, jaws and object (see the module's docstring).

    Attributes:
        angle: rad past closed. velocity: rad/s. torque: N·m the motor applies at its output (closing
        is negative). object_width: m, ``None`` without an object. object_force: N, the squeeze now.
    """

    def __init__(self, config: GripperConfig, params: MotorSimParams, dt: float) -> None:
        self.config = config
        self.params = params
        self.dt = dt
        self.angle = 0.5 * config.open_angle
        self.velocity = 0.0
        self.torque = 0.0
        self.object_width: float | None = None
        self.object_stiffness = DEFAULT_OBJECT_STIFFNESS
        self.object_damping = 0.0
        self.object_force = 0.0
        self.engaged = False  # the object is between the jaws (else: placed where they are closer than its width)
        self.inertia = config.motor.reflected_inertia + JAW_MASS * config.max_slope ** 2
        self._klim = params.limit_stiffness
        self._clim = 2.0 * math.sqrt(self._klim * self.inertia)
        self._driver: SimulatedDriver | None = None

    def attach(self, driver: SimulatedDriver) -> None:
        """The driver whose torque turns the output."""
        self._driver = driver

    @property
    def width(self) -> float:
        """m between the jaws now."""
        return self.config.width_at(self.angle)

    def motor_state(self) -> tuple[float, float]:
        """The motor side (position before the driver's zero, velocity), as :meth:`Plant.motor_state`."""
        c = self.config
        q = self.angle
        play = 0.5 * self.params.backlash
        if play:  # backlash (a varied unit): the encoder leads the output by half the play, as the torque turns
            q += play * math.tanh(self.torque / (0.05 * c.motor.t_max))
        return (q - c.offset) * c.direction, self.velocity * c.direction

    def set_width(self, width: float) -> None:
        """Put the jaws ``width`` m apart, at rest."""
        self.angle = self.config.angle_at(self.config.check_width(width))
        self.velocity = 0.0

    def place_object(self, width: float, stiffness: float = DEFAULT_OBJECT_STIFFNESS) -> None:
        """An object ``width`` m wide between the jaws (0 < width < stroke), ``stiffness`` N/m."""
        w = self.config.check_width(width)
        k = float(stiffness)
        if not (w > 0.0 and math.isfinite(k) and k > 0.0):
            raise ArgumentError(f"an object needs a width above 0 m and a positive stiffness, got {width!r} m, "
                                f"{stiffness!r} N/m", joint=self.config.name, fix="e.g. place_object(0.03)")
        self.object_width = w
        self.object_stiffness = k
        # critically damped against the jaws' mass seen at the width
        mass = self.inertia / self.config.max_slope ** 2
        self.object_damping = 2.0 * math.sqrt(k * mass)
        # jaws closer than its width: it goes between them once they open that wide
        self.engaged = self.width >= w

    def remove_object(self) -> None:
        self.object_width = None
        self.engaged = False
        self.object_force = 0.0

    def _motor(self, t: float, q: float, v: float) -> tuple[float, float, float, float]:
        """The motor's torque at the output now, its stiffness and damping (N·m, per rad, per rad/s), and
        the Coulomb friction it sees (with its load-dependent part), as the driver commands at ``t``."""
        drv = self._driver
        c = self.config
        p = self.params
        if drv is None:
            return 0.0, 0.0, 0.0, p.coulomb
        s = c.direction
        tm, k, d = drv.output(t, (q - c.offset) * s, v * s)
        cap = c.motor.t_max
        if tm > cap:
            tm, k, d = cap, 0.0, 0.0
        elif tm < -cap:
            tm, k, d = -cap, 0.0, 0.0
        drv.torque = tm
        cur = tm / drv.kt_out
        temp = drv.temperature
        drv.temperature = temp + self.dt / p.thermal_capacity * (
            cur * cur * p.resistance - (temp - p.ambient) / p.thermal_resistance)
        # a varied unit: the output gets torque_scale times what the motor reports; friction grows with the current
        scale = p.torque_scale
        return s * tm * scale, k * scale, d * scale, p.coulomb + p.coulomb_load * abs(cur)

    def step(self, t: float) -> None:
        """One step ``dt`` from time ``t``, with the driver's torque at ``t``."""
        c = self.config
        p = self.params
        dt = self.dt
        q, v = self.angle, self.velocity
        tau, k, d, coulomb = self._motor(t, q, v)
        self.torque = tau
        x = v / p.coulomb_eps
        th = math.tanh(x)
        tau -= p.viscous * v + coulomb * th
        d += p.viscous + (coulomb / p.coulomb_eps if -1e-9 < x < 1e-9 else coulomb * th / v)
        # the jaws' end stops: closed and fully open
        hi = c.open_angle
        if q < 0.0:
            f = self._klim * (0.0 - q) - self._clim * v
            if f > 0.0:
                tau += f
                k += self._klim
                d += self._clim
        elif q > hi:
            f = -self._klim * (q - hi) - self._clim * v
            if f < 0.0:
                tau += f
                k += self._klim
                d += self._clim
        # the object pushes the jaws apart while they press into it
        force = 0.0
        ow = self.object_width
        if ow is not None and not self.engaged and c.width_at(q) >= ow:
            self.engaged = True
        if ow is not None and self.engaged:
            w = c.width_at(q)
            slope = c.slope_at(q)
            if w < ow:
                force = self.object_stiffness * (ow - w) - self.object_damping * slope * v
                if force > 0.0:
                    tau += force * slope
                    k += self.object_stiffness * slope * slope
                    d += self.object_damping * slope * slope
                else:
                    force = 0.0
        self.object_force = force
        dv = dt * (tau - dt * k * v) / (self.inertia + dt * d + dt * dt * k)
        v += dv
        self.velocity = v
        self.angle = q + dt * v
