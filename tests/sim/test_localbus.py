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


def test_a_reader_that_falls_behind_loses_the_oldest_frames_and_counts_them(pair):
    a, b = pair
    n = 700
    for k in range(n):
        a.send(_msg(1, k.to_bytes(2, "big")))
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
