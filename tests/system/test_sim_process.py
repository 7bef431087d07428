"""The simulator in a process of its own, on akarm_local: what the benchmarks and `akarm bench` use."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import akarm
from akarm.errors import StateError
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS


def test_an_arm_moves_against_a_simulator_in_another_process(channel):
    robot = ROBOTS / "planar2.yaml"
    cpus = sorted(os.sched_getaffinity(0))[:1] if hasattr(os, "sched_getaffinity") else None
    with SimulatorProcess(robot, channel=channel, cpus=cpus) as sim:
        if cpus:
            status = Path(f"/proc/{sim.pid}/status").read_text()
            assert f"Cpus_allowed_list:\t{cpus[0]}" in status
        config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
        # real time against another process on a possibly busy machine: the watchdog is relaxed
        with akarm.Arm(config, feedback_timeout=0.5) as arm:
            arm.enable()
            target = np.array([0.3, -0.4])
            arm.move_to(target)
            arm.sleep(0.5)
            assert np.max(np.abs(arm.state().q - target)) < 5e-3
        assert sim.cpu_seconds() > 0.0
    with pytest.raises(StateError, match="not running"):
        _ = sim.pid


def test_a_simulator_that_cannot_start_says_why(tmp_path, channel):
    bad = tmp_path / "broken.yaml"
    bad.write_text("joints: [\n")
    with pytest.raises(StateError, match="did not start") as e, SimulatorProcess(bad, channel=channel):
        pass
    assert "broken.yaml" in str(e.value)


def test_the_simulator_says_how_late_it_took_frames_in(channel):
    """Frames sent while the simulator's process is stopped (SIGSTOP: as a machine that cannot run it)
    wait for it: it reports the longest wait, through its control channel, once."""
    import signal
    import time

    import can

    from akarm.protocol import mit

    robot = ROBOTS / "planar2.yaml"
    with SimulatorProcess(robot, channel=channel, control=True) as sim, \
            can.Bus(interface="akarm_local", channel=channel) as bus:
        assert sim.control is not None
        bus.send(can.Message(arbitration_id=1, data=mit.EXIT, is_extended_id=False))
        time.sleep(0.3)
        assert 0.0 <= sim.control.late() < 0.25  # taken in at once (at most a busy machine's delay)
        os.kill(sim.pid, signal.SIGSTOP)
        try:
            bus.send(can.Message(arbitration_id=1, data=mit.EXIT, is_extended_id=False))
            time.sleep(0.6)
        finally:
            os.kill(sim.pid, signal.SIGCONT)
        time.sleep(0.3)
        assert sim.control.late() >= 0.55  # it waited while the simulator was stopped
        assert sim.control.late() == 0.0   # and that was reported once: no frame since


def test_a_simulator_that_stops_running_is_named_in_the_stop_not_the_cables(channel, tmp_path):
    """The simulator's process stopped (SIGSTOP: a machine that does not run it in time) while an arm
    holds: the watchdog's FeedbackTimeout says that the simulator has not read the bus since before
    the unanswered commands, not "the adapter, the cable". A simulated power loss of every motor (the
    simulator runs and reads the commands) still blames the bus's hardware."""
    import signal
    import time

    import akarm
    from akarm.errors import FeedbackTimeout
    from akarm.sim import faults

    robot = ROBOTS / "planar2.yaml"
    config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
    with SimulatorProcess(robot, channel=channel, control=True, pose="down") as sim, akarm.Arm(config) as arm:
        assert sim.control is not None
        arm.enable()
        os.kill(sim.pid, signal.SIGSTOP)
        try:
            with pytest.raises(FeedbackTimeout) as e:
                arm.sleep(2.0)
        finally:
            os.kill(sim.pid, signal.SIGCONT)
        text = str(e.value)
        assert "and the simulator on bus 'arm' has not read the bus for" in text, text
        assert "the simulator ran late" in text and "adapter" not in text and "--profile slow" in e.value.fix
        # the simulator runs, the motors are silent: the bus's hardware is the likelier cause
        time.sleep(0.3)
        arm.enable()
        for joint in config.joint_names:
            sim.control.inject(joint, faults.Unplugged())
        with pytest.raises(FeedbackTimeout) as e:
            arm.sleep(2.0)
        assert "simulator" not in str(e.value) and ("the bus (the adapter" in str(e.value)
                                                    or "this motor" in str(e.value)), str(e.value)
