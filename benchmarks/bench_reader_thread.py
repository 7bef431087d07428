"""Does a reader thread per bus make the cycle cheaper? akarm's loop reading its bus itself, against
the same loop taking its frames from a queue that a thread per bus fills.

    .venv/bin/python benchmarks/bench_reader_thread.py                  # 3 rounds of 15 s per side
    .venv/bin/python benchmarks/bench_reader_thread.py --rounds 1 --seconds 5

Both sides: ``Arm`` on the 6 MIT joints of robots/arm6.yaml at 480 Hz, moving between its poses,
every check on, against ``akarm sim`` in a process of its own on an ``akarm_local`` channel, each
side in a fresh process of its own, the sides alternating round by round (as
``bench_cpu_peer.py``). The loop drains each bus once per cycle with ``recv(0)``:

- direct: the ``akarm_local`` bus itself (what akarm does).
- reader: the same bus behind :class:`ReaderThreadBus`, a python-can bus (registered for this
  benchmark only) whose thread waits in the inner bus's ``recv`` and appends what comes to a deque;
  its ``recv(0)`` pops from that deque. That is what python-can's ``Notifier`` does, which
  TMotorCANControl (the peer of ``bench_cpu_peer.py``) reads its replies with.

Printed per round and side: process CPU per cycle across all threads, the receive stage's mean and
p99, the whole compute, the loop's lateness p99 and its missed slots (µs). ``akarm_local`` has no
blocking wait (its ``recv`` polls its rings, backing off from 20 to 200 µs), so the reader here
polls too; on SocketCAN the thread would sleep in the kernel until a frame came.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import sys
import threading
import time
from typing import Any

import can
from bench_cpu_peer import MARK, RATE, run_akarm, spawn

READER = "akarm_bench_reader"


class ReaderThreadBus(can.BusABC):
    """An ``akarm_local`` bus with a reader thread in front: the thread queues every frame the inner
    bus receives; :meth:`recv` takes them from the queue."""

    def __init__(self, channel: str, receive_own_messages: bool = False, **kwargs: Any) -> None:
        self.inner = can.Bus(interface="akarm_local", channel=channel, receive_own_messages=receive_own_messages)
        self.queue: collections.deque[can.Message] = collections.deque()
        self.channel_info = f"{self.inner.channel_info} behind a reader thread"
        super().__init__(channel=channel)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._read, name="bench-bus-reader", daemon=True)
        self.thread.start()

    def _read(self) -> None:
        recv, append, stop = self.inner.recv, self.queue.append, self._stop
        while not stop.is_set():
            msg = recv(0.05)
            if msg is not None:
                append(msg)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        end = None if timeout is None else time.perf_counter() + timeout
        while True:
            try:
                return self.queue.popleft()
            except IndexError:
                if end is not None and time.perf_counter() >= end:
                    return None
                time.sleep(50e-6)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.inner.send(msg, timeout)

    def shutdown(self) -> None:
        self._stop.set()
        self.thread.join(1.0)
        self.inner.shutdown()
        super().shutdown()


def register() -> None:
    """Make ``can.Bus(interface=READER)`` open a :class:`ReaderThreadBus` (python-can keeps the
    names it accepts in a set made at import: the name is added there too)."""
    import can.interfaces
    import can.util

    can.interfaces.BACKENDS[READER] = (__name__, "ReaderThreadBus")
    can.util.VALID_INTERFACES = frozenset({*can.util.VALID_INTERFACES, READER})  # type: ignore[attr-defined]


def run(side: str, seconds: float) -> dict:
    register()
    return run_akarm(f"reader-{os.getpid()}", seconds, READER if side == "reader" else "akarm_local")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=15.0, help="length of each side's run, s")
    ap.add_argument("--child", choices=("direct", "reader"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(MARK + json.dumps(run(args.child, args.seconds)), flush=True)
        return
    us = 1e6
    print(f"arm6, 6 MIT joints, {RATE:g} Hz, akarm sim in its own process on akarm_local; {args.seconds:g} s per "
          f"side, {os.cpu_count()} CPUs, Python {sys.version.split()[0]}")
    print(f"{'round':>5} {'side':>7} {'cycles':>7} {'missed':>6} {'CPU/cycle':>10} {'receive':>8} {'rcv p99':>8} "
          f"{'compute':>8} {'late p99':>9} {'stops':>5}   (µs)")
    for r in range(1, args.rounds + 1):
        for side in ("direct", "reader"):
            x = spawn(side, args.seconds, __file__)
            print(f"{r:5d} {side:>7} {x['cycles']:7d} {x['missed']:6d} {x['cpu_per_cycle'] * us:10.1f} "
                  f"{x['stage_mean']['receive'] * us:8.1f} {x['stage_p99']['receive'] * us:8.1f} "
                  f"{x['compute_mean'] * us:8.1f} "
                  f"{x['late_p99'] * us:9.1f} {x['stops']:5d}", flush=True)


if __name__ == "__main__":
    main()
