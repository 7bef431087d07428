"""The view in a process of its own (``--view``): it serves the page, asks this process only for
snapshots, says why it cannot start, and never outlives the program that runs the arm.

The page in a real browser, served this way by ``akarm serve --view``, is tests/system/test_view.py.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
import urllib.request
from pathlib import Path

import pytest

from akarm.errors import StateError
from akarm.robotfile.load import load_robot
from akarm.server.snapshot import Snapshot

from .conftest import ROBOTS, wait_until

pytestmark = pytest.mark.slow
pytest.importorskip("viser", reason="the view extra is not installed (pip install -e \".[view]\")")

from akarm.view.process import ViewProcess  # noqa: E402

ARM6 = ROBOTS / "arm6.yaml"


class Counting:
    """A source that counts the snapshots asked of it, from which thread, and can be made to fail."""

    title = "counting"
    controls = None

    def __init__(self, names: tuple[str, ...]) -> None:
        self.names = names
        self.asked = 0
        self.threads: set[str] = set()
        self.fail = False

    def snapshot(self) -> Snapshot:
        self.asked += 1
        self.threads.add(threading.current_thread().name)
        if self.fail:
            raise StateError("the arm is gone")
        n = len(self.names)
        z = (0.0,) * n
        return Snapshot(t=time.monotonic(), names=self.names, q=z, q_des=z, error=z, tau=z, tau_ff=z,
                        temperature=(math.nan,) * n, age=z, fault=(0,) * n, mode="holding", enabled=True,
                        moving=False, stop="", rate_hz=500.0, loop_rate_hz=500.0, cycles=0, missed_slots=0)

    def close(self) -> None:
        pass


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    # a zombie (not yet reaped by its parent) runs no more
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def test_the_page_is_served_by_a_child_that_asks_this_process_only_for_snapshots() -> None:
    config = load_robot(ARM6)
    source = Counting(config.joint_names)
    view = ViewProcess(config, source, port=0)
    with view:
        pid = view.pid
        assert pid is not None and pid != os.getpid() and view.alive()
        with urllib.request.urlopen(view.url, timeout=30) as page:
            assert page.status == 200
            assert b"<html" in page.read().lower()
        # ~30 a second, asked from one thread of ours that only answers
        assert wait_until(lambda: source.asked >= 30, 30.0), source.asked
        assert source.threads == {"akarm-view-feed"}
        asked = view.snapshots
        assert asked >= 30 and view.snapshot_seconds > 0
        source.fail = True  # the source gone: the child is told the error and goes on asking
        before = source.asked
        assert wait_until(lambda: source.asked > before + 10, 30.0)
        assert view.alive()
    assert view.pid is None
    assert wait_until(lambda: gone(pid), 10.0)
    with pytest.raises(OSError):
        urllib.request.urlopen(view.url, timeout=5)


def test_a_view_that_cannot_serve_says_why_in_this_process() -> None:
    config = load_robot(ARM6)
    view = ViewProcess(config, Counting(config.joint_names), host="203.0.113.7", port=0)  # no such local address
    with pytest.raises(StateError, match=r"cannot serve the view on 203\.0\.113\.7") as e:
        view.start()
    assert "--host" in e.value.fix
    assert view.pid is None


SCRIPT = textwrap.dedent("""
    # a user's script with no `if __name__ == "__main__"`: the child must not run it again
    import time
    from akarm.robotfile.load import load_robot
    from akarm.server.snapshot import Snapshot
    from akarm.view.process import ViewProcess

    class Still:
        title, controls = "still", None
        def snapshot(self):
            n = len(config.joint_names)
            z = (0.0,) * n
            return Snapshot(t=time.monotonic(), names=config.joint_names, q=z, q_des=z, error=z, tau=z,
                            tau_ff=z, temperature=z, age=z, fault=(0,) * n, mode="holding", enabled=True,
                            moving=False, stop="", rate_hz=500.0, loop_rate_hz=500.0, cycles=0, missed_slots=0)
        def close(self):
            pass

    print("script started", flush=True)
    config = load_robot({robot!r})
    view = ViewProcess(config, Still(), port=0).start()
    print("view", view.pid, flush=True)
    time.sleep(600)
""")


def test_the_view_ends_with_the_program_even_when_it_is_killed(tmp_path: Path) -> None:
    script = tmp_path / "user_script.py"
    script.write_text(SCRIPT.format(robot=str(ARM6)))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("view "):
                break
        assert lines and lines[-1].startswith("view "), "".join(lines)
        child = int(lines[-1].split()[1])
        assert not gone(child)
        proc.send_signal(signal.SIGKILL)  # no chance to stop the child: its pipes close
        proc.wait(30)
        assert wait_until(lambda: gone(child), 15.0), f"the view's process {child} outlived its program"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    assert sum(line.startswith("script started") for line in lines) == 1, "".join(lines)
