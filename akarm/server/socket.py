"""The server's local control socket: JSON lines over a Unix socket, for the ``akarm`` CLI.

A request is one line ``{"id": N, "op": NAME, "args": {...}}``; the answer one line ``{"id": N,
"ok": true, "result": ...}`` or ``{"id": N, "ok": false, "error": {"type": "LimitError", "what": ...,
"joint": ..., "fix": ...}}``, which :class:`SocketClient` raises again as the same
:mod:`akarm.errors` class. The id pairs each answer with its request: a call cut short (Ctrl-C while
it waited) leaves its answer on the socket, and the next call skips it rather than take it for its own.
Each connection is served by a thread of its own, so one client may wait for a motion while
another stops it; the dispatcher is told which connection asks, and when a connection ends (so what
a client started, teach mode, ends with it, however the client went away).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import socket
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from akarm import errors
from akarm.errors import AkarmError, StateError

__all__ = ["SocketClient", "SocketServer"]


def _error_doc(e: AkarmError) -> dict[str, Any]:
    return {"type": type(e).__name__, "what": getattr(e, "what", str(e)), "joint": getattr(e, "joint", None),
            "fix": getattr(e, "fix", "")}


def _rebuild(doc: dict[str, Any]) -> AkarmError:
    """The server's error as the same :mod:`akarm.errors` class (or its nearest plain parent)."""
    cls = getattr(errors, str(doc.get("type")), None)
    if not (isinstance(cls, type) and issubclass(cls, AkarmError)):
        cls = AkarmError
    for candidate in (cls, errors.SafetyStop if issubclass(cls, errors.SafetyStop) else AkarmError, AkarmError):
        try:
            return candidate(str(doc.get("what")), joint=doc.get("joint"), fix=str(doc.get("fix") or ""))
        except TypeError:  # a class with a constructor of its own (ConfigError, MotorFault, ...)
            continue
    return AkarmError(str(doc.get("what")))


class SocketServer:
    """Serves ``dispatch(op, args, client) -> result`` on a Unix socket at ``path`` until :meth:`close`.

    ``client`` is a number for the connection the request came on; ``closed(client)`` is called once
    that connection has ended (the client closed it, exited, was killed)."""

    def __init__(self, path: str | os.PathLike[str], dispatch: Callable[[str, dict[str, Any], int], Any],
                 closed: Callable[[int], None] | None = None) -> None:
        self.path = Path(path)
        self.dispatch = dispatch
        self.closed = closed
        self._clients = itertools.count(1)
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.bind(str(self.path))
        os.chmod(self.path, 0o600)
        self._sock.listen(8)
        self._sock.settimeout(0.2)
        self._running = True
        self._thread = threading.Thread(target=self._accept, name="akarm-serve-control", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while self._running:
            try:
                conn, _ = self._sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            threading.Thread(target=self._serve, args=(conn, next(self._clients)), name="akarm-serve-client",
                             daemon=True).start()

    def _serve(self, conn: socket.socket, client: int) -> None:
        try:
            with contextlib.suppress(OSError), conn, conn.makefile("rwb") as f:  # a client that left (Ctrl-C)
                for line in f:
                    req: Any = None
                    try:
                        req = json.loads(line)
                        result: Any = self.dispatch(str(req["op"]), dict(req.get("args") or {}), client)
                        answer = {"ok": True, "result": result}
                    except AkarmError as e:
                        answer = {"ok": False, "error": _error_doc(e)}
                    except Exception as e:  # a bug or a malformed request: say so, keep serving
                        answer = {"ok": False, "error": {"type": "AkarmError", "what": f"server error: {e!r}"}}
                    answer["id"] = req.get("id") if isinstance(req, dict) else None
                    f.write(json.dumps(answer).encode() + b"\n")
                    f.flush()
        finally:
            if self.closed is not None:
                self.closed(client)

    def close(self) -> None:
        self._running = False
        with contextlib.suppress(OSError):
            self._sock.close()
        self._thread.join(2.0)
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()


class SocketClient:
    """A connection to a server's control socket; :meth:`call` raises the server's errors as they were."""

    def __init__(self, path: str | os.PathLike[str], timeout: float | None = None) -> None:
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._sock.connect(str(path))
        except OSError as e:
            self._sock.close()
            raise StateError(f"cannot reach akarm serve at {path}: {e.strerror or e}",
                             fix="is the server still starting or stopping? try again, or stop it") from None
        self._sock.settimeout(timeout)
        self._file = self._sock.makefile("rwb")
        self._ids = itertools.count(1)

    def call(self, op: str, **args: Any) -> Any:
        request = next(self._ids)
        try:
            self._file.write(json.dumps({"id": request, "op": op, "args": args}).encode() + b"\n")
            self._file.flush()
            while True:  # answers to calls cut short before (Ctrl-C while waiting) come first: skip them
                line = self._file.readline()
                if not line:
                    raise StateError("akarm serve closed the connection (it is stopping?)",
                                     fix="see the server's output")
                answer = json.loads(line)
                if answer.get("id") == request:
                    break
        except OSError as e:
            raise StateError(f"lost the connection to akarm serve ({e})", fix="is the server still running?") from None
        if not answer.get("ok"):
            raise _rebuild(answer.get("error") or {})
        return answer.get("result")

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._file.close()
            self._sock.close()

    def __enter__(self) -> SocketClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
