"""CAN bus load of a robot configuration: how much of each bus the control loop uses.

Frame lengths (classic CAN, 8 data bytes, including the 3-bit interframe space; see
``ak-protocol.md`` §4):

==========  =========  =========================
frame       nominal    worst-case bit stuffing
==========  =========  =========================
standard    111 bits   135 bits
extended    131 bits   160 bits
==========  =========  =========================

In general a frame of ``n`` data bytes has ``47 + 8n`` bits (standard, 11-bit ID) or ``67 + 8n``
(extended, 29-bit ID); bit stuffing covers SOF..CRC (``34 + 8n`` resp. ``54 + 8n`` bits) and adds
at most one bit per four after the first five: ``(stuffable - 1) // 4``.

Traffic per joint:

- MIT, firmware v2: per control cycle one standard command and one standard reply (8 bytes each);
- MIT, firmware v3: per cycle one extended command and one extended ``0x29xx`` status reply;
- servo: per cycle one extended command (8 bytes, ``SET_POS_SPD``, the longest), plus the status
  frames the motor sends on its own at ``status_rate_hz`` (extended, 8 bytes), whatever the loop rate.

Load is bits per second over the bit rate, in percent. :func:`bus_loads` reports both the nominal
load (no stuffing bits) and the worst case (every frame maximally stuffed), and the highest loop rate
that keeps each under :data:`LOAD_LIMIT` (80 %, leaving room for retransmissions). Real traffic lies
between the two: MIT data is rarely stuffed to the maximum.

Policy used by the loader (documented here so the controller and ``akarm check`` agree): a
configuration whose *nominal* load exceeds 80 % is an error, since it overloads the bus whatever the
data; one whose worst case exceeds 80 % but whose nominal load does not is accepted with a warning
(six MIT v2 joints at 500 Hz are exactly this case: 67 % nominal, 81 % worst case; robots/arm6.yaml
runs at 480 Hz, 64 % and 78 %, so that the shipped example stays under both).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from akarm.config import JointConfig, RobotConfig

__all__ = [
    "LOAD_LIMIT",
    "BusLoad",
    "JointTraffic",
    "bus_loads",
    "frame_bits",
    "joint_traffic",
    "load_of",
]

#: Fraction of a bus the control loop may use (the rest is left for retransmissions and other nodes).
LOAD_LIMIT = 0.8


def frame_bits(data_bytes: int = 8, *, extended: bool = False, stuffed: bool = False) -> int:
    """Bit times one classic CAN data frame occupies, interframe space included.

    Args:
        data_bytes: 0-8 data bytes.
        extended: 29-bit identifier instead of 11-bit.
        stuffed: add the largest possible number of stuff bits.

    >>> frame_bits(), frame_bits(stuffed=True), frame_bits(extended=True), frame_bits(extended=True, stuffed=True)
    (111, 135, 131, 160)
    """
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"a classic CAN frame carries 0-8 data bytes, not {data_bytes}")
    stuffable = (54 if extended else 34) + 8 * data_bytes  # SOF through CRC
    bits = stuffable + 13  # CRC delimiter, ACK slot and delimiter, EOF (7), interframe space (3)
    if stuffed:
        bits += (stuffable - 1) // 4
    return bits


@dataclass(frozen=True)
class JointTraffic:
    """One joint's frames: per control cycle and per second regardless of the loop rate.

    Attributes:
        standard_per_cycle, extended_per_cycle: frames (command and reply) every control cycle.
        extended_per_s: frames per second sent on the motor's own schedule (servo status frames).
    """

    standard_per_cycle: int = 0
    extended_per_cycle: int = 0
    extended_per_s: float = 0.0

    def bits(self, rate_hz: float, *, stuffed: bool) -> float:
        """Bits per second this joint puts on its bus at loop rate ``rate_hz`` (Hz)."""
        std = frame_bits(8, stuffed=stuffed)
        ext = frame_bits(8, extended=True, stuffed=stuffed)
        per_cycle = self.standard_per_cycle * std + self.extended_per_cycle * ext
        return rate_hz * per_cycle + self.extended_per_s * ext


def joint_traffic(joint: JointConfig) -> JointTraffic:
    """The frames ``joint`` costs, from its mode, firmware and status rate (see the module text)."""
    if joint.mode == "servo":
        return JointTraffic(extended_per_cycle=1, extended_per_s=float(joint.status_rate_hz))
    if joint.firmware == "v3":
        return JointTraffic(extended_per_cycle=2)
    return JointTraffic(standard_per_cycle=2)


def _max_rate(traffic: Iterable[JointTraffic], bitrate: float, *, stuffed: bool, limit: float) -> float:
    items = list(traffic)
    fixed = sum(t.bits(0.0, stuffed=stuffed) for t in items)
    per_hz = sum(t.bits(1.0, stuffed=stuffed) for t in items) - fixed
    room = limit * bitrate - fixed
    if room <= 0:
        return 0.0
    return float("inf") if per_hz == 0 else room / per_hz


@dataclass(frozen=True)
class BusLoad:
    """The load one bus carries at one loop rate.

    Attributes:
        bus: bus name. bitrate: bit/s. rate_hz: the loop rate this was computed for (Hz).
        joints: names of the joints on the bus.
        percent: worst-case load (every frame maximally stuffed), % of the bit rate.
        percent_nominal: load without stuffing bits, %.
        max_rate_hz: highest loop rate keeping the worst-case load at or under 80 %, Hz.
        max_rate_hz_nominal: highest loop rate keeping the nominal load at or under 80 %, Hz.
        saturation_hz: loop rate at which the bus is 100 % busy in the worst case, Hz.
        saturation_hz_nominal: loop rate at which the bus is 100 % busy without stuffing bits, Hz.
    """

    bus: str
    bitrate: int
    rate_hz: float
    joints: tuple[str, ...]
    percent: float
    percent_nominal: float
    max_rate_hz: float
    max_rate_hz_nominal: float
    saturation_hz: float
    saturation_hz_nominal: float

    @property
    def over_limit(self) -> bool:
        """The nominal load is above 80 %: the configuration is rejected."""
        return self.percent_nominal > 100 * LOAD_LIMIT

    @property
    def worst_case_over_limit(self) -> bool:
        """The worst-case load is above 80 % (a warning when the nominal load is not)."""
        return self.percent > 100 * LOAD_LIMIT


def load_of(name: str, bitrate: int, rate_hz: float, joints: Iterable[JointConfig]) -> BusLoad:
    """The load of bus ``name`` (``bitrate`` bit/s) carrying ``joints`` at loop rate ``rate_hz`` (Hz)."""
    joints = tuple(joints)
    traffic = [joint_traffic(j) for j in joints]
    worst = sum(t.bits(rate_hz, stuffed=True) for t in traffic)
    nominal = sum(t.bits(rate_hz, stuffed=False) for t in traffic)
    return BusLoad(
        bus=name,
        bitrate=bitrate,
        rate_hz=float(rate_hz),
        joints=tuple(j.name for j in joints),
        percent=100.0 * worst / bitrate,
        percent_nominal=100.0 * nominal / bitrate,
        max_rate_hz=_max_rate(traffic, bitrate, stuffed=True, limit=LOAD_LIMIT),
        max_rate_hz_nominal=_max_rate(traffic, bitrate, stuffed=False, limit=LOAD_LIMIT),
        saturation_hz=_max_rate(traffic, bitrate, stuffed=True, limit=1.0),
        saturation_hz_nominal=_max_rate(traffic, bitrate, stuffed=False, limit=1.0),
    )


def bus_loads(config: RobotConfig, rate_hz: float | None = None) -> dict[str, BusLoad]:
    """Load of every bus of ``config`` at ``rate_hz`` (default: the config's ``rate_hz``), by bus name; a
    gripper's motor counts as a joint's."""
    rate = config.rate_hz if rate_hz is None else rate_hz
    return {
        name: load_of(name, bus.bitrate, rate, (j for j in config.motors if j.bus == name))
        for name, bus in config.buses.items()
    }
