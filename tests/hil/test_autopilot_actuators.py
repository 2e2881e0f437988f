"""Tests of the actuator map (hil.autopilot.actuators): HIL_ACTUATOR_CONTROLS channels -> the
control vector the flight takes."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from hil.autopilot.actuators import ActuatorMap

REPO = Path(__file__).resolve().parents[2]
STANDARD_PLANE = REPO / "docs" / "autopilot" / "px4-standard-plane.yaml"


def test_the_default_is_the_legacy_hil_order() -> None:
    amap = ActuatorMap.default()
    raw = [0.1, -0.2, 0.3, 0.6, 0.9] + [0.0] * 11
    assert amap.apply(raw) == [0.1, -0.2, 0.3, 0.6]  # channel 4 is not fed: flaps hold


def test_the_standard_plane_example_mixes_ailerons_flaps_and_moves_the_motor() -> None:
    amap = ActuatorMap.load(STANDARD_PLANE)
    # what PX4's allocation sends for roll r=0.4, pitch 0.2, yaw -0.1, motor 0.7, flaps 0.5
    raw = [0.0] * 16
    raw[5], raw[6] = -0.4, 0.4  # left, right aileron
    raw[7], raw[2], raw[4] = 0.2, -0.1, 0.7
    raw[3], raw[8] = 0.5, -0.5  # left flap, right flap (output reversed)
    roll, pitch, yaw, throttle, flaps = amap.apply(raw)
    assert (roll, pitch, yaw, throttle, flaps) == pytest.approx((0.4, 0.2, -0.1, 0.7, 0.5))


def test_the_standard_plane_map_steers_the_nose_wheel_with_the_rudder() -> None:
    # PWM_MAIN_FUNC1 = 440 (Landing Gear Wheel): PX4's wheel steering adds to the rudder
    amap = ActuatorMap.load(STANDARD_PLANE)
    raw = [0.0] * 16
    raw[0], raw[2] = 0.3, -0.1  # wheel steering right, rudder left
    assert amap.apply(raw)[2] == pytest.approx(0.2)


def test_a_nan_channel_makes_its_control_nan_and_a_pinned_control_ignores_it() -> None:
    amap = ActuatorMap.model_validate({"channels": [
        {"channel": 0, "control": "aileron"}, {"channel": 1, "control": "elevator"},
        {"channel": 2, "control": "rudder", "scale": 0.0, "offset": 0.0},
        {"channel": 3, "control": "throttle", "scale": 0.5, "offset": 0.5},
    ]})
    out = amap.apply([math.nan, 0.1, math.nan, 0.0])
    assert math.isnan(out[0]) and out[1:] == [0.1, 0.0, 0.5]


@pytest.mark.parametrize(("text", "message"), [
    ("channels: [{channel: 0, control: roll}]", "no channel feeds pitch, yaw, throttle"),
    ("channels: [{channel: 16, control: roll}]", "channels.0.channel"),
    ("channels: [{channel: 0, control: wings}]", "channels.0.control"),
    ("channels: [{channel: 0, control: roll, gain: 2}]", "channels.0.gain"),
    ("channels: [{channel: 0, control: roll, scale: .nan}]", "channels.0.scale"),
    ("- 1\n- 2", "expected a mapping"),
    ("channels: [", "not valid YAML (line"),
])
def test_bad_files_are_one_line_naming_the_file_and_entry(
        tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "map.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError) as info:
        ActuatorMap.load(path)
    line = str(info.value)
    assert "\n" not in line and str(path) in line and message in line


def test_a_missing_file_is_named() -> None:
    with pytest.raises(ValueError, match="no such file"):
        ActuatorMap.load("/nonexistent/map.yaml")
