"""MAVLink byte-stream framing with CRC checks and resynchronisation (no I/O).

One parser for every path: the live links (:mod:`hil.link`) and the decoder behind replay
(:class:`hil.codec.Decoder`), so damage anywhere costs only the damaged frame.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from enum import Enum
from typing import Final, Protocol

from hil.codec.wire import (
    CRC_LEN,
    HEADER_LEN,
    IFLAG_SIGNED,
    MAGIC_V2,
    SIGNATURE_BLOCK_LEN,
    crc_extra,
    mavlink2,
    mcrf4xx,
)

__all__ = ["MAGIC_V1", "FrameParser", "FramingCounters"]

MAGIC_V1: Final = 0xFE
_HEADER_LEN_V1: Final = 6
_MAGIC_RE: Final = re.compile(b"[\xfd\xfe]")
_EXTRA_BYTE: Final = tuple(bytes((x,)) for x in range(256))
_FRAME_OVERHEAD: Final = HEADER_LEN + CRC_LEN
# CRC_EXTRA as the byte the CRC takes, by message id (the ids of the dialect's messages)
_EXTRA_BYTE_OF_ID: Final = {
    i: _EXTRA_BYTE[x] for i in mavlink2.mavlink_map if (x := crc_extra(i)) is not None
}


class _Scan(Enum):
    FRAME = 1  # a CRC-valid frame of a known id
    SKIP = 2  # a frame to step over whole (MAVLink 1, unknown id); already counted
    NOT_A_FRAME = 3  # the marker byte is garbage: resume one byte later
    WAIT = 4  # need more bytes to decide


class FramingCounters(Protocol):
    """What :class:`FrameParser` counts (``hil.link.LinkCounters``,
    ``hil.codec.DecoderCounters``)."""

    garbage_bytes: int
    bad_crc: int
    unknown_msg_id: int
    truncated: int


class FrameParser:
    """Split a MAVLink byte stream into CRC-checked frames of known message ids.

    Stateful for streams (keeps an incomplete trailing frame, at most one frame long, for the
    next :meth:`feed`); a corrupted or cut frame costs only its own bytes: the parser resumes
    at the next start-of-frame marker. Counts ``garbage_bytes``, ``bad_crc``,
    ``unknown_msg_id`` and ``truncated``.

    Parameters
    ----------
    counters : FramingCounters
    on_mavlink1 : callable, optional
        Called for each CRC-valid MAVLink 1 frame, which is then dropped (the live links
        speak MAVLink 2 only). Without it MAVLink 1 frames are returned like MAVLink 2 ones
        (a log from a mixed link).
    """

    def __init__(
        self, counters: FramingCounters, on_mavlink1: Callable[[], None] | None = None
    ) -> None:
        self._c = counters
        self._on_mavlink1 = on_mavlink1
        self._buf = bytearray()

    def feed(self, data: bytes, *, final: bool = False) -> list[bytes]:
        """Parse more bytes.

        Parameters
        ----------
        data : bytes
            The next bytes of the stream (or one whole UDP datagram with ``final``).
        final : bool
            No more bytes follow (end of a datagram): an incomplete frame is counted as
            truncated and the buffer is emptied.

        Returns
        -------
        list of bytes
            Whole frames (header to signature) in stream order.
        """
        buf = self._buf
        if not buf and type(data) is bytes and self._whole_frame(data):
            return [data]  # the common case (one unsigned frame per call), without the scan
        buf += data
        out: list[bytes] = []
        n = len(buf)
        i = 0
        while i < n:
            found = _MAGIC_RE.search(buf, i)
            j = n if found is None else found.start()
            self._c.garbage_bytes += j - i
            i = j
            if i == n:
                break
            status, size = (
                self._v2(buf, i, n, final) if buf[i] == MAGIC_V2 else self._v1(buf, i, n, final)
            )
            if status is _Scan.WAIT:
                break
            if status is _Scan.NOT_A_FRAME:
                self._c.garbage_bytes += 1
                i += 1
                continue
            if status is _Scan.FRAME:
                out.append(bytes(buf[i : i + size]))
            i += size
        del buf[:i]
        return out

    @staticmethod
    def _whole_frame(data: bytes) -> bool:
        """``data`` is exactly one CRC-valid, unsigned MAVLink 2 frame of a known id, which
        the scan of :meth:`feed` would return as it is, counting nothing."""
        n = len(data)
        if n < _FRAME_OVERHEAD or data[0] != MAGIC_V2 or data[2] or n != data[1] + _FRAME_OVERHEAD:
            return False
        extra = _EXTRA_BYTE_OF_ID.get(data[7] | (data[8] << 8) | (data[9] << 16))
        return extra is not None and (  # one CRC call over the joined bytes: cheaper than two
            data[-2] | (data[-1] << 8)) == mcrf4xx(data[1:-2] + extra)

    def reset(self) -> None:
        """Forget a partial frame (the stream restarted); its bytes count as garbage."""
        self._c.garbage_bytes += len(self._buf)
        self._buf.clear()

    def _incomplete(self, final: bool) -> tuple[_Scan, int]:
        if not final:
            return _Scan.WAIT, 0
        self._c.truncated += 1
        return _Scan.NOT_A_FRAME, 0

    def _v2(self, buf: bytearray, i: int, n: int, final: bool) -> tuple[_Scan, int]:
        avail = n - i
        if avail >= 3 and buf[i + 2] & ~IFLAG_SIGNED:
            return _Scan.NOT_A_FRAME, 0  # unknown incompatibility flag: not a frame start
        if avail < HEADER_LEN:
            return self._incomplete(final)
        payload_len = buf[i + 1]
        size = HEADER_LEN + payload_len + CRC_LEN
        if buf[i + 2] & IFLAG_SIGNED:
            size += SIGNATURE_BLOCK_LEN
        extra = crc_extra(buf[i + 7] | (buf[i + 8] << 8) | (buf[i + 9] << 16))
        if extra is None:
            # No CRC check possible: believe the header only if a frame (or the end of the
            # datagram) follows exactly where it says the frame ends.
            if avail > size:
                if buf[i + size] in (MAGIC_V2, MAGIC_V1):
                    self._c.unknown_msg_id += 1
                    return _Scan.SKIP, size
                return _Scan.NOT_A_FRAME, 0
            if avail == size and final:
                self._c.unknown_msg_id += 1
                return _Scan.SKIP, size
            return (_Scan.NOT_A_FRAME, 0) if final else (_Scan.WAIT, 0)
        if avail < size:
            return self._incomplete(final)
        crc_at = i + HEADER_LEN + payload_len
        got = buf[crc_at] | (buf[crc_at + 1] << 8)
        if got != mcrf4xx(_EXTRA_BYTE[extra], mcrf4xx(buf[i + 1 : crc_at])):
            self._c.bad_crc += 1
            return _Scan.NOT_A_FRAME, 0
        return _Scan.FRAME, size

    def _v1(self, buf: bytearray, i: int, n: int, final: bool) -> tuple[_Scan, int]:
        # Bytes 0xFE are common in payloads, so a failing candidate is plain garbage.
        avail = n - i
        if avail < _HEADER_LEN_V1:
            return (_Scan.NOT_A_FRAME, 0) if final else (_Scan.WAIT, 0)
        msg_type = mavlink2.mavlink_map.get(buf[i + 5])
        if msg_type is None:
            return _Scan.NOT_A_FRAME, 0
        payload_len = buf[i + 1]
        if payload_len > msg_type.unpacker.size:  # longer than the whole message: not a frame
            return _Scan.NOT_A_FRAME, 0
        size = _HEADER_LEN_V1 + payload_len + CRC_LEN
        if avail < size:
            return (_Scan.NOT_A_FRAME, 0) if final else (_Scan.WAIT, 0)
        crc_at = i + _HEADER_LEN_V1 + payload_len
        crc = mavlink2.x25crc(bytes(buf[i + 1 : crc_at]))
        crc.accumulate(bytes((msg_type.crc_extra,)))
        if buf[crc_at] | (buf[crc_at + 1] << 8) != crc.crc:
            return _Scan.NOT_A_FRAME, 0
        if self._on_mavlink1 is None:
            return _Scan.FRAME, size
        self._on_mavlink1()
        return _Scan.SKIP, size
