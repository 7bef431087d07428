"""The turn check's logic and its state file (akarm.control.turns): pure, no simulator."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import akarm.files
from akarm.config import RobotConfig
from akarm.control.turns import PositionMemory, find_jump, state_file, tolerance, turn_step
from akarm.errors import AkarmError, TurnCountLost
from akarm.robotfile.load import load_robot
from akarm.sim import faults

from .conftest import ROBOTS


@pytest.fixture(scope="module")
def arm6() -> RobotConfig:
    return load_robot(ROBOTS / "arm6.yaml")


@pytest.mark.parametrize(("joint", "degrees"), [("shoulder_pan", 40.0), ("elbow", 40.0), ("wrist_roll", 60.0),
                                                ("shoulder_lift", 36.0)])
def test_a_rotor_turn_at_the_joint_is_360_degrees_over_the_gear_ratio(arm6: RobotConfig, joint: str,
                                                                      degrees: float) -> None:
    assert math.degrees(turn_step(arm6.joint(joint))) == pytest.approx(degrees)


@pytest.mark.parametrize("k", [1, -1, 2, -2, 3])
def test_whole_turns_off_are_found_with_their_k_and_one_suggestion(arm6: RobotConfig, k: int) -> None:
    j = arm6.joint("wrist_roll")
    step = turn_step(j)
    jump = find_jump(j, 0.2 + k * step + 0.01, 0.2)
    assert jump is not None and jump.turns == k
    assert jump.suggested == pytest.approx(0.21)
    error = jump.error()
    assert isinstance(error, TurnCountLost) and error.joint == "wrist_roll" and error.turns == k
    assert "akarm zero" in error.fix and "--accept-position" in error.fix


def test_near_where_it_was_or_moved_by_hand_is_no_lost_turn(arm6: RobotConfig) -> None:
    j = arm6.joint("wrist_roll")
    step = turn_step(j)
    assert find_jump(j, 0.2 + 0.04, 0.2) is None  # sagged a little
    assert find_jump(j, 0.2 + step / 2, 0.2) is None  # moved half a turn step: by hand, not a turn
    assert find_jump(j, 0.2 + step + 1.5 * tolerance(j), 0.2) is None
    assert find_jump(j, math.nan, 0.2) is None


def test_no_suggestion_where_no_turn_puts_it_back_in_range(arm6: RobotConfig) -> None:
    j = arm6.joint("shoulder_pan")  # range ±2.8
    step = turn_step(j)
    jump = find_jump(j, 3.5 + step, 3.5)  # remembered outside the range (the file was edited): nothing fits
    assert jump is not None and jump.turns == 1 and jump.suggested is None
    assert "most likely" not in str(jump.error())


def test_the_tolerance_never_lets_two_turns_overlap(arm6: RobotConfig) -> None:
    for j in arm6.joints:
        assert 0 < tolerance(j) <= turn_step(j) / 4


def test_the_state_file_is_under_xdg_state_home_else_local_state(tmp_path: Path) -> None:
    assert state_file("arm6", {"XDG_STATE_HOME": str(tmp_path)}) == tmp_path / "akarm/positions/arm6.json"
    assert state_file("a/../b c", {}) == Path.home() / ".local/state/akarm/positions/a_.._b_c.json"
    assert state_file("arm6", {"XDG_STATE_HOME": "relative"}).is_relative_to(Path.home())  # XDG: must be absolute


def test_remembered_positions_round_trip_and_are_checked(arm6: RobotConfig, tmp_path: Path) -> None:
    mem = PositionMemory(tmp_path / "s" / "arm6.json", arm6.joints)
    assert mem.load() == {}
    q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    mem.save(dict(zip(arm6.joint_names, q, strict=True)))
    remembered = mem.load()
    assert remembered == dict(zip(arm6.joint_names, q, strict=True))
    assert mem.check(q, remembered) is None
    moved = list(q)
    moved[5] += 2 * turn_step(arm6.joint("wrist_roll"))
    error = mem.check(moved, remembered)
    assert error is not None and error.joint == "wrist_roll" and error.turns == 2
    mem.forget()
    assert mem.load() == {}


def test_a_crash_while_writing_leaves_the_old_state_file(arm6: RobotConfig, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    mem = PositionMemory(tmp_path / "arm6.json", arm6.joints)
    mem.save({"wrist_roll": 0.25})
    old = mem.path.read_bytes()

    def crash(fd: int) -> None:  # the new bytes are written, not yet renamed into place: the process dies
        raise SystemExit("killed")

    monkeypatch.setattr(akarm.files.os, "fsync", crash)
    with pytest.raises(SystemExit):
        mem.save({"wrist_roll": 1.25})
    monkeypatch.undo()
    assert mem.path.read_bytes() == old and mem.load() == {"wrist_roll": 0.25}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm6.json"]  # no temporary file left


def test_a_state_file_that_is_not_one_is_named_with_what_to_do(arm6: RobotConfig, tmp_path: Path) -> None:
    path = tmp_path / "arm6.json"
    path.write_text("{not json")
    with pytest.raises(AkarmError, match="cannot read the remembered joint positions") as e:
        PositionMemory(path, arm6.joints).load()
    assert "delete the file" in e.value.fix
    path.write_bytes(b"x" * 100_000)
    with pytest.raises(AkarmError, match="MAX_STATE_BYTES"):
        PositionMemory(path, arm6.joints).load()


@pytest.mark.parametrize(("spec", "fault"), [("wrist_roll:power-cycle:1", faults.PowerCycle(1)),
                                             ("wrist_roll:power-cycle:-2,0.5", faults.PowerCycle(-2, 0.5))])
def test_power_cycle_from_the_command_line(spec: str, fault: faults.Fault) -> None:
    assert faults.parse(spec) == ("wrist_roll", fault)


@pytest.mark.parametrize("spec", ["j:power-cycle", "j:power-cycle:1.5", "j:power-cycle:1,0", "j:power-cycle:1,2,3"])
def test_bad_power_cycles_are_refused(spec: str) -> None:
    with pytest.raises(AkarmError, match=r"(?i)power.?cycle"):
        faults.parse(spec)


def test_a_simulated_arm_keeps_its_positions_apart_from_the_real_one(tmp_path: Path) -> None:
    from akarm.buses.bus import simulated
    from akarm.config import BusConfig

    env = {"XDG_STATE_HOME": str(tmp_path)}
    assert state_file("arm6", env) == tmp_path / "akarm" / "positions" / "arm6.json"
    assert state_file("arm6", env, simulator=True) == tmp_path / "akarm" / "positions" / "arm6.sim.json"
    sim = [BusConfig("arm", "virtual", "x"), BusConfig("aux", "socketcan", "vcan1")]
    assert all(map(simulated, sim)) and simulated(BusConfig("arm", "akarm_local", "c"))
    assert not simulated(BusConfig("real", "socketcan", "can0"))
    assert not all(map(simulated, [*sim, BusConfig("real", "socketcan", "can0")]))  # one real bus: the real file
    assert not simulated(BusConfig("arm", "pcan", "PCAN_USBBUS1"))


# ------------------------------------------------------------------------- the turn check by physics (issue 39)
def two_link_gravity(q):  # arm6-like: shoulder_lift carries 8 N·m at most, the elbow 3; the others nothing
    import numpy as np

    return np.array([0.0, 8.0 * math.cos(q[1]) + 3.0 * math.cos(q[1] + q[2]), 3.0 * math.cos(q[1] + q[2]),
                     0.0, 0.0, 0.0])


def test_the_torque_at_the_true_pose_refuses_a_reading_a_turn_off_and_names_the_joint(arm6: RobotConfig) -> None:
    import numpy as np

    from akarm.control.turns import GravityTurnCheck

    check = GravityTurnCheck(arm6.joints, two_link_gravity, [True] * 6)
    truth = np.array([0.0, 0.3, 0.4, 0.0, 0.0, 0.0])
    tau = two_link_gravity(truth)
    assert check.judge(truth, tau).error is None  # the readings explain it
    step = turn_step(arm6.joint("elbow"))
    reading = truth.copy()
    reading[2] += step  # the elbow (AK80-9) reads one rotor turn (40°) more than it stands
    verdict = check.judge(reading, tau)
    e = verdict.error
    assert e is not None and e.joint == "elbow" and e.turns == 1 and math.isnan(e.remembered)
    assert e.measured == pytest.approx(tau[2]) and e.explained == pytest.approx(tau[2])
    assert e.expected == pytest.approx(two_link_gravity(reading)[2])
    # within the band (friction + 2 % of the limit) of the reading's gravity: explained, never refused
    near = two_link_gravity(reading) + np.array([0.0, 0.5, 0.5, 0.0, 0.0, 0.0])
    assert check.judge(reading, near).error is None


def test_a_joint_whose_torque_a_turn_does_not_change_cannot_be_told(arm6: RobotConfig) -> None:
    import numpy as np

    from akarm.control.turns import GravityTurnCheck

    check = GravityTurnCheck(arm6.joints, two_link_gravity, [True] * 6)
    q = np.array([0.3, 0.3, 0.4, 0.2, 0.0, 0.1])
    verdict = check.judge(q, two_link_gravity(q))
    assert verdict.error is None and {"shoulder_pan", "forearm_roll", "wrist_roll"} <= set(verdict.undecided)


def test_a_joint_on_its_hard_stop_may_hold_less_than_gravity_asks(arm6: RobotConfig) -> None:
    import numpy as np

    from akarm.control.turns import GravityTurnCheck

    check = GravityTurnCheck(arm6.joints, two_link_gravity, [True] * 6)
    q = np.array([0.0, 1.7, 1.4, 0.0, 0.0, 0.0])  # shoulder_lift on its upper stop (the robot file's 1.7)
    tau = two_link_gravity(q)
    tau[1] += 2.0  # the stop carries 2 N·m of it (it pushes down: the motor holds more)
    assert check.judge(q, tau).error is None


def test_a_reading_past_the_hard_stop_by_whole_turns_is_a_lost_turn(arm6: RobotConfig) -> None:
    from akarm.control.turns import GravityTurnCheck

    check = GravityTurnCheck(arm6.joints, two_link_gravity, [True] * 6, [j.limits.lower for j in arm6.joints],
                             [j.limits.upper for j in arm6.joints])
    step = turn_step(arm6.joint("shoulder_lift"))  # AK70-10: 36°
    e = check.out_of_range([0.0, 1.7 + step, 0.0, 0.0, 0.0, 0.0])
    assert e is not None and e.joint == "shoulder_lift" and e.turns == 1 and "past its hard stop" in str(e)
    assert check.out_of_range([0.0, 1.75, 0.0, 0.0, 0.0, 0.0]) is None  # (pressed into its stop: in range)
