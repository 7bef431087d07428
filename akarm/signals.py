"""Signals that end a program: SIGTERM, SIGHUP, SIGQUIT handled like Ctrl-C, so an arm is damped and disabled.

Python turns Ctrl-C (SIGINT) into :class:`KeyboardInterrupt`, which unwinds ``with arm:`` blocks
and ``finally`` clauses: the arm is damped and disabled on the way out. SIGTERM (``kill``, systemd,
a process manager, ``timeout``), SIGHUP (a closed terminal) and SIGQUIT (Ctrl-\\) instead end a
Python program at once, leaving the motors holding their last command. :func:`install` makes them raise
:class:`Terminated`, a :class:`KeyboardInterrupt`, in the main thread, so every way out of a
program unwinds the same way. It only replaces the default action (a program's own handlers are
left alone), and :class:`~akarm.Arm` installs it while it is open; the ``akarm`` command installs
it for every verb.

:func:`deferred` holds these signals back while an arm is being stopped, so a second Ctrl-C cannot
cut the damping short.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["Terminated", "deferred", "exit_code", "install", "installed", "uninstall"]

#: The signals turned into :class:`Terminated` (those this platform has): SIGQUIT too (Ctrl-\, whose
#: default is to end the program at once, with a core dump, and the motors powered).
HANDLED: tuple[signal.Signals, ...] = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP", "SIGQUIT")
                                            if hasattr(signal, n))
_STOPPING = (signal.SIGINT, *HANDLED)


class Terminated(KeyboardInterrupt):
    """The program was told to end by a signal (SIGTERM, SIGHUP, SIGQUIT): unwinds like Ctrl-C.

    Attributes:
        signum: the signal's number.
    """

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(f"terminated by {signal.Signals(signum).name}")


def exit_code(interrupt: BaseException) -> int:
    """The exit status of a program ended by ``interrupt``: 128 + the signal's number (130 for Ctrl-C)."""
    return 128 + getattr(interrupt, "signum", int(signal.SIGINT))


def _raise(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signum)


_lock = threading.Lock()
_users = 0
_replaced: list[signal.Signals] = []


def install() -> bool:
    """Make SIGTERM, SIGHUP and SIGQUIT raise :class:`Terminated` in the main thread, where their
    action is still the default. Counted: each call needs an :func:`uninstall`. Returns False (and does
    nothing) outside the main thread, where Python cannot set handlers."""
    global _users
    if threading.current_thread() is not threading.main_thread():
        return False
    with _lock:
        if _users == 0:
            for sig in HANDLED:
                if signal.getsignal(sig) is signal.SIG_DFL:
                    signal.signal(sig, _raise)
                    _replaced.append(sig)
        _users += 1
    return True


def installed() -> bool:
    """Whether SIGTERM, SIGHUP and SIGQUIT are handled now, by :func:`install` or by the program itself
    (none of them ends the program at once)."""
    return all(signal.getsignal(sig) is not signal.SIG_DFL for sig in HANDLED)


def uninstall() -> None:
    """Undo one :func:`install` (call it only for an install that returned True); the last one
    restores the default action where ours is still set, from the main thread (elsewhere ours stays:
    it ends the program as the default would, by an exception in the main thread)."""
    global _users
    with _lock:
        if _users == 0:
            return
        _users -= 1
        if _users == 0 and threading.current_thread() is threading.main_thread():
            for sig in _replaced:
                if signal.getsignal(sig) is _raise:
                    signal.signal(sig, signal.SIG_DFL)
            _replaced.clear()


@contextlib.contextmanager
def deferred(message: str = "stopping the arm safely; please wait", reraise: bool = False) -> Iterator[None]:
    """While inside, SIGINT, SIGTERM and SIGHUP do not interrupt (``message`` is printed once instead).

    With ``reraise``, the first one held back is raised when the block ends (as
    :class:`KeyboardInterrupt` or :class:`Terminated`), so a request to end the program is
    delayed, not lost. Main thread only; elsewhere it does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        if not held:
            print(message, file=sys.stderr, flush=True)
        held.append(signum)

    previous = {}
    for sig in _STOPPING:
        with contextlib.suppress(ValueError, OSError):
            previous[sig] = signal.signal(sig, hold)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if reraise and held:
        if held[0] == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(held[0])
