"""akarm_local across threads and processes: a blocking receive, frames between processes, a dead
process's ring reclaimed."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import can
import pytest

from akarm.buses import localbus
from akarm.buses.bus import open_bus
from akarm.buses.localbus import LocalBus
from akarm.config import BusConfig
from akarm.errors import BusError

from ..sim.test_localbus import bus, pair  # noqa: F401 (fixtures)


def test_recv_waits_for_a_frame_from_another_thread_and_times_out_without_one(pair):  # noqa: F811
    import threading

    a, b = pair
    t0 = time.monotonic()
    assert b.recv(0.05) is None
    assert time.monotonic() - t0 >= 0.05
    timer = threading.Timer(0.05, lambda: a.send(can.Message(arbitration_id=3, data=b"late", is_extended_id=False)))
    timer.start()
    try:
        m = b.recv(5.0)
    finally:
        timer.join()
    assert m is not None and m.data == b"late"


def test_frames_cross_processes(bus, channel):  # noqa: F811
    rx = bus()
    code = ("import can, akarm.buses.localbus as lb\n"
            f"b = lb.LocalBus({channel!r})\n"
            "for k in range(50):\n"
            "    b.send(can.Message(arbitration_id=0x300 + k, data=bytes([k] * 8), is_extended_id=False))\n"
            "b.shutdown()\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
    got = []
    while (m := rx.recv(0.0)) is not None:
        got.append((m.arbitration_id, bytes(m.data)))
    assert got == [(0x300 + k, bytes([k] * 8)) for k in range(50)]


def test_a_dead_process_ring_is_reclaimed_and_a_full_channel_is_refused(channel):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    keeper = LocalBus(channel)
    try:
        # every other place taken by a process that no longer exists: a new bus still gets one
        for r in range(localbus._RINGS):
            if r != keeper._ring:
                localbus._OWNER.pack_into(keeper._mm, localbus._OWNERS_AT + r * localbus._OWNER.size, dead.pid, 7, 1)
        late = LocalBus(channel)
        late.shutdown()
        # every place taken by a live process: refused, naming it
        for r in range(localbus._RINGS):
            if r != keeper._ring:
                localbus._OWNER.pack_into(keeper._mm, localbus._OWNERS_AT + r * localbus._OWNER.size,
                                          os.getpid(), 7, 1)
        with pytest.raises(can.CanInitializationError, match=f"all 32 places.*{os.getpid()}"):
            LocalBus(channel)
        with pytest.raises(BusError, match="cannot open CAN bus 'arm'"):
            open_bus(BusConfig("arm", "akarm_local", channel))
    finally:
        for r in range(localbus._RINGS):
            if r != keeper._ring:
                localbus._OWNER.pack_into(keeper._mm, localbus._OWNERS_AT + r * localbus._OWNER.size, 0, 0, 1)
        keeper.shutdown()
