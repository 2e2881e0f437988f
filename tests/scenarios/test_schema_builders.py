"""What a scenario builds: the flight, sensors, plan and filter configuration, with overrides
and defaults, and keys such as the wind and the date reaching the models."""


from __future__ import annotations

from pathlib import Path

import pytest

from scenarios.schema import (
    ALTITUDE_METHODS,
    BRIDGE_METHODS,
    Scenario,
    ScenarioError,
    load_scenario,
)
from tests.scenarios.test_schema import error_of, write


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
        "none", "gmdh", "gmdh-pseudo", "mlp", "rbf", "bp-parallel", "gmdh-airspeed", "gmdh-wind",
        "gmdh-pitot", "gmdh-thermal",
    )
    assert ALTITUDE_METHODS == ("ekf", "loop", "loop-mpc", "loop-kf")


def test_model_is_frozen_and_strict() -> None:
    scenario = Scenario.model_validate({"duration_s": 60})
    with pytest.raises(ValueError):
        setattr(scenario, "seed", 3)  # noqa: B010 - the point is the plain assignment
    with pytest.raises(ValueError, match="Extra inputs"):
        Scenario.model_validate({"duration_s": 60, "sead": 1})




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
