"""Nothing answers on an akarm_local channel another process holds: the hint names that process."""

from __future__ import annotations

import subprocess
import sys

from akarm.buses.bus import no_answer_hint
from akarm.config import BusConfig

from .conftest import wait_until


def test_no_answer_on_akarm_local_says_nothing_is_on_the_channel(channel: str) -> None:
    bus = BusConfig("arm", "akarm_local", channel)
    assert f"no simulator or motor is on akarm_local channel {channel!r}" in no_answer_hint(bus)
    assert f"akarm sim ROBOT.yaml -i akarm_local -c {channel}" in no_answer_hint(bus)
    # another process on the channel: it is there, but did not answer as these joints
    code = (f"import can, sys, time; b = can.Bus(interface='akarm_local', channel={channel!r}); print('up', "
            "flush=True); sys.stdin.read(); b.shutdown()")
    other = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout is not None and other.stdout.readline().strip() == "up"
        assert wait_until(lambda: f"processes {other.pid}" in no_answer_hint(bus), 5.0), no_answer_hint(bus)
        assert "same CAN IDs" in no_answer_hint(bus)
    finally:
        other.communicate("", timeout=10)
