"""Values echoed in error texts: compact (akarm.errors.num: a refused 1e308 is not 309 digits), and a
value that is not a number named by its point and joint."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akarm.errors import ArgumentError, LimitError, num
from akarm.motion.timed import timed_plan
from akarm.motion.trajectory import JointLimits, Planner

LIMITS = JointLimits(("shoulder", "elbow"), np.array([-1.0, -2.0]), np.array([1.0, 2.0]), np.array([2.0, 2.0]),
                     np.array([10.0, 10.0]), np.array([100.0, 100.0]))
START = (np.zeros(2), np.zeros(2), np.zeros(2))


@pytest.mark.parametrize(("x", "decimals", "sign", "text"), [
    (0.5, 4, False, "0.5000"), (1.2, 4, True, "+1.2000"), (-0.25, 3, True, "-0.250"), (999999.0, 1, False, "999999.0"),
    (1e308, 4, False, "1e+308"), (-2.5e7, 4, True, "-2.5e+07"), (1.7976931348623157e308, 4, True, "+1.798e+308"),
    (math.nan, 4, False, "nan"), (-math.inf, 4, True, "-inf"),
])
def test_num_is_fixed_point_while_it_reads_well_and_compact_beyond(x: float, decimals: int, sign: bool, text: str):
    assert num(x, decimals, sign) == text


def test_a_huge_target_is_echoed_compactly():
    with pytest.raises(LimitError) as e:
        LIMITS.check_position(np.array([0.0, 1e308]))
    assert str(e.value).startswith("joint 'elbow': target 1e+308 rad is outside the joint's range [-2.0000, 2.0000]")
    assert len(str(e.value)) < 300


def test_a_timed_trajectory_names_the_point_and_joint_of_a_value_that_is_not_a_number():
    planner = Planner(LIMITS)
    with pytest.raises(ArgumentError, match=r"joint 'elbow': point 1: velocity nan is not a number"):
        timed_plan(planner, START, 0.0, [1.0, 2.0], [[0.1, 0.1], [0.2, 0.2]], [[0.0, 0.0], [0.0, math.nan]])
    with pytest.raises(ArgumentError, match=r"joint 'shoulder': point 0 position is inf"):
        timed_plan(planner, START, 0.0, [1.0], [[math.inf, 0.1]])
    with pytest.raises(ArgumentError, match=r"increasing \(point 1: nan s\)"):
        timed_plan(planner, START, 0.0, [1.0, math.nan], [[0.1, 0.1], [0.2, 0.2]])
