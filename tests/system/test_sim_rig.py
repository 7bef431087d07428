"""SimulatedArm with the simulator in a process of its own (akarm_local, real time): the same frames
and faults as in lock step, and a simulator that dies is reported."""

from __future__ import annotations

import math
import os
import signal
import sys

import numpy as np
import pytest

from akarm import FeedbackTimeout, StateError
from akarm.protocol import mit
from akarm.sim import faults
from akarm.testing.rig import SimulatedArm

from ..sim.test_sim_rig import DOWN, PLANAR2, counts_match


def test_in_its_own_process_on_akarm_local_the_frames_and_faults_are_the_same() -> None:
    with SimulatedArm.start(PLANAR2, "akarm_local", timing="slow", pose=DOWN) as rig:
        assert rig.transport == "akarm_local" and rig.clock is None
        with rig.arm() as arm:
            assert arm.config.rate_hz == 25.0                  # the slow profile's loop
            arm.enable()
            arm.move_to("home")
            assert np.allclose(arm.state().q, rig.config.pose("home"), atol=0.02)
            rig.inject("elbow", faults.Unplugged())
            with pytest.raises(FeedbackTimeout, match="elbow"):
                arm.sleep(3.0)
        rig.clear_faults()
        assert rig.enabled_joints() == ["elbow"]             # unplugged, it never heard the EXIT
        counts_match(rig, faulted=("elbow",))                 # every frame, across processes
        assert len(rig.frames(joint="elbow", to_motor=True)) > rig.state()[1].frames_in   # sent while cut off
        last = {f.joint: f.data for f in rig.frames(to_motor=True)}
        assert last["shoulder"] == mit.EXIT


def test_a_simulator_that_dies_is_reported_when_leaving() -> None:
    rig = SimulatedArm.start(PLANAR2, "akarm_local", timing="slow")
    os.kill(rig.process.pid, signal.SIGKILL)
    rig.process.proc.wait(30)
    with pytest.raises(StateError, match="the simulator stopped before the test ended: exit status -9"):
        rig.close()
    assert math.isnan(float("nan"))


def test_a_simulator_that_no_longer_answers_is_stopped_all_the_same_when_leaving() -> None:
    """Its control channel gone (as one too slow to answer within its catch-up time): closing says so,
    and still stops the simulator, which would otherwise answer on the next test's bus as a second motor."""
    rig = SimulatedArm.start(PLANAR2, "akarm_local", timing="slow")
    proc = rig.process.proc
    assert proc is not None and rig.process.control is not None
    rig.process.control.path.unlink()
    with pytest.raises(StateError, match="control channel"):
        rig.close()
    assert proc.poll() is not None                           # stopped, not left running
    rig.close()                                              # and closed: a second close does nothing


@pytest.mark.skipif(sys.version_info < (3, 11), reason="exception notes are new in Python 3.11")
def test_a_failure_in_the_block_stays_the_one_reported_when_closing_fails_too() -> None:
    """A test that failed while the simulator stopped answering: the test's own error comes out (pytest's
    summary names it), with what closing said as a note, and the simulator is stopped all the same."""
    with pytest.raises(ValueError, match="the test's own failure") as failed, \
            SimulatedArm.start(PLANAR2, "akarm_local", timing="slow") as rig:
        proc = rig.process.proc
        assert proc is not None and rig.process.control is not None
        rig.process.control.path.unlink()
        raise ValueError("the test's own failure")
    assert any("closing the simulated arm failed too: StateError" in n for n in failed.value.__notes__)
    assert proc.poll() is not None
