"""The telemetry ring buffer: every value of a record lands in its field, in order, across wrap-around."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm.telemetry.log import FIELDS, Telemetry


def test_records_land_in_their_fields_oldest_first_across_the_wrap() -> None:
    tel = Telemetry(["a", "b"], capacity=4)
    for k in range(6):  # two more than it holds: the first two are gone
        v = [10.0 * k + f for f in range(len(FIELDS) * 2)]
        args = [v[2 * f:2 * f + 2] for f in range(len(FIELDS))]
        tel.record(0.5 * k, *args[:-1], tau_ext=None if k == 5 else np.array(args[-1]))
    log = tel.snapshot()
    assert log.t.tolist() == [1.0, 1.5, 2.0, 2.5]
    assert log.q_des.tolist() == [[20.0, 21.0], [30.0, 31.0], [40.0, 41.0], [50.0, 51.0]]
    assert log.tau_ff[0].tolist() == [30.0, 31.0]  # the sixth field of record 2
    assert log.tau_ext[2].tolist() == [52.0, 53.0]  # record 4, the seventh field
    assert all(math.isnan(x) for x in log.tau_ext[3])  # not known: NaN
    assert tel.snapshot(since=2.0).t.tolist() == [2.0, 2.5]


def test_a_record_of_the_wrong_size_is_refused_and_writes_nothing() -> None:
    tel = Telemetry(["a", "b"], capacity=4)
    with pytest.raises(Exception):  # noqa: B017 (struct.error: a programming error, not a user's)
        tel.record(0.0, [1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0], [5.0, 5.0], [6.0, 6.0])
    assert tel.count == 0 and not tel.rows.any()


def _record(tel: Telemetry, k: int) -> None:
    """Record ``k``: stamped k, every value k (a torn or misplaced row shows as a value off its stamp)."""
    v = [float(k)] * len(tel.joint_names)
    tel.record(float(k), *([v] * (len(FIELDS) - 1)), tau_ext=v)


@pytest.mark.parametrize("since", [None, 0.0, 123.5, 1e12])
def test_a_snapshot_between_records_gives_whole_rows_in_order(since: float | None) -> None:
    tel = Telemetry(["a", "b", "c"], capacity=1000)
    for k in range(2500):  # across two and a half wraps; a chunk is 1024 rows: the copy spans chunks too
        _record(tel, k)
    log = tel.snapshot(since)
    want = [float(k) for k in range(1500, 2500) if since is None or k >= since]
    assert log.t.tolist() == want
    for f, _ in FIELDS:
        assert (getattr(log, f) == log.t[:, None]).all(), f


def test_a_snapshot_while_the_loop_records_leaves_out_what_it_overwrote() -> None:
    """The loop records in its own thread while snapshots are taken without any lock: each snapshot is
    a run of whole records, consecutive, each the record its stamp says, never more than the ring holds."""
    import threading

    tel = Telemetry(["a", "b", "c", "d", "e", "f"], capacity=3000)
    done = threading.Event()
    written = [0]

    def loop() -> None:
        k = 0
        while not done.is_set():
            _record(tel, k)
            k += 1
        written[0] = k

    th = threading.Thread(target=loop)
    th.start()
    snapshots = 0
    try:
        while snapshots < 200:
            log = tel.snapshot(since=float(snapshots * 10))
            if len(log.t):
                t = log.t
                assert (np.diff(t) == 1.0).all() and len(t) <= 3000
                assert t[0] >= snapshots * 10
                for f, _ in FIELDS:
                    assert (getattr(log, f) == t[:, None]).all(), f
            snapshots += 1
    finally:
        done.set()
        th.join()
    assert written[0] > 3000  # the ring wrapped while it was read
