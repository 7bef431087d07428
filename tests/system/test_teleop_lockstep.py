"""Teleoperation in lock step: what it needs of the Arm (extra torque in teach mode, unsynchronised
streaming), and a leader and a follower on one clock (tests/system has the long acceptance runs)."""

from __future__ import annotations

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
