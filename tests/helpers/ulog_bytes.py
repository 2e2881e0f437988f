"""Craft ULog files for tests by filtering a real one at the message level (pyulog cannot
write).

ULog (PX4 docs, "ULog File Format"): a 16-byte header (``ULog`` magic, version, start time
µs), then messages of ``uint16 msg_size | uint8 msg_type | payload``. In the data section an
``A`` message (``uint8 multi_id | uint16 msg_id | name``) subscribes a topic under ``msg_id``
and each ``D`` message (``uint16 msg_id | payload``, the payload starting with the uint64
``timestamp``) carries one sample. Dropping a topic's ``A`` and ``D`` messages, or the ``D``
messages after a time, gives a valid log without them (the files used here have no appended
data, so no offsets need fixing).
"""

from __future__ import annotations

import struct
from collections.abc import Collection
from pathlib import Path

_HEADER_LEN = 16
_MSG_HEADER = struct.Struct("<HB")


def filter_ulog(src: Path, dst: Path, *, drop_topics: Collection[str] = (),
                until_s: float | None = None) -> Path:
    """Copy ``src`` to ``dst`` without the topics ``drop_topics`` and, with ``until_s``,
    without the data samples stamped later than ``until_s`` after the log start."""
    data = src.read_bytes()
    (start_us,) = struct.unpack_from("<Q", data, 8)
    out = bytearray(data[:_HEADER_LEN])
    dropped_ids: set[int] = set()
    pos = _HEADER_LEN
    while pos + _MSG_HEADER.size <= len(data):
        size, kind = _MSG_HEADER.unpack_from(data, pos)
        end = pos + _MSG_HEADER.size + size
        if end > len(data):
            break
        payload = data[pos + _MSG_HEADER.size:end]
        keep = True
        if kind == ord("A"):
            msg_id = struct.unpack_from("<H", payload, 1)[0]
            name = payload[3:].decode("ascii", "replace")
            if name in drop_topics:
                dropped_ids.add(msg_id)
                keep = False
        elif kind == ord("D"):
            msg_id = struct.unpack_from("<H", payload, 0)[0]
            if msg_id in dropped_ids:
                keep = False
            elif until_s is not None:
                (stamp_us,) = struct.unpack_from("<Q", payload, 2)
                keep = stamp_us <= start_us + until_s * 1e6
        if keep:
            out += data[pos:end]
        pos = end
    dst.write_bytes(bytes(out))
    return dst
