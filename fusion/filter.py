"""NavFilter: the loosely coupled INS/GNSS error-state EKF, sequencing the pure pieces.

Per IMU sample: validate, integrate the strapdown INS (:mod:`fusion.strapdown`), accumulate time
for the covariance propagation (:mod:`fusion.error_model`, at ``covariance_rate_hz``), store the
INS state for delayed measurements (:mod:`fusion.history`), fuse the GNSS fixes that became due,
watch for GNSS outages, consult the bridging strategy during one, and emit an estimate at
``output_rate_hz``. GNSS / baro / magnetometer samples go through their control (*when*) and
model (*how*) in :mod:`fusion.aiding`; each accepted update (Joseph form, chi-square gated,
:mod:`fusion.kalman`) is fed back into the INS at once and the error state reset to zero.

Bad input never raises and is never integrated: non-finite or out-of-range IMU samples are
replaced by the last good one (zero-order hold over their interval); duplicated or backwards
timestamps are dropped; a forward IMU time jump larger than ``ImuTuning.time_jump_s`` is not
integrated (the INS coasts at constant velocity over the gap and the covariance grows by the
process noise); GNSS fixes without a 3-D fix, with non-finite fields or a poor accuracy are
not fused. Everything is counted in :class:`Health`.

Altitude (``FilterConfig.altitude.method``): ``ekf`` outputs the EKF's own vertical (baro fused
as an EKF update); ``loop`` / ``loop-mpc`` / ``loop-kf`` run paper P4's baro-inertial channel
(:class:`fusion.altitude.channel.AltitudeChannel`) beside the EKF and output its altitude and
vertical velocity, while the EKF keeps fusing the baro samples the channel accepted (why: see
the "altitude channel" section of :class:`NavFilter`). Every method screens the barometer
(pressure out of the atmosphere model, frozen sensor; loop methods also a gate on jumps) and
counts what it rejects in :class:`Health`; :class:`AltitudeStatus` reports the calibration and
compensator state.

The pieces are small on purpose: this module only sequences calls and keeps counters.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion import earth, kalman, strapdown
from fusion.aiding import Observation
from fusion.aiding import baro as baro_aid
from fusion.aiding import gnss as gnss_aid
from fusion.aiding import mag as mag_aid
from fusion.alignment import AlignmentResult, InFlightAlignment, StaticAlignment
from fusion.altitude.atmosphere import P_MAX_PA, P_MIN_PA
from fusion.altitude.baro_monitor import BaroMonitor
from fusion.altitude.channel import AltitudeChannel, AltitudeChannelConfig
from fusion.bridging.interface import (
    Bridge,
    BridgeEpoch,
    BridgeStatus,
    InsError,
    NoBridge,
    OutputCorrection,
    PseudoGnss,
)
from fusion.bridging.shadows import ShadowBank
from fusion.config import ALTITUDE_METHODS, FilterConfig
from fusion.error_model import ErrorModel, ProcessNoise, StateLayout, layout_for
from fusion.history import InsHistory, span_capacity
from fusion.rotations import dcm_from_quat, euler_from_quat, quat_product, quat_to_dcm, rotvec_quat
from fusion.samples import BaroSample, GnssFix, ImuSample, MagSample
from fusion.strapdown import InsState

FloatArray = NDArray[np.float64]
_ZERO3 = (0.0, 0.0, 0.0)
_TWO_RATE = 2.0 * earth.RATE
_dot = np.dot
_isfinite = math.isfinite
_ins_update = strapdown.update

MODE_INITIALIZING = "initializing"
MODE_GNSS = "gnss"
MODE_FREE_INERTIAL = "free-inertial"
MODE_BRIDGING = "bridging"


@dataclass(frozen=True)
class Health:
    """Counters since construction (or :meth:`NavFilter.reset`)."""

    imu_ok: int = 0
    """IMU samples integrated as received."""
    imu_nan: int = 0
    """IMU samples with NaN/Inf (or unreadable) fields: replaced by the last good sample."""
    imu_out_of_range: int = 0
    """IMU samples beyond the configured sensor range: replaced by the last good sample."""
    time_backwards: int = 0
    """Samples (any sensor) older than the previous one of the same sensor: dropped."""
    time_jump: int = 0
    """IMU forward time steps above ``time_jump_s``: the gap was not integrated."""
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


_HEALTH_FIELDS = tuple(f.name for f in fields(Health))


class _Counters:
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

    def __init__(self) -> None:
        for name in _HEALTH_FIELDS:
            setattr(self, name, 0)

    def snapshot(self) -> Health:
        # Health is frozen: fill its __dict__ directly (4x faster than __init__ with 22
        # arguments; this runs at the output rate)
        health = object.__new__(Health)
        health.__dict__.update(self.__dict__)
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
    mode : str
        ``"initializing"``, ``"gnss"``, ``"free-inertial"`` or ``"bridging"``.
    accel_bias_b, gyro_bias_b : ndarray, shape (3,)
        Estimated sensor biases, m/s^2 and rad/s.
    baro_bias_m : float
        Estimated baro height bias (ISA pressure height minus navigation height), m.
    health : Health
    test_ratios : TestRatios
    time_since_gnss_s : float
        Seconds since the last fused fix (``inf`` if none yet).
    state_layout : str
        ``"ins16"`` or ``"ins22"``, with ``"+gnss"`` when the GNSS bias states are on.
    altitude : AltitudeStatus or None
        The altitude method's state. With a loop method, ``alt_msl_m`` and ``v_ned_mps[2]`` are
        the altitude channel's (``P_diag`` and ``baro_bias_m`` stay the EKF's).
    bridge : BridgeStatus or None
        The bridging strategy's state (:class:`fusion.bridging.interface.BridgeStatus`: untrained /
        training / trained / stale, validation errors, per-component fallback); ``None`` for a
        strategy without a ``status``.
    """

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: FloatArray
    q_nb: FloatArray
    euler_rad: FloatArray
    P_diag: FloatArray
    mode: str
    accel_bias_b: FloatArray
    gyro_bias_b: FloatArray
    baro_bias_m: float
    health: Health
    test_ratios: TestRatios
    time_since_gnss_s: float
    state_layout: str
    altitude: AltitudeStatus | None = None
    bridge: BridgeStatus | None = None


_ESTIMATE_SETTERS = tuple(getattr(NavEstimate, f.name).__set__ for f in fields(NavEstimate))


def _new_estimate(*values: Any) -> NavEstimate:
    """``NavEstimate(*values)`` (every field, positionally) through the slot setters: the
    generated frozen ``__init__`` goes through ``object.__setattr__`` per field and costs about
    twice as much at the output rate. No validation, as with ``__init__``."""
    est = object.__new__(NavEstimate)
    for setter, value in zip(_ESTIMATE_SETTERS, values):  # noqa: B905  # 18 values, one caller
        setter(est, value)
    return est


def _vec3(a: Any) -> tuple[float, float, float]:
    """Three floats from an array or sequence (``ValueError``/``TypeError`` if it is not 3)."""
    try:
        x, y, z = a.tolist()
    except AttributeError:
        x, y, z = a
    return float(x), float(y), float(z)


class NavFilter:
    """Loosely coupled INS/GNSS/baro/mag error-state EKF (see module docstring).

    Parameters
    ----------
    config : FilterConfig, optional
        Defaults to ``FilterConfig()``.
    bridge : Bridge, optional
        GNSS-outage bridging strategy; defaults to :class:`fusion.bridging.interface.NoBridge`.

    Examples
    --------
    >>> nav = NavFilter()
    >>> for sample in samples:                # IMU, GNSS, baro, mag, in time order
    ...     for est in nav.step(sample):      # at the configured output rate
    ...         publish(est)
    """

    def __init__(self, config: FilterConfig | None = None, *, bridge: Bridge | None = None) -> None:
        self.config = config if config is not None else FilterConfig()
        self.bridge: Bridge = bridge if bridge is not None else NoBridge()
        cfg = self.config
        method = cfg.altitude.method
        if method not in ALTITUDE_METHODS:  # model_copy(update=...) skips pydantic's check
            raise ValueError(
                f"unknown altitude method {method!r}; valid methods: {', '.join(ALTITUDE_METHODS)}"
            )
        self._alt_cfg: AltitudeChannelConfig | None = (
            None if method == "ekf" else cfg.altitude.channel.model_copy(update={"method": method})
        )
        self._omega_s2 = cfg.altitude.channel.omega_s2
        self.layout: StateLayout = layout_for(cfg.state_layout)
        imu = cfg.imu
        self._noise = ProcessNoise(
            gyro_noise=imu.gyro_noise_density_rps_rthz,
            accel_noise=imu.accel_noise_density_mps2_rthz,
            gyro_bias_sigma=imu.gyro_bias_sigma_rps,
            gyro_bias_tau_s=imu.gyro_bias_tau_s,
            accel_bias_sigma=imu.accel_bias_sigma_mps2,
            accel_bias_tau_s=imu.accel_bias_tau_s,
            baro_bias_sigma=cfg.baro.bias_sigma_m,
            baro_bias_tau_s=cfg.baro.bias_tau_s,
            gyro_scale_sigma=imu.gyro_scale_sigma,
            gyro_scale_tau_s=imu.gyro_scale_tau_s,
            accel_scale_sigma=imu.accel_scale_sigma,
            accel_scale_tau_s=imu.accel_scale_tau_s,
            gnss_bias_sigma_h_m=cfg.gnss.bias_sigma_h_m,
            gnss_bias_sigma_v_m=cfg.gnss.bias_sigma_v_m,
            gnss_bias_tau_h_s=cfg.gnss.bias_tau_h_s,
            gnss_bias_tau_v_s=cfg.gnss.bias_tau_v_s,
        )
        self._model = ErrorModel(self.layout, self._noise)
        self._scale = self.layout.sa is not None
        n = self.layout.n
        self._x0 = np.zeros(n)
        rc = cfg.rates
        self._cov_period_s = 0.0 if rc.covariance_rate_hz is None else 1.0 / rc.covariance_rate_hz
        self._out_period_us = round(1e6 / rc.output_rate_hz)
        self._bridge_period_us = round(1e6 / cfg.bridge.rate_hz)
        self._gate3 = kalman.chi2_gate(3, cfg.gnss.gate_probability)
        self._gate_baro = kalman.chi2_gate(1, cfg.baro.gate_probability)
        self._gate_mag = kalman.chi2_gate(1, cfg.mag.gate_probability)
        self._accel_range = imu.accel_range_mps2
        self._gyro_range = imu.gyro_range_rps
        self._max_dt = imu.max_dt_s
        self._time_jump_s = imu.time_jump_s
        self._max_lead_us = round(imu.max_sensor_lead_s * 1e6)
        self._tau_a, self._tau_g = imu.accel_bias_tau_s, imu.gyro_bias_tau_s
        self._tau_b = cfg.baro.bias_tau_s
        self._tau_sa, self._tau_sg = imu.accel_scale_tau_s, imu.gyro_scale_tau_s
        self._handlers: dict[type, Callable[[Any], list[NavEstimate]]] = {}
        # output-rate caches of immutable estimate parts, keyed by their content (so valid
        # across reset()): _make_estimate, _altitude_status
        self._est_ratios_key: list[float] = []
        self._est_ratios = TestRatios()
        self._alt_status_idle: dict[bool, AltitudeStatus] = {}
        self.reset()

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Forget everything learned: back to ``initializing`` (configuration kept)."""
        cfg = self.config
        n = self.layout.n
        self._ins: InsState | None = None
        self._t_us = 0
        self._last_imu_us: int | None = None
        self._last_us: dict[str, int] = {}
        self._prev_dth: tuple[float, float, float] = _ZERO3
        self._prev_dv: tuple[float, float, float] = _ZERO3
        self._last_dt = 0.0
        self._good_fw: tuple[float, float, float, float, float, float] | None = None
        self._ba = [0.0, 0.0, 0.0]
        self._bg = [0.0, 0.0, 0.0]
        self._sa = [0.0, 0.0, 0.0]
        self._sg = [0.0, 0.0, 0.0]
        self._bb = 0.0
        # GNSS position-bias estimate (NED, m) and the time it refers to: it is decayed with
        # its Gauss-Markov time constant only when used (_gnss_bias), not on the IMU path
        self._gb = [0.0, 0.0, 0.0]
        self._gb_us = 0
        self._P = np.zeros((n, n))
        self._acc_dt = 0.0
        self._acc_v0: tuple[float, float, float] = _ZERO3
        self._acc_f = [0.0, 0.0, 0.0]
        self._acc_w = [0.0, 0.0, 0.0]
        self._f_n: tuple[float, float, float] = (0.0, 0.0, -earth.GE)
        self._decay_cache: dict[float, tuple[float, ...]] = {}
        self._history = InsHistory(span_capacity(cfg.gnss.max_delay_s))
        self._pending: deque[GnssFix] = deque()
        self._gnss_ctl = gnss_aid.GnssControl(cfg.gnss)
        self._baro_ctl = baro_aid.BaroControl(cfg.baro)
        # Altitude: the loop methods' channel is created at the first IMU or baro epoch after
        # alignment (_new_altitude_channel); the ekf method screens its baro with a monitor.
        self._alt: AltitudeChannel | None = None
        self._alt_ready = False
        self._baro_mon = BaroMonitor(cfg.altitude.channel.monitor)
        self._baro_run: tuple[float, int] | None = None  # (pressure, since time_us) of a repeat run
        self._mag_ctl = mag_aid.MagControl(cfg.mag)
        self._aligner: InFlightAlignment | StaticAlignment = (
            InFlightAlignment(cfg.init, cfg.gnss)
            if cfg.init.mode == "in_flight"
            else StaticAlignment(cfg.init, cfg.gnss, cfg.mag, cfg.imu)
        )
        self.alignment_method: str | None = None
        self._c = _Counters()
        self._ratios = [math.nan] * 4
        self._next_out_us = 0
        self._timeout_us = round(cfg.gnss.outage_timeout_s * 1e6)
        self._in_outage = False
        self._bridge_active = False
        self._next_bridge_us = 0
        self._out_corr: OutputCorrection | None = None
        # Virtual outages (fusion.bridging.shadows.ShadowBank) only when the strategy asks for them:
        # otherwise None, and the IMU loop pays one attribute test.
        v_s = self.bridge.virtual_outage_s
        self._shadows: ShadowBank | None = (
            ShadowBank(v_s, self.bridge.virtual_outage_count, self._epoch) if v_s > 0.0 else None
        )

    def step(self, sample: ImuSample | GnssFix | BaroSample | MagSample) -> list[NavEstimate]:
        """Process one sample of any kind (in time order per sensor).

        Parameters
        ----------
        sample : ImuSample | GnssFix | BaroSample | MagSample
            Anything with the attributes of one of the :mod:`fusion.samples` protocols.

        Returns
        -------
        list of NavEstimate
            Estimates due at the output rate (empty for most samples and before alignment).

        Raises
        ------
        TypeError
            If ``sample`` matches none of the four sample kinds.
        """
        handler = self._handlers.get(type(sample))
        if handler is None:
            handler = self._classify(sample)
        return handler(sample)

    def estimate(self) -> NavEstimate | None:
        """The current estimate (``None`` before alignment)."""
        if self._ins is None:
            return None
        return self._make_estimate()

    @property
    def health(self) -> Health:
        """Counters snapshot."""
        return self._c.snapshot()

    @property
    def mode(self) -> str:
        """``initializing`` | ``gnss`` | ``free-inertial`` | ``bridging``."""
        if self._ins is None:
            return MODE_INITIALIZING
        if self._gnss_ctl.is_active(self._t_us):
            return MODE_GNSS
        return MODE_BRIDGING if self._bridge_active else MODE_FREE_INERTIAL

    @property
    def bridge_status(self) -> BridgeStatus:
        """The bridging strategy's status."""
        return self.bridge.status

    @property
    def shadow_states(self) -> list[InsState | None]:
        """The virtual-outage shadow INS states (empty when the strategy asks for none)."""
        return [] if self._shadows is None else self._shadows.shadows

    @property
    def ins_state(self) -> InsState | None:
        """The INS state (IMU position, velocity, attitude) at the current time."""
        return self._ins

    @property
    def gnss_bias_ned_m(self) -> tuple[float, float, float] | None:
        """Estimated time-correlated GNSS position error (NED, m) at the current time;
        ``None`` without the GNSS bias states (a layout without ``+gnss``)."""
        if self.layout.gnss is None:
            return None
        b = self._gnss_bias()
        return (b[0], b[1], b[2])

    @property
    def altitude_channel(self) -> AltitudeChannel | None:
        """The altitude channel of a loop method (``None`` for ``ekf`` or before it started)."""
        return self._alt

    @property
    def covariance(self) -> FloatArray:
        """Copy of the error-state covariance (propagated to the current time)."""
        self._flush()
        return self._P.copy()

    @property
    def time_us(self) -> int:
        """INS time (0 before alignment)."""
        return self._t_us

    def initialize(
        self,
        time_us: int,
        lat_rad: float,
        lon_rad: float,
        alt_msl_m: float,
        v_ned_mps: ArrayLike,
        q_nb: ArrayLike,
        *,
        covariance: ArrayLike | None = None,
        accel_bias_b: ArrayLike | None = None,
        gyro_bias_b: ArrayLike | None = None,
        baro_bias_m: float | None = None,
    ) -> None:
        """Start the filter from a known state (instead of the automatic alignment).

        Parameters
        ----------
        time_us : int
            Time of the state; the next IMU sample must be later.
        lat_rad, lon_rad, alt_msl_m : float
        v_ned_mps : array_like, shape (3,)
        q_nb : array_like, shape (4,)
        covariance : array_like, shape (n,) or (n, n), optional
            Initial error covariance (diagonal or full) in the layout; default from
            ``InitConfig`` and the IMU bias sigmas.
        accel_bias_b, gyro_bias_b : array_like, shape (3,), optional
            Initial bias estimates (default zero).
        baro_bias_m : float, optional
            Initial baro bias; default: set from the first baro sample.
        """
        n = self.layout.n
        state = InsState.from_arrays(lat_rad, lon_rad, alt_msl_m, v_ned_mps, q_nb)
        if covariance is None:
            cov = np.diag(self._default_p0_diag())
        else:
            cov = np.asarray(covariance, dtype=float)
            if cov.shape == (n,):
                cov = np.diag(cov)
            if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
                raise ValueError(f"covariance must be finite with shape ({n},) or ({n}, {n})")
        for name, b in (("accel_bias_b", accel_bias_b), ("gyro_bias_b", gyro_bias_b)):
            if b is not None and np.asarray(b, dtype=float).shape != (3,):
                raise ValueError(f"{name} must have shape (3,)")
        self._start(int(time_us), state, cov)
        if accel_bias_b is not None:
            self._ba = [float(v) for v in np.asarray(accel_bias_b, dtype=float)]
        if gyro_bias_b is not None:
            self._bg = [float(v) for v in np.asarray(gyro_bias_b, dtype=float)]
        if baro_bias_m is not None:
            self._bb = float(baro_bias_m)
            self._baro_ctl.on_bias_init()
        self.alignment_method = "given"

    # ------------------------------------------------------------------ dispatch
    def _classify(self, sample: object) -> Callable[[Any], list[NavEstimate]]:
        handler: Callable[[Any], list[NavEstimate]]
        if hasattr(sample, "angular_rate_b_rps") and hasattr(sample, "specific_force_b_mps2"):
            handler = self._on_imu
        elif hasattr(sample, "fix_type") and hasattr(sample, "eph_m"):
            handler = self._on_gnss
        elif hasattr(sample, "pressure_pa"):
            handler = self._on_baro
        elif hasattr(sample, "field_b_tesla"):
            handler = self._on_mag
        else:
            raise TypeError(
                f"{type(sample).__name__} is not an IMU, GNSS, baro or magnetometer sample"
            )
        self._handlers[type(sample)] = handler
        return handler

    def _check_order(self, kind: str, time_us: Any) -> int | None:
        """Per-sensor time order. Returns the time, or None (and counts) when the timestamp is
        unreadable (``<kind>_invalid``), repeats (``duplicates``), goes backwards
        (``time_backwards``) or lies more than ``max_sensor_lead_s`` ahead of the IMU
        (``time_jump``: it would otherwise block its stream until the IMU caught up)."""
        c = self._c
        try:
            t = int(time_us)
        except (TypeError, ValueError, OverflowError):
            setattr(c, f"{kind}_invalid", getattr(c, f"{kind}_invalid") + 1)
            return None
        last = self._last_us.get(kind)
        if last is not None and t <= last:
            if t == last:
                c.duplicates += 1
            else:
                c.time_backwards += 1
            return None
        imu = self._last_imu_us
        if imu is not None and t - imu > self._max_lead_us:
            c.time_jump += 1
            return None
        self._last_us[kind] = t
        return t

    # ------------------------------------------------------------------ IMU
    def _on_imu(self, s: ImuSample) -> list[NavEstimate]:
        c = self._c
        try:
            t = int(s.time_us)
        except (TypeError, ValueError, OverflowError):
            c.imu_nan += 1
            return []
        last = self._last_imu_us
        if last is not None and t <= last:
            if t == last:
                c.duplicates += 1
            else:
                c.time_backwards += 1
            return []
        try:
            try:  # fast path: numpy arrays
                fx, fy, fz = s.specific_force_b_mps2.tolist()
                wx, wy, wz = s.angular_rate_b_rps.tolist()
            except AttributeError:
                fx, fy, fz = _vec3(s.specific_force_b_mps2)
                wx, wy, wz = _vec3(s.angular_rate_b_rps)
            dt_s = float(s.dt_s)
            # x * 0 is 0 for finite x, NaN for NaN/Inf: one test for all seven fields
            finite = (fx + fy + fz + wx + wy + wz + dt_s) * 0.0 == 0.0
        except (TypeError, ValueError, AttributeError):
            finite = False
        good = False
        if not finite:
            c.imu_nan += 1
        else:
            ar = self._accel_range
            gr = self._gyro_range
            if (
                abs(fx) > ar or abs(fy) > ar or abs(fz) > ar
                or abs(wx) > gr or abs(wy) > gr or abs(wz) > gr
            ):  # fmt: skip
                c.imu_out_of_range += 1
            else:
                c.imu_ok += 1
                good = True
                self._good_fw = (fx, fy, fz, wx, wy, wz)
        if not good:
            if self._good_fw is None:
                self._last_imu_us = t
                return []
            fx, fy, fz, wx, wy, wz = self._good_fw
        if last is None:
            self._last_imu_us = t
            if not (good and 0.0 < dt_s <= self._max_dt):
                return []
            dt = dt_s
        else:
            dt = (t - last) * 1e-6
            self._last_imu_us = t
            if dt > self._time_jump_s:
                c.time_jump += 1
                if self._ins is not None:
                    self._coast(t, dt)
                    if self._alt is not None:
                        # no IMU data over the gap: the channel coasts on zero acceleration
                        self._alt.update_imu(-2.0 * self._omega_s2 * self._ins.alt_msl_m, dt)
                return self._outputs(t) if self._ins is not None else []

        ins0 = self._ins
        if ins0 is None:
            if good:
                self._aligner.add_imu(t, dt, (fx, fy, fz), (wx, wy, wz))
                self._try_align()
            return []

        ba, bg = self._ba, self._bg
        if self._scale:
            sa, sg = self._sa, self._sg
            dth = (
                (wx - bg[0]) / (1.0 + sg[0]) * dt,
                (wy - bg[1]) / (1.0 + sg[1]) * dt,
                (wz - bg[2]) / (1.0 + sg[2]) * dt,
            )
            dv = (
                (fx - ba[0]) / (1.0 + sa[0]) * dt,
                (fy - ba[1]) / (1.0 + sa[1]) * dt,
                (fz - ba[2]) / (1.0 + sa[2]) * dt,
            )
            af, aw = self._acc_f, self._acc_w
            af[0] += dv[0]
            af[1] += dv[1]
            af[2] += dv[2]
            aw[0] += dth[0]
            aw[1] += dth[1]
            aw[2] += dth[2]
        else:
            dth = ((wx - bg[0]) * dt, (wy - bg[1]) * dt, (wz - bg[2]) * dt)
            dv = ((fx - ba[0]) * dt, (fy - ba[1]) * dt, (fz - ba[2]) * dt)
        ins = _ins_update(ins0, dth, dv, self._prev_dth, self._prev_dv, dt)
        self._ins = ins
        self._prev_dth = dth
        self._prev_dv = dv
        self._last_dt = dt
        self._t_us = t
        if self._shadows is not None:  # virtual outages (fusion.bridging.shadows.ShadowBank)
            self._shadows.step(t, ins, dth, dv, dt, ba, bg)
        acc_dt = self._acc_dt + dt
        self._acc_dt = acc_dt
        if acc_dt >= self._cov_period_s - 1e-9:
            self._propagate()
        self._history.push(t, ins)
        if self._alt_cfg is not None:
            # The mechanised vertical acceleration of this epoch's strapdown step alone (no
            # feedback in it): specific force less the EKF's bias estimates, normal gravity at
            # the INS height, Coriolis and transport terms. The channel wants f_up - g(lat, 0)
            # and adds 2 ws^2 h of its *own* height back (P4 eq. 5), hence the shift by the
            # INS height's free-air term.
            ch = self._alt or self._new_altitude_channel(t - round(dt * 1e6))
            vd0 = ins0.v_ned_mps[2]
            ch.update_imu((vd0 - ins.v_ned_mps[2]) / dt - 2.0 * self._omega_s2 * ins.alt_msl_m, dt)
        if self._pending and self._pending[0].time_us <= t:
            self._drain_pending()
        return self._outputs(t)

    def _outputs(self, t: int) -> list[NavEstimate]:
        """Outage bookkeeping, bridging epochs and the output clock (after every IMU epoch)."""
        last_fused = self._gnss_ctl.last_fused_us
        if not self._in_outage and last_fused is not None and t - last_fused > self._timeout_us:
            self._in_outage = True
            self._c.gnss_outages += 1
            self._next_bridge_us = t
            if self._shadows is not None and self._ins is not None:
                self._shadows.begin_outage(
                    t, self._ins, self._ba, self._bg, self._prev_dth, self._prev_dv
                )
        if self._in_outage and t >= self._next_bridge_us:
            self._bridge_step(t)
        if t >= self._next_out_us:
            self._next_out_us += self._out_period_us
            if self._next_out_us <= t:
                self._next_out_us = t + self._out_period_us
            return [self._make_estimate()]
        return []

    def _try_align(self) -> None:
        res = self._aligner.poll()
        if res is not None:
            self._start_from_alignment(res)

    def default_initial_variances(self) -> FloatArray:
        """Initial error variances (n,) from ``InitConfig`` and the sensor sigmas (what
        :meth:`initialize` uses when no covariance is given)."""
        return self._default_p0_diag()

    def _default_p0_diag(self) -> FloatArray:
        lay, cfg = self.layout, self.config
        d = np.zeros(lay.n)
        d[lay.pos] = cfg.init.pos_sigma_m**2
        d[lay.vel] = cfg.init.vel_sigma_mps**2
        d[lay.att] = [cfg.init.roll_pitch_sigma_rad**2] * 2 + [cfg.init.yaw_sigma_rad**2]
        # Initial bias uncertainty: the turn-on (repeatability) bias, a random constant, plus
        # the in-run Gauss-Markov part.
        d[lay.ba] = cfg.imu.accel_turn_on_sigma_mps2**2 + cfg.imu.accel_bias_sigma_mps2**2
        d[lay.bg] = cfg.imu.gyro_turn_on_sigma_rps**2 + cfg.imu.gyro_bias_sigma_rps**2
        d[lay.baro] = cfg.baro.bias_sigma_m**2
        if lay.gnss is not None:
            g = cfg.gnss
            d[lay.gnss] = [g.bias_sigma_h_m**2] * 2 + [g.bias_sigma_v_m**2]
        if lay.sa is not None and lay.sg is not None:
            d[lay.sa] = cfg.imu.accel_scale_sigma**2
            d[lay.sg] = cfg.imu.gyro_scale_sigma**2
        return d

    def _start_from_alignment(self, res: AlignmentResult) -> None:
        lay = self.layout
        d = self._default_p0_diag()
        d[lay.pos] = np.square(res.sigma_pos_ned_m)
        d[lay.vel] = res.sigma_vel_mps**2
        d[lay.att] = np.square(res.sigma_att_ned_rad)
        cov = np.diag(d)
        if lay.gnss is not None:
            # the aligned position is a fix: its error is the receiver's bias plus white noise,
            # i.e. dr = -db + w (db = b^ - b with b^ = 0), correlation -sigma_b^2 per axis
            for i in range(3):
                pi, gi = lay.POS + i, lay.GNSS + i
                c = min(cov[gi, gi], 0.9 * cov[pi, pi])
                cov[pi, gi] = cov[gi, pi] = -c
        self._start(res.time_us, res.state, cov)
        self.alignment_method = res.method

    def _start(self, time_us: int, state: InsState, cov: FloatArray) -> None:
        self._ins = state
        self._t_us = time_us
        if self._last_imu_us is None or self._last_imu_us < time_us:
            self._last_imu_us = time_us
        self._P = 0.5 * (cov + cov.T)
        self._prev_dth = self._prev_dv = _ZERO3
        self._acc_dt = 0.0
        self._acc_v0 = state.v_ned_mps
        self._acc_f = [0.0, 0.0, 0.0]
        self._acc_w = [0.0, 0.0, 0.0]
        self._history.clear()
        self._history.push(time_us, state)
        self._gnss_ctl.start(time_us)
        self._gb, self._gb_us = [0.0, 0.0, 0.0], time_us
        self._next_out_us = time_us
        self._in_outage = False
        self._alt = None  # a (re)start also restarts the altitude channel
        self._alt_ready = False

    def _coast(self, t: int, gap_s: float) -> None:
        """IMU data missing for ``gap_s``: constant-velocity dead reckoning, covariance grown by
        the process model over the gap, coning/sculling memory cleared."""
        self._flush()
        ins = self._ins
        assert ins is not None
        if self._shadows is not None:  # the shadows cannot mechanise a gap either: restart
            self._shadows.restart(t)
        lt = earth.local_terms(ins.lat_rad, ins.alt_msl_m)
        vn, ve, vd = ins.v_ned_mps
        self._ins = InsState(
            ins.lat_rad + vn * gap_s / lt.rho_n_m,
            ins.lon_rad + ve * gap_s / (lt.rho_e_m * lt.cos_lat),
            ins.alt_msl_m - vd * gap_s,
            ins.v_ned_mps,
            ins.q_nb,
        )
        # first-order Phi is fine for 10 ms, not for seconds: propagate in sub-steps
        n_sub = min(100, max(1, math.ceil(gap_s / 0.1)))
        for _ in range(n_sub):
            self._acc_v0 = ins.v_ned_mps
            self._acc_dt = gap_s / n_sub
            self._propagate()
        # the sensors did not see what the vehicle did meanwhile: unknown manoeuvres
        imu, lay = self.config.imu, self.layout
        sa, sw = imu.gap_accel_sigma_mps2, imu.gap_rate_sigma_rps
        P = self._P.copy()
        idx = np.arange(3)
        P[lay.POS + idx, lay.POS + idx] += (0.5 * sa * gap_s * gap_s) ** 2
        P[lay.VEL + idx, lay.VEL + idx] += (sa * gap_s) ** 2
        P[lay.POS + idx, lay.VEL + idx] += 0.5 * sa * sa * gap_s**3
        P[lay.VEL + idx, lay.POS + idx] += 0.5 * sa * sa * gap_s**3
        P[lay.ATT + idx, lay.ATT + idx] += (sw * gap_s) ** 2
        self._P = P
        self._prev_dth = self._prev_dv = _ZERO3
        self._t_us = t
        self._history.push(t, self._ins)
        if self._pending:
            self._drain_pending()

    # ------------------------------------------------------------------ covariance
    def _decay(self, dt: float) -> tuple[float, ...]:
        k = self._decay_cache.get(dt)
        if k is None:
            k = tuple(
                math.exp(-dt / tau)
                for tau in (self._tau_a, self._tau_g, self._tau_b, self._tau_sa, self._tau_sg)
            )
            if len(self._decay_cache) < 64:
                self._decay_cache[dt] = k
        return k

    def _propagate(self) -> None:
        """P <- Phi P Phi^T + Q over the accumulated interval; Gauss-Markov decay of the bias
        estimates over the same interval."""
        T = self._acc_dt
        ins = self._ins
        assert ins is not None
        lat, _, h, v, q = ins
        vn, ve, vd = v
        v0n, v0e, v0d = self._acc_v0
        lt = earth.local_terms(lat, h)
        rho_n, rho_e, g, s_lat, c_lat = lt
        # c = 2 omega_ie + omega_en
        wen_n = ve / rho_e
        cx = _TWO_RATE * c_lat + wen_n
        cy = -vn / rho_n
        cz = -_TWO_RATE * s_lat - wen_n * s_lat / c_lat
        # mean specific force in NED: v' = f + g - (2 w_ie + w_en) × v
        f_n = (
            (vn - v0n) / T + (cy * vd - cz * ve),
            (ve - v0e) / T + (cz * vn - cx * vd),
            (vd - v0d) / T - g + (cx * ve - cy * vn),
        )
        self._f_n = f_n
        c_nb = dcm_from_quat(q)
        if self._scale:
            af, aw = self._acc_f, self._acc_w
            f_b = (af[0] / T, af[1] / T, af[2] / T)
            w_b = (aw[0] / T, aw[1] / T, aw[2] / T)
            self._acc_f = [0.0, 0.0, 0.0]
            self._acc_w = [0.0, 0.0, 0.0]
        else:
            f_b = w_b = _ZERO3
        model = self._model
        Phi = model.first_order_transition(lat, h, v, c_nb, f_n, T, f_b, w_b, terms=lt)
        # P = Phi P Phi^T + Q  (Q diagonal: white sensor noise and Gauss-Markov driving noise)
        # (np.dot: the same GEMMs as @, with less dispatch overhead on these small matrices)
        P = _dot(_dot(Phi, self._P), Phi.T)
        P += model.process_noise(T)
        self._P = P
        # The IMU bias and scale-factor *estimates* are held, not decayed with the Gauss-Markov
        # time constant: a real sensor's bias is a turn-on constant plus a zero-mean in-run
        # process, and decaying the estimate of the constant part towards zero (tau ~ 100 s for
        # MEMS datasheets) makes the filter forget what it learned and fight every GNSS fix.
        # The covariance keeps the Gauss-Markov dynamics. The baro bias is a zero-mean process.
        self._bb *= self._decay(T)[2]
        self._acc_dt = 0.0
        self._acc_v0 = ins.v_ned_mps

    def _flush(self) -> None:
        if self._acc_dt > 0.0 and self._ins is not None:
            self._propagate()

    # ------------------------------------------------------------------ updates
    def _correct(self, obs: Observation, gate: float) -> kalman.Correction:
        """Gated Joseph-form update; on acceptance the error estimate is fed back at once."""
        self._flush()
        res = kalman.correct(self._x0, self._P, obs.z, obs.H, obs.R, gate)
        if res.test_ratio <= 1.0:
            self._P = res.P
            self._feedback(res.x)
        return res

    def _feedback(self, dx: FloatArray) -> None:
        """Move the error estimate into the INS (subtract: errors are estimated minus true)."""
        ins = self._ins
        assert ins is not None
        lay = self.layout
        d = dx.tolist()
        p, v, a = lay.POS, lay.VEL, lay.ATT
        lt = earth.local_terms(ins.lat_rad, ins.alt_msl_m)
        vn, ve, vd = ins.v_ned_mps
        # q <- q(-phi) ⊗ q
        rw, rx, ry, rz = quat_product(rotvec_quat(-d[a], -d[a + 1], -d[a + 2]), ins.q_nb)
        norm = math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
        if rw < 0.0:
            norm = -norm
        self._ins = InsState(
            ins.lat_rad - d[p] / lt.rho_n_m,
            ins.lon_rad - d[p + 1] / (lt.rho_e_m * lt.cos_lat),
            ins.alt_msl_m + d[p + 2],
            (vn - d[v], ve - d[v + 1], vd - d[v + 2]),
            (rw / norm, rx / norm, ry / norm, rz / norm),
        )
        ba, bg, b, g = self._ba, self._bg, lay.BA, lay.BG
        self._ba = [ba[0] - d[b], ba[1] - d[b + 1], ba[2] - d[b + 2]]
        self._bg = [bg[0] - d[g], bg[1] - d[g + 1], bg[2] - d[g + 2]]
        self._bb -= d[lay.BARO]
        if lay.gnss is not None:
            gb, g = self._gnss_bias(), lay.GNSS
            self._gb = [gb[0] - d[g], gb[1] - d[g + 1], gb[2] - d[g + 2]]
        if lay.sa is not None and lay.sg is not None:
            b = int(lay.sa.start)
            self._sa = [self._sa[i] - d[b + i] for i in range(3)]
            b = int(lay.sg.start)
            self._sg = [self._sg[i] - d[b + i] for i in range(3)]
        self._history.add_correction(d[p : p + 3] + d[v : v + 3] + d[a : a + 3])
        self._acc_v0 = self._ins.v_ned_mps

    def _reset_block(self, block: slice, z: FloatArray, variances: FloatArray) -> None:
        """Set a block of the INS to the measurement (dx = z on that block), decorrelate it."""
        self._flush()
        dx = np.zeros(self.layout.n)
        dx[block] = z
        self._feedback(dx)
        P = self._P.copy()
        P[block, :] = 0.0
        P[:, block] = 0.0
        P[block, block] = np.diag(variances)
        self._P = P

    def _reset_position(self, z: FloatArray, variances: FloatArray) -> None:
        """Position reset to the fix (``z`` its position innovation, ``variances`` the white
        part). With the GNSS bias states the bias also goes back to its prior (estimate 0,
        sigma_b): the INS position becomes the fix itself, whose error is bias plus white noise,
        ``dr = -db + w``, hence the covariance ``[[sb^2 + r, -sb^2], [-sb^2, sb^2]]``."""
        lay = self.layout
        if lay.gnss is None:
            self._reset_block(lay.pos, z, variances)
            return
        self._flush()
        gb = np.array(self._gnss_bias())
        dx = np.zeros(lay.n)
        dx[lay.pos] = z - gb  # z holds + b^: the INS moves onto the fix, not onto fix - b^
        dx[lay.gnss] = gb  # b^ <- b^ - dx = 0
        self._feedback(dx)
        g = self.config.gnss
        sb2 = np.array([g.bias_sigma_h_m**2] * 2 + [g.bias_sigma_v_m**2])
        P = self._P.copy()
        for blk in (lay.pos, lay.gnss):
            P[blk, :] = 0.0
            P[:, blk] = 0.0
        P[lay.pos, lay.pos] = np.diag(variances + sb2)
        P[lay.gnss, lay.gnss] = np.diag(sb2)
        P[lay.pos, lay.gnss] = P[lay.gnss, lay.pos] = -np.diag(sb2)
        self._P = P

    def _gnss_bias(self) -> list[float]:
        """The GNSS position-bias estimate (NED, m) decayed to the current time: between fixes
        (and through outages) it relaxes to zero as its Gauss-Markov mean does."""
        dt = (self._t_us - self._gb_us) * 1e-6
        if dt > 0.0:
            g = self.config.gnss
            kh, kv = math.exp(-dt / g.bias_tau_h_s), math.exp(-dt / g.bias_tau_v_s)
            b = self._gb
            self._gb = [b[0] * kh, b[1] * kh, b[2] * kv]
            self._gb_us = self._t_us
        return self._gb

    # ------------------------------------------------------------------ GNSS
    def _on_gnss(self, fix: GnssFix) -> list[NavEstimate]:
        t = self._check_order("gnss", fix.time_us)
        if t is None:
            return []
        c = self._c
        try:
            reason = gnss_aid.fix_quality(fix, self.config.gnss)
        except (TypeError, ValueError, AttributeError):
            reason = "invalid"
        if reason is not None:
            if reason == "no_fix":
                c.gnss_no_fix += 1
            elif reason == "invalid":
                c.gnss_invalid += 1
            else:
                c.gnss_inaccurate += 1
            self._gnss_ctl.on_bad_fix()
            return []
        if self._ins is None:
            self._aligner.add_fix(fix)
            self._try_align()
            return []
        if t > self._t_us:
            self._pending.append(fix)
            return []
        self._fuse_gnss(fix)
        return []

    def _drain_pending(self) -> None:
        while self._pending and self._pending[0].time_us <= self._t_us:
            self._fuse_gnss(self._pending.popleft())

    def _past_state(self, time_us: int) -> InsState | None:
        if time_us >= self._t_us:
            return self._ins
        return self._history.at(time_us)

    def _omega_b(self) -> tuple[float, float, float]:
        dt = self._last_dt
        if dt <= 0.0:
            return _ZERO3
        a = self._prev_dth
        return (a[0] / dt, a[1] / dt, a[2] / dt)

    def _fuse_gnss(self, fix: GnssFix) -> None:
        c, cfg, ctl, lay = self._c, self.config.gnss, self._gnss_ctl, self.layout
        t = int(fix.time_us)
        now = self._t_us
        past = self._past_state(t)
        if past is None or now - t > round(cfg.max_delay_s * 1e6):
            c.gnss_too_old += 1
            return
        if not ctl.on_good_fix(t, now):
            return
        sig_h, sig_v, sig_vel = gnss_aid.fix_sigmas(fix, cfg)
        delay = (now - t) * 1e-6
        lat, lon, alt = float(fix.lat_rad), float(fix.lon_rad), float(fix.alt_msl_m)
        bias = None if lay.gnss is None else self._gnss_bias()
        w_h, w_v = gnss_aid.white_position_sigmas(sig_h, sig_v, cfg, lay)
        obs = gnss_aid.position_model(
            lay, past, lat, lon, alt, w_h, w_v, cfg.lever_arm_b_m, delay,
            None if bias is None else (bias[0], bias[1], bias[2]),
        )  # fmt: skip
        if obs is None:
            c.gnss_invalid += 1
            return
        ins_pre_pos = self._ins  # for the shadows' errors (virtual outages)
        res = self._correct(obs, self._gate3)
        pos_ok = res.test_ratio <= 1.0
        self._ratios[0] = res.test_ratio
        # the bridge learns the INS minus the fix as received (without the bias estimate)
        z_pos = obs.z if bias is None else obs.z - np.array(bias)
        if not pos_ok and ctl.on_result("pos", t, False):
            self._reset_position(obs.z, np.diag(obs.R))
            ctl.on_reset("pos", t)
            c.gnss_resets += 1
        elif pos_ok:
            ctl.on_result("pos", t, True)
        past = self._past_state(t)
        assert past is not None
        if pos_ok and self._alt_cfg is not None:
            self._altitude_gnss(fix, past, sig_v)
        v_fix = np.asarray(fix.v_ned_mps, dtype=float)
        obs_v = gnss_aid.velocity_model(
            lay, past, self._omega_b(), v_fix, sig_vel, cfg.lever_arm_b_m
        )
        if obs_v is None:
            c.gnss_invalid += 1
            return
        ins_pre_vel = self._ins
        res_v = self._correct(obs_v, self._gate3)
        vel_ok = res_v.test_ratio <= 1.0
        self._ratios[1] = res_v.test_ratio
        if not vel_ok and ctl.on_result("vel", t, False):
            self._reset_block(lay.vel, obs_v.z, np.diag(obs_v.R))
            ctl.on_reset("vel", t)
            c.gnss_resets += 1
        elif vel_ok:
            ctl.on_result("vel", t, True)
        if pos_ok and vel_ok:
            c.gnss_fused += 1
        else:
            c.gnss_rejected += 1
        zp, zv = z_pos.tolist(), obs_v.z.tolist()
        if len(zv) == 2:  # vertical velocity not reported by the receiver
            zv.append(math.nan)
        shadows = self._shadows
        virtual = (
            shadows.samples(t, ins_pre_pos, ins_pre_vel, zp, zv)
            if shadows is not None and pos_ok and vel_ok
            and ins_pre_pos is not None and ins_pre_vel is not None
            else ()
        )  # fmt: skip
        self.bridge.on_gnss(
            self._epoch(t, past),
            InsError((zp[0], zp[1], zp[2]), (zv[0], zv[1], zv[2]), pos_ok, vel_ok, virtual),
        )
        if self._in_outage and ctl.is_active(now):
            self._leave_outage(now)

    # ------------------------------------------------------------------ bridging
    def _epoch(self, time_us: int, state: InsState) -> BridgeEpoch:
        ba, bg = self._ba, self._bg
        shadows = self._shadows
        return BridgeEpoch(
            time_us=time_us,
            lat_rad=state.lat_rad,
            lon_rad=state.lon_rad,
            alt_msl_m=state.alt_msl_m,
            v_ned_mps=state.v_ned_mps,
            euler_rad=euler_from_quat(state.q_nb),
            f_n_mps2=self._f_n,
            omega_ib_b_rps=self._omega_b(),
            time_since_gnss_s=max(0.0, self._gnss_ctl.time_since_fused_s(time_us)),
            accel_bias_b_mps2=(ba[0], ba[1], ba[2]),
            gyro_bias_b_rps=(bg[0], bg[1], bg[2]),
            free_state=None if shadows is None else shadows.free_state,
        )

    def _bridge_step(self, t: int) -> None:
        self._next_bridge_us = max(self._next_bridge_us + self._bridge_period_us, t + 1)
        ins = self._ins
        assert ins is not None
        action = self.bridge.on_outage(self._epoch(t, ins))
        if action is None:
            return
        if isinstance(action, OutputCorrection):
            self._out_corr = action
            self._bridge_active = True
            self._c.bridge_updates += 1
        elif isinstance(action, PseudoGnss):
            lay, cfg = self.layout, self.config.gnss
            obs = gnss_aid.position_model(
                lay, ins, action.lat_rad, action.lon_rad, action.alt_msl_m,
                action.sigma_pos_m, action.sigma_pos_m, cfg.lever_arm_b_m,
            )  # fmt: skip
            if obs is not None:
                self._correct(obs, self._gate3)
            ins = self._ins
            assert ins is not None
            obs_v = gnss_aid.velocity_model(
                lay, ins, self._omega_b(), np.asarray(action.v_ned_mps, dtype=float),
                action.sigma_vel_mps, cfg.lever_arm_b_m,
            )  # fmt: skip
            if obs_v is not None:
                self._correct(obs_v, self._gate3)
            self._bridge_active = True
            self._c.bridge_updates += 1

    def _leave_outage(self, t: int) -> None:
        self._in_outage = False
        self._bridge_active = False
        self._out_corr = None
        ins = self._ins
        assert ins is not None
        self.bridge.on_gnss_restored(self._epoch(t, ins))
        if self._shadows is not None:
            self._shadows.end_outage(t)

    # ------------------------------------------------------------------ altitude channel
    # With a loop method (P4's baro-inertial channel) the estimate's altitude and vertical
    # velocity come from fusion.altitude.channel.AltitudeChannel, fed here with the INS vertical
    # acceleration (_on_imu), every baro sample (_on_baro) and the fused GNSS heights
    # (_fuse_gnss). The EKF keeps its own baro update for its internal state, but only with the
    # samples the channel accepted (range, freeze and glitch checks); the channel's output is
    # not fed back. Why: (1) the EKF's vertical stays bounded by the barometer through an outage
    # exactly as with `ekf`, and the horizontal solution is *identical* to `ekf` whenever the
    # barometer is healthy (only faulty samples differ, and those are better left out of the
    # EKF too); (2) the channel's height is a filtered, time-correlated signal that already
    # contains the GNSS heights the EKF fused: feeding it back as a white pseudo-measurement
    # would double-count GNSS and make the EKF overconfident in height, vertical velocity and
    # the accelerometer bias; (3) the altitude methods then differ only in the output vertical,
    # which is what a comparison of them should measure.
    def _new_altitude_channel(self, start_us: int) -> AltitudeChannel:
        assert self._alt_cfg is not None
        self._alt = AltitudeChannel(self._alt_cfg, start_us * 1e-6)
        return self._alt

    def _altitude_gnss(self, fix: GnssFix, past: InsState, sigma_m: float) -> None:
        """A fused GNSS height into the channel, moved from the antenna to the IMU and from its
        time of validity to now with the INS height change (0.1 s of latency at 2.5 m/s of
        climb would otherwise be a 0.25 m bias in the calibration and the MPC reference)."""
        ins = self._ins
        assert ins is not None
        ch = self._alt or self._new_altitude_channel(self._t_us)
        h = float(fix.alt_msl_m) + (ins.alt_msl_m - past.alt_msl_m)
        ax, ay, az = self.config.gnss.lever_arm_b_m
        if ax or ay or az:  # antenna height = IMU height - (C_nb arm)_D
            c_nb = dcm_from_quat(past.q_nb)
            h += c_nb[6] * ax + c_nb[7] * ay + c_nb[8] * az
        hh, c = ch.health, self._c
        n_cal, n_rej = hh.calibration_updates, hh.gnss_rejected
        ch.update_gnss_height(h, sigma_m, self._t_us * 1e-6)
        c.altitude_calibration_updates += hh.calibration_updates - n_cal
        c.altitude_gnss_rejected += hh.gnss_rejected - n_rej

    def _baro_screen(self, s: BaroSample, p: float, t: int) -> bool:
        """Range / freeze (and, for the loop methods, the channel's gate and the channel's own
        update): whether the EKF may use the sample. Rejections are counted, never raised."""
        c = self._c
        if self._alt_cfg is None:
            mon = self._baro_mon
            if mon.check(p, t * 1e-6) is None:  # in range (checked before): frozen
                c.baro_frozen += 1
                return False
            return True
        try:
            temp: float | None = float(s.temperature_k)
        except (TypeError, ValueError, AttributeError):
            temp = None
        if temp is not None and not (math.isfinite(temp) and temp > 0.0):
            temp = None
        ch = self._alt or self._new_altitude_channel(self._t_us)
        hb = ch.health.baro
        n_frozen, n_gate, n_realign = hb.frozen_samples, hb.gate_rejections, hb.realignments
        used = ch.update_baro(p, temp, t * 1e-6)
        c.baro_frozen += hb.frozen_samples - n_frozen
        c.baro_glitches += hb.gate_rejections - n_gate
        c.baro_realignments += hb.realignments - n_realign
        return used

    def _baro_repeat_ok(self, p: float, t: int) -> bool:
        """False (counted) for a reading unchanged for more than ``ekf_repeat_hold_s``."""
        run = self._baro_run
        tol = self.config.altitude.channel.monitor.freeze_tolerance_pa
        if run is None or abs(p - run[0]) > tol:
            self._baro_run = (p, t)
            return True
        if (t - run[1]) * 1e-6 > self.config.altitude.ekf_repeat_hold_s:
            self._c.baro_repeats_held += 1
            return False
        return True

    def _altitude_ready(self, ch: AltitudeChannel) -> bool:
        """The channel's output is used from its first GNSS calibration (if it learns one) and
        its compensator's first reference (if it has one) on: before that it would show the
        uncalibrated baro height and then jump by the calibration (tens of metres)."""
        hh = ch.health
        if not hh.initialised:
            return False
        bc = ch.config.baro
        if bc.mode == "calibrated" and bc.calibration.use_gnss and hh.calibration_updates == 0:
            return False
        comp = ch.mpc if ch.mpc is not None else ch.kf
        self._alt_ready = comp is None or comp.started
        return self._alt_ready

    def _altitude_status(self) -> AltitudeStatus:
        ch = self._alt
        if ch is None:
            # no channel: the status has one variable field, so it is built once per value
            # (AltitudeStatus is immutable; its __init__ with 17 fields costs ~3 us)
            frozen = self._baro_mon.health.frozen
            cached = self._alt_status_idle.get(frozen)
            if cached is None:
                cached = AltitudeStatus(self.config.altitude.method, baro_frozen=frozen)
                self._alt_status_idle[frozen] = cached
            return cached
        cal = ch.altimeter.calibration
        hh = ch.health
        return AltitudeStatus(
            ch.method, self._alt_ready, hh.initialised, ch.gnss_valid, cal.frozen, cal.scale,
            cal.bias_m, cal.sea_level_dt_k, cal.sea_level_dp_pa, ch.loop_height_m, ch.baro_height_m,
            ch.correction_m, hh.compensator_steps, hh.qp_active, hh.undamped, hh.baro.frozen,
            hh.baro.rejecting,
        )  # fmt: skip

    # ------------------------------------------------------------------ baro, mag
    def _on_baro(self, s: BaroSample) -> list[NavEstimate]:
        t = self._check_order("baro", s.time_us)
        if t is None:
            return []
        c = self._c
        try:
            p = float(s.pressure_pa)
        except (TypeError, ValueError):
            p = math.nan
        if not P_MIN_PA <= p <= P_MAX_PA:  # also NaN and p <= 0
            c.baro_invalid += 1
            return []
        h_baro = baro_aid.pressure_to_height(p)
        if self._ins is None:
            return []
        if not (self._baro_screen(s, p, t) and self._baro_repeat_ok(p, t)):
            return []
        ctl = self._baro_ctl
        batch = ctl.add_sample(t, h_baro)
        if batch is None:
            return []
        t_mean, h_mean, count = batch
        past = self._past_state(t_mean)
        if past is None:
            past = self._ins
        if ctl.need_bias_init(t_mean):
            self._init_baro_bias(h_mean - past.alt_msl_m)
            ctl.on_bias_init()
            return []
        obs = baro_aid.height_model(
            self.layout, past.alt_msl_m, self._bb, h_mean,
            self.config.baro.noise_m / math.sqrt(count),
        )  # fmt: skip
        if obs is None:
            c.baro_invalid += 1
            return []
        res = self._correct(obs, self._gate_baro)
        self._ratios[2] = res.test_ratio
        ok = res.test_ratio <= 1.0
        if ok:
            c.baro_fused += 1
        else:
            c.baro_rejected += 1
        if ctl.on_result(t_mean, ok):
            self._init_baro_bias(h_mean - past.alt_msl_m)
            ctl.on_bias_init()
            c.baro_resets += 1
        return []

    def _init_baro_bias(self, bias_m: float) -> None:
        """b^ = h_baro - h^: the bias error is dr_D + noise, so its covariance row is that of
        the down-position error plus the baro noise on the diagonal."""
        self._flush()
        self._bb = bias_m
        lay = self.layout
        d, b = lay.POS + 2, lay.BARO
        P = self._P.copy()
        row = P[d, :].copy()
        row[b] = P[d, d] + self.config.baro.noise_m**2
        P[b, :] = row
        P[:, b] = row
        self._P = P

    def _on_mag(self, s: MagSample) -> list[NavEstimate]:
        t = self._check_order("mag", s.time_us)
        if t is None:
            return []
        c = self._c
        # scalar checks, and the array only for a sample that is used (most are not due):
        # numpy's all(isfinite) on 3 values costs more than the rest of a skipped sample
        try:
            field = _vec3(s.field_b_tesla)
        except (TypeError, ValueError, AttributeError):
            field = (math.nan, math.nan, math.nan)
        if not (_isfinite(field[0]) and _isfinite(field[1]) and _isfinite(field[2])):
            c.mag_invalid += 1
            return []
        if self._ins is None:
            if isinstance(self._aligner, StaticAlignment):
                self._aligner.add_mag(np.array(field))
                self._try_align()
            return []
        ctl = self._mag_ctl
        if not ctl.due(t):
            return []
        m = np.array(field)
        c_nb = quat_to_dcm(self._ins.q_nb)
        if ctl.reference_n is None or ctl.calibrator is not None:
            self._flush()
            yaw_sigma = math.sqrt(self._P[self.layout.ATT + 2, self.layout.ATT + 2])
            if ctl.reference_n is None:
                ctl.learn(c_nb @ m, yaw_sigma)
            ctl.offer_calibration(c_nb, m, euler_from_quat(self._ins.q_nb)[2], yaw_sigma)
            if ctl.reference_n is None:
                return []
        cfg = self.config.mag
        obs = mag_aid.heading_model(
            self.layout, c_nb, ctl.corrected(m), ctl.reference_n, ctl.heading_noise_rad(),
            cfg.min_horizontal_field_tesla,
        )  # fmt: skip
        if obs is None:
            c.mag_invalid += 1
            return []
        res = self._correct(obs, self._gate_mag)
        self._ratios[3] = res.test_ratio
        ok = res.test_ratio <= 1.0
        ctl.on_result(t, ok)
        if ok:
            c.mag_fused += 1
        else:
            c.mag_rejected += 1
        return []

    # ------------------------------------------------------------------ output
    def _make_estimate(self) -> NavEstimate:
        # runs at the output rate (50 Hz default): no per-call dataclass __init__ where a
        # cached immutable part or the slot setters (_new_estimate) do
        ins = self._ins
        assert ins is not None
        lat, lon, alt, v, q = ins
        corr = self._out_corr
        if corr is not None:
            lt = earth.local_terms(lat, alt)
            dn, de, dd = corr.pos_ned_m
            lat -= dn / lt.rho_n_m
            lon -= de / (lt.rho_e_m * lt.cos_lat)
            alt += dd
            cv = corr.vel_ned_mps
            v = (v[0] - cv[0], v[1] - cv[1], v[2] - cv[2])
        ch = self._alt
        if ch is not None and (self._alt_ready or self._altitude_ready(ch)):
            # loop methods: the vertical is the altitude channel's (it supersedes the EKF's
            # and any bridging correction's vertical)
            alt = ch.height_m
            v = (v[0], v[1], -ch.vz_mps)
        # one read-only array, the vector fields are views of it
        buf = np.array((*v, *q, *euler_from_quat(q), *self._ba, *self._bg))
        buf.setflags(write=False)
        p_diag = self._P.diagonal().copy()
        p_diag.setflags(write=False)
        r = self._ratios
        if r != self._est_ratios_key:  # list ==: identity first, so NaN == the same NaN
            self._est_ratios_key = r[:]
            self._est_ratios = TestRatios(r[0], r[1], r[2], r[3])
        t = self._t_us
        gctl = self._gnss_ctl
        mode = (
            MODE_GNSS if gctl.is_active(t)
            else MODE_BRIDGING if self._bridge_active else MODE_FREE_INERTIAL
        )  # fmt: skip
        return _new_estimate(
            t, lat, lon, alt,
            buf[0:3], buf[3:7], buf[7:10],  # v_ned_mps, q_nb, euler_rad
            p_diag, mode,
            buf[10:13], buf[13:16], self._bb,  # accel_bias_b, gyro_bias_b, baro_bias_m
            self._c.snapshot(), self._est_ratios,
            gctl.time_since_fused_s(t), self.layout.name,
            self._altitude_status(), self.bridge.status,
        )  # fmt: skip

