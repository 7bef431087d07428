"""Simulated servo-mode drivers: each of the seven CAN commands, status frames, release, origin.

robots/servo3.yaml: pan (AK70-10, vertical axis: gravity does not act on it), shoulder (AK70-10,
direction -1), elbow (AK60-6); status frames at 200 Hz. In lock step on a virtual bus.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import can
import numpy as np
import pytest

from akarm.config import RobotConfig
from akarm.protocol import servo, units
from akarm.protocol.motors import MotorModel
from akarm.robotfile.load import load_robot
from akarm.sim import ServoDriver, SimulatedRobot, default_params, faults

from .conftest import ROBOTS, drain

PAN, SHOULDER, ELBOW = 1, 2, 3


def send(bus: can.BusABC, frame: tuple[int, bytes]) -> None:
    bus.send(can.Message(arbitration_id=frame[0], data=frame[1], is_extended_id=True))


def status_of(bus: can.BusABC, motor_id: int) -> list[servo.ServoStatus]:
    return [servo.decode_status(m.arbitration_id, m.data) for m in drain(bus)
            if m.arbitration_id == servo.status_arbitration_id(motor_id)]


@pytest.fixture(scope="module")
def servo3() -> RobotConfig:
    return load_robot(ROBOTS / "servo3.yaml")


@pytest.fixture
def rig(servo3: RobotConfig, channel: str) -> Iterator[tuple[SimulatedRobot, can.BusABC]]:
    with SimulatedRobot(servo3, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        yield sim, bus


def pan_motor(sim: SimulatedRobot) -> MotorModel:
    return sim.config.joints[0].motor


def test_status_frames_at_the_configured_rate_with_the_state(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.model.set_gravity((0.0, 0.0, 0.0))
    sim.set_state([0.5, 0.0, 0.0])
    sim.run_for(1.0)
    frames = drain(bus)
    for mid in (PAN, SHOULDER, ELBOW):
        mine = [m for m in frames if m.arbitration_id == 0x2900 | mid]
        assert len(mine) == 200                      # 200 Hz for 1 s (status_rate_hz in servo3.yaml)
        assert all(m.is_extended_id and len(m.data) == 8 for m in mine)
    last = [m for m in frames if m.arbitration_id == 0x2901][-1]
    m = pan_motor(sim)
    assert bytes(last.data) == servo.encode_status(PAN, units.rad_to_servo_deg(m, 0.5), 0.0, 0.0, 25.0, 0)[1]


def test_status_rate_is_per_joint(servo3: RobotConfig, channel: str) -> None:
    from dataclasses import replace

    joints = (replace(servo3.joints[0], status_rate_hz=50.0), *servo3.joints[1:])
    config = replace(servo3, joints=joints)
    with SimulatedRobot(config, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        sim.run_for(2.0)
        counts = {mid: 0 for mid in (PAN, SHOULDER, ELBOW)}
        for msg in drain(bus):
            counts[msg.arbitration_id & 0xFF] += 1
    assert counts == {PAN: 100, SHOULDER: 400, ELBOW: 400}


def test_current_gives_torque_kt_gr_and_is_limited_to_peak(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    send(bus, servo.encode_current(PAN, 3.0))
    send(bus, servo.encode_current(SHOULDER, 3.0))
    sim.run_for(0.01)
    assert sim.tau[0] == pytest.approx(3.0 * m.kt * m.gear_ratio)      # 3.69 N·m
    assert sim.tau[1] == pytest.approx(-3.0 * m.kt * m.gear_ratio)     # direction -1
    st = status_of(bus, PAN)[-1]
    assert st.current_a == pytest.approx(3.0, abs=0.005)
    send(bus, servo.encode_current(PAN, -50.0))
    sim.run_for(0.01)
    assert sim.tau[0] == pytest.approx(-m.peak_current * m.kt * m.gear_ratio)  # 20.2 A peak: 24.8 N·m


def test_zero_current_or_brake_releases_the_output(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    drv = sim.joint("pan")
    assert isinstance(drv, ServoDriver)
    steps = [(servo.encode_current(PAN, 1.0), "current"), (servo.encode_current(PAN, 0.0), None),
             (servo.encode_current_brake(PAN, 0.5), "brake"), (servo.encode_current_brake(PAN, 0.04), None),
             (servo.encode_current(PAN, -0.05), "current"), (servo.encode_current(PAN, 0.049), None)]
    for frame, control in steps:
        send(bus, frame)
        sim.run_for(0.01)
        assert drv.control == control and drv.enabled == (control is not None), frame
    assert sim.tau[0] == 0.0


def test_release_about_one_second_after_the_last_command(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    drv = sim.joint("pan")
    assert isinstance(drv, ServoDriver)
    send(bus, servo.encode_current(PAN, 1.0))
    sim.run_for(0.5)
    send(bus, servo.encode_current(PAN, 1.0))   # a command restarts the timeout
    sim.run_for(0.99)
    assert drv.control == "current" and sim.tau[0] != 0.0
    sim.run_for(0.02)
    assert drv.control is None and sim.tau[0] == 0.0
    assert len(status_of(bus, PAN)) > 0         # status frames go on while released


def test_duty_runs_at_the_dc_motor_speed(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    p = default_params(m)
    duty = 0.05
    send(bus, servo.encode_duty(PAN, duty))
    sim.run_for(0.8)
    # steady state: (duty·V - kt·GR·v)/R · kt·GR = viscous·v + coulomb·tanh(v/eps); solve for v by bisection
    ktgr = m.kt * m.gear_ratio

    def excess(v: float) -> float:
        return (duty * p.bus_voltage - ktgr * v) / p.resistance * ktgr - p.viscous * v - p.coulomb * math.tanh(
            v / p.coulomb_eps)

    lo, hi = 0.0, duty * p.bus_voltage / ktgr
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if excess(mid) > 0 else (lo, mid)
    assert sim.dq[0] == pytest.approx(lo, rel=0.01)        # ≈ 0.95 rad/s (no-load 0.976)
    assert lo < duty * p.bus_voltage / ktgr                 # friction takes a little


def test_brake_current_stops_and_holds_up_to_its_torque(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    limit = 2.0 * m.kt * m.gear_ratio
    sim.set_state([0.0, 0.0, 0.0], [2.0, 0.0, 0.0])
    send(bus, servo.encode_current_brake(PAN, 2.0))
    taus, speeds = [], []
    for _ in range(400):
        sim.run_for(0.001)
        taus.append(sim.tau[0])
        speeds.append(sim.dq[0])
    assert max(abs(t) for t in taus) <= limit + 1e-9
    assert min(taus) == pytest.approx(-limit)               # brakes at its full torque while sliding
    assert abs(speeds[-1]) < 1e-3                           # stopped


def test_brake_holds_a_light_load_and_slips_under_a_heavy_one(servo3: RobotConfig, channel: str) -> None:
    with SimulatedRobot(servo3, "virtual", channel, realtime=False, q0=[0.0, 0.6, 0.0]) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        g = abs(sim.model.gravity(sim.q)[1])                   # shoulder gravity torque, N·m
        m = sim.config.joints[1].motor
        strong = 2.0 * g / (m.kt * m.gear_ratio)
        send(bus, servo.encode_current_brake(SHOULDER, strong))
        sim.run_for(0.8)
        assert sim.q[1] == pytest.approx(0.6, abs=0.005)
        send(bus, servo.encode_current_brake(SHOULDER, 0.3 * g / (m.kt * m.gear_ratio)))
        sim.run_for(0.3)
        assert sim.q[1] > 0.65                                 # leaning forward further: it slips


def test_rpm_speed_loop_reaches_the_commanded_erpm(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    send(bus, servo.encode_rpm(PAN, 2000.0))
    sim.run_for(0.6)
    assert sim.dq[0] == pytest.approx(units.erpm_to_rad_s(m, 2000.0), rel=0.005)  # 0.997 rad/s
    st = status_of(bus, PAN)[-1]
    assert st.speed_erpm == pytest.approx(2000.0, abs=10.0)


def test_set_pos_moves_at_12000_erpm_and_40000_erpm_per_s(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    send(bus, servo.encode_position(PAN, 140.0))
    speeds = []
    for _ in range(950):
        sim.run_for(0.001)
        speeds.append(sim.dq[0])
    v = np.array(speeds)
    assert v.max() == pytest.approx(units.erpm_to_rad_s(m, 12_000.0), rel=0.03)        # 5.98 rad/s
    accel = np.diff(v[:200]) / 0.001
    assert np.median(accel[20:150]) == pytest.approx(units.erpm_to_rad_s(m, 40_000.0), rel=0.05)  # 19.9 rad/s²
    assert math.degrees(sim.q[0]) == pytest.approx(140.0, abs=0.1)
    st = status_of(bus, PAN)[-1]
    assert st.position_deg == pytest.approx(140.0, abs=0.1)


def test_position_speed_move_has_the_commanded_speed_and_acceleration(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    speed_erpm, accel_erpm_s = 3000.0, 5000.0
    v_max, a_max = units.erpm_to_rad_s(m, speed_erpm), units.erpm_to_rad_s(m, accel_erpm_s)  # 1.50 rad/s, 2.49 rad/s²
    send(bus, servo.encode_position_speed(PAN, 90.0, speed_erpm, accel_erpm_s))
    qs, vs = [], []
    dt = 0.002
    for _ in range(int(0.98 / dt)):
        sim.run_for(dt)
        qs.append(sim.q[0])
        vs.append(sim.dq[0])
    send(bus, servo.encode_position_speed(PAN, 90.0, speed_erpm, accel_erpm_s))  # keep it from releasing
    for _ in range(int(0.98 / dt)):
        sim.run_for(dt)
        qs.append(sim.q[0])
        vs.append(sim.dq[0])
    v = np.array(vs)
    t = np.arange(1, len(v) + 1) * dt
    # peak speed: the commanded one (measured 1.50 rad/s, within 2 %)
    assert v.max() == pytest.approx(v_max, rel=0.02)
    # acceleration: slope of a line fitted to the speed while it ramps from 10 % to 90 % of the peak
    ramp = (v > 0.1 * v_max) & (v < 0.9 * v_max) & (t < v_max / a_max + 0.1)
    slope = np.polyfit(t[ramp], v[ramp], 1)[0]
    assert slope == pytest.approx(a_max, rel=0.03)
    # cruise: time spent at the peak speed matches a trapezoid of that length
    cruise = np.sum(v > 0.98 * v_max) * dt
    assert cruise == pytest.approx(math.radians(90.0) / v_max - v_max / a_max, abs=0.05)
    # arrives and stays within 0.15° (measured: 0.1° overshoot while the PID's integral unwinds the
    # friction torque it carried during the move)
    arrived = t > math.radians(90.0) / v_max + v_max / a_max + 0.05
    assert np.degrees(np.abs(np.array(qs)[arrived] - math.radians(90.0))).max() < 0.15


def test_origin_temporary_permanent_and_default(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    m = pan_motor(sim)
    drv = sim.joint("pan")
    sim.set_state([0.3, 0.0, 0.0])
    send(bus, servo.encode_origin(PAN, servo.OriginMode.TEMPORARY))
    sim.run_for(0.01)
    assert status_of(bus, PAN)[-1].position_deg == pytest.approx(0.0, abs=0.05)
    sim.set_state([0.5, 0.0, 0.0])
    sim.run_for(0.01)
    assert status_of(bus, PAN)[-1].position_deg == pytest.approx(units.rad_to_servo_deg(m, 0.2), abs=0.05)
    drv.inject(faults.Unplugged(power_lost=True))          # a power cycle forgets a temporary origin
    drv.clear_faults()
    sim.run_for(0.01)
    assert status_of(bus, PAN)[-1].position_deg == pytest.approx(units.rad_to_servo_deg(m, 0.5), abs=0.05)
    send(bus, servo.encode_origin(PAN, servo.OriginMode.PERMANENT))
    sim.run_for(0.01)
    drv.inject(faults.Unplugged(power_lost=True))
    drv.clear_faults()
    sim.set_state([0.6, 0.0, 0.0])
    sim.run_for(0.01)
    assert status_of(bus, PAN)[-1].position_deg == pytest.approx(units.rad_to_servo_deg(m, 0.1), abs=0.05)
    send(bus, servo.encode_origin(PAN, servo.OriginMode.RESTORE_DEFAULT))
    sim.run_for(0.01)
    assert status_of(bus, PAN)[-1].position_deg == pytest.approx(units.rad_to_servo_deg(m, 0.6), abs=0.05)


def test_position_commands_are_relative_to_the_origin(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    sim.set_state([0.4, 0.0, 0.0])
    send(bus, servo.encode_origin(PAN, 0))
    send(bus, servo.encode_position(PAN, 10.0))
    sim.run_for(0.9)
    assert sim.q[0] == pytest.approx(0.4 + math.radians(10.0), abs=1e-3)


def test_position_hold_against_gravity_integrates_the_error_away(servo3: RobotConfig, channel: str) -> None:
    with SimulatedRobot(servo3, "virtual", channel, realtime=False) as sim, \
            can.Bus(interface="virtual", channel=channel) as bus:
        m = sim.config.joints[1].motor
        target = 0.5                                     # joint rad; the shoulder's motor runs the other way
        send(bus, servo.encode_position_speed(SHOULDER, units.rad_to_servo_deg(m, -target), 6000.0, 20000.0))
        sim.run_for(0.95)
        assert sim.q[1] == pytest.approx(target, abs=2e-3)


def test_malformed_and_out_of_range_commands_are_ignored(rig: tuple[SimulatedRobot, can.BusABC]) -> None:
    sim, bus = rig
    bad_brake = (0x200 | PAN, (-1000).to_bytes(4, "big", signed=True))  # negative brake current
    send(bus, bad_brake)
    send(bus, (0x100 | PAN, b"\x00\x00"))                                 # too short
    sim.run_for(0.01)
    assert sim.joint("pan").control is None  # type: ignore[attr-defined]
