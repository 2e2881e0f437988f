"""hil.thermal_cal: PX4 and ArduPilot thermal calibration files, and ``--thermal-cal`` bad
input."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from hil.thermal_cal import (
    calibration_from_params,
    load_calibration,
    px4_params,
    read_params,
    thermal_tuning,
)
from scenarios.cli.app import app

_AP = """# ArduPilot, as INS_TCAL1 learning saves it
INS_TCAL1_ENABLE,1
INS_TCAL1_TMIN,20.5
INS_TCAL1_TMAX,55.0
INS_TCAL1_ACC1_X,100
INS_TCAL1_ACC1_Y,0
INS_TCAL1_ACC1_Z,0
INS_TCAL1_ACC2_X,0
INS_TCAL1_ACC2_Y,0
INS_TCAL1_ACC2_Z,0
INS_TCAL1_ACC3_X,0
INS_TCAL1_ACC3_Y,0
INS_TCAL1_ACC3_Z,0
INS_TCAL1_GYR1_X,0
INS_TCAL1_GYR1_Y,0
INS_TCAL1_GYR1_Z,200
INS_TCAL1_GYR2_X,0
INS_TCAL1_GYR2_Y,0
INS_TCAL1_GYR2_Z,3
INS_TCAL1_GYR3_X,0
INS_TCAL1_GYR3_Y,0
INS_TCAL1_GYR3_Z,0
"""


def test_ardupilot_polynomial_is_scaled_and_referenced_to_35_degc() -> None:
    cal = calibration_from_params(read_params(_AP))
    assert cal.source == "ardupilot"
    # at 45 degC: x = 10 K, (200 x + 3 x^2) 1e-6, minus nothing at the 35 degC reference
    g, a = cal.offsets(273.15 + 45.0)
    assert g[2] == pytest.approx((200 * 10 + 3 * 100) * 1e-6)
    assert a[0] == pytest.approx(100 * 10 * 1e-6)
    assert cal.offsets(273.15 + 35.0) == ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    # clamped below TMIN
    assert cal.offsets(273.15) == cal.offsets(273.15 + 20.5)


def test_px4_file_round_trips(tmp_path: Path) -> None:
    cal = calibration_from_params(read_params(_AP))
    text = px4_params(cal)
    assert "TC_G0_X1_2" in text and "TC_A0_TREF" in text
    path = tmp_path / "unit.params"
    path.write_text(text)
    px4 = load_calibration(path)
    assert px4.source == "px4"
    for t in (290.0, 300.0, 320.0):
        g0, a0 = cal.offsets(t)
        g1, a1 = px4.offsets(t)
        assert g1 == pytest.approx(g0, abs=1e-12) and a1 == pytest.approx(a0, abs=1e-12)


@pytest.mark.parametrize("text, words", [
    ("TC_G0_X0_0 1\n", "missing parameter"),
    ("INS_TCAL1_ENABLE 0\n", "not 1"),
    ("FOO 1\n", "no PX4"),
    ("TC_G0_X0_0 abc\n", "no number"),
])  # fmt: skip
def test_bad_calibration_files_name_the_problem(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.parm"
    path.write_text(text)
    with pytest.raises(ValueError, match=words):
        load_calibration(path)


def test_thermal_options() -> None:
    assert thermal_tuning("states").mode == "states"
    with pytest.raises(ValueError, match="needs --thermal-cal"):
        thermal_tuning("cal")
    with pytest.raises(ValueError, match="unknown thermal mode"):
        thermal_tuning("warm")


def test_replay_with_a_bad_calibration_file_exits_2_with_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.parm"
    bad.write_text("INS_TCAL1_ENABLE 1\n")
    log = tmp_path / "x.tlog"
    log.write_bytes(b"")
    result = CliRunner().invoke(app, ["replay", str(log), "--out", str(tmp_path / "o"),
                                      "--thermal-cal", str(bad)])  # fmt: skip
    assert result.exit_code == 2
    assert "thermal calibration" in result.output and "Traceback" not in result.output


def test_thermal_part_sets_the_tempcos_and_a_bad_one_exits_2(tmp_path: Path) -> None:
    from hil.thermal_cal import command_thermal_tuning

    adis = command_thermal_tuning("blind", part="adis1646x")
    bmi = command_thermal_tuning("blind")
    assert adis.gyro_tempco_rps_per_k < bmi.gyro_tempco_rps_per_k
    assert bmi.quantum_k == 0.125 and bmi.update_period_s == 1.28
    log = tmp_path / "x.tlog"
    log.write_bytes(b"")
    result = CliRunner().invoke(app, ["replay", str(log), "--out", str(tmp_path / "o"),
                                      "--thermal", "states", "--thermal-part", "bmi99"])
    assert result.exit_code == 2 and "bmi088" in result.output
