"""hilnav on Eclipse Zenoh: key space, JSON payloads with their schemas, and a non-blocking bus.

Key space (ARCHITECTURE.md), one subtree per vehicle::

    hilnav/<vehicle>/sim/truth              true state (when the simulator knows it)
    hilnav/<vehicle>/sensors/{imu,gnss,baro,mag}
    hilnav/<vehicle>/fusion/estimate        navigation solution
    hilnav/<vehicle>/fusion/status          mode, outage timer, health, innovation ratios, links
    hilnav/<vehicle>/fusion/innovations     one message per aiding update
    hilnav/<vehicle>/fusion/error           estimate - truth (when truth is known)
    hilnav/<vehicle>/scenario/events        scenario timeline (GNSS off/on, faults, ...)
    hilnav/<vehicle>/fusion/config          queryable: the fusion service's configuration
    hilnav/<vehicle>/fusion/alive           liveliness token of the fusion service

Payloads are UTF-8 JSON objects. Every payload carries ``schema_version`` (:data:`SCHEMA_VERSION`)
and, where it has a time, ``time_us`` in *simulated* time. Field names carry units
(``lat_deg``, ``alt_msl_m``, ``v_ned_mps``); vectors are JSON arrays in the frame their name
says; numbers that are not finite (a test ratio before the first test, the time since GNSS before
the first fix) are ``null``. :data:`SCHEMAS` holds the JSON Schema of every topic (MCAP channels
carry it, so Foxglove / PlotJuggler can decode a recording).

Publishing never blocks the caller (the filter loop): :meth:`Bus.publish` rate-limits per topic,
serialises, and appends to a bounded queue that a publisher thread drains into Zenoh publishers
declared with congestion control ``DROP``. A full queue drops its *oldest* message (the freshest
estimate matters most) and counts it; :meth:`Bus.stats` reports every counter.

Connection: the default is a Zenoh *client* that connects to a router (``hilnav up``'s in-process
router, see :mod:`hil.router`, or zenohd). A Zenoh (1.10) client cannot open a session while no
router is reachable: ``connect/exit_on_failure: false`` only makes *peers and routers* connect
in the background; a client's open blocks for ``connect/timeout_ms`` (forever for -1) and then
fails. So the bus opens its session in the publisher thread, one attempt of
``BusConfig.connect_timeout_s`` at a time, until the router answers; meanwhile publications wait
in the queue (bounded, oldest dropped) and subscriptions, queryables and liveliness tokens are
declared as soon as the session exists. Once open, the Zenoh client reconnects by itself when the
router goes away and comes back, and re-declares everything (tested in ``tests/test_bus.py``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum, StrEnum
from typing import Any, Final, Literal, Self

import numpy as np
import pydantic
import zenoh

from fusion.earth import ned_offset_m

__all__ = [
    "PUBLISHED_TOPICS",
    "SCHEMAS",
    "SCHEMA_VERSION",
    "Bus",
    "BusConfig",
    "BusStats",
    "Declaration",
    "Message",
    "Topic",
    "check_main",
    "config_reply_payload",
    "encode",
    "error_payload",
    "estimate_payload",
    "event_payload",
    "innovation_payload",
    "key",
    "parse_key",
    "sample_payload",
    "status_payload",
    "truth_payload",
    "validate_endpoint",
    "validate_vehicle",
]

SCHEMA_VERSION: Final = 1
"""Version of every payload schema below; bump it when a field changes meaning or disappears."""

ROOT: Final = "hilnav"


class Topic(StrEnum):
    """Key-space suffixes under ``hilnav/<vehicle>/``."""

    TRUTH = "sim/truth"
    IMU = "sensors/imu"
    GNSS = "sensors/gnss"
    BARO = "sensors/baro"
    MAG = "sensors/mag"
    ESTIMATE = "fusion/estimate"
    STATUS = "fusion/status"
    INNOVATIONS = "fusion/innovations"
    ERROR = "fusion/error"
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


# ----------------------------------------------------------------------------------- schemas
_DRAFT: Final = "https://json-schema.org/draft/2020-12/schema"
_N: Final[dict[str, Any]] = {"type": "number"}
_N0: Final[dict[str, Any]] = {"type": ["number", "null"]}
_I: Final[dict[str, Any]] = {"type": "integer"}
_S: Final[dict[str, Any]] = {"type": "string"}


def _arr(n: int | None, *, nullable: bool = False) -> dict[str, Any]:
    s: dict[str, Any] = {"type": ["array", "null"] if nullable else "array", "items": _N}
    if n is not None:
        s |= {"minItems": n, "maxItems": n}
    return s


def _d(schema: Mapping[str, Any], description: str) -> dict[str, Any]:
    return {**schema, "description": description}


def _schema(
    topic: Topic, description: str, props: dict[str, Any], optional: Sequence[str] = ()
) -> dict[str, Any]:
    """One object schema: every property required except ``optional`` (which may be null)."""
    properties = {
        "schema_version": _d(
            {"type": "integer", "const": SCHEMA_VERSION}, "payload schema version"
        ),
        **props,
    }
    return {
        "$schema": _DRAFT,
        "$id": f"https://hilnav.invalid/schemas/{topic.value}/v{SCHEMA_VERSION}.json",
        "title": "hilnav." + topic.value.replace("/", "."),
        "description": description,
        "type": "object",
        "properties": properties,
        "required": [p for p in properties if p not in optional],
        # consumers must ignore fields they do not know: new optional fields keep the version
        "additionalProperties": True,
    }


_TIME = _d(_I, "simulated time of validity, microseconds")
_LATLON = {
    "lat_deg": _d(_N, "geodetic latitude WGS-84, deg"),
    "lon_deg": _d(_N, "longitude WGS-84, deg"),
    "alt_msl_m": _d(_N, "altitude above mean sea level, m"),
}
_ATT = {
    "q_nb": _d(_arr(4), "attitude quaternion body FRD -> NED, Hamilton [w, x, y, z]"),
    "roll_deg": _d(_N, "3-2-1 Euler roll, deg"),
    "pitch_deg": _d(_N, "3-2-1 Euler pitch, deg"),
    "yaw_deg": _d(_N, "3-2-1 Euler yaw (heading, true), deg in (-180, 180]"),
}

SCHEMAS: Final[Mapping[Topic, dict[str, Any]]] = {
    Topic.TRUTH: _schema(
        Topic.TRUTH,
        "True vehicle state from the simulator.",
        {
            "time_us": _TIME,
            **_LATLON,
            "v_ned_mps": _d(_arr(3), "velocity NED, m/s"),
            **_ATT,
            "omega_b_rps": _d(_arr(3, nullable=True), "body rate w.r.t. inertial, FRD, rad/s"),
            "specific_force_b_mps2": _d(_arr(3, nullable=True), "specific force FRD, m/s^2"),
            "static_pressure_pa": _d(_N0, "ambient static pressure, Pa"),
            "temperature_k": _d(_N0, "ambient temperature, K"),
            "airspeed_mps": _d(_N0, "true airspeed, m/s"),
            "indicated_airspeed_mps": _d(_N0, "indicated airspeed, m/s"),
        },
        optional=(
            "omega_b_rps",
            "specific_force_b_mps2",
            "static_pressure_pa",
            "temperature_k",
            "airspeed_mps",
            "indicated_airspeed_mps",
        ),
    ),
    Topic.IMU: _schema(
        Topic.IMU,
        "IMU sample averaged over dt_s ending at time_us.",
        {
            "time_us": _TIME,
            "dt_s": _d(_N, "averaging interval, s"),
            "specific_force_b_mps2": _d(_arr(3), "specific force FRD, m/s^2"),
            "angular_rate_b_rps": _d(_arr(3), "angular rate FRD, rad/s"),
            "temperature_k": _d(_N0, "sensor temperature, K"),
            "sensor_id": _d(_I, "sensor instance"),
        },
        optional=("temperature_k",),
    ),
    Topic.GNSS: _schema(
        Topic.GNSS,
        "GNSS receiver fix (time_us = time of validity).",
        {
            "time_us": _TIME,
            **_LATLON,
            "v_ned_mps": _d(_arr(3), "velocity NED, m/s"),
            "eph_m": _d(_N, "1-sigma horizontal position accuracy, m"),
            "epv_m": _d(_N, "1-sigma vertical position accuracy, m"),
            "speed_accuracy_mps": _d(_N, "1-sigma speed accuracy, m/s"),
            "fix_type": _d(_I, "GPS_FIX_TYPE (3 = 3D)"),
            "satellites_visible": _d(_I, "satellites used"),
            "sensor_id": _d(_I, "sensor instance"),
        },
    ),
    Topic.BARO: _schema(
        Topic.BARO,
        "Barometer sample.",
        {
            "time_us": _TIME,
            "pressure_pa": _d(_N, "static pressure, Pa"),
            "temperature_k": _d(_N0, "sensor temperature, K"),
            "sensor_id": _d(_I, "sensor instance"),
        },
        optional=("temperature_k",),
    ),
    Topic.MAG: _schema(
        Topic.MAG,
        "Magnetometer sample.",
        {
            "time_us": _TIME,
            "field_b_tesla": _d(_arr(3), "magnetic flux density FRD, T"),
            "sensor_id": _d(_I, "sensor instance"),
        },
    ),
    Topic.ESTIMATE: _schema(
        Topic.ESTIMATE,
        "Navigation solution of the fusion filter.",
        {
            "time_us": _TIME,
            "mode": _d(_S, "initializing | gnss | bridging | free-inertial"),
            **_LATLON,
            "v_ned_mps": _d(_arr(3), "velocity NED, m/s"),
            **_ATT,
            "pos_sigma_ned_m": _d(_arr(3, nullable=True), "1-sigma position N/E/D, m"),
            "vel_sigma_ned_mps": _d(_arr(3, nullable=True), "1-sigma velocity N/E/D, m/s"),
            "att_sigma_deg": _d(_arr(3, nullable=True), "1-sigma tilt N/E/D, deg"),
            "accel_bias_b_mps2": _d(_arr(3, nullable=True), "accelerometer bias FRD, m/s^2"),
            "gyro_bias_b_rps": _d(_arr(3, nullable=True), "gyro bias FRD, rad/s"),
            "baro_bias_m": _d(_N0, "baro height bias, m"),
            "time_since_gnss_s": _d(_N0, "seconds since the last fused fix (null: none yet)"),
        },
        optional=(
            "pos_sigma_ned_m",
            "vel_sigma_ned_mps",
            "att_sigma_deg",
            "accel_bias_b_mps2",
            "gyro_bias_b_rps",
            "baro_bias_m",
            "time_since_gnss_s",
        ),
    ),
    Topic.STATUS: _schema(
        Topic.STATUS,
        "Fusion service status: mode, outage timer, health counters, innovation test ratios, "
        "bridging (GMDH) health, link and bus counters.",
        {
            "time_us": _TIME,
            "mode": _d(_S, "initializing | gnss | bridging | free-inertial"),
            "time_since_gnss_s": _d(_N0, "outage timer: seconds since the last fused fix"),
            "state_layout": _d({"type": ["string", "null"]}, "error-state layout name"),
            "test_ratios": _d(
                {"type": "object", "additionalProperties": _N0},
                "last normalised innovation test ratio per aiding source (> 1 = rejected)",
            ),
            "health": _d({"type": "object", "additionalProperties": _I}, "filter health counters"),
            "bridge": _d(
                {"type": ["object", "null"]}, "bridging model health (method, trained, fit, ...)"
            ),
            "links": _d(
                {"type": ["object", "null"], "additionalProperties": {"type": "object"}},
                "per-link counters (hil.link.LinkCounters fields)",
            ),
            "bus": _d({"type": ["object", "null"]}, "Zenoh bus counters of the publisher"),
        },
        optional=("time_since_gnss_s", "state_layout", "bridge", "links", "bus"),
    ),
    Topic.INNOVATIONS: _schema(
        Topic.INNOVATIONS,
        "One aiding update: innovation, its predicted sigma, the gate test ratio.",
        {
            "time_us": _TIME,
            "source": _d(_S, "aiding source: gnss_pos, gnss_vel, baro_hgt, mag_hdg, "
                         "bridge_pos, bridge_vel"),
            "innovation": _d(
                _arr(None),
                "innovation of the error-state filter: INS-predicted minus measured, SI units "
                "of the observation (gnss_pos N/E/D m, gnss_vel N/E/D m/s, baro_hgt m, "
                "mag_hdg rad)",
            ),
            "innovation_sigma": _d(
                _arr(None, nullable=True), "sqrt(diag(S)), same units as the innovation"
            ),
            "test_ratio": _d(_N0, "NIS over the gate; > 1 = rejected"),
            "accepted": _d({"type": "boolean"}, "fused (true) or rejected by the gate"),
        },
        optional=("innovation_sigma", "test_ratio"),
    ),
    Topic.ERROR: _schema(
        Topic.ERROR,
        "Estimate minus truth at the same time of validity.",
        {
            "time_us": _TIME,
            "truth_time_us": _d(_I, "time of the truth sample used, microseconds"),
            "mode": _d({"type": ["string", "null"]}, "filter mode at time_us"),
            "pos_error_ned_m": _d(_arr(3), "position error N/E/D, m"),
            "horizontal_error_m": _d(_N, "horizontal position error, m"),
            "vertical_error_m": _d(_N, "altitude error (up positive), m"),
            "vel_error_ned_mps": _d(_arr(3), "velocity error N/E/D, m/s"),
            "roll_error_deg": _d(_N, "roll error, deg"),
            "pitch_error_deg": _d(_N, "pitch error, deg"),
            "yaw_error_deg": _d(_N, "yaw error wrapped to (-180, 180], deg"),
            "att_error_deg": _d(_N, "total attitude error angle, deg"),
        },
        optional=("mode",),
    ),
    Topic.EVENTS: _schema(
        Topic.EVENTS,
        "Scenario timeline event.",
        {
            "time_us": _TIME,
            "event": _d(_S, "event kind, e.g. gnss_off, gnss_on, fault, note"),
            "message": _d(_S, "human-readable text"),
            "detail": _d({"type": "object"}, "event parameters"),
        },
    ),
    Topic.CONFIG: _schema(
        Topic.CONFIG,
        "Reply of the fusion/config queryable.",
        {
            "vehicle": _d(_S, "vehicle name"),
            "config": _d({"type": "object"}, "the fusion service configuration"),
        },
    ),
}


# ---------------------------------------------------------------------------------- payloads
def _plain(x: Any) -> Any:
    """JSON-safe copy: numpy -> Python, dataclasses/mappings -> dicts, non-finite -> None."""
    if x is None or isinstance(x, (bool, str)):
        return x
    if isinstance(x, (int, np.integer)) and not isinstance(x, np.bool_):
        return int(x)
    if isinstance(x, (float, np.floating)):
        f = float(x)
        return f if math.isfinite(f) else None
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return [_plain(v) for v in x.tolist()]
    if isinstance(x, Enum):
        return _plain(x.value)
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: _plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if hasattr(x, "model_dump"):  # pydantic model
        return _plain(x.model_dump(mode="json"))
    if isinstance(x, Mapping):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    raise TypeError(f"cannot encode {type(x).__name__} as JSON")


def _field(obj: Any, name: str, what: str) -> Any:
    try:
        return getattr(obj, name)
    except AttributeError:
        raise ValueError(f"{what} has no field {name!r}") from None


def _num(x: Any, name: str) -> float | None:
    try:
        f = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    return f if math.isfinite(f) else None


def _fin(x: Any, name: str) -> float:
    """A finite float, else ``ValueError`` naming the field."""
    f = _num(x, name)
    if f is None:
        raise ValueError(f"{name} must be finite, got {x!r}")
    return f


def _vec(a: Any, n: int | None, name: str, *, finite: bool = True) -> list[Any]:
    try:
        v = np.asarray(a, dtype=np.float64).reshape(-1).tolist()
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric vector, got {a!r}") from None
    if n is not None and len(v) != n:
        raise ValueError(f"{name} must have {n} elements, got shape {np.shape(a)}")
    # element-wise in Python: faster than numpy on 3- and 4-vectors
    if finite and not all(math.isfinite(x) for x in v):
        raise ValueError(f"{name} must be finite, got {v}")
    return [x if math.isfinite(x) else None for x in v]


def _euler_deg(q: Sequence[float]) -> list[float]:
    """3-2-1 (roll, pitch, yaw) of ``q_nb`` in degrees; scalar math (this runs per message,
    ``fusion.rotations.quat_to_euler`` is ~50x slower on one quaternion)."""
    w, x, y, z = q
    n2 = w * w + x * x + y * y + z * z
    roll = math.atan2(2.0 * (w * x + y * z), n2 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x) / n2)))
    yaw = math.atan2(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z))
    return [math.degrees(roll), math.degrees(pitch), math.degrees(yaw)]


def _angle_between_deg(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Rotation angle of ``q1 * conj(q2)``, deg (atan2 form: accurate for tiny angles)."""
    w1, x1, y1, z1 = q1
    w2, x2, y2, z2 = q2
    # q1 * conj(q2), Hamilton product
    w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
    x = -w1 * x2 + x1 * w2 - y1 * z2 + z1 * y2
    y = -w1 * y2 + x1 * z2 + y1 * w2 - z1 * x2
    z = -w1 * z2 - x1 * y2 + y1 * x2 + z1 * w2
    return math.degrees(2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w)))


def _opt_vec(obj: Any, name: str, n: int, *, scale: float = 1.0) -> list[Any] | None:
    a = getattr(obj, name, None)
    if a is None:
        return None
    return _vec(np.asarray(a, dtype=np.float64) * scale, n, name, finite=False)


def _opt_num(obj: Any, name: str) -> float | None:
    a = getattr(obj, name, None)
    return None if a is None else _num(a, name)


def _time_us(obj: Any, what: str) -> int:
    t = _field(obj, "time_us", what)
    if isinstance(t, (bool, np.bool_)) or not isinstance(t, (int, np.integer)):
        raise ValueError(f"{what}.time_us must be an integer (microseconds), got {t!r}")
    return int(t)


def _pose(obj: Any, what: str) -> dict[str, Any]:
    """Position, velocity and attitude fields shared by truth and estimate payloads."""
    q = _vec(_field(obj, "q_nb", what), 4, f"{what}.q_nb")
    if not sum(c * c for c in q) > 0.5:
        raise ValueError(f"{what}.q_nb must be a unit quaternion, got {q}")
    euler = getattr(obj, "euler_rad", None)
    if euler is None:
        rpy = _euler_deg(q)
    else:
        rpy = [math.degrees(a) for a in _vec(euler, 3, f"{what}.euler_rad")]
    return {
        "lat_deg": math.degrees(_fin(_field(obj, "lat_rad", what), f"{what}.lat_rad")),
        "lon_deg": math.degrees(_fin(_field(obj, "lon_rad", what), f"{what}.lon_rad")),
        "alt_msl_m": _fin(_field(obj, "alt_msl_m", what), f"{what}.alt_msl_m"),
        "v_ned_mps": _vec(_field(obj, "v_ned_mps", what), 3, f"{what}.v_ned_mps"),
        "q_nb": q,
        "roll_deg": rpy[0],
        "pitch_deg": rpy[1],
        "yaw_deg": rpy[2],
    }


def truth_payload(truth: Any) -> dict[str, Any]:
    """Payload of ``sim/truth`` from a :class:`sim.samples.Truth`-like object.

    Required attributes: ``time_us, lat_rad, lon_rad, alt_msl_m, v_ned_mps (3,), q_nb (4,)``;
    the others of ``Truth`` are used when present.
    """
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": _time_us(truth, "truth"),
        **_pose(truth, "truth"),
        "omega_b_rps": _opt_vec(truth, "omega_b_rps", 3),
        "specific_force_b_mps2": _opt_vec(truth, "specific_force_b_mps2", 3),
        "static_pressure_pa": _opt_num(truth, "static_pressure_pa"),
        "temperature_k": _opt_num(truth, "temperature_k"),
        "airspeed_mps": _opt_num(truth, "airspeed_mps"),
        "indicated_airspeed_mps": _opt_num(truth, "indicated_airspeed_mps"),
    }


def _sensor_id(s: Any) -> int:
    return int(getattr(s, "sensor_id", 0))


_SAMPLE_MARKERS: Final = ("angular_rate_b_rps", "eph_m", "pressure_pa", "field_b_tesla")
_SAMPLE_TOPICS: Final = (Topic.IMU, Topic.GNSS, Topic.BARO, Topic.MAG)


def sample_payload(sample: Any) -> tuple[Topic, dict[str, Any]]:
    """Topic and payload of a sensor sample (:mod:`sim.samples` or anything shaped like one).

    The kind is recognised by its fields: ``angular_rate_b_rps`` (IMU), ``eph_m`` (GNSS),
    ``pressure_pa`` (baro), ``field_b_tesla`` (mag).
    """
    if not any(hasattr(sample, f) for f in _SAMPLE_MARKERS):
        raise ValueError(f"not a sensor sample: {type(sample).__name__}")
    base = {"schema_version": SCHEMA_VERSION, "time_us": _time_us(sample, "sample")}
    if hasattr(sample, "angular_rate_b_rps"):
        return Topic.IMU, base | {
            "dt_s": _fin(sample.dt_s, "imu.dt_s"),
            "specific_force_b_mps2": _vec(
                sample.specific_force_b_mps2, 3, "imu.specific_force_b_mps2", finite=False
            ),
            "angular_rate_b_rps": _vec(
                sample.angular_rate_b_rps, 3, "imu.angular_rate_b_rps", finite=False
            ),
            "temperature_k": _opt_num(sample, "temperature_k"),
            "sensor_id": _sensor_id(sample),
        }
    if hasattr(sample, "eph_m"):
        return Topic.GNSS, base | {
            "lat_deg": math.degrees(_fin(sample.lat_rad, "gnss.lat_rad")),
            "lon_deg": math.degrees(_fin(sample.lon_rad, "gnss.lon_rad")),
            "alt_msl_m": _fin(sample.alt_msl_m, "gnss.alt_msl_m"),
            "v_ned_mps": _vec(sample.v_ned_mps, 3, "gnss.v_ned_mps"),
            "eph_m": _fin(sample.eph_m, "gnss.eph_m"),
            "epv_m": _fin(sample.epv_m, "gnss.epv_m"),
            "speed_accuracy_mps": _fin(sample.speed_accuracy_mps, "gnss.speed_accuracy_mps"),
            "fix_type": int(getattr(sample, "fix_type", 3)),
            "satellites_visible": int(getattr(sample, "satellites_visible", 0)),
            "sensor_id": _sensor_id(sample),
        }
    if hasattr(sample, "pressure_pa"):
        return Topic.BARO, base | {
            "pressure_pa": _fin(sample.pressure_pa, "baro.pressure_pa"),
            "temperature_k": _opt_num(sample, "temperature_k"),
            "sensor_id": _sensor_id(sample),
        }
    if hasattr(sample, "field_b_tesla"):
        return Topic.MAG, base | {
            "field_b_tesla": _vec(sample.field_b_tesla, 3, "mag.field_b_tesla", finite=False),
            "sensor_id": _sensor_id(sample),
        }
    raise ValueError(f"not a sensor sample: {type(sample).__name__}")


def _sigmas(p_diag: Any) -> tuple[list[Any] | None, list[Any] | None, list[Any] | None]:
    """1-sigma position (m), velocity (m/s), tilt (deg) from the error-state variances.

    Every layout of ``fusion.error_model`` starts with position N/E/D (m^2), velocity (m/s)^2
    and attitude (rad^2): the first nine entries are read, the rest (biases, scale factors) is
    the filter's business.
    """
    if p_diag is None:
        return None, None, None
    p = np.asarray(p_diag, dtype=np.float64).reshape(-1)
    if p.size < 9:
        raise ValueError(f"estimate.P_diag must have at least 9 entries, got {p.size}")
    sd = np.sqrt(np.maximum(p[:9], 0.0))
    return (
        _vec(sd[0:3], 3, "pos_sigma", finite=False),
        _vec(sd[3:6], 3, "vel_sigma", finite=False),
        _vec(np.degrees(sd[6:9]), 3, "att_sigma", finite=False),
    )


def estimate_payload(est: Any) -> dict[str, Any]:
    """Payload of ``fusion/estimate`` from a ``fusion.filter.NavEstimate``-like object.

    Required attributes: ``time_us, lat_rad, lon_rad, alt_msl_m, v_ned_mps (3,), q_nb (4,)``.
    Used when present: ``euler_rad (3,)`` (else derived from ``q_nb``), ``P_diag (n>=9,)``,
    ``mode``, ``accel_bias_b_mps2``, ``gyro_bias_b_rps``, ``baro_bias_m``, ``time_since_gnss_s``.
    """
    pos_sd, vel_sd, att_sd = _sigmas(getattr(est, "P_diag", None))
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": _time_us(est, "estimate"),
        "mode": str(getattr(est, "mode", "unknown")),
        **_pose(est, "estimate"),
        "pos_sigma_ned_m": pos_sd,
        "vel_sigma_ned_mps": vel_sd,
        "att_sigma_deg": att_sd,
        "accel_bias_b_mps2": _opt_vec(est, "accel_bias_b_mps2", 3),
        "gyro_bias_b_rps": _opt_vec(est, "gyro_bias_b_rps", 3),
        "baro_bias_m": _opt_num(est, "baro_bias_m"),
        "time_since_gnss_s": _opt_num(est, "time_since_gnss_s"),
    }


def status_payload(
    est: Any,
    *,
    bridge: Any = None,
    links: Mapping[str, Any] | None = None,
    bus: BusStats | Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Payload of ``fusion/status``.

    Parameters
    ----------
    est : NavEstimate-like
        Read: ``time_us``, ``mode``, ``time_since_gnss_s``, ``state_layout``, ``test_ratios``
        (dataclass or mapping of ratios), ``health`` (dataclass or mapping of counters).
    bridge : dataclass or mapping, optional
        Health of the bridging model (GMDH: trained or not, training samples, fit error...).
    links : mapping of name -> ``hil.link.LinkCounters`` (or mapping), optional
    bus : BusStats or mapping, optional
        The publishing bus's counters (:meth:`Bus.stats`).
    """
    ratios = getattr(est, "test_ratios", None)
    health = getattr(est, "health", None)
    health_plain = _plain(health) if health is not None else {}
    if not isinstance(health_plain, dict) or not all(
        isinstance(v, int) for v in health_plain.values()
    ):
        raise ValueError("estimate.health must be a dataclass or mapping of integer counters")
    ratios_plain = _plain(ratios) if ratios is not None else {}
    if not isinstance(ratios_plain, dict):
        raise ValueError("estimate.test_ratios must be a dataclass or mapping of numbers")
    layout = getattr(est, "state_layout", None)
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": _time_us(est, "estimate"),
        "mode": str(getattr(est, "mode", "unknown")),
        "time_since_gnss_s": _opt_num(est, "time_since_gnss_s"),
        "state_layout": None if layout is None else str(layout),
        "test_ratios": ratios_plain,
        "health": health_plain,
        "bridge": None if bridge is None else _plain(bridge),
        "links": None if links is None else {str(k): _plain(v) for k, v in links.items()},
        "bus": None if bus is None else _plain(bus),
    }


def innovation_payload(
    time_us: int,
    source: str,
    innovation: Any,
    *,
    S: Any = None,  # the filter's letter for the innovation covariance
    test_ratio: float | None = None,
    accepted: bool,
) -> dict[str, Any]:
    """Payload of ``fusion/innovations`` for one aiding update.

    Parameters
    ----------
    time_us : int
        Time of validity of the observation.
    source : str
        ``gnss_pos``, ``gnss_vel``, ``baro_hgt``, ``mag_hdg``, ...
    innovation : array_like, shape (m,)
        ``z - h(x)``, SI units of the observation.
    S : array_like, shape (m, m) or (m,), optional
        Innovation covariance (or its diagonal); its square-rooted diagonal is published.
    test_ratio : float, optional
        NIS over the gate (``fusion.kalman.Correction.test_ratio``).
    accepted : bool
    """
    y = _vec(innovation, None, "innovation", finite=False)
    sigma = None
    if S is not None:
        s = np.asarray(S, dtype=np.float64)
        diag = np.diag(s) if s.ndim == 2 else s.reshape(-1)
        if diag.shape != (len(y),):
            raise ValueError(f"S must be ({len(y)}, {len(y)}) or ({len(y)},), got {s.shape}")
        sigma = _vec(np.sqrt(np.maximum(diag, 0.0)), len(y), "innovation_sigma", finite=False)
    if not isinstance(time_us, (int, np.integer)):
        raise ValueError(f"time_us must be an integer (microseconds), got {time_us!r}")
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": int(time_us),
        "source": str(source),
        "innovation": y,
        "innovation_sigma": sigma,
        "test_ratio": None if test_ratio is None else _num(test_ratio, "test_ratio"),
        "accepted": bool(accepted),
    }


def _wrap_deg(a: float) -> float:
    w = (a + 180.0) % 360.0 - 180.0
    return 180.0 if w == -180.0 else w


def error_payload(est: Any, truth: Any) -> dict[str, Any]:
    """Payload of ``fusion/error``: estimate minus truth.

    Position error N/E/D through the radii of curvature at the true position
    (``fusion.earth.ned_offset_m``; < 1 mm error for 100 m offsets); the vertical error is the
    altitude difference, up positive; attitude errors are Euler differences (yaw wrapped) and
    the rotation angle of ``q_est * conj(q_true)``. The caller pairs ``est`` with the truth of
    the same time; both times are in the payload.
    """
    t_est = _time_us(est, "estimate")
    t_true = _time_us(truth, "truth")
    e = _pose(est, "estimate")
    tr = _pose(truth, "truth")
    lat_e = math.radians(e["lat_deg"])
    lon_e = math.radians(e["lon_deg"])
    lat_t = math.radians(tr["lat_deg"])
    lon_t = math.radians(tr["lon_deg"])
    dn, de, dd = ned_offset_m(lat_e, lon_e, e["alt_msl_m"], lat_t, lon_t, tr["alt_msl_m"])
    dv = [a - b for a, b in zip(e["v_ned_mps"], tr["v_ned_mps"], strict=True)]
    mode = getattr(est, "mode", None)
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": t_est,
        "truth_time_us": t_true,
        "mode": None if mode is None else str(mode),
        "pos_error_ned_m": [float(dn), float(de), float(dd)],
        "horizontal_error_m": math.hypot(dn, de),
        "vertical_error_m": e["alt_msl_m"] - tr["alt_msl_m"],
        "vel_error_ned_mps": dv,
        "roll_error_deg": _wrap_deg(e["roll_deg"] - tr["roll_deg"]),
        "pitch_error_deg": _wrap_deg(e["pitch_deg"] - tr["pitch_deg"]),
        "yaw_error_deg": _wrap_deg(e["yaw_deg"] - tr["yaw_deg"]),
        "att_error_deg": _angle_between_deg(e["q_nb"], tr["q_nb"]),
    }


def event_payload(
    time_us: int, event: str, message: str = "", detail: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """Payload of ``scenario/events`` (``event`` e.g. ``"gnss_off"``, ``detail`` its parameters)."""
    if not isinstance(time_us, (int, np.integer)):
        raise ValueError(f"time_us must be an integer (microseconds), got {time_us!r}")
    if not event:
        raise ValueError("event must be a non-empty string")
    return {
        "schema_version": SCHEMA_VERSION,
        "time_us": int(time_us),
        "event": str(event),
        "message": str(message),
        "detail": _plain(dict(detail or {})),
    }


def config_reply_payload(vehicle: str, config: Any) -> dict[str, Any]:
    """Payload answered by the ``fusion/config`` queryable (``config``: mapping or pydantic)."""
    plain = _plain(config)
    if not isinstance(plain, dict):
        raise ValueError(f"config must be a mapping or a pydantic model, got {type(config)}")
    return {"schema_version": SCHEMA_VERSION, "vehicle": vehicle, "config": plain}


def _json_default(x: Any) -> Any:
    if isinstance(x, (np.ndarray, np.generic)):
        return x.tolist()
    raise TypeError(f"cannot encode {type(x).__name__} as JSON")


def encode(payload: Mapping[str, Any]) -> bytes:
    """Compact UTF-8 JSON of ``payload``, with ``schema_version`` added when missing.

    Raises ``ValueError`` for NaN/Inf (not JSON; the payload builders turn them into null) and
    for values JSON cannot represent.
    """
    if not isinstance(payload, Mapping):
        raise ValueError(f"payload must be a mapping, got {type(payload).__name__}")
    data = payload if "schema_version" in payload else {"schema_version": SCHEMA_VERSION, **payload}
    try:
        text = json.dumps(data, separators=(",", ":"), allow_nan=False, default=_json_default)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"payload is not encodable as JSON: {exc}") from None
    return text.encode()


# -------------------------------------------------------------------------------------- bus
_DEFAULT_RATES: Final[dict[Topic, float | None]] = {
    Topic.TRUTH: 25.0,
    Topic.IMU: 25.0,
    Topic.GNSS: None,
    Topic.BARO: 25.0,
    Topic.MAG: 25.0,
    Topic.ESTIMATE: 25.0,
    Topic.STATUS: 2.0,
    Topic.INNOVATIONS: None,
    Topic.ERROR: 25.0,
    Topic.EVENTS: None,
}


class BusConfig(pydantic.BaseModel):
    """Rates and limits of a :class:`Bus`.

    Attributes
    ----------
    rates_hz : mapping of topic -> max rate (Hz) or None (every message)
        Decimation per topic, on simulated time (``time_us`` of the payload) so a recording of
        a faster-than-real-time run is evenly sampled; payloads without ``time_us`` are
        decimated on the wall clock. Topics not listed keep their default
        (truth, IMU, baro, mag, estimate, error 25 Hz; status 2 Hz; GNSS, innovations,
        events unlimited).
    queue_size : int
        Messages waiting for the publisher thread; beyond it the oldest is dropped.
    connect_timeout_s : float
        One attempt to open the session (a client waits this long for the router), s.
    retry_s : float
        Pause between session-open attempts while no router answers, s.
    """

    model_config = pydantic.ConfigDict(frozen=True, extra="forbid")

    rates_hz: dict[Topic, float | None] = pydantic.Field(default_factory=dict)
    queue_size: int = pydantic.Field(default=4096, ge=1, le=10_000_000)
    connect_timeout_s: float = pydantic.Field(default=1.0, gt=0.0, le=60.0)
    retry_s: float = pydantic.Field(default=0.5, ge=0.0, le=60.0)

    @pydantic.field_validator("rates_hz")
    @classmethod
    def _check_rates(cls, v: dict[Topic, float | None]) -> dict[Topic, float | None]:
        for topic, rate in v.items():
            if topic in (Topic.CONFIG, Topic.ALIVE):
                raise ValueError(f"{topic.value} is not a published topic")
            if rate is not None and not (math.isfinite(rate) and rate > 0.0):
                raise ValueError(f"rate of {topic.value} must be > 0 Hz or null, got {rate}")
        return v

    def rate_hz(self, topic: Topic) -> float | None:
        """Effective maximum rate of ``topic`` (None = unlimited)."""
        return self.rates_hz.get(topic, _DEFAULT_RATES.get(topic))


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
    connect_attempts: int = 0
    reconnects: int = 0
    dropped_by_topic: dict[str, int] = dataclasses.field(default_factory=dict)


_COUNTERS: Final = (
    "enqueued", "decimated", "published", "dropped_queue_full", "unrouted", "put_errors",
    "received", "callback_errors", "connect_attempts", "reconnects",
)  # fmt: skip


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


def _message(key_expr: str, raw: bytes) -> Message:
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


class Declaration:
    """A subscription, queryable or liveliness token of a :class:`Bus`.

    Declared as soon as the session exists (immediately if it is open); :meth:`undeclare`
    removes it. Zenoh re-declares it by itself on a router that restarts.
    """

    def __init__(self, bus: Bus, kind: str, key_expr: str, make: Callable[[Any], Any]) -> None:
        self.kind = kind
        self.key_expr = key_expr
        self._bus = bus
        self._make = make
        self._handle: Any = None
        self._undeclared = False

    @property
    def declared(self) -> bool:
        """True once Zenoh holds the declaration."""
        return self._handle is not None

    def _apply(self, session: zenoh.Session) -> None:
        if self._handle is None and not self._undeclared:
            self._handle = self._make(session)

    def undeclare(self) -> None:
        """Remove the declaration (idempotent)."""
        with self._bus._lock:
            self._undeclared = True
            if self in self._bus._declarations:
                self._bus._declarations.remove(self)
            handle, self._handle = self._handle, None
        if handle is not None:
            try:
                handle.undeclare()
            except zenoh.ZError:
                pass  # the session is already closed: nothing left to remove


_Mode = Literal["client", "peer"]


class Bus:
    """Zenoh session of one hilnav process, in the key space of one vehicle.

    Parameters
    ----------
    connect : str, optional
        Router (client mode) or peer (peer mode) endpoint(s), comma separated, e.g.
        ``"tcp/127.0.0.1:7447"``. None is only valid in peer mode: a standalone session
        (in-process publish/subscribe, no network).
    vehicle : str
        The ``<vehicle>`` key chunk of this process's topics.
    mode : {"client", "peer"}
        ``"client"`` (default): talk through a router; the session opens in the background and
        keeps retrying until the router answers, then Zenoh reconnects by itself after a router
        restart. ``"peer"``: connect to ``connect`` directly (Zenoh >= 1.9 routers no longer
        relay between two peers, so two peer-mode buses need a direct link: give one of them a
        ``listen`` endpoint and the other ``connect`` to it).
    listen : str, optional
        Peer mode only: endpoint(s) to listen on, comma separated.
    config : BusConfig, optional
        Rates, queue size, connect timeout.

    Notes
    -----
    Use as a context manager (or :meth:`open` / :meth:`close`). :meth:`publish` and the
    ``publish_*`` helpers never wait for the network: they may be called from the filter loop.
    Subscription callbacks run on Zenoh's threads: keep them short.
    """

    def __init__(
        self,
        connect: str | None = None,
        *,
        vehicle: str = "sim1",
        mode: _Mode = "client",
        listen: str | None = None,
        config: BusConfig | None = None,
    ) -> None:
        if mode not in ("client", "peer"):
            raise ValueError(f"mode must be 'client' or 'peer', got {mode!r}")
        self.vehicle = validate_vehicle(vehicle)
        self.mode: _Mode = mode
        self.connect = self._endpoints(connect)
        self.listen = self._endpoints(listen)
        if mode == "client" and not self.connect:
            raise ValueError("client mode needs a router endpoint to connect to (connect=...)")
        if mode == "client" and self.listen:
            raise ValueError("listen endpoints are for peer mode only")
        self.config = config or BusConfig()
        self._keys = {t: key(self.vehicle, t) for t in Topic}
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._queue: deque[tuple[Topic, str, bytes]] = deque()
        self._declarations: list[Declaration] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._session: zenoh.Session | None = None
        self._thread: threading.Thread | None = None
        self._first_attempt = threading.Event()
        self._stopping = False
        self._closed = False
        self._next_due_us: dict[Topic, int] = {}
        self._connected = False
        self._ever_connected = False
        self.last_error: str | None = None
        self._c = dict.fromkeys(_COUNTERS, 0)
        self._dropped_by_topic: dict[str, int] = {}

    @staticmethod
    def _endpoints(spec: str | None) -> list[str]:
        if spec is None:
            return []
        return [validate_endpoint(e.strip()) for e in spec.split(",") if e.strip()]

    # ------------------------------------------------------------------- lifecycle
    def __enter__(self) -> Self:
        return self.open()

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def open(self) -> Self:
        """Start the publisher thread and the first session-open attempt; return self.

        Waits for that first attempt only (at most ``config.connect_timeout_s``): with a router
        up, the bus is connected on return; without one, it keeps trying in the background.
        """
        with self._lock:
            if self._closed:
                raise RuntimeError("the bus was closed; create a new one")
            if self._thread is not None:
                return self
            self._thread = threading.Thread(
                target=self._run, name=f"hilnav-bus-{self.vehicle}", daemon=True
            )
            self._thread.start()
        self._first_attempt.wait(self.config.connect_timeout_s + 5.0)
        return self

    def close(self) -> None:
        """Flush what is queued (best effort), undeclare everything, close the session."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._stopping = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            declarations = list(self._declarations)
        for d in declarations:
            d.undeclare()
        for p in self._publishers.values():
            try:
                p.undeclare()
            except zenoh.ZError:
                pass
        self._publishers.clear()
        if self._session is not None:
            self._session.close()

    @property
    def session(self) -> zenoh.Session | None:
        """The Zenoh session once open (None while no router has answered yet)."""
        return self._session

    def wait_connected(self, timeout_s: float) -> bool:
        """Block until the session is open and connected, at most ``timeout_s``; return it."""
        deadline = time.monotonic() + timeout_s
        while True:
            if self._session is not None and self._check_connected():
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)

    def stats(self) -> BusStats:
        """Snapshot of the counters (the connection state is checked now)."""
        self._check_connected()
        with self._lock:
            return BusStats(
                connected=self._connected,
                queued=len(self._queue),
                dropped_by_topic=dict(self._dropped_by_topic),
                **self._c,
            )

    # ------------------------------------------------------------------- publishing
    def key(self, topic: Topic | str) -> str:
        """Key of ``topic`` for this bus's vehicle."""
        return key(self.vehicle, topic)

    def due(self, topic: Topic, time_us: int | None = None) -> bool:
        """Whether a message of ``topic`` at ``time_us`` would pass the rate limit (no side
        effect): call it before building an expensive payload."""
        rate = self.config.rate_hz(topic)
        if rate is None:
            return True
        return self._is_due(topic, self._rate_time_us(time_us), round(1e6 / rate))

    @staticmethod
    def _rate_time_us(time_us: int | None) -> int:
        return time.monotonic_ns() // 1000 if time_us is None else int(time_us)

    def _is_due(self, topic: Topic, t: int, period: int) -> bool:
        nxt = self._next_due_us.get(topic)
        # more than a period before the last message: a new run or a replay; start over
        return nxt is None or t >= nxt or t < nxt - 2 * period

    def _take_slot(self, topic: Topic, time_us: int | None) -> bool:
        rate = self.config.rate_hz(topic)
        if rate is None:
            return True
        period = round(1e6 / rate)
        t = self._rate_time_us(time_us)
        if not self._is_due(topic, t, period):
            return False
        nxt = self._next_due_us.get(topic)
        # on schedule: keep the phase, so a 200 Hz stream decimates to an even 25 Hz
        on_schedule = nxt is not None and nxt <= t < nxt + period
        self._next_due_us[topic] = (nxt + period) if on_schedule and nxt is not None else t + period
        return True

    def publish(self, topic: Topic, payload: Mapping[str, Any], *, force: bool = False) -> bool:
        """Queue ``payload`` on ``topic`` (never blocks on the network).

        Parameters
        ----------
        topic : Topic
            A published topic (not ``CONFIG`` / ``ALIVE``).
        payload : mapping
            JSON object; ``schema_version`` is added when missing; ``time_us`` (simulated time)
            drives the rate limit when present.
        force : bool
            Bypass the rate limit (e.g. the last status before shutdown).

        Returns
        -------
        bool
            True if queued, False if skipped by the rate limit.

        Raises
        ------
        ValueError
            Unknown topic or a payload that is not valid JSON (NaN, unsupported types).
        RuntimeError
            The bus is not open (use ``with Bus(...)``) or already closed.
        """
        if not isinstance(topic, Topic) or topic not in PUBLISHED_TOPICS:
            raise ValueError(
                f"cannot publish on {topic!r}; published topics: "
                f"{', '.join(t.value for t in PUBLISHED_TOPICS)}"
            )
        if self._thread is None or self._closed:
            raise RuntimeError("the bus is not open: use `with Bus(...) as bus:`")
        time_us = payload.get("time_us") if isinstance(payload, Mapping) else None
        rate_t = int(time_us) if isinstance(time_us, (int, np.integer)) else None
        with self._lock:
            due = force or self._take_slot(topic, rate_t)
        if not due:
            with self._lock:
                self._c["decimated"] += 1
            return False
        data = encode(payload)
        self._enqueue(topic, self._keys[topic], data)
        return True

    def _enqueue(self, topic: Topic, key_expr: str, data: bytes) -> None:
        with self._cond:
            if len(self._queue) >= self.config.queue_size:
                old_topic, _, _ = self._queue.popleft()
                self._c["dropped_queue_full"] += 1
                self._dropped_by_topic[old_topic.value] = (
                    self._dropped_by_topic.get(old_topic.value, 0) + 1
                )
            self._queue.append((topic, key_expr, data))
            self._c["enqueued"] += 1
            self._cond.notify()

    def _publish_built(self, topic: Topic, time_us: int | None, build: Callable[[], dict]) -> bool:
        """Rate-limit first, build the payload only when it will be sent."""
        if not self.due(topic, time_us):
            with self._lock:
                self._c["decimated"] += 1
            return False
        return self.publish(topic, build())

    def publish_truth(self, truth: Any) -> bool:
        """Publish a Truth-like object on ``sim/truth`` (see :func:`truth_payload`)."""
        return self._publish_built(
            Topic.TRUTH, getattr(truth, "time_us", None), lambda: truth_payload(truth)
        )

    def publish_sample(self, sample: Any) -> bool:
        """Publish a sensor sample on ``sensors/<kind>`` (see :func:`sample_payload`)."""
        for marker, topic in zip(_SAMPLE_MARKERS, _SAMPLE_TOPICS, strict=True):
            if hasattr(sample, marker):
                return self._publish_built(
                    topic, getattr(sample, "time_us", None), lambda: sample_payload(sample)[1]
                )
        raise ValueError(f"not a sensor sample: {type(sample).__name__}")

    def publish_estimate(self, est: Any) -> bool:
        """Publish a NavEstimate-like object on ``fusion/estimate``."""
        return self._publish_built(
            Topic.ESTIMATE, getattr(est, "time_us", None), lambda: estimate_payload(est)
        )

    def publish_status(
        self,
        est: Any,
        *,
        bridge: Any = None,
        links: Mapping[str, Any] | None = None,
        force: bool = False,
    ) -> bool:
        """Publish ``fusion/status`` with this bus's own counters in ``bus``."""
        if not force and not self.due(Topic.STATUS, getattr(est, "time_us", None)):
            with self._lock:
                self._c["decimated"] += 1
            return False
        payload = status_payload(est, bridge=bridge, links=links, bus=self.stats())
        return self.publish(Topic.STATUS, payload, force=force)

    def publish_error(self, est: Any, truth: Any) -> bool:
        """Publish ``fusion/error`` = estimate - truth (see :func:`error_payload`)."""
        return self._publish_built(
            Topic.ERROR, getattr(est, "time_us", None), lambda: error_payload(est, truth)
        )

    def publish_innovation(
        self,
        time_us: int,
        source: str,
        innovation: Any,
        *,
        S: Any = None,
        test_ratio: float | None = None,
        accepted: bool,
    ) -> bool:
        """Publish one aiding update on ``fusion/innovations``."""
        return self.publish(
            Topic.INNOVATIONS,
            innovation_payload(
                time_us, source, innovation, S=S, test_ratio=test_ratio, accepted=accepted
            ),
        )

    def publish_event(
        self, time_us: int, event: str, message: str = "", detail: Mapping[str, Any] | None = None
    ) -> bool:
        """Publish a scenario event on ``scenario/events``."""
        return self.publish(Topic.EVENTS, event_payload(time_us, event, message, detail))

    # ---------------------------------------------------------------- declarations
    def _declare(self, kind: str, key_expr: str, make: Callable[[Any], Any]) -> Declaration:
        if self._closed:
            raise RuntimeError("the bus is closed")
        d = Declaration(self, kind, key_expr, make)
        with self._lock:
            self._declarations.append(d)
            if self._session is not None:
                d._apply(self._session)
        return d

    def _wrap(self, callback: Callable[[Message], object]) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            with self._lock:
                self._c["received"] += 1
            try:
                callback(_message(str(sample.key_expr), sample.payload.to_bytes()))
            except Exception:  # a bad callback must not kill Zenoh's receive thread
                with self._lock:
                    self._c["callback_errors"] += 1

        return on_sample

    def subscribe(
        self,
        topic: Topic | Literal["**"],
        callback: Callable[[Message], object],
        *,
        vehicle: str | None = None,
    ) -> Declaration:
        """Call ``callback(Message)`` for every sample of ``topic`` (``"**"``: all topics).

        ``vehicle`` defaults to this bus's vehicle; ``"*"`` subscribes to every vehicle.
        """
        return self.subscribe_key(key(vehicle or self.vehicle, topic), callback)

    def subscribe_key(self, key_expr: str, callback: Callable[[Message], object]) -> Declaration:
        """Subscribe to any key expression (e.g. ``"hilnav/**"``)."""
        zenoh.KeyExpr(key_expr)  # raises on a malformed key expression, now rather than later
        on_sample = self._wrap(callback)
        return self._declare(
            "subscriber", key_expr, lambda s: s.declare_subscriber(key_expr, on_sample)
        )

    def subscribe_liveliness(
        self,
        callback: Callable[[str, bool], None],
        *,
        vehicle: str | None = None,
        history: bool = True,
    ) -> Declaration:
        """Call ``callback(key, alive)`` when a ``fusion/alive`` token appears or disappears.

        With ``history`` the tokens already present are reported on declaration.
        """
        key_expr = key(vehicle or self.vehicle, Topic.ALIVE)

        def on_sample(sample: zenoh.Sample) -> None:
            try:
                callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                with self._lock:
                    self._c["callback_errors"] += 1

        return self._declare(
            "liveliness-subscriber",
            key_expr,
            lambda s: s.liveliness().declare_subscriber(key_expr, on_sample, history=history),
        )

    def declare_liveliness(self) -> Declaration:
        """Declare this process's ``fusion/alive`` token (gone when the process or link dies)."""
        key_expr = self.key(Topic.ALIVE)
        return self._declare(
            "liveliness", key_expr, lambda s: s.liveliness().declare_token(key_expr)
        )

    def declare_config_queryable(self, getter: Callable[[], Any]) -> Declaration:
        """Answer queries on ``fusion/config`` with ``getter()`` (mapping or pydantic model).

        The reply is :func:`config_reply_payload`; an exception in ``getter`` becomes a Zenoh
        error reply with its message.
        """
        key_expr = self.key(Topic.CONFIG)
        encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(SCHEMAS[Topic.CONFIG]["title"])

        def on_query(query: zenoh.Query) -> None:
            try:
                data = encode(config_reply_payload(self.vehicle, getter()))
            except Exception as exc:
                query.reply_err(f"{type(exc).__name__}: {exc}")
                return
            query.reply(key_expr, data, encoding=encoding)

        return self._declare(
            "queryable", key_expr, lambda s: s.declare_queryable(key_expr, on_query)
        )

    def query_config(self, *, vehicle: str | None = None, timeout_s: float = 2.0) -> dict | None:
        """Ask ``fusion/config`` of ``vehicle``; the decoded reply, or None (no answer)."""
        session = self._session
        if session is None:
            return None
        for reply in session.get(key(vehicle or self.vehicle, Topic.CONFIG), timeout=timeout_s):
            if reply.ok is not None:
                decoded = json.loads(reply.ok.payload.to_bytes())
                if isinstance(decoded, dict):
                    return decoded
        return None

    def fusion_alive(self, *, vehicle: str | None = None, timeout_s: float = 1.0) -> bool:
        """Whether a ``fusion/alive`` token of ``vehicle`` exists now."""
        session = self._session
        if session is None:
            return False
        replies = session.liveliness().get(
            key(vehicle or self.vehicle, Topic.ALIVE), timeout=timeout_s
        )
        return any(r.ok is not None for r in replies)

    # --------------------------------------------------------------- worker thread
    def _zenoh_config(self) -> zenoh.Config:
        timeout_ms = int(self.config.connect_timeout_s * 1000)
        cfg: dict[str, Any] = {
            "mode": self.mode,
            "connect": {
                "endpoints": self.connect,
                "timeout_ms": timeout_ms,
                # peer mode: connect in the background instead of failing the open
                "exit_on_failure": False,
                "retry": {"period_init_ms": 50, "period_max_ms": 1000, "period_increase_factor": 2},
            },
            # explicit endpoints only: no multicast discovery on the LAN
            "scouting": {"multicast": {"enabled": False}},
        }
        if self.mode == "peer":
            cfg["listen"] = {"endpoints": self.listen}
            cfg["scouting"]["delay"] = 50 if self.connect else 0
        return zenoh.Config.from_json5(json.dumps(cfg))

    def _try_open(self) -> None:
        try:
            session = zenoh.open(self._zenoh_config())
        except zenoh.ZError as exc:
            with self._lock:
                self._c["connect_attempts"] += 1
                self.last_error = str(exc)
            return
        with self._lock:
            self._session = session
            for d in self._declarations:
                try:
                    d._apply(session)
                except Exception as exc:  # a bad declaration must not stop the others
                    self.last_error = f"declaring {d.kind} {d.key_expr}: {exc}"
        self._check_connected()

    def _check_connected(self) -> bool:
        session = self._session
        if session is None or session.is_closed():
            return False
        try:
            info = session.info
            up = bool(info.routers_zid()) or (self.mode == "peer" and bool(info.peers_zid()))
        except zenoh.ZError:
            up = False
        if self.mode == "peer" and not self.connect:
            up = True  # standalone: nothing to connect to
        with self._lock:
            if up and not self._connected and self._ever_connected:
                self._c["reconnects"] += 1
            self._ever_connected |= up
            self._connected = up
        return up

    def _publisher(self, session: zenoh.Session, topic: Topic, key_expr: str) -> zenoh.Publisher:
        pub = self._publishers.get(key_expr)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key_expr)
                if pub is None:
                    pub = session.declare_publisher(
                        key_expr,
                        encoding=zenoh.Encoding.APPLICATION_JSON.with_schema(
                            SCHEMAS[topic]["title"]
                        ),
                        # a slow link must never stall the publisher thread (and so the queue)
                        congestion_control=zenoh.CongestionControl.DROP,
                    )
                    self._publishers[key_expr] = pub
        return pub

    def has_subscribers(self, topic: Topic) -> bool:
        """Whether a subscriber somewhere currently matches ``topic`` of this vehicle.

        False while the session is not open. Zenoh does not send samples nobody subscribes
        to, so a process that must not lose the first messages waits for this.
        """
        session = self._session
        if session is None or self._closed or topic not in PUBLISHED_TOPICS:
            return False
        try:
            status: Any = self._publisher(session, topic, self._keys[topic]).matching_status
        except zenoh.ZError:
            return False
        # the stub says bool, the runtime returns a MatchingStatus with `.matching`
        return bool(getattr(status, "matching", status))

    def _send(self, session: zenoh.Session, batch: Sequence[tuple[Topic, str, bytes]]) -> None:
        sent = errors = 0
        for topic, key_expr, data in batch:
            try:
                self._publisher(session, topic, key_expr).put(data)
                sent += 1
            except zenoh.ZError as exc:
                errors += 1
                self.last_error = str(exc)
        with self._lock:
            self._c["published"] += sent
            self._c["put_errors"] += errors
            if not self._connected:
                self._c["unrouted"] += sent

    def _run(self) -> None:
        check_every_s = 0.25
        next_check = 0.0
        while True:
            if self._session is None:
                with self._lock:
                    if self._stopping:
                        break
                self._try_open()
                self._first_attempt.set()
                if self._session is None:
                    with self._cond:
                        self._cond.wait_for(lambda: self._stopping, timeout=self.config.retry_s)
                    continue
            with self._cond:
                self._cond.wait_for(lambda: self._queue or self._stopping, timeout=check_every_s)
                batch, self._queue = self._queue, deque()
                stopping = self._stopping
            now = time.monotonic()
            if now >= next_check:
                self._check_connected()
                next_check = now + check_every_s
            if batch:
                try:
                    self._send(self._session, batch)
                except Exception as exc:  # keep the thread alive: it is the only drain
                    with self._lock:
                        self._c["put_errors"] += len(batch)
                        self.last_error = f"{type(exc).__name__}: {exc}"
            if stopping:
                break
        self._first_attempt.set()


# ------------------------------------------------------------------------ health-check CLI
def check_main(
    *,
    connect: str,
    vehicle: str = "sim1",
    alive: bool = False,
    keys: Sequence[str] = (),
    timeout_s: float = 5.0,
) -> int:
    """Health check for containers: 0 if the router answers (and the fusion token exists /
    a sample arrives on every key), else 1.

    Parameters
    ----------
    connect : str
        Router endpoint.
    vehicle : str
        Vehicle whose ``fusion/alive`` token ``alive`` asks for.
    alive : bool
        Require the fusion service's liveliness token.
    keys : sequence of str
        Key expressions on which a sample must arrive within ``timeout_s``.
    timeout_s : float
        Overall time budget, s.
    """
    deadline = time.monotonic() + timeout_s
    seen: dict[str, threading.Event] = {k: threading.Event() for k in keys}
    config = BusConfig(connect_timeout_s=min(max(timeout_s, 0.1), 60.0))
    with Bus(connect, vehicle=vehicle, config=config) as bus:
        for k, ev in seen.items():

            def on_sample(_msg: Message, ev: threading.Event = ev) -> None:
                ev.set()

            bus.subscribe_key(k, on_sample)
        if not bus.wait_connected(max(deadline - time.monotonic(), 0.0)):
            print(f"no router at {connect}", file=sys.stderr)
            return 1
        if alive and not bus.fusion_alive(timeout_s=max(deadline - time.monotonic(), 0.1)):
            print(f"no {bus.key(Topic.ALIVE)} token", file=sys.stderr)
            return 1
        for k, ev in seen.items():
            if not ev.wait(max(deadline - time.monotonic(), 0.0)):
                print(f"nothing on {k} within {timeout_s} s", file=sys.stderr)
                return 1
    return 0


def _arg_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m hil.bus", description="hilnav Zenoh bus utilities"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    check = sub.add_parser("check", help="health check: router reachable (+ token / samples)")
    check.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/zenohd:7447")
    check.add_argument("--vehicle", default="sim1")
    check.add_argument("--alive", action="store_true", help="require the fusion/alive token")
    check.add_argument(
        "--key", action="append", default=[], help="key on which a sample must arrive"
    )
    check.add_argument("--timeout", type=float, default=5.0, help="seconds")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m hil.bus check ...`` (container health checks)."""
    args = _arg_parser().parse_args(argv)
    try:
        return check_main(
            connect=args.connect,
            vehicle=args.vehicle,
            alive=args.alive,
            keys=args.key,
            timeout_s=args.timeout,
        )
    except (ValueError, pydantic.ValidationError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
