"""A scenario's GNSS windows and fault events as ArduPilot SITL ``SIM_*`` parameter changes.

ArduPilot SITL simulates its own GPS (from the position of the JSON physics backend), its own
barometer (from the altitude) and compass (from the attitude), so hilnav's faulted HIL_GPS /
HIL_SENSOR never reach it: the denial has to be set in ArduPilot's simulated sensors through
their parameters, at the simulated time of each event (``hil.autopilot.ardupilot`` sends them
as PARAM_SET). Names are those of ArduPilot 4.5+ (``libraries/SITL/SIM_GPS.cpp``: the
``SIM_GPS1_*`` group; ArduPilot <= 4.4 called them ``SIM_GPS_DISABLE`` (inverted),
``SIM_GPS_GLITCH_X/Y/Z``, ``SIM_GPS_DELAY``, ``SIM_GPS_HZ``).

Mapping (ArduPilot's defaults in brackets; at the start of a flight every parameter a
scenario touches is set to its default, so a previous run leaves nothing behind)

    ======================  ==================================================================
    GNSS-off window,        ``SIM_GPS1_ENABLE`` = 0 (no lock) while any is active [1]
    gnss_outage
    gnss_jamming            ``SIM_GPS1_JAM`` = 1 while active [0]. ArduPilot's own jamming
                            model (1-6 s without lock, then random satellites, lock, position
                            and velocity): ``blackout_s``, ``flap_*`` and ``garbage_*`` do not
                            map
    gnss_spoof_hijack       ``SIM_GPS1_GLTCH_X/Y/Z`` = the NED offset as latitude deg, longitude
                            deg (at the origin's latitude, ArduPilot's ``LATLON_TO_M``) and
                            altitude m (up) [0]
    gnss_spoof_drift        the same, updated every ``ramp_step_s`` of simulated time with the
                            offset reached; ``consistent_velocity`` does not map (ArduPilot's
                            glitch moves the position only)
    gnss_delay              ``SIM_GPS1_LAG_MS`` = 100 + extra latency [100]
    gnss_rate               ``SIM_GPS1_HZ`` = the rate rounded, >= 1 Hz (an integer) [5]
    gnss_degradation        ``SIM_GPS1_ACC`` (reported accuracy, m) x the factor, ramped [0.3].
                            Partial: ArduPilot's simulated fix has no position error to scale
    baro_glitch             ``SIM_BARO_GLITCH`` (altitude offset, m) = the altitude change of
                            the pressure offset at the origin's ISA pressure [0]
    baro_drift,             ``SIM_BARO_GLITCH`` ramped every ``ramp_step_s``; a weather front
    weather_front           keeps its final offset after it ends
    ======================  ==================================================================

    Overlapping events add up (offsets, biases) or combine (ENABLE: any outage; ACC: the
    largest factor; LAG_MS: the largest latency; HZ: the lowest rate).

Through the JSON line, not parameters (:data:`JSON_EVENTS`): the IMU events and the pitot
blockage / drift (ArduPilot's IMU and airspeed are the JSON ``imu`` and ``airspeed``, which
hil.autopilot.ardupilot fills from the faulted samples hilnav's fusion gets).

Not mapped (:func:`ardupilot_unmapped` says why): baro_freeze, mag_anomaly,
airspeed_failure.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from sim.atmosphere import geopotential_from_geometric, isa_pressure_pa, pressure_altitude_m
from sim.faults.events import (
    BaroDrift,
    BaroGlitch,
    FaultEvent,
    GnssDegradation,
    GnssDelay,
    GnssJamming,
    GnssOutage,
    GnssRate,
    GnssSpoofDrift,
    GnssSpoofHijack,
    WeatherFront,
    event_type_name,
)

__all__ = [
    "ARDUPILOT_DEFAULTS",
    "JSON_EVENTS",
    "LATLON_TO_M",
    "ParamSet",
    "ardupilot_param_schedule",
    "ardupilot_unmapped",
]

LATLON_TO_M = 0.011131884502145034
"""Metres per 1e-7 degree of latitude: ArduPilot's ``LATLON_TO_M`` (``AP_Common/Location``),
the scale of its flat-earth offsets (GPS glitches here, the JSON position in
:mod:`hil.autopilot.sitl_json`)."""

ARDUPILOT_DEFAULTS: dict[str, float] = {
    "SIM_GPS1_ENABLE": 1.0,
    "SIM_GPS1_JAM": 0.0,
    "SIM_GPS1_GLTCH_X": 0.0,
    "SIM_GPS1_GLTCH_Y": 0.0,
    "SIM_GPS1_GLTCH_Z": 0.0,
    "SIM_GPS1_LAG_MS": 100.0,
    "SIM_GPS1_HZ": 5.0,
    "SIM_GPS1_ACC": 0.3,
    "SIM_BARO_GLITCH": 0.0,
}
"""ArduPilot's defaults of every parameter this module sets."""

_IN_JSON = "reaches ArduPilot through the JSON state line, not a parameter"
_NOT_MAPPED = {
    "baro_freeze": "ArduPilot SITL has no frozen-barometer parameter",
    "mag_anomaly": "ArduPilot computes its compass from the attitude; no field offset mapped",
    "airspeed_failure": "the JSON airspeed cannot be absent: ArduPilot keeps reading the last "
                        "pitot airspeed (a stuck sensor, not a failed one)",
}
"""Events that do not reach ArduPilot as they are, and why."""
JSON_EVENTS = frozenset({"imu_bias_step", "imu_stuck", "imu_saturation", "pitot_blockage",
                         "pitot_drift"})
"""Events ArduPilot sees through the JSON state line (its ``imu`` is the faulted IMU sample,
its ``airspeed`` the faulted pitot's), so no parameter is set for them."""


@dataclass(frozen=True, slots=True)
class ParamSet:
    """Set ``name`` to ``value`` at ``time_s`` of simulated flight time."""

    time_s: float
    name: str
    value: float


def ardupilot_unmapped(event: FaultEvent) -> str | None:
    """Why ``event`` does not reach ArduPilot, or None when it does (by a parameter, as the
    module docstring says, or through the JSON line: :data:`JSON_EVENTS`)."""
    return _NOT_MAPPED.get(event_type_name(event))


# A contribution to one parameter: (name, start_s, end_s or None, value(t) -> float | None).
# value() returns None where the contribution does not apply.
_Term = tuple[str, float, float | None, Callable[[float], float]]


def ardupilot_param_schedule(
    events: Sequence[FaultEvent],
    gnss_off: Sequence[tuple[float, float]] = (),
    *,
    origin_lat_rad: float,
    origin_alt_msl_m: float,
    duration_s: float,
    ramp_step_s: float = 1.0,
) -> list[ParamSet]:
    """The parameter changes that play ``events`` and the GNSS-off windows
    (``(start_s, duration_s)``) in ArduPilot SITL, in time order.

    Parameters
    ----------
    events : sequence of FaultEvent
        The scenario's fault timeline (unmapped ones are skipped: :func:`ardupilot_unmapped`).
    gnss_off : sequence of (float, float)
        GNSS-off windows, s from the flight start.
    origin_lat_rad : float
        Latitude of ArduPilot's home, rad (turns east offsets into longitude degrees).
    origin_alt_msl_m : float
        Altitude of the flight, m (turns baro pressure offsets into altitude offsets).
    duration_s : float
        The flight's length (open-ended ramps are sampled until then).
    ramp_step_s : float
        Update period of ramped offsets, s of simulated time.

    Returns
    -------
    list of ParamSet
        At ``t = 0`` every touched parameter at its default, then each change.
    """
    if not (ramp_step_s > 0 and duration_s > 0):
        raise ValueError("ramp_step_s and duration_s must be > 0")
    terms: list[_Term] = []
    ramps: list[tuple[float, float]] = []
    m_per_deg_lat = LATLON_TO_M * 1e7
    m_per_deg_lon = m_per_deg_lat * max(math.cos(origin_lat_rad), 0.01)
    baro = _BaroOffset(float(isa_pressure_pa(geopotential_from_geometric(origin_alt_msl_m))))
    for start, length in gnss_off:
        terms.append(("SIM_GPS1_ENABLE", start, start + length, _const(0.0)))
    for ev in events:
        s, e = ev.start_s, ev.end_s
        if isinstance(ev, GnssOutage):
            terms.append(("SIM_GPS1_ENABLE", s, e, _const(0.0)))
        elif isinstance(ev, GnssJamming):
            terms.append(("SIM_GPS1_JAM", s, e, _const(1.0)))
        elif isinstance(ev, GnssSpoofHijack):
            n, east, d = ev.offset_ned_m
            terms += [("SIM_GPS1_GLTCH_X", s, e, _const(n / m_per_deg_lat)),
                      ("SIM_GPS1_GLTCH_Y", s, e, _const(east / m_per_deg_lon)),
                      ("SIM_GPS1_GLTCH_Z", s, e, _const(-d))]
        elif isinstance(ev, GnssSpoofDrift):
            b = math.radians(ev.bearing_deg)
            terms += [
                ("SIM_GPS1_GLTCH_X", s, e, _linear(s, ev.rate_mps * math.cos(b) / m_per_deg_lat)),
                ("SIM_GPS1_GLTCH_Y", s, e, _linear(s, ev.rate_mps * math.sin(b) / m_per_deg_lon)),
                ("SIM_GPS1_GLTCH_Z", s, e, _linear(s, ev.vertical_rate_mps)),
            ]
            ramps.append((s, duration_s if e is None else e))
        elif isinstance(ev, GnssDelay):
            terms.append(("SIM_GPS1_LAG_MS", s, e,
                          _const(float(round(100.0 + 1000.0 * ev.extra_latency_s)))))
        elif isinstance(ev, GnssRate):
            terms.append(("SIM_GPS1_HZ", s, e, _const(float(max(1, round(ev.rate_hz))))))
        elif isinstance(ev, GnssDegradation):
            terms.append(("SIM_GPS1_ACC", s, e, _degraded_accuracy(ev)))
            if ev.ramp_s > 0:
                ramps.append((s, s + ev.ramp_s))
        elif isinstance(ev, BaroGlitch):
            terms.append(("SIM_BARO_GLITCH", s, e, _const(baro.offset_m(ev.offset_pa))))
        elif isinstance(ev, BaroDrift | WeatherFront):
            keep = isinstance(ev, WeatherFront)
            end = duration_s if e is None else e
            terms.append(("SIM_BARO_GLITCH", s, None if keep else e,
                          baro.ramp(s, end, ev.rate_pa_per_s)))
            ramps.append((s, end))
    return _sample(terms, ramps, duration_s, ramp_step_s)


def _const(value: float) -> Callable[[float], float]:
    return lambda t: value


def _linear(start_s: float, rate: float) -> Callable[[float], float]:
    return lambda t: rate * (t - start_s)


def _degraded_accuracy(ev: GnssDegradation) -> Callable[[float], float]:
    default = ARDUPILOT_DEFAULTS["SIM_GPS1_ACC"]

    def accuracy(t: float) -> float:
        frac = 1.0 if ev.ramp_s <= 0 else min(1.0, (t - ev.start_s) / ev.ramp_s)
        return default * (1.0 + (ev.factor - 1.0) * frac)

    return accuracy


@dataclass(frozen=True)
class _BaroOffset:
    """Pressure offsets at the ISA pressure ``p0_pa`` as altitude offsets (ISA, exact)."""

    p0_pa: float

    def offset_m(self, dp_pa: float) -> float:
        return float(pressure_altitude_m(self.p0_pa + dp_pa) - pressure_altitude_m(self.p0_pa))

    def ramp(self, start_s: float, end_s: float, rate_pa_per_s: float) -> Callable[[float], float]:
        return lambda t: self.offset_m(rate_pa_per_s * (min(t, end_s) - start_s))


_COMBINE: dict[str, Callable[[list[float]], float]] = {
    "SIM_GPS1_ENABLE": min,
    "SIM_GPS1_JAM": max,
    "SIM_GPS1_LAG_MS": max,
    "SIM_GPS1_HZ": min,
    "SIM_GPS1_ACC": max,
}
"""How overlapping contributions combine (the rest add up)."""


def _value(name: str, t: float, terms: list[_Term]) -> float:
    active = [f(t) for n, s, e, f in terms if n == name and s <= t and (e is None or t < e)]
    if not active:
        return ARDUPILOT_DEFAULTS[name]
    combine = _COMBINE.get(name)
    return combine(active) if combine is not None else math.fsum(active)


def _sample(terms: list[_Term], ramps: list[tuple[float, float]], duration_s: float,
            step_s: float) -> list[ParamSet]:
    names = sorted({n for n, *_ in terms})
    times = {0.0}
    for _, s, e, _f in terms:
        times.add(s)
        if e is not None:
            times.add(e)
    for s, e in ramps:
        times.add(e)
        k = 1
        while s + k * step_s < min(e, duration_s):
            times.add(s + k * step_s)
            k += 1
    out: list[ParamSet] = []
    last: dict[str, float] = {}
    for t in sorted(x for x in times if x <= duration_s):
        for name in names:
            value = _value(name, t, terms)
            if t == 0.0 or not math.isclose(value, last[name], rel_tol=1e-9, abs_tol=1e-12):
                out.append(ParamSet(t, name, value))
                last[name] = value
    return out
