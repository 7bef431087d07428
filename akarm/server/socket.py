"""The server's local control socket: JSON lines over a Unix socket, for the ``akarm`` CLI.

A request is one line ``{"id": N, "op": NAME, "args": {...}}``; the answer one line ``{"id": N,
"ok": true, "result": ...}`` or ``{"id": N, "ok": false, "error": {"type": "LimitError", "what": ...,
"joint": ..., "fix": ..., "text": ..., "extra": {...}}}``, which :class:`SocketClient` raises again as
the same :mod:`akarm.errors` class (with the attributes in ``extra``). The id pairs each answer with
its request: a call cut short (Ctrl-C while it waited) leaves its answer on the socket, and the next
call skips it rather than take it for its own. Each connection is served by a thread of its own, so
one client may wait for a motion while another stops it; the dispatcher is told which connection
asks, and when a connection ends (so what a client started, teach mode, ends with it, however the
client went away).

The socket is the server's user's only (a 0700 directory, the socket 0600), and it cannot be wedged
by a client that misbehaves:

- at most :data:`MAX_CONNECTIONS` connections at once: a new one past that closes the connection
  that has waited longest for its next request, or, when every one is busy with a request, is
  taken on one of :data:`RESERVED_CONNECTIONS` more, which carry one request each and only the
  server's urgent operations (``disable``, ``stop``, ``hold``, the status: what an operator needs
  when every connection is held by long requests); anything else is answered there with a
  :class:`~akarm.StateError`, and a connection past those is answered so and closed;
- a request is at most :data:`MAX_REQUEST_BYTES` long (a longer one is answered with the error, and
  the rest of it, up to :data:`DRAIN_BYTES`, read and dropped before the connection is closed, so
  that a client still writing reads why rather than a broken pipe), and must arrive whole within
  :data:`REQUEST_TIMEOUT` s of its first byte; a connection with no request for
  :data:`IDLE_TIMEOUT` s is closed;
- NaN and infinities are not numbers a request may carry; what is not a JSON object, or not one
  of the dispatcher's operations with its arguments, is answered with an
  :class:`~akarm.ArgumentError` saying what is wrong;
- an error that is not akarm's (a bug) is logged with its traceback, and the client is told that the
  server failed, never the internal exception's text;
- the accept loop survives anything (file descriptors exhausted, a thread that cannot start, a
  bug) and keeps accepting.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import json
import math
import os
import select
import socket
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from akarm import errors
from akarm.errors import AkarmError, ArgumentError, StateError

__all__ = ["DRAIN_BYTES", "IDLE_TIMEOUT", "MAX_CONNECTIONS", "MAX_REQUEST_BYTES", "REQUEST_TIMEOUT",
           "RESERVED_CONNECTIONS", "SocketClient", "SocketServer"]

MAX_CONNECTIONS = 32  #: control connections open at once
#: connections more, for one urgent request each, when all the others are busy with requests
RESERVED_CONNECTIONS = 4
MAX_REQUEST_BYTES = 1 << 20  #: bytes of one request line (1 MiB)
REQUEST_TIMEOUT = 10.0  #: s for a request to arrive whole, from its first byte
DRAIN_BYTES = 16 << 20  #: bytes of a request too long read (and dropped) after its answer, at most
IDLE_TIMEOUT = 600.0  #: s a connection may wait between requests before it is closed
SEND_TIMEOUT = 10.0  #: s an answer may take to be taken by a client that does not read
_ACCEPT_RETRY = 0.05  # s between accepts while the process has no file descriptor to spare
_SIMPLE = (str, int, float, bool, type(None))


def _finite(obj: Any) -> Any:
    """``obj`` with every float that is not finite replaced by ``None`` (JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def error_doc(e: AkarmError) -> dict[str, Any]:
    """An akarm error as the socket carries it (see the module's docstring)."""
    extra = {k: v for k, v in vars(e).items() if k not in ("what", "joint", "fix") and isinstance(v, _SIMPLE)}
    public = next(c for c in type(e).__mro__ if getattr(errors, c.__name__, None) is c)  # not a private subclass
    return _finite({"type": public.__name__, "what": getattr(e, "what", str(e)), "joint": getattr(e, "joint", None),
                    "fix": getattr(e, "fix", ""), "text": str(e), "extra": extra})


def rebuild_error(doc: dict[str, Any]) -> AkarmError:
    """The server's error as the same :mod:`akarm.errors` class, its text and attributes as they were
    (an unknown class: a plain :class:`~akarm.AkarmError`)."""
    cls = getattr(errors, str(doc.get("type")), None)
    if not (isinstance(cls, type) and issubclass(cls, AkarmError)):
        cls = AkarmError
    what, fix, joint = str(doc.get("what")), str(doc.get("fix") or ""), doc.get("joint")
    text = str(doc.get("text") or AkarmError(what, joint=joint, fix=fix))
    e = cls.__new__(cls, text)  # its constructor may want more than the socket carries: set what was sent
    extra = doc.get("extra")
    if isinstance(extra, dict):
        vars(e).update({str(k): v for k, v in extra.items()})
    vars(e).update(what=what, joint=joint, fix=fix)
    return e


def _reject_constant(name: str) -> float:
    raise ArgumentError(f"{name} is not a number a request may carry", fix="send finite numbers only")


_REQUEST = '{"id": N, "op": NAME, "args": {...}}'


class _BadRequest(ArgumentError):
    """A request that is not one: what is wrong, and its id when it had one."""

    def __init__(self, what: str, req_id: Any = None, fix: str = f"send {_REQUEST}") -> None:
        self.req_id = req_id
        super().__init__(what, fix=fix)


def _parse(line: bytes) -> tuple[Any, str, dict[str, Any]]:
    """A request line's id, op and args (see the module's docstring), or :class:`_BadRequest` saying
    what is wrong with it (never the JSON decoder's own exception)."""
    try:
        req = json.loads(line, parse_constant=_reject_constant)
    except ArgumentError:
        raise
    except RecursionError:
        raise _BadRequest("a request must be one JSON object on one line; this one is nested too deeply") from None
    except ValueError as e:  # not JSON, not UTF-8
        where = f" (at character {e.pos})" if isinstance(e, json.JSONDecodeError) else ""
        raise _BadRequest(f"a request must be one JSON object on one line; this is not JSON{where}") from None
    if not isinstance(req, dict):
        raise _BadRequest("a request must be a JSON object")
    req_id = req.get("id")
    if not isinstance(req_id, int | str) or isinstance(req_id, bool):
        req_id = None
    extra = [str(k)[:40] for k in req if k not in ("id", "op", "args")]
    if extra:
        raise _BadRequest(f"a request has no field {extra[0]!r}", req_id)
    op, args = req.get("op"), req.get("args")
    if not isinstance(op, str):
        raise _BadRequest("a request's 'op' must be the operation's name (text)", req_id, 'e.g. "op": "state"')
    if args is None:
        args = {}
    if not isinstance(args, dict):
        raise _BadRequest("a request's 'args' must be a JSON object of the operation's arguments", req_id,
                          'e.g. "args": {"seconds": 1.0}')
    return req_id, op, args


class _Connection:
    """One client's connection, as the server keeps it."""

    __slots__ = ("busy", "client", "conn", "reserve", "since")

    def __init__(self, conn: socket.socket, client: int, reserve: bool = False) -> None:
        self.conn = conn
        self.client = client
        self.reserve = reserve  # one of the reserved connections: one urgent request, then closed
        self.busy = False  # a request is being carried out
        self.since = time.monotonic()  # when it last began to wait for a request

    def kick(self) -> None:
        """End the connection from another thread (its thread sees the end of input)."""
        with contextlib.suppress(OSError):
            self.conn.shutdown(socket.SHUT_RDWR)


def _readable(conn: socket.socket) -> bool:
    """Whether ``conn`` has something to read, or has ended, now (no wait). ``poll``, not ``select``:
    a process with more than 1023 files open has descriptors ``select`` cannot take (it raises, and a
    raise here once read as "the client left": every wait of the server returned at once)."""
    if hasattr(select, "poll"):
        p = select.poll()
        p.register(conn, select.POLLIN)
        return bool(p.poll(0))
    readable, _, _ = select.select([conn], [], [], 0)  # (no poll: Windows, whose select has no such limit)
    return bool(readable)


class SocketServer:
    """Serves ``dispatch(op, args, client) -> result`` on a Unix socket at ``path`` until :meth:`close`.

    ``client`` is a number for the connection the request came on; ``closed(client)`` is called once
    that connection has ended (the client closed it, exited, was killed, or it was closed here).
    ``log`` gets a line for what the server should hear about (a bug's traceback, descriptors
    running out). ``urgent``: the operations a reserved connection may carry. Limits: see the
    module's docstring."""

    def __init__(self, path: str | os.PathLike[str], dispatch: Callable[[str, dict[str, Any], int], Any],
                 closed: Callable[[int], None] | None = None, log: Callable[[str], None] | None = None,
                 urgent: frozenset[str] = frozenset()) -> None:
        self.path = Path(path)
        self.dispatch = dispatch
        self.urgent = urgent
        self.closed = closed
        self.log = log or (lambda text: None)
        self._clients = itertools.count(1)
        self._connections: dict[int, _Connection] = {}
        self._lock = threading.Lock()
        self.refused = 0  #: connections refused or closed because of the limits
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.bind(str(self.path))
        os.chmod(self.path, 0o600)
        self._sock.listen(64)
        self._sock.settimeout(0.2)
        self._running = True
        self._thread = threading.Thread(target=self._accept, name="akarm-serve-control", daemon=True)
        self._thread.start()

    @property
    def connections(self) -> int:
        """Connections open now."""
        return len(self._connections)

    # -- accepting -----------------------------------------------------------------------------
    def _accept(self) -> None:
        short = False  # descriptors ran out (said once until they are back)
        while self._running:
            try:
                conn, _ = self._sock.accept()
            except TimeoutError:
                continue
            except OSError as e:
                if not self._running:
                    return
                if e.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    if not short:
                        self.log(f"akarm serve: cannot accept a control connection: {e.strerror}; closing the "
                                 "connection idle longest, retrying")
                    short = True
                    if self._evict():  # its descriptor is what the waiting connection needs: soon free
                        time.sleep(0.001)
                        continue
                else:
                    self.log(f"akarm serve: accepting a control connection failed ({e}); going on")
                time.sleep(_ACCEPT_RETRY)
                continue
            except Exception:  # a bug: keep accepting
                self.log("akarm serve: the control socket's accept loop failed; going on\n" + traceback.format_exc())
                time.sleep(_ACCEPT_RETRY)
                continue
            short = False
            try:
                self._admit(conn)
            except Exception:
                with contextlib.suppress(OSError):
                    conn.close()
                self.log("akarm serve: could not serve a control connection; going on\n" + traceback.format_exc())

    def _evict(self) -> bool:
        """Close the connection that has waited longest for a request (none busy with one is closed, nor
        a reserved one: it ends soon anyway); False when every one is busy."""
        with self._lock:
            idle = [c for c in self._connections.values() if not c.busy and not c.reserve]
            if not idle:
                return False
            oldest = min(idle, key=lambda c: c.since)
            oldest.busy = True  # it is going: nothing more is taken from it
            self.refused += 1
        oldest.kick()
        return True

    def _admit(self, conn: socket.socket) -> None:
        with self._lock:
            reserved = sum(c.reserve for c in self._connections.values())
        reserve = len(self._connections) - reserved >= MAX_CONNECTIONS and not self._evict()
        if reserve and (reserved >= RESERVED_CONNECTIONS or not self.urgent):
            self.refused += 1
            self._refuse(conn)
            return
        with self._lock:
            c = _Connection(conn, next(self._clients), reserve)
            self._connections[c.client] = c
        try:
            threading.Thread(target=self._serve, args=(c,), name="akarm-serve-client", daemon=True).start()
        except BaseException:  # no thread to be had: this one connection is given up
            with self._lock:
                self._connections.pop(c.client, None)
            raise

    def _busy(self) -> StateError:
        urgent = f" (only {', '.join(sorted(self.urgent))} are taken now)" if self.urgent else ""
        return StateError(f"akarm serve has {MAX_CONNECTIONS} control connections busy with requests{urgent}",
                          fix="try again once one has finished")

    def _refuse(self, conn: socket.socket) -> None:
        e = self._busy()
        with contextlib.suppress(OSError), conn:
            conn.setblocking(False)
            conn.send(json.dumps({"id": None, "ok": False, "error": error_doc(e)}).encode() + b"\n")

    # -- one connection ------------------------------------------------------------------------
    def _serve(self, c: _Connection) -> None:
        try:
            self._requests(c)
        except OSError:  # the client went away (Ctrl-C, killed)
            pass
        finally:
            with self._lock:
                self._connections.pop(c.client, None)
            with contextlib.suppress(OSError):
                c.conn.close()
            if self.closed is not None:
                try:
                    self.closed(c.client)
                except Exception:
                    self.log("akarm serve: ending a control connection failed\n" + traceback.format_exc())

    def _requests(self, c: _Connection) -> None:
        """Read and carry out ``c``'s requests until it ends, breaks a limit, or the server closes."""
        conn = c.conn
        buf = bytearray()
        while self._running:
            newline = buf.find(b"\n")
            if newline >= 0:
                line = bytes(buf[:newline])
                del buf[:newline + 1]
                if not self._request(c, line) or c.reserve:  # (a reserved one carries one request)
                    return
                continue
            if len(buf) > MAX_REQUEST_BYTES:
                self._answer(c, None, ArgumentError(
                    f"a request is at most {MAX_REQUEST_BYTES} bytes; this one is longer",
                    fix="send smaller requests (a recording or trajectory: a file, by its path)"))
                _drain(conn)
                return
            limit = REQUEST_TIMEOUT if buf or c.reserve else IDLE_TIMEOUT
            left = c.since + limit - time.monotonic()
            if left <= 0:
                if buf:
                    self._answer(c, None, ArgumentError(f"a request began but did not end within {limit:g} s",
                                                        fix="end every request with a newline"))
                return
            conn.settimeout(left)
            try:
                data = conn.recv(1 << 16)
            except TimeoutError:
                continue
            if not data:
                return
            if not buf:
                c.since = time.monotonic()  # the request's first byte
            buf += data

    def _request(self, c: _Connection, line: bytes) -> bool:
        """Carry out one request and answer it; False when the connection is to end."""
        with self._lock:
            if c.busy:  # being closed for a newer connection
                return False
            c.busy = True
        req_id: Any = None
        try:
            req_id, op, args = _parse(line)
            if c.reserve and op not in self.urgent:  # a reserved connection carries urgent requests only
                self.refused += 1
                return self._answer(c, req_id, self._busy())
            return self._answer(c, req_id, None, self.dispatch(op, args, c.client))
        except AkarmError as e:
            return self._answer(c, e.req_id if isinstance(e, _BadRequest) else req_id, e)
        except Exception:  # a bug: the client is told the server failed, the log gets the details
            self.log("akarm serve: a control request failed\n" + traceback.format_exc())
            return self._answer(c, req_id, AkarmError("akarm serve failed on this request (a bug; the server "
                                                      "goes on)", fix="see the server's output, and report it"))
        finally:
            with self._lock:
                c.busy = False
                c.since = time.monotonic()

    def _answer(self, c: _Connection, req_id: Any, error: AkarmError | None, result: Any = None) -> bool:
        answer: dict[str, Any] = {"id": req_id, "ok": error is None}
        if error is None:
            answer["result"] = _finite(result)
        else:
            answer["error"] = error_doc(error)
        try:
            data = json.dumps(answer, allow_nan=False).encode() + b"\n"
        except (TypeError, ValueError):  # a result JSON cannot carry: a bug
            self.log(f"akarm serve: cannot send an answer as JSON: {answer!r:.300}")
            data = json.dumps({"id": req_id, "ok": False, "error": error_doc(AkarmError(
                "akarm serve could not encode its answer (a bug)", fix="see the server's output"))}).encode() + b"\n"
        try:
            c.conn.settimeout(SEND_TIMEOUT)
            c.conn.sendall(data)
        except OSError:  # gone, or not reading its answers
            return False
        return True

    def gone(self, client: int) -> bool:
        """True when connection ``client`` has ended or its client hung up (while a request of it runs:
        a long wait can give up early)."""
        c = self._connections.get(client)
        if c is None:
            return True
        try:
            return _readable(c.conn) and c.conn.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False
        except (OSError, ValueError):  # closed meanwhile
            return True

    def close(self) -> None:
        """Stop accepting, end every connection, remove the socket."""
        self._running = False
        with contextlib.suppress(OSError):
            self._sock.close()
        self._thread.join(2.0)
        with self._lock:
            for c in list(self._connections.values()):
                c.kick()
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()


def _drain(conn: socket.socket) -> None:
    """After the answer to a request too long: end the answer (the client reads it, then the end),
    and read and drop what the client is still sending, up to :data:`DRAIN_BYTES` and
    :data:`REQUEST_TIMEOUT` s (a second at most between chunks). Closed at once, the connection would
    cut a client still writing short with a broken pipe, before it could read why."""
    end, got = time.monotonic() + REQUEST_TIMEOUT, 0
    with contextlib.suppress(OSError):  # the client went, or went quiet (a timeout): done
        conn.shutdown(socket.SHUT_WR)
        while got < DRAIN_BYTES and (left := end - time.monotonic()) > 0:
            conn.settimeout(min(left, 1.0))
            data = conn.recv(1 << 16)
            if not data:
                return
            got += len(data)


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
            try:
                self._file.write(json.dumps({"id": request, "op": op, "args": args}).encode() + b"\n")
                self._file.flush()
            except OSError:  # refused (too many connections) or closed: its last word says why, if any
                line = self._file.readline()
                answer = json.loads(line) if line else {}
                if answer.get("ok") is False:
                    raise rebuild_error(answer.get("error") or {}) from None
                raise
            while True:  # answers to calls cut short before (Ctrl-C while waiting) come first: skip them
                line = self._file.readline()
                if not line:
                    raise StateError("akarm serve closed the connection (it is stopping?)",
                                     fix="see the server's output")
                answer = json.loads(line)
                if answer.get("id") == request or (answer.get("id") is None and not answer.get("ok")):
                    break
        except OSError as e:
            raise StateError(f"lost the connection to akarm serve ({e})", fix="is the server still running?") from None
        if not answer.get("ok"):
            raise rebuild_error(answer.get("error") or {})
        return answer.get("result")

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._file.close()
            self._sock.close()

    def __enter__(self) -> SocketClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
