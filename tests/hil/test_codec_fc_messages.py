"""hil.codec: decoding the messages a real flight controller sends (HIGHRES_IMU, SCALED_IMU,
RAW_IMU, GPS_RAW_INT, SCALED_PRESSURE, ...) into SI samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.codec import Decoder, Encoder, RawImuScale, mavlink2
from sim.samples import AirspeedSample, GnssFix
from tests.hil.codec_helpers import G0, one, parse_raw


# --- messages from a real flight controller ------------------------------------------------
def _fc_frames() -> dict[str, bytes]:
    fc = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    msgs = {
        "HIGHRES_IMU": mavlink2.MAVLink_highres_imu_message(
            2_000_000,
            0.5,
            -0.25,
            -9.75,
            0.125,
            -0.0625,
            0.03125,
            0.2,
            0.01,
            0.4,
            1001.5,
            0.0,
            110.0,
            31.5,
            0x1FFF,
            0,
        ),
        "SCALED_IMU": mavlink2.MAVLink_scaled_imu_message(
            1500, 100, -50, -1000, 10, -20, 30, 200, 10, 400, 3150
        ),
        "SCALED_IMU2": mavlink2.MAVLink_scaled_imu2_message(1500, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 0),
        "SCALED_IMU3": mavlink2.MAVLink_scaled_imu3_message(
            1500, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 100
        ),
        "RAW_IMU": mavlink2.MAVLink_raw_imu_message(
            2_000_000, 100, -50, -1000, 10, -20, 30, 200, 10, 400, 0, 0
        ),
        "GPS_RAW_INT": mavlink2.MAVLink_gps_raw_int_message(
            3_000_000,
            3,
            473_977_420,
            85_455_940,
            488_120,
            90,
            150,
            1000,
            9000,
            14,
            0,
            1200,
            2400,
            300,
            0,
            0,
        ),
        "SCALED_PRESSURE": mavlink2.MAVLink_scaled_pressure_message(1500, 1001.5, 0.25, 2150),
        "SCALED_PRESSURE3": mavlink2.MAVLink_scaled_pressure3_message(1500, 1000.0, 0.0, -500),
        "ATTITUDE": mavlink2.MAVLink_attitude_message(1500, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0),
    }
    out = {}
    for name, m in msgs.items():
        out[name] = m.pack(fc)
        fc.seq += 1
    return out


def test_flight_controller_messages_decode_to_si() -> None:
    frames = _fc_frames()
    dec = Decoder(raw_imu_scale=RawImuScale.milli_units())

    imu, mag, baro, airspeed = one(dec, frames["HIGHRES_IMU"])
    assert isinstance(airspeed, AirspeedSample)
    assert airspeed.diff_pressure_pa == 0.0  # bit 10 set with 0 hPa: a finite reading passes
    assert airspeed.temperature_k == pytest.approx(304.65)
    assert imu.specific_force_b_mps2.tolist() == [0.5, -0.25, -9.75]
    assert imu.angular_rate_b_rps.tolist() == [0.125, -0.0625, 0.03125]
    assert imu.temperature_k == pytest.approx(304.65)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])
    assert baro.pressure_pa == pytest.approx(100_150.0)

    imu, mag = one(dec, frames["SCALED_IMU"])
    assert imu.time_us == 1_500_000 and imu.sensor_id == 0
    assert imu.specific_force_b_mps2 == pytest.approx(np.array([0.1, -0.05, -1.0]) * G0)
    assert imu.angular_rate_b_rps == pytest.approx([0.01, -0.02, 0.03])
    assert imu.temperature_k == pytest.approx(304.65)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])

    (imu2,) = one(dec, frames["SCALED_IMU2"])  # all-zero field: no magnetometer
    assert imu2.sensor_id == 1 and math.isnan(imu2.temperature_k)  # 0 cdegC: not provided
    (imu3,) = one(dec, frames["SCALED_IMU3"])
    assert imu3.sensor_id == 2 and imu3.temperature_k == pytest.approx(274.15)

    imu, mag = one(dec, frames["RAW_IMU"])
    assert imu.specific_force_b_mps2 == pytest.approx(np.array([0.1, -0.05, -1.0]) * G0)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])

    (fix,) = one(dec, frames["GPS_RAW_INT"])
    assert math.degrees(fix.lat_rad) == pytest.approx(47.397742, abs=1e-9)
    assert math.degrees(fix.lon_rad) == pytest.approx(8.545594, abs=1e-9)
    assert fix.alt_msl_m == pytest.approx(488.12)
    assert fix.v_ned_mps[:2] == pytest.approx([0.0, 10.0], abs=1e-12)  # 10 m/s due east
    assert math.isnan(fix.v_ned_mps[2])  # GPS_RAW_INT has no vertical velocity
    assert (fix.eph_m, fix.epv_m, fix.speed_accuracy_mps) == pytest.approx((1.2, 2.4, 0.3))
    assert fix.satellites_visible == 14

    (b,) = one(dec, frames["SCALED_PRESSURE"])
    assert (b.time_us, b.pressure_pa, b.temperature_k) == pytest.approx(
        (1_500_000, 100_150.0, 294.65)
    )
    (b3,) = one(dec, frames["SCALED_PRESSURE3"])
    assert b3.sensor_id == 2 and b3.temperature_k == pytest.approx(268.15)

    assert one(dec, frames["ATTITUDE"]) == []
    assert dec.counters.ignored_msgs == 1
    assert dec.counters.samples == 13  # HIGHRES_IMU: IMU, mag, baro, airspeed


def test_raw_imu_needs_an_explicit_scale() -> None:
    frame = _fc_frames()["RAW_IMU"]
    dec = Decoder()
    assert dec.feed(frame) == []
    assert dec.counters.unscaled_raw_imu == 1
    scaled = Decoder(raw_imu_scale=RawImuScale(accel_mps2_per_lsb=0.01, gyro_rps_per_lsb=0.001))
    (imu,) = one(scaled, frame)  # no magnetometer scale: no MagSample
    assert imu.specific_force_b_mps2 == pytest.approx([1.0, -0.5, -10.0])
    with pytest.raises(ValueError, match="accel_mps2_per_lsb"):
        RawImuScale(accel_mps2_per_lsb=-1.0, gyro_rps_per_lsb=0.001)
    with pytest.raises(ValueError, match="extra"):
        RawImuScale(accel_mps2_per_lsb=1.0, gyro_rps_per_lsb=0.001, typo=1.0)  # type: ignore[call-arg]


def test_gps_raw_int_unknowns_are_nan() -> None:
    fc = mavlink2.MAVLink(None, 1, 1)
    frame = mavlink2.MAVLink_gps_raw_int_message(
        1, 3, 0, 0, 0, 65535, 65535, 65535, 65535, 255
    ).pack(fc)
    (fix,) = one(Decoder(), frame)
    assert np.isnan(fix.v_ned_mps).all()
    assert math.isnan(fix.eph_m) and math.isnan(fix.epv_m) and math.isnan(fix.speed_accuracy_mps)


def test_decode_message_accepts_pymavlink_objects() -> None:
    frame = Encoder().gnss(GnssFix(9, 0.5, 0.1, 1.0, np.zeros(3), 1.0, 2.0, 0.1))
    msg = parse_raw(frame)
    dec = Decoder()
    (item,) = dec.decode_message(msg)
    assert item.msg_id == mavlink2.MAVLINK_MSG_ID_HIL_GPS and item.sample.time_us == 9
    assert dec.decode_message(mavlink2.MAVLink_bad_data(b"\x01", "Bad prefix")) == []
    assert dec.counters.garbage_bytes == 1
