"""Bus load: frame lengths, per-joint traffic, the notes' numbers for six MIT joints."""

from __future__ import annotations

from dataclasses import replace

import pytest

from akarm.config import Gains, JointConfig, Limits
from akarm.config.busload import LOAD_LIMIT, bus_loads, frame_bits, joint_traffic, load_of
from akarm.protocol.motors import get
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS

LIMITS = Limits(-1.0, 1.0, 2.0, 10.0, 100.0, 10.0)


def joint(i: int, mode: str = "mit", firmware: str = "v2", status_rate_hz: float = 50.0) -> JointConfig:
    return JointConfig(name=f"j{i}", bus="arm", can_id=i, motor=get("AK80-9"), mode=mode,  # type: ignore[arg-type]
                       limits=LIMITS, firmware=firmware, gains=Gains(10, 1),  # type: ignore[arg-type]
                       status_rate_hz=status_rate_hz)


def test_frame_lengths_match_the_notes() -> None:
    assert frame_bits(8) == 111
    assert frame_bits(8, stuffed=True) == 135
    assert frame_bits(8, extended=True) == 131
    assert frame_bits(8, extended=True, stuffed=True) == 160
    # shorter frames: 8 bits per byte less, stuffing bounded by (stuffable - 1) // 4
    assert frame_bits(6) == 95
    assert frame_bits(0) == 47
    assert frame_bits(0, stuffed=True) == 47 + 8
    with pytest.raises(ValueError):
        frame_bits(9)


def test_traffic_per_mode_and_firmware() -> None:
    assert joint_traffic(joint(1)).bits(500, stuffed=True) == 500 * 2 * 135
    assert joint_traffic(joint(1, firmware="v3")).bits(500, stuffed=True) == 500 * 2 * 160
    servo = joint_traffic(joint(1, mode="servo", status_rate_hz=200))
    assert servo.bits(100, stuffed=False) == 100 * 131 + 200 * 131
    # the status frames do not depend on the loop rate
    assert servo.bits(0, stuffed=True) == 200 * 160


def test_six_mit_joints_at_500_hz_use_66_to_81_percent() -> None:
    load = load_of("arm", 1_000_000, 500, [joint(i) for i in range(1, 7)])
    assert load.percent_nominal == pytest.approx(66.6)
    assert load.percent == pytest.approx(81.0)
    assert 66 <= load.percent_nominal < load.percent <= 81.0 + 1e-9
    assert load.joints == tuple(f"j{i}" for i in range(1, 7))


def test_six_mit_joints_ceiling_is_620_to_750_hz_and_80_percent_rates() -> None:
    load = load_of("arm", 1_000_000, 500, [joint(i) for i in range(1, 7)])
    # 100 % of the bus: the notes' "roughly 620-750 Hz"
    assert load.saturation_hz == pytest.approx(1e6 / (12 * 135))  # 617.3
    assert load.saturation_hz_nominal == pytest.approx(1e6 / (12 * 111))  # 750.8
    assert 610 < load.saturation_hz < load.saturation_hz_nominal < 755
    # under the 80 % limit
    assert load.max_rate_hz == pytest.approx(LOAD_LIMIT * 1e6 / (12 * 135))  # 493.8
    assert load.max_rate_hz_nominal == pytest.approx(LOAD_LIMIT * 1e6 / (12 * 111))  # 600.6
    at_max = load_of("arm", 1_000_000, load.max_rate_hz, [joint(i) for i in range(1, 7)])
    assert at_max.percent == pytest.approx(80.0)
    assert not load.over_limit and load.worst_case_over_limit


def test_servo_status_frames_lower_the_ceiling() -> None:
    joints = [joint(i, mode="servo", status_rate_hz=500) for i in range(1, 4)]
    load = load_of("arm", 1_000_000, 200, joints)
    fixed = 3 * 500 * 160
    assert load.percent == pytest.approx(100 * (3 * 200 * 160 + fixed) / 1e6)
    assert load.max_rate_hz == pytest.approx((0.8e6 - fixed) / (3 * 160))
    # status traffic alone over the limit: no loop rate fits
    many = [joint(i, mode="servo", status_rate_hz=500) for i in range(1, 12)]
    assert load_of("arm", 1_000_000, 10, many).max_rate_hz == 0.0


def test_empty_bus_and_bitrate() -> None:
    empty = load_of("aux", 1_000_000, 500, [])
    assert empty.percent == 0.0 and empty.max_rate_hz == float("inf")
    slow = load_of("arm", 500_000, 500, [joint(1)])
    assert slow.percent == pytest.approx(2 * 2 * 135 * 500 / 1e6 * 100)


def test_bus_loads_of_the_robots() -> None:
    arm6 = bus_loads(load_robot(ROBOTS / "arm6.yaml"))
    assert list(arm6) == ["arm"]
    # 480 Hz: under the 80 % limit even with every frame maximally stuffed (no warning)
    assert arm6["arm"].percent == pytest.approx(100 * 480 * 12 * 135 / 1e6)  # 77.8
    assert arm6["arm"].percent_nominal == pytest.approx(100 * 480 * 12 * 111 / 1e6)  # 63.9
    assert not arm6["arm"].over_limit and not arm6["arm"].worst_case_over_limit
    biarm = bus_loads(load_robot(ROBOTS / "biarm.yaml"))
    assert set(biarm) == {"left", "right"}
    assert biarm["left"].joints == ("left_shoulder", "left_elbow")
    assert biarm["right"].percent == pytest.approx(100 * 500 * 4 * 135 / 1e6)
    servo3 = load_robot(ROBOTS / "servo3.yaml")
    assert bus_loads(servo3)["arm"].percent == pytest.approx(100 * 3 * (200 + 200) * 160 / 1e6)
    # another loop rate than the file's
    assert bus_loads(replace(servo3, rate_hz=100), 400)["arm"].rate_hz == 400
