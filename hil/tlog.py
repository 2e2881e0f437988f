"""The ``.tlog`` MAVLink log: what QGroundControl, MAVProxy and Mission Planner record and replay.

Format
    A flat sequence of records, no file header::

        uint64 big-endian timestamp, microseconds | one raw MAVLink frame (v1 or v2)

    The frame's length is not stored: it follows from the MAVLink header (``0xFE``: MAVLink 1,
    6-byte header; ``0xFD``: MAVLink 2, 10-byte header, plus a 13-byte signature when
    ``incompat_flags & 0x01``), then the payload and a 2-byte CRC. Ground stations write Unix
    wall-clock time; hilnav writes simulated time in lockstep runs and wall-clock time live.

Reading is robust: a truncated last record (a crash while writing) ends the iteration cleanly
and is counted; a record that does not start with a frame marker is skipped by scanning forward
to the next position where a timestamp is followed by a frame of a known message id with a
valid CRC (counted in ``skipped_bytes``). Frames are not CRC-checked on the normal path: that
is :class:`hil.codec.Decoder`'s job.
"""

from __future__ import annotations

import mmap
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Final

from hil.codec import Decoded, Decoder, mavlink2

__all__ = [
    "TlogReader",
    "TlogStats",
    "TlogWriter",
    "frame_length",
    "iter_decoded",
    "iter_messages",
    "read_tlog",
]

_TIMESTAMP: Final = struct.Struct(">Q")
TIMESTAMP_LEN: Final = _TIMESTAMP.size  # 8
_MARKER_V1: Final = 0xFE
_MARKER_V2: Final = 0xFD
_HEADER_LEN_V1: Final = 6
_HEADER_LEN_V2: Final = 10
_CRC_LEN: Final = 2
_SIGNATURE_LEN: Final = 13
_IFLAG_SIGNED: Final = 0x01
_UINT64_MAX: Final = 0xFFFF_FFFF_FFFF_FFFF


def frame_length(buf: bytes | bytearray | memoryview | mmap.mmap, pos: int = 0) -> int | None:
    """Total length of the MAVLink frame starting at ``buf[pos]``, from its header.

    Parameters
    ----------
    buf : bytes-like
        Buffer holding at least the frame's first 3 bytes.
    pos : int
        Offset of the start-of-frame marker.

    Returns
    -------
    int or None
        Header + payload + CRC (+ signature) length in bytes; None when ``buf[pos]`` is not a
        frame marker or fewer than 3 bytes are available.
    """
    if len(buf) - pos < 3:
        return None
    marker = buf[pos]
    payload_len = buf[pos + 1]
    if marker == _MARKER_V2:
        signed = buf[pos + 2] & _IFLAG_SIGNED
        return _HEADER_LEN_V2 + payload_len + _CRC_LEN + (_SIGNATURE_LEN if signed else 0)
    if marker == _MARKER_V1:
        return _HEADER_LEN_V1 + payload_len + _CRC_LEN
    return None


def _crc_ok(frame: bytes) -> bool:
    """True when ``frame`` is a known message whose CRC checks (used only to resynchronise)."""
    if frame[0] == _MARKER_V2:
        header_len = _HEADER_LEN_V2
        msg_id = frame[7] | frame[8] << 8 | frame[9] << 16
        sig_len = _SIGNATURE_LEN if frame[2] & _IFLAG_SIGNED else 0
    else:
        header_len = _HEADER_LEN_V1
        msg_id = frame[5]
        sig_len = 0
    msg_type = mavlink2.mavlink_map.get(msg_id)
    crc_end = len(frame) - sig_len - _CRC_LEN
    if msg_type is None or crc_end < header_len:
        return False
    crc = mavlink2.x25crc(frame[1:crc_end])
    crc.accumulate(bytes([msg_type.crc_extra]))
    wire_crc: int = struct.unpack_from("<H", frame, crc_end)[0]
    return bool(crc.crc == wire_crc)


class TlogWriter:
    """Append-only ``.tlog`` writer; a context manager.

    Parameters
    ----------
    path : str or Path
        File to create (truncated if it exists, unless ``append``).
    append : bool
        Append to an existing log instead of truncating it.

    Attributes
    ----------
    records : int
        Records written through this writer.
    """

    def __init__(self, path: str | os.PathLike[str], *, append: bool = False) -> None:
        self.path = Path(path)
        self._file: BinaryIO | None = open(self.path, "ab" if append else "wb")
        self.records = 0

    def write(self, frame: bytes, time_us: int) -> None:
        """Write one record.

        Parameters
        ----------
        frame : bytes
            Exactly one complete MAVLink frame (as returned by ``hil.codec.Encoder``).
        time_us : int
            Record timestamp, µs, in [0, 2**64).

        Raises
        ------
        ValueError
            ``frame`` is not exactly one frame, or ``time_us`` is out of range.
        """
        if self._file is None:
            raise ValueError(f"write to a closed TlogWriter ({self.path})")
        expected = frame_length(frame)
        if expected is None:
            raise ValueError(
                "frame must start with a MAVLink marker (0xFD or 0xFE) and hold a header, got "
                f"{bytes(frame[:3]).hex() or 'nothing'}"
            )
        if expected != len(frame):
            raise ValueError(
                f"frame must be exactly one MAVLink frame: header says {expected} bytes, got "
                f"{len(frame)}"
            )
        t = int(time_us)
        if t != time_us or not 0 <= t <= _UINT64_MAX:
            raise ValueError(f"time_us must be an integer in [0, 2**64), got {time_us!r}")
        self._file.write(_TIMESTAMP.pack(t))
        self._file.write(frame)
        self.records += 1

    def flush(self) -> None:
        """Push buffered records to the operating system."""
        if self._file is not None:
            self._file.flush()

    def close(self) -> None:
        """Flush and close; further writes raise."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


@dataclass(slots=True)
class TlogStats:
    """What a :class:`TlogReader` met.

    Attributes
    ----------
    records : complete records yielded.
    truncated_records : incomplete record at the end of the file (0 or 1).
    skipped_bytes : bytes skipped to resynchronise after a record without a frame marker.
    """

    records: int = 0
    truncated_records: int = 0
    skipped_bytes: int = 0


class TlogReader:
    """Iterate ``(timestamp_us, frame)`` over a ``.tlog`` file; a context manager.

    The file is memory-mapped, so logs larger than memory are fine. Iterate once.

    Parameters
    ----------
    path : str or Path

    Attributes
    ----------
    stats : TlogStats
        Filled in while iterating.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.stats = TlogStats()
        self._file: BinaryIO | None = open(self.path, "rb")
        size = os.fstat(self._file.fileno()).st_size
        # mmap refuses empty files.
        self._buf: mmap.mmap | bytes = (
            mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
        )

    def __iter__(self) -> Iterator[tuple[int, bytes]]:
        buf = self._buf
        n = len(buf)
        pos = 0
        while pos < n:
            frame_start = pos + TIMESTAMP_LEN
            length = frame_length(buf, frame_start)
            if length is None:
                if frame_start >= n or buf[frame_start] in (_MARKER_V1, _MARKER_V2):
                    # A timestamp and the start of a frame, cut short: the writer stopped.
                    self.stats.truncated_records += 1
                    return
                nxt = self._resync(pos + 1)
                if nxt is None:
                    self.stats.skipped_bytes += n - pos
                    return
                self.stats.skipped_bytes += nxt - pos
                pos = nxt
                continue
            end = frame_start + length
            if end > n:
                self.stats.truncated_records += 1
                return
            (timestamp_us,) = _TIMESTAMP.unpack(buf[pos:frame_start])
            self.stats.records += 1
            yield timestamp_us, bytes(buf[frame_start:end])
            pos = end

    def _resync(self, start: int) -> int | None:
        """First offset >= start where a timestamp is followed by a CRC-valid known frame."""
        buf = self._buf
        n = len(buf)
        for pos in range(start, n - TIMESTAMP_LEN):
            frame_start = pos + TIMESTAMP_LEN
            if buf[frame_start] not in (_MARKER_V1, _MARKER_V2):
                continue
            length = frame_length(buf, frame_start)
            if length is None or frame_start + length > n:
                continue
            if _crc_ok(bytes(buf[frame_start : frame_start + length])):
                return pos
        return None

    def close(self) -> None:
        """Release the file."""
        if isinstance(self._buf, mmap.mmap):
            self._buf.close()
        self._buf = b""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> TlogReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def read_tlog(path: str | os.PathLike[str]) -> Iterator[tuple[int, bytes]]:
    """Yield ``(timestamp_us, raw_frame)`` for every complete record of a ``.tlog``.

    Parameters
    ----------
    path : str or Path

    Yields
    ------
    tuple of (int, bytes)
        Record timestamp in µs and one raw MAVLink frame.
    """
    with TlogReader(path) as reader:
        yield from reader


def iter_messages(
    path: str | os.PathLike[str], decoder: Decoder | None = None
) -> Iterator[tuple[int, Any]]:
    """Yield ``(timestamp_us, pymavlink message)`` for every valid frame of a ``.tlog``.

    Frames with a bad CRC or an unknown id are counted in ``decoder.counters`` and skipped.

    Parameters
    ----------
    path : str or Path
    decoder : Decoder, optional
        Parser to use (and whose counters to update); a fresh one by default.

    Yields
    ------
    tuple of (int, pymavlink MAVLink_message)
    """
    dec = Decoder() if decoder is None else decoder
    for timestamp_us, frame in read_tlog(path):
        for msg in dec.parse(frame):
            yield timestamp_us, msg


def iter_decoded(
    path: str | os.PathLike[str], decoder: Decoder | None = None
) -> Iterator[tuple[int, Decoded]]:
    """Yield ``(timestamp_us, Decoded)`` for every SI sample in a ``.tlog``.

    Parameters
    ----------
    path : str or Path
    decoder : Decoder, optional
        Decoder to use (e.g. with ``imu_dt_s`` or a ``RawImuScale``); a fresh one by default.

    Yields
    ------
    tuple of (int, Decoded)
        Record timestamp in µs and one decoded sample (its own ``time_us`` is the message's).
    """
    dec = Decoder() if decoder is None else decoder
    for timestamp_us, frame in read_tlog(path):
        for item in dec.feed(frame):
            yield timestamp_us, item
