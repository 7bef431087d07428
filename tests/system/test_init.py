"""`akarm init`'s commented next steps, run as they are written: `akarm sim` and `akarm move` in
processes of their own."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from ..unit.test_init import init


def test_init_sim_and_move_on_the_command_line(tmp_path: Path, channel: str) -> None:
    """The file's own commented next steps: `akarm sim` in one process, `akarm move ... rest` in another."""
    from akarm.sim.process import SimulatorProcess

    out, text = init(tmp_path, "scara_ros2")
    assert "akarm sim scara_ros2.yaml -i akarm_local -c try" in text
    assert "akarm move scara_ros2.yaml rest -i akarm_local -c try" in text
    # with a 0.25 s feedback watchdog instead of 20 ms, and a 0.5 rad following-error limit instead of
    # t_max / kp (93 mrad for the shoulder): the simulator is a process the OS may pause, and on a loaded
    # 2-core machine a 50 ms pause at 2 rad/s reads as 100 mrad behind (in lock step the error stays under
    # 10 mrad: test_init_then_check_then_a_simulated_move)
    out.write_text(text.replace("  max_temperature: 80.0", "  max_temperature: 80.0\n  feedback_timeout: 0.25\n"
                                "  following_error: 0.5"))
    with SimulatorProcess(out, channel=channel):
        r = subprocess.run([sys.executable, "-m", "akarm", "move", str(out), "rest", "-i", "akarm_local", "-c",
                            channel], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "arrived" in r.stdout and "disabled" in r.stdout
