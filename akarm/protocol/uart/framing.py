"""UART framing: CRC-16/XMODEM, short and long frames, and a resynchronising stream decoder."""

from __future__ import annotations

import binascii
from collections import deque
from collections.abc import Callable, Iterable

from akarm.errors import FrameError, ProtocolError
from akarm.protocol.uart.packets import DEFAULT_MAX_PAYLOAD, LONG_MAX, SHORT_MAX

# ---- framing -------------------------------------------------------------------------------


def as_bytes(data: object, error: type[ProtocolError] = FrameError) -> bytes:
    """``data`` as bytes when it is bytes-like or an iterable of 0-255 ints, else ``error``."""
    if isinstance(data, bytes):
        return data
    if not isinstance(data, str | int) and data is not None:
        try:
            return bytes(data)  # type: ignore[call-overload]
        except (TypeError, ValueError):
            pass
    raise error(f"expected bytes, got {type(data).__name__}")


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/XMODEM (poly 0x1021, init 0, no reflection, no final XOR) of ``data``."""
    return binascii.crc_hqx(data, 0)


def encode_frame(payload: bytes | bytearray) -> bytes:
    """Wrap ``payload`` (1-65 535 bytes, command byte first) in a frame: start, length, payload, CRC, 03.

    Payloads up to 255 bytes get a short frame (``02 LEN``), longer ones a long frame (``03 LEN_HI LEN_LO``).

    Raises:
        ProtocolError: an empty payload or one longer than 65 535 bytes.
    """
    payload = as_bytes(payload, ProtocolError)
    n = len(payload)
    crc = binascii.crc_hqx(payload, 0)
    if 0 < n <= SHORT_MAX:
        return b"".join((bytes((2, n)), payload, bytes((crc >> 8, crc & 0xFF, 3))))
    if SHORT_MAX < n <= LONG_MAX:
        return b"".join((bytes((3, n >> 8, n & 0xFF)), payload, bytes((crc >> 8, crc & 0xFF, 3))))
    raise ProtocolError(f"a UART payload has 1 to {LONG_MAX} bytes, this one {n}",
                        fix="every payload starts with a command byte")


def decode_frame(frame: bytes | bytearray) -> bytes:
    """The payload of exactly one complete frame, checked strictly.

    Raises:
        FrameError: a bad start byte, a length byte that disagrees with the frame's size (e.g. the
            manual's GET_VALUES example, which says 73 payload bytes and carries 72), a bad end byte,
            or a CRC mismatch (e.g. the manual's SET_POS 180° example, printed with CRC 1EE7).
    """
    frame = as_bytes(frame)
    n = len(frame)
    if n < 6:
        raise FrameError(f"a UART frame has at least 6 bytes, this one {n}", data=frame)
    start = frame[0]
    if start == 2:
        hdr, length = 2, frame[1]
        if length == 0:
            raise FrameError("short frame with LEN 0: a payload needs at least a command byte", data=frame)
    elif start == 3:
        hdr, length = 3, (frame[1] << 8) | frame[2]
        if length == 0:
            raise FrameError("long frame with length 0: a payload needs at least a command byte", data=frame)
    else:
        raise FrameError(f"a UART frame starts with 02 or 03, this one with {start:02X}", data=frame)
    carried = n - hdr - 3
    if carried != length:
        raise FrameError(f"the frame's length field says {length} payload bytes but it carries {carried} "
                         f"(a frame of {n} bytes, {hdr + length + 3} expected): bytes lost or added",
                         data=frame)
    if frame[-1] != 3:
        raise FrameError(f"a UART frame ends with 03, this one with {frame[-1]:02X}", data=frame)
    payload = frame[hdr:hdr + length]
    got = (frame[-3] << 8) | frame[-2]
    want = binascii.crc_hqx(payload, 0)
    if got != want:
        raise FrameError(f"CRC mismatch: the frame says {got:04X}, the payload's CRC-16/XMODEM is {want:04X}",
                         data=frame)
    return payload


class FrameDecoder:
    """Finds frames in a serial byte stream, whatever is around them.

    ``feed(data)`` appends bytes and returns the payloads of the frames completed so far, in order.
    Bytes that cannot start a frame are skipped (counted in :attr:`discarded`). A candidate frame
    that turns out bad (a length of 0 or above ``max_payload``, a wrong end byte, a CRC mismatch) is
    reported as a :class:`~akarm.FrameError`, appended to :attr:`errors` and passed to ``on_error``,
    never raised; then only its start byte is dropped and scanning resumes at the next byte, so a
    valid frame that begins inside the bad one, or right after garbage, is still found.

    A candidate whose length runs past the bytes received so far is kept until more bytes come:
    :meth:`flush` (at the end of a stream) gives up on it and rescans what is left. ``max_payload``
    bounds that wait, so a garbage length field cannot stall the decoder for long.

    The end byte 03 is also a long frame's start byte, so a frame that lost only its end byte looks
    complete when a long frame follows, and would swallow that frame's start. After every good
    frame, its end byte is therefore also tried, silently, as the start of a long frame of 256-511
    bytes (what normally follows, ``02 LEN`` or ``03 LEN_HI``, reads as 512 or more and is dropped at
    once, so this never delays normal traffic). A long frame of 512 bytes or more that follows a frame
    missing its end byte is still lost.

    Attributes:
        errors: the most recent reports (up to ``max_errors``), oldest first.
        error_count: how many bad frames were reported in all.
        crc_errors: how many of them were whole (length and end byte right) but failed the CRC.
        discarded: how many bytes were skipped outside any candidate frame.
        frames: how many payloads were returned in all.
    """

    def __init__(self, *, max_payload: int = DEFAULT_MAX_PAYLOAD,
                 on_error: Callable[[FrameError], object] | None = None, max_errors: int = 100) -> None:
        if not 1 <= max_payload <= LONG_MAX:
            raise ProtocolError(f"max_payload must be 1..{LONG_MAX}, got {max_payload}")
        self.max_payload = max_payload
        self.on_error = on_error
        self.errors: deque[FrameError] = deque(maxlen=max_errors)
        self.error_count = 0
        self.crc_errors = 0
        self.discarded = 0
        self.frames = 0
        self._buf = bytearray()
        self._spec = False  # the buffer starts with the end byte of a good frame (see _scan)

    def __repr__(self) -> str:
        return (f"FrameDecoder(buffered={len(self._buf)}, frames={self.frames}, errors={self.error_count}, "
                f"discarded={self.discarded})")

    @property
    def buffered(self) -> int:
        """Bytes held back waiting for the rest of a frame (not counting a decoded frame's end byte)."""
        return len(self._buf) - self._spec

    def feed(self, data: bytes | bytearray | memoryview | Iterable[int]) -> list[bytes]:
        """Add received bytes; return the payloads of every frame completed so far (possibly none)."""
        self._buf += data if isinstance(data, bytes | bytearray | memoryview) else as_bytes(data)
        return self._scan(final=False)

    def flush(self) -> list[bytes]:
        """End of stream: treat any incomplete candidate as truncated, rescan the rest, empty the buffer."""
        return self._scan(final=True)

    def reset(self) -> None:
        """Drop buffered bytes (the counters and error log stay)."""
        self._buf.clear()
        self._spec = False

    def _report(self, what: str, data: bytes | bytearray) -> None:
        err = FrameError(what, data=bytes(data))
        self.errors.append(err)
        self.error_count += 1
        if self.on_error is not None:
            self.on_error(err)

    # C901 19 > 12, left as it was: a byte-level frame scanner kept in one loop for speed
    def _scan(self, *, final: bool) -> list[bytes]:  # noqa: C901
        buf = self._buf
        n = len(buf)
        out: list[bytes] = []
        i = 0
        maxp = self.max_payload
        # The end byte 03 is also a long frame's start byte. After a good frame its end byte is tried
        # (silently) as the start of a long frame, in case that frame had lost its own end byte and the
        # 03 belongs to the next one. Only lengths 256-511 are tried, so the frames that normally follow
        # (02 LEN ... or 03 LEN_HI ..., i.e. lengths of 512 and more) never make the decoder wait.
        spec = 0 if self._spec else -1
        while i < n:
            start = buf[i]
            if i == spec:
                if i + 1 < n and buf[i + 1] != 1:
                    i += 1
                    continue
                if i + 3 > n:
                    if final:
                        i += 1
                        continue
                    break
                length = 256 | buf[i + 2]
                end = i + 3 + length + 3
                if length > maxp:
                    i += 1
                    continue
                if end > n:
                    if final:
                        i += 1
                        continue
                    break
                payload = bytes(buf[i + 3:end - 3])
                if buf[end - 1] == 3 and binascii.crc_hqx(payload, 0) == (buf[end - 3] << 8) | buf[end - 2]:
                    out.append(payload)
                    i = spec = end - 1
                else:
                    i += 1
                continue
            if start != 2 and start != 3:
                j2 = buf.find(2, i)
                j3 = buf.find(3, i)
                j = n if j2 < 0 and j3 < 0 else j3 if j2 < 0 else j2 if j3 < 0 else min(j2, j3)
                self.discarded += j - i
                i = j
                continue
            hdr = 2 if start == 2 else 3
            if i + hdr > n:
                if not final:
                    break
                self._report("stream ended inside a frame header (truncated frame)", buf[i:])
                i += 1
                continue
            length = buf[i + 1] if hdr == 2 else (buf[i + 1] << 8) | buf[i + 2]
            if length == 0 or length > maxp:
                self._report(f"frame length {length} is outside 1..{maxp}", buf[i:i + hdr])
                i += 1
                continue
            end = i + hdr + length + 3
            if end > n:
                if not final:
                    break
                self._report(f"truncated frame: length {length} needs {end - i} bytes, the stream ended "
                             f"after {n - i}", buf[i:])
                i += 1
                continue
            if buf[end - 1] != 3:
                self._report(f"frame of length {length} ends with {buf[end - 1]:02X}, not 03", buf[i:end])
                i += 1
                continue
            payload = bytes(buf[i + hdr:end - 3])
            got = (buf[end - 3] << 8) | buf[end - 2]
            want = binascii.crc_hqx(payload, 0)
            if got != want:
                self.crc_errors += 1
                self._report(f"CRC mismatch in a frame of length {length}: frame says {got:04X}, "
                             f"payload gives {want:04X}", buf[i:end])
                i += 1
                continue
            out.append(payload)
            i = spec = end - 1
        if final:
            i = n
        self._spec = i == spec and i < n
        del buf[:i]
        self.frames += len(out)
        return out


