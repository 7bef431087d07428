"""Serial ports as byte streams that never block: a device opened with pyserial, or one end of a
pseudo-terminal pair.

Both sides of akarm's UART port use them: the controller's transport (:mod:`akarm.buses.uart`) on the
serial device, and the simulator (:mod:`akarm.sim.uart`) on its end of the line. A :class:`Port`
reads what has arrived and writes what the port takes; what it cannot take yet waits in
:attr:`Port.backlog`, in order, and goes out first at the next write or :meth:`Port.flush`, so frames
are never cut or interleaved, and a control loop never waits on a port.

A pseudo-terminal pair (:func:`open_pty`) is two ends of one line: bytes written to one end are read
at the other. The other end's path (``/dev/pts/N``) is what a controller opens, as it would open
``/dev/ttyUSB0``. Both ends are put in raw mode (no echo, no line editing, no CR/LF mapping), and a
baud rate means nothing on them.

Bytes written to a pseudo-terminal reach the other end through a kernel work queue: usually at once,
but on a loaded machine a moment later. Lock-step tests read right after the other end wrote, so
when both ends of a pair are open in this process, each end counts what the other wrote, and a read
waits (up to :data:`CATCH_UP` s) until all of it has arrived: a lock-step run over a pair then
depends on nothing but the code.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import sys
import time
from typing import Any

from akarm.errors import BusError

__all__ = ["DEFAULT_BAUDRATE", "Port", "open_pty", "open_serial"]

DEFAULT_BAUDRATE = 921_600  #: the AK drivers' serial port (AK manual §5.2.2)
CATCH_UP = 0.5  #: s a read waits for bytes the other end of a pair in this process wrote (see the docstring)
_READ = 65_536


class _Pair:
    """A pseudo-terminal pair made in this process: the bytes written into each end so far."""

    def __init__(self) -> None:
        self.to_master = 0  # written at the controller's end (the path), for the master to read
        self.to_slave = 0  # written at the master, for the path's end to read


_pairs: dict[str, _Pair] = {}  # by the path of the pair's other end


class Port:
    """A serial port as a non-blocking byte stream (see the module's docstring).

    Args:
        name: what to call it in messages (the device's path).
        fd: a file descriptor to read and write (made non-blocking), or ``None`` to use ``serial``'s
            own methods (a pyserial port without one, as on Windows).
        serial: the pyserial port behind ``fd``, if any (closed with it).
        keep: more file descriptors closed with the port (a pseudo-terminal's other end, kept open).
        pair: for :func:`open_pty` and :func:`open_serial`: this is an end (the master: True) of the
            in-process pair at that path.

    Attributes:
        bytes_in, bytes_out: bytes read and written so far.
    """

    def __init__(self, name: str, fd: int | None, serial: Any = None, keep: tuple[int, ...] = (),
                 pair: tuple[_Pair, bool, str] | None = None) -> None:
        self.name = name
        self._fd = fd
        self._serial = serial
        self._keep = keep
        self._pending = bytearray()
        self._closed = False
        self.bytes_in = 0
        self.bytes_out = 0
        # an end of a pair made in this process: where its writes are counted, and what the other end wrote
        self._pair: _Pair | None = None
        self._master = False
        self._expected0 = 0  # the other end's count when this end began to read
        self._pair_path = ""
        if fd is not None:
            os.set_blocking(fd, False)
            if pair is not None:
                self._pair, self._master, self._pair_path = pair
                self._expected0 = self._sent_to_me()

    def _sent_to_me(self) -> int:
        pair = self._pair
        return 0 if pair is None else pair.to_master if self._master else pair.to_slave

    def __repr__(self) -> str:
        return f"Port({self.name!r}, in={self.bytes_in}, out={self.bytes_out}, backlog={len(self._pending)})"

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def backlog(self) -> int:
        """Bytes written that the port has not taken yet."""
        return len(self._pending)

    def fileno(self) -> int | None:
        """The file descriptor to wait on, or ``None``."""
        return self._fd

    def read(self, check: bool = False) -> bytes:
        """Every byte that has arrived, without waiting (``b""``: none).

        ``check``: when nothing has arrived, also find out whether the port hung up (one more system
        call: a caller that hears nothing for a while asks).

        Raises:
            OSError: the port failed (a USB adapter unplugged, the other end of a pseudo-terminal
                closed); a hang-up only with ``check``, or where reading itself fails.
        """
        if self._fd is None:
            n = self._serial.in_waiting
            data = bytes(self._serial.read(n)) if n else b""
        else:
            chunks: list[bytes] = []
            while True:
                try:
                    chunk = os.read(self._fd, _READ)
                except BlockingIOError:
                    break
                except InterruptedError:
                    continue
                if not chunk:  # no data (a tty with VMIN 0), or a hang-up: readable, yet nothing to read
                    if check and not chunks and select.select([self._fd], [], [], 0)[0]:
                        try:
                            chunk = os.read(self._fd, _READ)  # bytes that came just after the first look
                        except BlockingIOError:
                            break
                        if not chunk:
                            raise OSError(errno.EIO, f"{self.name}: the port was closed or unplugged")
                        chunks.append(chunk)
                    break
                chunks.append(chunk)
                if len(chunk) < _READ:
                    break
            data = b"".join(chunks)
            if self._pair is not None:
                data += self._catch_up(len(data))
        self.bytes_in += len(data)
        return data

    def _catch_up(self, got: int) -> bytes:
        """What the other end of an in-process pair wrote that has not arrived yet (waiting at most
        :data:`CATCH_UP` s; what never comes is forgiven)."""
        assert self._fd is not None
        missing = self._sent_to_me() - self._expected0 - self.bytes_in - got
        if missing <= 0:
            return b""
        chunks: list[bytes] = []
        end = time.monotonic() + CATCH_UP
        while missing > 0 and (left := end - time.monotonic()) > 0:
            with contextlib.suppress(InterruptedError):
                select.select([self._fd], [], [], left)
            try:
                chunk = os.read(self._fd, _READ)
            except (BlockingIOError, InterruptedError):
                continue
            if not chunk:
                time.sleep(0.0002)
                continue
            chunks.append(chunk)
            missing -= len(chunk)
        if missing > 0:
            self._expected0 += missing  # lost (a full buffer): do not wait for them again
        return b"".join(chunks)

    def write(self, data: bytes) -> None:
        """Queue ``data`` behind the backlog and write what the port takes now.

        Raises:
            OSError: the port failed.
        """
        self._pending += data
        self.flush()

    def flush(self) -> None:
        """Write as much of the backlog as the port takes now.

        Raises:
            OSError: the port failed.
        """
        pending = self._pending
        while pending:
            try:
                if self._fd is None:
                    n = self._serial.write(bytes(pending))
                    n = len(pending) if n is None else n
                else:
                    n = os.write(self._fd, pending)
            except BlockingIOError:
                return
            except InterruptedError:
                continue
            if not n:
                return
            del pending[:n]
            self.bytes_out += n
            pair = self._pair
            if pair is not None:
                if self._master:
                    pair.to_slave += n
                else:
                    pair.to_master += n

    def discard_input(self) -> None:
        """Drop every byte that arrived and was not read (stale replies from before)."""
        if self._serial is not None:
            with contextlib.suppress(Exception):
                self._serial.reset_input_buffer()
        elif self._fd is not None:
            with contextlib.suppress(OSError):
                os.read(self._fd, _READ)
        if self._pair is not None:
            self._expected0 = self._sent_to_me() - self.bytes_in

    def wait(self, timeout: float) -> None:
        """Wait until bytes arrive or ``timeout`` s pass."""
        if timeout <= 0:
            return
        if self._fd is None:
            time.sleep(min(timeout, 0.0005))
            return
        with contextlib.suppress(InterruptedError, ValueError, OSError):
            select.select([self._fd], [], [], timeout)

    def close(self) -> None:
        """Close the port (and what it keeps open). Safe to call twice; never raises."""
        if self._closed:
            return
        self._closed = True
        if self._master and _pairs.get(self._pair_path) is self._pair:
            del _pairs[self._pair_path]
        if self._serial is not None:
            with contextlib.suppress(Exception):
                self._serial.close()
        elif self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
        for fd in self._keep:
            with contextlib.suppress(OSError):
                os.close(fd)


def open_serial(path: str, baudrate: int = DEFAULT_BAUDRATE, *, exclusive: bool = True,
                low_latency: bool = True) -> Port:
    """Open the serial device (or pyserial URL) ``path`` at ``baudrate``, 8N1, raw, no flow control.

    ``exclusive``: lock the device so a second program cannot open it too (POSIX). ``low_latency``:
    ask the driver to pass bytes on at once (Linux; FTDI adapters otherwise hold them up to 16 ms);
    ignored where the device does not support it (a pseudo-terminal).

    Raises:
        BusError: pyserial is missing, or the device will not open (what to check is in the message).
    """
    try:
        import serial
    except ImportError:
        raise BusError("the UART port needs pyserial, which is not installed",
                       fix="pip install pyserial (akarm depends on it: reinstall akarm)") from None
    kwargs: dict[str, Any] = {"baudrate": baudrate, "timeout": 0, "write_timeout": 0}
    if exclusive and os.name == "posix" and "://" not in path:
        kwargs["exclusive"] = True
    try:
        port = serial.serial_for_url(path, **kwargs)
    except (serial.SerialException, OSError, ValueError) as e:
        raise BusError(f"cannot open serial port {path!r}: {e}", fix=_open_fix(path, e)) from None
    if low_latency and hasattr(port, "set_low_latency_mode"):
        with contextlib.suppress(Exception):  # a pseudo-terminal or a driver without it
            port.set_low_latency_mode(True)
    fd = getattr(port, "fd", None)
    pair = _pairs.get(path)
    return Port(path, fd if isinstance(fd, int) else None, port, pair=None if pair is None else (pair, False, path))


def _open_fix(path: str, error: BaseException) -> str:
    text = str(error)
    code = getattr(error, "errno", None)
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO) or ("://" not in path and not os.path.exists(path)):
        return (f"there is no {path}: check the adapter is plugged in (ls /dev/ttyUSB* /dev/ttyACM* on Linux; "
                "dmesg says which name it got)")
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return ("you may not open it: add yourself to the group that owns it (on most Linux systems: "
                "sudo usermod -aG dialout $USER, then log in again)")
    if "lock" in text.lower() or code in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY):
        return "another program has the port open (a second controller, a serial terminal): close it first"
    return "check the device's path, its permissions, and that no other program uses it"


def open_pty() -> tuple[Port, str]:
    """A pseudo-terminal pair: the :class:`Port` of its master end, and the path of the other end
    (which stays open inside the port, so the line outlives a controller that closes it and opens it
    again).

    Raises:
        BusError: this system has no pseudo-terminals (Windows).
    """
    if sys.platform == "win32" or not hasattr(os, "openpty"):
        raise BusError("pseudo-terminals need a POSIX system", fix="give the simulator a serial device's path instead")
    import tty

    master, slave = os.openpty()
    for fd in (slave, master):
        tty.setraw(fd)
    path = os.ttyname(slave)
    pair = _pairs[path] = _Pair()
    return Port(f"pty {path}", master, keep=(slave,), pair=(pair, True, path)), path
