"""examples/pick_and_place.py runs in lock step (``--fast``) as a user runs it, in the README's test
command: it grasps the object, carries it, and the simulator finds it at the place point."""

from __future__ import annotations

import re
import subprocess
import sys

from .conftest import ROOT

#: examples tested here rather than in tests/system/test_examples.py
SIM_EXAMPLES = ("pick_and_place",)


def test_pick_and_place_moves_the_object() -> None:
    p = subprocess.run([sys.executable, "examples/pick_and_place.py", "--fast"], cwd=ROOT, capture_output=True,
                       text=True, timeout=180)
    assert p.returncode == 0, f"--- stdout\n{p.stdout}\n--- stderr\n{p.stderr}"
    out = p.stdout
    assert "lock step" in out and out.rstrip().endswith("disabled")
    m = re.search(r"grasped at ([0-9.]+) mm, squeezing ([0-9.]+) N \(asked 20 N\); the simulator counts ([0-9.]+) N",
                  out)
    assert m, out
    width, estimate, true = (float(x) for x in m.groups())
    assert abs(width - 30.0) < 2.0 and 16.0 < estimate < 24.0 and 16.0 < true < 24.0
    assert "still grasped True" in out
    m = re.search(r"moved ([0-9.]+) cm, ([0-9.]+) mm from the place point", out)
    assert m, out
    moved, off = (float(x) for x in m.groups())
    assert moved > 30.0 and off < 5.0  # from the pick point (0.45, -0.15) to the place point (0.40, 0.20)
