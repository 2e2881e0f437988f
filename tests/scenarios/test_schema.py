"""Scenario files: validation and error messages (file, line, key), one line for the user."""


from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest

from scenarios.schema import (
    Scenario,
    ScenarioError,
    load_scenario,
)
from sim import faults


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
