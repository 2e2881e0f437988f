"""Scenario files: validation, error messages (file, line, key), units, builders, JSON Schema,
and the shipped library."""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
import yaml

from fusion import earth
from hil.tracks import Fixes, HealthSeries, Track
from scenarios.metrics import Window
from scenarios.schema import (
    ALTITUDE_METHODS,
    BRIDGE_METHODS,
    KNOWN_METRICS,
    Scenario,
    ScenarioError,
    json_schema,
    list_library,
    load_scenario,
    metric_unit,
    parse_quantity,
)
from scenarios.summary import RunInfo, ScoringConfig, build_summary
from sim import faults
from sim.flight import FlightConfig
from sim.plans import FlightPlan
from sim.sensors import SensorSuite, SensorSuiteConfig

LIBRARY = list_library()


def write(tmp_path: Path, text: str, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def error_of(path: Path) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message  # one line for the user
    assert message.startswith(f"{path}:")
    return info.value


# ------------------------------------------------------------------------------ library
def test_library_has_at_least_twelve_scenarios() -> None:
    assert len(LIBRARY) >= 12


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: p.stem)
def test_library_scenario_validates_and_builds(path: Path) -> None:
    # GIVEN a shipped scenario WHEN it is loaded and its objects are built (no flying)
    scenario = load_scenario(path)
    flight = scenario.flight_config()
    plan = scenario.flight_plan()
    sensors = scenario.sensor_config()
    events = scenario.fault_events()
    criteria = scenario.criteria()
    # THEN every object is the simulator's own type, consistent with the file
    assert isinstance(flight, FlightConfig) and flight.seed == scenario.seed
    assert isinstance(plan, FlightPlan)
    assert isinstance(sensors, SensorSuiteConfig)
    assert scenario.name == path.stem
    assert criteria, "every library scenario has pass criteria"
    assert events, "every library scenario has a timeline"
    faults.check_events(events, scenario.duration_s)
    # the sensor suite and the injector accept them (rates divide, events valid)
    SensorSuite(sensors, scenario.seed, flight.rate_hz)
    faults.FaultInjector(events, seed=scenario.seed)
    header = path.read_text(encoding="utf-8").splitlines()[:12]
    assert header[0].startswith("# Rehearses:")
    assert any(line.startswith("# Paper setting:") for line in header)


def _by_name(name: str) -> Scenario:
    return load_scenario(next(p for p in LIBRARY if p.stem == name))


def test_library_reproduces_p0_setting() -> None:
    s = _by_name("p0-repeated-25s-outages")
    cfg = s.sensor_config()
    assert cfg.imu_rate_hz == 50.0 and cfg.gnss.rate_hz == 5.0
    outages = [e for e in s.fault_events() if isinstance(e, faults.GnssOutage)]
    assert len(outages) >= 3 and all(e.duration_s == 25.0 for e in outages)


def test_library_reproduces_p1_and_p2_settings() -> None:
    p1 = _by_name("p1-5min-outage")
    assert [e.duration_s for e in p1.fault_events()] == [300.0]
    p2 = _by_name("p2-900s-outage-from-700s")
    assert p2.duration_s == 900.0
    assert p2.sensors.imu.preset == "paper-p2" and p2.sensors.gnss.preset == "paper-p2"
    (outage,) = p2.fault_events()
    assert isinstance(outage, faults.GnssOutage)
    assert outage.start_s == 700.0 and outage.duration_s is None


def test_library_reproduces_p4_settings() -> None:
    climb = _by_name("p4-climb-cruise-descent-120s-outage")
    assert [(e.start_s, e.duration_s) for e in climb.fault_events()] == [(540.0, 120.0)]
    assert climb.fusion.altitude == "loop-mpc"
    front = _by_name("p4-weather-front-long-outage")
    (wf,) = [e for e in front.fault_events() if isinstance(e, faults.WeatherFront)]
    assert wf.rate_pa_per_s == pytest.approx(-100.0 / 600.0)  # 1 hPa per 10 min
    day = _by_name("p4-nonstandard-day-1500m")
    baro = day.sensor_config().baro
    assert baro.sea_level_temperature_offset_k == 15.0
    assert baro.sea_level_pressure_offset_hpa == -10.0
    assert day.flight_config().start.alt_msl_m == 1500.0


def test_library_covers_the_rehearsals() -> None:
    types = {type(e).__name__ for p in LIBRARY for e in load_scenario(p).fault_events()}
    assert {
        "GnssOutage", "GnssJamming", "GnssSpoofDrift", "GnssSpoofHijack", "WeatherFront",
        "ImuBiasStep", "BaroGlitch", "PitotBlockage",
    } <= types


def test_library_covers_long_denial_with_air_data() -> None:
    """Issue #18: 300 s and 900 s outages in survey, climb-descent and racetrack flight, wind
    up to 12 m/s with turbulence and shear, pitot blockages (stuck, zero) inside an outage, an
    aircraft without a pitot on synthetic airspeed; every one gated at 300 s into the outage."""
    long = {}
    for p in LIBRARY:
        s = load_scenario(p)
        outages = [e for e in s.fault_events() if isinstance(e, faults.GnssOutage)]
        if any(e.duration_s is not None and e.duration_s >= 300.0 for e in outages):
            long[p.stem] = s
    air = {k: s for k, s in long.items() if s.fusion.airspeed != "off"
           and any(c.path == "outages.horizontal_error_m_at.300" for c in s.criteria())}
    assert {s.plan for s in air.values()} >= {"survey", "climb-descent", "racetrack"}
    durations = {e.duration_s for s in air.values() for e in s.fault_events()
                 if isinstance(e, faults.GnssOutage)}
    assert {300.0, 900.0} <= durations
    speeds = [math.hypot(*s.wind_ned_mps[:2]) for s in air.values()]
    speeds += [math.hypot(r[1], r[2]) for s in air.values() for r in s.wind_table]
    assert max(speeds) >= 12.0 - 1e-9
    # turbulent air throughout, besides the steady-wind case that checks calm-air dead
    # reckoning (the turbulence estimated in flight)
    steady = {k for k, s in air.items() if s.turbulence == 0.0}
    assert steady == {"airdata-steady-wind-300s-outage"}
    assert all(s.turbulence > 0.0 for k, s in air.items() if k not in steady)
    assert any(s.wind_shear_exponent > 0.0 or s.wind_table for s in air.values())
    modes = set()
    for s in air.values():
        (outage,) = [e for e in s.fault_events() if isinstance(e, faults.GnssOutage)]
        assert outage.duration_s is not None
        for e in s.fault_events():
            if isinstance(e, faults.PitotBlockage):
                # inside the outage, and gated on its detection
                assert outage.start_s < e.start_s < outage.start_s + outage.duration_s
                assert any(c.path == "detect_s_by_sensor.airspeed" and c.none_fails
                           for c in s.criteria())
                modes.add(e.mode)
    assert modes == {"stuck", "zero"}
    no_pitot = [s for s in air.values() if s.sensors.pitot.preset == "none"]
    assert no_pitot and all(s.fusion.airspeed == "synthetic" for s in no_pitot)


# -------------------------------------------------------------------------- bad input
def test_unknown_key_names_key_line_and_suggestion(tmp_path: Path) -> None:
    path = write(tmp_path, """
        duration_s: 600
        sensors:
          imu:
            preset: tactical
            gyro:
              bias_instabilty_deg_per_h: 3
        """)
    err = error_of(path)
    assert err.line == 6
    assert err.key == "sensors.imu.gyro.bias_instabilty_deg_per_h"
    assert "did you mean 'bias_instability_deg_per_h'" in str(err)


def test_unknown_top_level_key(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, "duration_s: 60\nseeed: 3\n"))
    assert (err.line, err.key) == (2, "seeed")
    assert "unknown key 'seeed'" in str(err) and "'seed'" in str(err)


def test_negative_duration(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, "name: x\nduration_s: -5\n"))
    assert (err.line, err.key) == (2, "duration_s")
    assert "greater than 0" in str(err) and "-5" in str(err)


def test_negative_event_time(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage, at: -3 s, duration: 10}
        """))
    assert (err.line, err.key) == (3, "events[0].at")
    assert ">= 0 s" in str(err)


def test_event_outside_the_flight(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage, at: 300, duration: 60}
          - type: gnss_outage
            at: 11 min
        """))
    assert (err.line, err.key) == (5, "events[1].at")
    assert "660 s" in str(err) and "end of the flight" in str(err)


def test_event_running_past_the_end(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage, at: 550, duration: 2 min}
        """))
    assert err.key == "events[0].duration" and "670 s" in str(err)


def test_overlapping_contradictory_events(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage, at: 300, duration: 60}
          - {type: baro_glitch, at: 310, duration: 5}
          - type: gnss_spoof_hijack
            at: 320
        """))
    # the later event is the one blamed; the message names both and the other's line
    assert (err.line, err.key) == (5, "events[2]")
    message = str(err)
    assert "events[0] (gnss_outage)" in message and "events[2] (gnss_spoof_hijack)" in message
    assert "(see line 3)" in message


def test_compatible_overlaps_are_accepted(tmp_path: Path) -> None:
    # a weather front may overlap a baro glitch and an outage; bias steps add up
    scenario = load_scenario(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage, at: 100, duration: 300}
          - {type: weather_front, at: 100}
          - {type: baro_glitch, at: 200, duration: 10}
          - {type: imu_bias_step, at: 150, sensor: gyro, axis: 2, value_deg_per_h: 10}
          - {type: imu_bias_step, at: 160, sensor: gyro, axis: z, value_deg_per_h: 10}
        """))
    assert len(scenario.fault_events()) == 5


def test_unknown_preset(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        sensors:
          gnss: {preset: moden}
        """))
    assert (err.line, err.key) == (3, "sensors.gnss.preset")
    assert "unknown GNSS preset 'moden'" in str(err) and "did you mean 'modern'" in str(err)


def test_pitot_section_presets_overrides_and_events(tmp_path: Path) -> None:
    scn = load_scenario(write(tmp_path, """
        duration_s: 120
        sensors:
          pitot: {preset: sdp33, rate_hz: 25, noise_pa: 0.5}
          baro: {preset: ms5611, position_error_fwd: -0.02}
        events:
          - {type: pitot_blockage, at: 10 s, duration: 20, mode: zero}
          - {type: pitot_drift, at: 40, duration: 10, rate_pa_per_s: 2.5}
          - {type: airspeed_failure, at: 60}
        """))
    config = scn.sensor_config()
    assert config.pitot is not None and config.pitot.noise_pa == 0.5
    assert config.pitot.full_scale_pa == 1500.0 and config.pitot_rate_hz == 25.0
    assert config.baro.position_error_fwd == -0.02 and config.baro.has_position_error
    assert [type(e) for e in scn.fault_events()] == [
        faults.PitotBlockage, faults.PitotDrift, faults.AirspeedFailure
    ]
    # the default aircraft carries the default pitot; none means no airspeed sensor
    default = Scenario.model_validate({"duration_s": 60})
    assert default.sensor_config().pitot == default_pitot()
    bare = load_scenario(write(tmp_path, "duration_s: 60\nsensors: {pitot: {preset: none}}\n",
                               "bare.yaml"))
    assert bare.sensor_config().pitot is None
    err = error_of(write(tmp_path, """
        duration_s: 60
        sensors:
          pitot: {preset: none, noise_pa: 1.0}
        """, "bad.yaml"))
    assert "fits no sensor" in str(err) and "noise_pa" in str(err)


def default_pitot() -> Any:
    from sim.presets import DEFAULT_PITOT_PRESET, pitot_preset

    return pitot_preset(DEFAULT_PITOT_PRESET)


def test_unknown_event_type(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outag, at: 300}
        """))
    assert err.key == "events[0].type" and err.line == 3
    assert "did you mean 'gnss_outage'" in str(err)


def test_missing_required_key(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 600
        events:
          - {type: gnss_outage}
        """))
    assert (err.line, err.key) == (3, "events[0].at")
    assert "missing" in str(err)


def test_missing_duration(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, "name: x\n"))
    assert err.key == "duration_s" and "missing" in str(err)


@pytest.mark.parametrize(
    ("text", "key", "fragment"),
    [
        ("aircraft: c17\n", "aircraft", "did you mean 'c172x'"),
        ("fusion: {bridge: gmhd}\n", "fusion.bridge", "did you mean 'gmdh'"),
        ("fusion: {altitude: mpc}\n", "fusion.altitude", "unknown altitude method"),
        ("fusion: {airspeed: maybe}\n", "fusion.airspeed", "unknown airspeed mode"),
        ("fusion: {align: statc}\n", "fusion.align", "did you mean 'static'"),
        ("plan: nowhere.yaml\n", "plan", "unknown flight plan"),
        ("turbulence: stormy\n", "turbulence", "unknown turbulence level"),
        ("sensors: {imu: {rate_hz: 70}}\n", "sensors.imu.rate_hz", "must divide"),
        ("sensors: {baro: {rate_hz: 500}}\n", "sensors.baro.rate_hz", "exceeds"),
        ("sensors: {imu: {gyro: {range_dps: -1}}}\n", "sensors.imu.gyro.range_dps",
         "greater than 0"),
        ("criteria: [{metric: gnss_on.horizontal_rmse_m, max: 3 deg}]\n", "criteria[0].max",
         "expected a length"),
        ("criteria: [{metric: gnss_on.horizontl_rmse_m, max: 3}]\n", "criteria[0].metric",
         "did you mean 'gnss_on.horizontal_rmse_m'"),
        ("criteria: [{metric: outages.horizontal_rmse_m, max: 3}]\n", "criteria[0].metric",
         "no gnss_outage or gnss_jamming event"),
        ("events: [{type: gnss_outage, at: 10, duration: 30}]\n"
         "criteria: [{metric: outages.horizontal_error_m_at.60, max: 3}]\n",
         "criteria[0].metric", "no outage lasts 60 s"),
        ("criteria: [{metric: gnss_on.yaw_rmse_deg}]\n", "criteria[0]",
         "exactly one of max and min"),
        ("criteria: [{metric: gnss_on.yaw_rmse_deg, max: 1, min: 0}]\n", "criteria[0]",
         "exactly one of max and min"),
        ("criteria: [{metric: events.detect_s, max: 3}]\n", "criteria[0].metric",
         "has none"),
        ("events: [{type: imu_bias_step, at: 10, sensor: gyro, axis: x, value_mg: 3}]\n",
         "events[0].value_mg", "takes value_deg_per_h"),
        ("events: [{type: baro_glitch, at: 10, offset_pa: 3, offset_hpa: 1}]\n",
         "events[0].offset_hpa", "not both"),
        ("events: [{type: gnss_rate, at: 10, rate_hz: 10}]\n", "events[0].rate_hz",
         "above the receiver's 5 Hz"),
        ("wind_table: [[900, 1, 0], [800, 2, 0]]\n", "wind_table", "must increase strictly"),
        ("wind_ned_mps: [3, 0, 0]\nwind_table: [[900, 1, 0]]\n", "wind_table",
         "replaces the horizontal wind"),
        ("wind_shear_exponent: -0.1\n", "wind_shear_exponent", "greater than or equal to 0"),
    ],
)
def test_bad_values_name_the_key(tmp_path: Path, text: str, key: str, fragment: str) -> None:
    err = error_of(write(tmp_path, "duration_s: 600\n" + text))
    assert err.key == key
    assert fragment in str(err)
    assert err.line is not None and err.line >= 2


def test_duplicate_key(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, "duration_s: 600\nseed: 3\nseed: 4\n"))
    assert (err.line, err.key) == (3, "seed") and "twice" in str(err)


def test_yaml_syntax_error_has_a_line(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, "duration_s: 600\nevents: [\n  {type: gnss_outage\n"))
    assert err.line is not None and "not valid YAML" in str(err)


def test_yaml_alias_bomb_is_refused_before_it_expands(tmp_path: Path) -> None:
    """GIVEN a ~700-byte 'billion laughs' file (each level 10 aliases of the previous) WHEN
    loaded THEN one line naming the first alias and its line, without building the document
    (nine levels would be 10^9 strings)."""
    lines = ['l0: &l0 "lol"']
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, 10)]
    text = "\n".join(["duration_s: 600", *lines]) + "\n"
    assert len(text) < 1000
    err = error_of(write(tmp_path, text))
    assert err.line == 3 and "aliases (*l0) are not allowed" in str(err)
    assert len(str(err).splitlines()) == 1


def test_deep_nesting_and_huge_files_are_refused_with_one_line(tmp_path: Path) -> None:
    deep = error_of(write(tmp_path, "duration_s: 600\nx: " + "[" * 5000 + "]" * 5000 + "\n"))
    assert "nested deeper than 32 levels" in str(deep) and deep.line == 2
    big = write(tmp_path, "duration_s: 600\n" + "# padding\n" * 120_000, name="big.yaml")
    err = error_of(big)
    assert "file too large" in str(err) and "1048576" in str(err)
    with pytest.raises(ScenarioError, match="is a directory"):
        load_scenario(tmp_path)


def test_not_a_mapping_and_missing_file(tmp_path: Path) -> None:
    assert "YAML mapping" in str(error_of(write(tmp_path, "- 1\n- 2\n")))
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "absent.yaml")


# ------------------------------------------------------------------------------ units
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


# -------------------------------------------------------------------------- builders
def test_builders_apply_overrides_and_defaults(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, """
        name: custom
        aircraft: c310
        start: {heading_deg: 90}
        duration_s: 120
        seed: 42
        sim_rate_hz: 100
        wind_ned_mps: [1, 2, 0]
        turbulence: moderate
        sensors:
          imu:
            preset: tactical
            rate_hz: 50
            gyro: {bias_instability_deg_per_h: 0.5}
            accel: {turn_on_bias_mg: 0.2}
          gnss: {preset: modern, rate_hz: 10, latency_s: 0.2}
          baro: {sea_level_pressure_offset_hpa: 5, rate_hz: 25}
          mag: {preset: ideal}
        fusion: {bridge: gmdh, altitude: loop-kf}
        """))
    flight = scenario.flight_config()
    assert flight.aircraft == "c310" and flight.rate_hz == 100.0 and flight.seed == 42
    assert flight.start.heading_deg == 90.0
    assert flight.start.alt_msl_m == 1000.0  # the aircraft's suggested trim altitude
    assert flight.wind_ned_mps == (1.0, 2.0, 0.0) and flight.turbulence == pytest.approx(0.57)
    assert scenario.flight_config(seed=7).seed == 7
    cfg = scenario.sensor_config()
    assert cfg.imu.gyro.bias_instability_deg_per_h == 0.5
    assert cfg.imu.gyro.range_dps == 1000.0  # the rest of the tactical preset is kept
    assert cfg.imu.accel.turn_on_bias_mg == 0.2
    assert cfg.imu_rate_hz == 50.0
    assert cfg.gnss.rate_hz == 10.0 and cfg.gnss.latency_s == 0.2
    assert cfg.baro.sea_level_pressure_offset_hpa == 5.0 and cfg.baro_rate_hz == 25.0
    assert cfg.baro.noise_pa == 1.2  # ms5611 default preset
    assert cfg.mag.noise_ut == 0.0
    assert scenario.imu_preset == "tactical"
    assert scenario.fusion.bridge == "gmdh" and scenario.fusion.altitude == "loop-kf"
    assert scenario.flight_plan().name == "racetrack"


def test_plan_relative_to_the_scenario_file(tmp_path: Path) -> None:
    (tmp_path / "plans").mkdir()
    (tmp_path / "plans" / "square.yaml").write_text(
        "legs:\n  - {kind: turn, turn_deg: 90}\n", encoding="utf-8"
    )
    scenario = load_scenario(write(tmp_path, "duration_s: 60\nplan: plans/square.yaml\n"))
    assert scenario.flight_plan().name == "square"
    assert scenario.source_dir == tmp_path
    # and survives with_overrides (the base directory is kept)
    assert scenario.with_overrides(seed=3).flight_plan().name == "square"


def test_inline_plan(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, """
        name: inline-demo
        duration_s: 60
        plan:
          repeat: false
          legs:
            - {kind: heading, heading_deg: 0, duration_s: 30}
        """))
    plan = scenario.flight_plan()
    assert plan.name == "inline-demo" and plan.repeat is False and len(plan.legs) == 1


def test_bad_inline_plan_names_the_leg(tmp_path: Path) -> None:
    err = error_of(write(tmp_path, """
        duration_s: 60
        plan:
          legs:
            - {kind: heading, heading_deg: 0}
        """))
    assert (err.line, err.key) == (4, "plan.legs[0]") and "needs duration_s" in str(err)


def test_with_overrides(tmp_path: Path) -> None:
    base = load_scenario(write(tmp_path, """
        duration_s: 600
        sensors: {imu: {gyro: {bias_instability_deg_per_h: 3}}}
        events:
          - {type: gnss_outage, at: 300, duration: 60}
        """))
    changed = base.with_overrides(seed=9, bridge="rbf", altitude="loop", duration_s=400)
    assert (changed.seed, changed.fusion.bridge, changed.fusion.altitude) == (9, "rbf", "loop")
    assert changed.duration_s == 400.0
    assert changed.sensor_config() == base.sensor_config()
    assert changed.fault_events() == base.fault_events()
    assert base.seed == 1 and base.fusion.bridge == "none"  # the original is untouched
    with pytest.raises(ScenarioError, match="unknown bridging method 'gmdhh'"):
        base.with_overrides(bridge="gmdhh")
    with pytest.raises(ScenarioError, match="end of the flight"):
        base.with_overrides(duration_s=330)


def test_method_lists() -> None:
    assert BRIDGE_METHODS == (
        "none", "gmdh", "gmdh-pseudo", "mlp", "rbf", "bp-parallel", "gmdh-airspeed", "gmdh-wind"
    )
    assert ALTITUDE_METHODS == ("ekf", "loop", "loop-mpc", "loop-kf")


def test_model_is_frozen_and_strict() -> None:
    scenario = Scenario.model_validate({"duration_s": 60})
    with pytest.raises(ValueError):
        setattr(scenario, "seed", 3)  # noqa: B010 - the point is the plain assignment
    with pytest.raises(ValueError, match="Extra inputs"):
        Scenario.model_validate({"duration_s": 60, "sead": 1})


# ------------------------------------------------------------------------ JSON Schema
def test_json_schema_is_valid_draft_2020_12() -> None:
    schema = json_schema()
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)
    assert json.loads(json.dumps(schema)) == schema  # plain JSON, as `hilnav schema` prints it
    assert {"duration_s", "sensors", "fusion", "criteria", "events"} <= set(schema["properties"])


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: p.stem)
def test_library_validates_against_json_schema(path: Path) -> None:
    validator = jsonschema.Draft202012Validator(json_schema())
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    errors = [e.message for e in validator.iter_errors(data)]
    assert errors == []


def test_json_schema_rejects_what_the_models_reject() -> None:
    validator = jsonschema.Draft202012Validator(json_schema())
    assert not validator.is_valid({"duration_s": 60, "seeed": 1})
    assert not validator.is_valid({"duration_s": 60, "sensors": {"gnss": {"preset": "moden"}}})
    assert not validator.is_valid(
        {"duration_s": 60, "events": [{"type": "gnss_outage", "at": 1, "bogus": 2}]}
    )
    assert validator.is_valid(
        {"duration_s": 60, "events": [{"type": "gnss_outage", "at": "5 min"}]}
    )


# ------------------------------------------------------- criteria metrics vs the scorer
#: Numbers in summary.json that are not pass criteria: bookkeeping, scoring settings, curves.
NOT_CRITERIA = {
    "schema_version", "seed", "wall_s", "nees.nees_dof", "outages.drift.step_s",
    "outages.drift.horizontal_m", "scoring.reconverge_threshold_m", "scoring.reconverge_hold_s",
    "scoring.bad_fix_m",
    # a flag (true / false; null for an event without a re-accept check), not a number
    "events.reaccepted_early",
}


def _numeric_paths(node: Any, prefix: str = "") -> set[str]:
    """Dotted paths of the number (or null) leaves; lists of objects fan out like criteria."""
    if isinstance(node, dict):
        out: set[str] = set()
        for key, value in node.items():
            out |= _numeric_paths(value, f"{prefix}.{key}" if prefix else str(key))
        return out
    if isinstance(node, list) and all(isinstance(v, dict) for v in node):
        return set().union(set(), *(_numeric_paths(v, prefix) for v in node))
    if isinstance(node, list) or (isinstance(node, int | float | None)
                                  and not isinstance(node, bool)):
        return {prefix}
    return set()


def _full_summary() -> dict[str, Any]:
    """A scored run that fills every part of summary.json: a 130 s outage, a spoof event and
    one event per other sensor, sigmas, and a health series with every counter and the fixes."""
    t = np.round(np.arange(0.0, 320.0, 0.1), 6)
    n = t.size
    lat0, lon0 = math.radians(47.0), math.radians(8.0)
    r_n, r_e = (float(r) for r in earth.principal_radii(lat0))
    east = 40.0 * t
    err_n = 1.0 + np.clip(t - 100.0, 0.0, 130.0) * (t < 230.0)
    sigma = np.tile([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.01], (n, 1))

    def track(north: np.ndarray, sig: np.ndarray | None = None) -> Track:
        return Track(t, lat0 + north / r_n, lon0 + east / (r_e * math.cos(lat0)),
                     np.full(n, 500.0), np.zeros((n, 3)), np.zeros((n, 3)), sig)

    truth, est = track(np.zeros(n)), track(err_n, sigma)
    fix_t = t[((t < 100.0) | (t >= 230.0)) & (np.round(t * 10) % 2 == 0)]
    spoof = (fix_t >= 260.0) & (fix_t < 290.0)
    fixes = Fixes(fix_t, lat0 + spoof * 500.0 / r_n, np.interp(fix_t, t, truth.lon_rad),
                  np.full(fix_t.size, 500.0))
    counter = np.searchsorted(fix_t, t, side="right").astype(np.int64)
    rejected = np.searchsorted(fix_t[spoof], t, side="right").astype(np.int64)
    health = HealthSeries(
        t, mode=np.where((t > 101.0) & (t < 230.0), "free-inertial", "gnss"),
        gnss_fused=counter, gnss_rejected=rejected, gnss_resets=counter,
        gnss_quality_rejected=counter, baro_fused=counter, baro_rejected=counter,
        baro_resets=counter, mag_fused=counter, mag_rejected=counter,
        airspeed_blockages=counter, fixes=fixes)
    # one event per sensor, so that every detect_s_by_sensor list has a value
    others = [{"type": name, "start_s": 300.0, "end_s": 310.0} for name in (
        "baro_glitch", "mag_anomaly", "imu_bias_step", "pitot_blockage", "solar_flare")]
    summary, _ = build_summary(
        RunInfo("full", 1, 320.0, 1.0, "none", "ekf"), est, truth, [Window(100.0, 230.0)],
        settle_s=20.0, health={"filter": {"gnss_fused": 1}}, series=health,
        events=[{"type": "gnss_spoof_hijack", "start_s": 260.0, "end_s": 290.0}, *others],
        scoring=ScoringConfig(bad_fix_m=50.0))
    return summary


def test_known_metrics_are_exactly_what_the_scorer_produces() -> None:
    # GIVEN a scored run that fills every section of summary.json
    produced = {p for p in _numeric_paths(_full_summary()) if not p.startswith("health.")}
    # THEN every number in it is either a criterion metric or named as bookkeeping, and every
    # criterion metric the schema accepts is there: adding or renaming a metric in the scorer
    # without updating KNOWN_METRICS (or the reverse) fails here
    assert NOT_CRITERIA <= produced
    assert sorted(produced - NOT_CRITERIA - set(KNOWN_METRICS)) == []
    assert sorted(set(KNOWN_METRICS) - produced) == []


def test_wind_keys_reach_the_flight(tmp_path: Path) -> None:
    cfg = load_scenario(write(tmp_path, """
        duration_s: 60
        wind_ned_mps: [8, -4, 0.5]
        wind_shear_exponent: 0.143
        wind_ref_agl_m: 800
        turbulence: light
    """)).flight_config()
    assert (cfg.wind_ned_mps, cfg.wind_shear_exponent, cfg.wind_ref_agl_m) == (
        (8.0, -4.0, 0.5), 0.143, 800.0)
    assert cfg.turbulence == 0.43 and cfg.wind_varies_with_altitude
    table = load_scenario(write(tmp_path, """
        duration_s: 60
        wind_table: [[500, 0, 2], [1500, 10, 2]]
    """)).flight_config()
    assert table.wind_table == ((500.0, 0.0, 2.0), (1500.0, 10.0, 2.0))
    assert table.wind_at(1000.0, 1000.0) == (5.0, 2.0, 0.0)


def test_the_scenario_date_reaches_the_magnetometer_and_the_filter(tmp_path: Path) -> None:
    from physconst.geomag import DEFAULT_DECIMAL_YEAR
    from scenarios.runner import filter_config

    dated = load_scenario(write(tmp_path, "name: x\nduration_s: 60\ndate: 2016-07-02\n"))
    assert dated.decimal_year == pytest.approx(2016.5, abs=0.01)
    assert dated.sensor_config().decimal_year == dated.decimal_year
    assert filter_config(dated).mag.decimal_year == dated.decimal_year
    plain = load_scenario(write(tmp_path, "name: y\nduration_s: 60\n", "plain.yaml"))
    assert plain.sensor_config().decimal_year == DEFAULT_DECIMAL_YEAR
    assert filter_config(plain).mag.decimal_year == DEFAULT_DECIMAL_YEAR
    err = error_of(write(tmp_path, "name: z\nduration_s: 60\ndate: next tuesday\n", "bad.yaml"))
    assert err.key == "date"
