"""Decoder of flight-controller sensor messages: SCALED_IMU*, RAW_IMU, GPS_RAW_INT,
SCALED_PRESSURE* -> SI samples.

SCALED_IMU / SCALED_IMU2 / SCALED_IMU3 (sensor ids 0/1/2; mG, mrad/s, mgauss, cdegC; an
all-zero magnetic field means "no magnetometer" and yields no MagSample; temperature 0 means
"not provided" -> NaN); RAW_IMU (raw ADC counts by definition, so accepted only with an
explicit :class:`RawImuScale`, otherwise counted in ``unscaled_raw_imu`` and dropped;
ArduPilot actually fills it in mG / mrad/s / mgauss: ``RawImuScale.milli_units()``);
GPS_RAW_INT (position, ``h_acc``/``v_acc``/``vel_acc`` when non-zero, else NaN; its ``eph`` is
an HDOP, not an accuracy, and is not used; the message has no vertical velocity, so
``v_ned_mps[2]`` is NaN, and N/E are NaN when ``vel`` or ``cog`` is unknown); SCALED_PRESSURE
/ 2 / 3 (sensor ids 0/1/2). ``time_boot_ms`` is turned into ``time_us``. HIGHRES_IMU has
HIL_SENSOR's layout and is decoded by :func:`hil.codec.hil_messages.decode_hil_sensor`.
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np
from pydantic import BaseModel, ConfigDict, PositiveFloat

from hil.codec.counters import DecoderCounters
from hil.codec.sources import SourceKey, SourceState
from hil.codec.wire import (
    DEGE7_PER_RAD,
    KELVIN_AT_0_CELSIUS,
    PA_PER_HPA,
    TESLA_PER_GAUSS,
    UINT16_MAX,
    mavlink2,
)
from physconst import G0_MPS2  # MAVLink's mG is 1e-3 G0
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Sample, Truth

__all__ = [
    "SCALED_IMU_IDS",
    "SCALED_PRESSURE_IDS",
    "RawImuScale",
    "decode_gps_raw_int",
    "decode_raw_imu",
    "decode_scaled_imu",
    "decode_scaled_pressure",
]

# sensor id of each SCALED_IMU* / SCALED_PRESSURE* message id
SCALED_IMU_IDS: Final = {
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU: 0,
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU2: 1,
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU3: 2,
}
SCALED_PRESSURE_IDS: Final = {
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE: 0,
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE2: 1,
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE3: 2,
}


class RawImuScale(BaseModel):
    """Scale factors that turn RAW_IMU counts into SI (RAW_IMU is raw ADC by definition).

    Attributes
    ----------
    accel_mps2_per_lsb : float
        m/s^2 per count of ``xacc/yacc/zacc``.
    gyro_rps_per_lsb : float
        rad/s per count of ``xgyro/ygyro/zgyro``.
    mag_tesla_per_lsb : float or None
        T per count of ``xmag/ymag/zmag``; None: the magnetometer is not decoded.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    accel_mps2_per_lsb: PositiveFloat
    gyro_rps_per_lsb: PositiveFloat
    mag_tesla_per_lsb: PositiveFloat | None = None

    @classmethod
    def milli_units(cls) -> RawImuScale:
        """ArduPilot's RAW_IMU, which it fills in mG, mrad/s and mgauss like SCALED_IMU."""
        return cls(
            accel_mps2_per_lsb=G0_MPS2 * 1e-3,
            gyro_rps_per_lsb=1e-3,
            mag_tesla_per_lsb=1e-3 * TESLA_PER_GAUSS,
        )


def decode_scaled_imu(
    msg: Any, key: SourceKey, sources: SourceState, counters: DecoderCounters
) -> list[Sample | Truth]:
    """SCALED_IMU / 2 / 3 (mG, mrad/s, mgauss, cdegC) -> ImuSample (+ MagSample).

    ``key`` carries the sensor id of the message (0/1/2); ``sources`` infers ``dt_s``.
    """
    return _int16_imu(
        msg,
        key,
        sources,
        counters,
        int(msg.time_boot_ms) * 1000,
        accel_scale=G0_MPS2 * 1e-3,
        gyro_scale=1e-3,
        mag_scale=1e-3 * TESLA_PER_GAUSS,
    )


def decode_raw_imu(
    msg: Any,
    key: SourceKey,
    sources: SourceState,
    counters: DecoderCounters,
    scale: RawImuScale | None,
) -> list[Sample | Truth]:
    """RAW_IMU -> ImuSample (+ MagSample) through ``scale``; without one it is counted and
    dropped (raw ADC counts have no unit)."""
    if scale is None:
        counters.unscaled_raw_imu += 1
        return []
    return _int16_imu(
        msg,
        key,
        sources,
        counters,
        int(msg.time_usec),
        accel_scale=scale.accel_mps2_per_lsb,
        gyro_scale=scale.gyro_rps_per_lsb,
        mag_scale=scale.mag_tesla_per_lsb,
    )


def _int16_imu(
    msg: Any,
    key: SourceKey,
    sources: SourceState,
    counters: DecoderCounters,
    time_us: int,
    accel_scale: float,
    gyro_scale: float,
    mag_scale: float | None,
) -> list[Sample | Truth]:
    out: list[Sample | Truth] = []
    # 0 cdegC means "not provided" (a sensor at exactly 0 degC must send 1).
    temp_cdeg = int(msg.temperature)
    temperature_k = math.nan if temp_cdeg == 0 else temp_cdeg * 1e-2 + KELVIN_AT_0_CELSIUS
    dt = sources.imu_dt_s(key, time_us, counters)
    if dt is None:
        return out
    out.append(
        ImuSample(
            time_us=time_us,
            dt_s=dt,
            specific_force_b_mps2=np.array([msg.xacc, msg.yacc, msg.zacc], dtype=np.float64)
            * accel_scale,
            angular_rate_b_rps=np.array([msg.xgyro, msg.ygyro, msg.zgyro], dtype=np.float64)
            * gyro_scale,
            temperature_k=temperature_k,
            sensor_id=key[3],
        )
    )
    raw_mag = (int(msg.xmag), int(msg.ymag), int(msg.zmag))
    # The Earth's field is never exactly zero: all zeros means "no magnetometer".
    if mag_scale is not None and raw_mag != (0, 0, 0):
        out.append(MagSample(time_us, np.array(raw_mag, dtype=np.float64) * mag_scale, key[3]))
    return out


def decode_gps_raw_int(msg: Any) -> GnssFix:
    """GPS_RAW_INT -> GnssFix: N/E velocity from ``vel`` and ``cog`` (NaN when unknown), no
    vertical velocity (NaN), accuracies from ``h_acc``/``v_acc``/``vel_acc`` (NaN when 0)."""
    vel, cog = int(msg.vel), int(msg.cog)
    if vel == UINT16_MAX or cog == UINT16_MAX:
        vn = ve = math.nan
    else:
        speed = vel * 1e-2
        course = math.radians(cog * 1e-2)
        vn, ve = speed * math.cos(course), speed * math.sin(course)

    def mm_or_nan(value: int) -> float:
        # Extension fields: 0 when the sender does not fill them.
        return value * 1e-3 if value > 0 else math.nan

    return GnssFix(
        time_us=int(msg.time_usec),
        lat_rad=msg.lat / DEGE7_PER_RAD,
        lon_rad=msg.lon / DEGE7_PER_RAD,
        alt_msl_m=msg.alt * 1e-3,
        v_ned_mps=np.array([vn, ve, math.nan], dtype=np.float64),
        eph_m=mm_or_nan(int(msg.h_acc)),
        epv_m=mm_or_nan(int(msg.v_acc)),
        speed_accuracy_mps=mm_or_nan(int(msg.vel_acc)),
        fix_type=int(msg.fix_type),
        satellites_visible=int(msg.satellites_visible),
        sensor_id=0,
    )


def decode_scaled_pressure(msg: Any, sensor_id: int) -> BaroSample:
    """SCALED_PRESSURE / 2 / 3 (hPa, cdegC) -> BaroSample of sensor ``sensor_id``."""
    return BaroSample(
        time_us=int(msg.time_boot_ms) * 1000,
        pressure_pa=float(msg.press_abs) * PA_PER_HPA,
        temperature_k=int(msg.temperature) * 1e-2 + KELVIN_AT_0_CELSIUS,
        sensor_id=sensor_id,
    )
