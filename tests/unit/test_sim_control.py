"""The simulator's control channel without a simulator: faults as JSON both ways, bad fault objects, a
channel with nobody there (requests to a served simulator: tests/sim/test_sim_control.py)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from akarm import AkarmError, StateError
from akarm.sim import faults
from akarm.sim.channel import SimulatorControl, fault_from_json, fault_to_json

EVERY_FAULT = [faults.DropReplies(0.3, seed=7), faults.DelayReplies(0.005), faults.Unplugged(power_lost=True),
               faults.ErrorCode(5), faults.FrozenEncoder(affects_control=True), faults.FaultAfter(1.5, code=2),
               faults.ForgedReply(12.45, count=3, interval=0.01), faults.RogueExit(on_bus=False), faults.Blocked(),
               faults.CorruptBytes(0.5, seed=2), faults.PartialFrame(0.25), faults.BadCrc(seed=3), faults.SilentPort(),
               faults.Brownout(0.01), faults.PowerCycle(-2, seconds=0.5), faults.Twin(0.7), faults.MissedFrames(2)]


@pytest.mark.parametrize("fault", EVERY_FAULT, ids=lambda f: type(f).__name__)
def test_every_fault_goes_through_json_unchanged(fault: faults.Fault) -> None:
    text = json.dumps(fault_to_json(fault))
    assert fault_from_json(json.loads(text)) == fault


def test_the_json_of_a_fault_names_its_class_and_fields() -> None:
    assert fault_to_json(faults.DropReplies(0.3, seed=7)) == {"type": "DropReplies", "fraction": 0.3, "seed": 7}


def test_every_fault_class_is_covered() -> None:
    classes = {n for n in faults.__all__ if dataclasses.is_dataclass(getattr(faults, n))}
    assert classes == {type(f).__name__ for f in EVERY_FAULT}


@pytest.mark.parametrize(("obj", "says"), [
    ({"type": "Meteor"}, "unknown fault"),
    ({"type": "Fault"}, "unknown fault"),                       # the base class is no fault to inject
    ({"type": "parse", "spec": "x"}, "unknown fault"),           # a function of the module, not a fault
    ("DropReplies", "unknown fault"),
    ({"type": "DropReplies", "share": 0.3}, "the fields of DropReplies are: fraction, seed"),
    ({"type": "DropReplies", "fraction": 3.0}, "outside 0..1"),  # the fault's own check
])
def test_a_bad_fault_object_is_a_clear_error(obj: object, says: str) -> None:
    with pytest.raises(AkarmError, match=says):
        fault_from_json(obj)


def test_a_simulator_that_is_not_there_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(StateError, match="cannot reach the simulator's control channel"):
        SimulatorControl(tmp_path / "nobody.sock", timeout=1.0).state()
