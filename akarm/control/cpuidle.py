"""Keeping the CPUs out of deep idle states while the control loop runs (Linux PM QoS).

Between cycles the loop's thread sleeps, and its core goes idle. A deep idle state takes time to
leave, and on many processors (and on a virtual machine whose host gives the idle core away) it
loses the core's caches, so every cycle starts cold. On our 2-core virtual machines (``haltpoll``
cpuidle driver), arm6 at 480 Hz measured, with the request held against without, in three pairs of
runs of four: the cycle's compute 167-189 µs against 226-245 µs, the process's CPU per cycle 203-231
µs against 283-309 µs, and the loop's lateness p99 41-42 µs against 68-82 µs (the fourth pair came
out even). The library calls every cycle makes (ruckig, four Pinocchio passes) cost 20-26 µs instead
of 51-58 µs (``benchmarks/bench_cycle_floor.py``).

The request is the one ``cyclictest`` makes: the 32-bit latency bound (µs) written to
``/dev/cpu_dma_latency``, which the kernel honours for as long as that file stays open. Closing it,
or the process ending in any way, withdraws it: nothing is left behind. It applies to every CPU of
the machine: idle cores poll instead of sleeping, which costs power (not the CPU time of other
programs: a polling idle core runs any task that becomes ready at once). Opening the file needs
root (or a udev rule that gives the device to the user's group); a refusal is reported, never fatal.
"""

from __future__ import annotations

import contextlib
import logging
import os
import struct

from akarm.errors import ArgumentError

__all__ = ["PM_QOS_PATH", "IdleLatencyHold"]

log = logging.getLogger(__name__)

PM_QOS_PATH = "/dev/cpu_dma_latency"  #: Linux's CPU latency request (PM QoS)


class IdleLatencyHold:
    """A request that the CPUs wake from idle within ``latency_us`` µs, held from :meth:`acquire` to
    :meth:`release` (see the module's docstring). One per loop thread; not thread-safe.

    Args:
        latency_us: the bound, µs (0: no idle state deeper than polling).
        path: the PM QoS device (a test gives a file of its own).
    """

    def __init__(self, latency_us: int = 0, path: str = PM_QOS_PATH) -> None:
        if not isinstance(latency_us, int) or isinstance(latency_us, bool) or not 0 <= latency_us < 2 ** 31:
            raise ArgumentError(f"latency_us must be a whole number of µs ≥ 0, got {latency_us!r}",
                                fix="0 keeps every idle core polling; a few µs allows the shallowest states")
        self.latency_us = latency_us
        self.path = path
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """True while the request is held."""
        return self._fd is not None

    def acquire(self) -> str:
        """Make the request; a one-line report of the outcome. Never raises."""
        if self._fd is not None:
            return f"CPU idle latency held at {self.latency_us} µs"
        try:
            fd = os.open(self.path, os.O_WRONLY | getattr(os, "O_CLOEXEC", 0))
        except OSError as e:
            report = (f"CPU idle latency not held ({e.strerror or e.__class__.__name__}: {self.path}); run as root, "
                      f"or give the loop's user write access to {self.path} (a udev rule)")
            log.info("control loop: %s", report)
            return report
        try:
            os.write(fd, struct.pack("=i", self.latency_us))
        except OSError as e:
            os.close(fd)
            return f"CPU idle latency not held (writing {self.path}: {e.strerror or e.__class__.__name__})"
        self._fd = fd
        return f"CPU idle latency held at {self.latency_us} µs"

    def release(self) -> None:
        """Withdraw the request (closing the file does it). Never raises; again is harmless."""
        fd, self._fd = self._fd, None
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)
