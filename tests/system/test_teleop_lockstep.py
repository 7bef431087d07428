"""Teleoperation in lock step: what it needs of the Arm (extra torque in teach mode, unsynchronised
streaming), and a leader and a follower on one clock (tests/system has the long acceptance runs)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from .conftest import lockstep_arm


def test_teach_mode_adds_the_extra_torque_to_the_weight_it_carries(channel: str) -> None:
    with lockstep_arm("planar2", channel, q0=[-0.5, 0.3], enable=True) as (arm, sim):
        arm.teach(0.1)
        arm.sleep(0.05)
        carried = sim.tau.copy()
        sim.set_blocked("shoulder", True)   # held where it is, so damping adds nothing
        sim.set_blocked("elbow", True)
        arm.set_extra_torque([0.8, -0.4])
        arm.sleep(0.02)
        np.testing.assert_allclose(sim.tau - carried, [0.8, -0.4], atol=0.02)
        np.testing.assert_allclose(arm.observe.tau_ff - carried, [0.8, -0.4], atol=0.02)
        arm.set_extra_torque([100.0, 0.0])  # clamped to the joint's torque limit
        arm.sleep(0.02)
        assert sim.tau[0] == pytest.approx(arm.config.joints[0].limits.torque, abs=0.05)
        arm.set_extra_torque(None)
        arm.sleep(0.02)
        np.testing.assert_allclose(sim.tau, carried, atol=0.02)


def test_an_unsynchronised_stream_brings_each_joint_at_its_own_pace(channel: str) -> None:
    with lockstep_arm("planar2", channel, q0=[0.0, 0.0], enable=True) as (arm, sim):
        synced = arm.stream_to([1.0, 0.05])
        free = arm.stream_to([1.0, 0.05], synchronize=False)
        assert synced.superseded
        seg = free.plan.segments[-1]
        # the elbow's small move is over long before the shoulder's, instead of spread over the same time
        t_elbow = next(t for t in np.linspace(0, seg.duration, 400) if abs(seg.at(seg.t0 + t)[0][1] - 0.05) < 1e-9)
        assert t_elbow < 0.5 * seg.duration
        free.wait()
        np.testing.assert_allclose(arm.state().q_des, [1.0, 0.05], atol=1e-9)


def test_the_follower_engages_at_reduced_speed_then_follows_the_hand_guided_leader(channel: str) -> None:
    from akarm.teleop import Teleop

    from ..teleop_rig import Hand, leader_follower, run, smooth

    with leader_follower(channel, leader_q0=[-0.5, 0.3], follower_q0=[-0.1, 0.3]) as (leader, lsim, follower, fsim):
        said: list[str] = []
        t0 = leader.clock.now()
        hand = Hand(lsim, smooth([-0.5, 0.3], [0.25, -0.15], 0.5, start=t0 + 0.8))  # from 0.8 s: 0.39 rad/s at most
        with Teleop(leader, follower, engage_speed=0.5, say=said.append) as tele:
            assert leader.mode.name == "TEACH"
            steps = run(tele, 1.8, hand)
        phases = [s.phase for s in steps]
        engaged = phases.index("following")
        assert set(phases[:engaged]) == {"engaging"} and set(phases[engaged:]) == {"following"}
        assert said[0].startswith("engaging") and said[1].startswith("engaged")
        log = follower.telemetry(since=t0)
        v_engage = np.abs(np.diff(log.q_des, axis=0)).max(axis=0) / follower.observe.loop.period
        assert np.all(v_engage <= 0.5 * follower.limits.velocity + 1e-9)  # never faster than it engages
        err = np.array([s.follower_q - s.command for s in steps[engaged + 150:]])
        assert np.abs(err).max() < 0.02                                  # within 20 mrad while following
        assert max(np.abs(s.leader_dq).max() for s in steps) > 0.3         # (and the leader did move)
        assert tele.summary().latency_p50 == pytest.approx(0.002)          # lock step: one follower period
        assert leader.mode.name == "ACTIVE" and follower.enabled           # finished: both held, enabled


@pytest.mark.parametrize("faulty", ["leader", "follower"])
def test_a_fault_on_either_arm_stops_both(channel: str, faulty: str) -> None:
    from akarm import SafetyStop
    from akarm.sim import faults
    from akarm.teleop import Teleop

    from ..teleop_rig import leader_follower, run

    with leader_follower(channel, leader_q0=[-0.5, 0.3], follower_q0=[-0.5, 0.3]) as (leader, lsim, follower, fsim):
        with Teleop(leader, follower) as tele:
            run(tele, 0.1)
            (lsim if faulty == "leader" else fsim).inject("elbow", faults.ErrorCode(1))
            with pytest.raises(SafetyStop):
                run(tele, 0.5)
        assert tele.phase == "stopped"
        assert not leader.enabled and not follower.enabled
        assert not any(d.enabled for d in (*lsim.drivers, *fsim.drivers))  # every motor limp: damped, then exit


def test_two_arms_on_one_bus_pair_as_well(channel: str) -> None:
    from akarm.teleop import Teleop

    from ..teleop_rig import leader_follower, run

    with leader_follower(channel, leader_q0=[-0.4, 0.2], follower_q0=[-0.4, 0.2], same_bus=True) as \
            (leader, lsim, follower, fsim):
        assert leader.config.buses["arm"].channel == follower.config.buses["arm"].channel
        with Teleop(leader, follower) as tele:
            lsim.set_external_torque([0.6, 0.0])
            steps = run(tele, 0.4)
        assert steps[-1].phase == "following" and steps[-1].leader_q[0] > -0.3
        assert abs(steps[-1].follower_q[0] - steps[-1].command[0]) < 0.02


def test_a_teleop_session_with_grippers_records_a_gripper_column(channel: str, tmp_path: Path) -> None:
    """The acceptance of issue 36: the hand closes the leader's gripper (let go by the session), the
    follower's closes on a 30 mm object
    and holds it within its force; the episode's observation.state and action end with a gripper
    column (the width measured and asked, m), read back with pyarrow."""
    pq = pytest.importorskip("pyarrow.parquet")
    from akarm.datasets import GRIPPER, DatasetWriter
    from akarm.teleop import Teleop
    from akarm.teleop.recording import EpisodeRecorder

    from ..teleop_rig import leader_follower, run

    with leader_follower(channel, robot="arm6g") as (leader, lsim, follower, fsim):
        assert leader.gripper is not None and follower.gripper is not None
        leader.gripper.open()
        follower.gripper.open()
        fsim.place_object(0.03)
        writer = DatasetWriter(tmp_path, (*follower.names, GRIPPER), 50, robot_type="arm6g")
        rec = EpisodeRecorder(writer, follower.config.rate_hz)
        with Teleop(leader, follower) as tele:
            steps = run(tele, 0.3)
            assert steps[-1].phase == "following"
            rec.begin("grasp the 30 mm part", steps[-1].t)
            for s in run(tele, 0.5):  # the follower's jaws follow the leader's, open
                rec.add(s)
            closing, peak = [], 0.0
            for k in range(1250):  # 2.5 s: the hand squeezes the (free) leader gripper shut in 0.5 s
                lsim.set_gripper_width(max(0.0, 0.08 * (1.0 - k / 250)))
                closing.append(tele.step())
                rec.add(closing[-1])
                peak = max(peak, fsim.object_force())
        assert rec.finish() == 0
        last = closing[-1]
        assert last.grasped and abs(last.gripper_width - 0.03) < 0.002
        assert last.gripper_command == pytest.approx(0.0, abs=0.0006)  # what the leader asks: closed
        assert 16.0 <= fsim.object_force() <= 24.0 and peak <= follower.gripper.force_limit * 1.1
    data = pq.read_table(tmp_path / "data/chunk-000/file-000.parquet")
    info = (tmp_path / "meta/info.json").read_text()
    assert '"gripper"' in info
    state = np.array(data.column("observation.state").to_pylist())
    action = np.array(data.column("action").to_pylist())
    effort = np.array(data.column("observation.effort").to_pylist())
    assert state.shape[1] == action.shape[1] == 7
    assert state[0, 6] == pytest.approx(0.08, abs=0.002) and action[0, 6] == pytest.approx(0.08, abs=0.001)
    assert state[-1, 6] == pytest.approx(0.03, abs=0.002) and action[-1, 6] == pytest.approx(0.0, abs=0.001)
    assert 16.0 <= effort[-1, 6] <= 24.0


def test_a_trigger_joint_drives_the_follower_gripper_and_feels_the_grasp(channel: str, tmp_path: Path) -> None:
    from akarm.clock import SteppedClock
    from akarm.teleop import Pairing, Teleop

    from ..conftest import lockstep_arm

    clock = SteppedClock()
    # the leader: arm6 without a gripper, its wrist_roll the trigger (1 rad: open, 0: closed)
    with lockstep_arm("arm6", channel + "-leader", clock=clock, q0=[0, 0, 0, 0, 0, 1.0], enable=True) as \
            (leader, lsim), lockstep_arm("arm6g", channel + "-follower", clock=clock, enable=True) as (follower, fsim):
        names = list(leader.names)
        path = tmp_path / "map.yaml"
        path.write_text("pairs:\n" + "".join(f"  - {{leader: {n}, follower: {n}}}\n" for n in names[:5])
                        + "gripper: {trigger: wrist_roll, closed: 0.0, open: 1.0, force: 20.0}\n")
        pairing = Pairing.load(path, leader.names, follower.names)
        fsim.place_object(0.03)
        t0 = clock.now()
        # a finger on the trigger: a spring (5 N·m/rad) turning it shut from 0.6 s on, over 1 s, then held
        i = names.index("wrist_roll")

        def push(t: float) -> None:
            target = 0.5 * (1.0 + math.cos(math.pi * min(max(t - t0 - 0.6, 0.0), 1.0)))
            tau = np.zeros(len(names))
            tau[i] = 5.0 * (target - lsim.q[i]) - 0.1 * lsim.dq[i]
            lsim.set_external_torque(tau)

        with Teleop(leader, follower, pairing, force_feedback=1.0) as tele:
            opened, closing = [], []
            for k in range(1500):  # 3 s
                push(clock.now())
                (opened if k < 300 else closing).append(tele.step())
        assert opened[-1].gripper_command == pytest.approx(0.08, abs=0.001)
        assert opened[-1].gripper_width == pytest.approx(0.08, abs=0.002)
        held = [s for s in closing if s.grasped]
        assert all(s.grasped for s in closing[-500:])  # held for the last second, steadily
        assert held and abs(held[-1].gripper_width - 0.03) < 0.002
        assert 16.0 <= held[-1].gripper_force <= 24.0
        # felt: the trigger is pushed open by the squeeze's work over its span (gain 1: 20 N · 0.08 m / 1 rad),
        # within the feedback's limit, only while the jaws hold something
        limit = tele.force_limit[i]
        fb = np.array([s.feedback[i] for s in held[-50:]])
        assert np.all(fb > 0) and np.all(fb <= limit + 1e-9)
        print(f"trigger feedback {fb.mean():.3f} N·m (limit {limit:.3f}), squeeze {held[-1].gripper_force:.1f} N, "
              f"{len(held)} steps held, width {held[-1].gripper_width * 1e3:.1f} mm")
        assert fb.mean() == pytest.approx(min(limit, held[-1].gripper_force * 0.08), rel=0.25)
        assert all(s.feedback[i] == 0.0 for s in opened)
