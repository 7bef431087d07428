"""akarm.control.probe against the real-time simulator: scanning, reading joints, zeroing, releasing.

Each test runs a :class:`SimulatedRobot` in real time on a virtual bus of its own and talks to it
over that bus exactly as to hardware. planar2 starts hanging straight down (shoulder -π/2, elbow 0),
where gravity holds it still even when its motors are limp.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import can
import numpy as np
import pytest

from akarm import AkarmError, BusError, StateError, load_robot
from akarm.config import BusConfig, RobotConfig
from akarm.control.probe import read_state, release, scan, zero
from akarm.protocol import mit, servo
from akarm.sim import SimulatedRobot, faults

from .conftest import ROBOTS, drain, missing_socketcan_fix, wait_until

HANGING = [-math.pi / 2, 0.0]


def config_of(robot: str, channel: str, **joint_edits: dict) -> RobotConfig:
    """``robots/<robot>.yaml`` on the virtual bus ``channel``, with per-joint field overrides."""
    cfg = load_robot(ROBOTS / f"{robot}.yaml").with_bus(interface="virtual", channel=channel)
    if joint_edits:
        cfg = replace(cfg, joints=tuple(replace(j, **joint_edits.get(j.name, {})) for j in cfg.joints))
    return cfg


@contextmanager
def simulated(cfg: RobotConfig, **kwargs) -> Iterator[SimulatedRobot]:
    with SimulatedRobot(cfg, realtime=True, **kwargs) as sim:
        yield sim


@contextmanager
def controller(channel: str, can_id: int, model: str, position: float) -> Iterator[None]:
    """A stand-in for a running controller: ENTER, then a zero-gain command to ``can_id`` every 4 ms;
    the block starts once the driver has answered a command."""
    stop, answered = threading.Event(), threading.Event()
    codec = mit.codec(model)

    def run() -> None:
        with can.Bus(interface="virtual", channel=channel) as bus:
            bus.send(can.Message(arbitration_id=can_id, data=mit.ENTER, is_extended_id=False))
            sent = False
            while not stop.wait(0.004):
                if sent and any(m.dlc >= 6 and m.data[0] == can_id for m in drain(bus)):
                    answered.set()
                bus.send(can.Message(arbitration_id=can_id, is_extended_id=False,
                                     data=codec.encode_command(position, 0.0, 0.0, 0.0, 0.0)))
                sent = True

    th = threading.Thread(target=run, daemon=True)
    th.start()
    assert answered.wait(5.0), "the simulated driver did not answer the stand-in controller"
    try:
        yield
    finally:
        stop.set()
        th.join(2.0)


# ------------------------------------------------------------------------------------------------
# scan
# ------------------------------------------------------------------------------------------------
def test_scan_finds_mit_motors_by_exit_and_leaves_them_disabled(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim:
        found = scan(cfg.buses["arm"], range(1, 17), listen=0.05, timeout=0.3)
        assert [(f.can_id, f.mode) for f in found] == [(1, "mit"), (2, "mit")]
        assert all(f.reply_id == 0 and not f.active and f.error == 0 for f in found)
        assert found[0].position == pytest.approx(-math.pi / 2, abs=2e-3)  # generic ±12.5 rad range
        assert found[0].model is None and found[0].temperature == pytest.approx(25.0, abs=2.0)
        assert not sim.joint("shoulder").enabled and not sim.joint("elbow").enabled
        # with the models known, the position is decoded with them (and the result says so)
        named = scan(cfg.buses["arm"], [1, 2], listen=0.0, timeout=0.3, models={1: cfg.joints[0].motor})
        assert named[0].model == "AK80-9" and named[1].model is None


def test_scan_matches_replies_on_byte0_whatever_their_arbitration_id(channel: str) -> None:
    cfg = config_of("planar2", channel, elbow={"reply_id": 2})  # some units answer on their own ID
    with simulated(cfg, q0=HANGING):
        found = scan(cfg.buses["arm"], range(1, 9), listen=0.0, timeout=0.3)
    assert {(f.can_id, f.reply_id) for f in found} == {(1, 0), (2, 2)}


def test_scan_leaves_a_motor_a_controller_is_driving_alone(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim, controller(channel, 1, "AK80-9", -math.pi / 2):
        assert sim.joint("shoulder").enabled
        found = {f.can_id: f for f in scan(cfg.buses["arm"], [1, 2], listen=0.05, timeout=0.3)}
        assert found[1].active and not found[2].active
        assert sim.joint("shoulder").enabled                    # no EXIT was sent to it


def test_scan_hears_servo_status_frames_even_at_a_low_rate(channel: str) -> None:
    cfg = config_of("servo3", channel, elbow={"status_rate_hz": 5.0})
    with simulated(cfg, q0=[0.4, 0.0, 0.0]):
        found = scan(cfg.buses["arm"], range(1, 9), listen=0.3)   # 0.3 s holds a whole 5 Hz period
    assert [(f.can_id, f.mode) for f in found] == [(1, "servo"), (2, "servo"), (3, "servo")]
    assert found[0].reply_id == 0x2901 and found[0].position == pytest.approx(0.4, abs=0.01)


def test_scan_rejects_bad_ids_and_reports_an_unopenable_bus() -> None:
    with pytest.raises(AkarmError, match="outside 1-255"):
        scan(BusConfig("x", "virtual", "unused"), [0, 1])
    with pytest.raises(BusError) as info:
        scan(BusConfig("x", "socketcan", "akarmnope0"), [1])
    assert missing_socketcan_fix("akarmnope0") in str(info.value)


# ------------------------------------------------------------------------------------------------
# read_state
# ------------------------------------------------------------------------------------------------
def test_read_state_is_joint_side_through_direction_and_offset(channel: str) -> None:
    cfg = config_of("planar2", channel, shoulder={"direction": -1, "offset": 0.3})
    with simulated(cfg, q0=HANGING) as sim:
        states = read_state(cfg)
        q = sim.q
    assert [s.name for s in states] == ["shoulder", "elbow"]
    assert states[0].position == pytest.approx(q[0], abs=2e-3)  # the motor reads (q - 0.3) · -1
    assert states[1].position == pytest.approx(q[1], abs=2e-3)
    assert all(s.queried and not s.missing and s.fault == 0 for s in states)
    assert states[0].temperature == pytest.approx(25.0, abs=2.0)


def test_read_state_servo_waits_for_status_frames(channel: str) -> None:
    cfg = config_of("servo3", channel)
    with simulated(cfg, q0=[0.4, 0.3, 0.0]) as sim:
        states = read_state(cfg)
        q = sim.q
    assert [s.queried for s in states] == [False, False, False]   # nothing is sent to servo motors
    for s, qi in zip(states, q, strict=True):
        assert s.position == pytest.approx(qi, abs=0.02)
    assert abs(q[1]) > 0.2          # shoulder has direction -1: a motor-side reading would have the other sign


def test_read_state_listens_first_and_does_not_disable_a_driven_joint(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim, controller(channel, 1, "AK80-9", -math.pi / 2):
        states = read_state(cfg)
        assert sim.joint("shoulder").enabled
    assert not states[0].queried and states[1].queried
    assert states[0].position == pytest.approx(-math.pi / 2, abs=2e-3)


def test_read_state_reports_a_silent_joint_as_missing(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim:
        sim.inject("elbow", faults.Unplugged())
        t0 = time.monotonic()
        shoulder, elbow = read_state(cfg, timeout=0.4)
        assert time.monotonic() - t0 < 2.0                    # waits its timeout (not for ever), then reports it
    assert not shoulder.missing and shoulder.position is not None
    assert elbow.missing and elbow.position is None and elbow.velocity is None and elbow.fault is None
    assert elbow.as_dict()["missing"] is True and elbow.fault_text() == "-"


def test_read_state_reports_a_fault_with_its_meaning(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim:
        sim.inject("elbow", faults.ErrorCode(2))
        states = read_state(cfg)
    assert states[1].fault == 2 and states[1].fault_text() == "2 over-current"
    assert states[1].as_dict()["fault_text"] == "over-current"


# ------------------------------------------------------------------------------------------------
# zero and release
# ------------------------------------------------------------------------------------------------
def test_zero_mit_waits_out_the_silence_and_reads_zero_back(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING, zero_silence=0.3) as sim:
        t0 = time.monotonic()
        p = zero(cfg, "shoulder", wait=0.35)
        assert time.monotonic() - t0 >= 0.35
        assert p == pytest.approx(0.0, abs=2e-3)
        assert sim.joint("shoulder").zero == pytest.approx(-math.pi / 2, abs=2e-3)
        assert sim.joint("elbow").zero == 0.0                   # only that joint
        shoulder, _ = read_state(cfg)
        assert shoulder.position == pytest.approx(0.0, abs=2e-3)


def test_zero_mit_too_short_a_wait_still_reads_it_back_once_it_answers(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING, zero_silence=0.3):
        assert zero(cfg, "elbow", wait=0.0, timeout=1.0) == pytest.approx(0.0, abs=2e-3)


def test_zero_refuses_a_driven_joint_and_names_a_silent_one(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim:
        with controller(channel, 1, "AK80-9", -math.pi / 2), pytest.raises(StateError, match="controller"):
            zero(cfg, "shoulder", wait=0.0)
        assert sim.joint("shoulder").zero == 0.0
        sim.inject("elbow", faults.Unplugged())
        with pytest.raises(AkarmError, match="joint 'elbow': no answer") as e:
            zero(cfg, "elbow", wait=0.0, timeout=0.1)
        assert e.value.joint == "elbow"


def test_zero_servo_sets_a_temporary_or_permanent_origin(channel: str) -> None:
    cfg = config_of("servo3", channel)
    with simulated(cfg, q0=[0.4, 0.0, 0.0]) as sim:
        assert zero(cfg, "pan") == pytest.approx(0.0, abs=0.01)
        pan = sim.joint("pan")
        assert pan.origin == pytest.approx(0.4, abs=0.01) and pan.permanent_origin == 0.0
        zero(cfg, "pan", permanent=True)
        assert pan.permanent_origin == pytest.approx(0.4, abs=0.01)


def test_release_disables_mit_joints_and_clears_their_stored_command(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with simulated(cfg, q0=HANGING) as sim:
        codec = mit.codec("AK80-9")
        with can.Bus(interface="virtual", channel=channel) as bus:
            bus.send(can.Message(arbitration_id=1, data=mit.ENTER, is_extended_id=False))
            bus.send(can.Message(arbitration_id=1, is_extended_id=False,
                                 data=codec.encode_command(-math.pi / 2, 0.0, 5.0, 0.2, 0.0)))
            bus.send(can.Message(arbitration_id=2, data=mit.ENTER, is_extended_id=False))
            assert wait_until(lambda: sim.joint("elbow").enabled
                              and sim.joint("shoulder").stored_command.kp == pytest.approx(5.0, 0.01), 2.0)
        states = release(cfg)
        assert not any(d.enabled for d in sim.drivers)
        assert sim.joint("shoulder").stored_command.kp == 0.0    # the next ENTER cannot kick
    assert all(not s.missing for s in states)


def test_release_servo_sends_zero_current(channel: str) -> None:
    cfg = config_of("servo3", channel)
    with simulated(cfg) as sim:
        with can.Bus(interface="virtual", channel=channel) as bus:  # the drivers holding a position first
            for motor_id in (1, 2, 3):
                bus.send(can.Message(arbitration_id=(6 << 8) | motor_id, is_extended_id=True,
                                     data=servo.encode_position_speed(motor_id, 0.0, 1000.0, 10000.0)[1]))
        # (the simulator takes in frames on its own threads)
        assert wait_until(lambda: [d.control for d in sim.drivers] == ["position"] * 3, 2.0)
        states = release(cfg)
        # zero current releases them, as a VESC-derived driver does below its minimum current
        assert wait_until(lambda: [d.control for d in sim.drivers] == [None] * 3, 2.0)
        assert np.allclose(sim.tau, 0.0, atol=1e-9)
    assert all(not s.missing for s in states)
