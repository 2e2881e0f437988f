"""Live Foxglove WebSocket server: the monitor's bus samples streamed to Foxglove as they arrive.

``foxglove-sdk``'s server (protocol ``foxglove.websocket.v1``) on ``127.0.0.1:<port>`` carries
the same channels as the MCAP recording (:mod:`hil.monitor.recorder`): one ``json`` channel per
bus key with its topic's JSON Schema, and the Foxglove well-known channels of
:mod:`hil.monitor.foxglove`, every message stamped with its simulated time.
"""

from __future__ import annotations

import json
import threading
from typing import Final

import foxglove
from foxglove import Channel, Context, Schema

from hil.bus import SCHEMAS, Message
from hil.monitor.foxglove import FoxgloveConverter, FoxgloveMessage, foxglove_schema

__all__ = ["DEFAULT_FOXGLOVE_PORT", "FoxgloveLive"]

DEFAULT_FOXGLOVE_PORT: Final = 8765


class FoxgloveLive:
    """A Foxglove WebSocket server fed with bus samples (thread-safe).

    Parameters
    ----------
    port : int
        TCP port (0: any free port; :attr:`port` says which).
    host : str
        Bind address (loopback by default: the server has no authentication).
    """

    def __init__(self, port: int = DEFAULT_FOXGLOVE_PORT, *, host: str = "127.0.0.1") -> None:
        if not 0 <= port <= 65535:
            raise ValueError(f"foxglove port must be 0..65535, got {port}")
        self._context = Context()
        self._server = foxglove.start_server(
            name="hilnav", host=host, port=port, context=self._context
        )
        self.host = host
        self._lock = threading.Lock()
        self._channels: dict[str, Channel] = {}
        self._converter = FoxgloveConverter()
        self._closed = False
        self.messages = 0

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self._server.port)

    @property
    def url(self) -> str:
        """What to type into Foxglove's "Open connection" dialog."""
        return f"ws://{self.host}:{self.port}"

    def _channel(self, topic: str, schema: Schema, encoding: str) -> Channel:
        ch = self._channels.get(topic)
        if ch is None:
            ch = Channel(topic, message_encoding=encoding, schema=schema, context=self._context)
            self._channels[topic] = ch
        return ch

    def _fox(self, topic: str, message: FoxgloveMessage) -> Channel:
        name, encoding, data = foxglove_schema(message)
        return self._channel(topic, Schema(name=name, encoding=encoding, data=data), encoding)

    def write(self, msg: Message) -> None:
        """Stream one received sample (ignored after :meth:`close` or without a JSON payload)."""
        with self._lock:
            if self._closed or msg.payload is None:
                return
            fox = self._converter.messages(msg)
            t_ns = self._converter.log_time_ns(msg.payload)
            if msg.topic is not None:
                schema = SCHEMAS[msg.topic]
                ch = self._channel(
                    msg.key,
                    Schema(name=schema["title"], encoding="jsonschema",
                           data=json.dumps(schema).encode()),
                    "json",
                )
                ch.log(msg.raw, log_time=msg.received_ns if t_ns is None else t_ns)
                self.messages += 1
            for topic, message, fox_ns in fox:
                self._fox(topic, message).log(message.encode(), log_time=fox_ns)
                self.messages += 1

    def close(self) -> None:
        """Stop the server (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._server.stop()
