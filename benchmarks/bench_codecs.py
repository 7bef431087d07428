"""Throughput of the wire codecs, in encode+decode pairs (frames) per second on one core.

Run: ``.venv/bin/python benchmarks/bench_codecs.py [--iterations N] [--repeat R] [--strict]``

Each row times N iterations of one encode and one decode with ``time.perf_counter`` (the loop's own
cost included) and keeps the best of R runs, since other processes only ever make a run slower.
The target for the control loop is 300 000 MIT command+reply pairs per second (about 3 µs a pair,
so six joints at 1 kHz cost under 2 % of a core); ``--strict`` exits 1 when the prepared codec
misses it.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
from collections.abc import Callable

from akarm.protocol import mit, motors, servo, uart

TARGET_PAIRS_PER_S = 300_000


def _time(body: Callable[[int], None], n: int, repeat: int) -> tuple[float, float]:
    """Best wall time (``perf_counter``) and best CPU time (``process_time``) of ``repeat`` runs of ``body(n)``, s."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        t0 = time.perf_counter()
        body(n)
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _mit_prepared(n: int) -> None:
    c = mit.codec("AK80-9")
    enc, dec = c.encode_command, c.decode_reply
    reply = c.encode_reply(1, 0.5, -1.0, 2.0, 30.0, 0)
    for _ in itertools.repeat(None, n):
        enc(0.5, -1.0, 30.0, 1.0, 2.0)
        dec(reply)


def _mit_module_name(n: int) -> None:
    enc, dec = mit.encode_command, mit.decode_reply
    reply = mit.encode_reply("AK80-9", 1, 0.5, -1.0, 2.0, 30.0, 0)
    for _ in itertools.repeat(None, n):
        enc("AK80-9", 0.5, -1.0, 30.0, 1.0, 2.0)
        dec("AK80-9", reply)


def _mit_module_model(n: int) -> None:
    m = motors.get("AK80-9")
    enc, dec = mit.encode_command, mit.decode_reply
    reply = mit.encode_reply(m, 1, 0.5, -1.0, 2.0, 30.0, 0)
    for _ in itertools.repeat(None, n):
        enc(m, 0.5, -1.0, 30.0, 1.0, 2.0)
        dec(m, reply)


def _mit_v3(n: int) -> None:
    c = mit.codec("AK70-9")
    enc, dec = c.encode_command, c.decode_reply_v3
    aid, status = servo.encode_status(1, 90.0, 1000.0, 2.5, 30.0)
    for _ in itertools.repeat(None, n):
        enc(0.5, -1.0, 30.0, 1.0, 2.0, firmware="v3")
        dec(aid, status)


def _mit_motor_side(n: int) -> None:
    c = mit.codec("AK80-9")
    dec, enc = c.decode_command, c.encode_reply
    frame = c.encode_command(0.5, -1.0, 30.0, 1.0, 2.0)
    for _ in itertools.repeat(None, n):
        dec(frame)
        enc(1, 0.5, -1.0, 2.0, 30.0, 0)


def _servo_controller(n: int) -> None:
    enc, dec = servo.encode_position_speed, servo.decode_status
    aid, status = servo.encode_status(1, 90.0, 1000.0, 2.5, 30.0)
    for _ in itertools.repeat(None, n):
        enc(1, 90.0, 5000.0, 30000.0)
        dec(aid, status)


def _servo_motor_side(n: int) -> None:
    dec, enc = servo.decode_command, servo.encode_status
    aid, data = servo.encode_position_speed(1, 90.0, 5000.0, 30000.0)
    for _ in itertools.repeat(None, n):
        dec(aid, data)
        enc(1, 90.0, 1000.0, 2.5, 30.0)


def _uart_command(n: int) -> None:
    enc, dec = uart.encode_position_speed, uart.FrameDecoder()
    feed = dec.feed
    for _ in itertools.repeat(None, n):
        feed(enc(180.0, 5000.0, 30000.0))


def _uart_get_values(n: int) -> None:
    frame = uart.encode_get_values_reply(uart.GetValues(35.8, 30.0, 1.5, 0.5, 0.0, 1.5, 0.1, 1000.0, 24.0, 0,
                                                        90.0, 1, 0.5, 2.0))
    enc, decoder, decode = uart.encode_get_values, uart.FrameDecoder(), uart.decode_get_values
    feed = decoder.feed
    for _ in itertools.repeat(None, n):
        enc()
        for payload in feed(frame):
            decode(payload)


ROWS: list[tuple[str, Callable[[int], None], int]] = [
    # (what one iteration is, body, iterations divisor: slower rows run fewer iterations)
    ("MIT prepared codec: encode_command + decode_reply", _mit_prepared, 1),
    ("MIT module functions (model name): same pair", _mit_module_name, 1),
    ("MIT module functions (MotorModel): same pair", _mit_module_model, 1),
    ("MIT V3: encode_command + decode_reply_v3", _mit_v3, 2),
    ("MIT motor side: decode_command + encode_reply", _mit_motor_side, 1),
    ("servo CAN: encode_position_speed + decode_status", _servo_controller, 2),
    ("servo CAN motor side: decode_command + encode_status", _servo_motor_side, 2),
    ("UART: encode_position_speed frame + FrameDecoder.feed", _uart_command, 2),
    ("UART: GET_VALUES request + 78-byte reply feed + decode", _uart_get_values, 2),
]


def main(argv: list[str] | None = None) -> int:
    """Run every row, print the table; return 1 under ``--strict`` when the MIT target is missed."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=300_000, help="iterations of the fastest rows (default 300000)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per row; the best counts (default 3)")
    ap.add_argument("--strict", action="store_true", help="exit 1 if the prepared MIT codec misses the target")
    args = ap.parse_args(argv)

    print(f"Python {sys.version.split()[0]}, best of {args.repeat} runs, time.perf_counter\n")
    try:
        load = " (load average {:.2f} {:.2f} {:.2f})".format(*os.getloadavg())
    except OSError:
        load = ""
    print(f"{os.cpu_count()} CPUs{load}")
    header = (f"{'pair (one encode + one decode)':<56} {'iterations':>10} {'µs/pair':>8} {'pairs/s':>10}"
              f" {'CPU µs':>7} {'CPU pairs/s':>11}")
    print(header)
    print("-" * len(header))
    results: dict[str, float] = {}
    for name, body, div in ROWS:
        n = max(1, args.iterations // div)
        body(min(n, 1000))  # warm up (caches, specialisation)
        wall, cpu = _time(body, n, args.repeat)
        results[name] = n / wall
        print(f"{name:<56} {n:>10} {wall / n * 1e6:>8.2f} {n / wall:>10,.0f} {cpu / n * 1e6:>7.2f} {n / cpu:>11,.0f}")
    mit_rate = results[ROWS[0][0]]
    ok = mit_rate >= TARGET_PAIRS_PER_S
    print("\nµs/pair and pairs/s: wall clock (perf_counter); CPU: process time, which other processes on a busy")
    print("machine inflate less. The target is judged on wall clock.")
    print(f"MIT target {TARGET_PAIRS_PER_S:,} pairs/s: {'met' if ok else 'MISSED'} ({mit_rate:,.0f})")
    return 1 if args.strict and not ok else 0


if __name__ == "__main__":
    sys.exit(main())
