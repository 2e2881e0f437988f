"""Filter configuration: frozen pydantic models that reject unknown keys; SI units only.

Human units (deg/h, mg, ug/sqrt(Hz)) belong to the YAML files and are converted before building
these models. Defaults describe a mid-range MEMS IMU (gyro 0.005 deg/s/sqrt(Hz), 10 deg/h bias;
accelerometer 100 ug/sqrt(Hz), 1 mg bias), a single-frequency GNSS receiver at 5 Hz and a
MEMS barometer.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    field_validator,
    model_validator,
)

from fusion.altitude.channel import AltitudeChannelConfig
from fusion.choices import (  # noqa: F401  # re-exported: the commands' choices
    AIRSPEED_MODES,
    ALIGN_MODES,
    ALTITUDE_METHODS,
    DEFAULT_AIRSPEED_MODE,
    DEFAULT_ALIGN_MODE,
)
from fusion.error_model import ProcessNoise
from fusion.state_layout import LayoutName
from fusion.thermal.tuning import ThermalTuning, widened_bias_sigma
from physconst.geomag import DEFAULT_DECIMAL_YEAR

Probability = float


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ImuTuning(_Frozen):
    """What the filter assumes about the IMU: its error model and its measurement range."""

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
    """Scale-factor sigma (only with ``state_layout="ins22"`` / ``"ins35"``), dimensionless."""
    gyro_scale_tau_s: PositiveFloat = 3600.0
    accel_scale_sigma: PositiveFloat = 1e-3
    accel_scale_tau_s: PositiveFloat = 3600.0
    gyro_misalignment_sigma_rad: PositiveFloat = 1e-3
    """Misalignment / cross-axis sigma per off-diagonal entry (only with
    ``state_layout="ins35"``), rad; its correlation time is the scale factor's."""
    accel_misalignment_sigma_rad: PositiveFloat = 1e-3
    gyro_range_rps: PositiveFloat = math.radians(2000.0)
    """Samples with any axis beyond this are rejected as garbage, rad/s."""
    accel_range_mps2: PositiveFloat = 16.0 * 9.80665
    """Samples with any axis beyond this are rejected as garbage, m/s^2."""
    max_dt_s: PositiveFloat = 0.05
    """Longest plausible IMU interval; larger ``dt_s`` values are treated as invalid, s."""
    time_jump_s: PositiveFloat = 1.0
    """An IMU timestamp more than this ahead of the filter's clock (or any amount behind it) is
    not trusted on its own: it is quarantined and counted, and the clock does not move. Only
    ``time_base_confirm_samples`` consecutive such samples at plausible intervals (a
    consistent new time base) are acted on: a forward gap up to ``max_coast_s`` is coasted
    over (not integrated), anything else re-initialises the filter, s."""
    time_base_confirm_samples: PositiveInt = 5
    """Consecutive quarantined IMU samples, each within ``max_dt_s`` of the previous, that
    confirm a new time base (a link drop-out or a simulator restart, not one bogus frame)."""
    max_coast_s: PositiveFloat = 10.0
    """Longest confirmed forward gap the INS coasts over; a longer one (or a step back)
    re-initialises the filter (``Health.time_rebases``), s."""
    max_sensor_lead_s: PositiveFloat = 5.0
    """GNSS / baro / mag samples stamped further than this ahead of the IMU are dropped and
    counted as time jumps (one bogus future stamp must not block its stream), s."""
    gap_accel_sigma_mps2: PositiveFloat = 2.0
    """Unknown acceleration assumed over a time-jump gap (the INS coasts at constant velocity;
    the covariance grows by this much manoeuvring) and over the interval of a sample replaced
    by the last good one (NaN, out of range), m/s^2."""
    gap_rate_sigma_rps: PositiveFloat = math.radians(3.0)
    """Unknown rotation rate assumed over a time-jump gap or a held sample's interval, rad/s."""


class GnssTuning(_Frozen):
    """What the filter assumes about the GNSS receiver, and how it fuses its fixes."""

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
    """Good-quality fixes rejected by the gate for this long: reset position and velocity (a
    bounded reset, see ``reset_sigma``)."""
    reset_sigma: PositiveFloat = 5.0
    """A reset goes to a fix only if the INS does not contradict it: every axis of the
    innovation within ``reset_sigma`` times the INS's own sigma plus the fix's claimed
    accuracy. A contradicted fix needs ``reset_confirm_fixes`` consecutive rejected fixes
    that agree with each other (positions moving as their velocities say)."""
    reset_confirm_fixes: PositiveInt = 5
    """Consecutive mutually consistent rejected fixes that allow a reset the INS contradicts."""
    max_accel_mps2: PositiveFloat = 30.0
    """Acceleration allowed between two consecutive fixes in that consistency check, m/s^2."""
    min_alt_m: float = -1000.0
    """Fixes below this altitude (MSL) are invalid, m."""
    max_alt_m: float = 50_000.0
    """Fixes above this altitude (MSL) are invalid, m."""
    max_speed_mps: PositiveFloat = 600.0
    """Fixes reporting a faster horizontal or vertical speed are invalid, m/s."""
    max_delay_s: PositiveFloat = 0.5
    """Fixes whose time of validity is older than this (w.r.t. the INS) are dropped, s."""
    bias_sigma_h_m: PositiveFloat = 1.4
    """Steady-state sigma of the receiver's time-correlated position error (atmosphere, orbits,
    multipath) per horizontal axis, m. Used by the layouts with the GNSS position-bias states
    (``ins16+gnss`` / ``ins22+gnss``, :attr:`FilterConfig.state_layout`): the position update
    then takes only the white part of the reported accuracy,
    ``sqrt(eph^2 - bias_sigma_h_m^2)`` (floored by ``pos_noise_floor_m``)."""
    bias_sigma_v_m: PositiveFloat = 2.4
    """Steady-state sigma of the correlated position error, Down, m."""
    bias_tau_h_s: PositiveFloat = 120.0
    """Correlation time of the horizontal position bias, s."""
    bias_tau_v_s: PositiveFloat = 120.0
    """Correlation time of the vertical position bias, s."""


class BaroTuning(_Frozen):
    """What the filter assumes about the barometer: height aiding with a Gauss-Markov bias
    state."""

    noise_m: PositiveFloat = 0.5
    """Height noise sigma of one sample, m."""
    fuse_rate_hz: PositiveFloat = 10.0
    """Samples are averaged over ``1 / fuse_rate_hz`` and fused as one height (variance divided
    by the count, time of validity the mean time): same information, fewer updates."""
    bias_sigma_m: PositiveFloat = 5.0
    """Steady-state sigma of the baro-bias Gauss-Markov process, m."""
    bias_tau_s: PositiveFloat = 1000.0
    scale_sigma: PositiveFloat = 0.05
    """Prior sigma of the baro scale factor (layouts with the state, ``ins35``): how much the
    ISA pressure height's changes differ from true height changes in a non-standard
    atmosphere, ``dT / T``: 0.05 covers a day 15 K off ISA at 1 sigma (paper P4)."""
    scale_tau_s: PositiveFloat = 3600.0
    """The scale factor is a random constant plus a random walk that reaches ``scale_sigma``
    in this time (the atmosphere changes slowly), s."""
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    timeout_s: PositiveFloat = 1.0
    """No baro sample for this long: baro aiding reported inactive (the bias is kept)."""
    reset_after_rejected_s: PositiveFloat = 5.0
    """Rejected for this long: re-initialise the baro bias from the current height."""


class MagTuning(_Frozen):
    """What the filter assumes about the magnetometer, and how it fuses its heading."""

    heading_noise_rad: PositiveFloat = math.radians(3.0)
    """Heading sigma (generous: covers soft/hard-iron residuals and field errors), rad."""
    fuse_rate_hz: PositiveFloat = 0.5
    """Highest rate at which mag samples are fused, Hz. The heading error of a magnetometer
    (hard/soft-iron residual, error of the reference field) is correlated over tens of seconds,
    so fusing it as white noise at 5 Hz counts one error ten times and makes the yaw
    overconfident; at 0.5 Hz (tuning seeds 1-2 of ``bench/consistency.py``) the yaw was both
    more accurate and more consistent (docs/results.md, "Consistency")."""
    learn_rate_hz: PositiveFloat = 5.0
    """Rate at which samples feed the reference-field learning and the hard-iron calibration,
    Hz (their samples are averaged, not fused: their rate is not the heading update's)."""
    reference: Literal["wmm", "learned"] = "wmm"
    """Where the Earth field that heading is measured against comes from. ``wmm``: the World
    Magnetic Model (:mod:`physconst.geomag`) at the filter's position and ``decimal_year``
    (declination, inclination and strength), re-evaluated every 500 m travelled; usable from
    the first moment a position is known (static alignment, heading at hover). ``learned``:
    from the body field and the filter attitude once the yaw sigma is below
    ``learn_yaw_sigma_rad`` (no mag heading fusion before that), where the local field departs
    from the model (magnetic anomalies). ``reference_field_n_tesla`` overrides both."""
    decimal_year: float = Field(default=DEFAULT_DECIMAL_YEAR, ge=1900.0, le=2100.0)
    """Date of the data, e.g. 2026.5 (:func:`physconst.geomag.decimal_year`): the date the WMM
    field is evaluated at (secular variation: ~0.15 deg/yr of declination in Europe)."""
    reference_field_n_tesla: tuple[float, float, float] | None = None
    """A fixed Earth field in NED (T) that replaces ``reference`` (e.g. a local survey)."""
    learn_yaw_sigma_rad: PositiveFloat = math.radians(2.0)
    min_horizontal_field_tesla: PositiveFloat = 5e-6
    """Samples whose horizontal field (after tilt) is weaker than this are not used."""
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    hard_iron_calibration: bool = True
    """Estimate the body-fixed (hard-iron) field offset and the Earth field together in flight,
    from GNSS-aided attitudes spread over headings (``m_b = C_bn m_n + b``, least squares)."""
    uncalibrated_heading_noise_rad: PositiveFloat = math.radians(10.0)
    """Heading sigma used before the hard-iron calibration completes (a hard-iron residual of
    1 uT at 20 uT horizontal field is a heading error of +-3 deg that flips with heading: fused
    as white noise at the calibrated sigma it pulls yaw off), rad."""
    calibration_min_heading_span_rad: PositiveFloat = math.radians(150.0)
    """Headings covered (in 30-deg bins) before the calibration is trusted, rad."""
    calibration_hard_iron_sigma_tesla: PositiveFloat = 5e-6
    """Prior sigma of each hard-iron component (regularises the axis the attitudes do not
    excite, e.g. body z in level flight), T."""


class AirspeedTuning(_Frozen):
    """Air data (:mod:`fusion.aiding.airspeed`): true-airspeed fusion with two wind states
    and an airspeed scale state, synthetic sideslip for a fixed-wing aircraft, pitot fault
    detection and, without a usable pitot, synthetic airspeed from the last wind estimate.

    Needs a layout with the air-data block (``+air``, :attr:`FilterConfig.state_layout`);
    the commands' default has it. Defaults follow PX4 EKF2 where it has a parameter (named).
    """

    enabled: bool = True
    """Fuse air data when the stream carries it (``--airspeed off``: ``False``; the samples
    are then counted in ``Health.airspeed_ignored`` and nothing air-related is fused)."""
    fixed_wing: bool = True
    """The vehicle flies on a wing: its air-relative velocity lies along the body x axis
    (synthetic sideslip ``beta = 0``), and synthetic airspeed is meaningful."""
    fuse_rate_hz: PositiveFloat = 1.0
    """Airspeed samples are averaged over ``1 / fuse_rate_hz`` and fused as one (the sensor
    noise part of the variance divided by the count); sideslip at ``sideslip_rate_hz``.
    1 Hz, not EKF2's ~10 Hz: without gust states a gust (correlated over ~6 s, Dryden L/V)
    is white noise to the filter and faster updates count it many times (tuning flights,
    seeds 2-5 x manoeuvre, cruise: 5 Hz / 1 m/s left 2,200 m summed 300 s into the outage,
    1 Hz / 2 m/s 1,514 m, free inertial 4,192 m). With the gust states 1 Hz and 2 Hz are
    alike on the tuning flights (seeds 1-5: 1,366 and 1,404 m)."""
    sideslip_rate_hz: PositiveFloat = 5.0
    """Rate of the air-data epochs that fuse the synthetic sideslip (and start the wind states),
    Hz; the TAS is fused at the slower ``fuse_rate_hz``. Without a pitot the wind is learned
    from sideslip alone, and at 1 Hz it did not converge within minutes."""
    diff_pressure_noise_pa: PositiveFloat = 1.0
    """White noise of one differential-pressure reading, Pa (about the MS4525DO / SDP3x
    class); sets the sensor part of the TAS sigma, ``sigma_qc / (rho V)``, and what the
    stuck-sensor check expects to see."""
    tas_noise_floor_mps: PositiveFloat = 1.0
    """Floor of the TAS sigma of one fused batch, m/s: pitot position error, sensor lag and the
    sideslip the model neglects. Turbulence is not in it: the gust states carry it
    (``gust_sigma_mps``); without them the floor would have to cover the gusts (2 m/s). On
    the tuning flights (seeds 1-5 x manoeuvre, cruise) 1 and 2 m/s left the same summed
    error 300 s into the outage (1,366 and 1,379 m)."""
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    """Chi-square gate of the TAS update (0.999: 3.3 sigma; EKF2_TAS_GATE is 3 sigma)."""
    min_airspeed_mps: PositiveFloat = 8.0
    """Airspeed fusion (and sideslip) start above this measured airspeed (EKF2_ARSP_THR, a
    fixed-wing's 'airborne'); below it samples are counted in ``airspeed_low``, m/s."""
    negative_tolerance_pa: NonNegativeFloat = 5.0
    """A reading down to this far below zero is a live sensor's noise around zero (at rest, or
    a blocked line): taken as 0 Pa. Anything more negative is invalid (counted), Pa."""
    max_diff_pressure_pa: PositiveFloat = 20_000.0
    """Readings above this are absurd (Mach 0.5 at sea level is ~19 kPa), Pa."""
    timeout_s: PositiveFloat = 1.0
    """No fused airspeed for this long: air data reported inactive (mode, status), s."""
    wind_init_sigma_mps: PositiveFloat = 3.0
    """Wind sigma per axis when the wind states start from ``v - TAS * heading`` (added in
    quadrature to ``TAS * yaw sigma`` and the TAS sigma), m/s."""
    wind_start_max_heading_sigma_deg: PositiveFloat = 3.0
    """The wind states start from ``v - TAS * heading`` only once the heading's sigma is at
    most this, deg. The wind so computed carries the heading's error (``TAS * dpsi``: 2 m/s
    for 3 deg at 40 m/s) without its correlation: started earlier, while the heading is still
    aligning (no magnetometer, before the first turn), the sideslip and airspeed updates
    take the two as independent, give the heading information it does not have, and leave
    a wind wrong by many of its sigmas. The wait lasts at most ``wind_start_max_wait_s``."""
    wind_start_max_wait_s: PositiveFloat = 60.0
    """Longest wait for the heading (``wind_start_max_heading_sigma_deg``), s of airspeed
    readings: a heading that stays unknown (no magnetometer, or a weak one, and no turns)
    would otherwise leave the aircraft without air data for the whole flight. A wind
    started against a wrong heading still predicts the velocity while the course holds
    (``v = TAS (cos psi, sin psi) + w`` with the same heading error in both terms); a
    consumer MEMS IMU with the magnetometer fused at 0.1 Hz on a straight cruise (tuning
    flight ``cruise`` seed 2) never got its heading within 3 deg and, waiting, flew its
    outage free inertial."""
    wind_init_sigma_no_pitot_mps: PositiveFloat = 10.0
    """Wind sigma per axis when a fixed-wing without a pitot starts its wind states (at zero)
    to learn them from sideslip and GNSS for synthetic airspeed, m/s."""
    scale_sigma: PositiveFloat = 0.05
    """Prior sigma of the airspeed scale factor (pitot calibration ratio, position error)."""
    wind_noise_mps2_rthz: PositiveFloat = 0.05
    """Wind random walk, m/s^2/sqrt(Hz) (EKF2_WIND_NSD); in still air
    ``still_air_wind_noise_mps2_rthz``."""
    wind_climb_scaler_spm: NonNegativeFloat = 0.5
    """Wind noise times ``1 + scaler |climb rate|``, s/m (EKF2's ``wind_vel_nsd_scaler``)."""
    scale_noise_rthz: PositiveFloat = 1e-4
    """Airspeed scale random walk, 1/sqrt(s) (PX4 WEST_SC_P_NOISE)."""
    gust_sigma_mps: PositiveFloat = 1.5
    """Horizontal gust (turbulence) sigma per axis, m/s: the steady state of the gust states
    (:mod:`fusion.error_model`). MIL-F-8785C light turbulence at low altitude is about
    1 m/s (sigma_w = 0.1 W_20 with a 15 kt 20-ft wind, sigma_u = sigma_w / (0.177 +
    0.000823 h)^0.4 at h = 1000 ft), moderate about 2 m/s."""
    gust_length_m: PositiveFloat = 300.0
    """Gust correlation length, m: the correlation time is this over the airspeed (Dryden
    ``L_u = h / (0.177 + 0.000823 h)^1.2`` ft, 1000 ft at 1000 ft above ground; 1750 ft above
    2000 ft). Measured on JSBSim's MIL-F-8785C turbulence at 50 m/s: 5.5-6 s, 275-300 m."""
    sideslip_noise_rad: PositiveFloat = 0.3
    """Synthetic sideslip sigma, rad (EKF2_BETA_NOISE default 0.3)."""
    sideslip_gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    stuck_window_s: PositiveFloat = 4.0
    """Window of the stuck-sensor check, s."""
    stuck_ratio: float = Field(default=0.25, gt=0.0, lt=1.0)
    """Stuck when the readings' standard deviation over the window is below this fraction of
    what the sensor noise plus the predicted change of impact pressure would give."""
    stuck_min_change_mps: PositiveFloat = 2.0
    """... judged only over windows where the predicted airspeed changed by at least this
    much (a stuck reading in steady flight is undetectable, and still right), m/s."""
    zero_airspeed_mps: PositiveFloat = 3.0
    """A reading below this airspeed reads 'zero' (a blocked or disconnected line), m/s."""
    flying_speed_mps: PositiveFloat = 15.0
    """... a zero reading is a fault when the predicted airspeed (or, with the wind
    states dormant, the ground speed) is above this, m/s."""
    zero_time_s: PositiveFloat = 1.0
    """Zero while flying for this long: blocked, s."""
    reject_time_s: PositiveFloat = 5.0
    """Every fused batch rejected by the gate for this long: blocked, s."""
    recover_time_s: PositiveFloat = 10.0
    """A blocked pitot is fused again only after its batches passed the innovation test
    (against the current wind and velocity, not fused) and the stuck and zero checks for
    this long, s."""
    synthetic_when_blocked: bool = True
    """Fixed-wing only: when GNSS is lost and the pitot the stream carries is not usable
    (blocked, or nothing fused within ``timeout_s``), fuse a synthetic TAS: the airspeed
    estimate ``|v - w|`` averaged over the last ``synthetic_average_s`` of trusted aiding,
    as ArduPilot EKF3 does with its default airspeed (without it the INS leaves dead
    reckoning at once)."""
    synthetic_when_no_pitot: bool = False
    """Fixed-wing only, a stream without any airspeed sample: start the wind states once
    flying on GNSS, learn the wind from the synthetic sideslip and the GNSS velocity, and
    fuse the synthetic TAS when GNSS is lost (``--airspeed synthetic``). Off by default so
    that a stream without air data navigates exactly as without the air-data states (and a
    free-inertial baseline stays free-inertial); the ``synthetic`` baseline of the benches
    turns it on."""
    synthetic_average_s: PositiveFloat = 60.0
    """The synthetic TAS is the mean of ``|v_k - w|`` over the ground velocities of this span
    before trusted aiding stopped, against the wind estimate of that moment: the cruise
    airspeed, not the phase of a phugoid or of a throttle change when GNSS was lost, s."""
    synthetic_rate_hz: PositiveFloat = 1.0
    """Rate of the synthetic TAS updates, Hz: its error (the real airspeed's excursions from
    cruise) is correlated over tens of seconds, so fusing it at the batch rate would count
    one error many times (the reason the magnetometer is fused at 0.5 Hz)."""
    synthetic_noise_mps: PositiveFloat = 3.0
    """Sigma of the synthetic TAS (throttle and pitch changes move the real airspeed by a
    few m/s: the cruise-speed spread of a small fixed-wing), m/s."""
    learn_max_wind_sigma_mps: PositiveFloat = 2.0
    """A learned airspeed model (``--bridge gmdh-airspeed``) trains on ``|v - w|`` only while
    the wind is known to this 1-sigma per axis (m/s): before the wind has converged the target
    would move under the model."""
    adaptive_turbulence: bool = True
    """Estimate the turbulence intensity in flight (:mod:`fusion.aiding.turbulence`): while
    GNSS is good, the variance of the airspeed residual against the mean wind, less the
    pitot's own noise, sets the gust states' sigma (between ``gust_sigma_min_mps`` and
    ``gust_sigma_max_mps``; ``gust_sigma_mps`` until enough residuals have been seen); an
    outage keeps the last estimate. ``False``: ``gust_sigma_mps`` whatever the air. Above
    still air (``outage_hold_max_turbulence_mps``) the gust states keep ``gust_sigma_mps``
    unless ``gust_sigma_estimated_above_still_air``."""
    gust_sigma_estimated_above_still_air: bool = False
    """Let the turbulence estimate set the gust sigma in turbulence too (above
    ``outage_hold_max_turbulence_mps``), not only in still air. Off: on the tuning flights
    (seeds 1-3 of manoeuvre and cruise, turbulence 0.1-0.4, estimates 0.85-2.2 m/s) the
    estimate lost to the fixed 1.5 m/s on five of six flights (summed outage RMSE 179
    against 171 m industrial, 253 against 220 m consumer), both where it was below 1.5 and
    where it was above, while the fixed sigma stayed consistent there (outage
    rms(error/sigma) at most 0.77). The estimate's part is then to recognise still air,
    where it pays (gust sigma at the floor, the still-air walk and the outage hold), and a
    saturated scatter (the ceiling)."""
    gust_sigma_min_mps: PositiveFloat = 0.2
    """Floor of the estimated gust sigma, m/s: still air is never taken as perfectly still
    (the residual's own scatter at 1 Hz is of this order on calm tuning flights)."""
    gust_sigma_max_mps: PositiveFloat = 4.0
    """Ceiling of the estimated gust sigma, m/s (MIL-F-8785C severe turbulence at low altitude
    is about 3.5-4 m/s horizontally). A residual scatter above it is not air any more but a
    pitot or model fault: flagged ``turbulence_saturated`` and the ceiling is used."""
    turbulence_window_s: PositiveFloat = 120.0
    """Time constant of the exponential window of the turbulence estimate, s: some 20 gust
    correlation times, so one gust does not move it and a change of weather does within
    minutes."""
    turbulence_min_residuals: PositiveInt = 30
    """Residuals (1 Hz batches with GNSS and a converged wind) needed before the estimate
    replaces ``gust_sigma_mps``."""
    outage_hold: bool = True
    """Hold the mean wind and the airspeed scale through a GNSS outage: their level-flight
    random walk is multiplied by ``outage_noise_factor`` while GNSS is lost, the climb-driven
    part of the wind noise by ``outage_climb_noise_factor``. Without GNSS both are
    observable only through turns, and a random walk tuned for GNSS-aided flight lets them
    drift on noise. ``False``: the same noise with and without GNSS."""
    outage_noise_factor: NonNegativeFloat = 0.0
    """Level-flight wind and scale noise in an outage over their GNSS-aided values (see
    ``outage_hold``; 0 and 0.1 alike on the tuning flights, seeds 1-3 of manoeuvre and
    cruise)."""
    still_air_wind_noise_mps2_rthz: PositiveFloat = 0.01
    """Wind random walk in still air (the turbulence in use at most
    ``outage_hold_max_turbulence_mps``, on a measured airspeed), m/s^2/sqrt(Hz); the climb
    part scales with it. The mean wind's random walk sets its sigma when GNSS is lost (about
    ``(nsd^2 sigma_TAS^2 / f)^(1/4)`` against 1 Hz airspeed batches): a sigma kept above the
    wind's real error hands the first airspeed residuals of an outage, the INS's own drift,
    to the wind. 0.01 (0.6 m/s of wind change in an hour of level flight) against EKF2's
    0.05 (``wind_noise_mps2_rthz``, kept in turbulence) on the JSBSim tuning flights in
    steady wind (seeds 1-3 of manoeuvre and cruise): summed outage RMSE 47 against 62 m
    industrial, 27 against 51 m consumer; 0.02 gave 53 / 35 m, 0.005 44 / 25 m (5-9 %
    better, at half the rate a change of weather is followed). A slower walk is safe only on
    a wind that is not already wrong by many of its sigmas, which is why the wind waits
    for the heading (``wind_start_max_heading_sigma_deg``): started at once, on the
    synthetic flight of the filter's tests, the walk at 0.01 left one seed 256 m off at the
    end of the outage and the NEES at 16."""
    outage_climb_noise_factor: NonNegativeFloat = 0.0
    """Climb-driven wind noise (``wind_climb_scaler_spm``) in an outage hold over its
    GNSS-aided value. The climb part models flying through the wind's change with height;
    without GNSS only turns observe the wind, and a climb then lets the held wind wander on
    the airspeed residuals as the level part would (0 against 1 on the tuning flights in
    steady wind: summed outage RMSE 74 against 79 m industrial, 66 against 74 m consumer; 54
    against 54 and 34 against 34 m with the still-air noise)."""
    outage_hold_max_turbulence_mps: PositiveFloat = 0.5
    """Still air: the outage hold and ``still_air_wind_noise_mps2_rthz`` apply only while
    the turbulence in use is at most this, m/s: in
    turbulence the long-wavelength part of the gusts moves the mean wind over minutes, and
    holding it cost accuracy on the tuning flights (manoeuvre seed 3, turbulence 0.3: 99 m
    outage RMSE with the hold alone, 82 m with neither, 84 m with the turbulence estimate
    alone). Between the floor (still air) and the 0.7-2 m/s estimated in turbulence."""
    position_error_fit: bool = True
    """Fit the pitot-static position error against the angle of attack while GNSS is good
    and remove it from the measured airspeed (:mod:`fusion.aiding.position_error`)."""
    position_error_window_s: PositiveFloat = 600.0
    """Time constant of the fit's exponential window, s (the angle of attack varies with
    turns, climbs and speed changes: minutes of flight see enough of it)."""
    position_error_max_per_rad: PositiveFloat = 0.5
    """Bound on the fitted slope of ``TAS / |a|`` against the angle of attack, 1/rad (0.5 is
    about 5 % of the airspeed over a 6° change, beyond 14 CFR 23.1323(b)'s 3 % limit on the
    whole system error)."""
    max_wind_mps: PositiveFloat = 40.0
    """Plausible bound on the mean wind, m/s: a wind estimate above it (flagged
    ``wind_implausible``) restarts the air-data states from the next airspeed, and a pitot
    airspeed further than this from the ground speed (flagged ``pitot_implausible``) is not
    fused."""




def airspeed_tuning(mode: str, base: AirspeedTuning | None = None) -> AirspeedTuning:
    """``base`` (default :class:`AirspeedTuning`) set for the command-line choice ``mode``
    (:data:`AIRSPEED_MODES`; ValueError names the valid ones)."""
    if mode not in AIRSPEED_MODES:
        raise ValueError(
            f"unknown airspeed mode {mode!r}; valid choices: {', '.join(AIRSPEED_MODES)}"
        )
    base = base or AirspeedTuning()
    return base.model_copy(update={
        "enabled": mode != "off", "synthetic_when_no_pitot": mode == "synthetic",
    })  # fmt: skip


class ZeroMotionTuning(_Frozen):
    """Rest detection and zero-velocity updates (:mod:`fusion.aiding.zero_motion`).

    A block of ``window_s`` is still when every specific-force and angular-rate standard
    deviation is below ``max(floor, noise_factor * N * sqrt(f / 2))`` (``N`` the IMU tuning's
    noise density, ``f`` the IMU rate), the mean rate is below ``max_rate_rps`` and the INS
    speed below ``max_speed_mps``."""

    enabled: bool = True
    window_s: PositiveFloat = 1.0
    """Detection block, s (a verdict per block; the first update comes one block after rest
    begins)."""
    max_speed_mps: PositiveFloat = 2.0
    """INS speed above which nothing is accumulated: an IMU cannot tell rest from unaccelerated
    straight flight, the speed can (a walking pace; a taxiing aircraft is faster)."""
    max_rate_rps: PositiveFloat = 0.05
    """Mean angular rate bound, rad/s (3 deg/s: above the Earth rate and a consumer MEMS gyro's
    turn-on bias, below any manoeuvre)."""
    noise_factor: PositiveFloat = 3.0
    """Multiple of the per-sample white-noise sigma a standard deviation may reach."""
    accel_std_floor_mps2: PositiveFloat = 0.1
    """Lower bound of the specific-force bound, m/s^2 (quantisation and the micro-vibration of a
    vehicle on the ground; a running engine or spinning propellers are well above it)."""
    gyro_std_floor_rps: PositiveFloat = 0.01
    """Lower bound of the angular-rate bound, rad/s."""
    velocity_sigma_mps: PositiveFloat = 0.1
    """1-sigma per axis of the velocity of a vehicle at rest (sway in wind), m/s."""
    fuse_rate_hz: PositiveFloat = 5.0
    gate_probability: Probability = Field(default=0.999, gt=0.5, lt=1.0)
    zero_rate: bool = True
    """Also fuse zero angular rate (the Earth rate) at the end of every still block: the gyro
    bias calibration of the fine alignment at rest."""
    rate_sigma_floor_rps: PositiveFloat = 1e-6
    """Lower bound of the zero-rate sigma, rad/s (0.2 deg/h: g-sensitivity and scale factor
    times the Earth rate, below any MEMS bias instability)."""


class InitConfig(_Frozen):
    """Alignment and initial uncertainties."""

    mode: Literal["auto", "in_flight", "static"] = "auto"
    """``auto`` (the default, :class:`fusion.alignment.AutoAlignment`): static at rest, from
    the GNSS track when moving at ``min_speed_mps`` or more, heading from the magnetometer
    when moving slower (hover). ``in_flight``: only from two GNSS fixes (heading from the
    track, level from specific force minus GNSS acceleration). ``static``: only levelling plus
    magnetometer heading (gyrocompassing without a magnetometer), vehicle at rest."""
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
    """Yaw sigma of a magnetic heading at alignment (hard-iron residual, local anomaly); the
    moving magnetic alignment adds the tilt error carried by the vertical field."""
    baro_bias_sigma_m: PositiveFloat = 2.0
    """Added (in quadrature) to the height sigma when the baro bias is initialised, m."""




def init_for_align(mode: str, base: InitConfig | None = None) -> InitConfig:
    """``base`` (default :class:`InitConfig`) set for the command-line choice ``mode``
    (:data:`ALIGN_MODES`; ValueError names the valid ones)."""
    if mode not in ALIGN_MODES:
        raise ValueError(f"unknown alignment {mode!r}; valid choices: {', '.join(ALIGN_MODES)}")
    return (base or InitConfig()).model_copy(update={"mode": mode.replace("-", "_")})


class RatesConfig(_Frozen):
    """Covariance propagation and output rates."""

    covariance_rate_hz: PositiveFloat | None = 100.0
    """Covariance propagated at this rate, the transition accumulated in between; ``None``:
    every IMU sample."""
    output_rate_hz: PositiveFloat = 50.0
    """Rate of the estimates returned by ``NavFilter.step``, Hz."""


BRIDGE_FEATURES: tuple[str, ...] = (
    "t", "t2", "t3", "fn", "fe", "fd", "sinpsi", "cospsi", "sinpsi0", "cospsi0", "roll",
    "pitch", "vn", "ve", "vd", "wx", "wy", "wz", "dn", "de", "dvn", "dve", "bax", "bay", "baz",
    "bgx", "bgy", "bgz", "own", "own_rel", "own_rate",
)  # fmt: skip
"""Input features a bridging network may use (:mod:`fusion.bridging` documents each)."""


class BridgeConfig(_Frozen):
    """GNSS-outage bridging (:mod:`fusion.bridging`): consultation rate, what the networks
    learn from, their inputs, the training budget and the fallback rules.

    ``rate_hz`` is read by the filter; everything else by the learned strategies
    (:func:`fusion.bridging.registry.make_bridge`).
    """

    rate_hz: PositiveFloat = 5.0
    """The strategy is consulted this often during an outage, Hz."""
    training: Literal["virtual", "fix"] = "virtual"
    """``virtual``: learn the drift of INS copies re-seeded from the filter while GNSS
    is good (virtual outages, :class:`fusion.bridging.virtual_outages.VirtualOutageBank`).
    ``fix``: paper P0's pairs, the filter's INS-minus-GNSS error at each fix (closed loop:
    about zero)."""
    features: tuple[str, ...] | None = None
    """Network inputs (names in :data:`BRIDGE_FEATURES`); ``None``: the method's default."""
    virtual_outage_s: PositiveFloat = 90.0
    """Length of a virtual outage: each INS copy is re-seeded this often, s."""
    virtual_outage_count: PositiveInt = 3
    """Number of staggered INS copies (re-seeds every ``virtual_outage_s / count``)."""
    window_s: PositiveFloat = 300.0
    """Sliding training window (GNSS time), s."""
    refit_period_s: PositiveFloat = 10.0
    """Each component's network is refitted this often while GNSS is good; the six fits are
    spread over the period (one per ``refit_period_s / 6``), so no fix pays more than one."""
    max_samples: PositiveInt = 3000
    """Budget of one fit: the window is thinned evenly to at most this many pairs."""
    min_samples: PositiveInt = 150
    """Fewer training pairs: ``untrained`` (the strategy behaves as ``none``)."""
    min_horizon_s: NonNegativeFloat = 20.0
    """Virtual training: the pairs must reach this far into a virtual outage before the first
    fit (an outage right after start stays uncorrected), s."""
    warmup_s: NonNegativeFloat = 90.0
    """Virtual outages started within this time of the first fix are not learned from (the
    filter is still converging: their drift says nothing about later outages), s."""
    gate_horizon_s: PositiveFloat = 60.0
    """The fallback gate (:mod:`fusion.bridging.gate`): every virtual outage is
    replayed, once it is over, through the models that were in use when it *started* (so it
    is data they never saw), and scored over its first ``gate_horizon_s``: the mean squared
    error left after the correction against the mean squared error of no correction, s."""
    gate_outages: PositiveInt = 6
    """The gate judges each component on its last this-many scored outages (virtual ones,
    and the end of each real outage: the first fix after it measures what the correction
    did)."""
    gate_min_outages: PositiveInt = 3
    """Fewer scored outages: the component stays off (behaves as ``none``)."""
    gate_margin: float = Field(default=0.8, gt=0.0, le=1.0)
    """A component is on only while its RMS error with the correction is at most this times
    the RMS error without it over the judged outages, both summed and per outage (geometric
    mean of the ratios)..."""
    gate_min_wins: float = Field(default=0.75, gt=0.0, le=1.0)
    """... *and* the correction made the error smaller in at least this share of them,
    including the most recent one (it turns off as soon as it stops winning)."""
    stale_after_s: PositiveFloat = 120.0
    """No completed refit for this long: status ``stale`` (the models are still used), s."""
    pseudo_min_sigma_pos_m: PositiveFloat = 1.0
    """Floor of the pseudo-GNSS position sigma (``gmdh-pseudo``), m."""
    pseudo_min_sigma_vel_mps: PositiveFloat = 0.1
    """Floor of the pseudo-GNSS velocity sigma, m/s."""
    gmdh_max_layers: PositiveInt = 5
    gmdh_max_neurons: PositiveInt = 10
    gmdh_alpha: float = Field(default=0.6, ge=0.0, le=1.0)
    """P0's GMDH settings: 5 layers, 10 neurons per layer, selection pressure 0.6."""
    rbf_centers: PositiveInt = 15
    """P0's RBF comparator: 15 Gaussian neurons."""
    mlp_hidden: PositiveInt = 35
    """P1's NARX MLP: 35 hidden neurons."""
    mlp_max_nfev: PositiveInt = 3
    """Levenberg-Marquardt function evaluations per MLP refit (about one LM step; bounds the
    refit time). Each refit continues from the previous weights (warm start), so training
    proceeds across refits."""
    mlp_max_samples: PositiveInt = 200
    """The MLP's own sample budget (LM is O(samples x weights^2))."""
    bp_hidden: PositiveInt = 6
    """P2's small sigmoid networks: hidden neurons."""
    bp_epochs: PositiveInt = 100
    """Back-propagation epochs per refit; each refit continues from the previous weights
    (warm start)."""

    @field_validator("features")
    @classmethod
    def _known_features(cls, v: tuple[str, ...] | None) -> tuple[str, ...] | None:
        if v is None:
            return v
        if not v:
            raise ValueError("features must name at least one input (or be None)")
        bad = [f for f in v if f not in BRIDGE_FEATURES]
        if bad:
            raise ValueError(f"unknown features {bad}; valid: {', '.join(BRIDGE_FEATURES)}")
        return v



AltitudeMethodName = Literal["ekf", "loop", "loop-mpc", "loop-kf"]


class AltitudeConfig(_Frozen):
    """Where the output altitude and vertical velocity come from.

    ``ekf``: the error-state filter's own vertical channel (baro height fused as an EKF update
    with a Gauss-Markov bias state, :class:`BaroTuning`). ``loop`` / ``loop-mpc`` /
    ``loop-kf``: paper P4's barometric-inertial channel
    (:class:`fusion.altitude.channel.AltitudeChannel`) runs inside the filter on the INS
    vertical acceleration, the barometer (pressure and temperature, non-standard-atmosphere
    calibration from GNSS height) and GNSS height; the estimate's altitude and vertical velocity
    are the channel's. The EKF keeps fusing the baro
    samples the channel accepted, for its internal state only (see :mod:`fusion.filter`).
    """

    method: AltitudeMethodName = "ekf"
    preset: Literal["tuned", "p4"] = "tuned"
    """Where the channel's settings come from when ``channel`` is not given: ``tuned`` (the
    defaults of :class:`~fusion.altitude.channel.AltitudeChannelConfig`: loop with a triple
    pole at 3 s, baro-calibration random walk 0.005 m/√s, MPC pole 0.6, KF with a
    near-constant baro bias, all chosen on the tuning seeds of ``bench/altitude_jsbsim.py``) or
    ``p4`` (paper P4's channel, :meth:`~fusion.altitude.channel.AltitudeChannelConfig.p4`:
    gains K1 = 3.00, K2 = 0.6452, K3 = 0.8710, the untuned MPC, P4's KF with a 600 s
    Gauss–Markov bias, and P4's baro set-up: scale from the sensed temperature, bias not learned
    from GNSS). Giving both ``channel``
    and ``preset="p4"`` is an error."""
    channel: AltitudeChannelConfig = AltitudeChannelConfig()
    """The channel's settings for the loop methods. Its own ``method`` field is ignored
    (replaced by :attr:`method`); its ``monitor`` (range, freeze) also screens the baro samples
    of the ``ekf`` method. A QNH setting goes in ``channel.baro.qnh_pa`` (Pa): the calibration
    then starts from it instead of the standard atmosphere."""
    ekf_repeat_hold_s: PositiveFloat = 0.25
    """A baro reading identical to the previous ones for longer than this is not fused into the
    EKF (any method): it is a frozen sensor's signature, and the EKF cannot undo what it fused
    in the ``freeze_time_s`` the monitor needs to declare the sensor frozen. A live sensor whose
    noise exceeds its resolution (MS5611: 1.2 Pa noise, 1 Pa steps) never repeats that long;
    raise it for a coarse sensor in still air, s."""

    @model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("preset") == "p4":
            if data.get("channel") is not None:
                raise ValueError("preset: give either preset='p4' or channel, not both")
            method = data.get("method", "ekf")
            data = {
                **data,
                "channel": AltitudeChannelConfig.p4(
                    method if method in ("loop", "loop-mpc", "loop-kf") else "loop-mpc"
                ),
            }
        return data


class FilterConfig(_Frozen):
    """Everything :class:`fusion.filter.NavFilter` needs."""

    state_layout: LayoutName = "ins16"
    """The error-state layout, by name (:func:`fusion.state_layout.layout_for`): ``ins16``: pos,
    vel, att, accel bias, gyro bias, baro bias. ``ins22``: plus accelerometer and gyro scale
    factors. ``+gnss``: plus the receiver's time-correlated position error as three
    Gauss-Markov states (North, East, Down; sigmas and correlation times in
    :class:`GnssTuning`). Without them each fix is fused as white noise with sigma ``eph`` /
    ``epv``, which makes the filter overconfident when the receiver error is correlated over
    minutes (5 fixes/s of an error that changes over 120 s are taken as independent); with
    them a receiver whose error is really white at ``eph`` is fused with too small an ``R``
    and gated out. The split of ``eph`` into correlated and white parts is a property of the
    receiver: :func:`hil.tuning.gnss_state_layout` chooses the layout from a receiver
    description. ``+air`` (e.g. ``ins35+gnss+air``, the commands' default): plus the wind
    North / East and the airspeed scale factor, dormant until an airspeed sample (or, for a
    fixed-wing without a pitot, flight) starts them (:class:`AirspeedTuning`)."""
    imu: ImuTuning = ImuTuning()
    gnss: GnssTuning = GnssTuning()
    baro: BaroTuning = BaroTuning()
    mag: MagTuning = MagTuning()
    init: InitConfig = InitConfig()
    rates: RatesConfig = RatesConfig()
    bridge: BridgeConfig = BridgeConfig()
    altitude: AltitudeConfig = AltitudeConfig()
    airspeed: AirspeedTuning = AirspeedTuning()
    zero_motion: ZeroMotionTuning = ZeroMotionTuning()
    thermal: ThermalTuning = ThermalTuning()
    """The thermal strategy (``off`` by default; :mod:`fusion.thermal`)."""

    def process_noise(self) -> ProcessNoise:
        """The error model's process-noise parameters from the sensor tunings (SI units); a
        thermal strategy widens the bias random walk by its share of the thermal drift
        (:meth:`fusion.thermal.tuning.ThermalTuning.thermal_rate_density`)."""
        imu, baro, gnss, air = self.imu, self.baro, self.gnss, self.airspeed
        th = self.thermal
        gyro_sigma, accel_sigma = imu.gyro_bias_sigma_rps, imu.accel_bias_sigma_mps2
        kg = ka = 0.0
        share = th.residual_share()
        if share > 0.0:
            qg, qa = th.thermal_rate_density()
            gyro_sigma = widened_bias_sigma(gyro_sigma, imu.gyro_bias_tau_s, share * qg)
            accel_sigma = widened_bias_sigma(accel_sigma, imu.accel_bias_tau_s, share * qa)
        if th.mode == "states":
            kg, ka = th.tempco_walk_density()
        return ProcessNoise(
            gyro_noise=imu.gyro_noise_density_rps_rthz,
            accel_noise=imu.accel_noise_density_mps2_rthz,
            gyro_bias_sigma=gyro_sigma,
            gyro_bias_tau_s=imu.gyro_bias_tau_s,
            accel_bias_sigma=accel_sigma,
            accel_bias_tau_s=imu.accel_bias_tau_s,
            gyro_tempco_walk=kg,
            accel_tempco_walk=ka,
            baro_bias_sigma=baro.bias_sigma_m,
            baro_bias_tau_s=baro.bias_tau_s,
            gyro_scale_sigma=imu.gyro_scale_sigma,
            gyro_scale_tau_s=imu.gyro_scale_tau_s,
            accel_scale_sigma=imu.accel_scale_sigma,
            accel_scale_tau_s=imu.accel_scale_tau_s,
            gyro_misalignment_sigma=imu.gyro_misalignment_sigma_rad,
            accel_misalignment_sigma=imu.accel_misalignment_sigma_rad,
            baro_scale_sigma=baro.scale_sigma,
            baro_scale_tau_s=baro.scale_tau_s,
            gnss_bias_sigma_h_m=gnss.bias_sigma_h_m,
            gnss_bias_sigma_v_m=gnss.bias_sigma_v_m,
            gnss_bias_tau_h_s=gnss.bias_tau_h_s,
            gnss_bias_tau_v_s=gnss.bias_tau_v_s,
            wind_noise_mps2_rthz=air.wind_noise_mps2_rthz,
            wind_climb_scaler_spm=air.wind_climb_scaler_spm,
            airspeed_scale_noise_rthz=air.scale_noise_rthz,
            gust_sigma_mps=air.gust_sigma_mps,
            gust_length_m=air.gust_length_m,
        )
