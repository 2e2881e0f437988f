"""MAVLink 2 codec: SI sample dataclasses <-> MAVLink frames.

This is the only module of hilnav that knows MAVLink's wire units (degE7, mm, cm/s, cdeg, hPa,
mG, gauss, cdegC). Everything it returns is SI (see ``sim.samples`` and ``fusion``'s package
docstring for frames and quaternion order).

Dialect
    One explicit dialect module, ``pymavlink.dialects.v20.ardupilotmega`` (a superset of
    ``common``; ArduPilot-specific messages in a real flight controller's stream are then
    "known, ignored" instead of "unknown"), MAVLink 2 framing. The process-global dialect that
    ``pymavlink.mavutil`` picks from environment variables is never used. Import the dialect
    from here (:data:`mavlink2`) so every hilnav module agrees on it.

Messages written (:class:`Encoder`)
    ================================  ======================================================
    HIL_SENSOR (107)                  IMU, magnetometer, barometer (one frame, one time)
    HIL_GPS (113)                     GNSS fix; ``time_usec`` is the fix's time of validity
    HIL_STATE_QUATERNION (115)        truth, sent from its own component id
    ================================  ======================================================

    HIL_SENSOR ``fields_updated`` carries only the bits of what was given (bits 0-2 accel,
    3-5 gyro, 6-8 mag, 9 abs_pressure, 10 diff_pressure, 11 pressure_alt, 12 temperature).
    Following PX4's reading ("temperature only updated with baro"), the temperature field and
    bits 11/12 are sent only together with a barometer sample; ``pressure_alt`` is the ISA
    pressure altitude of the static pressure. An IMU's own temperature is therefore not
    transmitted.

    HIL_GPS ``eph`` / ``epv``: the MAVLink text calls them "dilution of position", but PX4's
    simulator interface (``simulator_mavlink``) and MAVROS read them as centimetres of 1-sigma
    horizontal / vertical position accuracy (``eph * 1e-2`` = metres). hilnav follows PX4:
    ``eph = round(100 * GnssFix.eph_m)``; ``UINT16_MAX`` (65535) means unknown (a NaN or
    infinite accuracy is sent as unknown, an unknown is decoded as NaN). HIL_GPS has no speed
    accuracy field: decoded fixes carry ``speed_accuracy_mps = nan``. ``vel`` is the ground
    speed, ``cog`` the course over ground derived from the NED velocity (65535 when the ground
    speed is zero) and ``yaw`` is 0 (= unknown); on decode only ``vn/ve/vd`` are used.

    HIL_STATE_QUATERNION ``xacc/yacc/zacc`` carry the truth's specific force in body FRD
    (mG, 1 mG = 9.80665e-3 m/s^2). The message has no pressure or temperature: a decoded
    :class:`~sim.samples.Truth` has ``static_pressure_pa = temperature_k = nan``.

Component ids
    Sensors (HIL_SENSOR, HIL_GPS) come from :data:`SENSOR_COMPONENT_ID` = 200
    (``MAV_COMP_ID_IMU``), truth from :data:`TRUTH_COMPONENT_ID` = 25 (``MAV_COMP_ID_USER1``,
    the private-use range: no autopilot or ground station gives it a meaning, and a consumer
    separates truth from sensors by component). Each component has its own sequence counter,
    as MAVLink requires.

Saturation
    Values beyond a wire field's range are clipped to that range, never wrapped; every clip is
    counted in :attr:`Encoder.saturations` under ``"MESSAGE.field"`` (e.g. a velocity above
    327.67 m/s in an int16 cm/s field). Non-finite values where a number is required, or values
    outside their physical domain (``|lat| > 90 deg``, negative time), raise ``ValueError``.

Wire quantisation (what a round trip may lose)
    float32 fields round to half a float32 ulp: a relative error <= 2**-24 (6.0e-8).
    ``abs_pressure`` is float32 hPa: from 512 to 1024 hPa (sea level up to ~5 km) one ulp is
    2**-14 hPa = 6.1e-3 Pa, so the round-trip error is <= 3.1e-3 Pa (<= 6.1e-3 Pa from 1024 to
    2048 hPa, smaller still at altitude) — about 0.3 mm of height, far below any barometer's
    noise. The temperature (float32 degC) loses <= 1e-6 K at room temperature. degE7 angles
    round to 5e-8 deg (<= 5.6 mm on the ground); ``alt`` rounds to 0.5 mm; cm/s velocities to
    5 mm/s; ``eph/epv`` to 5 mm; mG specific forces to 4.9e-3 m/s^2.

Decoding (:class:`Decoder`)
    HIL_SENSOR / HIGHRES_IMU  -> ImuSample (needs all six accel+gyro bits), MagSample (bits
    6-8), BaroSample (bit 9; the temperature is the last one received with bit 12 from that
    source, NaN before the first). ImuSample's temperature is that same last temperature.
    HIL_GPS -> GnssFix; HIL_STATE_QUATERNION -> Truth (from any component: filtering truth
    from sensors is the consumer's decision, made on ``Decoded.component_id``).
    Flight-controller messages: SCALED_IMU / SCALED_IMU2 / SCALED_IMU3 (sensor ids 0/1/2; mG,
    mrad/s, mgauss, cdegC; an all-zero magnetic field means "no magnetometer" and yields no
    MagSample; temperature 0 means "not provided" -> NaN); RAW_IMU (raw ADC counts by
    definition, so accepted only with an explicit :class:`RawImuScale`, otherwise counted in
    ``unscaled_raw_imu`` and dropped; ArduPilot actually fills it in mG / mrad/s / mgauss:
    ``RawImuScale.milli_units()``); GPS_RAW_INT (position, ``h_acc``/``v_acc``/``vel_acc``
    when non-zero, else NaN; its ``eph`` is an HDOP, not an accuracy, and is not used; the
    message has no vertical velocity, so ``v_ned_mps[2]`` is NaN, and N/E are NaN when ``vel``
    or ``cog`` is unknown); SCALED_PRESSURE / 2 / 3 (sensor ids 0/1/2). ``time_boot_ms`` is
    turned into ``time_us``.

    CRCs are checked by pymavlink, except when the ``MAV_IGNORE_CRC`` environment variable is
    set (pymavlink reads it at import; never set it for hilnav).

    ``ImuSample.dt_s`` is not on the wire: the decoder infers it from consecutive timestamps of
    the same source (system, component, message id, sensor id). The first sample of a source
    gets ``imu_dt_s`` if given, else :data:`DEFAULT_FIRST_IMU_DT_S` = 0.0 (no interval
    information: integrating it adds nothing). A repeated timestamp is a duplicate and is
    dropped; a timestamp that goes backwards (simulator restart) restarts the source; both are
    counted.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, fields
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, PositiveFloat
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from physconst import G0_MPS2, ISA_L0_KPM, ISA_P0_PA, ISA_T0_K  # G0: MAVLink's mG is 1e-3 G0
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Sample, Truth

__all__ = [
    "DEFAULT_FIRST_IMU_DT_S",
    "SENSOR_COMPONENT_ID",
    "TRUTH_COMPONENT_ID",
    "Decoded",
    "Decoder",
    "DecoderCounters",
    "Encoder",
    "HilSensorField",
    "RawImuScale",
    "mavlink2",
]

# --- wire units -----------------------------------------------------------------------------
TESLA_PER_GAUSS: Final = 1e-4
PA_PER_HPA: Final = 100.0
KELVIN_AT_0_CELSIUS: Final = 273.15
DEGE7_PER_RAD: Final = 1e7 * 180.0 / math.pi
UINT8_MAX: Final = 0xFF
UINT16_MAX: Final = 0xFFFF
INT16_MIN: Final = -0x8000
INT16_MAX: Final = 0x7FFF
INT32_MIN: Final = -0x8000_0000
INT32_MAX: Final = 0x7FFF_FFFF
UINT64_MAX: Final = 0xFFFF_FFFF_FFFF_FFFF
FLOAT32_MAX: Final = float(np.finfo(np.float32).max)

# ISA troposphere, for HIL_SENSOR.pressure_alt only (the fusion never reads it back).
_ISA_P0_PA: Final = ISA_P0_PA
_ISA_T0_K: Final = ISA_T0_K
_ISA_LAPSE_KPM: Final = -ISA_L0_KPM
_ISA_EXPONENT: Final = 0.190263  # R * L / (g0 * M) for dry air

SENSOR_COMPONENT_ID: Final = int(mavlink2.MAV_COMP_ID_IMU)  # 200
TRUTH_COMPONENT_ID: Final = int(mavlink2.MAV_COMP_ID_USER1)  # 25
DEFAULT_FIRST_IMU_DT_S: Final = 0.0


class HilSensorField:
    """Bits of HIL_SENSOR / HIGHRES_IMU ``fields_updated`` (same layout in both messages)."""

    XACC: Final = 1 << 0
    YACC: Final = 1 << 1
    ZACC: Final = 1 << 2
    XGYRO: Final = 1 << 3
    YGYRO: Final = 1 << 4
    ZGYRO: Final = 1 << 5
    XMAG: Final = 1 << 6
    YMAG: Final = 1 << 7
    ZMAG: Final = 1 << 8
    ABS_PRESSURE: Final = 1 << 9
    DIFF_PRESSURE: Final = 1 << 10
    PRESSURE_ALT: Final = 1 << 11
    TEMPERATURE: Final = 1 << 12
    SIM_RESET: Final = 1 << 31
    ACCEL: Final = XACC | YACC | ZACC
    GYRO: Final = XGYRO | YGYRO | ZGYRO
    IMU: Final = ACCEL | GYRO
    MAG: Final = XMAG | YMAG | ZMAG
    BARO: Final = ABS_PRESSURE | PRESSURE_ALT | TEMPERATURE


# --- input checks ---------------------------------------------------------------------------
def _finite(value: float, name: str) -> float:
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x!r}")
    return x


def _vec(value: ArrayLike, name: str, n: int = 3) -> list[float]:
    """A length-``n`` finite vector as Python floats (cheaper than numpy for 3 elements)."""
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {v.shape}")
    xs: list[float] = v.tolist()
    if not all(math.isfinite(x) for x in xs):
        raise ValueError(f"{name} must be finite, got {xs}")
    return xs


def _time_us(value: int, name: str) -> int:
    try:
        t = int(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an integer number of microseconds") from exc
    if t != value or not 0 <= t <= UINT64_MAX:
        raise ValueError(f"{name} must be an integer in [0, 2**64), got {value!r}")
    return t


def _uint8(value: int, name: str) -> int:
    v = int(value)
    if v != value or not 0 <= v <= UINT8_MAX:
        raise ValueError(f"{name} must be an integer in [0, 255], got {value!r}")
    return v


def _component_id(value: int, name: str) -> int:
    v = int(value)
    if v != value or not 1 <= v <= UINT8_MAX:
        raise ValueError(f"{name} must be an integer in [1, 255] (0 is broadcast), got {value!r}")
    return v


def _isa_pressure_altitude_m(pressure_pa: float) -> float:
    """ISA (troposphere) pressure altitude of a static pressure.

    Parameters
    ----------
    pressure_pa : float
        Static pressure, Pa (> 0).

    Returns
    -------
    float
        Pressure altitude, m: ``T0 / L * (1 - (p / p0) ** (R L / g M))``.
    """
    return _ISA_T0_K / _ISA_LAPSE_KPM * (1.0 - (pressure_pa / _ISA_P0_PA) ** _ISA_EXPONENT)


# --- encoder --------------------------------------------------------------------------------
class Encoder:
    """Encode SI samples into MAVLink 2 frames (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION).

    Parameters
    ----------
    system_id : int
        MAVLink system id of the simulated vehicle, 1..255.
    sensor_component_id : int
        Component that sends HIL_SENSOR and HIL_GPS (default 200, ``MAV_COMP_ID_IMU``).
    truth_component_id : int
        Component that sends HIL_STATE_QUATERNION (default 25, ``MAV_COMP_ID_USER1``); must
        differ from ``sensor_component_id`` so a receiver can tell truth from sensors.

    Attributes
    ----------
    saturations : collections.Counter[str]
        Number of values clipped to their wire range, keyed ``"MESSAGE.field"``.
    """

    def __init__(
        self,
        *,
        system_id: int = 1,
        sensor_component_id: int = SENSOR_COMPONENT_ID,
        truth_component_id: int = TRUTH_COMPONENT_ID,
    ) -> None:
        sys_id = _component_id(system_id, "system_id")
        sensor_comp = _component_id(sensor_component_id, "sensor_component_id")
        truth_comp = _component_id(truth_component_id, "truth_component_id")
        if sensor_comp == truth_comp:
            raise ValueError(
                "truth_component_id must differ from sensor_component_id "
                f"(both are {sensor_comp}): receivers tell truth from sensors by component"
            )
        self.system_id = sys_id
        self.sensor_component_id = sensor_comp
        self.truth_component_id = truth_comp
        self._sensor_mav = mavlink2.MAVLink(None, srcSystem=sys_id, srcComponent=sensor_comp)
        self._truth_mav = mavlink2.MAVLink(None, srcSystem=sys_id, srcComponent=truth_comp)
        self.saturations: Counter[str] = Counter()

    # -- helpers that clip to the wire range and count it --
    def _f32(self, value: float, field: str) -> float:
        if value > FLOAT32_MAX:
            self.saturations[field] += 1
            return FLOAT32_MAX
        if value < -FLOAT32_MAX:
            self.saturations[field] += 1
            return -FLOAT32_MAX
        return value

    def _f32_vec(self, xs: list[float], names: tuple[str, ...], msg: str) -> list[float]:
        if all(-FLOAT32_MAX <= x <= FLOAT32_MAX for x in xs):
            return xs
        return [self._f32(x, f"{msg}.{n}") for x, n in zip(xs, names, strict=True)]

    def _int(self, value: float, lo: int, hi: int, field: str) -> int:
        if value > hi:
            self.saturations[field] += 1
            return hi
        if value < lo:
            self.saturations[field] += 1
            return lo
        return round(value)

    @staticmethod
    def _pack(msg: Any, mav: Any) -> bytes:
        frame: bytes = msg.pack(mav)
        # MAVLink.send() would advance the sequence; pack() alone does not.
        mav.seq = (mav.seq + 1) % 256
        return frame

    def sensors(
        self,
        imu: ImuSample | None,
        baro: BaroSample | None = None,
        mag: MagSample | None = None,
        *,
        time_us: int | None = None,
        diff_pressure_pa: float | None = None,
    ) -> bytes:
        """One HIL_SENSOR frame with ``fields_updated`` bits for exactly what is given.

        Parameters
        ----------
        imu : ImuSample or None
            Specific force (m/s^2, FRD) and angular rate (rad/s) -> bits 0-5.
            ``dt_s`` and ``temperature_k`` are not transmitted.
        baro : BaroSample or None
            Static pressure -> ``abs_pressure`` hPa (bit 9), ISA ``pressure_alt`` (bit 11),
            temperature degC (bit 12).
        mag : MagSample or None
            Flux density, T -> gauss (bits 6-8).
        time_us : int, optional
            ``time_usec`` of the frame (simulated time). Default: the samples' common
            ``time_us``; samples with different times need it explicitly.
        diff_pressure_pa : float, optional
            Differential (pitot) pressure, Pa -> ``diff_pressure`` hPa (bit 10).

        Returns
        -------
        bytes
            One MAVLink 2 frame from the sensor component.

        Raises
        ------
        ValueError
            Nothing given, samples disagreeing on time or sensor id, non-finite values.
        """
        given: list[tuple[str, ImuSample | BaroSample | MagSample]] = [
            (name, s) for name, s in (("imu", imu), ("baro", baro), ("mag", mag)) if s is not None
        ]
        if not given and diff_pressure_pa is None:
            raise ValueError("sensors() needs at least one of imu, baro, mag, diff_pressure_pa")
        if time_us is None:
            if not given:
                raise ValueError("time_us is required when only diff_pressure_pa is given")
            first_name, first = given[0]
            for name, s in given[1:]:
                if s.time_us != first.time_us:
                    raise ValueError(
                        f"{name}.time_us ({s.time_us}) differs from {first_name}.time_us "
                        f"({first.time_us}); pass time_us explicitly"
                    )
            t = _time_us(first.time_us, f"{first_name}.time_us")
        else:
            t = _time_us(time_us, "time_us")
        sensor_id = 0
        if given:
            first_name, first = given[0]
            sensor_id = _uint8(first.sensor_id, f"{first_name}.sensor_id")
            for name, s in given[1:]:
                if s.sensor_id != first.sensor_id:
                    raise ValueError(
                        f"{name}.sensor_id ({s.sensor_id}) differs from {first_name}.sensor_id "
                        f"({first.sensor_id}): HIL_SENSOR has one id field"
                    )

        bits = 0
        acc = gyro = mag_g = [0.0, 0.0, 0.0]  # sent as zeros when their bits are clear
        abs_hpa = diff_hpa = alt_m = temp_c = 0.0
        if imu is not None:
            f = _vec(imu.specific_force_b_mps2, "imu.specific_force_b_mps2")
            w = _vec(imu.angular_rate_b_rps, "imu.angular_rate_b_rps")
            acc = self._f32_vec(f, ("xacc", "yacc", "zacc"), "HIL_SENSOR")
            gyro = self._f32_vec(w, ("xgyro", "ygyro", "zgyro"), "HIL_SENSOR")
            bits |= HilSensorField.IMU
        if mag is not None:
            b_gauss = [x / TESLA_PER_GAUSS for x in _vec(mag.field_b_tesla, "mag.field_b_tesla")]
            mag_g = self._f32_vec(b_gauss, ("xmag", "ymag", "zmag"), "HIL_SENSOR")
            bits |= HilSensorField.MAG
        if baro is not None:
            p = _finite(baro.pressure_pa, "baro.pressure_pa")
            if p <= 0.0:
                raise ValueError(f"baro.pressure_pa must be > 0, got {p!r}")
            temp_k = _finite(baro.temperature_k, "baro.temperature_k")
            abs_hpa = self._f32(p / PA_PER_HPA, "HIL_SENSOR.abs_pressure")
            alt_m = _isa_pressure_altitude_m(p)
            temp_c = self._f32(temp_k - KELVIN_AT_0_CELSIUS, "HIL_SENSOR.temperature")
            bits |= HilSensorField.BARO
        if diff_pressure_pa is not None:
            diff_hpa = self._f32(
                _finite(diff_pressure_pa, "diff_pressure_pa") / PA_PER_HPA,
                "HIL_SENSOR.diff_pressure",
            )
            bits |= HilSensorField.DIFF_PRESSURE
        msg = mavlink2.MAVLink_hil_sensor_message(
            t, *acc, *gyro, *mag_g, abs_hpa, diff_hpa, alt_m, temp_c, bits, sensor_id
        )
        return self._pack(msg, self._sensor_mav)

    def gnss(self, fix: GnssFix) -> bytes:
        """One HIL_GPS frame (``time_usec`` = the fix's time of validity).

        Parameters
        ----------
        fix : GnssFix
            Position (rad, m MSL), NED velocity (m/s), 1-sigma accuracies (m; NaN/inf =
            unknown), fix type, satellites, receiver id.

        Returns
        -------
        bytes
            One MAVLink 2 frame from the sensor component.
        """
        t = _time_us(fix.time_us, "fix.time_us")
        lat_e7, lon_e7 = self._lat_lon_e7(fix.lat_rad, fix.lon_rad, "fix")
        alt_mm = self._int(
            _finite(fix.alt_msl_m, "fix.alt_msl_m") * 1e3, INT32_MIN, INT32_MAX, "HIL_GPS.alt"
        )
        v = [x * 100.0 for x in _vec(fix.v_ned_mps, "fix.v_ned_mps")]
        vn, ve, vd = (
            self._int(x, INT16_MIN, INT16_MAX, f"HIL_GPS.{n}")
            for x, n in zip(v, ("vn", "ve", "vd"), strict=True)
        )
        ground_cms = math.hypot(v[0], v[1])
        vel = self._int(ground_cms, 0, UINT16_MAX - 1, "HIL_GPS.vel")
        if ground_cms > 0.0:
            cog_deg = math.degrees(math.atan2(v[1], v[0])) % 360.0
            cog = round(cog_deg * 100.0) % 36000
        else:
            cog = UINT16_MAX
        eph = self._accuracy_cm(fix.eph_m, "fix.eph_m", "HIL_GPS.eph")
        epv = self._accuracy_cm(fix.epv_m, "fix.epv_m", "HIL_GPS.epv")
        msg = mavlink2.MAVLink_hil_gps_message(
            t,
            _uint8(fix.fix_type, "fix.fix_type"),
            lat_e7,
            lon_e7,
            alt_mm,
            eph,
            epv,
            vel,
            vn,
            ve,
            vd,
            cog,
            _uint8(fix.satellites_visible, "fix.satellites_visible"),
            _uint8(fix.sensor_id, "fix.sensor_id"),
            0,  # yaw: 0 = unknown (no dual-antenna heading in GnssFix)
        )
        return self._pack(msg, self._sensor_mav)

    def truth(self, truth: Truth) -> bytes:
        """One HIL_STATE_QUATERNION frame from the truth component.

        Parameters
        ----------
        truth : Truth
            True state; pressure and temperature are not transmitted.

        Returns
        -------
        bytes
            One MAVLink 2 frame from the truth component.
        """
        t = _time_us(truth.time_us, "truth.time_us")
        q = _vec(truth.q_nb, "truth.q_nb", 4)
        w = _vec(truth.omega_b_rps, "truth.omega_b_rps")
        m = "HIL_STATE_QUATERNION"
        lat_e7, lon_e7 = self._lat_lon_e7(truth.lat_rad, truth.lon_rad, "truth")
        alt_mm = self._int(
            _finite(truth.alt_msl_m, "truth.alt_msl_m") * 1e3, INT32_MIN, INT32_MAX, f"{m}.alt"
        )
        v = [x * 100.0 for x in _vec(truth.v_ned_mps, "truth.v_ned_mps")]
        vx, vy, vz = (
            self._int(x, INT16_MIN, INT16_MAX, f"{m}.{n}")
            for x, n in zip(v, ("vx", "vy", "vz"), strict=True)
        )
        ias = self._int(
            _finite(truth.indicated_airspeed_mps, "truth.indicated_airspeed_mps") * 100.0,
            0,
            UINT16_MAX,
            f"{m}.ind_airspeed",
        )
        tas = self._int(
            _finite(truth.airspeed_mps, "truth.airspeed_mps") * 100.0,
            0,
            UINT16_MAX,
            f"{m}.true_airspeed",
        )
        f_b = _vec(truth.specific_force_b_mps2, "truth.specific_force_b_mps2")
        f_mg = [x / (G0_MPS2 * 1e-3) for x in f_b]
        xacc, yacc, zacc = (
            self._int(x, INT16_MIN, INT16_MAX, f"{m}.{n}")
            for x, n in zip(f_mg, ("xacc", "yacc", "zacc"), strict=True)
        )
        msg = mavlink2.MAVLink_hil_state_quaternion_message(
            t,
            self._f32_vec(q, ("attitude_quaternion",) * 4, m),
            *self._f32_vec(w, ("rollspeed", "pitchspeed", "yawspeed"), m),
            lat_e7,
            lon_e7,
            alt_mm,
            vx,
            vy,
            vz,
            ias,
            tas,
            xacc,
            yacc,
            zacc,
        )
        return self._pack(msg, self._truth_mav)

    @staticmethod
    def _lat_lon_e7(lat_rad: float, lon_rad: float, owner: str) -> tuple[int, int]:
        lat = _finite(lat_rad, f"{owner}.lat_rad")
        lon = _finite(lon_rad, f"{owner}.lon_rad")
        if abs(lat) > math.pi / 2:
            raise ValueError(f"{owner}.lat_rad must be in [-pi/2, pi/2], got {lat!r}")
        # Longitude is periodic: normalise to [-180, 180) deg rather than reject.
        lon = (lon + math.pi) % (2.0 * math.pi) - math.pi
        lat_e7 = round(lat * DEGE7_PER_RAD)
        lon_e7 = round(lon * DEGE7_PER_RAD)
        return lat_e7, lon_e7

    def _accuracy_cm(self, value_m: float, name: str, field: str) -> int:
        x = float(value_m)
        if math.isnan(x) or math.isinf(x):
            return UINT16_MAX  # unknown
        if x < 0.0:
            raise ValueError(f"{name} must be >= 0 (or NaN for unknown), got {x!r}")
        # 65535 means unknown, so the largest known accuracy is 655.34 m.
        return self._int(x * 100.0, 0, UINT16_MAX - 1, field)


# --- decoder --------------------------------------------------------------------------------
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


@dataclass(frozen=True, slots=True)
class Decoded:
    """One SI sample decoded from a MAVLink message, with where it came from."""

    sample: Sample | Truth
    system_id: int
    component_id: int
    msg_id: int


@dataclass(slots=True)
class DecoderCounters:
    """What the decoder saw. Every frame or message dropped is counted in exactly one place.

    Attributes
    ----------
    frames_ok : CRC-checked frames of known message ids.
    bad_crc : frames with a CRC mismatch (dropped).
    bad_signature : signed frames rejected by a configured signing key (dropped).
    bad_frames : other framing errors: bad length, unknown incompat flags (dropped).
    garbage_bytes : bytes skipped between frames (no start-of-frame marker).
    unknown_msg_id : frames whose id the dialect does not know; pymavlink cannot check their
        CRC (no CRC_EXTRA), so they are dropped.
    ignored_msgs : valid messages that carry no sensor or truth data hilnav decodes.
    samples : SI samples produced.
    incomplete_fields : HIL_SENSOR / HIGHRES_IMU with only part of the accel+gyro or mag bits.
    unscaled_raw_imu : RAW_IMU messages dropped because no :class:`RawImuScale` was given.
    imu_duplicates : IMU messages with the same timestamp as the previous one (dropped).
    imu_time_resets : IMU timestamps that went backwards (source restarted).
    sim_resets : HIL_SENSOR frames with bit 31 ("simulation reset") set.
    """

    frames_ok: int = 0
    bad_crc: int = 0
    bad_signature: int = 0
    bad_frames: int = 0
    garbage_bytes: int = 0
    unknown_msg_id: int = 0
    ignored_msgs: int = 0
    samples: int = 0
    incomplete_fields: int = 0
    unscaled_raw_imu: int = 0
    imu_duplicates: int = 0
    imu_time_resets: int = 0
    sim_resets: int = 0

    def as_dict(self) -> dict[str, int]:
        """Counters as a plain dict (for JSON status output)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


_SourceKey = tuple[int, int, int, int]  # system, component, msg id, sensor id

_SCALED_IMU_IDS: Final = {
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU: 0,
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU2: 1,
    mavlink2.MAVLINK_MSG_ID_SCALED_IMU3: 2,
}
_SCALED_PRESSURE_IDS: Final = {
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE: 0,
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE2: 1,
    mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE3: 2,
}


class Decoder:
    """Parse a MAVLink byte stream and turn sensor and truth messages into SI samples.

    Stateful: it keeps partial frames between :meth:`feed` calls, the previous IMU timestamp
    of each source (to infer ``ImuSample.dt_s``) and the last temperature of each HIL_SENSOR /
    HIGHRES_IMU source.

    Parameters
    ----------
    imu_dt_s : float, optional
        ``dt_s`` given to the first IMU sample of each source (> 0). Default
        :data:`DEFAULT_FIRST_IMU_DT_S` (0.0: unknown interval).
    raw_imu_scale : RawImuScale, optional
        Enables RAW_IMU decoding; without it RAW_IMU is counted and dropped.

    Attributes
    ----------
    counters : DecoderCounters
    mav : pymavlink MAVLink
        The parser (robust parsing on). Configure signing on ``mav.signing`` to reject
        unsigned or badly signed frames.
    """

    def __init__(
        self, *, imu_dt_s: float | None = None, raw_imu_scale: RawImuScale | None = None
    ) -> None:
        if imu_dt_s is not None and not (math.isfinite(imu_dt_s) and imu_dt_s > 0.0):
            raise ValueError(f"imu_dt_s must be a finite number > 0, got {imu_dt_s!r}")
        self._first_dt_s = DEFAULT_FIRST_IMU_DT_S if imu_dt_s is None else float(imu_dt_s)
        self._raw_imu_scale = raw_imu_scale
        self.mav = mavlink2.MAVLink(None, srcSystem=0, srcComponent=0)
        # Robust parsing returns MAVLink_bad_data objects (counted) instead of raising.
        self.mav.robust_parsing = True
        self.counters = DecoderCounters()
        self._last_imu_time: dict[_SourceKey, int] = {}
        self._last_temperature_k: dict[_SourceKey, float] = {}

    # -- bytes -> messages --
    def parse(self, data: bytes) -> list[Any]:
        """Parse bytes into valid pymavlink messages of known ids; count and drop the rest.

        Parameters
        ----------
        data : bytes
            Any slice of a MAVLink byte stream; an incomplete trailing frame is kept for the
            next call.

        Returns
        -------
        list of pymavlink MAVLink_message
        """
        msgs = self.mav.parse_buffer(data)
        if not msgs:
            return []
        return [m for m in msgs if self._accept(m)]

    def _accept(self, msg: Any) -> bool:
        msg_id = msg.get_msgId()
        if msg_id == mavlink2.MAVLINK_MSG_ID_BAD_DATA:
            reason = str(getattr(msg, "reason", ""))
            if reason == "Bad prefix":
                self.counters.garbage_bytes += len(msg.data)
            elif "CRC" in reason:
                self.counters.bad_crc += 1
            elif "signature" in reason:
                self.counters.bad_signature += 1
            else:
                self.counters.bad_frames += 1
            return False
        if msg_id == mavlink2.MAVLINK_MSG_ID_UNKNOWN:
            self.counters.unknown_msg_id += 1
            return False
        self.counters.frames_ok += 1
        return True

    def feed(self, data: bytes) -> list[Decoded]:
        """Parse bytes and decode every sensor / truth message in them.

        Parameters
        ----------
        data : bytes
            Any slice of a MAVLink byte stream (partial frames are kept for the next call).

        Returns
        -------
        list of Decoded
            In stream order; one message may give several samples (HIL_SENSOR: IMU, mag, baro).
        """
        out: list[Decoded] = []
        for msg in self.parse(data):
            out.extend(self._decode(msg))
        return out

    def decode_message(self, msg: Any) -> list[Decoded]:
        """Decode one pymavlink message object (e.g. from ``mavutil`` or a tlog reader).

        Bad-data and unknown-id placeholders are counted and give no sample.

        Parameters
        ----------
        msg : pymavlink MAVLink_message

        Returns
        -------
        list of Decoded
        """
        if not self._accept(msg):
            return []
        return self._decode(msg)

    # -- messages -> samples --
    def _decode(self, msg: Any) -> list[Decoded]:
        msg_id = msg.get_msgId()
        sys_id = msg.get_srcSystem()
        comp_id = msg.get_srcComponent()
        samples: list[Sample | Truth]
        if msg_id in (mavlink2.MAVLINK_MSG_ID_HIL_SENSOR, mavlink2.MAVLINK_MSG_ID_HIGHRES_IMU):
            samples = self._hil_sensor(msg, (sys_id, comp_id, msg_id, int(msg.id)))
        elif msg_id == mavlink2.MAVLINK_MSG_ID_HIL_GPS:
            samples = [self._hil_gps(msg)]
        elif msg_id == mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION:
            samples = [self._hil_state_quaternion(msg)]
        elif msg_id in _SCALED_IMU_IDS:
            sensor_id = _SCALED_IMU_IDS[msg_id]
            samples = self._scaled_imu(msg, (sys_id, comp_id, msg_id, sensor_id))
        elif msg_id == mavlink2.MAVLINK_MSG_ID_RAW_IMU:
            samples = self._raw_imu(msg, (sys_id, comp_id, msg_id, int(msg.id)))
        elif msg_id == mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT:
            samples = [self._gps_raw_int(msg)]
        elif msg_id in _SCALED_PRESSURE_IDS:
            samples = [self._scaled_pressure(msg, _SCALED_PRESSURE_IDS[msg_id])]
        else:
            self.counters.ignored_msgs += 1
            return []
        self.counters.samples += len(samples)
        return [Decoded(s, sys_id, comp_id, msg_id) for s in samples]

    def _imu_dt_s(self, key: _SourceKey, time_us: int) -> float | None:
        """Interval since the source's previous sample; None for a duplicate (drop it)."""
        last = self._last_imu_time.get(key)
        if last is not None and time_us == last:
            self.counters.imu_duplicates += 1
            return None
        self._last_imu_time[key] = time_us
        if last is None:
            return self._first_dt_s
        if time_us < last:
            self.counters.imu_time_resets += 1
            return self._first_dt_s
        return (time_us - last) * 1e-6

    def _hil_sensor(self, msg: Any, key: _SourceKey) -> list[Sample | Truth]:
        bits = int(msg.fields_updated)
        t = int(msg.time_usec)
        sensor_id = key[3]
        out: list[Sample | Truth] = []
        if bits & HilSensorField.SIM_RESET:
            self.counters.sim_resets += 1
            self._last_imu_time.pop(key, None)
        if bits & HilSensorField.TEMPERATURE:
            self._last_temperature_k[key] = float(msg.temperature) + KELVIN_AT_0_CELSIUS
        temperature_k = self._last_temperature_k.get(key, math.nan)
        imu_bits = bits & HilSensorField.IMU
        if imu_bits == HilSensorField.IMU:
            dt = self._imu_dt_s(key, t)
            if dt is not None:
                out.append(
                    ImuSample(
                        time_us=t,
                        dt_s=dt,
                        specific_force_b_mps2=np.array(
                            [msg.xacc, msg.yacc, msg.zacc], dtype=np.float64
                        ),
                        angular_rate_b_rps=np.array(
                            [msg.xgyro, msg.ygyro, msg.zgyro], dtype=np.float64
                        ),
                        temperature_k=temperature_k,
                        sensor_id=sensor_id,
                    )
                )
        elif imu_bits:
            self.counters.incomplete_fields += 1
        mag_bits = bits & HilSensorField.MAG
        if mag_bits == HilSensorField.MAG:
            field_g = np.array([msg.xmag, msg.ymag, msg.zmag], dtype=np.float64)
            out.append(MagSample(t, field_g * TESLA_PER_GAUSS, sensor_id))
        elif mag_bits:
            self.counters.incomplete_fields += 1
        if bits & HilSensorField.ABS_PRESSURE:
            out.append(
                BaroSample(t, float(msg.abs_pressure) * PA_PER_HPA, temperature_k, sensor_id)
            )
        return out

    @staticmethod
    def _hil_gps(msg: Any) -> GnssFix:
        def accuracy_m(cm: int) -> float:
            return math.nan if cm == UINT16_MAX else cm * 1e-2

        return GnssFix(
            time_us=int(msg.time_usec),
            lat_rad=msg.lat / DEGE7_PER_RAD,
            lon_rad=msg.lon / DEGE7_PER_RAD,
            alt_msl_m=msg.alt * 1e-3,
            v_ned_mps=np.array([msg.vn, msg.ve, msg.vd], dtype=np.float64) * 1e-2,
            eph_m=accuracy_m(msg.eph),
            epv_m=accuracy_m(msg.epv),
            speed_accuracy_mps=math.nan,  # HIL_GPS has no speed accuracy field
            fix_type=int(msg.fix_type),
            satellites_visible=int(msg.satellites_visible),
            sensor_id=int(msg.id),
        )

    @staticmethod
    def _hil_state_quaternion(msg: Any) -> Truth:
        mg = G0_MPS2 * 1e-3
        return Truth(
            time_us=int(msg.time_usec),
            lat_rad=msg.lat / DEGE7_PER_RAD,
            lon_rad=msg.lon / DEGE7_PER_RAD,
            alt_msl_m=msg.alt * 1e-3,
            v_ned_mps=np.array([msg.vx, msg.vy, msg.vz], dtype=np.float64) * 1e-2,
            q_nb=np.array(msg.attitude_quaternion, dtype=np.float64),
            omega_b_rps=np.array([msg.rollspeed, msg.pitchspeed, msg.yawspeed], dtype=np.float64),
            specific_force_b_mps2=np.array([msg.xacc, msg.yacc, msg.zacc], dtype=np.float64) * mg,
            static_pressure_pa=math.nan,  # not in HIL_STATE_QUATERNION
            temperature_k=math.nan,  # not in HIL_STATE_QUATERNION
            airspeed_mps=msg.true_airspeed * 1e-2,
            indicated_airspeed_mps=msg.ind_airspeed * 1e-2,
        )

    def _int16_imu(
        self,
        msg: Any,
        key: _SourceKey,
        time_us: int,
        accel_scale: float,
        gyro_scale: float,
        mag_scale: float | None,
    ) -> list[Sample | Truth]:
        out: list[Sample | Truth] = []
        # 0 cdegC means "not provided" (a sensor at exactly 0 degC must send 1).
        temp_cdeg = int(msg.temperature)
        temperature_k = math.nan if temp_cdeg == 0 else temp_cdeg * 1e-2 + KELVIN_AT_0_CELSIUS
        dt = self._imu_dt_s(key, time_us)
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

    def _scaled_imu(self, msg: Any, key: _SourceKey) -> list[Sample | Truth]:
        return self._int16_imu(
            msg,
            key,
            int(msg.time_boot_ms) * 1000,
            accel_scale=G0_MPS2 * 1e-3,
            gyro_scale=1e-3,
            mag_scale=1e-3 * TESLA_PER_GAUSS,
        )

    def _raw_imu(self, msg: Any, key: _SourceKey) -> list[Sample | Truth]:
        scale = self._raw_imu_scale
        if scale is None:
            self.counters.unscaled_raw_imu += 1
            return []
        return self._int16_imu(
            msg,
            key,
            int(msg.time_usec),
            accel_scale=scale.accel_mps2_per_lsb,
            gyro_scale=scale.gyro_rps_per_lsb,
            mag_scale=scale.mag_tesla_per_lsb,
        )

    @staticmethod
    def _gps_raw_int(msg: Any) -> GnssFix:
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

    @staticmethod
    def _scaled_pressure(msg: Any, sensor_id: int) -> BaroSample:
        return BaroSample(
            time_us=int(msg.time_boot_ms) * 1000,
            pressure_pa=float(msg.press_abs) * PA_PER_HPA,
            temperature_k=int(msg.temperature) * 1e-2 + KELVIN_AT_0_CELSIUS,
            sensor_id=sensor_id,
        )
