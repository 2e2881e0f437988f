"""The shadow vehicle's SYS_STATUS bits and landed state follow what the sensors and the filter
did over each interval (hil/shadow_vehicle.py), one sensor at a time."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from fusion.estimate import AirDataStatus, Health, NavEstimate
from hil.codec import mavlink2
from hil.shadow import ShadowEncoder
from hil.shadow_vehicle import ShadowVehicle
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample
from tests.hil.test_service import _estimate

IMU = int(mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL)
MAG = int(mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG)
BARO = int(mavlink2.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE)
GNSS = int(mavlink2.MAV_SYS_STATUS_SENSOR_GPS)
PITOT = int(mavlink2.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE)
AHRS = int(mavlink2.MAV_SYS_STATUS_AHRS)
ALL = IMU | MAG | BARO | GNSS | PITOT | AHRS


def _feed(v: ShadowVehicle, t_us: int, *, fix_type: int = 3, gnss: bool = True) -> None:
    """One sample of every sensor at ``t_us`` (GNSS optional)."""
    v.on_sample(ImuSample(t_us, 0.005, np.zeros(3), np.zeros(3)))
    v.on_sample(BaroSample(t_us, 90_000.0, 280.0))
    v.on_sample(MagSample(t_us, np.array([2e-5, 0.0, 4e-5])))
    v.on_sample(AirspeedSample(t_us, 900.0, 280.0))
    if gnss:
        v.on_sample(GnssFix(t_us, 0.8, 0.1, 1000.0, np.zeros(3), 1.0, 2.0, 0.1,
                            fix_type=fix_type))


def _est(t_us: int, health: Health, **kw: Any) -> NavEstimate:
    return dataclasses.replace(_estimate(), time_us=t_us, health=health, **kw)


def _vehicle(**kw: Any) -> ShadowVehicle:
    v = ShadowVehicle(ShadowEncoder(7), **kw)
    _feed(v, 1_000_000)
    v.sensor_bits(_est(1_000_000, Health(mag_fused=1, baro_fused=1, gnss_fused=1)))
    return v


def test_nothing_known_before_samples_and_estimates() -> None:
    v = ShadowVehicle(ShadowEncoder(7))
    bits = v.sensor_bits(None)
    assert (bits.present, bits.enabled, bits.health) == (AHRS, AHRS, 0)
    assert v.in_air(None) is None


def test_all_healthy_in_a_good_interval_and_pitot_disabled_when_air_data_is_off() -> None:
    v = _vehicle()
    _feed(v, 2_000_000)
    bits = v.sensor_bits(_est(2_000_000, Health(mag_fused=2, baro_fused=2, gnss_fused=2)))
    assert (bits.present, bits.enabled, bits.health) == (ALL, ALL, ALL)
    off = _vehicle(airspeed_enabled=False)
    _feed(off, 2_000_000)
    bits = off.sensor_bits(_est(2_000_000, Health(mag_fused=2, baro_fused=2, gnss_fused=2)))
    assert bits.present & PITOT and not bits.enabled & PITOT


@pytest.mark.parametrize(
    ("health", "kw", "unhealthy"),
    [
        (Health(mag_fused=1, mag_rejected=3, baro_fused=2, gnss_fused=2), {}, MAG),
        (Health(mag_fused=2, baro_fused=1, baro_rejected=3, gnss_fused=2), {}, BARO),
        (Health(mag_fused=2, baro_fused=2, baro_frozen=1, gnss_fused=2), {}, BARO),
        (Health(mag_fused=2, baro_fused=2, gnss_fused=2, imu_nan=1), {}, IMU),
        (Health(mag_fused=2, baro_fused=2, gnss_fused=2, airspeed_invalid=1), {}, PITOT),
        (Health(mag_fused=2, baro_fused=2, gnss_fused=2),
         {"air_data": AirDataStatus("blocked", True, fault="stuck")}, PITOT),
        (Health(mag_fused=2, baro_fused=2, gnss_fused=2, time_rebases=1), {}, AHRS),
        # fixes arrive but the filter has not fused one for 3 s (rejected: a possible spoofer)
        (Health(mag_fused=2, baro_fused=2, gnss_fused=1, gnss_rejected=5),
         {"time_since_gnss_s": 3.0}, GNSS),
    ],
)
def test_each_fault_clears_only_its_own_health_bit(health: Health, kw: dict[str, Any],
                                                   unhealthy: int) -> None:
    v = _vehicle()
    _feed(v, 2_000_000)
    bits = v.sensor_bits(_est(2_000_000, health, **kw))
    assert bits.health == ALL & ~unhealthy
    assert bits.present == ALL  # a fault does not make a sensor absent


def test_gnss_unhealthy_without_a_recent_3d_fix() -> None:
    v = _vehicle()
    _feed(v, 2_000_000, fix_type=2)  # 2-D fix
    bits = v.sensor_bits(_est(2_000_000, Health(mag_fused=2, baro_fused=2, gnss_fused=2)))
    assert bits.health == ALL & ~GNSS
    v = _vehicle()
    _feed(v, 4_000_000, gnss=False)  # the last fix is 3 s old: an outage
    est = _est(4_000_000, Health(mag_fused=2, baro_fused=2, gnss_fused=1),
               time_since_gnss_s=3.0)
    bits = v.sensor_bits(est)
    assert bits.health == ALL & ~GNSS and v.fix_lost(est)  # GPS_RAW_INT says NO_FIX


def test_in_air_from_speed_or_height_above_home() -> None:
    v = _vehicle()
    fast = _est(2_000_000, Health())  # 50 m/s
    v.enc.global_position_int(fast)  # sets home at the first aligned estimate
    assert v.in_air(fast) is True
    parked = dataclasses.replace(fast, v_ned_mps=np.zeros(3))
    assert v.in_air(parked) is False
    climbed = dataclasses.replace(parked, alt_msl_m=fast.alt_msl_m + 15.0)
    assert v.in_air(climbed) is True
    assert v.in_air(dataclasses.replace(fast, mode="initializing")) is None
