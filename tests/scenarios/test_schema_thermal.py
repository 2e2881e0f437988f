"""The IMU's thermal keys (``sensors.imu.thermal``): what they build, that bad values are one
line naming the key (exit 2 on the command line), and that leaving them out changes nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from scenarios.cli.app import app
from scenarios.schema import load_scenario
from tests.scenarios.test_schema import error_of, write

THERMAL = """
    name: thermal
    duration_s: 600
    sensors:
      imu:
        preset: consumer-mems
        thermal:
          preset: bmi088
          start_temperature_c: -20
          power_on_s: -60
          ambient_offset_k: 12
          heater: {setpoint_c: 55, fails_at_s: 300}
          part: {gyro_tempco_dps_per_k: 0.02}
      baro: {sea_level_temperature_offset_k: 15}
    """


def test_thermal_keys_reach_the_sensor_suite(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, THERMAL))
    cfg = scenario.sensor_config().imu_thermal
    assert cfg is not None
    assert cfg.preset == "bmi088"
    assert cfg.part.gyro_tempco_dps_per_k == 0.02
    assert cfg.part.temperature_resolution_k == 0.125  # the rest of the preset is kept
    assert (cfg.start_temperature_c, cfg.power_on_s, cfg.ambient_offset_k) == (-20.0, -60.0, 12.0)
    assert (cfg.heater_setpoint_c, cfg.heater_fails_at_s) == (55.0, 300.0)
    record = scenario.setup_record()
    assert record["sensors"]["imu"] == "consumer-mems"
    assert record["imu_thermal"].startswith("bmi088 start_temperature_c=-20.0")


def test_no_thermal_keys_or_off_give_no_model_and_an_unchanged_record(tmp_path: Path) -> None:
    plain = load_scenario(write(tmp_path, "name: plain\nduration_s: 60\n", "a.yaml"))
    off = load_scenario(write(tmp_path, """
        name: plain
        duration_s: 60
        sensors: {imu: {thermal: {preset: off}}}
        """, "b.yaml"))
    assert plain.sensor_config().imu_thermal is None and off.sensor_config().imu_thermal is None
    assert plain.sensor_config() == off.sensor_config()
    assert "imu_thermal" not in plain.setup_record() and "imu_thermal" not in off.setup_record()
    assert off.setup_record()["sensors"]["imu"] == "industrial-mems"


@pytest.mark.parametrize(
    ("thermal", "key", "needle"),
    [
        ("{preset: bmi089}", "sensors.imu.thermal.preset", "did you mean 'bmi088'"),
        ("{preset: off, start_temperature_c: 5}", "sensors.imu.thermal",
         "remove start_temperature_c"),
        ("{preset: bmi088, power_on_s: 30}", "sensors.imu.thermal.power_on_s",
         "less than or equal to 0"),
        ("{preset: bmi088, start_temperature_c: -100}",
         "sensors.imu.thermal.start_temperature_c", "greater than or equal to -60"),
        ("{preset: bmi088, heater: {setpoint_c: 55, fails_at_s: 900}}",
         "sensors.imu.thermal.heater.fails_at_s", "end of the flight"),
        ("{preset: bmi088, heater: {fails_at_s: 9}}", "sensors.imu.thermal.heater.setpoint_c",
         "required"),
        ("{preset: bmi088, part: {knee_width_k: 0}}", "sensors.imu.thermal.part.knee_width_k",
         "greater than 0"),
        ("{preset: bmi088, part: {tempco: 1}}", "sensors.imu.thermal.part.tempco",
         "unknown key"),
    ],
)
def test_bad_thermal_values_are_one_line_naming_the_key(
        tmp_path: Path, thermal: str, key: str, needle: str) -> None:
    path = write(tmp_path, f"""
        name: bad
        duration_s: 600
        sensors:
          imu:
            thermal: {thermal}
        """)
    err = error_of(path)
    assert err.key == key
    assert needle in str(err)
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert len([ln for ln in result.output.splitlines() if ln.strip()]) == 1
    assert "Traceback" not in result.output
