"""The simulator in real time: its ticker sleeps until something is due, so an idle simulator costs
little CPU (on a slow machine, one that ticked every plant step took most of a CPU and fell seconds
behind the frames sent to it), and nothing due comes late for that.

Real time on a python-can virtual bus in this process; the bounds are generous (a busy machine), and
each fails by far if the ticker kept sleeping through what is due.
"""

from __future__ import annotations

import itertools
import time

import can
import pytest

from akarm import load_robot
from akarm.protocol import mit
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS


def test_an_idle_simulator_wakes_about_once_per_idle_interval_and_keeps_time(channel: str) -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    with SimulatedRobot(config, "virtual", channel) as sim:
        assert sim.idle_interval == pytest.approx(0.02)
        sim.driver_states()
        t0, ticks0, wall0 = sim.t, sim.ticks, time.monotonic()
        time.sleep(1.0)
        states = sim.driver_states()
        ticks, wall = sim.ticks - ticks0, time.monotonic() - wall0
    # 2 kHz plant: ticking every 2 ms was 500 wakes a second; one per idle interval is 50
    assert 10 <= ticks <= 120, ticks
    assert sim.t - t0 == pytest.approx(wall, abs=0.06)  # the plant followed the wall clock all the same
    assert not any(s.enabled for s in states)


def test_servo_status_frames_come_at_their_rate_though_it_is_longer_than_the_idle_interval(channel: str) -> None:
    config = load_robot(ROBOTS / "servo3.yaml")
    with SimulatedRobot(config, "virtual", channel, max_lag=2.0) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.idle_interval = 1.0  # the ticker would sleep 1 s with nothing due
        ticks0 = sim.ticks
        start, stamps = time.monotonic(), []
        while time.monotonic() - start < 1.0:
            msg = bus.recv(timeout=0.2)
            if msg is not None and msg.is_extended_id and msg.arbitration_id == 0x2901:
                stamps.append(time.monotonic())
        assert sim.ticks - ticks0 >= len(stamps) // 3  # it woke for them (three joints, one wake may send several)
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    assert len(stamps) > 100, len(stamps)  # 200 Hz configured
    assert max(gaps) < 0.25, max(gaps)


def test_a_delayed_reply_goes_out_at_its_time_not_at_the_next_idle_wake(channel: str) -> None:
    config = load_robot(ROBOTS / "planar2.yaml")
    joint = config.joints[0]
    with SimulatedRobot(config, "virtual", channel, max_lag=2.0) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.idle_interval = 1.0
        time.sleep(0.05)  # the ticker is asleep for 1 s now
        sim.inject(joint.name, faults.DelayReplies(0.02))
        sent = time.monotonic()
        bus.send(can.Message(arbitration_id=joint.can_id, data=mit.ENTER, is_extended_id=False))
        reply = None
        while reply is None and time.monotonic() - sent < 2.0:
            msg = bus.recv(timeout=0.1)
            if msg is not None and not msg.is_extended_id and msg.data[:1] == bytes([joint.can_id]):
                reply = time.monotonic() - sent
    assert reply is not None
    assert 0.015 < reply < 0.5, reply  # 20 ms late as asked; the ticker's next idle wake was ~1 s away



def test_a_backlog_of_old_setpoints_is_answered_once_and_enter_and_exit_are_honoured(channel: str) -> None:
    """A backlog (frames stamped 1 s ago, as a simulator that could not keep up finds them): of its MIT
    commands the driver answers the newest it finds (akarm.sim.robot.overrun), so the replies do not
    pile up; ENTER and EXIT are honoured however late."""
    config = load_robot(ROBOTS / "planar2.yaml")
    joint = config.joints[0]
    command = mit.encode_command(joint.motor, 0.1, 0.0, 5.0, 0.5, 0.0)

    def frame(data: bytes, age: float) -> can.Message:
        return can.Message(arbitration_id=joint.can_id, data=data, is_extended_id=False, timestamp=time.time() - age)

    def replies(bus: can.BusABC, wait: float = 1.0) -> int:  # (a busy machine: generous)
        end, n = time.monotonic() + wait, 0
        while time.monotonic() < end:
            msg = bus.recv(timeout=0.05)
            n += msg is not None and not msg.is_extended_id and msg.data[:1] == bytes([joint.can_id])
        return n

    with SimulatedRobot(config, "virtual", channel) as sim, \
            can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as bus:
        assert sim.overrun_after == pytest.approx(0.25)
        bus.send(frame(mit.ENTER, 1.0))
        assert replies(bus) == 1 and sim.joint(joint.name).enabled          # late, yet taken
        for _ in range(50):
            bus.send(frame(command, 1.0))
        answered = replies(bus)
        assert answered >= 1 and answered + sim.overruns == 50              # each answered or replaced
        assert sim.overruns > 0 and f"overruns {sim.overruns}" in sim.status_line()
        assert sim.take_late() >= 1.0
        bus.send(frame(mit.EXIT, 1.0))
        replies(bus)
        assert not sim.joint(joint.name).enabled                           # EXIT however late
