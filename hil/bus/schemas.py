"""JSON Schemas of the bus payloads, one per topic.

Payloads are UTF-8 JSON objects. Every payload carries ``schema_version`` (:data:`SCHEMA_VERSION`)
and, where it has a time, ``time_us`` in *simulated* time. Field names carry units
(``lat_deg``, ``alt_msl_m``, ``v_ned_mps``); vectors are JSON arrays in the frame their name
says; numbers that are not finite (a test ratio before the first test, the time since GNSS before
the first fix) are ``null``. :data:`SCHEMAS` holds the JSON Schema of every topic (MCAP channels
carry it, so Foxglove / PlotJuggler can decode a recording).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

from hil.bus.keys import Topic

__all__ = ["EVENT_SEVERITIES", "SCHEMAS", "SCHEMA_VERSION"]

SCHEMA_VERSION: Final = 1
"""Version of every payload schema below; bump it when a field changes meaning or disappears."""


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


EVENT_SEVERITIES: Final = ("emergency", "alert", "critical", "error", "warning", "notice", "info",
                           "debug")
"""``fusion/events`` severities: MAVLink's ``MAV_SEVERITY`` names, index = value (0 .. 7)."""

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
    Topic.AIRSPEED: _schema(
        Topic.AIRSPEED,
        "Airspeed (pitot-static differential pressure) sample.",
        {
            "time_us": _TIME,
            "diff_pressure_pa": _d(_N, "impact pressure (total minus static), Pa"),
            "temperature_k": _d(_N0, "sensor temperature, K"),
            "sensor_id": _d(_I, "sensor instance"),
        },
        optional=("temperature_k",),
    ),
    Topic.ESTIMATE: _schema(
        Topic.ESTIMATE,
        "Navigation solution of the fusion filter.",
        {
            "time_us": _TIME,
            "mode": _d(_S, "initializing | gnss | bridging | dead-reckoning | free-inertial"),
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
        "bridging (GMDH) health, link and bus counters, alignment.",
        {
            "time_us": _TIME,
            "mode": _d(_S, "initializing | gnss | bridging | dead-reckoning | free-inertial"),
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
            "air_data": _d(
                {"type": ["object", "null"]},
                "air data: state (off | waiting | fusing | blocked | synthetic | stale), mean "
                "wind N/E m/s, airspeed scale, last TAS m/s, pitot fault, gust N/E m/s, "
                "turbulence_mps (gust sigma in use), turbulence_source (default | estimated | "
                "turbulent | saturated), turbulence_estimate_mps, flags (comma-separated: "
                "pitot_implausible, wind_implausible, turbulence_saturated)",
            ),
            "alignment": _d(
                {"type": ["object", "null"]},
                "alignment: method (in_flight | in_flight_mag | static_mag | "
                "static_gyrocompass | given) and at_rest (zero-velocity and zero-angular-rate "
                "updates running: the fine alignment at rest)",
            ),
            "thermal": _d(
                {"type": ["object", "null"]},
                "IMU thermal strategy: mode (off | blind | states | cal), temperature_k (last "
                "good die temperature), temperature_good, rate_k_per_s, the temperature "
                "coefficient estimates (states); null when none runs",
            ),
        },
        optional=("time_since_gnss_s", "state_layout", "bridge", "links", "bus", "air_data",
                  "alignment", "thermal"),
    ),
    Topic.INNOVATIONS: _schema(
        Topic.INNOVATIONS,
        "One aiding update: innovation, its predicted sigma, the gate test ratio.",
        {
            "time_us": _TIME,
            "source": _d(_S, "aiding source: gnss_pos, gnss_vel, baro_hgt, mag_hdg, "
                         "bridge_pos, bridge_vel, airspeed, sideslip, zero_vel, zero_rate"),
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
    Topic.FUSION_EVENTS: _schema(
        Topic.FUSION_EVENTS,
        "Navigation event: a mode change or a fault the fusion detected (hil.nav_events).",
        {
            "time_us": _TIME,
            "event": _d(_S, "kind: mode, gnss_rejected, gnss_rejections_persist, "
                            "gnss_gate_clear, spoof_suspected, gnss_reset, "
                            "gnss_reset_refused, pitot_dropped, pitot_recovered, baro_frozen, "
                            "baro_reset, imu_invalid, filter_rebase"),
            "severity": _d({"type": "string", "enum": list(EVENT_SEVERITIES)},
                           "MAVLink MAV_SEVERITY name, lower case"),
            "message": _d(_S, "human-readable text (the STATUSTEXT sent)"),
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
