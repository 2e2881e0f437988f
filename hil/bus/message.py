"""A sample received on the bus, with its key split and its JSON payload decoded."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Any

from hil.bus.keys import Topic, parse_key

__all__ = ["Message", "message_from_sample"]


@dataclass(frozen=True, slots=True)
class Message:
    """A sample received on the bus.

    Attributes
    ----------
    key : full key expression, ``hilnav/<vehicle>/<topic>``.
    vehicle : the ``<vehicle>`` chunk.
    topic : the :class:`Topic`, or None for a key outside the key space.
    payload : the decoded JSON object, or None if it is not a JSON object.
    raw : the payload bytes as received.
    received_ns : wall-clock receive time (``time.time_ns()``).
    """

    key: str
    vehicle: str
    topic: Topic | None
    payload: dict[str, Any] | None
    raw: bytes
    received_ns: int


def message_from_sample(key_expr: str, raw: bytes) -> Message:
    """The :class:`Message` of one received sample (key expression and payload bytes)."""
    try:
        vehicle, topic = parse_key(key_expr)
    except ValueError:
        vehicle, topic = "", None
    try:
        decoded = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        decoded = None
    return Message(
        key=key_expr,
        vehicle=vehicle,
        topic=topic,
        payload=decoded if isinstance(decoded, dict) else None,
        raw=raw,
        received_ns=time.time_ns(),
    )
