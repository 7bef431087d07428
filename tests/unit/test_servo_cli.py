"""``akarm servo``: the SpaceMouse's axes as a twist, and the verb's refusals before anything is opened."""

from __future__ import annotations

import argparse
import math
import sys

import pytest

from akarm.cli import servo
from akarm.cli.servo import twist_from_axes
from akarm.errors import AkarmError, ArgumentError


def parse(argv: list[str]) -> argparse.Namespace:
    """The verb's own parser (it joins `akarm`'s VERBS once the README lists it: see docs/compliance.md)."""
    parser = argparse.ArgumentParser(prog="akarm servo")
    servo.add_arguments(parser)
    return parser.parse_args(argv)


def test_axes_become_a_twist_past_the_dead_band() -> None:
    assert twist_from_axes([0.05, -0.05, 0.0, 0.0, 0.0, 0.0], 0.05, 0.3, 0.1) == [0.0] * 6
    t = twist_from_axes([1.0, -1.0, 0.55, 0.0, 0.0, -1.0], 0.05, 0.3, 0.1)
    assert t[0] == pytest.approx(0.05) and t[1] == pytest.approx(-0.05) and t[2] == pytest.approx(0.025)
    assert t[5] == pytest.approx(-0.3)
    assert twist_from_axes([3.0, math.nan, -math.inf, 0, 0, 0], 0.05, 0.3, 0.1)[:3] == [0.05, 0.0, -0.05]


def test_the_verb_needs_an_input_and_says_how_to_get_pyspacemouse(monkeypatch) -> None:
    with pytest.raises(ArgumentError, match="--spacemouse"):
        servo.run(parse(["robots/arm6.yaml"]))
    monkeypatch.setitem(sys.modules, "pyspacemouse", None)  # as if the spacemouse extra were not installed
    with pytest.raises(AkarmError, match=r"akarm\[spacemouse\]"):
        servo.run(parse(["robots/arm6.yaml", "--spacemouse"]))
