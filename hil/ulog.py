"""PX4 ULog (``.ulg``) flight logs -> the SI sensor samples of :mod:`sim.samples`, and the
autopilot's own estimate (EKF2) as a reference track.

Read through ``pyulog``. Every field below was checked against PX4's ``msg/*.msg``; times are
the topics' ``timestamp_sample`` when it is logged and non-zero (the sensor's time of
validity), else ``timestamp`` (µs since boot), rebased so that 0 is the log's start
(``ULog.start_timestamp``, or the earliest time of validity if a sample predates it).

Sensors (instance 0 of each topic; other instances are counted, not used)
    ``sensor_combined``
        ``gyro_rad[3]`` rad/s and ``accelerometer_m_s2[3]`` m/s^2, body FRD, each the mean over
        its integration interval ``gyro_integral_dt`` (µs as uint32; seconds in releases
        before v1.8, where the field is a float) -> :class:`ImuSample` at ``timestamp`` (the
        gyro's; the accelerometer's is ``timestamp + accelerometer_timestamp_relative``,
        within one sample). A row with a non-finite value is dropped (``dropped``). The
        sample's temperature is the IMU's: the latest ``sensor_accel`` ``temperature`` °C at
        or before it (else ``vehicle_imu_status`` ``temperature_accel``; PX4 logs either at
        about 1 Hz), NaN before the first or when neither is logged.
    ``vehicle_gps_position`` (else ``sensor_gps``)
        ``latitude_deg`` / ``longitude_deg`` / ``altitude_msl_m`` (v1.14 on) or ``lat`` /
        ``lon`` degE7 and ``alt`` mm MSL (before); ``vel_n_m_s`` ... NED m/s; ``eph`` /
        ``epv`` m (1 sigma); ``s_variance_m_s`` m/s (speed accuracy, despite its name);
        ``fix_type`` (0-1 none, 2 2-D, 3 3-D, 4 DGPS, 5 RTK float, 6 RTK fixed: MAVLink's
        GPS_FIX_TYPE) -> :class:`GnssFix`.
    ``vehicle_air_data``
        ``baro_pressure_pa`` Pa, ``baro_temp_celcius`` (sic) °C -> :class:`BaroSample`.
    ``vehicle_magnetometer``
        ``magnetometer_ga[3]`` gauss, body FRD (calibrated) -> :class:`MagSample` in tesla.
    ``airspeed``
        ``indicated_airspeed_m_s`` -> :class:`AirspeedSample` with the differential pressure
        PX4 derived it from: ``q = rho0 IAS |IAS| / 2``, ``rho0`` the ISA sea-level density
        (PX4's ``calc_IAS``), temperature ``air_temperature_celsius``.
    ``actuator_controls_0``
        ``control[0..7]``: PX4's normalised roll, pitch, yaw, throttle, ... -> the
        :class:`ActuatorSample` HIL_ACTUATOR_CONTROLS carries. ``actuator_outputs`` holds
        mixer outputs (PWM of motors or servos, airframe-specific), not controls: counted in
        ``topics``, not decoded.

Reference (the autopilot's estimate, never truth)
    ``vehicle_attitude`` ``q[4]`` (Hamilton, body FRD -> NED, as ours) gives the reference
    times; ``vehicle_global_position`` ``lat`` / ``lon`` deg and ``alt`` m MSL, or else
    ``vehicle_local_position`` ``x`` / ``y`` / ``z`` m NED about ``ref_lat`` / ``ref_lon`` /
    ``ref_alt`` (rows with ``xy_global`` and ``z_global``; PX4's azimuthal equidistant
    projection on a sphere of radius 6371 km), give the position; ``vehicle_local_position``
    ``vx`` / ``vy`` / ``vz`` m/s NED (rows with ``v_xy_valid`` and ``v_z_valid``) the velocity.
    Position and velocity are interpolated to the attitude times; outside their logged span
    they are NaN (never extrapolated).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray
from pyulog import ULog
from pyulog.core import ULogException

from hil.codec import KELVIN_AT_0_CELSIUS, TESLA_PER_GAUSS
from physconst import ISA_P0_PA, ISA_R_AIR_JPKGK, ISA_T0_K
from sim.samples import (
    ActuatorSample,
    AirspeedSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    Sample,
    Truth,
)

__all__ = ["REFERENCE_LABEL", "UlogLog", "read_ulog"]

REFERENCE_LABEL: Final = "PX4 EKF2"
"""How summaries and plots name the reference of a ULog replay (never "truth")."""

_RHO0_KGPM3: Final = ISA_P0_PA / (ISA_R_AIR_JPKGK * ISA_T0_K)  # 1.225, PX4's sea-level density
_PX4_EARTH_RADIUS_M: Final = 6371000.0  # CONSTANTS_RADIUS_OF_EARTH of PX4's map projection
_N_CONTROLS: Final = 16

#: Topics this reader decodes (or reads as the reference); any other is counted as ignored.
TOPICS: Final = (
    "sensor_combined", "vehicle_gps_position", "sensor_gps", "vehicle_air_data",
    "vehicle_magnetometer", "airspeed", "actuator_controls_0", "actuator_outputs",
    "vehicle_attitude", "vehicle_global_position", "vehicle_local_position",
    "sensor_accel", "vehicle_imu_status",
)  # fmt: skip

FloatArray = NDArray[np.float64]
_Series = tuple[FloatArray, ...]


@dataclass
class UlogLog:
    """What :func:`read_ulog` found.

    Attributes
    ----------
    samples : list of Sample
        Sensor samples in time order, times rebased to the log start (µs).
    reference : list of Truth
        The autopilot's estimate at the ``vehicle_attitude`` times; fields it does not carry
        (rates, specific force, air data) are NaN, and so are position / velocity where the
        log has none.
    reference_position, reference_height : str or None
        Topic the reference's horizontal position / height came from (None: the log has no
        global position / height).
    reference_velocity : bool
        The reference has a velocity (``vehicle_local_position`` with valid velocity).
    gnss_topic : str or None
        Topic the fixes came from.
    fix_types : dict of int to int
        Fixes per ``fix_type``.
    first_fix_utc_us : int or None
        GPS UTC time (``time_utc_usec``) of the first 3-D fix, µs since 1970.
    duration_s : float
        Log start to the last logged message, s.
    topics : dict of str to int
        Messages read per topic used (instance 0).
    ignored_topics : int
        Logged topics (or extra instances) not used.
    dropped : dict of str to int
        Rows dropped per topic (non-finite values).
    corrupt : bool
        pyulog met a damaged stretch and skipped it.
    notes : str
        What pyulog said while reading (e.g. "File corruption detected ...").
    dropouts, dropout_ms : int
        Logger dropouts (messages the logger could not write: data lost on the vehicle) and
        their total duration, ms.
    """

    samples: list[Sample] = field(default_factory=list)
    reference: list[Truth] = field(default_factory=list)
    reference_position: str | None = None
    reference_height: str | None = None
    reference_velocity: bool = False
    gnss_topic: str | None = None
    fix_types: dict[int, int] = field(default_factory=dict)
    first_fix_utc_us: int | None = None
    duration_s: float = 0.0
    topics: dict[str, int] = field(default_factory=dict)
    ignored_topics: int = 0
    dropped: dict[str, int] = field(default_factory=dict)
    corrupt: bool = False
    notes: str = ""
    dropouts: int = 0
    dropout_ms: int = 0

    def count(self, kind: type) -> int:
        """Samples of type ``kind`` (e.g. ``ImuSample``)."""
        return sum(1 for s in self.samples if isinstance(s, kind))


def read_ulog(path: str | os.PathLike[str]) -> UlogLog:
    """Read a PX4 ULog file (see the module docstring for the topics and units).

    Raises
    ------
    ValueError
        The file is not a ULog (bad header), or cannot be parsed.
    """
    p = Path(path)
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said):  # pyulog prints what it skips
            ulog = ULog(str(p))
    except (ULogException, ValueError, IndexError, KeyError, UnicodeDecodeError) as exc:
        raise ValueError(f"{p}: not a readable PX4 ULog file ({exc})") from None
    notes = " ".join(ln.strip() for ln in said.getvalue().splitlines() if ln.strip())
    out = UlogLog(corrupt=bool(getattr(ulog, "file_corruption", False)) or bool(notes),
                  notes=notes, dropouts=len(ulog.dropouts),
                  dropout_ms=sum(int(d.duration) for d in ulog.dropouts))
    data: dict[str, Any] = {}
    for d in ulog.data_list:
        if d.name in TOPICS and d.multi_id == 0 and d.name not in data:
            data[d.name] = d
            out.topics[d.name] = len(d.data["timestamp"])
        else:
            out.ignored_topics += 1
    # time 0: the log start, or an earlier time of validity (a sample taken before logging
    # started) so that no time is negative
    t0 = min([int(ulog.start_timestamp)]
             + [int(_times_us(d, 0).min()) for d in data.values() if len(d.data["timestamp"])])
    out.duration_s = max(0, int(ulog.last_timestamp) - t0) * 1e-6
    samples: list[Sample] = []
    if "sensor_combined" in data:
        samples += _imu(data["sensor_combined"], t0, out, _imu_temperature(data, t0))
    gps_topic = next((n for n in ("vehicle_gps_position", "sensor_gps") if n in data), None)
    if gps_topic is not None:
        out.gnss_topic = gps_topic
        samples += _gnss(data[gps_topic], t0, out)
    if "vehicle_air_data" in data:
        samples += _baro(data["vehicle_air_data"], t0, out)
    if "vehicle_magnetometer" in data:
        samples += _mag(data["vehicle_magnetometer"], t0, out)
    if "airspeed" in data:
        samples += _airspeed(data["airspeed"], t0, out)
    if "actuator_controls_0" in data:
        samples += _controls(data["actuator_controls_0"], t0, out)
    # stable: at equal times the order above (IMU first) is kept
    samples.sort(key=lambda s: s.time_us)
    out.samples = samples
    if "vehicle_attitude" in data:
        out.reference = _reference(data, t0, out)
    return out


# ------------------------------------------------------------------------------ helpers
def _col(d: Any, name: str) -> NDArray[Any] | None:
    a = d.data.get(name)
    return None if a is None else np.asarray(a)


def _vec(d: Any, name: str) -> FloatArray:
    return np.column_stack([np.asarray(d.data[f"{name}[{k}]"], dtype=float) for k in range(3)])


def _times_us(d: Any, t0: int) -> NDArray[np.int64]:
    """``timestamp_sample`` where logged and non-zero, else ``timestamp``; rebased to ``t0``."""
    t = np.asarray(d.data["timestamp"], dtype=np.int64)
    ts = _col(d, "timestamp_sample")
    if ts is not None:
        ts = ts.astype(np.int64)
        t = np.where(ts > 0, ts, t)
    return t - t0


def _field_type(d: Any, name: str) -> str:
    return next((f.type_str for f in d.field_data if f.field_name == name), "")


def _drop(out: UlogLog, topic: str, ok: NDArray[np.bool_]) -> None:
    bad = int(np.count_nonzero(~ok))
    if bad:
        out.dropped[topic] = out.dropped.get(topic, 0) + bad


# ------------------------------------------------------------------------------ sensors
def _imu_temperature(data: dict[str, Any], t0: int) -> tuple[FloatArray, FloatArray] | None:
    """Times (µs) and temperatures (K) of the IMU's logged temperature, finite rows only."""
    for topic, name in (("sensor_accel", "temperature"),
                        ("vehicle_imu_status", "temperature_accel")):
        d = data.get(topic)
        col = None if d is None else _col(d, name)
        if d is not None and col is not None:
            temp = col.astype(float) + 273.15
            ok = np.isfinite(temp)
            if np.any(ok):
                return _times_us(d, t0)[ok].astype(float), temp[ok]
    return None


def _imu(d: Any, t0: int, out: UlogLog,
         temperature: tuple[FloatArray, FloatArray] | None = None) -> list[Sample]:
    t = _times_us(d, t0)
    w = _vec(d, "gyro_rad")
    f = _vec(d, "accelerometer_m_s2")
    dt = np.asarray(d.data["gyro_integral_dt"], dtype=float)
    # uint32 µs since PX4 v1.8; a float in seconds before
    dt_s = dt if _field_type(d, "gyro_integral_dt") == "float" else dt * 1e-6
    ok = np.isfinite(w).all(axis=1) & np.isfinite(f).all(axis=1) & np.isfinite(dt_s)
    _drop(out, "sensor_combined", ok)
    temp_k = np.full(len(t), np.nan)
    if temperature is not None:
        times, values = temperature
        order = np.argsort(times, kind="stable")
        k = np.searchsorted(times[order], t, side="right") - 1  # the latest at or before
        temp_k = np.where(k >= 0, values[order][np.maximum(k, 0)], np.nan)
    return [ImuSample(int(t[i]), float(dt_s[i]), f[i], w[i], float(temp_k[i]))
            for i in np.flatnonzero(ok)]


def _gnss(d: Any, t0: int, out: UlogLog) -> list[Sample]:
    t = _times_us(d, t0)
    if "latitude_deg" in d.data:  # PX4 v1.14 on
        lat = np.asarray(d.data["latitude_deg"], dtype=float)
        lon = np.asarray(d.data["longitude_deg"], dtype=float)
        alt = np.asarray(d.data["altitude_msl_m"], dtype=float)
    else:
        lat = np.asarray(d.data["lat"], dtype=float) * 1e-7
        lon = np.asarray(d.data["lon"], dtype=float) * 1e-7
        alt = np.asarray(d.data["alt"], dtype=float) * 1e-3
    v = np.column_stack([np.asarray(d.data[f"vel_{c}_m_s"], dtype=float) for c in "ned"])
    eph = np.asarray(d.data["eph"], dtype=float)
    epv = np.asarray(d.data["epv"], dtype=float)
    sacc = np.asarray(d.data["s_variance_m_s"], dtype=float)
    fix = np.asarray(d.data["fix_type"], dtype=int)
    sats_col = _col(d, "satellites_used")
    sats = sats_col.astype(int) if sats_col is not None else np.zeros(len(t), dtype=int)
    utc_col = _col(d, "time_utc_usec")
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    _drop(out, out.gnss_topic or "gnss", ok)
    fixes: list[Sample] = []
    for i in np.flatnonzero(ok):
        ft = int(fix[i])
        out.fix_types[ft] = out.fix_types.get(ft, 0) + 1
        if ft >= 3 and out.first_fix_utc_us is None and utc_col is not None and utc_col[i] > 0:
            out.first_fix_utc_us = int(utc_col[i])
        fixes.append(GnssFix(
            int(t[i]), math.radians(lat[i]), math.radians(lon[i]), float(alt[i]), v[i],
            float(eph[i]), float(epv[i]), float(sacc[i]), fix_type=ft,
            satellites_visible=int(sats[i]),
        ))  # fmt: skip
    return fixes


def _baro(d: Any, t0: int, out: UlogLog) -> list[Sample]:
    if "baro_pressure_pa" not in d.data:  # releases before v1.9 logged only the altitude
        out.dropped["vehicle_air_data"] = len(d.data["timestamp"])
        return []
    t = _times_us(d, t0)
    p = np.asarray(d.data["baro_pressure_pa"], dtype=float)
    temp_c = _col(d, "baro_temp_celcius")
    temp_k = (temp_c.astype(float) if temp_c is not None else np.full(len(t), ISA_T0_K
                                                                      - KELVIN_AT_0_CELSIUS))
    temp_k = temp_k + KELVIN_AT_0_CELSIUS
    ok = np.isfinite(p) & (p > 0.0) & np.isfinite(temp_k)
    _drop(out, "vehicle_air_data", ok)
    return [BaroSample(int(t[i]), float(p[i]), float(temp_k[i])) for i in np.flatnonzero(ok)]


def _mag(d: Any, t0: int, out: UlogLog) -> list[Sample]:
    t = _times_us(d, t0)
    m = _vec(d, "magnetometer_ga") * TESLA_PER_GAUSS
    ok = np.asarray(np.isfinite(m).all(axis=1), dtype=bool)
    _drop(out, "vehicle_magnetometer", ok)
    return [MagSample(int(t[i]), m[i]) for i in np.flatnonzero(ok)]


def _airspeed(d: Any, t0: int, out: UlogLog) -> list[Sample]:
    t = _times_us(d, t0)
    ias = np.asarray(d.data["indicated_airspeed_m_s"], dtype=float)
    temp = _col(d, "air_temperature_celsius")
    temp_k = (temp.astype(float) + KELVIN_AT_0_CELSIUS if temp is not None
              else np.full(len(t), ISA_T0_K))  # fmt: skip
    ok = np.isfinite(ias) & np.isfinite(temp_k)
    _drop(out, "airspeed", ok)
    dp = 0.5 * _RHO0_KGPM3 * ias * np.abs(ias)
    return [AirspeedSample(int(t[i]), float(dp[i]), float(temp_k[i]))
            for i in np.flatnonzero(ok)]  # fmt: skip


def _controls(d: Any, t0: int, out: UlogLog) -> list[Sample]:
    t = _times_us(d, t0)
    n = sum(1 for k in range(_N_CONTROLS) if f"control[{k}]" in d.data)
    c = np.column_stack([np.asarray(d.data[f"control[{k}]"], dtype=float) for k in range(n)])
    ok = np.isfinite(c[:, :4]).all(axis=1)
    _drop(out, "actuator_controls_0", ok)
    c = np.nan_to_num(c)
    pad = (0.0,) * (_N_CONTROLS - n)
    return [ActuatorSample(int(t[i]), tuple(float(x) for x in c[i]) + pad)
            for i in np.flatnonzero(ok)]  # fmt: skip


# ---------------------------------------------------------------------------- reference
def _reference(data: dict[str, Any], t0: int, out: UlogLog) -> list[Truth]:
    att = data["vehicle_attitude"]
    t_us = _times_us(att, t0)
    q = np.column_stack([np.asarray(att.data[f"q[{k}]"], dtype=float) for k in range(4)])
    norm = np.linalg.norm(q, axis=1)
    ok = np.isfinite(q).all(axis=1) & (norm > 0.5)
    _drop(out, "vehicle_attitude", ok)
    t_us, q = t_us[ok], q[ok] / norm[ok, None]
    t_s = t_us * 1e-6
    horizontal, vertical = _reference_position(data, t0, out)
    n = len(t_us)
    lat = lon = alt = np.full(n, np.nan)
    if horizontal is not None:
        lat, lon = _interp(t_s, horizontal[0], horizontal[1]), _interp(t_s, *horizontal[::2])
    if vertical is not None:
        alt = _interp(t_s, *vertical)
    v = np.full((n, 3), np.nan)
    lpos = data.get("vehicle_local_position")
    if lpos is not None:
        valid = (_flag(lpos, "v_xy_valid") & _flag(lpos, "v_z_valid"))
        if np.any(valid):
            tl = np.asarray(_times_us(lpos, t0)[valid] * 1e-6, dtype=float)
            v = np.column_stack([_interp(t_s, tl, np.asarray(lpos.data[c], dtype=float)[valid])
                                 for c in ("vx", "vy", "vz")])  # fmt: skip
            out.reference_velocity = True
    # where the autopilot has a global position (or height), the reference is the part that
    # has it (a scored stretch without would give NaN position errors); without any, the
    # reference is attitude (and velocity) only
    has = np.isfinite(lat) | np.isfinite(alt)
    rows = np.flatnonzero(has) if has.any() else np.arange(n)
    nan3 = np.full(3, np.nan)
    return [
        Truth(int(t_us[i]), float(lat[i]), float(lon[i]), float(alt[i]), v[i], q[i], nan3,
              nan3, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
        for i in rows
    ]


def _flag(d: Any, name: str) -> NDArray[np.bool_]:
    a = _col(d, name)
    return np.ones(len(d.data["timestamp"]), bool) if a is None else a.astype(bool)


def _interp(t: FloatArray, tp: FloatArray, fp: FloatArray) -> FloatArray:
    """Linear interpolation at ``t``; NaN outside ``tp``'s span (never extrapolated)."""
    if tp.size == 0:
        return np.full(t.shape, np.nan)
    y = np.interp(t, tp, fp)
    y[(t < tp[0]) | (t > tp[-1])] = np.nan
    return y


def _reference_position(
    data: dict[str, Any], t0: int, out: UlogLog
) -> tuple[_Series | None, _Series | None]:
    """The autopilot's global position: ``(time_s, lat_rad, lon_rad)`` and
    ``(time_s, alt_msl_m)``, each None when the log has none."""
    gpos = data.get("vehicle_global_position")
    if gpos is not None and len(gpos.data["timestamp"]):
        t = _times_us(gpos, t0) * 1e-6
        lat = np.radians(np.asarray(gpos.data["lat"], dtype=float))
        lon = np.radians(np.asarray(gpos.data["lon"], dtype=float))
        alt = np.asarray(gpos.data["alt"], dtype=float)
        ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
        if np.any(ok):
            out.reference_position = "vehicle_global_position"
            out.reference_height = "vehicle_global_position"
            return (t[ok], lat[ok], lon[ok]), (t[ok], alt[ok])
    lpos = data.get("vehicle_local_position")
    if lpos is None:
        return None, None
    t = _times_us(lpos, t0) * 1e-6
    ref = {c: np.asarray(lpos.data[f"ref_{c}"], dtype=float) for c in ("lat", "lon", "alt")}
    ok_h = (_flag(lpos, "xy_global") & _flag(lpos, "xy_valid") & np.isfinite(ref["lat"])
            & np.isfinite(ref["lon"]))  # fmt: skip
    ok_v = _flag(lpos, "z_global") & _flag(lpos, "z_valid") & np.isfinite(ref["alt"])
    horizontal = vertical = None
    if np.any(ok_h):
        x, y = (np.asarray(lpos.data[c], dtype=float)[ok_h] for c in ("x", "y"))
        lat, lon = _reproject(np.radians(ref["lat"][ok_h]), np.radians(ref["lon"][ok_h]), x, y)
        horizontal = (t[ok_h], lat, lon)
        out.reference_position = "vehicle_local_position"
    if np.any(ok_v):
        z = np.asarray(lpos.data["z"], dtype=float)[ok_v]
        vertical = (t[ok_v], ref["alt"][ok_v] - z)
        out.reference_height = "vehicle_local_position"
    return horizontal, vertical


def _reproject(
    ref_lat_rad: FloatArray, ref_lon_rad: FloatArray, x_m: FloatArray, y_m: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """PX4's ``MapProjection::reproject``: local North/East (m) about a reference -> lat/lon
    (rad), azimuthal equidistant projection on a sphere."""
    xr = x_m / _PX4_EARTH_RADIUS_M
    yr = y_m / _PX4_EARTH_RADIUS_M
    c = np.hypot(xr, yr)
    sin_c, cos_c = np.sin(c), np.cos(c)
    s_lat, c_lat = np.sin(ref_lat_rad), np.cos(ref_lat_rad)
    safe_c = np.where(c > 0.0, c, 1.0)
    lat = np.where(c > 0.0, np.arcsin(cos_c * s_lat + xr * sin_c * c_lat / safe_c), ref_lat_rad)
    lon = np.where(
        c > 0.0,
        ref_lon_rad + np.arctan2(yr * sin_c, safe_c * c_lat * cos_c - xr * s_lat * sin_c),
        ref_lon_rad,
    )
    return lat, lon
