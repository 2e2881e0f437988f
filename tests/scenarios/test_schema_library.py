"""The shipped scenario library: every file validates, builds, and matches the JSON Schema;
the library covers the papers' settings and the rehearsals."""


from __future__ import annotations

import json
import math
import re
from pathlib import Path

import jsonschema
import pytest
import yaml

from scenarios.schema import (
    Scenario,
    json_schema,
    list_library,
    load_scenario,
)
from sim import faults
from sim.flight import FlightConfig
from sim.plans import FlightPlan
from sim.sensors import SensorSuite, SensorSuiteConfig

LIBRARY = list_library()


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
    """The long-denial air-data scenarios: 300 s and 900 s outages in survey, climb-descent
    and racetrack flight, wind up to 12 m/s with turbulence and shear, pitot blockages
    (stuck, zero) inside an outage, an aircraft without a pitot on synthetic airspeed; every
    one gated at 300 s into the outage."""
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


def test_the_scenarios_page_lists_every_library_file() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "scenarios.md").read_text("utf-8")
    listed = set(re.findall(r"^\| `([a-z0-9-]+\.yaml)` \|", page, flags=re.MULTILINE))
    assert listed == {p.name for p in LIBRARY}
    assert f"holds {len(LIBRARY)} scenarios" in page


def test_library_covers_the_thermal_rehearsals() -> None:
    """A warm-up outage (power-on at the start, GNSS lost within 10 min), a cold soak in a
    climb, a hot day and a heater failure inside an outage, each on a thermal IMU preset."""
    thermal = {}
    for p in LIBRARY:
        s = load_scenario(p)
        t = s.sensor_config().imu_thermal
        if t is not None:
            thermal[p.stem] = (s, t)
    warm = thermal["thermal-warmup-outage"]
    (outage,) = warm[0].fault_events()
    assert isinstance(outage, faults.GnssOutage)
    assert warm[1].power_on_s == 0.0 and outage.start_s < 600.0 and outage.duration_s == 300.0
    cold = thermal["thermal-cold-soak-climb"]
    assert cold[1].start_temperature_c is not None and cold[1].start_temperature_c < 0.0
    assert cold[0].plan == "climb-descent"
    hot = thermal["thermal-hot-day"]
    assert hot[0].sensor_config().baro.sea_level_temperature_offset_k > 0.0
    heater = thermal["thermal-heater-failure"]
    fails = heater[1].heater_fails_at_s
    (outage,) = heater[0].fault_events()
    assert isinstance(outage, faults.GnssOutage) and outage.duration_s is not None
    assert fails is not None and outage.start_s < fails < outage.start_s + outage.duration_s
    assert {t.preset for _, t in thermal.values()} >= {"bmi088", "icm42688p", "adis1646x"}
