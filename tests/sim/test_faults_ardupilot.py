"""Scenario events as ArduPilot SITL SIM_* parameter changes (sim.faults.ardupilot)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest

from sim.atmosphere import altitude_from_pressure, pressure_from_altitude
from sim.faults import (
    AirspeedFailure,
    BaroDrift,
    BaroFreeze,
    BaroGlitch,
    FaultEvent,
    GnssDegradation,
    GnssDelay,
    GnssJamming,
    GnssOutage,
    GnssRate,
    GnssSpoofDrift,
    GnssSpoofHijack,
    ImuBiasStep,
    PitotBlockage,
    WeatherFront,
)
from sim.faults.ardupilot import (
    JSON_EVENTS,
    LATLON_TO_M,
    ParamSet,
    ardupilot_param_schedule,
    ardupilot_unmapped,
)

LAT = math.radians(47.0)


def _schedule(events: list[FaultEvent], gnss_off: Sequence[tuple[float, float]] = (),
              **kw: float) -> list[ParamSet]:
    options = {"origin_lat_rad": LAT, "origin_alt_msl_m": 1000.0, "duration_s": 200.0, **kw}
    return ardupilot_param_schedule(events, gnss_off, **options)


def _values(schedule: list[ParamSet], name: str) -> list[tuple[float, float]]:
    return [(p.time_s, p.value) for p in schedule if p.name == name]


def test_outages_and_gnss_off_windows_disable_the_gps_while_any_is_active() -> None:
    # GIVEN a GNSS-off window 30-70 s and an outage 60-90 s that overlap
    s = _schedule([GnssOutage(start_s=60.0, duration_s=30.0)], [(30.0, 40.0)])
    # THEN the GPS is set to its default at the start, off at 30 s and back on at 90 s only
    assert _values(s, "SIM_GPS1_ENABLE") == [(0.0, 1.0), (30.0, 0.0), (90.0, 1.0)]
    assert {p.name for p in s} == {"SIM_GPS1_ENABLE"}


def test_hijack_offsets_are_latitude_and_longitude_degrees_and_metres_up() -> None:
    s = _schedule([GnssSpoofHijack(start_s=10.0, duration_s=20.0, offset_ned_m=(500, -300, 20))])
    x, y, z = (_values(s, f"SIM_GPS1_GLTCH_{a}") for a in "XYZ")
    assert x[1][0] == 10.0 and x[1][1] * 1e7 * LATLON_TO_M == pytest.approx(500.0)
    assert y[1][1] * 1e7 * LATLON_TO_M * math.cos(LAT) == pytest.approx(-300.0)
    assert z[1] == (10.0, -20.0)  # 20 m down = altitude -20 m
    assert x[2] == y[2] == z[2] == (30.0, 0.0)


def test_spoof_drift_is_ramped_each_second_and_cleared_at_its_end() -> None:
    ev = GnssSpoofDrift(start_s=100.0, duration_s=10.0, rate_mps=2.0, bearing_deg=90.0,
                        vertical_rate_mps=0.5)
    s = _schedule([ev])
    east = [(t, v * 1e7 * LATLON_TO_M * math.cos(LAT)) for t, v in
            _values(s, "SIM_GPS1_GLTCH_Y")]
    assert [t for t, _ in east] == [0.0, *[100.0 + k for k in range(1, 10)], 110.0]
    assert east[5][1] == pytest.approx(2.0 * 5.0) and east[-1][1] == 0.0
    assert _values(s, "SIM_GPS1_GLTCH_Z")[9] == (109.0, pytest.approx(4.5))


def test_gps_timing_jamming_and_degradation_parameters() -> None:
    s = _schedule([
        GnssDelay(start_s=5.0, duration_s=5.0, extra_latency_s=0.25),
        GnssDelay(start_s=7.0, duration_s=5.0, extra_latency_s=0.5),
        GnssRate(start_s=20.0, duration_s=5.0, rate_hz=0.4),
        GnssJamming(start_s=30.0, duration_s=5.0),
        GnssDegradation(start_s=40.0, duration_s=10.0, factor=3.0, ramp_s=2.0),
    ])
    assert _values(s, "SIM_GPS1_LAG_MS") == [(0.0, 100.0), (5.0, 350.0), (7.0, 600.0),
                                            (12.0, 100.0)]
    assert _values(s, "SIM_GPS1_HZ") == [(0.0, 5.0), (20.0, 1.0), (25.0, 5.0)]
    assert _values(s, "SIM_GPS1_JAM") == [(0.0, 0.0), (30.0, 1.0), (35.0, 0.0)]
    # the accuracy ramps from x1 at 40 s (no change, so not sent) to x3 at 42 s
    assert _values(s, "SIM_GPS1_ACC") == [(0.0, 0.3), (41.0, pytest.approx(0.6)),
                                         (42.0, pytest.approx(0.9)), (50.0, 0.3)]


def test_baro_offsets_are_isa_altitude_offsets_and_add_up() -> None:
    p0 = float(pressure_from_altitude(1000.0))
    s = _schedule([
        BaroGlitch(start_s=10.0, duration_s=10.0, offset_pa=200.0),
        BaroDrift(start_s=15.0, duration_s=3.0, rate_pa_per_s=-10.0),
        WeatherFront(start_s=50.0, duration_s=2.0, rate_pa_per_s=5.0),
    ])
    glitch = dict(_values(s, "SIM_BARO_GLITCH"))
    alt = float(altitude_from_pressure(p0 + 200.0)) - 1000.0
    assert alt < 0 and glitch[10.0] == pytest.approx(alt, abs=1e-3)  # more pressure = lower
    drift = float(altitude_from_pressure(p0 - 20.0)) - 1000.0
    both = alt + drift  # overlapping offsets add up (as altitude offsets)
    assert glitch[17.0] == pytest.approx(both, abs=1e-3)
    assert glitch[18.0] == pytest.approx(alt, abs=1e-3) and glitch[20.0] == 0.0
    front = float(altitude_from_pressure(p0 + 10.0)) - 1000.0
    assert glitch[52.0] == pytest.approx(front, abs=1e-3)  # the front's offset stays
    assert max(glitch) == 52.0


def test_imu_and_pitot_events_set_no_parameter_and_the_rest_is_reported_unmapped() -> None:
    imu = ImuBiasStep(start_s=3.0, duration_s=4.0, sensor="accel", axis="y", value=0.5)
    pitot = PitotBlockage(start_s=5.0, mode="zero")
    freeze = BaroFreeze(start_s=1.0, duration_s=2.0)
    s = _schedule([imu, pitot, freeze, AirspeedFailure(start_s=1.0)])
    assert s == []  # the IMU and pitot reach ArduPilot through the JSON line
    assert {"imu_bias_step", "pitot_blockage"} <= JSON_EVENTS
    assert ardupilot_unmapped(imu) is None and ardupilot_unmapped(pitot) is None
    assert "last pitot airspeed" in (ardupilot_unmapped(AirspeedFailure(start_s=1.0)) or "")
    assert "frozen" in (ardupilot_unmapped(freeze) or "")


def test_nothing_to_play_is_an_empty_schedule() -> None:
    assert _schedule([]) == []
    with pytest.raises(ValueError):
        _schedule([], ramp_step_s=0.0)
