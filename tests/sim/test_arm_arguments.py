"""The Arm's boundary: a bad argument (the wrong type, NaN, out of its range) is an ArgumentError naming
it, raised before anything is sent or any mode changes; never a raw TypeError, a hang or a motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm import ArgumentError
from akarm.control.modes import Mode

NAN = math.nan


@pytest.mark.parametrize("timeout", [NAN, math.inf, -1.0, "x", True])
def test_enable_refuses_a_bad_timeout_before_the_mode_changes(lockstep, timeout) -> None:
    with lockstep("planar2") as (arm, sim):
        with pytest.raises(ArgumentError, match=r"enable timeout must be a finite number \(s\), at least 0, got") as e:
            arm.enable(timeout=timeout)
        assert e.value.fix and arm.mode is Mode.DISABLED
        arm.enable(timeout=0.5)  # nothing was left half-done: a good enable still works
        assert arm.enabled
        assert np.all(np.isfinite(arm.state().q))
