"""The CPU idle latency request: what it writes, that it is withdrawn, and refusals that never raise."""

from __future__ import annotations

import os
import struct

import pytest

from akarm.control.cpuidle import IdleLatencyHold
from akarm.errors import ArgumentError


def _open_fds() -> set[str]:
    return set(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else set()


def test_acquire_writes_the_bound_and_holds_the_file_open_until_release(tmp_path):
    dev = tmp_path / "cpu_dma_latency"
    dev.write_bytes(b"")
    hold = IdleLatencyHold(latency_us=5, path=str(dev))
    before = _open_fds()
    report = hold.acquire()
    assert report == "CPU idle latency held at 5 µs"
    assert hold.held
    assert dev.read_bytes() == struct.pack("=i", 5)  # what the kernel reads: a native 32-bit int
    if before:
        assert len(_open_fds() - before) == 1  # the request lasts as long as this descriptor
    assert hold.acquire() == report  # again: the same request, no second descriptor
    if before:
        assert len(_open_fds() - before) == 1
    hold.release()
    assert not hold.held
    if before:
        assert _open_fds() == before
    hold.release()  # again: harmless


def test_a_missing_or_forbidden_device_is_reported_not_raised(tmp_path):
    hold = IdleLatencyHold(path=str(tmp_path / "absent"))
    report = hold.acquire()
    assert report.startswith("CPU idle latency not held")
    assert str(tmp_path / "absent") in report and "root" in report  # what failed, and what allows it
    assert not hold.held
    hold.release()


@pytest.mark.parametrize("bad", [-1, 1.5, True, 2 ** 31, "0"])
def test_a_bound_that_is_not_whole_microseconds_is_refused(bad):
    with pytest.raises(ArgumentError, match="latency_us"):
        IdleLatencyHold(latency_us=bad)
