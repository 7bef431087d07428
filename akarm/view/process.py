"""The view in a process of its own, fed snapshots by the process that runs the loop.

A :class:`~akarm.view.page.ViewServer` draws 30 poses a second and a dozen plots ten times a
second through viser's threads. In the control loop's process that work holds the interpreter
lock against the loop: measured (``benchmarks/bench_view.py``), 9-12 % of the slots missed with
the page open against none closed. :class:`ViewProcess` runs the same page in a child process
instead (``akarm serve --view``, ``akarm sim --view``, ``akarm demo --view``), so the loop's process
does only what ``akarm view`` asks of a server over its socket: a snapshot about 30 times a second
(:func:`akarm.server.snapshot.take`: one copy of the joints' state under the controller's lock).

Pipes join the processes: on *life* the child says it serves the page (or why not) and the parent
says stop; on the *feed* the child asks for a snapshot and the parent's
``akarm-view-feed`` thread answers it; on the *commands* pipe (a source with controls: a server)
the child sends the page's enable, hold, disable and jog and the parent's ``akarm-view-commands``
thread runs them through the source's :class:`~akarm.view.sources.Controls`, answering with the
result or the error (rebuilt as the same :mod:`akarm.errors` class in the child, as the control
socket does). A command that takes time (enabling) does not hold the snapshots up.

The child runs at a lower priority (``CHILD_NICE``): where the CPU is short, the loop gets it and
the view lags. It ends when the parent says so (:meth:`ViewProcess.stop`) or when the parent is
gone (its end of the pipes closes), so a killed server leaves no page behind. It ignores SIGINT:
Ctrl-C in a terminal goes to the whole group, and the parent stops the child itself.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akarm.errors import AkarmError, StateError
from akarm.server.snapshot import Snapshot
from akarm.server.socket import error_doc, rebuild_error
from akarm.view.sources import Controls

if TYPE_CHECKING:
    from akarm.config import RobotConfig
    from akarm.view.sources import Source

__all__ = ["CHILD_NICE", "START_TIMEOUT", "ViewProcess"]

_PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])  # the directory that holds this akarm

#: niceness added to the view's process: the loop's process wins the CPU where it is short
CHILD_NICE = 10
#: s the child may take to import viser and serve the page
START_TIMEOUT = 60.0
#: s the child waits for an answer to a snapshot before it says the source is gone
FEED_TIMEOUT = 5.0
#: s the child is given to stop once asked, before it is terminated
STOP_TIMEOUT = 10.0


class ViewProcess:
    """The page of :class:`~akarm.view.page.ViewServer` for ``source``, served by a child process.

    Takes the same arguments as :class:`~akarm.view.page.ViewServer` and offers the same ``start``,
    ``stop``, ``url``, ``host``, ``port`` and ``source``. :attr:`snapshots` and
    :attr:`snapshot_seconds` count what the child asked of this process.

    Raises:
        ArgumentError: a bad host, port or rate (at once, in this process).
        AkarmError: viser is not installed (the ``view`` extra), said before anything starts.
    """

    def __init__(self, config: RobotConfig, source: Source, *, host: str = "127.0.0.1", port: int = 8080,
                 rate_hz: float = 30.0, plot_hz: float = 10.0, history: float = 10.0, visuals: bool = True) -> None:
        from akarm.view.page import check_options  # (imported when used: the child only after SIGINT is off)

        check_options(host, port, rate_hz, plot_hz)
        if importlib.util.find_spec("viser") is None:
            raise AkarmError("the view needs viser, which is not installed", fix='pip install "akarm[view]"')
        self.config = config
        self.source = source
        self.host, self.port = host, port
        self.options = {"rate_hz": float(rate_hz), "plot_hz": float(plot_hz), "history": float(history),
                        "visuals": bool(visuals)}
        self.snapshots = 0
        self.snapshot_seconds = 0.0
        self._process: subprocess.Popen[bytes] | None = None
        self._life: Connection | None = None
        self._threads: list[threading.Thread] = []
        self._conns: list[Connection] = []

    @property
    def url(self) -> str:
        """The page's address (:attr:`port` is the one bound, once started)."""
        from akarm.view.page import page_url

        return page_url(self.host, self.port)

    @property
    def pid(self) -> int | None:
        """The view's process, while it runs."""
        return self._process.pid if self._process is not None else None

    def alive(self) -> bool:
        """Whether the view's process runs."""
        return self._process is not None and self._process.poll() is None

    def start(self) -> ViewProcess:
        """Start the child and wait until it serves the page (:attr:`port` is then the one bound).

        Raises:
            StateError: the port cannot be bound, or the child did not start within ``START_TIMEOUT``.
            AkarmError: whatever else stopped the child from serving (its own error, rebuilt).
        """
        feed, child_feed = Pipe()
        life, child_life = Pipe()
        commands = child_commands = None
        if self.source.controls is not None:
            commands, child_commands = Pipe()
        ends = [c for c in (child_feed, child_life, child_commands) if c is not None]
        # a fresh interpreter running this module, never a fork of a process that runs a loop's threads,
        # nor multiprocessing's spawn (which runs the caller's main script again in the child)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (_PACKAGE_ROOT, env.get("PYTHONPATH")) if p)
        argv = [sys.executable, "-m", "akarm.view.process", str(child_feed.fileno()), str(child_life.fileno()),
                str(child_commands.fileno() if child_commands is not None else -1)]
        try:
            process = subprocess.Popen(argv, pass_fds=[c.fileno() for c in ends], env=env, stdin=subprocess.DEVNULL)
        except OSError as e:
            for conn in (feed, life, commands):
                if conn is not None:
                    conn.close()
            raise StateError(f"cannot start the view's process: {e}", fix="see that Python runs here") from None
        finally:
            for end in ends:
                end.close()  # the child holds them now: the parent's copies would keep EOF away
        self._process, self._life = process, life
        self._conns = [c for c in (feed, life, commands) if c is not None]
        try:
            life.send((self.config, self.source.title, self.host, self.port, self.options))
            if not life.poll(START_TIMEOUT):
                raise StateError(f"the view's process did not start within {START_TIMEOUT:g} s",
                                 fix="see its output above; or run akarm view ROBOT.yaml beside this program")
            kind, value = life.recv()
        except (EOFError, OSError):
            self.stop()
            raise StateError("the view's process ended before it served the page",
                             fix="see its output above") from None
        except BaseException:
            self.stop()
            raise
        if kind != "ready":
            self.stop()
            raise rebuild_error(value)
        self.port = int(value)
        self._spawn(lambda: _answer(feed, self._snapshot), "akarm-view-feed")
        if commands is not None:
            controls = self.source.controls
            assert controls is not None
            self._spawn(lambda: _answer(commands, lambda request: _run_command(controls, request)),
                        "akarm-view-commands")
        return self

    def _spawn(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        thread.start()
        self._threads.append(thread)

    def _snapshot(self, request: object) -> Snapshot:
        """A snapshot for the child (its request says nothing more), counted and timed."""
        t0 = time.perf_counter()
        try:
            return self.source.snapshot()
        finally:
            self.snapshot_seconds += time.perf_counter() - t0
            self.snapshots += 1

    def stop(self) -> None:
        """Stop the page and its process (the arm and the source are left as they are)."""
        process, self._process = self._process, None
        if self._life is not None:
            with contextlib.suppress(OSError):
                self._life.send("stop")
        if process is not None:
            try:
                process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(5.0)
        for conn in self._conns:
            conn.close()  # the answering threads see it and end
        self._conns, self._life = [], None
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(5.0)
        self._threads.clear()

    def __enter__(self) -> ViewProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _answer(conn: Connection, handle: Callable[[Any], Any]) -> None:
    """Answer each of the child's requests on ``conn`` with ``handle``'s result, or its akarm error
    as the control socket carries it, until the child is gone."""
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):
            return
        try:
            reply: tuple[str, Any] = ("ok", handle(request))
        except AkarmError as e:
            reply = ("error", error_doc(e))
        try:
            conn.send(reply)
        except (EOFError, OSError):
            return


def _run_command(controls: Controls, request: Any) -> Any:
    """One of the page's commands, ``(op, args)``, through ``controls`` (in this process); anything
    else (a broken child) is refused by :meth:`Controls.call` as an operation it does not run."""
    op, args = request if isinstance(request, tuple) and len(request) == 2 else ("?", {})
    return controls.call(op, args)


# ----------------------------------------------------------------------------------------------
# the child
# ----------------------------------------------------------------------------------------------
class _FedSource:
    """The child's source: snapshots and commands through the pipes to the parent."""

    def __init__(self, title: str, feed: Connection, commands: Connection | None, config: RobotConfig) -> None:
        self.title = title
        self._feed, self._commands = feed, commands
        self._feed_lock, self._cmd_lock = threading.Lock(), threading.Lock()
        self.controls: Controls | None = Controls(self._call, config) if commands is not None else None

    def snapshot(self) -> Snapshot:
        with self._feed_lock:
            return _ask(self._feed, "snapshot", FEED_TIMEOUT)

    def _call(self, op: str, args: dict[str, Any]) -> Any:
        assert self._commands is not None
        with self._cmd_lock:
            return _ask(self._commands, (op, args), None)

    def close(self) -> None:
        pass


def _ask(conn: Connection, request: Any, timeout: float | None) -> Any:
    try:
        conn.send(request)
        if timeout is not None and not conn.poll(timeout):
            raise StateError(f"the program that runs the arm did not answer within {timeout:g} s",
                             fix="it may be stopping or stalled; the view shows the last state")
        kind, value = conn.recv()
    except (EOFError, OSError):
        raise StateError("the program that runs the arm is gone", fix="the view ends with it") from None
    if kind != "ok":
        raise rebuild_error(value)
    return value


def _child_main(feed: Connection, life: Connection, commands: Connection | None) -> int:
    """The view's process: serve the page until the parent says stop or is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError):
        os.nice(CHILD_NICE)
    try:
        config, title, host, port, options = life.recv()
    except (EOFError, OSError):
        return 1
    from akarm.view.page import ViewServer

    try:
        view = ViewServer(config, _FedSource(title, feed, commands, config), host=host, port=port,
                          rate_hz=options["rate_hz"], plot_hz=options["plot_hz"], history=options["history"],
                          visuals=options["visuals"])
        view.start()
    except AkarmError as e:
        life.send(("error", error_doc(e)))
        return 1
    except Exception as e:  # said to the parent, which raises it
        life.send(("error", error_doc(AkarmError(f"the view could not start: {e!r}"))))
        return 1
    try:
        life.send(("ready", view.port))
        with contextlib.suppress(EOFError, OSError):
            life.recv()  # "stop", or EOF: the parent is gone
    finally:
        view.stop()
    return 0


if __name__ == "__main__":
    fds = [int(a) for a in sys.argv[1:4]]
    sys.exit(_child_main(Connection(fds[0]), Connection(fds[1]), Connection(fds[2]) if fds[2] >= 0 else None))
