"""ArduPilot servo outputs -> PX4-order controls (hil.autopilot.servos)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from hil.autopilot.servos import ServoMap
from sim.vehicle_state import CONTROL_INDEX

ROLL, PITCH, YAW, THROTTLE = (CONTROL_INDEX[k] for k in ("roll", "pitch", "yaw", "throttle"))


def test_default_map_is_arduplane_outputs_with_px4_signs() -> None:
    # GIVEN ArduPlane's outputs 1 aileron, 2 elevator, 3 throttle, 4 rudder at 1000-2000 us
    m = ServoMap.default()
    # WHEN the aileron is full right, the elevator half up, throttle 3/4 and rudder neutral
    out = m.controls([2000, 1750, 1750, 1500])
    # THEN PX4's order and signs: + roll right, + nose up, throttle 0..1
    assert out.controls[ROLL] == 1.0 and out.controls[PITCH] == 0.5
    assert out.controls[THROTTLE] == 0.75 and out.controls[YAW] == 0.0
    assert (out.clipped, out.undriven) == (0, 0)
    assert m.controls([1000, 1250, 1000, 1000]).controls[:4] == (-1.0, -0.5, -1.0, 0.0)


def test_out_of_range_pwm_is_clipped_and_an_undriven_output_holds() -> None:
    out = ServoMap.default().controls([2500, 0, 900, 65535])
    assert out.controls[ROLL] == 1.0 and out.controls[THROTTLE] == 0.0
    assert math.isnan(out.controls[PITCH]) and math.isnan(out.controls[YAW])
    assert (out.clipped, out.undriven) == (2, 2)


def test_pwm_is_the_inverse_of_controls() -> None:
    m = ServoMap.from_mapping({"channels": [
        {"servo": 1, "control": "aileron", "reversed": True},
        {"servo": 2, "control": "elevator", "pwm_min_us": 1100, "pwm_trim_us": 1400,
         "pwm_max_us": 1900},
        {"servo": 7, "control": "throttle", "reversed": True},
        {"servo": 4, "control": "rudder"},
    ]})
    controls = [0.3, -0.6, 0.2, 0.8]
    pwm = m.pwm(controls)
    assert pwm[0] < 1500  # reversed aileron: roll right is below the trim
    assert pwm[6] == 1200 and pwm[2] == 0  # reversed throttle on output 7; output 3 unmapped
    back = m.controls(pwm).controls
    assert back[:4] == pytest.approx(controls, abs=1.0 / 250)  # 1 us of PWM resolution


def test_load_reads_the_documented_yaml(tmp_path: Path) -> None:
    path = tmp_path / "servos.yaml"
    path.write_text("channels:\n  - {servo: 1, control: aileron}\n"
                    "  - {servo: 2, control: elevator}\n  - {servo: 3, control: throttle}\n"
                    "  - {servo: 4, control: rudder}\n  - {servo: 5, control: flaps}\n")
    m = ServoMap.load(path)
    out = m.controls([1500, 1500, 1000, 1500, 1500])
    assert out.controls[CONTROL_INDEX["flaps"]] == 0.0


@pytest.mark.parametrize(("text", "words"), [
    ("channels: []\n", "non-empty list"),
    ("chanels:\n  - {servo: 1, control: aileron}\n", "one key 'channels'"),
    ("channels:\n  - {servo: 17, control: aileron}\n", "channel 1: servo"),
    ("channels:\n  - {servo: 1, control: wings}\n", "channel 1: control"),
    ("channels:\n  - {servo: 1, control: aileron, pwm_trim_us: 900}\n", "pwm_min_us <"),
    ("channels:\n  - {servo: 1, control: aileron}\n  - {servo: 1, control: rudder}\n",
     "more than once"),
    ("channels: [\n", "cannot read"),
])
def test_a_bad_file_is_one_clear_error(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=words) as info:
        ServoMap.load(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_missing_file_names_the_file(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="cannot read it"):
        ServoMap.load(tmp_path / "nope.yaml")
