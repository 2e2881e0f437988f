"""The Zenoh key space of hilnav: topics, ``hilnav/<vehicle>/<topic>`` keys and their checks.

One subtree per vehicle::

    hilnav/<vehicle>/sim/truth              true state (when the simulator knows it)
    hilnav/<vehicle>/sensors/{imu,gnss,baro,mag,airspeed}
    hilnav/<vehicle>/fusion/estimate        navigation solution
    hilnav/<vehicle>/fusion/status          mode, outage timer, health, innovation ratios, links
    hilnav/<vehicle>/fusion/innovations     one message per aiding update
    hilnav/<vehicle>/fusion/error           estimate - truth (when truth is known)
    hilnav/<vehicle>/fusion/events          what the navigation did and detected (mode, faults)
    hilnav/<vehicle>/scenario/events        scenario timeline (GNSS off/on, faults, ...)
    hilnav/<vehicle>/fusion/config          queryable: the fusion service's configuration
    hilnav/<vehicle>/fusion/alive           liveliness token of the fusion service
"""

from __future__ import annotations

import re
from enum import StrEnum
from typing import Final

__all__ = [
    "PUBLISHED_TOPICS",
    "ROOT",
    "Topic",
    "key",
    "parse_key",
    "validate_endpoint",
    "validate_vehicle",
]

ROOT: Final = "hilnav"


class Topic(StrEnum):
    """Key-space suffixes under ``hilnav/<vehicle>/``."""

    TRUTH = "sim/truth"
    IMU = "sensors/imu"
    GNSS = "sensors/gnss"
    BARO = "sensors/baro"
    MAG = "sensors/mag"
    AIRSPEED = "sensors/airspeed"
    ESTIMATE = "fusion/estimate"
    STATUS = "fusion/status"
    INNOVATIONS = "fusion/innovations"
    ERROR = "fusion/error"
    FUSION_EVENTS = "fusion/events"
    EVENTS = "scenario/events"
    CONFIG = "fusion/config"
    """Queryable, not published: answers with :func:`config_reply_payload`."""
    ALIVE = "fusion/alive"
    """Liveliness token, no payload."""


PUBLISHED_TOPICS: Final = tuple(t for t in Topic if t not in (Topic.CONFIG, Topic.ALIVE))
"""The topics that carry published samples (everything but the queryable and the token)."""

_VEHICLE_RE = re.compile(r"^[A-Za-z0-9_.-]+$")
# proto/address:port[#metadata]; zenoh checks the rest when it opens the link
_ENDPOINT_RE = re.compile(r"^(tcp|udp|tls|quic|ws|unixsock-stream)/\S+$")


def validate_vehicle(vehicle: str, *, wildcard: bool = False) -> str:
    """Return ``vehicle`` if it is usable as one key chunk, else raise ``ValueError``.

    Letters, digits, ``_``, ``.`` and ``-`` only (no ``/``, no Zenoh wildcards ``*``, ``$``, no
    ``?``/``#`` selectors); ``"*"`` (every vehicle) is allowed when ``wildcard`` is true.
    """
    if wildcard and vehicle == "*":
        return vehicle
    if not isinstance(vehicle, str) or not _VEHICLE_RE.fullmatch(vehicle):
        raise ValueError(
            f"vehicle {vehicle!r} is not a valid key chunk: use letters, digits, '_', '.', '-'"
        )
    return vehicle


def validate_endpoint(endpoint: str) -> str:
    """Return ``endpoint`` if it looks like a Zenoh locator (``tcp/127.0.0.1:7447``)."""
    if not isinstance(endpoint, str) or not _ENDPOINT_RE.fullmatch(endpoint):
        raise ValueError(
            f"invalid Zenoh endpoint {endpoint!r}: expected PROTO/HOST:PORT, e.g. "
            "tcp/127.0.0.1:7447"
        )
    return endpoint


def key(vehicle: str, topic: Topic | str) -> str:
    """Zenoh key of ``topic`` for ``vehicle``: ``hilnav/<vehicle>/<topic>``.

    ``topic`` may also be ``"**"`` (the vehicle's whole subtree); ``vehicle`` may be ``"*"``.
    """
    validate_vehicle(vehicle, wildcard=True)
    suffix = topic.value if isinstance(topic, Topic) else str(topic)
    if suffix != "**" and suffix not in _TOPIC_BY_SUFFIX:
        raise ValueError(f"unknown topic {topic!r}; valid: {', '.join(t.value for t in Topic)}")
    return f"{ROOT}/{vehicle}/{suffix}"


_TOPIC_BY_SUFFIX: Final = {t.value: t for t in Topic}


def parse_key(key_expr: str) -> tuple[str, Topic | None]:
    """Split ``hilnav/<vehicle>/<suffix>`` into the vehicle and its :class:`Topic`.

    Returns ``(vehicle, None)`` for a suffix outside the key space; raises ``ValueError`` for a
    key that is not under ``hilnav/<vehicle>/``.
    """
    parts = key_expr.split("/", 2)
    if len(parts) != 3 or parts[0] != ROOT or not parts[1]:
        raise ValueError(f"key {key_expr!r} is not under {ROOT}/<vehicle>/")
    return parts[1], _TOPIC_BY_SUFFIX.get(parts[2])
