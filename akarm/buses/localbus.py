"""``akarm_local``: a CAN bus shared by the processes of one machine, for the simulator without vcan.

SocketCAN's ``vcan`` is the best stand-in for a real bus, but only Linux kernels with the vcan module
have it, and python-can's ``virtual`` bus lives inside one process. This python-can interface joins
processes on any machine, through a memory-mapped file::

    akarm sim robots/arm6.yaml -i akarm_local -c can0          # terminal 1: the simulated drivers
    akarm move robots/arm6.yaml ready -i akarm_local -c can0   # terminal 2: the controller

Like ``vcan0``, a channel is machine-wide (per user): every bus opened on the same channel name, by
any process, receives every frame the others send (and not its own, unless ``receive_own_messages``).
Classic CAN only (at most 8 data bytes); there is no bit timing, so ``bitrate`` is accepted and
ignored, as on vcan.

Why not sockets: sending and receiving need no system call, so a frame costs about 2 µs each way, where
python-can's ``virtual`` bus deep-copies every frame into a queue per listener (15-40 µs) and a
loopback datagram costs 10-30 µs when the caller wakes from sleep. With the simulator in a process of
its own, the controller's loop pays only its own work, and the simulator does not share its
interpreter lock. The price: a receiver that waits polls, sleeping 20-200 µs between looks (so
an idle bus costs well under 1 % of a core, and a frame waits at most about 0.3 ms to be seen).

How: the file (``/dev/shm/akarm-can-UID-CHANNEL`` on Linux, the temporary directory elsewhere) holds
32 rings of 512 frame slots. Each open bus owns one ring and is its only writer; readers keep a
position in every ring. A slot is written data first and sequence number last, and carries a CRC-32
of its sequence number and contents, so a reader never takes a half-written frame, nor the frame a
slot held one lap before (which a weakly ordered CPU could show it beside the new sequence number). A reader
that falls 512 frames behind a writer loses the oldest (counted in :attr:`LocalBus.overruns`), as a
CAN controller's receive queue would. Rings of processes that died are reclaimed.

Registered with python-can as the ``akarm_local`` interface (``can.Bus(interface="akarm_local",
channel="can0")``), so python-can's own tools (``python -m can.viewer -i akarm_local -c can0``)
work on it too.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import re
import struct
import sys
import tempfile
import threading
import time
import zlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import can
from can.typechecking import AutoDetectedConfig

from akarm.buses.frames import message

__all__ = ["INTERFACE", "LocalBus", "channel_path", "peers"]

INTERFACE = "akarm_local"

_MAGIC = b"AKCANv2\0"  # v2: the CRC covers the sequence number
_RINGS = 32
_SLOTS = 512  # per ring; a power of two
# header: magic, rings, slots, generation (bumped when a ring is claimed or released); then per ring:
# owner pid (0 = free), owner token, ever used (only those rings hold frames)
_HEADER = struct.Struct("<8sII")
_GEN = struct.Struct("<I")
_GEN_AT = _HEADER.size
_OWNER = struct.Struct("<III")
_OWNERS_AT = _GEN_AT + _GEN.size
# per ring, after the owners: the monotonic time (s) its owner last read the channel to the end
# (LocalBus.beat(), which a simulator calls; 0: never), so that a controller can tell a simulator
# that did not run in time from a motor that does not answer
_BEAT = struct.Struct("<d")
_BEATS_AT = 1024
_RINGS_AT = 4096
# slot: sequence number (frame k of the ring is written with k + 1; 0 = never written), then the
# CRC-32 of the sequence number and the rest: timestamp, CAN ID with SocketCAN's flag bits, DLC, 3 pad
# bytes, 8 data bytes
_SEQ = struct.Struct("<Q")
_CRC = struct.Struct("<I")
_REST = struct.Struct("<dIB3x8s")
_BODY = struct.Struct("<IdIB3x8s")
_SLOT_SIZE = 40
_PAD = _SLOT_SIZE - _SEQ.size - _BODY.size
_RING_SIZE = _SLOTS * _SLOT_SIZE
_SIZE = _RINGS_AT + _RINGS * _RING_SIZE
_EFF, _RTR, _ERR = 0x8000_0000, 0x4000_0000, 0x2000_0000
_ID_MASK = 0x1FFF_FFFF
_POLL_MIN, _POLL_MAX = 20e-6, 200e-6
_SKIPPED = object()


def _slot(ring: int, k: int) -> int:
    """Offset in the file of the slot that holds frame ``k`` of ``ring``."""
    return _RINGS_AT + ring * _RING_SIZE + k % _SLOTS * _SLOT_SIZE


def channel_path(channel: str) -> Path:
    """The file behind ``channel`` (per user; in ``/dev/shm`` where it exists)."""
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", channel)[:64]
    if safe != channel:
        safe += f"-{zlib.crc32(channel.encode('utf-8')):08x}"  # distinct names stay distinct
    user = os.getuid() if hasattr(os, "getuid") else 0
    folder = Path("/dev/shm") if Path("/dev/shm").is_dir() else Path(tempfile.gettempdir())
    return folder / f"akarm-can-{user}-{safe}"


def peers(channel: str) -> list[int]:
    """IDs of the other live processes with a bus open on ``channel`` (read-only; empty when the
    channel's file does not exist or cannot be read)."""
    try:
        with open(channel_path(channel), "rb") as f:
            data = f.read(_RINGS_AT)
    except OSError:
        return []
    if len(data) < _OWNERS_AT + _RINGS * _OWNER.size or data[:8] != _MAGIC:
        return []
    pids = {_OWNER.unpack_from(data, _OWNERS_AT + r * _OWNER.size)[0] for r in range(_RINGS)}
    return sorted(p for p in pids if p and p != os.getpid() and _alive(p))


def _alive(pid: int) -> bool:
    if pid == os.getpid() or sys.platform == "win32":  # (os.kill would terminate it there)
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists (another user's), or cannot tell: do not take its ring
    return True


@contextlib.contextmanager
def _locked(fd: int) -> Iterator[None]:
    """Hold an exclusive lock on the file (claiming and releasing rings; never on the hot path)."""
    try:
        import fcntl
    except ImportError:  # Windows: no advisory locks; rings are claimed optimistically
        yield
        return
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        yield
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)


class LocalBus(can.BusABC):
    """A python-can bus on the machine-wide channel ``channel`` (see the module docstring).

    Args:
        channel: the channel's name, any string (``"can0"``, ``"test-1234"``).
        receive_own_messages: also receive the frames this bus sends.
        bitrate, and other python-can keyword arguments: accepted and ignored (``can_filters`` works).

    Attributes:
        overruns: frames lost because this bus read too slowly (more than 512 behind a writer).

    Raises:
        can.CanInitializationError: the channel's file cannot be created or mapped, or all 32 rings
            are taken by live processes (the message says which file).
    """

    def __init__(self, channel: Any = "can0", receive_own_messages: bool = False, **kwargs: Any) -> None:
        self.channel = str(channel)
        self.channel_info = f"akarm_local channel {self.channel!r}"
        self.receive_own_messages = bool(receive_own_messages)
        self.overruns = 0
        self._path = channel_path(self.channel)
        self._closed = True
        self._send_lock = threading.Lock()
        self._token = int.from_bytes(os.urandom(4), "little") or 1
        self._fd, self._mm = self._open()
        try:
            with _locked(self._fd):
                self._ring = self._claim()
                # read from now on: every ring's next sequence number is where its writer is
                self._pos = [self._head(r) for r in range(_RINGS)]
                self._seq = self._pos[self._ring]
        except BaseException:
            self._mm.close()
            os.close(self._fd)
            raise
        self._closed = False
        self._gen = -1
        self._active: list[int] = []
        self._next = 0  # index in _active to look at first
        super().__init__(channel=self.channel, can_filters=kwargs.get("can_filters"))

    # -- the shared file ------------------------------------------------------------------------
    def _open(self) -> tuple[int, mmap.mmap]:
        """Open (creating if need be) and map the channel's file, the one at its path right now."""
        for _ in range(100):
            try:
                fd = os.open(self._path, os.O_RDWR | os.O_CREAT, 0o600)
            except OSError as e:
                raise can.CanInitializationError(f"{self.channel_info}: cannot open {self._path} ({e})") from None
            try:
                with _locked(fd):
                    try:
                        same = os.stat(self._path).st_ino == os.fstat(fd).st_ino
                    except FileNotFoundError:
                        same = False
                    if same:  # not unlinked by the channel's last user meanwhile
                        return fd, self._map(fd)
            except BaseException:
                os.close(fd)
                raise
            os.close(fd)
        raise can.CanInitializationError(f"{self.channel_info}: {self._path} keeps being replaced")

    def _map(self, fd: int) -> mmap.mmap:
        size = os.fstat(fd).st_size
        if size not in (0, _SIZE):
            raise can.CanInitializationError(
                f"{self.channel_info}: {self._path} has {size} bytes, not {_SIZE}; it is not an akarm_local "
                f"channel of this version: delete it (when nothing uses the channel) or pick another channel")
        if size == 0:
            os.ftruncate(fd, _SIZE)  # sparse: only the pages of rings in use take memory
        mm = mmap.mmap(fd, _SIZE)
        magic, rings, slots = _HEADER.unpack_from(mm, 0)
        if magic == b"\0" * 8:
            _HEADER.pack_into(mm, 0, _MAGIC, _RINGS, _SLOTS)
        elif (magic, rings, slots) != (_MAGIC, _RINGS, _SLOTS):
            mm.close()
            raise can.CanInitializationError(
                f"{self.channel_info}: {self._path} is not an akarm_local channel of this version: delete it "
                f"(when nothing uses the channel) or pick another channel")
        return mm

    def _claim(self) -> int:
        pids = []
        for r in range(_RINGS):
            pid, _token, _used = _OWNER.unpack_from(self._mm, _OWNERS_AT + r * _OWNER.size)
            if pid == 0 or not _alive(pid):
                _OWNER.pack_into(self._mm, _OWNERS_AT + r * _OWNER.size, os.getpid(), self._token, 1)
                _BEAT.pack_into(self._mm, _BEATS_AT + r * _BEAT.size, 0.0)  # not the last owner's
                self._bump()
                return r
            pids.append(pid)
        raise can.CanInitializationError(
            f"{self.channel_info}: all {_RINGS} places on the channel are taken (processes "
            f"{', '.join(map(str, sorted(set(pids))))}); close some buses or use another channel")

    def _bump(self) -> None:
        """Tell every reader that the set of rings in use changed (under the file lock)."""
        _GEN.pack_into(self._mm, _GEN_AT, (_GEN.unpack_from(self._mm, _GEN_AT)[0] + 1) & 0xFFFF_FFFF)

    def _refresh(self) -> None:
        """Re-list the rings to read when a ring was claimed or released since the last look: the
        owned ones, plus released ones that still hold frames this bus has not read (a process that
        sent and exited before this bus looked)."""
        self._gen = _GEN.unpack_from(self._mm, _GEN_AT)[0]
        active = []
        for r in range(_RINGS):
            if r == self._ring and not self.receive_own_messages:
                continue
            pid, _token, used = _OWNER.unpack_from(self._mm, _OWNERS_AT + r * _OWNER.size)
            if pid or (used and self._pending(r)):
                active.append(r)
        self._active = active

    def _pending(self, ring: int) -> bool:
        pos = self._pos[ring]
        return _SEQ.unpack_from(self._mm, _slot(ring, pos))[0] > pos

    def _head(self, ring: int) -> int:
        """The next sequence number ``ring``'s writer will use (the highest written, from the slots)."""
        if not _OWNER.unpack_from(self._mm, _OWNERS_AT + ring * _OWNER.size)[2]:
            return 0  # never used: do not touch (and so allocate) its pages
        base = _slot(ring, 0)
        return max(seq for seq, in struct.iter_unpack(f"<Q{_SLOT_SIZE - 8}x", self._mm[base:base + _RING_SIZE]))

    # -- a simulator's heartbeat -----------------------------------------------------------------
    def beat(self) -> None:
        """Say that this bus's process has just read every frame waiting (a simulator calls it after
        each look at the channel): :meth:`peers_read` of the other processes then tells it."""
        if not self._closed:
            _BEAT.pack_into(self._mm, _BEATS_AT + self._ring * _BEAT.size, time.monotonic())

    def peers_read(self) -> float | None:
        """The monotonic time (s) at which a live process of the channel that beats (a simulator: see
        :meth:`beat`) last read it to the end, the latest of them; ``None`` when none beats. A
        simulator that has not read the channel since a command was sent has not seen the command."""
        if self._closed:
            return None
        latest = None
        for r in range(_RINGS):
            if r == self._ring:
                continue
            beat = _BEAT.unpack_from(self._mm, _BEATS_AT + r * _BEAT.size)[0]
            pid = _OWNER.unpack_from(self._mm, _OWNERS_AT + r * _OWNER.size)[0]
            if beat > 0.0 and pid and _alive(pid) and (latest is None or beat > latest):
                latest = beat
        return latest

    # -- python-can's interface -----------------------------------------------------------------
    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Put ``msg`` on the channel for every other bus (never blocks)."""
        if self._closed:
            raise can.CanOperationError(f"{self.channel_info} is shut down")
        if msg.is_fd or msg.dlc > 8:
            raise can.CanOperationError(f"{self.channel_info} carries classic CAN frames only (at most 8 bytes)")
        can_id = msg.arbitration_id & _ID_MASK
        if msg.is_extended_id:
            can_id |= _EFF
        if msg.is_remote_frame:
            can_id |= _RTR
        if msg.is_error_frame:
            can_id |= _ERR
        self._write(_REST.pack(time.time(), can_id, msg.dlc, bytes(msg.data)))

    def send_frames(self, frames: Sequence[tuple[int, bool, bytes]]) -> None:
        """:meth:`send` for data frames given by their fields (``(arbitration_id, is_extended_id,
        data)``; at most 8 bytes each, valid IDs), in order, stamped alike and published under one
        hold of the ring: the control loop's commands, one call a cycle for the bus, without a
        :class:`can.Message` each. Checked first: a frame of more than 8 bytes refuses them all."""
        if self._closed:
            raise can.CanOperationError(f"{self.channel_info} is shut down")
        stamp = time.time()
        pack = _REST.pack
        rests = []
        for arbitration_id, is_extended_id, data in frames:
            n = len(data)
            if n > 8:
                raise can.CanOperationError(f"{self.channel_info} carries classic CAN frames only (at most 8 bytes)")
            rests.append(pack(stamp, arbitration_id & _ID_MASK | _EFF if is_extended_id else arbitration_id & _ID_MASK,
                              n, data))
        self._write(*rests)

    def _write(self, *rests: bytes) -> None:
        """Publish slot bodies (stamp, ID with flags, DLC, data) as this ring's next frames, in order."""
        mm = self._mm
        with self._send_lock:
            seq = self._seq
            for rest in rests:
                seq += 1
                at = _slot(self._ring, seq - 1)
                mm[at + 12:at + _SLOT_SIZE - _PAD] = rest
                mm[at + 8:at + 12] = _CRC.pack(zlib.crc32(rest, zlib.crc32(_SEQ.pack(seq))))
                _SEQ.pack_into(mm, at, seq)  # last: publishes the slot
                self._seq = seq

    def _next_frame(self, ring: int) -> tuple[float, int, int, bytes] | object | None:
        """The next frame of ``ring`` as ``(stamp, can_id with flags, dlc, data)``, its position taken:
        ``None`` if there is none yet, or ``_SKIPPED`` if there was one this bus does not deliver (its
        own, or frames lost to an overrun): look again."""
        pos = self._pos[ring]
        at = _slot(ring, pos)
        mm = self._mm
        seq = _SEQ.unpack_from(mm, at)[0]
        if seq <= pos:
            return None
        if seq != pos + 1:  # the writer lapped us: skip to the oldest frame still there
            oldest = self._head(ring) - _SLOTS + 1
            if oldest <= pos + 1:  # not a lap: a slot someone scribbled on; step over it
                oldest = pos + 2
            self.overruns += oldest - pos - 1
            self._pos[ring] = oldest - 1
            return _SKIPPED
        crc, stamp, can_id, dlc, data = _BODY.unpack_from(mm, at + 8)
        if zlib.crc32(mm[at + 12:at + _SLOT_SIZE - _PAD], zlib.crc32(_SEQ.pack(seq))) != crc:
            return None  # being written right now, or the last lap's frame (a weakly ordered CPU): look again
        self._pos[ring] = seq
        if (ring == self._ring and not self.receive_own_messages) or dlc > 8:
            return _SKIPPED
        if can_id & _RTR:
            data = b""
        elif dlc < 8:
            data = data[:dlc]
        return stamp, can_id, dlc, data

    def _take(self, ring: int) -> can.Message | object | None:
        """:meth:`_next_frame` as a message."""
        frame = self._next_frame(ring)
        if not isinstance(frame, tuple):  # None or _SKIPPED
            return frame
        stamp, can_id, dlc, data = frame
        return message(can_id & _ID_MASK, data, bool(can_id & _EFF), stamp, bool(can_id & _RTR),
                       bool(can_id & _ERR), dlc, self.channel, ring != self._ring)

    def drain(self, limit: int) -> list[tuple[int, bool, bool, int, bytes]]:
        """Every frame waiting from the other buses, at most ``limit``, without waiting and without
        building a :class:`can.Message` for each: ``(arbitration_id, is_extended_id, plain, dlc,
        data)``, ``plain`` false for remote and error frames. Ring by ring (the order within a ring is
        its writer's). With filters set (``can_filters``): the frames they pass.

        The control loop reads its replies this way: one call a cycle instead of a :meth:`recv` and a
        message per frame."""
        out: list[tuple[int, bool, bool, int, bytes]] = []
        if self._closed:
            return out
        if self._filters is not None:
            return self._drain_filtered(limit)
        try:
            if _GEN.unpack_from(self._mm, _GEN_AT)[0] != self._gen:
                self._refresh()
            for ring in self._active:
                while len(out) < limit:
                    frame = self._next_frame(ring)
                    if frame is None:
                        break
                    if not isinstance(frame, tuple):  # _SKIPPED
                        continue
                    _stamp, can_id, dlc, data = frame
                    out.append((can_id & _ID_MASK, bool(can_id & _EFF), not can_id & (_RTR | _ERR), dlc, data))
        except ValueError:  # shut down by another thread meanwhile
            pass
        return out

    def _drain_filtered(self, limit: int) -> list[tuple[int, bool, bool, int, bytes]]:
        """:meth:`drain` through the filters (``recv(0)`` would stop at the first frame they hold back)."""
        out: list[tuple[int, bool, bool, int, bytes]] = []
        while len(out) < limit and (msg := self._recv_internal(0.0)[0]) is not None:
            if self._matches_filters(msg):
                out.append((msg.arbitration_id, msg.is_extended_id, not (msg.is_remote_frame or msg.is_error_frame),
                            msg.dlc, bytes(msg.data)))
        return out

    def _poll(self) -> can.Message | None:
        """One pass over the rings in use, starting after the one that gave the last frame (fairness)."""
        if _GEN.unpack_from(self._mm, _GEN_AT)[0] != self._gen:
            self._refresh()
        active = self._active
        n = len(active)
        for k in range(n):
            i = (self._next + k) % n
            msg = self._take(active[i])
            while msg is _SKIPPED:
                msg = self._take(active[i])
            if msg is not None:
                self._next = i + 1
                return msg  # type: ignore[return-value]
        return None

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next frame from the other buses on the channel, or ``None`` after ``timeout`` s
        (``None``: wait for ever; 0: do not wait). Without filters this skips python-can's generic
        filtering loop, which costs as much as the read itself."""
        if self._filters is None:
            if timeout == 0.0 and not self._closed:  # the loop's drain: one pass, no clock reads
                try:
                    return self._poll()
                except ValueError:  # shut down by another thread meanwhile
                    return None
            return self._recv_internal(timeout)[0]
        return super().recv(timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        nap = _POLL_MIN
        while not self._closed:
            try:
                msg = self._poll()
            except ValueError:  # shut down by another thread meanwhile
                break
            if msg is not None:
                return msg, False
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0.0:
                break
            time.sleep(nap if left is None else min(nap, left))
            nap = min(2.0 * nap, _POLL_MAX)
        return None, False

    def shutdown(self) -> None:
        """Give up this bus's ring and unmap the channel; the last bus on a channel deletes its file."""
        if not self._closed:
            self._closed = True
            with self._send_lock, _locked(self._fd):
                mm = self._mm
                at = _OWNERS_AT + self._ring * _OWNER.size
                pid, token, _used = _OWNER.unpack_from(mm, at)
                if (pid, token) == (os.getpid(), self._token):
                    _OWNER.pack_into(mm, at, 0, 0, 1)
                    self._bump()
                owners = [_OWNER.unpack_from(mm, _OWNERS_AT + r * _OWNER.size)[0] for r in range(_RINGS)]
                if not any(p and _alive(p) for p in owners):
                    with contextlib.suppress(OSError):
                        os.unlink(self._path)  # (a bus opening now notices, and makes a new file)
            with contextlib.suppress(BufferError):  # a reader in another thread still holds a view
                mm.close()
            os.close(self._fd)
        super().shutdown()

    @staticmethod
    def _detect_available_configs() -> list[AutoDetectedConfig]:
        return [{"interface": INTERFACE, "channel": "can0"}]

