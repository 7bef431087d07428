"""Simulator faults as text (akarm sim --fault) and their checked arguments (the faults in the
simulator: tests/sim/test_sim_faults.py)."""

from __future__ import annotations

import pytest

from akarm.errors import AkarmError
from akarm.sim import faults


@pytest.mark.parametrize(("spec", "expected"), [
    ("elbow:drop:0.3", ("elbow", faults.DropReplies(0.3))),
    ("elbow:drop:0.3,7", ("elbow", faults.DropReplies(0.3, seed=7))),
    ("wrist_roll:delay:0.005", ("wrist_roll", faults.DelayReplies(0.005))),
    ("elbow:missed", ("elbow", faults.MissedFrames(1))),
    ("elbow:missed:3", ("elbow", faults.MissedFrames(3))),
    ("elbow:unplugged", ("elbow", faults.Unplugged())),
    ("elbow:unplugged:power", ("elbow", faults.Unplugged(power_lost=True))),
    ("elbow:error:1", ("elbow", faults.ErrorCode(1))),
    ("elbow:frozen", ("elbow", faults.FrozenEncoder())),
    ("elbow:frozen:control", ("elbow", faults.FrozenEncoder(affects_control=True))),
    ("elbow:fault-after:2.0", ("elbow", faults.FaultAfter(2.0))),
    ("elbow:fault_after:2.5,5", ("elbow", faults.FaultAfter(2.5, code=5))),
    ("elbow:forged:12.45", ("elbow", faults.ForgedReply(12.45))),
    ("elbow:forged:-3,4,0.01", ("elbow", faults.ForgedReply(-3.0, 4, 0.01))),
    ("elbow:rogue-exit", ("elbow", faults.RogueExit())),
    ("elbow:rogue_exit:silent", ("elbow", faults.RogueExit(on_bus=False))),
    ("elbow:blocked", ("elbow", faults.Blocked())),
])
def test_parse_command_line_faults(spec: str, expected: tuple[str, faults.Fault]) -> None:
    assert faults.parse(spec) == expected


@pytest.mark.parametrize("spec", ["elbow", "elbow:melt", "elbow:drop", "elbow:drop:1.5", "elbow:delay:-1",
                                  "elbow:error:x", ":drop:0.1", "elbow:unplugged:maybe", "elbow:forged",
                                  "elbow:forged:1,0", "elbow:forged:nan", "elbow:forged:-inf",
                                  "elbow:forged:1,2,inf", "elbow:rogue-exit:loud", "elbow:blocked:1",
                                  "elbow:missed:0", "elbow:missed:2.5", "elbow:missed:1,2"])
def test_parse_rejects_bad_faults_with_the_kinds_listed(spec: str) -> None:
    with pytest.raises(AkarmError) as info:
        faults.parse(spec)
    assert ("drop:FRACTION" in str(info.value) or "outside" in str(info.value) or "negative" in str(info.value)
            or "count ≥ 1" in str(info.value) or "not a finite number" in str(info.value))


@pytest.mark.parametrize("args", [(float("nan"),), (float("inf"), 2), (1.0, 2, float("inf")), (1.0, 2, float("nan"))])
def test_a_forged_reply_needs_a_finite_position_and_interval(args: tuple) -> None:
    # nan cannot be put in a reply (the simulator's thread would fail); an infinite interval never comes
    with pytest.raises(AkarmError) as info:
        faults.ForgedReply(*args)
    assert repr(args[0] if len(args) == 1 or args[0] != 1.0 else args[2]) in str(info.value) and info.value.fix
