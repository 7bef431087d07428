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
