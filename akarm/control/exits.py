"""The one way out: every way a program can leave an open arm ends in the same close.

``Arm.close()``, leaving ``with arm:``, the interpreter's exit (an atexit hook, with a warning) and
the garbage collector (a finalizer on the Arm, with a warning) all call :meth:`Exits.close`, which
runs the controller's shutdown (damp, disable, stop the loop, close the buses) once:

- a second caller (another thread, the atexit hook while a close is under way) waits for the first
  one to finish instead of returning with the arm still powered (the loop's own thread cannot wait
  for its own cycles, and returns);
- while it runs, Ctrl-C and SIGTERM are held back (:func:`akarm.signals.deferred`) and raised after;
- while the arm is open, SIGTERM and SIGHUP raise in the main thread (:func:`akarm.signals.install`),
  so that ``with arm:`` unwinds.
"""

from __future__ import annotations

import atexit
import threading
import warnings
import weakref
from collections.abc import Callable

from akarm import signals

__all__ = ["Exits", "UnsafeExitWarning"]


class UnsafeExitWarning(UserWarning):
    """An Arm was still enabled when the program ended or dropped it: akarm damped and disabled it.
    Use ``with arm:`` or call ``arm.disable()`` / ``arm.close()`` yourself."""


class Exits:
    """The way out of one controller (see the module's docstring).

    Args:
        shutdown: ``shutdown(warn)``: the controller's damp-disable-close sequence; ``warn`` is the
            warning to give if the arm was still powered (the program ended, or dropped the Arm).
        is_open: whether there is anything to close.
        on_loop_thread: whether the caller is the control loop's own thread.
        patience: s a second closer waits for the first.
    """

    def __init__(self, shutdown: Callable[[str | None], None], is_open: Callable[[], bool],
                 on_loop_thread: Callable[[], bool], patience: float) -> None:
        self._shutdown = shutdown
        self._is_open = is_open
        self._on_loop_thread = on_loop_thread
        self._patience = patience
        self._lock = threading.Lock()
        self._closing: threading.Event | None = None  # set when the close under way (in any thread) ends
        self._signals_installed = False  # this controller counts in akarm.signals' handlers

    def opened(self) -> None:
        """The controller is open: the interpreter's exit closes it; SIGTERM, SIGHUP and SIGQUIT raise
        (from the main thread; an Arm opened in another thread warns where they would end the program
        at once, unless they are handled already: :func:`akarm.signals.install` from the main thread)."""
        _open.add(self)
        self._signals_installed = signals.install()
        if not self._signals_installed and not signals.installed():
            warnings.warn("this Arm was opened outside the main thread, where Python cannot set signal "
                          "handlers: SIGTERM, SIGHUP and SIGQUIT would end the program with the motors "
                          "powered; call akarm.signals.install() once from the main thread first (or open the "
                          "Arm there)", UnsafeExitWarning, stacklevel=4)

    def close(self, warn: str | None = None) -> None:
        """Run the shutdown once (see the module's docstring). Never raises its errors; signals are
        held back until it is done."""
        uninstall = False
        try:
            # signals are held back before the close is claimed: an interrupt between the two would
            # leave it claimed and never run (every later close, the interpreter's exit's too, waiting
            # for it, and the motors powered)
            with signals.deferred(reraise=threading.current_thread() is threading.main_thread() and warn is None):
                with self._lock:
                    if not self._is_open():
                        return
                    closing = self._closing
                    if not closing:
                        self._closing = threading.Event()
                if closing:  # another thread closes it: return once closed (the loop's own thread cannot wait)
                    if not self._on_loop_thread():
                        closing.wait(self._patience)
                    return
                try:
                    self._shutdown(warn)
                finally:
                    _open.discard(self)
                    uninstall, self._signals_installed = self._signals_installed, False
                    with self._lock:
                        done, self._closing = self._closing, None
                    if done:
                        done.set()
        finally:
            if uninstall:  # (after the held signals' handlers are back: the default action is restored)
                signals.uninstall()

    def close_collected(self) -> None:
        """The Arm was garbage-collected while open: close, with a warning if it was still enabled.

        The collection may run in the loop's own thread (Python's cycle collector runs in whichever
        thread allocates): the loop cannot wait for its own cycles, so a thread of its own closes
        the arm, with the damping, while the loop goes on; if no thread can be started (the
        interpreter is exiting), the joints exit motor mode at once."""
        warn = ("an akarm Arm was garbage-collected while enabled: akarm damped and disabled it "
                "(use `with arm:` or call arm.close())")
        if self._on_loop_thread():
            try:
                threading.Thread(target=self.close, kwargs={"warn": warn}, name="akarm-close").start()
                return
            except RuntimeError:
                pass
        self.close(warn=warn)

    def track(self, owner: object) -> weakref.finalize:
        """Close (with a warning if still enabled) when ``owner`` (the Arm) is garbage-collected."""
        fin = weakref.finalize(owner, self.close_collected)
        fin.atexit = False  # the interpreter's exit has its own hook (_close_all_at_exit)
        return fin


_open: weakref.WeakSet[Exits] = weakref.WeakSet()


def _close_all_at_exit() -> None:
    for exits in list(_open):
        exits.close(warn="an akarm Arm was still enabled when the program ended: akarm damped and disabled it "
                         "(use `with arm:` or call arm.close())")


atexit.register(_close_all_at_exit)
