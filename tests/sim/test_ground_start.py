"""A ground start: the aircraft at rest on a runway, engine idling, for an autopilot to take off.

GIVEN a c172x placed on a runway at 450 m, heading 090, WHEN nothing moves the throttle, THEN
it stays where it is, level on its gear, with 1 g on the accelerometers and no airspeed; WHEN
full throttle and a scripted rotation are flown, THEN it leaves the runway on its heading.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from hil.autopilot.sitl_json import JsonOrigin, json_state_line
from hil.codec import mavlink2
from hil.pipeline import SimChain, SimSetup
from physconst import G0_MPS2
from physconst.airdata import calibrated_airspeed_mps
from sim.flight import Flight, FlightConfig, StartState
from sim.plans import load_plan
from sim.samples import AirspeedSample, ImuSample

FIELD_M = 450.0
HEADING_DEG = 90.0
LAT_DEG, LON_DEG = 47.0, 8.0


def _ground_flight(**start: float) -> Flight:
    config = FlightConfig(
        start=StartState(kind="ground", lat_deg=LAT_DEG, lon_deg=LON_DEG, alt_msl_m=FIELD_M,
                         heading_deg=HEADING_DEG, **start),
        control="external",
    )
    return Flight(config, load_plan("cruise"))


def _euler_deg(q_nb: np.ndarray) -> tuple[float, float, float]:
    w, x, y, z = (float(v) for v in q_nb)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw) % 360.0


def _north_east_m(lat_rad: float, lon_rad: float) -> tuple[float, float]:
    r_m = 6_371_000.0
    return ((lat_rad - math.radians(LAT_DEG)) * r_m,
            (lon_rad - math.radians(LON_DEG)) * r_m * math.cos(math.radians(LAT_DEG)))


def test_at_rest_on_the_runway_for_30_s_at_idle() -> None:
    with _ground_flight() as flight:
        first = flight.truth()
        flight.command([0.0, 0.0, 0.0, 0.0])
        truths = [flight.run_for(1.0) for _ in range(30)]
    n0, e0 = _north_east_m(first.lat_rad, first.lon_rad)
    for truth in [first, *truths]:
        n, e = _north_east_m(truth.lat_rad, truth.lon_rad)
        assert math.hypot(n - n0, e - e0) < 1.0  # no drift
        assert 0.5 < truth.alt_msl_m - FIELD_M < 2.5  # the CG over the runway, not sinking
        assert abs(truth.alt_msl_m - first.alt_msl_m) < 0.05
        roll, pitch, yaw = _euler_deg(truth.q_nb)
        assert abs(roll) < 1.0 and 0.0 <= pitch < 2.0  # the c172x's gear: +0.4 deg nose up
        assert abs(yaw - HEADING_DEG) < 0.5
        assert truth.airspeed_mps < 0.3
        assert float(np.linalg.norm(truth.v_ned_mps)) < 0.05
        np.testing.assert_allclose(truth.specific_force_b_mps2, (0.0, 0.0, -G0_MPS2), atol=0.2)


def test_takes_off_under_full_throttle_and_a_scripted_rotation() -> None:
    """Full throttle, the rudder (nose wheel) holding the heading, wings level, rotate at
    28 m/s to 8 deg of pitch: the ground roll stays on the centre line and the aircraft
    climbs away on the runway heading."""
    with _ground_flight() as flight:
        truth = flight.truth()
        n0, e0 = _north_east_m(truth.lat_rad, truth.lon_rad)
        lift_off: tuple[float, float, float] | None = None  # time, north, east
        for k in range(60 * 50):
            roll, pitch, yaw = _euler_deg(truth.q_nb)
            heading_error = (HEADING_DEG - yaw + 180.0) % 360.0 - 180.0
            rotate = truth.airspeed_mps > 28.0
            elevator = min(max(0.05 * (8.0 - pitch), -0.5), 0.5) if rotate else 0.0
            flight.command([min(max(-0.2 * roll, -1.0), 1.0), elevator,
                            min(max(0.1 * heading_error, -1.0), 1.0), 1.0])
            truth = flight.run_for(0.02)
            if lift_off is None and truth.alt_msl_m - FIELD_M > 3.0:
                lift_off = (k * 0.02, *_north_east_m(truth.lat_rad, truth.lon_rad))
            if truth.alt_msl_m - FIELD_M > 30.0:
                break
    assert lift_off is not None
    lift_off_s, n_lift, e_lift = lift_off
    assert 10.0 < lift_off_s < 40.0
    assert abs(n_lift - n0) < 10.0  # on a 30 m runway (090: east), by a crude P law
    assert 150.0 < e_lift - e0 < 600.0  # the ground roll
    assert truth.alt_msl_m - FIELD_M > 30.0
    assert abs(_euler_deg(truth.q_nb)[2] - HEADING_DEG) < 10.0
    assert truth.airspeed_mps > 25.0


def test_the_autopilot_first_sees_an_aircraft_at_rest() -> None:
    """The first HIL_SENSOR PX4 reads and the first state line ArduPilot's JSON interface
    reads: no airspeed, 1 g up, no motion."""
    setup = SimSetup.build(plan="cruise", duration_s=2.0, start_kind="ground",
                           alt_msl_m=FIELD_M, heading_deg=HEADING_DEG)
    setup = dataclasses.replace(setup, flight=setup.flight.model_copy(
        update={"control": "external"}))
    imu: ImuSample | None = None
    pitot: AirspeedSample | None = None
    parser = mavlink2.MAVLink(None)
    hil_sensor = None
    with SimChain(setup) as chain:
        for step in chain.steps():
            for _, frame in step.frames:
                for message in parser.parse_buffer(frame) or []:
                    if message.get_type() == "HIL_SENSOR" and hil_sensor is None:
                        hil_sensor = message
            for sample in step.samples:
                if isinstance(sample, ImuSample) and imu is None:
                    imu = sample
                if isinstance(sample, AirspeedSample) and pitot is None:
                    pitot = sample
            if imu is not None and pitot is not None and hil_sensor is not None:
                truth = step.truth
                break
    assert imu is not None and pitot is not None and hil_sensor is not None
    # PX4's view: HIL_SENSOR (m/s^2, rad/s, hPa)
    np.testing.assert_allclose((hil_sensor.xacc, hil_sensor.yacc, hil_sensor.zacc),
                               (0.0, 0.0, -G0_MPS2), atol=0.3)
    np.testing.assert_allclose((hil_sensor.xgyro, hil_sensor.ygyro, hil_sensor.zgyro),
                               (0.0, 0.0, 0.0), atol=0.01)
    assert abs(hil_sensor.diff_pressure) < 0.05  # hPa: under 3 m/s
    # ArduPilot's view: the JSON state line
    airspeed = calibrated_airspeed_mps(pitot.diff_pressure_pa)
    assert airspeed < 3.0  # the pitot's noise and offset around zero
    line = json.loads(json_state_line(truth, JsonOrigin(math.radians(LAT_DEG),
                                                        math.radians(LON_DEG), FIELD_M),
                                      imu=imu, airspeed_mps=airspeed))
    np.testing.assert_allclose(line["imu"]["accel_body"], (0.0, 0.0, -G0_MPS2), atol=0.3)
    np.testing.assert_allclose(line["imu"]["gyro"], (0.0, 0.0, 0.0), atol=0.01)
    np.testing.assert_allclose(line["velocity"], (0.0, 0.0, 0.0), atol=0.05)
    assert -2.5 < line["position"][2] < -0.5  # up from the home at the runway's elevation
    assert line["airspeed"] < 3.0


def test_hilnavs_guidance_law_does_not_fly_a_ground_start() -> None:
    config = FlightConfig(start=StartState(kind="ground", alt_msl_m=FIELD_M))
    with pytest.raises(ValueError, match="ground start needs an autopilot"):
        Flight(config, load_plan("cruise"))


def test_an_in_air_start_stays_above_100_m() -> None:
    with pytest.raises(ValueError, match="in-air start needs alt_msl_m >= 100"):
        StartState(alt_msl_m=50.0)
    assert StartState(kind="ground", alt_msl_m=0.0).terrain_alt_msl_m == 0.0
    assert StartState(kind="ground", alt_msl_m=450.0).terrain_alt_msl_m == 450.0
    assert StartState(alt_msl_m=450.0).terrain_alt_msl_m == 0.0


def test_wind_shear_from_the_ground_needs_its_reference_height() -> None:
    start = StartState(kind="ground", alt_msl_m=FIELD_M)
    with pytest.raises(ValueError, match="wind_ref_agl_m"):
        FlightConfig(start=start, wind_ned_mps=(5.0, 0.0, 0.0), wind_shear_exponent=1 / 7)
    FlightConfig(start=start, wind_ned_mps=(5.0, 0.0, 0.0), wind_shear_exponent=1 / 7,
                 wind_ref_agl_m=10.0)
