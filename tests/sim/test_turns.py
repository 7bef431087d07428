"""Turn counts lost at power-up (issue 26): a driver power-cycled reads whole rotor turns off; the arm
remembers where each joint stopped and refuses an enable that reads turns from it. In lock step."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from akarm.errors import ArgumentError, FeedbackTimeout, SafetyStop, TurnCountLost
from akarm.protocol import mit
from akarm.sim import SimulatedRobot, faults

from .conftest import lockstep_arm

Q0 = [0.3, 0.0, 0.0, 0.2, 0.0, 0.1]  # arm6 at rest limp (gravity-free pose) (shoulder_pan AK10-9, wrist_roll AK60-6)


def state_dir() -> Path:
    """Where this test's state files are (tests/conftest.py gives each test its own XDG_STATE_HOME)."""
    return Path(os.environ["XDG_STATE_HOME"])


def commands_with_effort(sim: SimulatedRobot, joint: str, since: int) -> list[mit.MitCommand]:
    """The MIT commands with kp > 0 or a torque (beyond the 12-bit field's step around 0) that ``joint``
    took in since frame ``since``."""
    cfg = sim.config.joint(joint)
    codec = mit.codec(cfg.motor)
    step = 2 * cfg.motor.t_max / 4095
    out = []
    for f in sim.logged_frames(since)[0]:
        if f.joint == joint and f.to_motor and mit.special_frame(f.data) is None:
            c = codec.decode_command(f.data)
            if c.kp > 0 or abs(c.torque) > step:
                out.append(c)
    return out


def test_the_power_cycle_fault_goes_silent_then_reads_whole_turns_off_out_of_motor_mode(channel: str) -> None:
    with lockstep_arm("arm6", channel, q0=Q0) as (arm, sim):
        arm.enable()
        arm.disable()
        before = arm.state().q[5]
        sim.inject("wrist_roll", faults.PowerCycle(turns=1, seconds=0.2))
        assert not sim.joint("wrist_roll").powered
        sim.run_for(0.1)
        n = sim.joint("wrist_roll").frames_sent
        sim.run_for(0.05)
        assert sim.joint("wrist_roll").frames_sent == n  # silent
        sim.run_for(0.1)
        driver = sim.joint("wrist_roll")
        assert driver.powered and not driver.enabled and driver.faults == ()  # back, out of motor mode
        assert driver.zero == pytest.approx(-2 * math.pi / 6)  # AK60-6: one rotor turn is 60° at the output
        with pytest.raises(TurnCountLost) as e:
            arm.enable()
        assert e.value.reading == pytest.approx(before + math.pi / 3, abs=2e-3)


@pytest.mark.parametrize("joint", ["shoulder_pan", "wrist_roll"])  # AK10-9 (40° a turn), AK60-6 (60°)
@pytest.mark.parametrize("turns", [1, -1, 2, -2])
def test_a_power_cycle_between_sessions_refuses_the_enable_and_nothing_moves(channel: str, joint: str,
                                                                             turns: int) -> None:
    with lockstep_arm("arm6", channel, q0=Q0, sim_options={"log_frames": True}) as (arm, sim):
        arm.enable()
        arm.disable()
        i = arm.names.index(joint)
        remembered = arm.state().q[i]
        sim.inject(joint, faults.PowerCycle(turns=turns, seconds=0.05))
        arm.sleep(0.1)
        q_before, since = sim.q.copy(), sim.logged_frames()[1]
        with pytest.raises(TurnCountLost) as e:
            arm.enable()
        step = 2 * math.pi / arm.config.joint(joint).motor.gear_ratio
        assert e.value.joint == joint and e.value.turns == turns
        assert e.value.remembered == pytest.approx(remembered, abs=1e-9)
        assert e.value.reading == pytest.approx(remembered + turns * step, abs=2e-3)
        assert f"{remembered:+.3f}" in str(e.value) and "akarm zero" in str(e.value)
        assert "--accept-position" in str(e.value)
        lo, hi = arm.config.joint(joint).limits.lower, arm.config.joint(joint).limits.upper
        if lo <= remembered <= hi:  # exactly one k puts it back in range near where it was: suggested
            said = re.search(r"it most likely stands at ([-+.0-9]+) rad", str(e.value))
            assert said is not None and float(said.group(1)) == pytest.approx(remembered, abs=3e-3)
        arm.sleep(0.2)
        assert not arm.enabled
        assert np.max(np.abs(sim.q - q_before)) < 1e-3  # nothing moved (but the last stop's settling, 0.2 mrad)
        for name in arm.names:
            assert commands_with_effort(sim, name, since) == [], name  # no kp > 0, no torque, on any joint
        assert not any(d.enabled for d in sim.driver_states())
        arm.enable(accept_position=True)  # checked by eye: the reading is taken as it is
        assert arm.enabled


def test_no_turns_lost_enables_normally_and_the_state_file_says_where_it_stopped(channel: str) -> None:
    with lockstep_arm("arm6", channel, q0=Q0) as (arm, sim):
        arm.enable()
        arm.move_to({"wrist_roll": 0.5})
        arm.disable()
        assert any(p.name.startswith("lockstep-") for p in state_dir().iterdir())
        sim.inject("wrist_roll", faults.PowerCycle(turns=0, seconds=0.05))
        arm.sleep(0.1)
        arm.enable()
        assert arm.enabled and arm.state().q[5] == pytest.approx(0.5, abs=5e-3)


def test_a_joint_gravity_moves_while_limp_is_not_remembered_so_its_fall_is_no_lost_turn(channel: str) -> None:
    """Held where gravity loads shoulder_lift and elbow, then limp: they fall, by any angle (a whole
    turn step too), so only the joints that stay put are remembered and compared."""
    with lockstep_arm("arm6", channel, q0=Q0) as (arm, sim):
        arm.enable()
        arm.move_to({"shoulder_lift": 0.8, "elbow": 0.7})
        g = arm.model.gravity(arm.state().q)
        assert abs(g[1]) > 1.0 and abs(g[2]) > 1.0 and abs(g[0]) < 1e-6  # (the pose loads those two only)
        arm.disable()
        files = [p for p in state_dir().iterdir() if p.name.startswith("lockstep-")]
        assert len(files) == 1
        remembered = json.loads(files[0].read_text())["positions"]
        assert set(remembered) == {"shoulder_pan", "forearm_roll", "wrist_roll"}, remembered  # (wrist_pitch loaded too)
        q = sim.q.copy()
        q[2] += 2 * math.pi / 9  # the elbow (AK80-9) lies exactly one rotor turn from where it stopped
        sim.set_state(q, np.zeros(6))
        arm.enable()
        assert arm.enabled


def test_a_joint_moved_by_hand_while_limp_is_not_a_lost_turn(channel: str) -> None:
    with lockstep_arm("arm6", channel, q0=Q0) as (arm, sim):
        arm.enable()
        arm.disable()
        q = sim.q.copy()
        q[5] += 0.5  # half a turn step of an AK60-6 (1.047 rad): moved, not a turn lost
        sim.set_state(q, np.zeros(6))
        arm.enable()
        assert arm.enabled


@pytest.mark.parametrize(("joint", "seconds", "stop"), [("wrist_roll", 0.1, FeedbackTimeout),
                                                      ("shoulder_pan", 0.1, FeedbackTimeout)])
def test_a_power_cycle_while_holding_stops_within_50_ms_and_the_next_enable_checks(
        channel: str, joint: str, seconds: float, stop: type[SafetyStop]) -> None:
    """Off for longer than the watchdog: the silence stops the arm, named, and the next enable finds
    the turn lost. (Back sooner, the reply a turn off trips the following-error check first.)"""
    with lockstep_arm("arm6", channel, q0=Q0) as (arm, sim):
        k = arm.names.index(joint)
        arm.enable()
        held = arm.state().q[k]
        t = arm.clock.now()
        sim.inject(joint, faults.PowerCycle(turns=-1, seconds=seconds))  # silent from t
        with pytest.raises(stop) as e:
            arm.sleep(1.0)
        assert e.value.joint == joint and e.value.at is not None
        assert e.value.at - t <= seconds + 0.05, e.value  # a named stop within 50 ms of silence, or of the reboot
        sim.run_for(0.5)  # the stop ends; the driver is back, a turn off
        assert sim.joint(joint).powered
        with pytest.raises(TurnCountLost) as lost:
            arm.enable()
        assert lost.value.joint == joint and lost.value.turns == -1
        assert lost.value.remembered == pytest.approx(held, abs=5e-3)


def test_without_remembered_positions_nothing_is_compared(channel: str) -> None:
    with lockstep_arm("arm6", channel, q0=Q0, remember_positions=False) as (arm, sim):
        arm.enable()
        arm.disable()
        sim.inject("wrist_roll", faults.PowerCycle(turns=1, seconds=0.05))
        arm.sleep(0.1)
        arm.enable()  # the reading is believed (the failure, on purpose)
        assert not state_dir().exists() or list(state_dir().iterdir()) == []


def test_on_virtual_buses_another_programs_simulated_arm_is_not_remembered(channel: str) -> None:
    """python-can's virtual bus lives in one process: its simulator started with this program, so where
    another program's simulated arm stopped (NAME.sim.json) says nothing of it. That file had the
    examples refuse to enable a fresh simulator whose wrist_roll stood one rotor turn from it."""
    from akarm import Arm, load_robot
    from akarm.control.turns import arm_key, state_file

    config = load_robot(Path(__file__).parents[2] / "robots" / "arm6.yaml").with_bus(interface="virtual",
                                                                                     channel=channel)
    local = config.with_bus(interface="akarm_local", channel=channel)
    stale = state_file(arm_key(local), simulator=True)  # (what that arm on akarm_local would remember)
    stale.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({"robot_positions": 1, "positions": {"wrist_roll": -2 * math.pi / 6}})  # AK60-6: 1 turn
    stale.write_text(text)
    state_file(arm_key(config), simulator=True).write_text(text)  # (and on this virtual bus: never read)
    with SimulatedRobot(config, realtime=False, q0=[0.0] * 6) as sim, Arm(config, clock=sim.clock) as arm:
        arm.enable()  # (refused with TurnCountLost when the file was read)
        arm.disable()
    assert stale.read_text() == text  # neither read nor written
    # the same arm on a bus another process's simulator may answer on: remembered, and checked
    with SimulatedRobot(local, realtime=False, q0=[0.0] * 6) as sim, Arm(local, clock=sim.clock) as arm, \
            pytest.raises(TurnCountLost) as lost:
        arm.enable()
    assert lost.value.joint == "wrist_roll"


def test_two_arms_of_one_robot_file_on_two_channels_each_keep_their_own_positions(channel: str) -> None:
    """Issue 39: arm B moved its pan two AK10-9 rotor turns (+1.396 rad) and stopped; arm A, the same robot
    file on another channel, moved to 0 and stopped; A's next enable was refused as if it had lost two
    turns: one state file per robot file. Now each arm remembers under its own buses and channels."""
    from akarm import Arm, load_robot
    from akarm.control.turns import arm_key, state_file

    base = load_robot(Path(__file__).parents[2] / "robots" / "arm6.yaml")
    a, b = (base.with_bus(interface="akarm_local", channel=f"{channel}-{x}") for x in "ab")
    assert arm_key(a) != arm_key(b) and arm_key(a).startswith("arm6@akarm_local-")
    with SimulatedRobot(a, realtime=False, q0=Q0) as sim_a, Arm(a, clock=sim_a.clock) as arm_a, \
            SimulatedRobot(b, realtime=False, q0=Q0) as sim_b, Arm(b, clock=sim_b.clock) as arm_b:
        arm_b.enable()
        arm_b.move_to({"shoulder_pan": 0.3 + 4 * math.pi / 9})  # two rotor turns of an AK10-9 from A's
        arm_b.disable()
        arm_a.enable()
        arm_a.move_to({"shoulder_pan": 0.3})
        arm_a.disable()
        arm_a.enable()  # (refused with TurnCountLost: -2 rotor turns, when both shared one file)
        arm_b.disable()
        arm_b.enable()
        assert arm_a.enabled and arm_b.enabled
    assert state_file(arm_key(a), simulator=True).exists() and state_file(arm_key(b), simulator=True).exists()


def test_an_arm_named_by_its_id_keeps_its_positions_under_it_on_any_channel(channel: str) -> None:
    """``arm_id`` (``--id``): the physical arm moved to another adapter is still judged by its own memory."""
    from akarm import Arm, load_robot
    from akarm.control.turns import state_file

    base = load_robot(Path(__file__).parents[2] / "robots" / "arm6.yaml")
    first = base.with_bus(interface="akarm_local", channel=f"{channel}-1")
    with SimulatedRobot(first, realtime=False, q0=Q0) as sim, Arm(first, clock=sim.clock, arm_id="left") as arm:
        arm.enable()
        arm.disable()
        q = sim.q.copy()
    assert state_file("id-left", simulator=True).exists()
    moved = base.with_bus(interface="akarm_local", channel=f"{channel}-2")  # the same arm, another adapter
    with SimulatedRobot(moved, realtime=False, q0=q) as sim, Arm(moved, clock=sim.clock, arm_id="left") as arm:
        sim.inject("wrist_roll", faults.PowerCycle(turns=1, seconds=0.05))
        arm.sleep(0.1)
        with pytest.raises(TurnCountLost) as lost:
            arm.enable()
        assert lost.value.joint == "wrist_roll" and lost.value.turns == 1
    with pytest.raises(ArgumentError):
        Arm(base, arm_id="../x")
