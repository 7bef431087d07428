"""The arm's modes and the transitions allowed between them: one table, checked on every change.

::

    CLOSED ──open──▶ DISABLED ──enable──▶ ENABLING ──settled──▶ ACTIVE ⇄ TEACH
                        ▲                    │                    │        │
                        │                 refused               stop / safety stop
                        │                    ▼                    ▼        ▼
                        └───────────────── (exit) ◀───────────── STOPPING
                                                                  │
                                       a bus died under the arm ──┴──▶ FAULT ──close──▶ CLOSED

Only DISABLED and CLOSED leave the motors unpowered for certain. Closing from any other mode
damps and disables first (FAULT: the lost bus's joints cannot be told anything; the others were
disabled on the way into it).
"""

from __future__ import annotations

import enum

from akarm.errors import StateError

__all__ = ["Mode", "ModeMachine"]


class Mode(enum.Enum):
    """What the arm is doing.

    CLOSED: no bus open, no loop. DISABLED: loop running, motors unpowered (nothing sent).
    ENABLING: making contact with every joint, then damping until the arm is at rest.
    ACTIVE: holding or moving. TEACH: hand-guidable, weight carried. STOPPING: damping, then exit.
    FAULT: a bus died; the arm cannot be driven until it is closed.
    """

    CLOSED = "closed"
    DISABLED = "disabled"
    ENABLING = "enabling"
    ACTIVE = "active"
    TEACH = "teach"
    STOPPING = "stopping"
    FAULT = "fault"

    def __str__(self) -> str:
        return self.value

    @property
    def powered(self) -> bool:
        """True in the modes where a motor may be applying torque (everything but CLOSED and DISABLED)."""
        return self not in (Mode.CLOSED, Mode.DISABLED)

    @property
    def enabled(self) -> bool:
        """True in the modes where the motors are powered and under control: ACTIVE (holding or
        moving) and TEACH (hand-guided, weight carried)."""
        return self in (Mode.ACTIVE, Mode.TEACH)


_ALLOWED: dict[Mode, frozenset[Mode]] = {
    Mode.CLOSED: frozenset({Mode.DISABLED}),
    Mode.DISABLED: frozenset({Mode.ENABLING, Mode.FAULT, Mode.CLOSED}),
    Mode.ENABLING: frozenset({Mode.ACTIVE, Mode.DISABLED, Mode.STOPPING, Mode.FAULT, Mode.CLOSED}),
    Mode.ACTIVE: frozenset({Mode.TEACH, Mode.STOPPING, Mode.FAULT, Mode.CLOSED}),
    Mode.TEACH: frozenset({Mode.ACTIVE, Mode.STOPPING, Mode.FAULT, Mode.CLOSED}),
    Mode.STOPPING: frozenset({Mode.DISABLED, Mode.FAULT, Mode.CLOSED}),
    Mode.FAULT: frozenset({Mode.CLOSED}),
}


class ModeMachine:
    """The current :class:`Mode`; :meth:`go` refuses a transition the table does not allow.

    Transitions to CLOSED from a powered mode are allowed only for the last-resort paths (a loop that
    crashed, a finalizer) that have already sent the exit frames themselves.
    """

    __slots__ = ("mode",)

    def __init__(self) -> None:
        self.mode = Mode.CLOSED

    def go(self, new: Mode) -> None:
        """Change to ``new``; :class:`~akarm.StateError` if the table does not allow it (a bug in akarm)."""
        if new is self.mode:
            return
        if new not in _ALLOWED[self.mode]:
            raise StateError(f"the arm cannot go from {self.mode} to {new}",
                             fix="this is a bug in akarm; please report it with the traceback")
        self.mode = new

    def __repr__(self) -> str:
        return f"ModeMachine({self.mode})"
