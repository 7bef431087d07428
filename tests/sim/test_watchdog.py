"""Whose fault a gap is, in lock step: a silent motor, the loop's own stalls, a driver that was reset.

A stall of the loop is made by moving the stepped clock on without running a cycle (``clock.sleep``):
the simulator integrates the arm under the last commands, as real motors do while the controlling
process is stopped, and the next cycle starts late. Commands are read back from the simulator's own
log of the frames its drivers took in (what the motors were told).
"""

from __future__ import annotations

import numpy as np
import pytest

from akarm import DriverReset, FeedbackTimeout, LoopStall
from akarm.control.modes import Mode
from akarm.sim import faults

from ..conftest import command_steps


def stall(arm, seconds: float) -> None:
    """The controlling process stops for ``seconds``: the simulated arm goes on, no cycle runs."""
    arm.clock.stall(seconds)


# ------------------------------------------------------------------------------------------------
# a silent motor: judged on the commands it was sent
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("moving", [False, True])
def test_an_unplugged_motor_is_stopped_within_25_ms_naming_the_motor_first(lockstep, moving: bool) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        assert arm.config.rate_hz == 500
        if moving:
            arm.move_to("up", wait=False)
            arm.sleep(0.1)
        t = arm.clock.now()
        sim.joint("elbow").inject(faults.Unplugged())
        with pytest.raises(FeedbackTimeout) as info:
            arm.sleep(0.5)
        e = info.value
        assert e.joint == "elbow" and e.at - t <= 0.025, e.at - t
        text = str(e)
        assert "no reply to its last 10 commands" in text
        assert text.index("this motor") < text.index("damped"), text  # the shoulder answers: the motor first
        assert "power" in e.fix and "CAN" in e.fix


def test_a_bus_on_which_no_joint_answers_names_the_bus_first(lockstep) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        t = arm.clock.now()
        for name in arm.names:
            sim.joint(name).inject(faults.Unplugged())
        with pytest.raises(FeedbackTimeout) as info:
            arm.sleep(0.5)
        assert info.value.at - t <= 0.025
        assert "no joint on bus 'arm' answers: the likelier cause is the bus" in str(info.value)


def test_a_motor_unplugged_as_the_loop_resumes_from_a_stall_is_stopped_25_ms_after(lockstep) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        stall(arm, 0.15)
        sim.joint("shoulder").inject(faults.Unplugged())  # its replies to the last commands are in
        t = arm.clock.now()
        with pytest.raises(FeedbackTimeout) as info:
            arm.sleep(0.5)
        assert info.value.joint == "shoulder" and info.value.at - t <= 0.025


# ------------------------------------------------------------------------------------------------
# the loop's own stalls
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("moving, seconds", [(False, 0.15), (True, 0.05), (True, 0.15)])
def test_a_stall_under_the_limit_resumes_without_a_step_and_the_plan_waits(lockstep, seconds: float,
                                                                            moving: bool) -> None:
    with lockstep("arm6", q0=[0.0, 0.3, 1.3, 0.0, 0.0, 0.0], enable=True,
                  sim_options={"log_frames": True}) as (arm, sim):
        period = 1.0 / arm.config.rate_hz
        target = np.array(arm.config.pose("left" if moving else "ready"))
        motion = arm.move_to(target, wait=False)
        arm.sleep(0.3)  # under way (the pan turns at 2.2 of its 2.5 rad/s by now), or holding
        assert not moving or arm.moving
        stall(arm, seconds)
        stall(arm, period / 3)  # (and off the loop's grid)
        motion.wait()
        arm.sleep(0.1)
        assert arm.fault is None and arm.enabled
        # the plan waited for the motors: every slot the loop missed (the first after the stall it ran) is
        # added to its time base
        missed = np.floor((seconds + period / 3) / period) - 1
        assert arm.observe.plan_lag == pytest.approx(missed * period, abs=1e-9)
        # (the joints went on under the last command, ahead of it: they come back, not yet all the way)
        np.testing.assert_allclose(arm.state().q, target, atol=0.02)
        frames, _ = sim.logged_frames()
        steps = command_steps(frames, arm.config)
        assert max(steps.values()) <= 1.0 + 1e-6, steps  # no command stepped further than v_max · period
        if moving:
            assert steps["shoulder_pan"] > 0.8  # (the check looked at a joint near its full speed)


def test_without_the_plan_waiting_the_resumed_commands_would_step(lockstep) -> None:
    """What the time base prevents: at full speed a 150 ms stall is 75 periods of travel in one step."""
    with lockstep("arm6", q0=[0.0, 0.3, 1.3, 0.0, 0.0, 0.0], enable=True) as (arm, sim):
        motion = arm.move_to("left", wait=False)
        arm.sleep(0.3)
        before = arm.observe.plan_lag
        t = arm.clock.now()
        q0 = motion.plan.sample(t - before)[0][0]
        stall(arm, 0.15)
        jumped = motion.plan.sample(arm.clock.now() - before)[0][0]
        assert abs(jumped - q0) > 50 * arm.limits.velocity[0] / arm.config.rate_hz


def test_a_stall_over_the_limit_is_a_loop_stall_not_a_feedback_timeout(lockstep) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True) as (arm, sim):
        arm.move_to("up", wait=False)
        arm.sleep(0.1)
        stall(arm, 1.0)
        with pytest.raises(LoopStall) as info:
            arm.sleep(0.1)
        e = info.value
        assert e.joint is None and e.limit == 0.2 and e.stalled == pytest.approx(1.0, abs=0.003)
        assert "the control loop did not run for 998 ms (limit 200 ms)" in str(e) and "not a motor" in str(e)
        for name in ("load", "realtime_priority", "busy_wait", "--profile slow"):
            assert name in e.fix, name
        assert "wiring" not in e.fix and "cable" not in e.fix
        assert arm.mode is Mode.DISABLED and not any(d.enabled for d in sim.drivers)


def test_the_stall_limit_is_an_option_and_the_slow_profile_s_is_larger(lockstep) -> None:
    with lockstep("planar2", q0=[-1.0, 0.0], enable=True, stall_limit=0.5) as (arm, sim):
        assert arm.observe.stall_limit == 0.5
        stall(arm, 0.4)
        arm.sleep(0.1)
        assert arm.fault is None and arm.enabled
        stall(arm, 0.6)
        with pytest.raises(LoopStall, match="limit 500 ms"):
            arm.sleep(0.1)
    with lockstep("planar2", q0=[-1.0, 0.0], timing="slow", enable=True) as (arm, sim):
        assert arm.observe.stall_limit == 1.0
        stall(arm, 0.8)
        arm.sleep(0.2)
        assert arm.fault is None and arm.enabled


def test_a_stall_in_teach_mode_is_the_loop_s_too(lockstep) -> None:
    with lockstep("planar2", q0=[-1.5, 0.0], enable=True) as (arm, sim):
        arm.teach()
        stall(arm, 0.1)
        arm.sleep(0.05)
        assert arm.fault is None and arm.mode is Mode.TEACH
        stall(arm, 0.3)
        with pytest.raises(LoopStall):
            arm.sleep(0.05)


# ------------------------------------------------------------------------------------------------
# a driver reset (a brown-out): it answers, but out of motor mode
# ------------------------------------------------------------------------------------------------
def law(arm, log) -> np.ndarray:
    """The torque each row's MIT command asked for at the state measured in that row (N·m per joint)."""
    kp, kd = arm.gains
    return kp * (log.q_des - log.q) + kd * (log.dq_des - log.dq) + log.tau_ff


@pytest.mark.parametrize("robot, pose, joint, weight", [("arm6", "reach", "shoulder_lift", True),
                                                        ("planar2", "home", "elbow", False)])
def test_a_10_ms_brownout_while_holding_is_stopped_within_50_ms(lockstep, robot: str, pose: str, joint: str,
                                                                weight: bool) -> None:
    """Within 50 ms of its first replies after the reset where the law asks it for at least a tenth of
    its torque limit at once (the shoulder holding the arm out), else of the law asking that much (the
    limp forearm falls until the hold asks it for that)."""
    with lockstep(robot, enable=True) as (arm, sim):
        arm.move_to(pose)
        arm.sleep(0.2)
        t = arm.clock.now()
        sim.joint(joint).inject(faults.Brownout(0.01))
        with pytest.raises(DriverReset) as info:
            arm.sleep(0.5)
        e = info.value
        k = arm.names.index(joint)
        limit = arm.config.joints[k].limits.torque
        log = arm.telemetry(since=t + 0.01)  # the driver is back, out of motor mode: it answers
        asked = np.abs(law(arm, log)[:, k]) >= 0.1 * limit
        first = log.t[int(np.argmax(asked))]
        assert asked.any() and e.joint == joint and e.at - max(t + 0.01, first) <= 0.05, (e.at - t, first - t)
        if weight:
            assert e.at - (t + 0.01) <= 0.05 and first - (t + 0.01) <= 2.5 / arm.config.rate_hz
        assert abs(e.reported) < 0.05 and abs(e.expected) >= 0.1 * limit
        assert str(e).index("brown-out") < str(e).index("another program")
        assert not any(d.enabled for d in sim.drivers)


def test_a_brownout_of_a_gravity_free_joint_is_stopped_once_the_law_asks_it_for_torque(lockstep) -> None:
    with lockstep("arm6", q0=[0.0, 0.3, 1.3, 0.0, 0.0, 0.0], enable=True) as (arm, sim):
        arm.sleep(0.2)
        t = arm.clock.now()
        sim.joint("shoulder_pan").inject(faults.Brownout(0.01))
        arm.sleep(0.1)  # back, limp, and nothing asks it for torque (no weight): nothing to judge yet
        assert not sim.joint("shoulder_pan").enabled and sim.joint("shoulder_pan").frames_sent > 0
        assert arm.enabled
        with pytest.raises(DriverReset) as info:
            arm.move_to("left")
        e = info.value
        log = arm.telemetry(since=t)
        asked = np.abs(law(arm, log)[:, 0]) >= 0.1 * arm.config.joints[0].limits.torque
        first = log.t[int(np.argmax(asked))]
        assert asked.any() and e.joint == "shoulder_pan" and e.at - first <= 0.05, (e.at, first)
        assert not any(d.enabled for d in sim.drivers)


def test_a_brownout_is_silent_then_the_driver_answers_out_of_motor_mode(lockstep) -> None:
    with lockstep("planar2", q0=[-1.5, 0.0], enable=True) as (arm, sim):
        d = sim.joint("elbow")
        sent = d.frames_sent
        d.inject(faults.Brownout(0.05))
        arm.clock.stall(0.04)
        assert d.frames_sent == sent and not d.enabled and not d.powered
        assert d.faults == (faults.Brownout(0.05),)
        arm.clock.stall(0.02)
        assert d.powered and not d.enabled and d.faults == () and d.stored_command.kp == 0.0


def test_dropped_replies_and_a_delay_are_not_a_reset(lockstep) -> None:
    with lockstep("planar2", q0=[0.0, 0.0], enable=True) as (arm, sim):
        sim.joint("elbow").inject(faults.DropReplies(0.3, seed=4))
        sim.joint("shoulder").inject(faults.DelayReplies(0.004))
        arm.move_to("up")
        arm.move_to("home")
        assert arm.fault is None
