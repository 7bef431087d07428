"""A simulated arm that is a real unit, not the datasheet: per joint and per seed, its truth differs
from the robot file within spreads measured on real AK motors (../shared/docs/ak-protocol.md §6).

Without a variation the simulator computes exactly what the controller assumes (the same masses, torque
constant and friction law), so a test against it proves only that the code agrees with itself.
``SimulatedRobot(config, variation=Variation(seed=7))`` draws, per joint (deterministically from the
seed and the joint's index):

=====================  =======================================  ==========================================
quantity               spread                                   where it comes from
=====================  =======================================  ==========================================
torque constant        × 0.7-1.3 (uniform)                      two AK40-10 units measured 30 % apart
true / reported        × 0.7-1.0 (uniform)                      TMotorCANControl's AK80-9: true ≈ 0.75 ×
torque                                                          the reply's torque
Coulomb friction       × 0.5-2 (log-uniform) of the simulator's  dfki AK80-6: 0.09-0.19 N·m
                       default, plus 0-6 % of the load torque   AK80-9 with a load cell: 0.27 N·m +
                       (``coulomb_load``, N·m per A of Iq)       0.049 N·m/A (6 % of its 0.82 N·m/A)
viscous friction       × 0.5-2 (log-uniform)
backlash               0-5 mrad (uniform)                       gearbox play
link masses, CoMs      × 0.8-1.2 each (uniform), per link       URDF masses are estimates
reply delay jitter     0-1 ms per reply (uniform)               USB adapters, busy drivers
=====================  =======================================  ==========================================

The firmware turns the commanded torque into a current with the catalogue's torque constant and
reports the current times that constant; the joint then gets ``torque_scale`` = (torque constant
factor × true/reported) times the torque the motor reports. Friction's load-dependent part grows with
the current ``|τ_reported| / (kt · gear ratio)``. Backlash: the motor's encoder leads the link by half the
play in the direction of the motor's torque. ``Variation()`` (no seed) is the nominal model, and so is
``SimulatedRobot(config)``; the keywords set one quantity for every joint instead of drawing it
(``Variation(friction=2.0)``: twice the catalogue's friction, the rest nominal).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from akarm.errors import ArgumentError
from akarm.sim.params import MotorSimParams

if TYPE_CHECKING:
    from akarm.config import JointConfig, RobotConfig

__all__ = ["SPREADS", "JointTruth", "LinkTruth", "Truth", "Variation", "kt_out"]

#: The spreads a seeded :class:`Variation` draws from (low, high), see the module's docstring.
SPREADS: dict[str, tuple[float, float]] = {
    "kt": (0.7, 1.3),
    "true_over_reported": (0.7, 1.0),
    "coulomb": (0.5, 2.0),
    "coulomb_load_share": (0.0, 0.06),
    "viscous": (0.5, 2.0),
    "backlash": (0.0, 0.005),
    "link_mass": (0.8, 1.2),
    "link_com": (0.8, 1.2),
    "reply_jitter": (0.0, 0.001),
}


@dataclass(frozen=True)
class JointTruth:
    """What one joint of a varied unit really is (SI).

    Attributes:
        name: the joint.
        kt: its torque constant over the catalogue's.
        true_over_reported: the torque at the output over the torque the motor's current makes.
        torque_scale: ``kt · true_over_reported``: the torque the joint gets per N·m the motor reports.
        coulomb: Coulomb friction at no load, N·m. coulomb_load: N·m more per A of Iq.
        viscous: N·m·s/rad. backlash: rad of play. reply_jitter: s, the most a reply is delayed.
    """

    name: str
    kt: float
    true_over_reported: float
    torque_scale: float
    coulomb: float
    coulomb_load: float
    viscous: float
    backlash: float
    reply_jitter: float


@dataclass(frozen=True)
class LinkTruth:
    """A link's mass and centre of mass as factors of the URDF's (the body a joint moves)."""

    name: str
    mass: float
    com: float


@dataclass(frozen=True)
class Truth:
    """What a :class:`Variation` drew for one robot: per joint and per link (config order), and for the
    gripper's motor (``None`` without a gripper): its torque constant, friction, backlash and jitter vary
    as a joint's do."""

    seed: int | None
    joints: tuple[JointTruth, ...]
    links: tuple[LinkTruth, ...]
    gripper: JointTruth | None = None

    def joint(self, name: str) -> JointTruth:
        for j in self.joints:
            if j.name == name:
                return j
        raise ArgumentError(f"no joint {name!r} in this truth", fix="joints are: " + ", ".join(
            j.name for j in self.joints))


def _factor(x: float | None, what: str) -> float | None:
    if x is None:
        return None
    if not (isinstance(x, int | float) and x > 0 and math.isfinite(x)):
        raise ArgumentError(f"Variation's {what} must be a positive number (a factor), got {x!r}")
    return float(x)


@dataclass(frozen=True)
class Variation:
    """A real unit's deviations from its robot file (see the module's docstring).

    Args:
        seed: draw every quantity within :data:`SPREADS` from this seed; ``None``: the nominal model.
        friction: a factor on every joint's Coulomb and viscous friction instead of the drawn ones.
        torque_scale: every joint's torque per N·m reported, instead of the drawn one.
        masses: a factor on every link's mass instead of the drawn ones.
    """

    seed: int | None = None
    friction: float | None = None
    torque_scale: float | None = None
    masses: float | None = None
    _truth: Truth | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.seed is not None and (isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0):
            raise ArgumentError(f"Variation's seed must be a whole number ≥ 0, got {self.seed!r}")
        _factor(self.friction, "friction")
        _factor(self.torque_scale, "torque_scale")
        _factor(self.masses, "masses")

    @property
    def nominal(self) -> bool:
        """Whether this is the robot file's own model (no seed, no factor)."""
        return self.seed is None and self.friction is None and self.torque_scale is None and self.masses is None

    def _draws(self, index: int) -> dict[str, float]:
        """The seeded draws of joint ``index`` (each quantity from its own stream: adding one later
        changes none of the others)."""
        if self.seed is None:
            return {"kt": 1.0, "true_over_reported": 1.0, "coulomb": 1.0, "coulomb_load_share": 0.0, "viscous": 1.0,
                    "backlash": 0.0, "link_mass": 1.0, "link_com": 1.0, "reply_jitter": 0.0}
        out = {}
        for k, (name, (lo, hi)) in enumerate(SPREADS.items()):
            u = float(np.random.default_rng([self.seed, index, k]).random())
            if name in ("coulomb", "viscous"):  # log-uniform: as likely half as twice
                out[name] = lo * (hi / lo) ** u
            else:
                out[name] = lo + (hi - lo) * u
        return out

    def truth(self, config: RobotConfig | None = None) -> Truth:
        """What was drawn for ``config``'s joints (on the simulator's default constants), or, without
        ``config``, for the robot this variation was last given to (:meth:`apply`)."""
        if config is None:
            if self._truth is None:
                raise ArgumentError("this Variation was not given to a simulator yet: say for which robot",
                                    fix="variation.truth(config), or give it to SimulatedRobot(..., variation=) first")
            return self._truth
        from akarm.sim.params import default_params

        return self._draw(config, [default_params(j.motor) for j in config.joints])

    def _draw(self, config: RobotConfig, base: Sequence[MotorSimParams],
              gripper_base: MotorSimParams | None = None) -> Truth:
        joints = []
        links = []
        for i, (jc, p) in enumerate(zip(config.joints, base, strict=True)):
            joints.append(self._joint(i, jc, p))
            d = self._draws(i)
            links.append(LinkTruth(jc.name, d["link_mass"] if self.masses is None else self.masses,
                                   d["link_com"]))
        gripper = None
        if config.gripper is not None:  # the next index: its draws change none of the joints'
            from akarm.sim.params import default_params

            gp = gripper_base if gripper_base is not None else default_params(config.gripper.motor)
            gripper = self._joint(len(config.joints), config.gripper.joint, gp)
        return Truth(self.seed, tuple(joints), tuple(links), gripper)

    def _joint(self, index: int, jc: JointConfig, p: MotorSimParams) -> JointTruth:
        d = self._draws(index)
        fixed_scale = self.torque_scale is not None
        kt = self.torque_scale if self.torque_scale is not None else d["kt"]
        tor = 1.0 if fixed_scale else d["true_over_reported"]
        fc = d["coulomb"] if self.friction is None else self.friction
        fv = d["viscous"] if self.friction is None else self.friction
        return JointTruth(jc.name, kt, tor, kt * tor, p.coulomb * fc, d["coulomb_load_share"] * kt_out(jc),
                          p.viscous * fv, d["backlash"], d["reply_jitter"])

    def apply(self, config: RobotConfig, base: Sequence[MotorSimParams],
              gripper: MotorSimParams | None = None) -> list[MotorSimParams]:
        """``base`` (per joint, config order) with this variation's friction, torque scale, backlash and
        jitter; :meth:`truth` then says what was drawn. ``gripper``: the gripper motor's base parameters
        (default: the simulator's for its motor); :meth:`apply_gripper` gives them varied."""
        truth = self._draw(config, base, gripper)
        object.__setattr__(self, "_truth", truth)
        return [_varied(p, t) for p, t in zip(base, truth.joints, strict=True)]

    def apply_gripper(self, base: MotorSimParams) -> MotorSimParams:
        """The gripper motor's ``base`` parameters with what :meth:`apply` drew for it (call it after)."""
        truth = self.truth()
        if truth.gripper is None:
            raise ArgumentError("this robot has no gripper")
        return _varied(base, truth.gripper)


def _varied(p: MotorSimParams, t: JointTruth) -> MotorSimParams:
    return dataclasses.replace(p, coulomb=t.coulomb, viscous=t.viscous, torque_scale=t.torque_scale,
                               coulomb_load=t.coulomb_load, backlash=t.backlash, reply_jitter=t.reply_jitter)


def kt_out(joint: JointConfig) -> float:
    """Output torque per A of Iq (kt · gear ratio), as the simulated drivers compute it."""
    m = joint.motor
    if m.kt is not None:
        return float(m.kt * m.gear_ratio)
    if m.peak_current:
        return float(m.t_max / m.peak_current)
    return float(m.t_max / 20.0)

