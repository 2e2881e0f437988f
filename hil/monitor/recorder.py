"""MCAP recorder of bus samples: one channel per key, each carrying its topic's JSON Schema.

One channel per key (``hilnav/<vehicle>/<topic>``), message encoding ``json``, each channel
carrying its topic's JSON Schema (encoding ``jsonschema``, :data:`hil.bus.SCHEMAS`), so
Foxglove and PlotJuggler replay it as is. Beside them, the Foxglove well-known channels of
:mod:`hil.monitor.foxglove` (``foxglove.LocationFix``, ``foxglove.FrameTransform``,
``foxglove.Log``, protobuf with the official FileDescriptorSets), through the same writer.
``log_time`` is the simulated time (:func:`hil.monitor.foxglove.sim_time_ns` of the payload's
``time_us``; a sample without one takes the last simulated time, or the receive time before
any); ``publish_time`` is the wall-clock receive time.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Self

from mcap.writer import CompressionType, Writer

from hil.bus import SCHEMA_VERSION, SCHEMAS, Message, Topic
from hil.monitor.foxglove import FoxgloveConverter, FoxgloveMessage, foxglove_schema

__all__ = ["McapRecorder"]


class McapRecorder:
    """Write :class:`hil.bus.Message` s to an MCAP file (thread-safe).

    Parameters
    ----------
    path : Path
        Output file (overwritten). Its folder must exist.
    metadata : mapping of str -> str, optional
        Written as an MCAP metadata record named ``hilnav``.

    Attributes
    ----------
    messages : int
        Messages written.
    skipped : int
        Samples not written because their payload is not a JSON object.
    """

    def __init__(self, path: Path, *, metadata: Mapping[str, str] | None = None) -> None:
        path = Path(path)
        if not path.parent.is_dir():
            raise ValueError(f"record: folder {path.parent} does not exist")
        self.path = path
        self._file: IO[bytes] = path.open("wb")
        self._writer = Writer(self._file, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="hilnav")
        self._writer.add_metadata(
            "hilnav", {"schema_version": str(SCHEMA_VERSION), **dict(metadata or {})}
        )
        self._lock = threading.Lock()
        self._schemas: dict[Topic, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._fox_schemas: dict[str, int] = {}
        self._fox_channels: dict[str, int] = {}
        self._converter = FoxgloveConverter()
        self._closed = False
        self.messages = 0
        self.skipped = 0

    def _channel(self, msg: Message) -> int:
        cid = self._channels.get(msg.key)
        if cid is not None:
            return cid
        schema_id = 0  # 0 = no schema (a key outside the key space)
        if msg.topic is not None:
            schema_id = self._schemas.get(msg.topic, 0)
            if schema_id == 0:
                schema = SCHEMAS[msg.topic]
                schema_id = self._writer.register_schema(
                    name=schema["title"],
                    encoding="jsonschema",
                    data=json.dumps(schema).encode(),
                )
                self._schemas[msg.topic] = schema_id
        cid = self._writer.register_channel(
            topic=msg.key, message_encoding="json", schema_id=schema_id, metadata={}
        )
        self._channels[msg.key] = cid
        return cid

    def _fox_channel(self, topic: str, message: FoxgloveMessage) -> int:
        cid = self._fox_channels.get(topic)
        if cid is None:
            name, encoding, data = foxglove_schema(message)
            sid = self._fox_schemas.get(name)
            if sid is None:
                sid = self._writer.register_schema(name=name, encoding=encoding, data=data)
                self._fox_schemas[name] = sid
            cid = self._writer.register_channel(
                topic=topic, message_encoding=encoding, schema_id=sid, metadata={}
            )
            self._fox_channels[topic] = cid
        return cid

    def _add(self, cid: int, log_time_ns: int, data: bytes, publish_time_ns: int) -> None:
        seq = self._sequence.get(cid, 0)
        self._sequence[cid] = seq + 1
        self._writer.add_message(
            channel_id=cid, log_time=log_time_ns, data=data, publish_time=publish_time_ns,
            sequence=seq,
        )
        self.messages += 1

    def write(self, msg: Message) -> None:
        """Append one received sample (ignored after :meth:`close`)."""
        with self._lock:
            if self._closed:
                return
            if msg.payload is None:
                self.skipped += 1
                return
            fox = self._converter.messages(msg)
            t_ns = self._converter.log_time_ns(msg.payload)
            self._add(self._channel(msg), msg.received_ns if t_ns is None else t_ns, msg.raw,
                      msg.received_ns)
            for topic, message, fox_ns in fox:
                self._add(self._fox_channel(topic, message), fox_ns, message.encode(),
                          msg.received_ns)

    @property
    def topics(self) -> list[str]:
        """Keys recorded so far."""
        with self._lock:
            return sorted(self._channels) + sorted(self._fox_channels)

    def close(self) -> None:
        """Write the summary section and close the file (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()
            self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
