"""hilnav on Eclipse Zenoh: the public names of the bus package, importable from ``hil.bus``.

=========================  ==============================================================
:mod:`hil.bus.keys`        key space: :class:`Topic`, :func:`key`, :func:`parse_key`, checks
:mod:`hil.bus.schemas`     JSON Schema of every topic's payload (:data:`SCHEMAS`)
:mod:`hil.bus.payloads`    payload builders from samples, truth and estimates; :func:`encode`
:mod:`hil.bus.config`      :class:`BusConfig`: rates, queue size, connect timing
:mod:`hil.bus.stats`       :class:`BusStats`: the counters a bus reports
:mod:`hil.bus.message`     :class:`Message`: a received sample, its payload decoded
:mod:`hil.bus.rate`        :class:`~hil.bus.rate.RateLimiter`: per-topic decimation
:mod:`hil.bus.session`     :class:`Bus`: the non-blocking Zenoh session of one process
:mod:`hil.bus.health`      :func:`check_bus`: the health check of a deployment
:mod:`hil.bus.security`    :class:`ClientSecurity`, :class:`RouterSecurity`: usrpwd, TLS/mTLS, ACL
:mod:`hil.bus.auth`        :class:`PayloadAuth`: HMAC-tagged samples, challenge of the fusion
=========================  ==============================================================
"""

from __future__ import annotations

from hil.bus.auth import KEY_ENV, PayloadAuth
from hil.bus.config import BusConfig
from hil.bus.health import check_bus
from hil.bus.keys import (
    PUBLISHED_TOPICS,
    ROOT,
    Topic,
    key,
    parse_key,
    validate_endpoint,
    validate_vehicle,
)
from hil.bus.message import Message
from hil.bus.payloads import (
    config_reply_payload,
    encode,
    error_payload,
    estimate_payload,
    event_payload,
    fusion_event_payload,
    innovation_payload,
    sample_payload,
    sample_topic,
    status_payload,
    truth_payload,
)
from hil.bus.schemas import SCHEMA_VERSION, SCHEMAS
from hil.bus.security import PASSWORD_ENV, BusAccess, ClientSecurity, RouterSecurity
from hil.bus.session import Bus, Declaration
from hil.bus.stats import BusStats

__all__ = [
    "KEY_ENV",
    "PASSWORD_ENV",
    "PUBLISHED_TOPICS",
    "ROOT",
    "SCHEMAS",
    "SCHEMA_VERSION",
    "Bus",
    "BusAccess",
    "BusConfig",
    "BusStats",
    "ClientSecurity",
    "Declaration",
    "Message",
    "PayloadAuth",
    "RouterSecurity",
    "Topic",
    "check_bus",
    "config_reply_payload",
    "encode",
    "error_payload",
    "estimate_payload",
    "event_payload",
    "fusion_event_payload",
    "innovation_payload",
    "key",
    "parse_key",
    "sample_payload",
    "sample_topic",
    "status_payload",
    "truth_payload",
    "validate_endpoint",
    "validate_vehicle",
]
