"""Payload builders: SI samples, truth and estimates -> the JSON objects the bus publishes.

Each builder returns the payload of one topic (schemas in :mod:`hil.bus.schemas`);
:func:`encode` turns a payload into the bytes on the wire.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from enum import Enum
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from fusion.earth import ned_offset_m
from fusion.rotations import quat_conjugate, quat_multiply
from hil.bus.keys import Topic
from hil.bus.schemas import EVENT_SEVERITIES, SCHEMA_VERSION

if TYPE_CHECKING:
    from hil.bus.stats import BusStats

__all__ = [
    "config_reply_payload",
    "encode",
    "error_payload",
    "estimate_payload",
    "event_payload",
    "fusion_event_payload",
    "innovation_payload",
    "sample_payload",
    "sample_topic",
    "status_payload",
    "truth_payload",
]


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


def _floats(a: Any) -> list[float]:
    """``np.asarray(a, float64).reshape(-1).tolist()``, straight from a 1-D float64 array (the
    filter's vectors) without the conversions: the estimate is built on the live path, where
    each numpy call costs tens of microseconds (docs/results.md, "Live latency")."""
    if type(a) is np.ndarray and a.ndim == 1 and a.dtype == np.float64:
        return a.tolist()
    return np.asarray(a, dtype=np.float64).reshape(-1).tolist()


def _vec(a: Any, n: int | None, name: str, *, finite: bool = True) -> list[Any]:
    try:
        v = _floats(a)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric vector, got {a!r}") from None
    if n is not None and len(v) != n:
        raise ValueError(f"{name} must have {n} elements, got shape {np.shape(a)}")
    # element-wise in Python: faster than numpy on 3- and 4-vectors
    if finite:
        if not all(map(math.isfinite, v)):
            raise ValueError(f"{name} must be finite, got {v}")
        return v
    return [x if math.isfinite(x) else None for x in v]


def _euler_deg(q: Sequence[float]) -> list[float]:
    """3-2-1 (roll, pitch, yaw) of ``q_nb`` in degrees, in scalar math on one quaternion."""
    # not fusion.rotations.quat_to_euler: its DCM-based form rounds differently, so the
    # published angles would change in their last bits
    w, x, y, z = q
    n2 = w * w + x * x + y * y + z * z
    roll = math.atan2(2.0 * (w * x + y * z), n2 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x) / n2)))
    yaw = math.atan2(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z))
    return [math.degrees(roll), math.degrees(pitch), math.degrees(yaw)]


def _angle_between_deg(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Rotation angle of ``q1 * conj(q2)``, deg (atan2 form: accurate for tiny angles)."""
    w, x, y, z = quat_multiply(q1, quat_conjugate(q2)).tolist()
    return math.degrees(2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w)))


def _opt_vec(obj: Any, name: str, n: int, *, scale: float = 1.0) -> list[Any] | None:
    a = getattr(obj, name, None)
    if a is None:
        return None
    if scale != 1.0:  # x * 1.0 == x for every float: skip the array it would make
        a = np.asarray(a, dtype=np.float64) * scale
    return _vec(a, n, name, finite=False)


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


_SAMPLE_MARKERS: Final = (
    "angular_rate_b_rps", "eph_m", "pressure_pa", "field_b_tesla", "diff_pressure_pa"
)
_SAMPLE_TOPICS: Final = (Topic.IMU, Topic.GNSS, Topic.BARO, Topic.MAG, Topic.AIRSPEED)


def sample_topic(sample: Any) -> Topic:
    """Topic of a sensor sample, recognised by its fields as in :func:`sample_payload`.

    Raises ``ValueError`` for an object that is not a sensor sample.
    """
    for marker, topic in zip(_SAMPLE_MARKERS, _SAMPLE_TOPICS, strict=True):
        if hasattr(sample, marker):
            return topic
    raise ValueError(f"not a sensor sample: {type(sample).__name__}")


def sample_payload(sample: Any) -> tuple[Topic, dict[str, Any]]:
    """Topic and payload of a sensor sample (:mod:`sim.samples` or anything shaped like one).

    The kind is recognised by its fields: ``angular_rate_b_rps`` (IMU), ``eph_m`` (GNSS),
    ``pressure_pa`` (baro), ``field_b_tesla`` (mag), ``diff_pressure_pa`` (airspeed).
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
    if hasattr(sample, "diff_pressure_pa"):
        return Topic.AIRSPEED, base | {
            "diff_pressure_pa": _fin(sample.diff_pressure_pa, "airspeed.diff_pressure_pa"),
            "temperature_k": _opt_num(sample, "temperature_k"),
            "sensor_id": _sensor_id(sample),
        }
    raise ValueError(f"not a sensor sample: {type(sample).__name__}")


def _sigmas(p_diag: Any) -> tuple[list[Any] | None, list[Any] | None, list[Any] | None]:
    """1-sigma position (m), velocity (m/s), tilt (deg) from the error-state variances.

    Every layout of ``fusion.error_model`` starts with position N/E/D (m^2), velocity (m/s)^2
    and attitude (rad^2): the first nine entries are read, the rest (biases, scale factors) is
    the filter's business. Negative variances read as 0; NaN and inf give None.
    """
    if p_diag is None:
        return None, None, None
    p = _floats(p_diag)
    if len(p) < 9:
        raise ValueError(f"estimate.P_diag must have at least 9 entries, got {len(p)}")
    # scalar math, the same IEEE operations as np.sqrt(np.maximum(p, 0)) and np.degrees;
    # np.maximum(x, 0) is x when x > 0 or NaN, else 0.0 (so -0.0 becomes 0.0)
    sd = [math.sqrt(x) if x > 0.0 or x != x else 0.0 for x in p[:9]]
    att = [math.degrees(x) for x in sd[6:9]]
    return (
        [x if math.isfinite(x) else None for x in sd[0:3]],
        [x if math.isfinite(x) else None for x in sd[3:6]],
        [x if math.isfinite(x) else None for x in att],
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
    thermal: Any = None,
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
    thermal : dataclass or mapping, optional
        The IMU thermal strategy's state (:class:`fusion.thermal.link.ThermalStatus`);
        ``null`` when none runs.
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
        "air_data": None if getattr(est, "air_data", None) is None else _plain(est.air_data),
        "alignment": (None if getattr(est, "alignment", None) is None
                      else _plain(est.alignment)),
        "thermal": None if thermal is None else _plain(thermal),
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


def fusion_event_payload(
    time_us: int, event: str, severity: str, message: str = "",
    detail: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Payload of ``fusion/events`` (:class:`hil.nav_events.NavEvent`'s fields)."""
    if severity not in EVENT_SEVERITIES:
        raise ValueError(f"severity must be one of {', '.join(EVENT_SEVERITIES)}, got {severity!r}")
    return {**event_payload(time_us, event, message, detail), "severity": severity}


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
