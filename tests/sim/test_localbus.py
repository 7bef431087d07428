"""akarm_local: the machine-wide shared-memory CAN bus (frames, processes, overruns, bad files)."""

from __future__ import annotations

import struct
import time

import can
import numpy as np
import pytest

import akarm
from akarm.buses import localbus
from akarm.buses.bus import open_bus
from akarm.buses.localbus import LocalBus, channel_path
from akarm.config import BusConfig
from akarm.sim import SimulatedRobot


@pytest.fixture
def bus(channel):
    """``bus(**kw)`` opens a LocalBus on this test's channel (``bus(channel=...)`` elsewhere); every
    bus opened is shut down when the test ends."""
    opened: list[LocalBus] = []

    def open_(**kw) -> LocalBus:
        kw.setdefault("channel", channel)
        opened.append(LocalBus(**kw))
        return opened[-1]

    yield open_
    for b in opened:
        b.shutdown()


@pytest.fixture
def pair(bus):
    return bus(), bus()


def _msg(arbitration_id: int, data: bytes, extended: bool = False, **kw) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=extended, **kw)


def test_a_frame_arrives_exactly_at_the_other_bus_and_not_back(pair):
    a, b = pair
    before = time.time()
    a.send(_msg(0x2903, bytes.fromhex("0102030405060708"), extended=True))
    a.send(_msg(0x7FF, b"\xaa"))
    a.send(_msg(0x141, b"", is_remote_frame=True, dlc=6))
    got = [b.recv(0.5) for _ in range(3)]
    assert [(m.arbitration_id, m.is_extended_id, m.is_remote_frame, m.dlc, bytes(m.data)) for m in got] == [
        (0x2903, True, False, 8, bytes.fromhex("0102030405060708")),
        (0x7FF, False, False, 1, b"\xaa"),
        (0x141, False, True, 6, b""),
    ]
    assert all(m.is_rx and m.channel == b.channel and before <= m.timestamp <= time.time() for m in got)
    assert b.recv(0.0) is None
    assert a.recv(0.0) is None  # its own frames are not echoed


def test_receive_own_messages_echoes_them(bus):
    a = bus(receive_own_messages=True)
    a.send(_msg(0x10, b"\x01"))
    m = a.recv(0.1)
    assert m is not None and m.arbitration_id == 0x10 and not m.is_rx


def test_channels_do_not_mix(bus, channel):
    a, b, other = bus(), bus(), bus(channel=channel + "-other")
    a.send(_msg(1, b"x"))
    assert other.recv(0.02) is None
    assert b.recv(0.1).data == b"x"


def test_order_per_sender_is_kept_and_every_sender_is_heard(bus):
    a, b, rx = bus(), bus(), bus()
    for k in range(200):
        a.send(_msg(1, k.to_bytes(2, "big")))
        b.send(_msg(2, k.to_bytes(2, "big")))
    got: dict[int, list[int]] = {1: [], 2: []}
    while (m := rx.recv(0.0)) is not None:
        got[m.arbitration_id].append(int.from_bytes(m.data, "big"))
    assert got == {1: list(range(200)), 2: list(range(200))}


def _flood(bus: LocalBus, n: int) -> None:
    """Send frames 0 .. n - 1 (their number in the data), more than a reader's ring keeps if n > 512."""
    for k in range(n):
        bus.send(_msg(1, k.to_bytes(2, "big")))


def test_a_reader_that_falls_behind_loses_the_oldest_frames_and_counts_them(pair):
    a, b = pair
    n = 700
    _flood(a, n)
    got = []
    while (m := b.recv(0.0)) is not None:
        got.append(int.from_bytes(m.data, "big"))
    assert got == list(range(n - 512, n))
    assert b.overruns == n - 512


def test_a_half_written_slot_is_not_delivered(pair):
    a, b = pair
    a.send(_msg(1, b"good"))
    # scribble on the body of the next slot and publish it with a matching sequence number:
    # its CRC no longer matches, so the reader waits instead of taking it
    at = localbus._slot(a._ring, 1)
    a._mm[at + 12:at + 20] = b"\xff" * 8
    struct.pack_into("<Q", a._mm, at, 2)
    assert b.recv(0.0).data == b"good"
    assert b.recv(0.0) is None


def test_a_slot_still_holding_the_last_laps_frame_is_not_delivered(pair):
    """A weakly ordered CPU may show a reader the new sequence number beside the old body and CRC:
    the CRC covers the sequence number, so that stale frame is refused instead of delivered."""
    a, b = pair
    for k in range(localbus._SLOTS):  # fill the ring once; the reader takes them all
        a.send(_msg(1, k.to_bytes(2, "big")))
    while b.recv(0.0) is not None:
        pass
    at = localbus._slot(a._ring, localbus._SLOTS)  # the slot of frame 512 is the slot of frame 0
    assert struct.unpack_from("<Q", a._mm, at)[0] == 1
    struct.pack_into("<Q", a._mm, at, localbus._SLOTS + 1)  # the new number, with the old body and CRC
    assert b.recv(0.0) is None
    a._seq = localbus._SLOTS  # the writer now writes frame 512 for real: delivered
    a.send(_msg(1, b"new"))
    assert b.recv(0.0).data == b"new"


def test_filters_apply(bus):
    a = bus()
    b = bus(can_filters=[{"can_id": 0x20, "can_mask": 0x7FF, "extended": False}])
    a.send(_msg(0x10, b"no"))
    a.send(_msg(0x20, b"yes"))
    assert b.recv(0.1).data == b"yes"
    assert b.recv(0.0) is None


def test_python_can_finds_it_by_name(channel):
    a = can.Bus(interface="akarm_local", channel=channel)
    b = open_bus(BusConfig("arm", "akarm_local", channel))
    try:
        assert isinstance(a, LocalBus) and isinstance(b, LocalBus)
        a.send(_msg(5, b"hi"))
        assert b.recv(0.1).data == b"hi"
    finally:
        a.shutdown()
        b.shutdown()


def test_classic_frames_only_and_no_send_after_shutdown(pair):
    a, _ = pair
    with pytest.raises(can.CanOperationError, match="classic CAN"):
        a.send(can.Message(arbitration_id=1, data=bytes(12), is_fd=True))
    a.shutdown()
    with pytest.raises(can.CanOperationError, match="shut down"):
        a.send(_msg(1, b""))


def test_the_last_bus_deletes_the_file_and_a_new_one_starts_fresh(bus, channel):
    a, b = bus(), bus()
    path = channel_path(channel)
    assert path.exists()
    a.shutdown()
    assert path.exists()
    b.shutdown()
    assert not path.exists()
    c, d = bus(), bus()
    c.send(_msg(9, b"again"))
    assert d.recv(0.1).data == b"again"


def test_a_foreign_file_is_refused_not_overwritten(channel):
    path = channel_path(channel)
    path.write_bytes(b"not a channel")
    try:
        with pytest.raises(can.CanInitializationError, match="not an akarm_local channel"):
            LocalBus(channel)
        assert path.read_bytes() == b"not a channel"
    finally:
        path.unlink()


def test_arm_moves_against_the_simulator_over_it(planar2, channel):
    config = planar2.with_bus(interface="akarm_local", channel=channel)
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        target = np.array([0.4, -0.6])
        arm.move_to(target)
        for _ in range(100):
            arm.sleep(0.01)
        assert np.max(np.abs(arm.state().q - target)) < 1e-3


# -- drain: the control loop's read, a cycle's frames in one call -------------------------------

def _fields(m: can.Message) -> tuple[int, bool, bool, int, bytes]:
    """A message as drain() gives a frame."""
    return m.arbitration_id, m.is_extended_id, not (m.is_remote_frame or m.is_error_frame), m.dlc, bytes(m.data)


FRAMES = [_msg(0x2903, bytes.fromhex("0102030405060708"), extended=True), _msg(0x7FF, b"\xaa"),
          _msg(0x141, b"", is_remote_frame=True, dlc=6), _msg(0x2000_0004, b"\x00\x01\x02", extended=True,
                                                                is_error_frame=True)]


def test_drain_gives_what_recv_gives_field_for_field(bus):
    a, by_recv, by_drain = bus(), bus(), bus()
    for m in FRAMES:
        a.send(m)
    expected = [_fields(m) for m in iter(lambda: by_recv.recv(0.0), None)]
    assert len(expected) == 4 and expected[2] == (0x141, False, False, 6, b"")  # (a remote frame has no data)
    assert by_drain.drain(100) == expected
    assert by_drain.drain(100) == [] and a.drain(100) == []  # each frame once; its own are not echoed


def test_drain_takes_at_most_its_limit_and_every_sender_in_order(bus):
    a, b, rx = bus(), bus(), bus()
    for k in range(5):
        a.send(_msg(1, bytes([k])))
        b.send(_msg(2, bytes([k])))
    first = rx.drain(3)
    rest = rx.drain(100)
    assert len(first) == 3 and len(rest) == 7
    got: dict[int, list[int]] = {1: [], 2: []}
    for arbitration_id, _ext, _plain, _dlc, data in first + rest:
        got[arbitration_id].append(data[0])
    assert got == {1: list(range(5)), 2: list(range(5))}


def test_drain_counts_an_overrun_and_skips_half_written_and_stale_slots(pair):
    a, b = pair
    n = 700
    _flood(a, n)
    got = [int.from_bytes(f[4], "big") for f in b.drain(1024)]
    assert got == list(range(n - 512, n)) and b.overruns == n - 512
    # a published slot whose CRC does not match (half written, or the last lap's body) is left for later
    at = localbus._slot(a._ring, n)
    struct.pack_into("<Q", a._mm, at, n + 1)  # the new number beside the last lap's body and CRC
    assert b.drain(10) == []
    a.send(_msg(1, b"new"))  # the writer writes it for real
    assert [f[4] for f in b.drain(10)] == [b"new"]


def test_drain_applies_filters_and_echoes_own_frames_when_asked(bus):
    a = bus(receive_own_messages=True)
    b = bus(can_filters=[{"can_id": 0x20, "can_mask": 0x7FF, "extended": False}])
    a.send(_msg(0x10, b"no"))
    a.send(_msg(0x20, b"yes"))
    assert b.drain(10) == [(0x20, False, True, 3, b"yes")]
    assert [f[4] for f in a.drain(10)] == [b"no", b"yes"]


def test_send_frames_puts_what_send_puts_field_for_field(bus):
    a, rx = bus(), bus()
    frames = [(0x2903, True, bytes(range(8))), (0x141, False, b"\x01\x02\x03"), (0x1FFF_FFFF, True, b"")]
    a.send_frames(frames)
    for arbitration_id, extended, data in frames:
        a.send(_msg(arbitration_id, data, extended))
    got = [_fields(m) for m in iter(lambda: rx.recv(0.0), None)]
    assert got == [(arbitration_id, extended, True, len(data), data) for arbitration_id, extended, data in frames] * 2
    # a frame too long refuses the whole batch: nothing of it is written
    with pytest.raises(can.CanOperationError, match="at most 8 bytes"):
        a.send_frames([(0x1, False, b"ok"), (0x2, False, bytes(9))])
    assert rx.recv(0.0) is None
    a.send_frames([])
    assert rx.recv(0.0) is None
    a.shutdown()
    with pytest.raises(can.CanOperationError, match="shut down"):
        a.send_frames([(0x1, False, b"")])


def test_an_akarm_local_bus_that_refuses_the_loops_frames_is_lost_and_stops_the_arm(planar2, channel):
    config = planar2.with_bus(interface="akarm_local", channel=channel)
    with SimulatedRobot(config, realtime=False) as sim, akarm.Arm(config, clock=sim.clock,
                                                                  remember_positions=False) as arm:
        arm.enable()
        bus = arm.observe.buses["arm"]
        assert isinstance(bus, LocalBus)

        def full(frames):
            raise can.CanOperationError("Transmit buffer full")

        bus.send_frames = full  # the loop's commands go this way on akarm_local
        with pytest.raises(akarm.BusLost, match="Transmit buffer full"):
            arm.sleep(0.5)
        assert arm.mode is akarm.Mode.FAULT


def test_a_simulators_beat_tells_the_others_when_it_last_read_the_channel(bus):
    controller, simulator, viewer = bus(), bus(), bus()
    assert controller.peers_read() is None  # nobody beats: no simulator to judge
    before = time.monotonic()
    simulator.beat()
    last = controller.peers_read()
    assert last is not None and before <= last <= time.monotonic()
    assert simulator.peers_read() is None, "its own beat is not a peer's"
    time.sleep(0.01)
    assert controller.peers_read() == last and viewer.peers_read() == last  # an old read stays old
    simulator.shutdown()
    assert controller.peers_read() is None, "a simulator gone says nothing"
    bus()  # its ring taken anew: the new owner does not inherit the old beat
    assert controller.peers_read() is None
