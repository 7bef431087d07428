"""Reading a disabled arm's motors through its open controller, as ``akarm status`` reads them.

An enabled arm's feedback is fresh every cycle: each command is answered. A disabled one's MIT
joints are silent (nothing is sent to them), so the state the controller last heard grows old while
the arm may fall or be moved by hand. :func:`read_disabled` asks them, as
:meth:`akarm.control.probe.Probe.read_state` does without a controller: each MIT joint gets its
query frames (EXIT: a disabled driver answers and stays disabled; V3 boards: a zero-gain,
zero-torque command), sent on the controller's own buses; the loop, which keeps draining and routing
them while the arm is disabled, takes the replies. Servo joints report on their own and are not asked.

Nothing is sent unless the arm is DISABLED (or in FAULT): under the controller's lock, so an
enable cannot begin meanwhile. The cycle itself is not touched.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING

from akarm.control.modes import Mode
from akarm.errors import StateError

if TYPE_CHECKING:
    from akarm.control.controller import Controller
    from akarm.control.joints import Joint

__all__ = ["read_disabled"]


def read_disabled(ctl: Controller, timeout: float) -> list[str]:
    """Ask a disabled arm's MIT joints for their state and wait up to ``timeout`` s (of the arm's
    clock; in lock step the cycles run meanwhile) for every one to answer. Returns the names of the
    joints asked; none when the arm is not disabled (it is then answering every cycle, or being
    enabled or stopped, and nothing is sent). A joint that does not answer keeps its old feedback
    (its age says how old)."""
    with ctl.lock:
        if ctl.modes.mode not in (Mode.DISABLED, Mode.FAULT):
            return []
        t0 = ctl.clock.now()
        asked: list[Joint] = []
        for j in ctl.joints:
            frames = j.query_frames() if j.answers_commands else []
            for f in frames:
                ctl.bus.send(j, f)
            if frames:
                asked.append(j)

    def answered() -> bool:
        return all(j.state.stamp >= t0 for j in asked)

    if asked:
        with contextlib.suppress(StateError):  # a joint that did not answer: its age says so
            ctl.wait_for(answered, timeout, "the joints to answer", raise_fault=False)
    return [j.name for j in asked]
