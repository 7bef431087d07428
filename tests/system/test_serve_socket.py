"""The control socket cannot be wedged: floods, descriptors running out, NaN, huge and deeply nested
requests, wrong arguments. Each leaves the server answering a fresh ``status`` within 1 s and its
thread count back where it was.

Against ``akarm serve --no-ros`` in a process of its own (the simulator in another, on akarm_local),
as a client would find it; the limits' own timing with a :class:`SocketServer` in this process.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import socket
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from akarm.buses.ownership import find_server, runtime_dir
from akarm.errors import ArgumentError, StateError
from akarm.robotfile.load import load_robot
from akarm.server import socket as control
from akarm.server.socket import SocketClient, SocketServer
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot, wait_until

pytestmark = pytest.mark.slow
INTERNAL = ("TypeError", "KeyError", "JSONDecodeError", "RecursionError", "ValueError", "Traceback")


class Serve:
    """``akarm serve --no-ros`` in a child process; its socket, pid and threads."""

    def __init__(self, robot: Path, channel: str) -> None:
        self.robot, self.channel = robot, channel
        self.lines: list[str] = []
        self.proc = subprocess.Popen([sys.executable, "-m", "akarm", "serve", str(robot), "-i", "akarm_local", "-c",
                                      channel, "--no-ros"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        started = threading.Event()

        def read() -> None:
            for line in self.proc.stdout:  # type: ignore[union-attr]
                self.lines.append(line)
                if line.startswith("serving"):
                    started.set()
            started.set()

        threading.Thread(target=read, daemon=True).start()
        if not started.wait(90) or self.proc.poll() is not None:
            self.close()
            pytest.fail("akarm serve did not start:\n" + "".join(self.lines))
        info = find_server(load_robot(robot).with_bus(interface="akarm_local", channel=channel))
        assert info is not None
        self.path = str(info["socket"])

    @property
    def threads(self) -> int:
        return len(os.listdir(f"/proc/{self.proc.pid}/task"))

    def fds(self) -> int:
        return len(os.listdir(f"/proc/{self.proc.pid}/fd"))

    def status_within(self, seconds: float = 1.0) -> float:
        """A fresh connection's ``status``: how long it took (it must answer within ``seconds``)."""
        t0 = time.monotonic()
        with SocketClient(self.path, timeout=seconds) as c:
            doc = c.call("status")
        took = time.monotonic() - t0
        assert doc["mode"] and took < seconds, f"status took {took:.3f} s"  # (a loaded machine may stop the arm)
        return took

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(60)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Serve]:
    robot = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path_factory.mktemp("socket"))
    channel = f"sock{os.getpid()}"
    with SimulatorProcess(robot, channel=channel, pose="down"):
        server = Serve(robot, channel)
        try:
            yield server
        finally:
            server.close()


@pytest.fixture
def idle(served: Serve) -> Iterator[int]:
    """The server's idle thread count, before the test; after it, the count must come back to it."""
    served.status_within(5.0)  # settled (the first status may wait for a loaded machine)
    assert wait_until(lambda: served.threads == served.threads, 1.0)
    before = served.threads
    yield before
    assert wait_until(lambda: served.threads <= before, 10.0), f"threads {served.threads}, idle {before}"
    served.status_within()
    assert served.proc.poll() is None, "".join(served.lines)


def raw(path: str, data: bytes, read: bool = True, timeout: float = 10.0) -> dict:
    """Send ``data`` as it is on a new connection; the first answer line (parsed), or {} if none came."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout)
        s.connect(path)
        s.sendall(data)
        if not read:
            return {}
        with s.makefile("rb") as f:
            line = f.readline()
    return json.loads(line) if line else {}


def test_the_socket_is_the_users_alone(served: Serve):
    assert stat.S_IMODE(os.stat(served.path).st_mode) == 0o600
    assert stat.S_IMODE(os.stat(runtime_dir()).st_mode) == 0o700


def test_a_thousand_connections_then_closed_leave_it_answering(served: Serve, idle: int):
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, max(soft, 4096)), hard))
    conns: list[socket.socket] = []
    try:
        for _ in range(1000):
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.connect(served.path)
            conns.append(s)
        served.status_within()  # even now: the connection idle longest made room for it
        assert served.threads <= idle + control.MAX_CONNECTIONS + 4
    finally:
        for s in conns:
            s.close()
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    served.status_within()


def test_descriptors_running_out_do_not_end_the_accept_loop(served: Serve, idle: int):
    soft, hard = resource.prlimit(served.proc.pid, resource.RLIMIT_NOFILE)
    conns: list[socket.socket] = []
    try:
        resource.prlimit(served.proc.pid, resource.RLIMIT_NOFILE, (served.fds() + 6, hard))
        for _ in range(40):  # past its descriptors: accept fails with EMFILE until it frees one
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.connect(served.path)
            conns.append(s)
        served.status_within()  # the idle longest closed to make room
    finally:
        resource.prlimit(served.proc.pid, resource.RLIMIT_NOFILE, (soft, hard))
        for s in conns:
            s.close()
    assert any("cannot accept a control connection" in line for line in served.lines)


@pytest.mark.parametrize("request_line", [
    b'{"id": 1, "op": "sleep", "args": {"seconds": NaN}}\n',
    b'{"id": 1, "op": "sleep", "args": {"seconds": Infinity}}\n',
    b'{"id": 1, "op": "sleep", "args": {"seconds": 1e999}}\n',
    b'{"id": 1, "op": "sleep", "args": {"seconds": -Infinity}}\n',
])
def test_nan_and_infinite_durations_are_refused_and_leave_no_thread(served: Serve, idle: int, request_line: bytes):
    answer = raw(served.path, request_line)
    assert answer["ok"] is False and answer["error"]["type"] == "ArgumentError"
    text = answer["error"]["text"]
    assert "NaN" in text or "Infinity" in text or "finite" in text
    assert not any(word in text for word in INTERNAL)


def test_a_64_mib_line_is_cut_off_at_the_limit(served: Serve, idle: int):
    sent: list[BaseException | None] = []

    def flood() -> None:
        try:
            raw(served.path, b'{"op": "state", "args": {"x": "' + b"a" * (64 << 20), read=False, timeout=30)
            sent.append(None)
        except OSError as e:  # the server closed the connection after the first MiB
            sent.append(e)

    t = threading.Thread(target=flood)
    t.start()
    served.status_within()  # meanwhile
    t.join(60)
    assert sent, "the sender is not stuck"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:  # and the answer says why
        s.settimeout(30)
        s.connect(served.path)
        with contextlib.suppress(OSError):
            s.sendall(b"x" * (control.MAX_REQUEST_BYTES + (1 << 17)))
        answer = json.loads(s.makefile("rb").readline())
    assert answer["error"]["type"] == "ArgumentError" and "at most 1048576 bytes" in answer["error"]["text"]


def test_a_client_still_writing_a_2_mib_request_reads_why_it_is_refused(served: Serve, idle: int):
    """Once past the 1 MiB limit the server answers and reads the rest away (up to DRAIN_BYTES):
    the client's write of 2 MiB completes, with no broken pipe, and the answer says why."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(30)
        s.connect(served.path)
        s.sendall(b'{"id": 3, "op": "state", "args": {"x": "' + b"a" * (2 << 20) + b'"}}\n')  # raises if cut short
        answer = json.loads(s.makefile("rb").readline())
    assert answer["ok"] is False and answer["error"]["type"] == "ArgumentError", answer
    assert "a request is at most 1048576 bytes; this one is longer" in answer["error"]["text"]
    with SocketClient(served.path, timeout=30) as c, pytest.raises(ArgumentError, match="at most 1048576 bytes"):
        c.call("state", x="a" * (2 << 20))  # the library's client says it too
    served.status_within()  # and the server goes on


@pytest.mark.parametrize("request_line", [
    b"[" * 200_000 + b"]" * 200_000 + b"\n",
    b'{"op": "move", "args": {"target": ' + b"[" * 50_000 + b"]" * 50_000 + b"}}\n",
    b'{"op": "move", "args": {"target": ' + b"[" * 500 + b"1" + b"]" * 500 + b"}}\n",
])
def test_deeply_nested_json_is_refused(served: Serve, idle: int, request_line: bytes):
    answer = raw(served.path, request_line)
    assert answer["ok"] is False and answer["error"]["type"] == "ArgumentError"
    assert "nested too deeply" in answer["error"]["text"] or "must be a number, not a list" in answer["error"]["text"]
    assert not any(word in answer["error"]["text"] for word in INTERNAL)


@pytest.mark.parametrize(("request_line", "named"), [
    (b'{"id": 7, "op": "move", "args": {"target": 5}}', "'target'"),
    (b'{"id": 7, "op": "move", "args": {"target": "home", "speed": "fast"}}', "'speed'"),
    (b'{"id": 7, "op": "move", "args": {"target": [0.1, null]}}', "'target' of 'move' item 1"),
    (b'{"id": 7, "op": "move", "args": {}}', "'target'"),
    (b'{"id": 7, "op": "move", "args": {"target": "home", "force": 1}}', "'force'"),
    (b'{"id": 7, "op": "wait", "args": {"id": "x"}}', "'id'"),
    (b'{"id": 7, "op": "sleep", "args": {"seconds": [1]}}', "'seconds'"),
    (b'{"id": 7, "op": "sleep", "args": {"seconds": -1}}', "'seconds'"),
    (b'{"id": 7, "op": "telemetry", "args": {"since": {"a": 1}}}', "'since'"),
    (b'{"id": 7, "op": "state", "args": {"read": "yes"}}', "'read'"),
    (b'{"id": 7, "op": "teach", "args": {"client": 3}}', "'client'"),
    (b'{"id": 7, "op": 5, "args": {}}', "'op'"),
    (b'{"id": 7, "op": "__init__", "args": {}}', "'__init__'"),
    (b'{"id": 7, "op": "state", "args": [1, 2]}', "'args'"),
    (b'{"id": 7, "op": "state", "args": {}, "sudo": true}', "'sudo'"),
    (b'[1, 2, 3]', "JSON object"),
    (b'{"op": "state", "args": {}', "not JSON"),
    (b'\xff\xfe not utf-8', "not JSON"),
])
def test_wrong_requests_get_an_argument_error_naming_what_is_wrong(served: Serve, idle: int, request_line: bytes,
                                                                   named: str):
    answer = raw(served.path, request_line + b"\n")
    assert answer["ok"] is False and answer["error"]["type"] == "ArgumentError", answer
    assert named in answer["error"]["text"]
    assert not any(word in answer["error"]["text"] for word in INTERNAL)
    if request_line.startswith(b'{"id": 7'):
        assert answer["id"] == 7


def test_one_connection_survives_its_bad_requests(served: Serve, idle: int):
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(10)
        s.connect(served.path)
        f = s.makefile("rwb")
        for line in (b"nonsense", b'{"op": "sleep", "args": {"seconds": NaN}}', b'{"id": 2, "op": "state"}'):
            f.write(line + b"\n")
            f.flush()
            answer = json.loads(f.readline())
        assert answer["ok"] and answer["id"] == 2 and answer["result"]["names"] == ["shoulder", "elbow"]
        assert all(isinstance(a, float) for a in answer["result"]["age"])


def test_a_client_that_hangs_up_during_a_long_sleep_leaves_no_thread(served: Serve, idle: int):
    with SocketClient(served.path, timeout=60) as c:
        if c.call("status")["stop"]:  # a loaded machine stopped the arm: the sleep would end at once
            c.call("enable")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(1.0)
        s.connect(served.path)
        s.sendall(b'{"id": 1, "op": "sleep", "args": {"seconds": 3600}}\n')
        with pytest.raises(TimeoutError):
            s.recv(1000)  # sleeping
    # the fixture checks that its thread ends (within 10 s, not an hour)


def test_the_protocol_describes_itself(served: Serve):
    with SocketClient(served.path, timeout=10) as c:
        doc = c.call("describe")
    assert doc["protocol"] == 2 and doc["ops"]["move"]["target"].startswith("text")
    assert doc["limits"] == {"connections": control.MAX_CONNECTIONS, "request_bytes": control.MAX_REQUEST_BYTES,
                             "request_seconds": control.REQUEST_TIMEOUT, "idle_seconds": control.IDLE_TIMEOUT,
                             "reserved_connections": control.RESERVED_CONNECTIONS,
                             "urgent_ops": ["describe", "disable", "hold", "snapshot", "state", "status", "stop"]}


# -- the limits' timing, on a socket server in this process ------------------------------------------
@pytest.fixture
def small_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(control, "MAX_CONNECTIONS", 3)
    monkeypatch.setattr(control, "REQUEST_TIMEOUT", 0.3)
    monkeypatch.setattr(control, "IDLE_TIMEOUT", 0.6)


def test_a_request_that_never_ends_and_an_idle_connection_are_closed(tmp_path: Path, small_limits: None):
    ended: list[int] = []
    server = SocketServer(tmp_path / "c.sock", lambda op, args, client: {"op": op}, closed=ended.append)
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as slow, \
                socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as quiet:
            slow.settimeout(5)
            quiet.settimeout(5)
            slow.connect(str(tmp_path / "c.sock"))
            quiet.connect(str(tmp_path / "c.sock"))
            slow.sendall(b'{"op": "st')  # and no more
            answer = json.loads(slow.makefile("rb").readline())
            assert "did not end within 0.3 s" in answer["error"]["text"]
            assert quiet.recv(10) == b"", "closed after 0.6 s without a request"
        assert wait_until(lambda: len(ended) == 2, 2.0)
    finally:
        server.close()


def test_past_the_connection_limit_the_idle_longest_goes_and_busy_ones_stay(tmp_path: Path, small_limits: None):
    release = threading.Event()
    blocked: list[int] = []

    def dispatch(op: str, args: dict, client: int) -> str:
        if op == "block":
            blocked.append(client)
            release.wait(10)
        return op

    server = SocketServer(tmp_path / "c.sock", dispatch)
    path = str(tmp_path / "c.sock")
    clients: list[SocketClient] = []
    waits: list[threading.Thread] = []

    def block(c: SocketClient) -> None:
        waits.append(threading.Thread(target=c.call, args=("block",), daemon=True))
        waits[-1].start()

    try:
        first = SocketClient(path, timeout=5)
        assert first.call("hello") == "hello"
        clients = [SocketClient(path, timeout=10) for _ in range(2)]
        for c in clients:
            block(c)
        assert wait_until(lambda: len(blocked) == 2, 2.0)
        fourth = SocketClient(path, timeout=10)  # the idle `first` makes room; the busy two stay
        assert fourth.call("hi") == "hi"
        with pytest.raises(StateError, match=r"closed the connection|lost the connection"):
            first.call("again")
        block(fourth)
        assert wait_until(lambda: len(blocked) == 3 and server.connections == 3, 2.0)
        with SocketClient(path, timeout=5) as fifth, pytest.raises(StateError, match="3 control connections busy"):
            fifth.call("x")  # every one busy with a request: refused, with the reason
        assert server.refused == 2
    finally:
        release.set()
        for t in waits:
            t.join(5)
        server.close()


def test_a_client_on_a_descriptor_past_1023_is_not_taken_for_gone(tmp_path: Path):
    """A process with more than 1023 files open (a script serving its arm with many files, cameras,
    sockets open): ``select`` cannot take such descriptors. The server's "has the client left?" used to
    read its error as "yes", so every served wait and sleep returned at once while the arm moved."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if max(soft, hard if hard != resource.RLIM_INFINITY else 4096) < 1200:
        pytest.skip("this process may not open 1200 files")
    if soft < 1200:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(4096, hard), hard))
    answers: list[bool] = []
    server: SocketServer | None = None

    def dispatch(op: str, args: dict, client: int) -> bool:
        assert server is not None
        gone = server.gone(client)
        answers.append(gone)
        return gone

    filler = [os.open(os.devnull, os.O_RDONLY) for _ in range(1100)]  # the connections' descriptors come after
    try:
        server = SocketServer(tmp_path / "c.sock", dispatch)
        try:
            with SocketClient(str(tmp_path / "c.sock"), timeout=5) as c:
                assert c.call("still_there") is False
            assert answers == [False]
        finally:
            server.close()
    finally:
        for fd in filler:
            os.close(fd)


def test_with_every_connection_busy_an_urgent_request_still_gets_through(tmp_path: Path, small_limits: None,
                                                                         monkeypatch: pytest.MonkeyPatch):
    """Connections held by long requests (sleeps of a day, waits for motions) used to refuse every new
    one, `akarm disable` included. A reserved connection carries one urgent request; others are refused."""
    monkeypatch.setattr(control, "RESERVED_CONNECTIONS", 1)
    release = threading.Event()
    blocked: list[int] = []
    done: list[str] = []

    def dispatch(op: str, args: dict, client: int) -> str:
        if op == "block":
            blocked.append(client)
            release.wait(10)
        done.append(op)
        return op

    path = tmp_path / "c.sock"
    server = SocketServer(path, dispatch, urgent=frozenset({"disable"}))
    waits: list[threading.Thread] = []
    clients = [SocketClient(str(path), timeout=10) for _ in range(3)]
    try:
        for c in clients:
            waits.append(threading.Thread(target=c.call, args=("block",), daemon=True))
            waits[-1].start()
        assert wait_until(lambda: len(blocked) == 3, 2.0)
        with SocketClient(str(path), timeout=5) as urgent:
            assert urgent.call("disable") == "disable"
        with SocketClient(str(path), timeout=5) as other, \
                pytest.raises(StateError, match=r"3 control connections busy.*only disable are taken now"):
            other.call("move")
        assert "move" not in done
        assert wait_until(lambda: server.connections == 3, 2.0)  # that reserved connection has ended
        # the reserve is one connection: while one holds it (no request yet), the next is refused at once
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as holder:
            holder.connect(str(path))
            assert wait_until(lambda: server.connections == 4, 2.0)
            with SocketClient(str(path), timeout=5) as late, pytest.raises(StateError, match="busy"):
                late.call("disable")
            assert holder.recv(10) == b"", "a reserved connection waits no longer than a request may take"
        assert wait_until(lambda: server.connections == 3, 2.0)
        with SocketClient(str(path), timeout=5) as again:  # free again
            assert again.call("disable") == "disable"
    finally:
        release.set()
        for t in waits:
            t.join(5)
        for c in clients:
            c.close()
        server.close()
