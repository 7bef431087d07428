"""Issue 41's acceptance: arm6 with the collision thresholds its robot file ships (not identified) is not
stopped by a real unit's model error, and still stops for a real collision.

In lock step, a session of moves between the named poses, at the robot's normal speed, ends with no safety
stop against (a) a 0.3 kg
payload at the tool the controller is not told about, (b) friction twice the catalogue's, (c) both, and
(d) 20 seeded :class:`akarm.sim.Variation` units (torque constants, true/reported torque, friction with a
load-dependent part, backlash, link masses and centres of mass, reply jitter); in each, a 4 N·m external
step on the elbow during a move afterwards is a :class:`~akarm.CollisionError` within 50 ms (the stop's
own time). Run on two workers by .ci/run's LOCKSTEP list (about 5 s of CPU per case). Then identification
with a known weight on a seeded unit against its truth, and the gripper's motor on a varied unit.
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

import numpy as np
import pytest

import akarm
from akarm.errors import CollisionError, LimitError
from akarm.sim import Variation

from ..conftest import ROBOTS, ROOT, lockstep_arm

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
#: the session: every named pose, reach twice (the shoulder's largest torque), back home
SESSION = ("ready", "left", "reach", "home", "reach", "ready", "upright", "home")
#: the moves' speed factor: the robot's normal speed. At full speed the move to `reach` once asked the
#: shoulder_lift's AK70-10 for 25.2 of its 25 N·m on the nominal arm: 5 of these 20 seeds (motors giving
#: 0.76-0.84 N·m per N·m reported) saturated, overshot and were stopped, and ran at half speed. The arm now
#: slows a move to what an unidentified joint can give (akarm.motion.torque: 70 % of its limit).
SPEED = 1.0
PUSH = 4.0  # N·m on the elbow
ELBOW = ARM6.joint_names.index("elbow")

CASES = {"payload": (None, 0.3), "friction": (Variation(friction=2.0), 0.0), "both": (Variation(friction=2.0), 0.3)}
CASES.update({f"seed{k}": (Variation(seed=k), 0.0) for k in range(20)})
#: Cases known to stop falsely (a strict xfail each). None: seed 3's elbow (0.68 N·m per N·m reported, its links
#: 8 % heavier) lagged the last move home -> ready at full speed and was stopped (-2.71 N·m against 1.10 + 1.55)
#: until the reflex learnt the share of the model's torque its error follows (ModelResidual.follow).
FALSE_STOP: set[str] = set()


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(
    strict=True, raises=CollisionError, reason="a false stop at full speed (see FALSE_STOP)"))
    if c in FALSE_STOP else c for c in CASES])
def test_a_session_on_a_real_unit_ends_without_a_stop_and_a_push_still_stops_it(channel: str, case: str) -> None:
    variation, payload = CASES[case]
    with lockstep_arm(ARM6, channel, q0=ARM6.pose("home"), enable=True,
                      sim_options={"variation": variation}) as (arm, sim):
        if payload:
            sim.set_payload(payload, (0.0, 0.0, 0.05))  # at the tool; the arm is not told
        for pose in SESSION:
            arm.move_to(pose, speed=SPEED)
        assert arm.enabled and arm.last_collision is None
        motion = arm.move_to("ready", speed=SPEED, wait=False)
        arm.sleep(motion.duration / 2)
        assert abs(arm.state().dq[ELBOW]) > 0.1  # during the move
        push = np.zeros(6)
        push[ELBOW] = PUSH
        t_push = sim.t
        sim.set_external_torque(push)
        with pytest.raises(CollisionError) as e:
            arm.sleep(0.3)
        sim.set_external_torque(None)
        assert e.value.joint == "elbow"
        assert e.value.at - t_push <= 0.050, f"{(e.value.at - t_push) * 1e3:.1f} ms"
        assert not arm.enabled


def _units_table() -> ModuleType:
    """docs/tools/realunits_table.py, which generates the docs' table of identified units."""
    path = ROOT / "docs" / "tools" / "realunits_table.py"
    spec = importlib.util.spec_from_file_location("realunits_table", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("realunits_table", module)
    spec.loader.exec_module(module)
    return module


def test_a_unit_too_weak_to_hold_a_pose_is_refused_the_move_there_and_stays_held(channel: str) -> None:
    """Seed 28's shoulder_lift gives 0.66 N·m per N·m reported, with 0.89 N·m of friction and 4.6 % of its
    load: holding `left` it reports 1.5 times the model's gravity torque, so holding `reach` and lifting the
    arm from there would need about 24 of its 25 N·m. Planned on the model, the move went, and the motor
    saturated on the way back (a TrackingError); measured, the move is refused before anything moves, and
    the arm stays held where it is, enabled."""
    with lockstep_arm(ARM6, channel, q0=ARM6.pose("home"), enable=True,
                      sim_options={"variation": Variation(seed=28)}) as (arm, sim):
        for pose in ("ready", "left"):
            arm.move_to(pose, speed=SPEED)
        arm.sleep(0.3)
        with pytest.raises(LimitError) as info:
            arm.move_to("reach", speed=SPEED)
        assert info.value.joint == "shoulder_lift" and "measured to need" in str(info.value)
        arm.sleep(0.5)
        assert arm.enabled and arm.fault is None
        assert np.max(np.abs(arm.state().q - ARM6.pose("left"))) < 0.03  # (a weak unit settles within mrad)
        arm.move_to("home", speed=SPEED)  # what it can do, it still does
        assert arm.enabled


@pytest.mark.parametrize("seed", [33, 49])
def test_a_weak_unit_is_caught_where_it_is_when_enabled_not_dropped(channel: str, seed: int) -> None:
    """Seeds 33 and 49: damped on the model's gravity while settling, their shoulder and elbow (0.69-0.72
    N·m per N·m reported) fell 1.9 rad in 3 s from `home` and the enable was refused (NotSettled, the arm
    disabled). The settling's gravity factor rises while a joint falls: the arm is caught within a few
    centimetres' travel and held."""
    home = np.array(ARM6.pose("home"))
    with lockstep_arm(ARM6, channel, q0=home, sim_options={"variation": Variation(seed=seed)}) as (arm, sim):
        arm.enable()
        arm.sleep(0.5)
        assert arm.enabled
        assert np.max(np.abs(arm.state().q - home)) < 0.05
        arm.move_to("ready", speed=SPEED)


#: the seeds CI identifies (about 20 s of CPU each); docs/tools/realunits_table.py does all 20 for the docs
IDENTIFIED = (1,)


@pytest.mark.parametrize("seed", IDENTIFIED)
def test_identifying_a_unit_with_a_known_weight_recovers_its_torque_scale_and_friction(channel: str,
                                                                                        seed: int) -> None:
    """Issue 41: `identify_unit` (two runs, the second with 0.5 kg hung 10 cm off the tool's axis, each
    followed by the pan alone, the links' inertial parameters free) recovers every joint's torque scale
    within 5 % and Coulomb friction within 20 % of `Variation.truth()`, though the unit's link masses are
    ±20 % off the URDF's; and the docs' generated table has these rows as they are now."""
    table = _units_table()
    rows = table.identify_seed(seed, channel)
    for row in rows:
        assert row.determined, row
        assert abs(row.scale_error) <= table.SCALE_TOLERANCE, row
        assert abs(row.coulomb_error) <= table.FRICTION_TOLERANCE, row
    page = (ROOT / "docs" / "real-hardware.md").read_text().splitlines()
    for row in rows:  # (to the last digit but one: the compiled build's floating point may differ in the last)
        written = [line for line in page if line.startswith(f"| {seed} | {row.joint} | ")]
        assert len(written) == 1, f"no row for seed {seed}'s {row.joint}: python docs/tools/realunits_table.py"
        cells = [c.split()[0] for c in written[0].strip("|").split("|")[2:]]
        now = [c.split()[0] for c in row.line().strip("|").split("|")[2:]]
        for a, b in zip(cells, now, strict=True):
            close = abs(float(a.rstrip("%")) - float(b.rstrip("%"))) <= (0.2 if a.endswith("%") else 0.002)
            assert close, f"docs/real-hardware.md's table is stale ({written[0]} now {row.line()}): " \
                          "python docs/tools/realunits_table.py"


@pytest.mark.parametrize("seed", [16])  # the gripper's motor 1.11 times as strong as reported
def test_the_grippers_motor_is_a_real_unit_too_and_squeezes_its_scale_times_the_force_asked(channel: str,
                                                                                          seed: int) -> None:
    """Issue 41: Variation varies the gripper's motor as a joint's (its own draws: the joints' are those of
    the same seed on arm6). A close on an object at 20 N is a grasp, with no stop, and the object feels the
    unit's torque scale times the force asked: the gripper knows only the torque its motor reports."""
    arm6g = akarm.load_robot(ROBOTS / "arm6g.yaml")
    truth = Variation(seed=seed).truth(arm6g)
    assert truth.gripper is not None and truth.joints == Variation(seed=seed).truth(ARM6).joints
    assert Variation().truth(arm6g).gripper.torque_scale == 1.0  # type: ignore[union-attr]
    with lockstep_arm(arm6g, channel, q0=arm6g.pose("upright"), enable=True,
                  sim_options={"variation": Variation(seed=seed)}) as (arm, sim):
        assert sim.truth.gripper == truth.gripper
        arm.gripper.open()
        sim.place_object(0.03)
        state = arm.gripper.close(force=20.0)
        arm.sleep(0.5)
        assert state.grasped and arm.enabled and arm.last_collision is None
        scale = truth.gripper.torque_scale
        assert sim.object_force() == pytest.approx(20.0 * scale, rel=0.15), (sim.object_force(), scale)
