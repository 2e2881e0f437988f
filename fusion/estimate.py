"""The navigation filter's outputs: the estimate, its mode, health counters, test ratios,
altitude status, and the record of each measurement update and aiding source."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields
from enum import StrEnum
from itertools import repeat
from operator import call, itemgetter
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.bridging.interface import BridgeStatus

FloatArray = NDArray[np.float64]


class Mode(StrEnum):
    """What the estimate rests on (a string enum: ``Mode.GNSS == "gnss"``,
    ``str(Mode.GNSS) == "gnss"``)."""

    INITIALIZING = "initializing"
    """Not aligned yet: no estimate."""
    GNSS = "gnss"
    """A fix was fused within ``GnssTuning.outage_timeout_s``."""
    FREE_INERTIAL = "free-inertial"
    """GNSS lost, the INS coasts on the remaining aiding."""
    BRIDGING = "bridging"
    """GNSS lost, the bridging strategy corrects the output or sends pseudo-fixes."""
    DEAD_RECKONING = "dead-reckoning"
    """GNSS lost, the INS is held by air data: true airspeed (measured, or synthetic from the
    last wind estimate) fused within ``AirspeedTuning.timeout_s``, against the wind states
    (a bridging strategy that is active takes precedence: ``bridging``)."""


class AidSource(StrEnum):
    """What a measurement update fused (:class:`Innovation`)."""

    GNSS_POS = "gnss_pos"
    GNSS_VEL = "gnss_vel"
    BARO_HGT = "baro_hgt"
    MAG_HDG = "mag_hdg"
    BRIDGE_POS = "bridge_pos"
    """A bridging strategy's pseudo-GNSS position."""
    BRIDGE_VEL = "bridge_vel"
    """A bridging strategy's pseudo-GNSS velocity."""
    AIRSPEED = "airspeed"
    """True airspeed, from the pitot or synthetic (:mod:`fusion.aiding.airspeed`)."""
    SIDESLIP = "sideslip"
    """Synthetic sideslip (zero) of a fixed-wing aircraft."""
    ZERO_VEL = "zero_vel"
    """Zero velocity while the vehicle is at rest (:mod:`fusion.aiding.zero_motion`)."""
    ZERO_RATE = "zero_rate"
    """Zero angular rate (the Earth rate) while at rest: the gyro bias (same module)."""


@dataclass(frozen=True, slots=True)
class Health:
    """Counters since construction (or :meth:`fusion.filter.NavFilter.reset`)."""

    imu_ok: int = 0
    """IMU samples integrated as received."""
    imu_nan: int = 0
    """IMU samples with NaN/Inf (or unreadable) fields: replaced by the last good sample."""
    imu_out_of_range: int = 0
    """IMU samples beyond the configured sensor range: replaced by the last good sample."""
    time_backwards: int = 0
    """Samples (any sensor) older than the previous one of the same sensor: dropped."""
    time_jump: int = 0
    """Confirmed IMU forward gaps above ``time_jump_s`` (up to ``max_coast_s``): coasted over,
    not integrated."""
    duplicates: int = 0
    """Samples (any sensor) with the same timestamp as the previous one: dropped."""
    gnss_fused: int = 0
    """Fixes whose position and velocity both passed the gate."""
    gnss_rejected: int = 0
    """Fixes with the position or the velocity rejected by the gate."""
    gnss_no_fix: int = 0
    """Fixes with ``fix_type < 3``."""
    gnss_invalid: int = 0
    """Fixes with non-finite or impossible fields."""
    gnss_inaccurate: int = 0
    """Fixes with ``eph_m`` above ``max_eph_m``."""
    gnss_too_old: int = 0
    """Fixes older than ``max_delay_s`` (or than the INS history) when due."""
    gnss_resets: int = 0
    """Position or velocity resets to GNSS (after an outage or a long rejection)."""
    gnss_resets_refused: int = 0
    """Resets the control asked for but the INS contradicted, without a run of consistent
    fixes to confirm them (``GnssTuning.reset_sigma``, ``reset_confirm_fixes``)."""
    gnss_outages: int = 0
    """Transitions from GNSS-aided to free-inertial / bridging."""
    baro_fused: int = 0
    baro_rejected: int = 0
    baro_invalid: int = 0
    """Baro samples whose pressure is not finite, <= 0 or outside the atmosphere model
    (-5 km .. 47 km pressure altitude): not used."""
    baro_resets: int = 0
    """Baro-bias re-initialisations after a long rejection."""
    mag_fused: int = 0
    mag_rejected: int = 0
    mag_invalid: int = 0
    """Magnetometer samples non-finite or with too weak a horizontal field."""
    bridge_updates: int = 0
    """Pseudo-GNSS updates fused or output corrections applied by the bridging strategy."""
    baro_frozen: int = 0
    """Baro samples rejected as coming from a frozen sensor (identical readings for
    ``AltitudeConfig.channel.monitor.freeze_time_s``); any altitude method."""
    baro_glitches: int = 0
    """Baro samples rejected by the altitude channel's gate (height more than ``gate_m`` from
    the loop's); loop methods only (``ekf``: its chi-square gate counts in ``baro_rejected``)."""
    baro_realignments: int = 0
    """Persistent baro steps taken as a new datum by the altitude channel (loop methods)."""
    altitude_calibration_updates: int = 0
    """GNSS heights that moved the baro calibration (P4's s, b); loop methods."""
    altitude_gnss_rejected: int = 0
    """GNSS heights rejected by the baro calibration's innovation gate; loop methods."""
    baro_repeats_held: int = 0
    """Baro samples held back from the EKF because the reading had not changed for more than
    ``AltitudeConfig.ekf_repeat_hold_s`` (before the sensor is declared frozen)."""
    time_quarantined: int = 0
    """IMU samples stamped more than ``time_jump_s`` ahead of the filter's clock (or beyond
    the timestamp range): dropped without moving the clock (backwards ones count in
    ``time_backwards``); a consistent run of them is a new time base."""
    time_rebases: int = 0
    """Confirmed new IMU time bases the INS could not coast into (a step back, as after a
    simulator restart, or a gap above ``max_coast_s``): the filter re-initialised (these
    counters survive it)."""
    airspeed_fused: int = 0
    """Averaged airspeed batches fused (measured TAS)."""
    airspeed_rejected: int = 0
    """Airspeed batches rejected by the gate."""
    airspeed_invalid: int = 0
    """Airspeed samples with a NaN, negative (below ``-negative_tolerance_pa``) or absurd
    (above ``max_diff_pressure_pa``) differential pressure: not used (a temperature outside
    150-350 K is replaced by the barometer's, not counted)."""
    airspeed_ignored: int = 0
    """Airspeed samples not used because air data is off (``--airspeed off``) or the layout
    has no air-data states."""
    airspeed_low: int = 0
    """Valid airspeed samples below ``min_airspeed_mps`` (on the ground): not fused."""
    airspeed_blockages: int = 0
    """Pitot faults detected (stuck, zero while flying, persistent gate rejections): the pitot
    is dropped until it passes its consistency check."""
    airspeed_blocked: int = 0
    """Airspeed samples dropped because the pitot is declared blocked."""
    airspeed_recoveries: int = 0
    """Blocked pitots trusted again after passing the consistency check."""
    sideslip_fused: int = 0
    sideslip_rejected: int = 0
    synthetic_airspeed_fused: int = 0
    """Synthetic TAS updates fused (no usable pitot, GNSS lost, fixed-wing)."""
    synthetic_airspeed_rejected: int = 0
    learned_airspeed_fused: int = 0
    """Learned-model TAS updates fused (``--bridge gmdh-airspeed``: no usable pitot, GNSS
    lost)."""
    learned_airspeed_rejected: int = 0
    learned_wind_updates: int = 0
    """Air-data epochs whose mean wind moved with the learned wind profile (``--bridge
    gmdh-wind``: GNSS lost, height changed within the profile)."""
    wind_implausible: int = 0
    """Air-data epochs whose mean wind was above ``AirspeedTuning.max_wind_mps``: the air-data
    states start again from the next airspeed."""
    airspeed_implausible: int = 0
    """Airspeed samples further from the ground speed than any plausible wind
    (``max_wind_mps``): not fused."""
    turbulence_saturated: int = 0
    """Times the turbulence estimate rose above ``gust_sigma_max_mps`` (the ceiling is then
    used, and the status flags it)."""
    wind_resets: int = 0
    """Starts of the wind states (from the first airspeed batch, or at zero for sideslip-only
    wind learning without a pitot)."""
    zupt_fused: int = 0
    """Zero-velocity updates fused (vehicle at rest, :mod:`fusion.aiding.zero_motion`)."""
    zupt_rejected: int = 0
    """Zero-velocity updates refused by the gate (the vehicle moved within a still block)."""
    zaru_fused: int = 0
    """Zero-angular-rate updates fused (one per still block of the rest detector)."""
    zaru_rejected: int = 0
    """Zero-angular-rate updates refused by the gate (a slow rotation, not rest)."""
    temperature_nan: int = 0
    """IMU temperature readings that were not finite (thermal strategies only,
    :mod:`fusion.thermal.screen`): the thermal corrections hold."""
    temperature_stuck: int = 0
    """IMU temperature streams found stuck (the same reading for longer than the sensor's
    update period allows)."""
    temperature_out_of_range: int = 0
    """IMU temperature readings outside the part's operating range."""
    temperature_jump: int = 0
    """IMU temperature readings further from the last good one than the die can move."""


HEALTH_FIELDS = tuple(f.name for f in fields(Health))
"""The counter names of :class:`Health`, in order."""
_HEALTH_SETTERS = tuple(getattr(Health, name).__set__ for name in HEALTH_FIELDS)
_HEALTH_VALUES = itemgetter(*HEALTH_FIELDS)
_N_HEALTH = len(HEALTH_FIELDS)
# runs an iterator to its end, keeping nothing
_consume: Callable[[Iterable[object]], None] = deque[object](maxlen=0).extend


class HealthCounters:
    """Mutable twin of :class:`Health` (plain attribute increments in the hot path)."""

    imu_ok: int
    imu_nan: int
    imu_out_of_range: int
    time_backwards: int
    time_jump: int
    duplicates: int
    gnss_fused: int
    gnss_rejected: int
    gnss_no_fix: int
    gnss_invalid: int
    gnss_inaccurate: int
    gnss_too_old: int
    gnss_resets: int
    gnss_resets_refused: int
    gnss_outages: int
    baro_fused: int
    baro_rejected: int
    baro_invalid: int
    baro_resets: int
    mag_fused: int
    mag_rejected: int
    mag_invalid: int
    bridge_updates: int
    baro_frozen: int
    baro_glitches: int
    baro_realignments: int
    altitude_calibration_updates: int
    altitude_gnss_rejected: int
    baro_repeats_held: int
    time_quarantined: int
    time_rebases: int
    airspeed_fused: int
    airspeed_rejected: int
    airspeed_invalid: int
    airspeed_ignored: int
    airspeed_low: int
    airspeed_blockages: int
    airspeed_blocked: int
    airspeed_recoveries: int
    sideslip_fused: int
    sideslip_rejected: int
    synthetic_airspeed_fused: int
    synthetic_airspeed_rejected: int
    learned_airspeed_fused: int
    learned_airspeed_rejected: int
    learned_wind_updates: int
    wind_implausible: int
    airspeed_implausible: int
    turbulence_saturated: int
    wind_resets: int
    zupt_fused: int
    zupt_rejected: int
    zaru_fused: int
    zaru_rejected: int
    temperature_nan: int
    temperature_stuck: int
    temperature_out_of_range: int
    temperature_jump: int

    def __init__(self) -> None:
        for name in HEALTH_FIELDS:
            setattr(self, name, 0)

    def snapshot(self) -> Health:
        """The counters as an immutable :class:`Health`."""
        # Health is frozen and slotted (a collected estimate holds one: ~300 bytes instead of
        # a 1.6 kB __dict__): fill its slots through their descriptors, no __init__ frame
        # (the slot setters called by map, not by a Python loop: ~half the instructions)
        health = object.__new__(Health)
        _consume(map(call, _HEALTH_SETTERS, repeat(health, _N_HEALTH),
                     _HEALTH_VALUES(self.__dict__)))
        return health


@dataclass(frozen=True, slots=True)
class AltitudeStatus:
    """State of the altitude method at one output epoch (:class:`fusion.config.AltitudeConfig`).

    The counters (invalid, frozen, glitch samples, calibration updates) are in :class:`Health`;
    this holds flags and the current calibration and compensator state. NaN / ``False`` where
    a field does not apply (``ekf``, or the channel before its first accepted baro sample).
    """

    method: str
    """``ekf``, ``loop``, ``loop-mpc`` or ``loop-kf``."""
    in_use: bool = False
    """The estimate's altitude is the channel's (loop methods, from the channel's first GNSS
    calibration and compensator reference on; before that the EKF's)."""
    initialised: bool = False
    """The channel is running (loop methods: first baro sample accepted after alignment)."""
    gnss_valid: bool = False
    """The channel had a GNSS height within ``gnss_timeout_s``: calibration learning and
    compensator tracking; ``False`` means the channel is holding through an outage."""
    calibration_frozen: bool = False
    """The baro calibration is frozen (GNSS outage)."""
    calibration_scale: float = math.nan
    """P4's non-standard-atmosphere scale ``s = dT/T0`` as estimated."""
    calibration_bias_m: float = math.nan
    """P4's bias ``b`` as estimated, m (geopotential)."""
    sea_level_dt_k: float = math.nan
    """Estimated sea-level temperature offset ``dT``, K."""
    sea_level_dp_pa: float = math.nan
    """Estimated sea-level pressure offset ``dP``, Pa."""
    loop_height_m: float = math.nan
    """The damping loop's own height (before the compensator's correction), m."""
    baro_height_m: float = math.nan
    """Last accepted calibrated baro height, m."""
    correction_m: float = math.nan
    """The compensator's ``dh`` (output height = loop height - dh; 0 for ``loop``), m."""
    compensator_steps: int = 0
    qp_active: int = 0
    """MPC steps where a move bound was active (bounded MPC only)."""
    undamped: bool = False
    """The loop ran without baro feedback at the last IMU epoch (no usable baro for longer
    than ``baro_hold_s``): free-inertial vertical."""
    baro_frozen: bool = False
    """The barometer currently reads as frozen."""
    baro_rejecting: bool = False
    """The channel's gate is currently rejecting the barometer."""


@dataclass(frozen=True, slots=True)
class TestRatios:
    """Last innovation test ratios (normalised innovation squared over the chi-square gate, as
    ESTIMATOR_STATUS reports them: > 1 means rejected). NaN before the first test."""

    __test__ = False  # not a pytest class

    gnss_pos: float = math.nan
    gnss_vel: float = math.nan
    baro_hgt: float = math.nan
    mag_hdg: float = math.nan
    airspeed: float = math.nan
    """True airspeed (ESTIMATOR_STATUS ``tas_ratio``)."""


@dataclass(frozen=True, slots=True)
class Innovation:
    """One gated measurement update (:attr:`fusion.filter.NavFilter.innovations`).

    Attributes
    ----------
    time_us : int
        Time of the sample whose processing made the update (a GNSS fix fused when the IMU
        caught up, or a bridging pseudo-fix, carries the IMU sample's time).
    source : AidSource
        What was fused.
    innovation : ndarray, shape (m,)
        INS-predicted minus measured, SI (m, m/s, rad).
    S : ndarray, shape (m, m)
        Innovation covariance ``H P H^T + R``.
    test_ratio : float
        Normalised innovation squared over the chi-square gate; > 1 means rejected.
    fused : bool
        The gate accepted it (``test_ratio <= 1``) and it was fed back.
    """

    time_us: int
    source: AidSource
    innovation: FloatArray
    S: FloatArray
    test_ratio: float
    fused: bool


_INNOVATION_SETTERS = tuple(getattr(Innovation, f.name).__set__ for f in fields(Innovation))


def new_innovation(
    time_us: int, source: AidSource, innovation: FloatArray, S: FloatArray, test_ratio: float,
    fused: bool,
) -> Innovation:  # fmt: skip
    """``Innovation(...)`` through the slot setters (one per update, see :func:`new_estimate`)."""
    inn = object.__new__(Innovation)
    s0, s1, s2, s3, s4, s5 = _INNOVATION_SETTERS
    s0(inn, time_us)
    s1(inn, source)
    s2(inn, innovation)
    s3(inn, S)
    s4(inn, test_ratio)
    s5(inn, fused)
    return inn


@dataclass(frozen=True, slots=True)
class AidSourceStatus:
    """State of one aiding source (as PX4's ``estimator_aid_source`` messages).

    Attributes
    ----------
    source : AidSource
    last : Innovation or None
        The source's last update (``None`` before the first).
    time_last_fused_us : int or None
        ``time_us`` of its last accepted update (``None`` before the first).
    """

    source: AidSource
    last: Innovation | None = None
    time_last_fused_us: int | None = None

    @property
    def test_ratio(self) -> float:
        """Last test ratio (NaN before the first update)."""
        return math.nan if self.last is None else self.last.test_ratio

    @property
    def fused(self) -> bool:
        """The last update was accepted."""
        return self.last is not None and self.last.fused

    @property
    def innovation(self) -> FloatArray | None:
        """Last innovation, SI (``None`` before the first update)."""
        return None if self.last is None else self.last.innovation

    def after(self, update: Innovation) -> AidSourceStatus:
        """The status once ``update`` (of this source) was made."""
        status = object.__new__(AidSourceStatus)  # the slot setters: one per update
        _set_source(status, self.source)
        _set_last(status, update)
        _set_fused_us(status, update.time_us if update.fused else self.time_last_fused_us)
        return status


_set_source, _set_last, _set_fused_us = (
    getattr(AidSourceStatus, f.name).__set__ for f in fields(AidSourceStatus)
)


@dataclass(frozen=True, slots=True)
class AidingStatus:
    """Every aiding source's :class:`AidSourceStatus` at one output epoch."""

    gnss_pos: AidSourceStatus = AidSourceStatus(AidSource.GNSS_POS)
    gnss_vel: AidSourceStatus = AidSourceStatus(AidSource.GNSS_VEL)
    baro_hgt: AidSourceStatus = AidSourceStatus(AidSource.BARO_HGT)
    mag_hdg: AidSourceStatus = AidSourceStatus(AidSource.MAG_HDG)
    bridge_pos: AidSourceStatus = AidSourceStatus(AidSource.BRIDGE_POS)
    bridge_vel: AidSourceStatus = AidSourceStatus(AidSource.BRIDGE_VEL)
    airspeed: AidSourceStatus = AidSourceStatus(AidSource.AIRSPEED)
    sideslip: AidSourceStatus = AidSourceStatus(AidSource.SIDESLIP)
    zero_vel: AidSourceStatus = AidSourceStatus(AidSource.ZERO_VEL)
    zero_rate: AidSourceStatus = AidSourceStatus(AidSource.ZERO_RATE)

    def __getitem__(self, source: AidSource) -> AidSourceStatus:
        status: AidSourceStatus = getattr(self, source.value)
        return status


@dataclass(frozen=True, slots=True)
class AlignmentStatus:
    """How the filter was aligned (:mod:`fusion.alignment`).

    Attributes
    ----------
    method : str
        ``in_flight`` (heading from the GNSS track), ``in_flight_mag`` (moving slowly: heading
        from the magnetometer), ``static_mag``, ``static_gyrocompass`` or ``given``
        (:meth:`fusion.filter.NavFilter.initialize`).
    at_rest : bool
        The rest detector's last block was still: zero-velocity and zero-angular-rate updates
        are being fused (the fine alignment of a vehicle at rest).
    """

    method: str
    at_rest: bool


@dataclass(frozen=True, slots=True)
class AirDataStatus:
    """State of the air data at one output epoch (:mod:`fusion.aiding.airspeed`).

    Attributes
    ----------
    state : str
        ``off`` (disabled or no air-data states), ``waiting`` (no airspeed fused yet),
        ``fusing`` (measured TAS fused within the timeout), ``blocked`` (pitot fault: dropped
        until it passes its consistency check), ``synthetic`` (synthetic TAS from the last
        wind estimate), ``stale`` (nothing fused within the timeout).
    wind_active : bool
        The wind states are running.
    wind_ne_mps : (float, float)
        Mean-wind estimate North, East (NaN while dormant), m/s.
    airspeed_scale : float
        Airspeed scale-factor estimate (``TAS_measured = (1 + k) |v - w|``).
    tas_mps : float
        Last valid measured TAS batch (NaN before the first), m/s.
    fault : str
        Why the pitot is blocked: ``stuck``, ``zero``, ``rejected`` (``""`` when not).
    gust_ne_mps : (float, float)
        Gust (turbulence) estimate North, East, on top of the mean wind (NaN while dormant),
        m/s.
    turbulence_mps : float
        Gust sigma per axis the filter uses, m/s.
    turbulence_source : str
        ``default`` (``AirspeedTuning.gust_sigma_mps``: not estimated, or too few residuals
        yet), ``estimated`` (the estimate: still air), ``turbulent`` (the estimate is above
        still air: ``gust_sigma_mps`` is used) or ``saturated`` (the estimate hit its
        ceiling: the ceiling is used).
    flags : str
        Comma-separated bad-input flags of the last 10 s: ``pitot_implausible`` (an airspeed
        further from the ground speed than any plausible wind: not fused),
        ``wind_implausible`` (a mean wind above the plausible bound: the air-data states
        restarted), ``turbulence_saturated``; ``""`` when none.
    position_error_per_rad : float
        Fitted slope of the pitot-static position error against the angle of attack
        (``TAS_measured / |a| - 1`` per rad; 0 until fitted), 1/rad.
    turbulence_estimate_mps : float
        The turbulence intensity estimated from the air-data residuals while GNSS was good
        (held in an outage), within its floor and ceiling, m/s; NaN until estimated.
    """

    state: str = "off"
    wind_active: bool = False
    wind_ne_mps: tuple[float, float] = (math.nan, math.nan)
    airspeed_scale: float = 0.0
    tas_mps: float = math.nan
    fault: str = ""
    gust_ne_mps: tuple[float, float] = (math.nan, math.nan)
    turbulence_mps: float = math.nan
    turbulence_source: str = ""
    flags: str = ""
    position_error_per_rad: float = 0.0
    turbulence_estimate_mps: float = math.nan


@dataclass(frozen=True, slots=True)
class NavEstimate:
    """Filter output at one IMU epoch (SI, NED; position errors in metres N/E/D).

    Attributes
    ----------
    time_us : int
        INS time (the IMU sample's time).
    lat_rad, lon_rad, alt_msl_m : float
        Position of the IMU.
    v_ned_mps : ndarray, shape (3,)
    q_nb : ndarray, shape (4,)
        Attitude body -> NED, scalar first.
    euler_rad : ndarray, shape (3,)
        Roll, pitch, yaw.
    P_diag : ndarray, shape (n,)
        Error-state variances in the layout ``state_layout`` (``fusion.error_model``): position
        m^2 (N, E, D), velocity (m/s)^2, attitude rad^2, biases SI^2, baro bias m^2; as of the
        last covariance propagation (at most ``1 / covariance_rate_hz`` old).
    mode : Mode
        ``initializing``, ``gnss``, ``free-inertial``, ``dead-reckoning`` or ``bridging`` (a
        string enum: it compares and prints as its value).
    accel_bias_b_mps2, gyro_bias_b_rps : ndarray, shape (3,)
        Estimated sensor biases, m/s^2 and rad/s.
    baro_bias_m : float
        Estimated baro height bias (ISA pressure height minus navigation height), m.
    health : Health
    test_ratios : TestRatios
    time_since_gnss_s : float
        Seconds since the last fused fix (``inf`` if none yet).
    state_layout : str
        The error-state layout's name (``"ins16"``, ``"ins16+gnss"``, ``"ins22"``,
        ``"ins22+gnss"``).
    altitude : AltitudeStatus or None
        The altitude method's state. With a loop method, ``alt_msl_m`` and ``v_ned_mps[2]`` are
        the altitude channel's (``P_diag`` and ``baro_bias_m`` stay the EKF's).
    bridge : BridgeStatus or None
        The bridging strategy's state (:class:`fusion.bridging.interface.BridgeStatus`:
        untrained / training / trained / stale, validation errors, per-component fallback).
    aiding : AidingStatus or None
        Per aiding source, the last update and when it last fused.
    P_nav : ndarray, shape (9, 9), or None
        Covariance of the position, velocity and attitude errors (the first nine states of
        every layout, same units and time as ``P_diag``), correlations included: what a
        consistency check (NEES) needs.
    air_data : AirDataStatus or None
        Air data: wind, airspeed scale, pitot state.
    omega_b_rps : ndarray, shape (3,), or None
        Body angular rate of the last IMU step (gyro increment minus the estimated bias, over
        the step; inertial rate, Earth rate included), rad/s: what ground stations show as
        roll / pitch / yaw rates. None from producers that do not know it.
    alignment : AlignmentStatus or None
        How the filter was aligned and whether the rest updates (fine alignment) run now.
    """

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: FloatArray
    q_nb: FloatArray
    euler_rad: FloatArray
    P_diag: FloatArray
    mode: Mode
    accel_bias_b_mps2: FloatArray
    gyro_bias_b_rps: FloatArray
    baro_bias_m: float
    health: Health
    test_ratios: TestRatios
    time_since_gnss_s: float
    state_layout: str
    altitude: AltitudeStatus | None = None
    bridge: BridgeStatus | None = None
    aiding: AidingStatus | None = None
    P_nav: FloatArray | None = None
    air_data: AirDataStatus | None = None
    omega_b_rps: FloatArray | None = None
    alignment: AlignmentStatus | None = None


_ESTIMATE_SETTERS = tuple(getattr(NavEstimate, f.name).__set__ for f in fields(NavEstimate))
_N_ESTIMATE = len(_ESTIMATE_SETTERS)


def new_estimate(*values: Any) -> NavEstimate:
    """``NavEstimate(*values)`` (every field, positionally) through the slot setters: the
    generated frozen ``__init__`` goes through ``object.__setattr__`` per field and costs about
    twice as much at the output rate. No validation, as with ``__init__``."""
    est = object.__new__(NavEstimate)
    # (the setters called by map, not by a Python loop; map stops at the shorter, as zip did)
    _consume(map(call, _ESTIMATE_SETTERS, repeat(est, _N_ESTIMATE), values))
    return est
