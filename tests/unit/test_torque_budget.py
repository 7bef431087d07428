"""Issue 41: a move's torque within what a real unit's joint can give (akarm.motion.torque.TorqueBudget).

arm6's move from `home` to `reach` at full speed asked its shoulder for 25.2 of its 25 N·m on the nominal
model: five of twenty seeded real units (`akarm.sim.Variation`, whose shoulder gives 0.76-0.84 N·m per N·m
reported) saturated there, overshot and were stopped. A move is now slowed until every joint's model
torque is within 70 % of its limit (an unidentified unit may give 30 % less), or 90 % of the limit times
its identified torque scale; gravity alone over a joint's limit is a named refusal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import akarm
from akarm.arm import Arm
from akarm.config import Friction
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError
from akarm.motion.torque import TorqueBudget

from .conftest import ROBOTS

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
LIFT = ARM6.joint_names.index("shoulder_lift")
START = np.array(ARM6.pose("home"))


def peak_torque(arm: Arm, plan: object) -> np.ndarray:
    model = RobotModel(arm.config, armature=True)
    times = np.linspace(plan.t0, plan.t_end, 400)  # type: ignore[attr-defined]
    return np.max([np.abs(model.inverse_dynamics(*plan.sample(t))) for t in times], axis=0)  # type: ignore[attr-defined]


def planned(arm: Arm, target: str, speed: float = 1.0) -> tuple[object, object]:
    """The move's plan as the planner makes it, and slowed by the factor the arm's torque budget gives
    (as `move_to` does; the refusal too). The arm's own use: test_realunits, test_fault_matrix."""
    def make(s: float) -> object:
        return arm.planner.move_from((START, np.zeros(6), np.zeros(6)), ARM6.pose(target), 0.0, s)

    budget = TorqueBudget(arm.config, RobotModel(arm.config, armature=True))
    budget.set_payload(arm.payload)
    plan = make(speed)
    factor, _ = budget.speed_factor(plan.sample, plan.t0, plan.t_end)  # type: ignore[attr-defined]
    return plan, plan if factor >= 0.995 else make(speed * factor * 0.98)


def test_a_move_is_slowed_until_its_torque_is_within_70_percent_of_an_unidentified_joints_limit() -> None:
    arm = Arm(ARM6)
    full, slowed = planned(arm, "reach")
    assert peak_torque(arm, full)[LIFT] > 24.5  # the kinematic limits alone: all of the 25 N·m
    assert slowed.duration > 1.3 * full.duration  # type: ignore[attr-defined]
    assert peak_torque(arm, slowed)[LIFT] <= 0.7 * 25.0 * 1.01
    # a move that asks little is not touched
    full, same = planned(arm, "upright")
    assert same.duration == pytest.approx(full.duration)  # type: ignore[attr-defined]


def test_an_identified_joint_gets_its_torque_scale_times_90_percent_of_its_limit() -> None:
    joints = list(ARM6.joints)
    joints[LIFT] = replace(joints[LIFT], friction=Friction(0.5, 0.05, 0.0, 0.0, 0.8))
    config = replace(ARM6, joints=tuple(joints))
    budget = TorqueBudget(config, RobotModel(config, armature=True))
    assert budget.budget[LIFT] == pytest.approx(25.0 * 0.8 * 0.9)
    assert budget.budget[0] == pytest.approx(0.7 * ARM6.joints[0].limits.torque)
    arm = Arm(config)
    _, slowed = planned(arm, "reach")
    assert peak_torque(arm, slowed)[LIFT] <= 18.0 * 1.01


def test_gravity_over_a_joints_limit_is_a_named_refusal() -> None:
    arm = Arm(ARM6)
    with pytest.warns(akarm.ConfigWarning):  # (set_payload says so too: not everywhere)
        arm.set_payload(3.0, (0.0, 0.0, 0.05))  # 3 kg at full reach: the elbow's 18 N·m cannot hold it
    with pytest.raises(LimitError) as info:
        planned(arm, "reach")
    assert info.value.joint == "elbow" and "more than the joint's 18.0 N·m" in str(info.value)


def planned_from(budget: TorqueBudget, arm: Arm, start: str, target: str) -> tuple[object, object]:
    """``planned`` with a given budget, from the named pose ``start``."""
    def make(s: float) -> object:
        return arm.planner.move_from((np.array(ARM6.pose(start)), np.zeros(6), np.zeros(6)), ARM6.pose(target), 0.0, s)

    plan = make(1.0)
    factor, _ = budget.speed_factor(plan.sample, plan.t0, plan.t_end)  # type: ignore[attr-defined]
    return plan, plan if factor >= 0.995 else make(factor * 0.98)


def test_a_hold_that_needs_more_than_the_model_slows_the_next_move_and_refuses_one_it_cannot_make() -> None:
    """A unit measured holding `ready` with 1.5 times the model's gravity torque on its shoulder (a weak
    motor, heavier links, or a payload nobody told the arm): moves plan with that, and friction, within 90 %
    of the limit. `reach` needs 14.4 N·m of gravity on the model: 21.5 measured, and 2.3 of friction to move
    from there, over 22.5: refused before anything moves, saying what was measured."""
    arm = Arm(ARM6)
    model = RobotModel(ARM6, armature=True)
    budget = TorqueBudget(ARM6, RobotModel(ARM6, armature=True))
    ready = np.array(ARM6.pose("ready"))
    g = model.gravity(ready)
    nominal = planned_from(budget, arm, "ready", "home")[1]
    budget.measure_hold(ready, g)  # the model's own torque: nothing changes
    assert budget.load[LIFT] == pytest.approx(1.0) and budget.load[0] == 1.0
    same = planned_from(budget, arm, "ready", "home")[1]
    assert same.duration == pytest.approx(nominal.duration)  # type: ignore[attr-defined]
    tau = g.copy()
    tau[LIFT] *= 1.5
    tau[0] = 3.0  # the pan: gravity does not load it, nothing is read from it
    budget.measure_hold(ready, tau)
    assert budget.load[LIFT] == pytest.approx(1.5) and budget.load[0] == 1.0
    with pytest.raises(LimitError) as info:
        planned_from(budget, arm, "ready", "reach")
    assert info.value.joint == "shoulder_lift" and "1.50 this arm was measured to need" in str(info.value)
    assert "arm.set_payload" in info.value.fix
    slowed = planned_from(budget, arm, "ready", "home")[1]  # down: slower than on the model
    assert slowed.duration > 1.05 * nominal.duration  # type: ignore[attr-defined]
    # a payload the arm is told starts the measurement over (it was measured against the model without it)
    budget.set_payload((0.3, np.array([0.0, 0.0, 0.05])))
    assert budget.load[LIFT] == 1.0
    planned_from(budget, arm, "ready", "reach")
