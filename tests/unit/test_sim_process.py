"""The CPU time read from /proc, and NaN for a process that is gone (the simulator's process:
tests/system/test_sim_process.py)."""

from __future__ import annotations

import os
from pathlib import Path


def test_cpu_time_of_a_process_that_is_gone_is_nan(tmp_path):
    from akarm.sim.process import stat_cpu_seconds

    if Path("/proc").is_dir():
        assert stat_cpu_seconds(f"/proc/{os.getpid()}/stat") > 0.0
    assert stat_cpu_seconds(tmp_path / "no-such-stat") != stat_cpu_seconds(tmp_path / "no-such-stat")  # NaN
