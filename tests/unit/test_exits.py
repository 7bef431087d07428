"""The one way out (akarm.control.exits) and the signals it holds (akarm.signals), on their own."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator

import pytest

from akarm import signals
from akarm.control.exits import Exits, UnsafeExitWarning

pytestmark = pytest.mark.skipif(threading.current_thread() is not threading.main_thread() or os.name != "posix",
                                reason="signals: POSIX, main thread")


@pytest.fixture
def default_handlers() -> Iterator[None]:
    """SIGTERM, SIGHUP and SIGQUIT at their default action for the test (as in a plain program)."""
    before = {sig: signal.signal(sig, signal.SIG_DFL) for sig in signals.HANDLED}
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


def exits(log: list[str], on_claim=None) -> Exits:
    def is_open() -> bool:
        if on_claim is not None:
            on_claim()
        return "closed" not in log

    return Exits(lambda warn: log.append("closed"), is_open, lambda: False, patience=1.0)


def test_a_ctrl_c_as_the_close_begins_is_held_until_the_arm_is_closed() -> None:
    """A second Ctrl-C right as close() began (before its signals were held) left the close claimed and
    never run: every later close, the interpreter's exit's too, waited for it, the motors powered."""
    log: list[str] = []
    sent = []

    def ctrl_c() -> None:
        if not sent:
            sent.append(1)
            os.kill(os.getpid(), signal.SIGINT)

    ex = exits(log, on_claim=ctrl_c)
    with pytest.raises(KeyboardInterrupt):  # delayed, not lost
        ex.close()
    assert log == ["closed"]
    ex.close()  # nothing left claimed: returns at once
    assert log == ["closed"]


def test_closing_restores_the_default_action_of_the_signals_it_handled(default_handlers: None) -> None:
    """close() let go of its handlers while they were held back, so the last uninstall found its own
    handler replaced and left SIGTERM raising in the program after the arm was closed."""
    log: list[str] = []
    ex = exits(log)
    ex.opened()
    assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
    ex.close()
    assert all(signal.getsignal(sig) is signal.SIG_DFL for sig in signals.HANDLED)


def test_an_arm_opened_outside_the_main_thread_warns_where_signals_would_end_the_program(
        default_handlers: None) -> None:
    caught: list[list[object]] = []

    def open_in_thread() -> None:
        import warnings

        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            ex = exits([])
            ex.opened()
            ex.close()
        caught.append([x.category for x in w])

    th = threading.Thread(target=open_in_thread)
    th.start()
    th.join()
    assert caught == [[UnsafeExitWarning]]
    assert signals.install()  # the program's main thread handles them: no warning then
    try:
        caught.clear()
        th = threading.Thread(target=open_in_thread)
        th.start()
        th.join()
        assert caught == [[]]
    finally:
        signals.uninstall()
