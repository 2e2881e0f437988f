"""HIL encoder: SI samples and truth -> HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION,
HIL_ACTUATOR_CONTROLS and RAW_RPM frames.

Messages written (:class:`Encoder`)
    ================================  ======================================================
    HIL_SENSOR (107)                  IMU, magnetometer, barometer, airspeed (one frame, one
                                      time)
    HIL_GPS (113)                     GNSS fix; ``time_usec`` is the fix's time of validity
    HIL_STATE_QUATERNION (115)        truth, sent from its own component id
    HIL_ACTUATOR_CONTROLS (93)        normalised controls, from the autopilot component
    RAW_RPM (339)                     propeller speed, from the autopilot component
    ================================  ======================================================

    HIL_ACTUATOR_CONTROLS ``controls[16]`` are :attr:`sim.samples.ActuatorSample.controls` as
    float32 (PX4 order: roll, pitch, yaw, throttle, flaps, ...; shorter tuples are padded with
    0), ``mode`` = ``MAV_MODE_FLAG_SAFETY_ARMED | MAV_MODE_FLAG_HIL_ENABLED`` (an armed vehicle
    in HIL), ``flags`` = 0 (the lockstep bit is not claimed). RAW_RPM ``frequency`` is
    :attr:`sim.samples.RpmSample.rpm` (rev/min, float32), ``index`` its ``index``; the message
    has no timestamp (the decoder stamps it), so the streamer sends it right after a frame of
    the same time.

    HIL_SENSOR ``fields_updated`` carries only the bits of what was given (bits 0-2 accel,
    3-5 gyro, 6-8 mag, 9 abs_pressure, 10 diff_pressure, 11 pressure_alt, 12 temperature).
    Following PX4's reading ("temperature only updated with baro"), the temperature field and
    bits 11/12 are sent by default only together with a barometer sample; ``pressure_alt`` is
    the ISA pressure altitude of the static pressure. An airspeed sample's temperature is not
    transmitted (PX4's simulator gives the differential-pressure report the HIL_SENSOR
    temperature; the decoder does the same). An IMU's own temperature is transmitted only when
    asked (``imu_temperature=True``, a thermal IMU model): then the frame carries the IMU and
    its temperature (bit 12) and no barometer, and the barometer travels in a frame of its
    own, so each temperature reaches the samples of its own sensor (the decoder gives a
    sample the last temperature of its source; PX4 takes the barometer group as bits 9, 11
    and 12 together, so an IMU frame's temperature never reaches its barometer).
    ``diff_pressure`` is float32 hPa (PX4: ``diff_pressure * 100`` = Pa): a round trip loses
    at most half a float32 ulp, <= 2**-24 relative (4e-5 Pa at 700 Pa).

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
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike

from hil.codec.fast_frames import (
    HIL_ACTUATOR_CONTROLS,
    HIL_GPS,
    HIL_SENSOR,
    HIL_STATE_QUATERNION,
    RAW_RPM,
    FastLayout,
    pack_frame,
)
from hil.codec.wire import (
    AUTOPILOT_COMPONENT_ID,
    DEGE7_PER_RAD,
    FLOAT32_MAX,
    INT16_MAX,
    INT16_MIN,
    INT32_MAX,
    INT32_MIN,
    KELVIN_AT_0_CELSIUS,
    PA_PER_HPA,
    SENSOR_COMPONENT_ID,
    SIM_SYSTEM_ID,
    TESLA_PER_GAUSS,
    TRUTH_COMPONENT_ID,
    UINT8_MAX,
    UINT16_MAX,
    UINT64_MAX,
    HilSensorField,
    mavlink2,
)
from physconst import G0_MPS2  # MAVLink's mG is 1e-3 G0
from physconst.isa import pressure_altitude_m
from sim.samples import (
    ActuatorSample,
    AirspeedSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    RpmSample,
    Truth,
)

__all__ = ["Encoder"]

_N_CONTROLS: Final = 16  # HIL_ACTUATOR_CONTROLS.controls
_ndarray = np.ndarray
_F64: Final = np.dtype(np.float64)
_SHAPE3: Final = (3,)
_HALF_PI: Final = math.pi / 2
_F32_MAX: Final = FLOAT32_MAX
_IMU_BITS: Final = HilSensorField.IMU
_MAG_BITS: Final = HilSensorField.MAG
_BARO_BITS: Final = HilSensorField.BARO
_DIFF_PRESSURE_BIT: Final = HilSensorField.DIFF_PRESSURE
_TEMPERATURE_BIT: Final = HilSensorField.TEMPERATURE
_HIL_SENSOR_PAYLOAD: Final = HIL_SENSOR.pack_fields
_HIL_GPS_PAYLOAD: Final = HIL_GPS.pack_wire_order
if HIL_GPS.wire_fields != ("time_usec", "lat", "lon", "alt", "eph", "epv", "vel", "vn", "ve", "vd",
                           "cog", "fix_type", "satellites_visible", "id", "yaw"):
    raise ImportError(f"HIL_GPS wire order changed in the dialect: {HIL_GPS.wire_fields}")

_HIL_ARMED_MODE: Final = int(
    mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | mavlink2.MAV_MODE_FLAG_HIL_ENABLED
)


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
    # One sum is finite iff every term is, unless finite terms overflow it: check those singly.
    if not math.isfinite(sum(xs)) and not all(map(math.isfinite, xs)):
        raise ValueError(f"{name} must be finite, got {xs}")
    return xs


def _time_us(value: int, name: str) -> int:
    if type(value) is int and 0 <= value <= UINT64_MAX:  # the usual case, without int()
        return value
    try:
        t = int(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an integer number of microseconds") from exc
    if t != value or not 0 <= t <= UINT64_MAX:
        raise ValueError(f"{name} must be an integer in [0, 2**64), got {value!r}")
    return t


def _sample_name(sample: object, imu: object, baro: object, mag: object) -> str:
    """Which argument of :meth:`Encoder.sensors` ``sample`` is (for error messages)."""
    return "imu" if sample is imu else "baro" if sample is baro else (
        "mag" if sample is mag else "airspeed")


def _uint8(value: int, name: str) -> int:
    if type(value) is int and 0 <= value <= UINT8_MAX:  # the usual case, without int()
        return value
    v = int(value)
    if v != value or not 0 <= v <= UINT8_MAX:
        raise ValueError(f"{name} must be an integer in [0, 255], got {value!r}")
    return v


def _component_id(value: int, name: str) -> int:
    v = int(value)
    if v != value or not 1 <= v <= UINT8_MAX:
        raise ValueError(f"{name} must be an integer in [1, 255] (0 is broadcast), got {value!r}")
    return v


class Encoder:
    """Encode SI samples into MAVLink 2 frames (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION,
    HIL_ACTUATOR_CONTROLS, RAW_RPM; STATUSTEXT for the scenario's events).

    Parameters
    ----------
    system_id : int
        MAVLink system id of the simulated vehicle, 1..255.
    sensor_component_id : int
        Component that sends HIL_SENSOR and HIL_GPS (default 200, ``MAV_COMP_ID_IMU``).
    truth_component_id : int
        Component that sends HIL_STATE_QUATERNION (default 25, ``MAV_COMP_ID_USER1``); must
        differ from ``sensor_component_id`` so a receiver can tell truth from sensors.
    autopilot_component_id : int
        Component that sends HIL_ACTUATOR_CONTROLS and RAW_RPM (default 1,
        ``MAV_COMP_ID_AUTOPILOT1``, where a real autopilot sends them); must differ from both.

    Attributes
    ----------
    saturations : collections.Counter[str]
        Number of values clipped to their wire range, keyed ``"MESSAGE.field"``.
    """

    def __init__(
        self,
        *,
        system_id: int = SIM_SYSTEM_ID,
        sensor_component_id: int = SENSOR_COMPONENT_ID,
        truth_component_id: int = TRUTH_COMPONENT_ID,
        autopilot_component_id: int = AUTOPILOT_COMPONENT_ID,
    ) -> None:
        sys_id = _component_id(system_id, "system_id")
        sensor_comp = _component_id(sensor_component_id, "sensor_component_id")
        truth_comp = _component_id(truth_component_id, "truth_component_id")
        autopilot_comp = _component_id(autopilot_component_id, "autopilot_component_id")
        if sensor_comp == truth_comp:
            raise ValueError(
                "truth_component_id must differ from sensor_component_id "
                f"(both are {sensor_comp}): receivers tell truth from sensors by component"
            )
        if autopilot_comp in (sensor_comp, truth_comp):
            raise ValueError(
                f"autopilot_component_id ({autopilot_comp}) must differ from the sensor and "
                "truth components: each component has its own sequence"
            )
        self.system_id = sys_id
        self.sensor_component_id = sensor_comp
        self.truth_component_id = truth_comp
        self.autopilot_component_id = autopilot_comp
        self._sensor_mav = mavlink2.MAVLink(None, srcSystem=sys_id, srcComponent=sensor_comp)
        self._truth_mav = mavlink2.MAVLink(None, srcSystem=sys_id, srcComponent=truth_comp)
        self._autopilot_mav = mavlink2.MAVLink(
            None, srcSystem=sys_id, srcComponent=autopilot_comp
        )
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
        if -FLOAT32_MAX <= min(xs) and max(xs) <= FLOAT32_MAX:
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
    def _pack(layout: FastLayout, mav: Any, *values: Any) -> bytes:
        """One frame of ``values`` (pymavlink's constructor order) through
        :mod:`hil.codec.fast_frames`: the bytes pymavlink's ``pack`` makes; advances the
        component's sequence as ``MAVLink.send`` would."""
        frame = pack_frame(layout, layout.payload(*values), mav.seq, mav.srcSystem,
                           mav.srcComponent)
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
        airspeed: AirspeedSample | None = None,
        imu_temperature: bool = False,
    ) -> bytes:
        """One HIL_SENSOR frame with ``fields_updated`` bits for exactly what is given.

        Parameters
        ----------
        imu : ImuSample or None
            Specific force (m/s^2, FRD) and angular rate (rad/s) -> bits 0-5.
            ``dt_s`` is not transmitted, ``temperature_k`` only with ``imu_temperature``.
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
        airspeed : AirspeedSample, optional
            The same from a sample (its time and sensor id are checked like the others'; its
            temperature is not transmitted). Give this or ``diff_pressure_pa``, not both.
        imu_temperature : bool
            Send the IMU sample's ``temperature_k`` (degC, bit 12); needs ``imu`` and no
            ``baro`` (one temperature field per frame).

        Returns
        -------
        bytes
            One MAVLink 2 frame from the sensor component.

        Raises
        ------
        ValueError
            Nothing given, samples disagreeing on time or sensor id, non-finite values.
        """
        if imu_temperature and (imu is None or baro is not None):
            raise ValueError("imu_temperature needs an imu sample and no baro sample "
                             "(one temperature field per frame)")
        if airspeed is not None:
            if diff_pressure_pa is not None:
                raise ValueError("give airspeed or diff_pressure_pa, not both")
            diff_pressure_pa = airspeed.diff_pressure_pa
        first: ImuSample | BaroSample | MagSample | AirspeedSample | None
        if baro is None and mag is None and airspeed is None:
            first = imu  # the IMU-rate frame: one sample, nothing to agree with
        else:
            given = [s for s in (imu, baro, mag, airspeed) if s is not None]
            first = given[0] if given else None
            # the usual case in one pass; a mismatch is reported by _check_agree
            for s in given:
                if s.time_us != given[0].time_us or s.sensor_id != given[0].sensor_id:
                    self._check_agree(imu, baro, mag, airspeed, time_us is None)
        if first is not None:
            sensor_id = first.sensor_id
            if type(sensor_id) is not int or not 0 <= sensor_id <= UINT8_MAX:  # name on error
                sensor_id = _uint8(sensor_id, f"{_sample_name(first, imu, baro, mag)}.sensor_id")
        elif diff_pressure_pa is None:
            raise ValueError(
                "sensors() needs at least one of imu, baro, mag, airspeed, diff_pressure_pa"
            )
        else:
            sensor_id = 0
        if time_us is None:
            if first is None:
                raise ValueError("time_us is required when only diff_pressure_pa is given")
            t = first.time_us
            if type(t) is not int or not 0 <= t <= UINT64_MAX:
                t = _time_us(t, f"{_sample_name(first, imu, baro, mag)}.time_us")
        else:
            t = _time_us(time_us, "time_us")

        bits = 0
        ax = ay = az = gx = gy = gz = mx = my = mz = 0.0  # sent as zeros when their bits are clear
        abs_hpa = diff_hpa = alt_m = temp_c = 0.0
        if imu is not None:
            f = imu.specific_force_b_mps2
            w = imu.angular_rate_b_rps
            # A float64 (3,) array each, finite and within float32's range (NaN fails every
            # comparison): sent as they are. Anything else takes the checked path, which
            # raises or clips (and counts) exactly as it always did.
            if (type(f) is _ndarray and type(w) is _ndarray and f.dtype is _F64
                    and w.dtype is _F64 and f.shape == _SHAPE3 and w.shape == _SHAPE3):
                ax, ay, az = f.tolist()
                gx, gy, gz = w.tolist()
                if not (-_F32_MAX <= ax <= _F32_MAX and -_F32_MAX <= ay <= _F32_MAX
                        and -_F32_MAX <= az <= _F32_MAX and -_F32_MAX <= gx <= _F32_MAX
                        and -_F32_MAX <= gy <= _F32_MAX and -_F32_MAX <= gz <= _F32_MAX):
                    ax, ay, az, gx, gy, gz = self._imu_checked(f, w)
            else:
                ax, ay, az, gx, gy, gz = self._imu_checked(f, w)
            bits = _IMU_BITS
            if imu_temperature:
                temp_c = self._f32(_finite(imu.temperature_k, "imu.temperature_k")
                                   - KELVIN_AT_0_CELSIUS, "HIL_SENSOR.temperature")
                bits |= _TEMPERATURE_BIT
        if mag is not None:
            b_gauss = [x / TESLA_PER_GAUSS for x in _vec(mag.field_b_tesla, "mag.field_b_tesla")]
            mx, my, mz = self._f32_vec(b_gauss, ("xmag", "ymag", "zmag"), "HIL_SENSOR")
            bits |= _MAG_BITS
        if baro is not None:
            p = _finite(baro.pressure_pa, "baro.pressure_pa")
            if p <= 0.0:
                raise ValueError(f"baro.pressure_pa must be > 0, got {p!r}")
            temp_k = _finite(baro.temperature_k, "baro.temperature_k")
            abs_hpa = self._f32(p / PA_PER_HPA, "HIL_SENSOR.abs_pressure")
            alt_m = pressure_altitude_m(p)  # for PX4; the fusion never reads it
            temp_c = self._f32(temp_k - KELVIN_AT_0_CELSIUS, "HIL_SENSOR.temperature")
            bits |= _BARO_BITS
        if diff_pressure_pa is not None:
            diff_hpa = self._f32(
                _finite(diff_pressure_pa, "diff_pressure_pa") / PA_PER_HPA,
                "HIL_SENSOR.diff_pressure",
            )
            bits |= _DIFF_PRESSURE_BIT
        mav = self._sensor_mav
        seq = mav.seq
        mav.seq = (seq + 1) % 256  # as MAVLink.send() would
        return pack_frame(
            HIL_SENSOR,
            _HIL_SENSOR_PAYLOAD(t, ax, ay, az, gx, gy, gz, mx, my, mz, abs_hpa, diff_hpa, alt_m,
                                temp_c, bits, sensor_id),
            seq, self.system_id, self.sensor_component_id,
        )

    def _imu_checked(self, f: ArrayLike, w: ArrayLike) -> list[float]:
        """An IMU sample's specific force and angular rate, checked (finite, shape (3,)) and
        clipped to float32's range (counted), as six floats."""
        acc = self._f32_vec(_vec(f, "imu.specific_force_b_mps2"), ("xacc", "yacc", "zacc"),
                            "HIL_SENSOR")
        gyro = self._f32_vec(_vec(w, "imu.angular_rate_b_rps"), ("xgyro", "ygyro", "zgyro"),
                             "HIL_SENSOR")
        return [*acc, *gyro]

    @staticmethod
    def _check_agree(
        imu: ImuSample | None,
        baro: BaroSample | None,
        mag: MagSample | None,
        airspeed: AirspeedSample | None,
        check_time: bool,
    ) -> None:
        """Raise the ValueError that names the samples whose time (when ``check_time``) or
        sensor id differs from the first one's."""
        given: list[tuple[str, ImuSample | BaroSample | MagSample | AirspeedSample]] = [
            (name, s)
            for name, s in (("imu", imu), ("baro", baro), ("mag", mag), ("airspeed", airspeed))
            if s is not None
        ]
        first_name, first = given[0]
        if check_time:
            for name, s in given[1:]:
                if s.time_us != first.time_us:
                    raise ValueError(
                        f"{name}.time_us ({s.time_us}) differs from {first_name}.time_us "
                        f"({first.time_us}); pass time_us explicitly"
                    )
        _uint8(first.sensor_id, f"{first_name}.sensor_id")
        for name, s in given[1:]:
            if s.sensor_id != first.sensor_id:
                raise ValueError(
                    f"{name}.sensor_id ({s.sensor_id}) differs from {first_name}.sensor_id "
                    f"({first.sensor_id}): HIL_SENSOR has one id field"
                )

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
        t = fix.time_us
        if type(t) is not int or not 0 <= t <= UINT64_MAX:
            t = _time_us(t, "fix.time_us")
        lat_e7, lon_e7 = self._lat_lon_e7(fix.lat_rad, fix.lon_rad, "fix")
        # Each check below admits only values the checked path (after ``else``) would send
        # unchanged; anything else (non-finite, out of range, not a float) takes that path,
        # which raises or clips (and counts) as it always did.
        alt = fix.alt_msl_m
        if type(alt) is float and INT32_MIN <= (alt_mm1 := alt * 1e3) <= INT32_MAX:
            alt_mm = round(alt_mm1)
        else:
            alt_mm = self._int(_finite(alt, "fix.alt_msl_m") * 1e3, INT32_MIN, INT32_MAX,
                               "HIL_GPS.alt")
        v = fix.v_ned_mps
        if type(v) is _ndarray and v.dtype is _F64 and v.shape == _SHAPE3:
            v0, v1, v2 = v.tolist()
        else:
            v0, v1, v2 = _vec(v, "fix.v_ned_mps")
        v0 *= 100.0
        v1 *= 100.0
        v2 *= 100.0
        if (INT16_MIN <= v0 <= INT16_MAX and INT16_MIN <= v1 <= INT16_MAX
                and INT16_MIN <= v2 <= INT16_MAX):
            vn, ve, vd = round(v0), round(v1), round(v2)
        else:
            _vec(v, "fix.v_ned_mps")  # a non-finite value raises here
            # field names as literals: formatted names would cost ~1 us a frame
            vn = self._int(v0, INT16_MIN, INT16_MAX, "HIL_GPS.vn")
            ve = self._int(v1, INT16_MIN, INT16_MAX, "HIL_GPS.ve")
            vd = self._int(v2, INT16_MIN, INT16_MAX, "HIL_GPS.vd")
        ground_cms = math.hypot(v0, v1)
        vel = (round(ground_cms) if ground_cms <= UINT16_MAX - 1
               else self._int(ground_cms, 0, UINT16_MAX - 1, "HIL_GPS.vel"))
        if ground_cms > 0.0:
            cog_deg = math.degrees(math.atan2(v1, v0)) % 360.0
            cog = round(cog_deg * 100.0) % 36000
        else:
            cog = UINT16_MAX
        eph_m, epv_m = fix.eph_m, fix.epv_m
        if (type(eph_m) is float and type(epv_m) is float
                and 0.0 <= (eph1 := eph_m * 100.0) <= UINT16_MAX - 1
                and 0.0 <= (epv1 := epv_m * 100.0) <= UINT16_MAX - 1):
            eph, epv = round(eph1), round(epv1)
        else:
            eph = self._accuracy_cm(eph_m, "fix.eph_m", "HIL_GPS.eph")
            epv = self._accuracy_cm(epv_m, "fix.epv_m", "HIL_GPS.epv")
        fix_type, sats, sensor_id = fix.fix_type, fix.satellites_visible, fix.sensor_id
        if not (type(fix_type) is int and 0 <= fix_type <= UINT8_MAX and type(sats) is int
                and 0 <= sats <= UINT8_MAX and type(sensor_id) is int
                and 0 <= sensor_id <= UINT8_MAX):
            fix_type = _uint8(fix_type, "fix.fix_type")
            sats = _uint8(sats, "fix.satellites_visible")
            sensor_id = _uint8(sensor_id, "fix.sensor_id")
        mav = self._sensor_mav
        seq = mav.seq
        mav.seq = (seq + 1) % 256  # as MAVLink.send() would
        return pack_frame(
            HIL_GPS,
            _HIL_GPS_PAYLOAD(  # wire order (checked against the dialect on import)
                t, lat_e7, lon_e7, alt_mm, eph, epv, vel, vn, ve, vd, cog, fix_type, sats,
                sensor_id,
                0,  # yaw: 0 = unknown (no dual-antenna heading in GnssFix)
            ),
            seq, self.system_id, self.sensor_component_id,
        )

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
        # field names as literals: formatted names would cost ~1 us a frame
        m = "HIL_STATE_QUATERNION"
        lat_e7, lon_e7 = self._lat_lon_e7(truth.lat_rad, truth.lon_rad, "truth")
        alt_mm = self._int(
            _finite(truth.alt_msl_m, "truth.alt_msl_m") * 1e3, INT32_MIN, INT32_MAX,
            "HIL_STATE_QUATERNION.alt",
        )
        v0, v1, v2 = (x * 100.0 for x in _vec(truth.v_ned_mps, "truth.v_ned_mps"))
        vx = self._int(v0, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.vx")
        vy = self._int(v1, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.vy")
        vz = self._int(v2, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.vz")
        ias = self._int(
            _finite(truth.indicated_airspeed_mps, "truth.indicated_airspeed_mps") * 100.0,
            0,
            UINT16_MAX,
            "HIL_STATE_QUATERNION.ind_airspeed",
        )
        tas = self._int(
            _finite(truth.airspeed_mps, "truth.airspeed_mps") * 100.0,
            0,
            UINT16_MAX,
            "HIL_STATE_QUATERNION.true_airspeed",
        )
        f_b = _vec(truth.specific_force_b_mps2, "truth.specific_force_b_mps2")
        f0, f1, f2 = (x / (G0_MPS2 * 1e-3) for x in f_b)
        xacc = self._int(f0, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.xacc")
        yacc = self._int(f1, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.yacc")
        zacc = self._int(f2, INT16_MIN, INT16_MAX, "HIL_STATE_QUATERNION.zacc")
        return self._pack(
            HIL_STATE_QUATERNION,
            self._truth_mav,
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

    def actuators(self, sample: ActuatorSample) -> bytes:
        """One HIL_ACTUATOR_CONTROLS frame from the autopilot component.

        Parameters
        ----------
        sample : ActuatorSample
            Up to 16 finite normalised controls (PX4 order), padded with 0 to 16; values are
            sent as given (range checks are the receiver's).

        Returns
        -------
        bytes
            One MAVLink 2 frame.

        Raises
        ------
        ValueError
            More than 16 controls, a non-finite control, a bad time.
        """
        t = _time_us(sample.time_us, "actuators.time_us")
        xs = [float(x) for x in sample.controls]  # plain floats: cheaper than numpy for 16
        if len(xs) > _N_CONTROLS:
            raise ValueError(f"actuators.controls has {len(xs)} values; at most 16")
        if not all(map(math.isfinite, xs)):
            raise ValueError(f"actuators.controls must be finite, got {xs}")
        xs.extend([0.0] * (_N_CONTROLS - len(xs)))
        controls = self._f32_vec(xs, ("controls",) * _N_CONTROLS, "HIL_ACTUATOR_CONTROLS")
        return self._pack(
            HIL_ACTUATOR_CONTROLS, self._autopilot_mav, t, controls, _HIL_ARMED_MODE, 0
        )

    def rpm(self, sample: RpmSample) -> bytes:
        """One RAW_RPM frame from the autopilot component (no timestamp on the wire).

        Parameters
        ----------
        sample : RpmSample
            Finite rpm >= 0, rev/min; ``index`` 0..255.

        Returns
        -------
        bytes
            One MAVLink 2 frame.
        """
        rpm = _finite(sample.rpm, "rpm.rpm")
        if rpm < 0.0:
            raise ValueError(f"rpm.rpm must be >= 0, got {rpm!r}")
        return self._pack(
            RAW_RPM, self._autopilot_mav,
            _uint8(sample.index, "rpm.index"), self._f32(rpm, "RAW_RPM.frequency"),
        )

    def statustext(self, severity: int, text: str) -> bytes:
        """One STATUSTEXT frame from the truth component: a scenario event, which (like the
        truth) only the simulator knows.

        Parameters
        ----------
        severity : int
            ``MAV_SEVERITY`` 0 (emergency) .. 7 (debug).
        text : str
            Cut to the message's 50 characters; non-ASCII characters become ``?``.

        Returns
        -------
        bytes
            One MAVLink 2 frame.
        """
        if not 0 <= severity <= 7:
            raise ValueError(f"STATUSTEXT severity must be 0..7, got {severity!r}")
        raw = text.encode("ascii", "replace")[:50]
        msg = mavlink2.MAVLink_statustext_message(severity, raw, 0, 0)
        frame: bytes = msg.pack(self._truth_mav)  # pymavlink: a message with a string field
        self._truth_mav.seq = (self._truth_mav.seq + 1) % 256  # as MAVLink.send() would
        return frame

    @staticmethod
    def _lat_lon_e7(lat_rad: float, lon_rad: float, owner: str) -> tuple[int, int]:
        lat = lat_rad if type(lat_rad) is float else float(lat_rad)
        lon = lon_rad if type(lon_rad) is float else float(lon_rad)
        if not (-math.inf < lat < math.inf and -math.inf < lon < math.inf):  # names on error
            lat = _finite(lat, f"{owner}.lat_rad")
            lon = _finite(lon, f"{owner}.lon_rad")
        if not -_HALF_PI <= lat <= _HALF_PI:
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
