"""Truth and sensor samples, SI units, frames in the field names.

These small frozen dataclasses are what the simulator produces, what ``hil.codec`` encodes
and decodes, and what ``fusion.NavFilter`` consumes (structurally, through the protocols in
``fusion.samples``).

:func:`make_imu_sample`, :func:`make_gnss_fix` and :func:`make_truth` make the same objects
as the classes' constructors (all fields given, positionally) at about a third of the cost:
for the decoder, which makes one per frame. A frozen dataclass's ``__init__`` sets each field
through ``object.__setattr__``; these set them on an unfrozen twin with the same slots, which
then becomes the frozen class by ``__class__`` assignment.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

Vec3 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Truth:
    """True vehicle state at ``time_us`` (simulated time).

    Attributes
    ----------
    lat_rad, lon_rad : geodetic latitude / longitude, rad (WGS-84).
    alt_msl_m : altitude above mean sea level, m.
    v_ned_mps : (3,) velocity in NED, m/s.
    q_nb : (4,) Hamilton quaternion [w, x, y, z], body FRD -> NED.
    omega_b_rps : (3,) body angular rate w.r.t. inertial space, expressed in body, rad/s.
    specific_force_b_mps2 : (3,) specific force at the IMU, body FRD, m/s^2 (≈ [0, 0, -9.8]
        in level flight).
    static_pressure_pa, temperature_k : ambient static pressure and temperature.
    airspeed_mps : true airspeed; ``indicated_airspeed_mps`` calibrated/indicated airspeed.
    alpha_rad, beta_rad : angle of attack and sideslip of the air-relative velocity in body
        axes (JSBSim ``aero/alpha-rad``, ``aero/beta-rad``): ``u = V cosα cosβ``,
        ``v = V sinβ``, ``w = V sinα cosβ``. Default 0 (level, coordinated); NaN when unknown
        (truth decoded from HIL_STATE_QUATERNION, which carries neither).
    wind_ned_mps : (3,) velocity of the air mass at the vehicle (steady wind, shear and
        turbulence), NED, m/s; NaN where the source does not carry it (decoded
        HIL_STATE_QUATERNION, constructors that leave it out).
    """

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: Vec3
    q_nb: NDArray[np.float64]
    omega_b_rps: Vec3
    specific_force_b_mps2: Vec3
    static_pressure_pa: float
    temperature_k: float
    airspeed_mps: float
    indicated_airspeed_mps: float
    alpha_rad: float = 0.0
    beta_rad: float = 0.0
    wind_ned_mps: Vec3 = field(default_factory=lambda: np.full(3, np.nan))


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One IMU output: specific force and angular rate in body FRD, averaged over ``dt_s``.

    ``time_us`` is the end of the averaging interval; ``dt_s`` its length.
    """

    time_us: int
    dt_s: float
    specific_force_b_mps2: Vec3
    angular_rate_b_rps: Vec3
    temperature_k: float = 288.15
    sensor_id: int = 0


@dataclass(frozen=True, slots=True)
class GnssFix:
    """One GNSS receiver fix. ``time_us`` is the time of validity (not of arrival).

    ``eph_m`` / ``epv_m`` are the receiver's reported 1-sigma horizontal / vertical position
    accuracy (see ``hil.codec`` for how they map to HIL_GPS). ``fix_type`` follows
    GPS_FIX_TYPE (0-1 no fix, 2 = 2D, 3 = 3D, ...).
    """

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: Vec3
    eph_m: float
    epv_m: float
    speed_accuracy_mps: float
    fix_type: int = 3
    satellites_visible: int = 12
    sensor_id: int = 0


@dataclass(frozen=True, slots=True)
class BaroSample:
    """Static pressure and the sensor's temperature."""

    time_us: int
    pressure_pa: float
    temperature_k: float
    sensor_id: int = 0


@dataclass(frozen=True, slots=True)
class MagSample:
    """Magnetic flux density in body FRD, tesla."""

    time_us: int
    field_b_tesla: Vec3
    sensor_id: int = 0


@dataclass(frozen=True, slots=True)
class AirspeedSample:
    """Pitot-static differential pressure (total minus static pressure), Pa, and the sensor's
    temperature, K (HIL_SENSOR ``diff_pressure``, bit 10, carries it in hPa)."""

    time_us: int
    diff_pressure_pa: float
    temperature_k: float
    sensor_id: int = 0


@dataclass(frozen=True, slots=True)
class ActuatorSample:
    """Normalised actuator controls in PX4's HIL_ACTUATOR_CONTROLS order (16 values: roll,
    pitch, yaw in [-1, 1], throttle in [0, 1], then flaps, spoilers, ..., unused = 0)."""

    time_us: int
    controls: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class RpmSample:
    """Propeller (engine) speed, revolutions per minute (MAVLink RAW_RPM ``frequency``).

    RAW_RPM has no timestamp: a decoder stamps it with the latest sensor time of its source.
    """

    time_us: int
    rpm: float
    index: int = 0


def _unfrozen_twin(cls: type) -> type:
    """A plain class with ``cls``'s slots: an instance of it takes ordinary attribute stores
    and then becomes a ``cls`` by ``__class__`` assignment (same layout)."""
    return type(f"_{cls.__name__}Unfrozen", (), {"__slots__": cls.__dict__["__slots__"]})


_new = object.__new__
_IMU_TWIN: Any = _unfrozen_twin(ImuSample)
_GNSS_TWIN: Any = _unfrozen_twin(GnssFix)
_TRUTH_TWIN: Any = _unfrozen_twin(Truth)


def make_imu_sample(
    time_us: int, dt_s: float, specific_force_b_mps2: Vec3, angular_rate_b_rps: Vec3,
    temperature_k: float, sensor_id: int,
) -> ImuSample:
    """``ImuSample(time_us, dt_s, specific_force_b_mps2, angular_rate_b_rps, temperature_k,
    sensor_id)``, the same object, made without the class call, its ``__init__`` and its
    frozen ``object.__setattr__`` per field."""
    s = _new(_IMU_TWIN)
    s.time_us = time_us
    s.dt_s = dt_s
    s.specific_force_b_mps2 = specific_force_b_mps2
    s.angular_rate_b_rps = angular_rate_b_rps
    s.temperature_k = temperature_k
    s.sensor_id = sensor_id
    s.__class__ = ImuSample  # frozen from here on
    sample: ImuSample = s
    return sample


def make_gnss_fix(
    time_us: int, lat_rad: float, lon_rad: float, alt_msl_m: float, v_ned_mps: Vec3,
    eph_m: float, epv_m: float, speed_accuracy_mps: float, fix_type: int,
    satellites_visible: int, sensor_id: int,
) -> GnssFix:
    """``GnssFix(...)`` with every field given in order, the same object, made as
    :func:`make_imu_sample` makes its sample."""
    s = _new(_GNSS_TWIN)
    s.time_us = time_us
    s.lat_rad = lat_rad
    s.lon_rad = lon_rad
    s.alt_msl_m = alt_msl_m
    s.v_ned_mps = v_ned_mps
    s.eph_m = eph_m
    s.epv_m = epv_m
    s.speed_accuracy_mps = speed_accuracy_mps
    s.fix_type = fix_type
    s.satellites_visible = satellites_visible
    s.sensor_id = sensor_id
    s.__class__ = GnssFix  # frozen from here on
    fix: GnssFix = s
    return fix


def make_truth(
    time_us: int, lat_rad: float, lon_rad: float, alt_msl_m: float, v_ned_mps: Vec3,
    q_nb: NDArray[np.float64], omega_b_rps: Vec3, specific_force_b_mps2: Vec3,
    static_pressure_pa: float, temperature_k: float, airspeed_mps: float,
    indicated_airspeed_mps: float, alpha_rad: float, beta_rad: float, wind_ned_mps: Vec3,
) -> Truth:
    """``Truth(...)`` with every field given in order, the same object, made as
    :func:`make_imu_sample` makes its sample (the decoder makes one per HIL_STATE_QUATERNION
    frame)."""
    s = _new(_TRUTH_TWIN)
    s.time_us = time_us
    s.lat_rad = lat_rad
    s.lon_rad = lon_rad
    s.alt_msl_m = alt_msl_m
    s.v_ned_mps = v_ned_mps
    s.q_nb = q_nb
    s.omega_b_rps = omega_b_rps
    s.specific_force_b_mps2 = specific_force_b_mps2
    s.static_pressure_pa = static_pressure_pa
    s.temperature_k = temperature_k
    s.airspeed_mps = airspeed_mps
    s.indicated_airspeed_mps = indicated_airspeed_mps
    s.alpha_rad = alpha_rad
    s.beta_rad = beta_rad
    s.wind_ned_mps = wind_ned_mps
    s.__class__ = Truth  # frozen from here on
    truth: Truth = s
    return truth


Sample = (
    ImuSample | GnssFix | BaroSample | MagSample | AirspeedSample | ActuatorSample | RpmSample
)
