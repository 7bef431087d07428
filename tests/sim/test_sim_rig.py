"""SimulatedArm (akarm.testing.rig): what the pytest plugin's fixtures are, used directly.

In lock step everything is exact: the frames recorded are compared with the simulated drivers' own
counts. The akarm_local runs put ``akarm sim`` in a process of its own, in real time, with the slow
timing profile (this machine is shared by several test runs).
"""

from __future__ import annotations

import warnings

import pytest

from akarm import FeedbackTimeout, MotorFault
from akarm.protocol import mit
from akarm.sim import faults
from akarm.testing.rig import LeftEnabledWarning, SimulatedArm

from .conftest import ROBOTS

PLANAR2 = ROBOTS / "planar2.yaml"
SERVO3 = ROBOTS / "servo3.yaml"
DOWN = "down"  # planar2 hanging: where it stays when limp


def counts_match(rig: SimulatedArm, faulted: tuple[str, ...] = ()) -> None:
    """Every frame a driver took in is a recorded command to it, every frame it sent a recorded reply
    (a driver a fault cuts off does not take in the frames recorded for it)."""
    frames = rig.frames()
    for s in rig.state():
        if s.name in faulted:
            continue
        assert sum(1 for f in frames if f.joint == s.name and f.to_motor) == s.frames_in, s.name
        assert sum(1 for f in frames if f.joint == s.name and not f.to_motor) == s.frames_out, s.name


def test_lock_step_records_exactly_the_traffic_and_names_each_frame() -> None:
    with SimulatedArm.start(PLANAR2, "virtual", pose=DOWN) as rig:
        assert rig.transport == "virtual" and rig.timing.name == "normal"
        with rig.arm() as arm:
            assert arm.clock is rig.clock
            arm.enable()
            t0 = rig.clock.now()
            arm.sleep(0.2)
            t1 = rig.clock.now()
            assert rig.enabled_joints() == ["shoulder", "elbow"]
        assert rig.enabled_joints() == []
        counts_match(rig)
        frames = rig.frames()
        shoulder = rig.config.joint("shoulder")
        to_shoulder = rig.frames(joint="shoulder", to_motor=True)
        assert {(f.bus, f.arbitration_id, f.is_extended) for f in to_shoulder} == {("arm", 1, False)}
        assert to_shoulder[0].data == mit.ENTER and to_shoulder[-1].data == mit.EXIT
        replies = rig.frames(joint="elbow", to_motor=False)
        assert all(f.arbitration_id == shoulder.reply_id and f.data[0] == 2 for f in replies)
        assert [f.t for f in frames] == sorted(f.t for f in frames)          # simulated time, in order
        # holding for 0.2 s at 500 Hz: one command to each joint per cycle, each answered at once
        assert sum(1 for f in to_shoulder if t0 <= f.t < t1) == round(0.2 * 500)
        assert sum(1 for f in rig.frames(joint="shoulder", to_motor=False) if t0 <= f.t < t1) == round(0.2 * 500)
        assert all(f.joint is not None for f in frames)


def test_servo_frames_are_told_apart_by_their_packet() -> None:
    with SimulatedArm.start(SERVO3, "virtual") as rig:
        with rig.arm() as arm:
            arm.enable()
            arm.sleep(0.05)
        assert rig.enabled_joints() == []                                     # zero current: released
        pan = rig.frames(joint="pan")
        packets = [f.arbitration_id >> 8 for f in pan if f.to_motor]
        assert 6 in packets and packets[-1] == 1             # position-speed commands, zero current at the end
        assert {f.arbitration_id for f in pan if not f.to_motor} == {0x2901}   # status frames
        counts_match(rig)


def test_faults_by_object_or_by_text_and_the_stop_they_cause() -> None:
    with SimulatedArm.start(PLANAR2, "virtual", pose=DOWN) as rig, rig.arm() as arm:
        arm.enable()
        rig.inject("shoulder", "error:1")
        with pytest.raises(MotorFault, match="shoulder"):
            arm.sleep(0.1)
        assert {s.name: s.error for s in rig.state()} == {"shoulder": 1, "elbow": 0}
        rig.clear_faults()
        arm.enable()
        rig.inject("elbow", faults.DropReplies(1.0))
        with pytest.raises(FeedbackTimeout, match="elbow"):
            arm.sleep(0.1)
        assert rig.state()[1].faults == ("DropReplies(fraction=1.0, seed=0)",)


def test_leaving_switches_off_what_a_program_left_on_and_warns_about_it() -> None:
    rig = SimulatedArm.start(PLANAR2, "virtual", pose=DOWN)
    own = rig.arm()
    own.open()
    own.enable()
    rig._arms.remove(own)  # as an Arm the program made itself
    try:
        rig.inject("elbow", faults.Unplugged())  # a joint cut off keeps its last command: not the program's doing
        with pytest.warns(LeftEnabledWarning, match=r"drivers of shoulder were still enabled"):
            rig.close()
        assert [d.enabled for d in rig.sim.drivers] == [False, False]
    finally:
        own.close()


def test_leaving_closes_the_arms_it_made_damped_then_disabled_without_a_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", LeftEnabledWarning)
        with SimulatedArm.start(PLANAR2, "virtual", pose=DOWN) as rig:
            arm = rig.arm()
            arm.open()
            arm.enable()
    assert not arm.enabled
    assert rig.frames(joint="elbow", to_motor=True)[-1].data == mit.EXIT


def test_a_simulator_keeps_no_frame_log_unless_asked(planar2) -> None:
    """The log holds 200 000 frames: kept only where someone reads it (the rig, akarm sim --control)."""
    from akarm.errors import StateError
    from akarm.sim import SimulatedRobot

    sim = SimulatedRobot(planar2.with_bus(interface="virtual", channel="no-log"), realtime=False)
    with pytest.raises(StateError, match="keeps no frame log"):
        sim.logged_frames()
