"""Counters a :class:`hil.bus.Bus` reports (:meth:`hil.bus.Bus.stats`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Final

__all__ = ["BusStats"]


@dataclass(frozen=True, slots=True)
class BusStats:
    """Counters of a :class:`Bus` since it was opened.

    Attributes
    ----------
    connected : the session is open and sees a router (client) or a peer/router (peer).
    queued : messages waiting for the publisher thread now.
    enqueued : messages accepted by :meth:`Bus.publish` (after decimation).
    decimated : messages skipped by the per-topic rate limit (not an error).
    published : messages handed to Zenoh.
    dropped_queue_full : oldest messages dropped because the queue was full.
    unrouted : messages handed to Zenoh while no router was connected (Zenoh drops them;
        the state is sampled every 0.25 s, so this is approximate around a disconnection).
    put_errors : Zenoh put failures.
    received : samples delivered to subscription callbacks.
    callback_errors : exceptions raised by subscription callbacks (swallowed, counted).
    unauthenticated : samples (and config replies) dropped for a missing or wrong HMAC tag
        (only with a shared key: forged or foreign publishers).
    replayed : correctly tagged samples dropped because their counter was already seen.
    connect_attempts : failed session-open attempts.
    reconnects : times the router was seen back after being seen lost.
    dropped_by_topic : ``dropped_queue_full`` split by topic suffix.
    """

    connected: bool = False
    queued: int = 0
    enqueued: int = 0
    decimated: int = 0
    published: int = 0
    dropped_queue_full: int = 0
    unrouted: int = 0
    put_errors: int = 0
    received: int = 0
    callback_errors: int = 0
    unauthenticated: int = 0
    replayed: int = 0
    connect_attempts: int = 0
    reconnects: int = 0
    dropped_by_topic: dict[str, int] = dataclasses.field(default_factory=dict)


COUNTER_NAMES: Final = (
    "enqueued", "decimated", "published", "dropped_queue_full", "unrouted", "put_errors",
    "received", "callback_errors", "unauthenticated", "replayed", "connect_attempts",
    "reconnects",
)  # fmt: skip
"""The integer counters of :class:`BusStats`, in field order."""
