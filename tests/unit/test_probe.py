"""A Probe refuses unknown joints and closed buses before it sends anything (against the simulator:
tests/system/test_probe.py)."""

from __future__ import annotations

import pytest

from akarm import AkarmError, StateError
from akarm.control.probe import Probe

from ..system.test_probe import config_of


def test_probe_needs_open_buses_and_known_joints(channel: str) -> None:
    cfg = config_of("planar2", channel)
    with pytest.raises(AkarmError, match="no joint named 'wrist'"):
        Probe(cfg, ["wrist"])
    with pytest.raises(StateError, match="not open"):
        Probe(cfg).read_state()
