"""Which ``akarm serve`` controls which CAN bus on this machine.

A server holds an exclusive ``flock`` on one file per bus it drives
(``/tmp/akarm-UID/serve-INTERFACE-CHANNEL.lock``), and writes
into it who it is (pid, robot, control socket, DDS domain and namespace). The kernel drops the lock
when the process ends, however it ends, so a lock is never stale. A second server for the same bus
is refused; a CLI verb finds the server and talks to it instead of opening the bus itself.

Buses of the ``virtual`` interface live inside one process and are never locked.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import stat
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from akarm.config import BusConfig, RobotConfig
from akarm.errors import StateError
from akarm.files import FileProblem, read_text

__all__ = ["BASE", "BusLock", "any_server", "bus_keys", "find_server", "lock_path", "refuse_if_served", "runtime_dir",
           "sweep_sockets"]

_LOCAL_ONLY = {"virtual"}  # interfaces whose buses no other process can see


#: where :func:`runtime_dir` is made: ``/tmp`` itself, not ``TMPDIR`` (which a service and a shell may set differently)
BASE = Path("/tmp")


def runtime_dir() -> Path:
    """The per-user directory for lock files and control sockets, ``/tmp/akarm-UID`` (created, mode
    700). One fixed place whatever the environment says: a server started by systemd and a CLI in a
    terminal (different ``XDG_RUNTIME_DIR`` or ``TMPDIR``, or none) must find each other.

    Raises:
        StateError: the directory exists but is another user's, or others may write in it (someone
            could plant locks and sockets there).
    """
    path = BASE / f"akarm-{os.getuid()}"
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = path.lstat()
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        raise StateError(f"{path} is not a private directory of this user (owner uid {st.st_uid}, mode "
                         f"{stat.S_IMODE(st.st_mode):o})", fix=f"remove it, or make it yours with mode 700 "
                                                                f"(chmod 700 {path})")
    return path


def bus_keys(robot: RobotConfig | Iterable[BusConfig]) -> list[str]:
    """One name per bus another process could share: ``akarm_local-can0``; for a robot, the buses its
    joints use."""
    if isinstance(robot, RobotConfig):
        used = {j.bus for j in robot.joints}
        buses = [b for name, b in robot.buses.items() if name in used]
    else:
        buses = list(robot)
    keys = {re.sub(r"[^A-Za-z0-9_.-]", "_", f"{b.interface}-{b.channel}") for b in buses
            if b.interface not in _LOCAL_ONLY}
    return sorted(keys)


def lock_path(key: str) -> Path:
    """The lock file of bus ``key`` (:func:`bus_keys`); it exists while a server holds the bus."""
    return runtime_dir() / f"serve-{key}.lock"


class BusLock:
    """The exclusive claim of a server on its robot's buses, for as long as it is held.

    Raises:
        StateError: another process already holds one of the buses (names it and its pid).
    """

    def __init__(self, config: RobotConfig, info: dict[str, Any]) -> None:
        self.keys = bus_keys(config)
        self._fds: list[tuple[str, int]] = []
        payload = json.dumps({**info, "pid": os.getpid()}).encode()
        try:
            for key in self.keys:
                fd = _claim(key)
                os.ftruncate(fd, 0)
                os.pwrite(fd, payload, 0)
                self._fds.append((key, fd))
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        """Give the buses up and remove the lock files (each while still locked: a process that opened
        it meanwhile finds, once it has the lock, that the file is no longer the bus's, and tries anew)."""
        fds, self._fds = self._fds, []
        for key, fd in fds:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
                if _is_the_file(fd, lock_path(key)):
                    lock_path(key).unlink()
            os.close(fd)  # closing drops the flock


def _is_the_file(fd: int, path: Path) -> bool:
    """True when ``path`` is still the file open as ``fd`` (not removed, not replaced)."""
    try:
        a, b = os.fstat(fd), os.stat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def _claim(key: str) -> int:
    """The lock file of bus ``key``, created if need be and locked exclusively: its descriptor.

    Raises:
        StateError: another server holds it (named), or it cannot be created.
    """
    for _ in range(100):  # a server that ends removes its file: lock the one that is there now
        try:
            fd = os.open(lock_path(key), os.O_RDWR | os.O_CREAT, 0o600)
        except OSError as e:
            raise StateError(f"cannot create the lock file for bus {key}: {e}",
                             fix=f"make {runtime_dir()} writable for this user") from None
        if not _lock_exclusive(fd):
            os.close(fd)
            other = _read(key)
            who = f"akarm serve (pid {other.get('pid', '?')}, {other.get('robot', '?')})" if other else \
                "another akarm serve"
            raise StateError(f"{who} already controls the bus {key}; two controllers on one bus are refused",
                             fix="use that server (the CLI verbs talk to it), or stop it first")
        if _is_the_file(fd, lock_path(key)):
            return fd
        os.close(fd)  # removed by the server that held it while this process waited: not the bus's any more
    raise StateError(f"the lock file of bus {key} keeps being replaced", fix="is another program removing files in "
                     f"{runtime_dir()}?")


def _lock_exclusive(fd: int, patience: float = 0.05) -> bool:
    """Take the exclusive lock, trying for ``patience`` s: a process that only looks whether a server
    runs (:func:`_held`, every CLI verb and every Arm.open) holds a shared lock for a moment."""
    end = time.monotonic() + patience
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= end:
                return False
            time.sleep(0.002)


def _read(key: str) -> dict[str, Any] | None:
    """What a server wrote in its lock file (a line of JSON; ``None`` when there is none or it is not
    that: anything past 64 KiB is not)."""
    try:
        text = read_text(lock_path(key), 1 << 16, what="lock file")
        found = json.loads(text) if text else None
    except (FileProblem, ValueError, RecursionError):
        return None
    return found if isinstance(found, dict) else None


def _held(key: str) -> bool:
    path = lock_path(key)
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def sweep_sockets() -> int:
    """Remove the control sockets of servers that are gone (``serve-PID-ID.sock`` of a process that
    no longer exists: a server killed with SIGKILL cannot remove its own). Returns how many."""
    removed = 0
    with contextlib.suppress(OSError):
        for path in runtime_dir().glob("serve-*-*.sock"):
            pid = path.name.split("-")[1]
            if not pid.isdigit():
                continue
            try:
                os.kill(int(pid), 0)
            except ProcessLookupError:
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed += 1
            except PermissionError:  # alive, another user's
                pass
    return removed


def any_server() -> bool:
    """True when some ``akarm serve`` of this user runs on this machine (cheap: no config needed)."""
    try:
        return any(_held(p.name[len("serve-"):-len(".lock")]) for p in runtime_dir().glob("serve-*.lock"))
    except OSError:  # no runtime directory to be had: then no server could have registered either
        return False


def find_server(robot: RobotConfig | Iterable[BusConfig], wait: float = 1.0) -> dict[str, Any] | None:
    """The running server (its info: pid, robot, socket, domain, namespace) that controls one of
    ``robot``'s buses (a robot's, or the buses given), or ``None``. A server of this very process
    does not count."""
    if not any_server():
        return None
    for key in bus_keys(robot):
        if not _held(key):
            continue
        end = time.monotonic() + wait
        info = _read(key)
        while info is None and time.monotonic() < end:  # a server that is writing who it is ...
            time.sleep(0.02)
            if not _held(key):  # ... or one that has just stopped
                break
            info = _read(key)
        if info is None and not _held(key):
            continue
        if info is not None and info.get("pid") == os.getpid():
            continue
        return info or {"pid": None, "bus": key}
    return None


def refuse_if_served(robot: RobotConfig | Iterable[BusConfig], what: str = "this") -> None:
    """Raise :class:`~akarm.StateError` when an ``akarm serve`` of another process drives one of the buses."""
    info = find_server(robot)
    if info is not None:
        raise StateError(f"akarm serve (pid {info.get('pid')}, {info.get('robot', '?')}) controls this robot's bus; "
                         f"{what} would be a second controller on it",
                         fix="stop the server first (Ctrl-C or kill -TERM), or let it do this (akarm CLI verbs use it)")
