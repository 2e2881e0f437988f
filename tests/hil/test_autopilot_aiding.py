"""hilnav's estimate as the autopilot's navigation (hil.autopilot.aiding): GPS_INPUT to
ArduPilot at 5 Hz, ODOMETRY to PX4 at 30 Hz of simulated time, nothing while the filter
initialises, and the parameters that make each autopilot use them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.estimate import Health, NavEstimate, TestRatios
from hil.autopilot.aiding import CompanionAiding, aiding_off_params, aiding_params
from hil.codec import mavlink2


def _estimate(time_us: int, mode: str = "gnss") -> NavEstimate:
    return NavEstimate(
        time_us=time_us, lat_rad=math.radians(47.0), lon_rad=math.radians(8.0),
        alt_msl_m=1000.0, v_ned_mps=np.array([50.0, 0.0, 0.0]),
        q_nb=np.array([1.0, 0.0, 0.0, 0.0]), euler_rad=np.zeros(3),
        P_diag=np.array([9.0, 16.0, 4.0, 0.01, 0.01, 0.04, 1e-4, 1e-4, 1e-3]),
        mode=mode, accel_bias_b_mps2=np.zeros(3), gyro_bias_b_rps=np.zeros(3),  # type: ignore[arg-type]
        baro_bias_m=0.0, health=Health(), test_ratios=TestRatios(), time_since_gnss_s=0.1,
        state_layout="ins16")


@pytest.mark.parametrize(("autopilot", "message", "per_s"), [
    ("ardupilot", "GPS_INPUT", 5), ("px4", "ODOMETRY", 30)])
def test_frames_at_the_companion_rate_of_simulated_time(autopilot: str, message: str,
                                                        per_s: int) -> None:
    aiding = CompanionAiding(autopilot)
    aiding.offer(_estimate(0, mode="initializing"))
    assert aiding.take_outgoing() == []
    for i in range(1, 1001):  # 4 s of estimates at 250 Hz
        aiding.offer(_estimate(1_000_000 + i * 4000))
    frames = aiding.take_outgoing()
    assert len(frames) == 4 * per_s and aiding.sent == 4 * per_s
    msg = mavlink2.MAVLink(None).parse_buffer(frames[0])[0]
    assert msg.get_type() == message
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == (1, 191)


def test_the_parameters_that_make_each_autopilot_use_them() -> None:
    assert [(p.name, p.value, p.param_type) for p in aiding_params("ardupilot")] == [
        ("GPS2_TYPE", 14.0, 9), ("GPS_AUTO_SWITCH", 1.0, 9)]
    assert [(p.name, p.value, p.param_type) for p in aiding_params("px4")] == [
        ("EKF2_EV_CTRL", 5.0, 6)]


def test_the_parameters_that_turn_it_off_for_the_unaided_autopilot() -> None:
    assert [(p.name, p.value, p.param_type) for p in aiding_off_params("ardupilot")] == [
        ("GPS2_TYPE", 0.0, 9)]
    assert [(p.name, p.value, p.param_type) for p in aiding_off_params("px4")] == [
        ("EKF2_EV_CTRL", 0.0, 6)]
