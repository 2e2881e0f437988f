"""Units in scenario files: quantities with units, criteria in the scorecard's units, events
converted from human units to SI and to the simulator's fault models."""


from __future__ import annotations

import math
from pathlib import Path

import pytest

from scenarios.schema import (
    Scenario,
    json_schema,
    load_scenario,
    metric_unit,
    parse_quantity,
)
from sim import faults
from tests.scenarios.test_schema import error_of, write


@pytest.mark.parametrize(
    ("value", "unit", "expected"),
    [
        (25, "m", 25.0),
        ("25 m", "m", 25.0),
        ("1.5 km", "m", 1500.0),
        ("100 ft", "m", 30.48),
        ("5 min", "s", 300.0),
        ("1.5h", "s", 5400.0),
        ("250 ms", "s", 0.25),
        ("0.5 deg", "deg", 0.5),
        ("2.3e-4 deg", "deg", 2.3e-4),
        (f"{math.pi} rad", "deg", 180.0),
        ("2 m/s", "m/s", 2.0),
        ("36 km/h", "m/s", 10.0),
        ("10 kn", "m/s", 10 * 1852 / 3600),
        ("42", "m", 42.0),
        (3.0, None, 3.0),
    ],
)
def test_parse_quantity(value: object, unit: str | None, expected: float) -> None:
    assert parse_quantity(value, unit) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("value", "unit", "fragment"),
    [
        ("25 m", "s", "is a length, expected a time"),
        ("3 furlongs", "m", "unknown unit"),
        ("fast", "m/s", "cannot read"),
        ("3 m", None, "no unit"),
        (True, "m", "expected a number"),
        (float("nan"), "m", "not finite"),
    ],
)
def test_parse_quantity_rejects(value: object, unit: str | None, fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        parse_quantity(value, unit)


def test_metric_units() -> None:
    assert metric_unit("outages.horizontal_error_m_at.60") == "m"
    assert metric_unit("outages.rmse.lat_deg") == "deg"
    assert metric_unit("outages.rmse.vn_mps") == "m/s"
    assert metric_unit("outages.duration_s") == "s"
    assert metric_unit("nees.nees_mean") is None


def test_criteria_convert_to_the_summary_unit(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, """
        duration_s: 600
        criteria:
          - {metric: gnss_on.horizontal_rmse_m, max: 0.01 km}
          - {name: yaw, metric: gnss_on.yaw_rmse_deg, max: 0.02 rad}
          - {metric: outages.rmse.vn_mps, max: 3.6 km/h}
          - {metric: nees.nees_mean, max: 50}
          - {metric: containment_3sigma.horizontal, min: 0.9}
          - {metric: events.detect_s, max: 2 s, fail_if_missing: true}
        events:
          - {type: gnss_outage, at: 100, duration: 30}
        """))
    c = scenario.criteria()
    assert c[0].path == "gnss_on.horizontal_rmse_m" and c[0].limit == pytest.approx(10.0)
    assert c[0].name == "gnss_on.horizontal_rmse_m <= 0.01 km"
    assert c[1].name == "yaw" and c[1].limit == pytest.approx(math.degrees(0.02))
    assert c[2].limit == pytest.approx(1.0)
    assert c[3].limit == 50.0
    assert (c[4].op, c[4].limit, c[4].none_fails) == (">=", 0.9, False)
    assert c[4].name == "containment_3sigma.horizontal >= 0.9"
    assert (c[5].op, c[5].limit, c[5].none_fails) == ("<=", 2.0, True)
    # and a criterion evaluates against a summary like build_summary's
    summary = {"gnss_on": {"horizontal_rmse_m": 9.0}}
    assert c[0].evaluate(summary)["ok"] is True


def test_events_convert_human_units_to_si(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, """
        duration_s: 3600
        events:
          - {type: imu_bias_step, at: 1 min, sensor: gyro, axis: z, value_deg_per_h: 360}
          - {type: imu_bias_step, at: 60, sensor: accel, axis: 0, value_mg: 2}
          - {type: imu_saturation, at: 90, duration: 5, sensor: gyro, limit_dps: 100}
          - {type: weather_front, at: 100, duration: 10 min, rate_hpa_per_10min: -1}
          - {type: baro_glitch, at: 900, duration: 10, offset_hpa: 2}
          - {type: baro_drift, at: 1000, duration: 10, rate_hpa_per_h: 3.6}
          - {type: mag_anomaly, at: 30, duration: 1, offset_ned_ut: [2, -1, 0.5]}
          - {type: gnss_spoof_drift, at: 1200, duration: 100, rate_mps: 0.5, bearing_deg: 45}
          - {type: gnss_jamming, at: 1400, duration: 60}
          - {type: gnss_rate, at: 1500, duration: 60, rate_hz: 1}
          - {type: gnss_delay, at: 1600, duration: 60, extra_latency_s: 0.3}
          - {type: gnss_degradation, at: 1700, duration: 60, factor: 3}
          - {type: imu_stuck, at: 1800, duration: 2, sensor: accel, axis: y}
          - {type: baro_freeze, at: 1900, duration: 5}
          - {type: gnss_outage, at: 2000}
        """))
    ev = scenario.fault_events()
    gyro, accel, sat, front, glitch, drift, mag = ev[:7]
    assert isinstance(gyro, faults.ImuBiasStep)
    assert (gyro.start_s, gyro.sensor, gyro.axis) == (60.0, "gyro", 2)
    assert gyro.value == pytest.approx(math.radians(0.1))  # 360 deg/h = 0.1 deg/s
    assert isinstance(accel, faults.ImuBiasStep) and accel.value == pytest.approx(2e-3 * 9.80665)
    assert isinstance(sat, faults.ImuSaturation) and sat.limit == pytest.approx(math.radians(100))
    assert sat.axis is None
    assert isinstance(front, faults.WeatherFront) and front.duration_s == 600.0
    assert front.rate_pa_per_s == pytest.approx(-100.0 / 600.0)
    assert isinstance(glitch, faults.BaroGlitch) and glitch.offset_pa == pytest.approx(200.0)
    assert isinstance(drift, faults.BaroDrift) and drift.rate_pa_per_s == pytest.approx(0.1)
    assert isinstance(mag, faults.MagAnomaly)
    assert mag.offset_ned_t == pytest.approx((2e-6, -1e-6, 0.5e-6))
    assert [type(e).__name__ for e in ev[7:]] == [
        "GnssSpoofDrift", "GnssJamming", "GnssRate", "GnssDelay", "GnssDegradation",
        "ImuStuck", "BaroFreeze", "GnssOutage",
    ]
    assert scenario.outage_windows() == ((1400.0, 1460.0), (2000.0, 3600.0))


def test_event_defaults_follow_sim_faults(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, """
        duration_s: 600
        events:
          - {type: weather_front, at: 10, duration: 10}
          - {type: baro_glitch, at: 30, duration: 10}
          - {type: baro_drift, at: 50, duration: 10}
          - {type: gnss_spoof_hijack, at: 100, duration: 10}
        """))
    front, glitch, drift, hijack = scenario.fault_events()
    assert front == faults.WeatherFront(10.0, 10.0)
    assert glitch == faults.BaroGlitch(30.0, 10.0)
    assert drift == faults.BaroDrift(50.0, 10.0)
    assert hijack == faults.GnssSpoofHijack(100.0, 10.0)


def test_events_are_the_sim_models_in_si(tmp_path: Path) -> None:
    # GIVEN a file written in the file's units
    scenario = load_scenario(write(tmp_path, """
        duration_s: 600
        events:
          - {type: baro_glitch, at: 1 min, duration: 10, offset_hpa: 2}
          - {type: imu_saturation, at: 100, sensor: gyro, limit_dps: 90, axis: x}
        """))
    glitch, sat = scenario.events
    # THEN the scenario holds sim.faults' own events (no copy), in SI
    assert scenario.fault_events() is scenario.events
    assert glitch == faults.BaroGlitch(start_s=60.0, duration_s=10.0, offset_pa=200.0)
    assert sat == faults.ImuSaturation(100.0, None, "gyro", math.pi / 2, 0)
    # and a dump holds the SI fields, which Scenario.model_validate takes back
    data = scenario.model_dump(by_alias=True, exclude_unset=True)
    assert data["events"][0] == {"type": "baro_glitch", "start_s": 60.0, "duration_s": 10.0,
                                 "offset_pa": 200.0}
    assert Scenario.model_validate(data).fault_events() == scenario.fault_events()


@pytest.mark.parametrize(
    ("event", "key", "fragment"),
    [
        # an SI field name is not a key of the file
        ("{type: gnss_outage, start_s: 10}", "events[0].start_s", "unknown key 'start_s'"),
        ("{type: weather_front, at: 10, rate_pa_per_s: 1}", "events[0].rate_pa_per_s",
         "did you mean 'rate_hpa_per_h'"),
        # the model's bound, reported at the file's key with the file's value
        ("{type: imu_saturation, at: 10, sensor: gyro, limit_dps: -1}", "events[0].limit_dps",
         "greater than 0 (got -1)"),
        ("{type: mag_anomaly, at: 10, offset_ned_ut: [1, .nan, 2]}",
         "events[0].offset_ned_ut[1]", "finite number (got nan)"),
        ("{type: gnss_outage, at: 10, duration: 0 s}", "events[0].duration",
         "must be > 0 s (got '0 s')"),
        ("{type: gnss_jamming, at: 10, blackout_s: true}", "events[0].blackout_s",
         "valid number"),
        ("{type: gnss_outage, at: 5 m}", "events[0].at", "is a length, expected a time"),
    ],
)
def test_event_errors_name_the_file_key(tmp_path: Path, event: str, key: str,
                                        fragment: str) -> None:
    err = error_of(write(tmp_path, f"duration_s: 600\nevents:\n  - {event}\n"))
    assert (err.line, err.key) == (3, key)
    assert fragment in str(err)


def test_json_schema_of_events_is_the_file_form() -> None:
    defs = json_schema()["$defs"]
    glitch = defs["BaroGlitch"]["properties"]
    assert {"type", "at", "duration", "offset_pa", "offset_hpa"} == set(glitch)
    assert glitch["offset_hpa"]["unit"] == "hPa" and glitch["at"]["unit"] == "s"
    assert defs["ImuBiasStep"]["required"] == ["type", "at", "sensor", "axis"]
