"""The turn check by physics (issue 39), at length, in lock step: arm6's other gravity-loaded joints, and
a sweep over random rest poses and payloads: no false refusal, and how often a lost turn is found.

Run as a script for the report (detection rate, the poses it cannot tell)::

    python -m tests.system.test_turns_gravity [N] [SEED]
"""

from __future__ import annotations

import dataclasses
import os
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import pytest

from akarm.config import Payload
from akarm.dynamics.model import RobotModel
from akarm.errors import TurnCountLost
from akarm.robotfile.load import load_robot
from akarm.sim import faults

from ..limp import rest_pose
from ..sim.test_turns_gravity import refused_before_any_motion_beyond_holding
from .conftest import ROBOTS, lockstep_arm

#: the joints gravity moves while limp (the others stay put and are remembered: test_turns.py)
LOADED = {"planar2": ["shoulder", "elbow"], "arm6": ["shoulder_lift", "elbow", "wrist_pitch"]}
#: kg at the tool: the sweep's payloads lie between 0 and this (what the motors of both arms carry
#: with margin; the model is told each one, as arm.set_payload would)
MAX_PAYLOAD = 1.0


@pytest.mark.parametrize("joint", ["shoulder_lift", "wrist_pitch"])
def test_arm6_lost_turns_on_its_other_loaded_joints_are_refused(channel: str, joint: str) -> None:
    refused_before_any_motion_beyond_holding("arm6", joint, channel)


@dataclass
class Sweep:
    poses: int = 0
    false_refusals: list[str] = field(default_factory=list)
    detected: int = 0  # the right joint, the right turns (or the turns among those that explain it too)
    misnamed: list[str] = field(default_factory=list)  # refused, but naming another joint
    missed: list[str] = field(default_factory=list)
    missed_why: Counter[str] = field(default_factory=Counter)

    def report(self, robot: str) -> str:
        lost = self.detected + len(self.misnamed) + len(self.missed)
        refused = self.detected + len(self.misnamed)
        return (f"{robot}: {self.poses} rest poses, false refusals {len(self.false_refusals)}; lost turns "
                f"refused {refused}/{lost} ({refused / lost:.0%}), naming the joint {self.detected}/{lost}; "
                f"not told: {dict(self.missed_why)}")


def sweep(robot: str, n: int, seed: int, channel: str) -> Sweep:
    """``n`` random rest poses of ``robot`` (payload 0 to MAX_PAYLOAD kg): each enabled as it is (k = 0),
    then with one loaded joint ``k`` = ±1 or ±2 rotor turns off."""
    rng = np.random.default_rng(seed)
    base = load_robot(ROBOTS / f"{robot}.yaml")
    out = Sweep()
    names = [j.name for j in base.joints]
    for trial in range(n):
        config = dataclasses.replace(base, payload=Payload(float(rng.uniform(0.0, MAX_PAYLOAD))))
        model = RobotModel(config)
        lo, hi = np.array([j.limits.lower for j in config.joints]), np.array([j.limits.upper for j in config.joints])
        q = None
        while q is None:
            q = rest_pose(config, model, rng.uniform(lo, hi))
        joint = str(rng.choice(LOADED[robot]))
        k = int(rng.choice([-2, -1, 1, 2]))
        where = f"q={np.round(q, 2).tolist()} payload={config.payload.mass:.2f} kg"
        with lockstep_arm(config, f"{channel}-{trial}", q0=q, remember_positions=False) as (arm, sim):
            zero = np.zeros(len(q))
            try:
                arm.enable()
            except TurnCountLost as e:
                out.false_refusals.append(f"{where}: {e}")
            arm.disable()
            sim.set_state(q, zero)
            sim.inject(joint, faults.PowerCycle(turns=k, seconds=0.05))
            arm.sleep(0.1)
            sim.set_state(q, zero)
            try:
                arm.enable()
            except TurnCountLost as e:
                if e.joint == joint and (e.turns == k or k in e.alternatives):
                    out.detected += 1
                else:
                    out.misnamed.append(f"{joint} {k:+d} at {where}: named {e.joint} {e.turns:+d}")
            else:
                # why not: on a stop (a turn there presses it on), or its torque within the band a turn away
                i = names.index(joint)
                at_stop = q[i] <= model.lower[i] + 0.05 or q[i] >= model.upper[i] - 0.05
                out.missed_why[f"{joint}{' on its stop' if at_stop else ''}"] += 1
                out.missed.append(f"{joint} {k:+d} at {where}")
        out.poses += 1
    return out


@pytest.mark.parametrize("robot", ["planar2", "arm6"])
def test_no_false_refusal_over_200_rest_poses_and_most_lost_turns_are_found(channel: str, robot: str) -> None:
    result = sweep(robot, 200, seed=39, channel=channel)
    print(result.report(robot))
    assert result.false_refusals == []
    lost = result.detected + len(result.misnamed) + len(result.missed)
    assert result.detected + len(result.misnamed) >= 0.6 * lost, result.report(robot)


if __name__ == "__main__":  # the report: python -m tests.system.test_turns_gravity [N] [SEED]
    os.environ.setdefault("XDG_STATE_HOME", tempfile.mkdtemp())
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 39
    for name in LOADED:
        r = sweep(name, count, seed, f"sweep-{os.getpid()}-{name}")
        print(r.report(name))
        for line in r.false_refusals + r.misnamed:
            print("  ", line)
        for line in r.missed:
            print("   not told:", line)
