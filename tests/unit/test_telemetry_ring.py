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
