"""Bus samples -> Foxglove's well-known messages (map, 3D, log panels), for MCAP and WebSocket.

Foxglove's Map panel reads ``foxglove.LocationFix``, its 3D panel ``foxglove.FrameTransform``
and its Log panel ``foxglove.Log``; our own ``hilnav.*`` JSON channels stay beside them.
:func:`foxglove_messages` turns one received bus sample into the Foxglove messages it implies
(encoded with the official protobuf definitions of the ``foxglove-sdk`` package):

==========================  ======================================  =========================
bus topic                   Foxglove channel                        schema
==========================  ======================================  =========================
``fusion/estimate``         ``/foxglove/estimate/fix``, ``/tf``     LocationFix (covariance
                                                                    from ``pos_sigma_ned_m``),
                                                                    FrameTransform
                                                                    ``world -> base_link``
``sim/truth``               ``/foxglove/truth/fix``, ``/tf``        LocationFix, FrameTransform
                                                                    ``world -> truth_base_link``
``sensors/gnss``            ``/foxglove/gnss/fix``                  LocationFix (``eph_m``,
                                                                    ``epv_m`` as approximated
                                                                    covariance)
``scenario/events``,        ``/foxglove/events``                    Log
``fusion/events``
==========================  ======================================  =========================

Time: every message's time is the simulated time of its payload, ``time_us`` mapped to
``SIM_EPOCH_NS + 1000 * time_us`` (:func:`sim_time_ns`; the simulation starts at the Unix epoch,
so Foxglove shows 1970-01-01 00:00:00 + simulated seconds). ``world`` is a local ENU frame whose
origin is the first estimate (or truth) position the converter sees; ``base_link`` is the body
frame in the ROS convention (x forward, y left, z up). Altitudes are MSL, as on the bus
(Foxglove's map does not use altitude).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from foxglove.messages import (
    FrameTransform,
    LocationFix,
    LocationFixPositionCovarianceType,
    Log,
    LogLevel,
    Quaternion,
    Timestamp,
    Vector3,
)

from fusion.earth import ned_offset_m
from fusion.rotations import quat_multiply
from hil.bus import Message, Topic

__all__ = [
    "EVENT_TOPICS",
    "FIX_TOPICS",
    "LOG_TOPIC",
    "SIM_EPOCH_NS",
    "TF_TOPIC",
    "FoxgloveConverter",
    "foxglove_schema",
    "sim_time_ns",
]

SIM_EPOCH_NS: Final = 0
"""Unix time (ns) of simulated time zero: log times are ``SIM_EPOCH_NS + 1000 * time_us``."""

FIX_TOPICS: Final = {
    Topic.ESTIMATE: "/foxglove/estimate/fix",
    Topic.TRUTH: "/foxglove/truth/fix",
    Topic.GNSS: "/foxglove/gnss/fix",
}
TF_TOPIC: Final = "/tf"
LOG_TOPIC: Final = "/foxglove/events"
EVENT_TOPICS: Final = ("scenario/events", "fusion/events")
"""Key suffixes whose samples become ``foxglove.Log`` (``fusion/events`` by suffix: the key
space may not name it yet)."""

_CHILD_FRAME: Final = {Topic.ESTIMATE: "base_link", Topic.TRUTH: "truth_base_link"}
_WORLD: Final = "world"
# q_enu_ned (NED -> ENU axes swap) and q_frd_flu (180 deg about x), scalar first
_Q_ENU_NED: Final = (0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0)
_Q_FRD_FLU: Final = (0.0, 1.0, 0.0, 0.0)
_LEVELS: Final = {
    "debug": LogLevel.Debug, "info": LogLevel.Info, "notice": LogLevel.Info,
    "warning": LogLevel.Warning, "warn": LogLevel.Warning, "error": LogLevel.Error,
    "critical": LogLevel.Fatal, "alert": LogLevel.Fatal, "emergency": LogLevel.Fatal,
    "fatal": LogLevel.Fatal,
}

FoxgloveMessage = LocationFix | FrameTransform | Log


def sim_time_ns(time_us: int) -> int:
    """Epoch-based nanosecond timestamp of a payload's simulated ``time_us``."""
    return SIM_EPOCH_NS + 1000 * int(time_us)


def foxglove_schema(message: FoxgloveMessage) -> tuple[str, str, bytes]:
    """Name, encoding (``protobuf``) and FileDescriptorSet bytes of a message's schema."""
    schema = type(message).get_schema()
    return schema.name, schema.encoding, bytes(schema.data)


def _timestamp(t_ns: int) -> Timestamp:
    return Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)


def _finite(x: Any) -> float | None:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return None
    f = float(x)
    return f if math.isfinite(f) else None


def _vec3(x: Any) -> list[float] | None:
    if not isinstance(x, list) or len(x) != 3:
        return None
    v = [_finite(c) for c in x]
    return None if None in v else [c for c in v if c is not None]


class FoxgloveConverter:
    """Turn bus samples into ``(channel topic, Foxglove message, log_time_ns)`` (one per call site).

    Stateful only for the local ``world`` origin (first estimate or truth position) and the
    last simulated time (the time of an event payload without ``time_us``).
    """

    def __init__(self) -> None:
        self._origin: tuple[float, float, float] | None = None
        self.last_time_ns: int | None = None

    def log_time_ns(self, payload: Mapping[str, Any] | None) -> int | None:
        """Simulated time of a payload (``time_us``), remembered; None if it has none yet."""
        t = None if payload is None else payload.get("time_us")
        if isinstance(t, int) and not isinstance(t, bool):
            self.last_time_ns = sim_time_ns(t)
        return self.last_time_ns

    def messages(self, msg: Message) -> list[tuple[str, FoxgloveMessage, int]]:
        """The Foxglove messages implied by one bus sample (empty for most topics / bad data)."""
        p = msg.payload
        if p is None:
            return []
        t_ns = self.log_time_ns(p)
        suffix = msg.key.split("/", 2)[2] if msg.key.count("/") >= 2 else ""
        if suffix in EVENT_TOPICS:
            return [] if t_ns is None else [(LOG_TOPIC, self._log(p, suffix, t_ns), t_ns)]
        if t_ns is None or msg.topic not in FIX_TOPICS:
            return []
        fix = self._fix(msg.topic, p, t_ns)
        if fix is None:
            return []
        out: list[tuple[str, FoxgloveMessage, int]] = [(FIX_TOPICS[msg.topic], fix, t_ns)]
        if msg.topic in _CHILD_FRAME:
            tf = self._transform(msg.topic, p, t_ns)
            if tf is not None:
                out.append((TF_TOPIC, tf, t_ns))
        return out

    def _fix(self, topic: Topic, p: Mapping[str, Any], t_ns: int) -> LocationFix | None:
        lat, lon, alt = (_finite(p.get(k)) for k in ("lat_deg", "lon_deg", "alt_msl_m"))
        if lat is None or lon is None or alt is None:
            return None
        cov = [0.0] * 9
        kind = LocationFixPositionCovarianceType.Unknown
        if topic is Topic.ESTIMATE:
            sd = _vec3(p.get("pos_sigma_ned_m"))
            if sd is not None:  # NED sigmas -> ENU diagonal
                cov[0], cov[4], cov[8] = sd[1] ** 2, sd[0] ** 2, sd[2] ** 2
                kind = LocationFixPositionCovarianceType.DiagonalKnown
        elif topic is Topic.GNSS:
            eph, epv = _finite(p.get("eph_m")), _finite(p.get("epv_m"))
            if eph is not None and epv is not None:
                cov[0] = cov[4] = eph**2
                cov[8] = epv**2
                kind = LocationFixPositionCovarianceType.Approximated
        v = _vec3(p.get("v_ned_mps"))
        yaw = _finite(p.get("yaw_deg"))
        return LocationFix(
            timestamp=_timestamp(t_ns), frame_id=_CHILD_FRAME.get(topic, "gnss"),
            latitude=lat, longitude=lon, altitude=alt, position_covariance=cov,
            position_covariance_type=kind,
            heading=None if yaw is None else math.radians(yaw) % (2.0 * math.pi),
            velocity=None if v is None else Vector3(x=v[1], y=v[0], z=-v[2]),
        )

    def _transform(self, topic: Topic, p: Mapping[str, Any], t_ns: int) -> FrameTransform | None:
        q = p.get("q_nb")
        if not isinstance(q, list) or len(q) != 4:
            return None
        qs = [f for f in (_finite(c) for c in q) if f is not None]
        if len(qs) != 4 or not sum(c * c for c in qs) > 0.5:
            return None
        lat, lon, alt = (float(p[k]) for k in ("lat_deg", "lon_deg", "alt_msl_m"))
        here = (math.radians(lat), math.radians(lon), alt)
        if self._origin is None:
            self._origin = here
        dn, de, dd = ned_offset_m(*here, *self._origin)
        w, x, y, z = quat_multiply(quat_multiply(_Q_ENU_NED, qs), _Q_FRD_FLU).tolist()
        return FrameTransform(
            timestamp=_timestamp(t_ns), parent_frame_id=_WORLD, child_frame_id=_CHILD_FRAME[topic],
            translation=Vector3(x=de, y=dn, z=-dd), rotation=Quaternion(x=x, y=y, z=z, w=w),
        )

    @staticmethod
    def _log(p: Mapping[str, Any], suffix: str, t_ns: int) -> Log:
        name = p.get("event", p.get("name", p.get("type", "event")))
        text = p.get("message", p.get("text", ""))
        detail = p.get("detail")
        message = f"{name}: {text}" if text else str(name)
        if isinstance(detail, Mapping) and detail:
            message += " " + ", ".join(f"{k}={v}" for k, v in detail.items())
        level = p.get("level", p.get("severity", "info"))
        return Log(
            timestamp=_timestamp(t_ns),
            level=_LEVELS.get(str(level).lower(), LogLevel.Info),
            message=message, name=suffix, file="", line=0,
        )
