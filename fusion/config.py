"""Filter configuration: frozen pydantic models that reject unknown keys; SI units only.

Human units (deg/h, mg, ug/sqrt(Hz)) belong to the YAML files and are converted before building
these models. Defaults describe a mid-range MEMS IMU (gyro 0.005 deg/s/sqrt(Hz), 10 deg/h bias;
accelerometer 100 ug/sqrt(Hz), 1 mg bias), a single-frequency GNSS receiver at 5 Hz and a
MEMS barometer.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, PositiveFloat, PositiveInt

Probability = float


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ImuConfig(_Frozen):
    """IMU error model (what the filter assumes) and the sensor's measurement range."""

    gyro_noise_density_rps_rthz: PositiveFloat = math.radians(0.005)
    """Angle random walk, rad/s/sqrt(Hz)."""
    accel_noise_density_mps2_rthz: PositiveFloat = 100e-6 * 9.80665
    """Velocity random walk, m/s^2/sqrt(Hz)."""
    gyro_bias_sigma_rps: PositiveFloat = math.radians(10.0) / 3600.0
    """Steady-state sigma of the Gauss-Markov gyro bias, rad/s."""
    gyro_bias_tau_s: PositiveFloat = 600.0
    accel_bias_sigma_mps2: PositiveFloat = 1e-3 * 9.80665
    """Steady-state sigma of the Gauss-Markov accelerometer bias, m/s^2."""
    accel_bias_tau_s: PositiveFloat = 600.0
    gyro_turn_on_sigma_rps: NonNegativeFloat = math.radians(30.0) / 3600.0
    """Turn-on (run-to-run) gyro bias sigma, a random constant: only widens the initial
    covariance of the gyro bias state, rad/s."""
    accel_turn_on_sigma_mps2: NonNegativeFloat = 2e-3 * 9.80665
    """Turn-on (run-to-run) accelerometer bias sigma, m/s^2 (initial covariance only)."""
    gyro_scale_sigma: PositiveFloat = 1e-3
    """Scale-factor sigma (only with ``state_layout="ins22"``), dimensionless."""
    gyro_scale_tau_s: PositiveFloat = 3600.0
    accel_scale_sigma: PositiveFloat = 1e-3
    accel_scale_tau_s: PositiveFloat = 3600.0
    gyro_range_rps: PositiveFloat = math.radians(2000.0)
    """Samples with any axis beyond this are rejected as garbage, rad/s."""
    accel_range_mps2: PositiveFloat = 16.0 * 9.80665
    """Samples with any axis beyond this are rejected as garbage, m/s^2."""
    max_dt_s: PositiveFloat = 0.05
    """Longest plausible IMU interval; larger ``dt_s`` values are treated as invalid, s."""
    time_jump_s: PositiveFloat = 1.0
    """A forward timestamp step larger than this is a time jump: the gap is not integrated."""
    max_sensor_lead_s: PositiveFloat = 5.0
    """GNSS / baro / mag samples stamped further than this ahead of the IMU are dropped and
    counted as time jumps (one bogus future stamp must not block its stream), s."""
    gap_accel_sigma_mps2: PositiveFloat = 2.0
    """Unknown acceleration assumed over a time-jump gap (the INS coasts at constant velocity;
    the covariance grows by this much manoeuvring), m/s^2."""
    gap_rate_sigma_rps: PositiveFloat = math.radians(3.0)
    """Unknown rotation rate assumed over a time-jump gap, rad/s."""


class GnssConfig(_Frozen):
    """GNSS position/velocity aiding."""

    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Antenna position relative to the IMU in body FRD, m."""
    pos_noise_floor_m: PositiveFloat = 0.5
    """Lower bound on the position sigma taken from ``eph_m`` / ``epv_m``, m."""
    vel_noise_floor_mps: PositiveFloat = 0.1
    """Lower bound on the velocity sigma taken from ``speed_accuracy_mps``, m/s."""
    default_eph_m: PositiveFloat = 5.0
    """Horizontal sigma used when a fix does not report ``eph`` (NaN), m."""
    default_epv_m: PositiveFloat = 8.0
    """Vertical sigma used when a fix does not report ``epv`` (NaN), m."""
    default_speed_accuracy_mps: PositiveFloat = 0.3
    """Velocity sigma used when a fix does not report speed accuracy (HIL_GPS never does), m/s."""
    max_eph_m: PositiveFloat = 25.0
    """Fixes reporting a larger horizontal accuracy are not used, m."""
    gate_probability: Probability = Field(default=0.995, gt=0.5, lt=1.0)
    """Chi-square gate acceptance probability for the 3-D position and velocity tests."""
    outage_timeout_s: PositiveFloat = 1.0
    """No fused fix for this long: mode becomes free-inertial (or bridging)."""
    reacquire_fixes: PositiveInt = 3
    """Consecutive good fixes needed to leave free-inertial mode."""
    reset_after_rejected_s: PositiveFloat = 5.0
    """Good-quality fixes rejected by the gate for this long: reset position and velocity."""
    max_delay_s: PositiveFloat = 0.5
    """Fixes whose time of validity is older than this (w.r.t. the INS) are dropped, s."""


class BaroConfig(_Frozen):
    """Barometric height aiding with a Gauss-Markov bias state."""

    noise_m: PositiveFloat = 0.5
    """Height noise sigma of one sample, m."""
    fuse_rate_hz: PositiveFloat = 10.0
    """Samples are averaged over ``1 / fuse_rate_hz`` and fused as one height (variance divided
    by the count, time of validity the mean time): same information, fewer updates."""
    bias_sigma_m: PositiveFloat = 5.0
    """Steady-state sigma of the baro-bias Gauss-Markov process, m."""
    bias_tau_s: PositiveFloat = 1000.0
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    timeout_s: PositiveFloat = 1.0
    """No baro sample for this long: baro aiding reported inactive (the bias is kept)."""
    reset_after_rejected_s: PositiveFloat = 5.0
    """Rejected for this long: re-initialise the baro bias from the current height."""


class MagConfig(_Frozen):
    """Magnetometer heading aiding."""

    heading_noise_rad: PositiveFloat = math.radians(3.0)
    """Heading sigma (generous: covers soft/hard-iron residuals and field errors), rad."""
    fuse_rate_hz: PositiveFloat = 5.0
    """Highest rate at which mag samples are fused, Hz."""
    reference_field_n_tesla: tuple[float, float, float] | None = None
    """Earth field in NED (T). ``None``: learned from the body field and the filter attitude once
    the yaw sigma is below ``learn_yaw_sigma_rad`` (no mag heading fusion before that)."""
    learn_yaw_sigma_rad: PositiveFloat = math.radians(2.0)
    min_horizontal_field_tesla: PositiveFloat = 5e-6
    """Samples whose horizontal field (after tilt) is weaker than this are not used."""
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)


class InitConfig(_Frozen):
    """Alignment and initial uncertainties."""

    mode: Literal["in_flight", "static"] = "in_flight"
    """``in_flight``: from two GNSS fixes (heading from the track, level from specific force
    minus GNSS acceleration). ``static``: levelling plus magnetometer heading (gyrocompassing
    when no magnetometer reference), vehicle at rest."""
    min_speed_mps: PositiveFloat = 5.0
    """In-flight alignment needs this ground speed for a track angle, m/s."""
    window_s: PositiveFloat = 1.0
    """In-flight alignment averages over this span of good fixes (longer: less GNSS velocity
    noise in the specific force, more blur of manoeuvres), s."""
    max_fix_interval_s: PositiveFloat = 1.5
    """A larger gap between good fixes restarts the in-flight alignment, s."""
    static_duration_s: PositiveFloat = 2.0
    """Averaging window of the static alignment, s."""
    static_max_rate_rps: PositiveFloat = 0.02
    """Static alignment restarts when the mean rate exceeds this (vehicle moving), rad/s."""
    pos_sigma_m: PositiveFloat = 5.0
    vel_sigma_mps: PositiveFloat = 0.5
    roll_pitch_sigma_rad: PositiveFloat = math.radians(2.0)
    yaw_sigma_rad: PositiveFloat = math.radians(15.0)
    """Covers the track-vs-heading difference of a crabbing aircraft (10 deg and more)."""
    static_yaw_sigma_rad: PositiveFloat = math.radians(5.0)
    baro_bias_sigma_m: PositiveFloat = 2.0
    """Added (in quadrature) to the height sigma when the baro bias is initialised, m."""


class RatesConfig(_Frozen):
    """Covariance propagation and output rates."""

    covariance_rate_hz: PositiveFloat | None = 100.0
    """Covariance propagated at this rate, the transition accumulated in between; ``None``:
    every IMU sample."""
    output_rate_hz: PositiveFloat = 50.0
    """Rate of the estimates returned by ``NavFilter.step``, Hz."""


class BridgeConfig(_Frozen):
    """How often the bridging strategy is consulted during an outage."""

    rate_hz: PositiveFloat = 5.0


class FilterConfig(_Frozen):
    """Everything :class:`fusion.filter.NavFilter` needs."""

    state_layout: Literal["ins16", "ins22"] = "ins16"
    """``ins16``: pos, vel, att, accel bias, gyro bias, baro bias. ``ins22``: plus accelerometer
    and gyro scale factors."""
    imu: ImuConfig = ImuConfig()
    gnss: GnssConfig = GnssConfig()
    baro: BaroConfig = BaroConfig()
    mag: MagConfig = MagConfig()
    init: InitConfig = InitConfig()
    rates: RatesConfig = RatesConfig()
    bridge: BridgeConfig = BridgeConfig()
