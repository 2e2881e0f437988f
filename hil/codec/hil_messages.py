"""Decoder of hilnav's HIL messages: HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION -> SI samples.

HIL_SENSOR (and HIGHRES_IMU, which has the same fields and ``fields_updated`` bits)
    -> ImuSample (needs all six accel+gyro bits), MagSample (bits 6-8), BaroSample (bit 9; the
    temperature is the last one received with bit 12 from that source, NaN before the first),
    AirspeedSample (bit 10, ``diff_pressure`` hPa -> Pa; a non-finite value is counted in
    ``bad_diff_pressure`` and gives no sample, any finite value passes, see
    :class:`~hil.codec.counters.DecoderCounters`). ImuSample's and AirspeedSample's
    temperature is that same last temperature.
HIL_GPS -> GnssFix; HIL_STATE_QUATERNION -> Truth (from any component: filtering truth from
    sensors is the consumer's decision, made on ``Decoded.component_id``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final

import numpy as np

from hil.codec.counters import DecoderCounters
from hil.codec.sources import SourceKey, SourceState
from hil.codec.wire import (
    DEGE7_PER_RAD,
    KELVIN_AT_0_CELSIUS,
    PA_PER_HPA,
    TESLA_PER_GAUSS,
    UINT16_MAX,
    HilSensorField,
)
from physconst import G0_MPS2  # MAVLink's mG is 1e-3 G0
from sim.samples import (
    AirspeedSample,
    BaroSample,
    GnssFix,
    MagSample,
    Sample,
    Truth,
)
from sim.samples import make_gnss_fix as _make_gnss_fix
from sim.samples import make_imu_sample as _make_imu_sample
from sim.samples import make_truth as _make_truth

__all__ = [
    "HIL_GPS_VALUES",
    "HIL_STATE_QUATERNION_WIRE",
    "decode_hil_gps",
    "decode_hil_gps_values",
    "decode_hil_sensor",
    "decode_hil_sensor_values",
    "decode_hil_state_quaternion",
    "decode_hil_state_quaternion_wire",
]

# the bits as plain ints (no class attribute look-up per message on the IMU-rate path)
_SIM_RESET = HilSensorField.SIM_RESET
_TEMPERATURE = HilSensorField.TEMPERATURE
_IMU = HilSensorField.IMU
_MAG = HilSensorField.MAG
_ABS_PRESSURE = HilSensorField.ABS_PRESSURE
_DIFF_PRESSURE = HilSensorField.DIFF_PRESSURE
_NOT_IMU = _MAG | _ABS_PRESSURE | _DIFF_PRESSURE
_array = np.array
_F64 = np.float64
_MG = G0_MPS2 * 1e-3  # MAVLink's mG, m/s^2


def decode_hil_sensor(
    msg: Any, key: SourceKey, sources: SourceState, counters: DecoderCounters
) -> list[Sample | Truth]:
    """HIL_SENSOR or HIGHRES_IMU -> ImuSample, MagSample, BaroSample, AirspeedSample, as its
    bits say.

    Parameters
    ----------
    msg : pymavlink HIL_SENSOR or HIGHRES_IMU message
    key : SourceKey
        (system, component, message id, sensor id) of the message.
    sources : SourceState
        IMU timestamps and temperatures of the decoder, updated here.
    counters : DecoderCounters
        Incomplete field sets, simulation resets and non-finite differential pressures are
        counted here.

    Returns
    -------
    list of ImuSample, MagSample, BaroSample, AirspeedSample
    """
    return decode_hil_sensor_values(
        msg, int(msg.time_usec), int(msg.fields_updated), (msg.xacc, msg.yacc, msg.zacc),
        (msg.xgyro, msg.ygyro, msg.zgyro), key, sources, counters)


def decode_hil_sensor_values(
    msg: Any, t: int, bits: int, acc: Sequence[float], gyro: Sequence[float], key: SourceKey,
    sources: SourceState, counters: DecoderCounters,
) -> list[Sample | Truth]:
    """:func:`decode_hil_sensor` with the time, ``fields_updated`` (ints) and the accel and
    gyro triples already read (the fast path slices them off the unpacked fields); the
    other fields are read from ``msg`` when its bits say so."""
    out: list[Sample | Truth] = []
    if bits & _SIM_RESET:
        counters.sim_resets += 1
        sources.restart(key)
    if bits & _TEMPERATURE:
        sources.last_temperature_k[key] = float(msg.temperature) + KELVIN_AT_0_CELSIUS
    temperature_k = sources.last_temperature_k.get(key, math.nan)
    imu_bits = bits & _IMU
    if imu_bits == _IMU:
        dt = sources.imu_dt_s(key, t, counters)
        if dt is not None:
            out.append(_make_imu_sample(t, dt, _array(acc, _F64), _array(gyro, _F64),
                                        temperature_k, key[3]))
    elif imu_bits:
        counters.incomplete_fields += 1
    if bits & _NOT_IMU:  # mag, baro and pitot: at lower rates than the IMU
        _decode_slow_fields(msg, bits, t, temperature_k, key[3], counters, out)
    return out


def _decode_slow_fields(msg: Any, bits: int, t: int, temperature_k: float, sensor_id: int,
                        counters: DecoderCounters, out: list[Sample | Truth]) -> None:
    """The MagSample, BaroSample and AirspeedSample of a HIL_SENSOR / HIGHRES_IMU, as its
    bits say, appended to ``out``."""
    mag_bits = bits & _MAG
    if mag_bits == _MAG:
        field_g = np.array([msg.xmag, msg.ymag, msg.zmag], dtype=np.float64)
        out.append(MagSample(t, field_g * TESLA_PER_GAUSS, sensor_id))
    elif mag_bits:
        counters.incomplete_fields += 1
    if bits & _ABS_PRESSURE:
        out.append(
            BaroSample(t, float(msg.abs_pressure) * PA_PER_HPA, temperature_k, sensor_id)
        )
    if bits & _DIFF_PRESSURE:
        dp_pa = float(msg.diff_pressure) * PA_PER_HPA
        if math.isfinite(dp_pa):
            out.append(AirspeedSample(t, dp_pa, temperature_k, sensor_id))
        else:
            counters.bad_diff_pressure += 1


def decode_hil_gps(msg: Any) -> GnssFix:
    """HIL_GPS -> GnssFix (accuracies NaN when unknown; no speed accuracy on the wire)."""
    return decode_hil_gps_values(
        msg.time_usec, msg.lat, msg.lon, msg.alt, msg.eph, msg.epv, msg.vn, msg.ve, msg.vd,
        msg.fix_type, msg.satellites_visible, msg.id)


HIL_GPS_VALUES: Final = ("time_usec", "lat", "lon", "alt", "eph", "epv", "vn", "ve", "vd",
                         "fix_type", "satellites_visible", "id")
"""The HIL_GPS fields :func:`decode_hil_gps_values` takes, in its order."""


def decode_hil_gps_values(
    time_usec: int, lat: int, lon: int, alt: int, eph: int, epv: int, vn: int, ve: int, vd: int,
    fix_type: int, satellites_visible: int, sensor_id: int,
) -> GnssFix:
    """:func:`decode_hil_gps` from the wire values of :data:`HIL_GPS_VALUES` (the fast path
    picks them off the unpacked payload in one call)."""
    return _make_gnss_fix(
        int(time_usec),
        lat / DEGE7_PER_RAD,
        lon / DEGE7_PER_RAD,
        alt * 1e-3,
        _array((vn * 1e-2, ve * 1e-2, vd * 1e-2), _F64),  # (cm/s) * 1e-2 each
        _accuracy_m(eph),
        _accuracy_m(epv),
        math.nan,  # speed accuracy: HIL_GPS has no such field
        int(fix_type),
        int(satellites_visible),
        int(sensor_id),
    )


def _accuracy_m(cm: int) -> float:
    """HIL_GPS eph / epv, cm (UINT16_MAX: unknown) -> m (NaN: unknown)."""
    return math.nan if cm == UINT16_MAX else cm * 1e-2


def decode_hil_state_quaternion(msg: Any) -> Truth:
    """HIL_STATE_QUATERNION -> Truth (no pressure, temperature, angle of attack, sideslip or
    wind on the wire: NaN)."""
    q = msg.attitude_quaternion
    return decode_hil_state_quaternion_wire((
        msg.time_usec, q[0], q[1], q[2], q[3], msg.rollspeed, msg.pitchspeed, msg.yawspeed,
        msg.lat, msg.lon, msg.alt, msg.vx, msg.vy, msg.vz, msg.ind_airspeed,
        msg.true_airspeed, msg.xacc, msg.yacc, msg.zacc))


HIL_STATE_QUATERNION_WIRE: Final = (
    "time_usec", "attitude_quaternion", "rollspeed", "pitchspeed", "yawspeed", "lat", "lon",
    "alt", "vx", "vy", "vz", "ind_airspeed", "true_airspeed", "xacc", "yacc", "zacc")
"""HIL_STATE_QUATERNION's fields in wire order (the quaternion: four values in a row), the
order of the values :func:`decode_hil_state_quaternion_wire` takes."""

_NAN3 = np.full(3, math.nan)


def decode_hil_state_quaternion_wire(w: Sequence[Any]) -> Truth:
    """:func:`decode_hil_state_quaternion` from its 19 wire values in the order of
    :data:`HIL_STATE_QUATERNION_WIRE` (the fast path hands over the unpacked payload as it
    is)."""
    # (each vector as the array of its wire values times the scale, element by element)
    return _make_truth(
        int(w[0]),  # time_us
        w[8] / DEGE7_PER_RAD,  # lat_rad
        w[9] / DEGE7_PER_RAD,  # lon_rad
        w[10] * 1e-3,  # alt_msl_m
        _array([w[11] * 1e-2, w[12] * 1e-2, w[13] * 1e-2], _F64),  # v_ned_mps
        _array(w[1:5], _F64),  # q_nb
        _array(w[5:8], _F64),  # omega_b_rps
        _array([w[16] * _MG, w[17] * _MG, w[18] * _MG], _F64),  # specific_force_b_mps2
        math.nan,  # static pressure: not in HIL_STATE_QUATERNION
        math.nan,  # temperature: not in HIL_STATE_QUATERNION
        w[15] * 1e-2,  # airspeed_mps (true)
        w[14] * 1e-2,  # indicated_airspeed_mps
        math.nan,  # angle of attack: not in HIL_STATE_QUATERNION
        math.nan,  # sideslip: not in HIL_STATE_QUATERNION
        _NAN3.copy(),  # wind: not in the message
    )
