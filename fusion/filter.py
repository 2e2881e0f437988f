"""NavFilter: the loosely coupled INS/GNSS/baro/mag error-state EKF, sequencing the pieces.

Per IMU sample: screen it (:mod:`fusion.screening`), compensate the sensor-error estimates and
integrate the strapdown INS (:mod:`fusion.strapdown`), step the virtual-outage INS copies of a
bridging strategy, accumulate time for the covariance propagation (:mod:`fusion.propagation`,
at ``covariance_rate_hz``), store the INS state for delayed measurements
(:mod:`fusion.history`), feed the altitude channel (:mod:`fusion.altitude_link`), fuse the GNSS
fixes that became due, watch for GNSS outages and consult the bridging strategy during one
(:mod:`fusion.outage`), and emit an estimate (:mod:`fusion.estimate`) at ``output_rate_hz``.
GNSS / baro / magnetometer samples and bridging pseudo-fixes go through their aiding source in
:mod:`fusion.aiding` (control: *when*; model: *how*); every update goes through the one funnel
of :mod:`fusion.filter_state` (gated Joseph update, feedback into the nominal state at once).

Bad input never raises and is never integrated: non-finite or out-of-range IMU samples are
replaced by the last good one (zero-order hold over their interval); duplicated timestamps are
dropped; one IMU stamp never moves the filter's clock: a stamp more than
``ImuTuning.time_jump_s`` ahead of it or behind it is quarantined, and only a consistent run of
them is a new time base (:mod:`fusion.screening`): a forward gap is then not integrated (the
INS coasts at constant velocity and the covariance grows by the process noise), a step back
or a long gap re-initialises the filter (``Health.time_rebases``); GNSS fixes without a
3-D fix, with non-finite or out-of-range fields or a poor accuracy are not fused, and a reset
to GNSS is bounded by what the INS knows (:mod:`fusion.aiding.gnss`). Everything is counted
in :class:`~fusion.estimate.Health`.

Altitude (``FilterConfig.altitude.method``): ``ekf`` outputs the EKF's own vertical (baro fused
as an EKF update); ``loop`` / ``loop-mpc`` / ``loop-kf`` run paper P4's baro-inertial channel
beside the EKF and output its altitude and vertical velocity, while the EKF keeps fusing the
baro samples the channel accepted (:mod:`fusion.altitude_link` says why). Every method screens
the barometer (pressure out of the atmosphere model, frozen sensor; loop methods also a gate on
jumps) and counts what it rejects; :class:`~fusion.estimate.AltitudeStatus` reports the
calibration and compensator state.

Air data (layouts ``+air``): pitot samples, the air-data epochs and their inputs go through
:mod:`fusion.air_data_link` and :mod:`fusion.aiding.airspeed`.

This module only sequences calls and keeps counters.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion import earth, strapdown
from fusion.aiding.airspeed import AirspeedAiding
from fusion.aiding.baro import BaroAiding
from fusion.aiding.gnss import GnssAiding, fix_sigmas
from fusion.aiding.mag import MagAiding
from fusion.aiding.pseudo_gnss import PseudoGnssAiding
from fusion.aiding.zero_motion import ZeroMotionAiding
from fusion.air_data_link import AIR_OFF, AirDataLink
from fusion.alignment import (
    AlignmentResult,
    AutoAlignment,
    InFlightAlignment,
    StaticAlignment,
    aligned_covariance,
    initial_variances,
)
from fusion.altitude.channel import AltitudeChannel
from fusion.altitude_link import AltitudeLink
from fusion.bridging.interface import (
    Bridge,
    BridgeEpoch,
    BridgeStatus,
    NoBridge,
    OutputCorrection,
    PseudoGnss,
)
from fusion.config import ALTITUDE_METHODS, FilterConfig
from fusion.estimate import (
    AidingStatus,
    AirDataStatus,
    AlignmentStatus,
    Health,
    HealthCounters,
    Mode,
    NavEstimate,
    TestRatios,
    new_estimate,
)
from fusion.filter_state import FilterState
from fusion.nominal import NominalState, initial_nominal, with_baro_bias, with_ins
from fusion.outage import OutageBridging
from fusion.rotations import euler_from_quat
from fusion.samples import (
    ActuatorSample,
    AirspeedSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    RpmSample,
    Sample,
)
from fusion.screening import SampleScreen
from fusion.strapdown import InsState
from fusion.thermal.link import ThermalLink, ThermalStatus
from physconst.isa import pressure_altitude_m

__all__ = ["Health", "NavEstimate", "NavFilter"]  # the filter, its output and counters

FloatArray = NDArray[np.float64]
_ZERO3 = (0.0, 0.0, 0.0)
_ins_update = strapdown.update
_increments = strapdown.increments
_increments_scaled = strapdown.increments_scaled
_increments_compensated = strapdown.increments_compensated
_with_ins = with_ins
_tuple_new = tuple.__new__
_with_baro_bias = with_baro_bias
_GNSS, _BRIDGING, _FREE = Mode.GNSS, Mode.BRIDGING, Mode.FREE_INERTIAL
_DEAD_RECKONING = Mode.DEAD_RECKONING


class NavFilter(FilterState):
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
        cfg = config if config is not None else FilterConfig()
        self.bridge: Bridge = bridge if bridge is not None else NoBridge()
        method = cfg.altitude.method
        if method not in ALTITUDE_METHODS:  # model_copy(update=...) skips pydantic's check
            raise ValueError(
                f"unknown altitude method {method!r}; valid methods: {', '.join(ALTITUDE_METHODS)}"
            )
        super().__init__(cfg)
        self._scale = self.layout.has_scale_factors
        rc = cfg.rates
        self._out_period_us = round(1e6 / rc.output_rate_hz)
        self._loop_alt = method != "ekf"
        # air data: fused only with the layout's air-data block and air data enabled
        self._air_on = self.layout.has_air and cfg.airspeed.enabled
        self._air_period_us = round(
            1e6 / max(cfg.airspeed.fuse_rate_hz, cfg.airspeed.sideslip_rate_hz))
        self._handlers: dict[type, Callable[[Any], list[NavEstimate]]] = {}
        self.reset()

    # ------------------------------------------------------------------ public API
    def reset(self, *, keep_counters: bool = False) -> None:
        """Forget everything learned: back to ``initializing`` (configuration kept; the health
        counters too with ``keep_counters``)."""
        cfg, lay = self.config, self.layout
        self._restart_state(self._c if keep_counters else HealthCounters())
        self._screen = SampleScreen(cfg.imu, self._c)
        self._history_push = self._history.push
        self._pending: deque[GnssFix] = deque()
        self._screen_imu = self._screen.imu
        self._gnss = GnssAiding(cfg.gnss, lay, self._c, self._correct)
        self._gnss_ctl = self._gnss.control
        self._baro = BaroAiding(cfg.baro, lay, self._c, self._correct, self._init_baro_bias)
        self._mag = MagAiding(cfg.mag, lay, self._c, self._correct)
        self._zero: ZeroMotionAiding | None = (
            ZeroMotionAiding(cfg.zero_motion, cfg.imu, lay, self._c, self._correct)
            if cfg.zero_motion.enabled else None
        )  # fmt: skip
        self._pseudo = PseudoGnssAiding(cfg.gnss, lay, self._correct)
        self._air: AirspeedAiding | None = (
            AirspeedAiding(cfg.airspeed, lay, self._c, self._correct, self._current_covariance,
                           self._activate_air, self._velocity_corrections,
                           self.bridge.airspeed_model, self.bridge.wind_model,
                           self.bridge.pitot_model)
            if self._air_on else None
        )  # fmt: skip
        self._learns_airspeed = self._air is not None and self._air.model is not None
        self._air_link = AirDataLink(self._air_period_us)
        self._alt = AltitudeLink(cfg.altitude, cfg.gnss.lever_arm_b_m, self._c)
        self._outage = OutageBridging(self.bridge, cfg.bridge.rate_hz, self._epoch)
        self._virtual = self._outage.virtual_outages  # the IMU path's view of it
        self._aligner: InFlightAlignment | StaticAlignment | AutoAlignment = (
            InFlightAlignment(cfg.init, cfg.gnss) if cfg.init.mode == "in_flight"
            else StaticAlignment(cfg.init, cfg.gnss, cfg.mag, cfg.imu)
            if cfg.init.mode == "static" else AutoAlignment(cfg)
        )  # fmt: skip
        self.alignment_method: str | None = None
        self._align_status: AlignmentStatus | None = None
        self._next_out_us = 0
        self._timeout_us = round(cfg.gnss.outage_timeout_s * 1e6)
        # the estimate's immutable parts, rebuilt from the sources' status only when an update
        # happened
        self._est_ratios = TestRatios()
        self._est_aiding = AidingStatus()
        model = self.bridge.thermal_model
        self._thermal = (
            ThermalLink(cfg.thermal, lay, self._c, model)
            if cfg.thermal.mode != "off" or model is not None else None
        )  # fmt: skip

    def step(self, sample: Sample) -> list[NavEstimate]:
        """Process one sample of any kind (in time order per sensor).

        Parameters
        ----------
        sample : fusion.samples.Sample
            Anything with the attributes of one of the :mod:`fusion.samples` protocols.

        Returns
        -------
        list of NavEstimate
            Estimates due at the output rate (empty for most samples and before alignment).

        Raises
        ------
        TypeError
            If ``sample`` matches none of the sample kinds.
        """
        if self._innovations:
            self._innovations = []
        handler = self._handlers.get(type(sample))
        if handler is None:
            handler = self._classify(sample)
        return handler(sample)

    def estimate(self) -> NavEstimate | None:
        """The current estimate (``None`` before alignment)."""
        if self._nom is None:
            return None
        return self._make_estimate()

    @property
    def mode(self) -> Mode:
        """``initializing`` | ``gnss`` | ``free-inertial`` | ``dead-reckoning`` |
        ``bridging``."""
        if self._nom is None:
            return Mode.INITIALIZING
        return self._mode(self._t_us)

    def _mode(self, t: int) -> Mode:
        if self._gnss_ctl.is_active(t):
            return _GNSS
        if self._outage.active:
            return _BRIDGING
        air = self._air
        return _DEAD_RECKONING if air is not None and air.is_fusing(t) else _FREE

    @property
    def wind_ne_mps(self) -> tuple[float, float] | None:
        """Wind estimate North, East (m/s); ``None`` while the air-data states are dormant
        or absent."""
        air = self._air
        if air is None or not air.state.active:
            return None
        return air.state.wind_ne_mps

    @property
    def air_data(self) -> AirDataStatus:
        """The air-data status (``off`` without air-data states or with air data disabled)."""
        air = self._air
        return AIR_OFF if air is None else air.status(self._t_us)

    @property
    def thermal_status(self) -> ThermalStatus | None:
        """The IMU thermal strategy's state (``None`` with ``--thermal off`` and no learned
        thermal model)."""
        thermal = self._thermal
        return None if thermal is None else thermal.status()

    @property
    def bridge_status(self) -> BridgeStatus:
        """The bridging strategy's status."""
        return self.bridge.status

    @property
    def virtual_outage_states(self) -> list[InsState | None]:
        """The states of the virtual-outage INS copies (empty when the strategy asks for
        none)."""
        copies = self._outage.virtual_outages
        return [] if copies is None else copies.states

    @property
    def altitude_channel(self) -> AltitudeChannel | None:
        """The altitude channel of a loop method (``None`` for ``ekf`` or before it started)."""
        return self._alt.channel

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
        accel_bias_b_mps2: ArrayLike | None = None,
        gyro_bias_b_rps: ArrayLike | None = None,
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
        accel_bias_b_mps2, gyro_bias_b_rps : array_like, shape (3,), optional
            Initial bias estimates, m/s^2 and rad/s (default zero).
        baro_bias_m : float, optional
            Initial baro bias; default: set from the first baro sample.
        """
        n = self.layout.n
        state = InsState.from_arrays(lat_rad, lon_rad, alt_msl_m, v_ned_mps, q_nb)
        if covariance is None:
            cov = np.diag(initial_variances(self.layout, self.config))
        else:
            cov = np.asarray(covariance, dtype=float)
            if cov.shape == (n,):
                cov = np.diag(cov)
            if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
                raise ValueError(f"covariance must be finite with shape ({n},) or ({n}, {n})")
        biases = (("accel_bias_b_mps2", accel_bias_b_mps2), ("gyro_bias_b_rps", gyro_bias_b_rps))
        for name, b in biases:
            if b is not None and np.asarray(b, dtype=float).shape != (3,):
                raise ValueError(f"{name} must have shape (3,)")
        self._start(int(time_us), state, cov)
        nom = self._nom
        assert nom is not None
        if accel_bias_b_mps2 is not None:
            nom = nom._replace(accel_bias_b_mps2=_floats3(accel_bias_b_mps2))
        if gyro_bias_b_rps is not None:
            nom = nom._replace(gyro_bias_b_rps=_floats3(gyro_bias_b_rps))
        if baro_bias_m is not None:
            # the INS height is the scale factor's reference height
            nom = nom._replace(baro_bias_m=float(baro_bias_m),
                               baro_reference_alt_m=float(state.alt_msl_m))  # fmt: skip
            self._baro.control.on_bias_init()
        self._nom = nom
        self.alignment_method = "given"
        self._align_status = None

    def default_initial_variances(self) -> FloatArray:
        """Initial error variances (n,) from ``InitConfig`` and the sensor sigmas (what
        :meth:`initialize` uses when no covariance is given)."""
        return initial_variances(self.layout, self.config)

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
        elif hasattr(sample, "diff_pressure_pa"):
            handler = self._on_airspeed
        elif hasattr(sample, "controls"):
            handler = self._on_controls
        elif hasattr(sample, "rpm"):
            handler = self._on_rpm
        else:
            raise TypeError(
                f"{type(sample).__name__} is not an IMU, GNSS, baro or magnetometer sample"
            )
        self._handlers[type(sample)] = handler
        return handler

    # ------------------------------------------------------------------ IMU
    def _on_imu(self, s: ImuSample) -> list[NavEstimate]:
        thermal = self._thermal
        if thermal is not None:
            s = thermal.pre(s)  # screened; calibrated with cal
        step = self._screen_imu(s)
        if step is None:
            if self._screen.rebase_pending:
                return self._rebase(s)
            return []
        t, dt, fw, good, gap = step
        nom0 = self._nom
        if gap:
            if nom0 is None:
                return []
            self._coast(t, dt)
            nom = self._nom
            assert nom is not None
            self._alt.coast(nom.ins.alt_msl_m, dt)
            return self._outputs(t)
        if nom0 is None:
            if good:
                self._aligner.add_imu(t, dt, fw[:3], fw[3:])
                self._try_align()
            return []
        ins0 = nom0.ins
        ba, bg = nom0.accel_bias_b_mps2, nom0.gyro_bias_b_rps
        if self._misalign:
            dth, dv = _increments_compensated(fw, dt, ba, bg, self._ta_inv, self._tg_inv)
            self._cov.accumulate_body(dth, dv)
        elif self._scale:
            dth, dv = _increments_scaled(fw, dt, ba, bg, nom0.accel_scale_b, nom0.gyro_scale_b)
            self._cov.accumulate_body(dth, dv)
        else:
            dth, dv = _increments(fw, dt, ba, bg)
        ins = _ins_update(ins0, dth, dv, self._prev_dth, self._prev_dv, dt)
        # fusion.nominal.with_ins, inlined (every IMU sample)
        nom = self._nom = _tuple_new(NominalState, (ins,) + nom0[1:])  # noqa: RUF005
        self._prev_dth = dth
        self._prev_dv = dv
        self._last_dt = dt
        self._t_us = t
        virtual = self._virtual
        if virtual is not None:  # fusion.bridging.virtual_outages.VirtualOutageBank
            virtual.step(t, ins, dth, dv, dt, ba, bg)
        cov = self._cov
        acc_dt = cov.acc_dt + dt
        cov.acc_dt = acc_dt
        if acc_dt >= self._cov_period_s - 1e-9:  # as _propagate, one call less on the hot path
            self._nom = _with_baro_bias(nom, nom.baro_bias_m * cov.propagate(ins))
        if not good:
            # integrated from the last good sample: the sensors did not see this interval
            cov.add_unknown_motion(dt)
        if thermal is not None:  # the bias moves with the die temperature
            self._nom = thermal.move_bias(self._nom, self._gnss_ctl.is_active(t), t, self._cov)
        self._history_push(t, ins)
        zero = self._zero
        if zero is not None and good:
            zero.on_imu(t, fw, dt, ins, bg)
        if self._loop_alt:
            self._alt.on_imu(t, dt, ins0.v_ned_mps[2], ins)
        if self._pending and self._pending[0].time_us <= t:
            self._drain_pending()
        return self._outputs(t)

    def _outputs(self, t: int) -> list[NavEstimate]:
        """Outage bookkeeping, bridging epochs and the output clock (after every IMU epoch)."""
        outage = self._outage
        last_fused = self._gnss_ctl.last_fused_us
        if not outage.in_outage and last_fused is not None and t - last_fused > self._timeout_us:
            self._c.gnss_outages += 1
            nom = self._nom
            assert nom is not None
            outage.begin(t, nom.ins, nom.accel_bias_b_mps2, nom.gyro_bias_b_rps, self._prev_dth,
                         self._prev_dv)  # fmt: skip
        if outage.in_outage and t >= outage.next_us:
            self._bridge_step(t)
        air_link = self._air_link
        if t >= air_link.next_us:
            air_link.advance(t)
            self._air_tick(t)
        if t >= self._next_out_us:
            self._next_out_us += self._out_period_us
            if self._next_out_us <= t:
                self._next_out_us = t + self._out_period_us
            return [self._make_estimate()]
        return []

    def _coast(self, t: int, gap_s: float) -> None:
        """IMU data missing for ``gap_s``: constant-velocity dead reckoning, covariance grown by
        the process model over the gap, coning/sculling memory cleared."""
        self._flush()
        nom = self._nom
        assert nom is not None
        ins = nom.ins
        virtual = self._outage.virtual_outages
        if virtual is not None:  # the INS copies cannot mechanise a gap either: restart
            virtual.restart(t)
        coasted = strapdown.coast(ins, gap_s)
        bb = nom.baro_bias_m
        for k in self._cov.coast(coasted, ins.v_ned_mps, gap_s):
            bb *= k
        self._nom = _with_baro_bias(_with_ins(nom, coasted), bb)
        self._prev_dth = self._prev_dv = _ZERO3
        self._t_us = t
        self._history.push(t, coasted)
        if self._pending:
            self._drain_pending()

    # ------------------------------------------------------------------ alignment
    def _try_align(self) -> None:
        res = self._aligner.poll()
        if res is not None:
            self._start_from_alignment(res)

    def _rebase(self, s: ImuSample) -> list[NavEstimate]:
        """A confirmed new IMU time base the INS cannot coast into (a step back, a long gap):
        re-initialise everything but the counters and start again from this sample."""
        self.reset(keep_counters=True)
        self._c.time_rebases += 1
        return self._on_imu(s)

    def _start_from_alignment(self, res: AlignmentResult) -> None:
        self._start(res.time_us, res.state, aligned_covariance(self.layout, self.config, res))
        self.alignment_method = res.method

    @property
    def alignment_state(self) -> str:
        """What the alignment is doing, in words: before alignment what it waits for, after
        it the method and whether the rest updates (fine alignment) run."""
        if self._nom is None:
            aligner = self._aligner
            if isinstance(aligner, AutoAlignment):
                return aligner.state
            return f"waiting ({self.config.init.mode})"
        status = self._alignment_status()
        return f"aligned: {status.method}" + (", at rest (fine alignment)"
                                             if status.at_rest else "")

    def _alignment_status(self) -> AlignmentStatus:
        zero = self._zero
        at_rest = zero is not None and zero.detector.still
        status = self._align_status
        if status is None or status.at_rest != at_rest:
            status = self._align_status = AlignmentStatus(self.alignment_method or "given",
                                                          at_rest)
        return status

    def _start(self, time_us: int, state: InsState, cov: FloatArray) -> None:
        # a start from a known state on a running filter keeps its sensor-error estimates;
        # the GNSS bias restarts at zero
        prev = self._nom
        if prev is None:
            self._nom = initial_nominal(state, time_us)
        else:
            self._nom = prev._replace(ins=state, gnss_bias_ned_m=_ZERO3, gnss_bias_time_us=time_us)
        self._t_us = time_us
        screen = self._screen
        if screen.last_imu_us is None or screen.last_imu_us < time_us:
            screen.last_imu_us = time_us
        self._cov.restart(cov, state.v_ned_mps)
        self._prev_dth = self._prev_dv = _ZERO3
        self._history.clear()
        self._history.push(time_us, state)
        self._gnss.control.start(time_us)
        self._next_out_us = time_us
        if self._thermal is not None:
            self._thermal.start()
        self._outage.restart()
        self._alt.restart()  # a (re)start also restarts the altitude channel
        air = self._air
        if air is not None:  # the air-data block starts dormant (the covariance restarted)
            air.state.active = False
            self._air_link.start(time_us)

    def _air_tick(self, t: int) -> None:
        """The air-data epoch (every ``1 / AirspeedTuning.sideslip_rate_hz``, or the TAS rate
        if faster)."""
        air, nom, link = self._air, self._nom, self._air_link
        assert air is not None and nom is not None
        ins = nom.ins
        p, temp = link.static_air(ins)
        cov = self._cov
        inputs = link.model_inputs(t, ins, cov.f_n, p, temp) if self._learns_airspeed else None
        if air.state.active:  # the nominal gust decays as its error did
            self._flush()
            air.state.decay(cov.take_gust_decay())
        gnss = self._gnss_ctl.is_active(t)
        air.tick(t, ins, self._past_state, p, temp, gnss, inputs)
        if air.state.active and self._nom is not None:
            cov.airspeed_mps = air.air_speed_mps(self._nom.ins.v_ned_mps)
        cov.gust_sigma_mps = air.turbulence.sigma_mps
        cov.air_noise = air.noise_factors(gnss, t)
        link.status = air.status(t)

    # ------------------------------------------------------------------ GNSS
    def _on_gnss(self, fix: GnssFix) -> list[NavEstimate]:
        t = self._screen.order("gnss", fix.time_us)
        if t is None or not self._gnss.usable(fix):
            return []
        if self._ins is None:
            self._aligner.add_fix(fix)
            self._try_align()
            return []
        if t > self._t_us:
            self._pending.append(fix)
            return []
        self._fuse_gnss(fix, t)
        return []

    def _drain_pending(self) -> None:
        while self._pending and self._pending[0].time_us <= self._t_us:
            self._fuse_gnss(self._pending.popleft(), self._t_us)

    def _fuse_gnss(self, fix: GnssFix, step_us: int) -> None:
        gnss = self._gnss
        t = int(fix.time_us)
        now = self._t_us
        past = gnss.admit(t, now, self._past_state(t))
        if past is None:
            return
        sigmas = fix_sigmas(fix, gnss.cfg)
        delay = (now - t) * 1e-6
        bias = self._gnss_bias() if self.layout.has_gnss_bias else None
        ins_pre_pos = self._ins  # for the virtual-outage INS errors
        pos = gnss.fuse_position(fix, sigmas, past, delay, bias, step_us, self._reset_position)
        if pos is None:
            return
        past = self._past_state(t)
        assert past is not None and self._ins is not None
        if pos.accepted and self._loop_alt:
            self._alt.on_gnss_height(fix, past, self._ins, sigmas[1], self._t_us)
        ins_pre_vel = self._ins
        vel = gnss.fuse_velocity(fix, sigmas, past, self._omega_b(), pos, step_us,
                                 self._reset_velocity)  # fmt: skip
        if vel is None:
            return
        outage = self._outage
        outage.on_fix(t, past, ins_pre_pos, ins_pre_vel, pos.accepted, vel.accepted,
                      pos.innovation, vel.innovation)  # fmt: skip
        if outage.in_outage and gnss.control.is_active(now):
            outage.end(now, self._epoch(now, self._ins))

    # ------------------------------------------------------------------ bridging
    def _epoch(self, time_us: int, state: InsState) -> BridgeEpoch:
        nom = self._nom
        assert nom is not None
        ba, bg = nom.accel_bias_b_mps2, nom.gyro_bias_b_rps
        virtual = self._outage.virtual_outages
        return BridgeEpoch(
            time_us=time_us,
            lat_rad=state.lat_rad,
            lon_rad=state.lon_rad,
            alt_msl_m=state.alt_msl_m,
            v_ned_mps=state.v_ned_mps,
            euler_rad=euler_from_quat(state.q_nb),
            f_n_mps2=self._cov.f_n,
            omega_ib_b_rps=self._omega_b(),
            time_since_gnss_s=max(0.0, self._gnss.control.time_since_fused_s(time_us)),
            accel_bias_b_mps2=(ba[0], ba[1], ba[2]),
            gyro_bias_b_rps=(bg[0], bg[1], bg[2]),
            free_state=None if virtual is None else virtual.free_state,
        )

    def _bridge_step(self, t: int) -> None:
        ins = self._ins
        assert ins is not None
        outage = self._outage
        action = outage.consult(t, self._epoch(t, ins))
        if action is None:
            return
        if isinstance(action, OutputCorrection):
            outage.correction = action
            outage.active = True
            self._c.bridge_updates += 1
        elif isinstance(action, PseudoGnss):
            self._pseudo.fuse_position(action, ins, t)
            ins = self._ins
            assert ins is not None
            self._pseudo.fuse_velocity(action, ins, self._omega_b(), t)
            outage.active = True
            self._c.bridge_updates += 1

    # ------------------------------------------------------------------ baro, mag
    def _on_baro(self, s: BaroSample) -> list[NavEstimate]:
        t = self._screen.order("baro", s.time_us)
        if t is None:
            return []
        baro = self._baro
        p = baro.pressure(s)
        if p is None:
            return []
        h_baro = pressure_altitude_m(p)
        ins = self._ins
        if ins is None:
            return []
        self._air_link.on_static(p, getattr(s, "temperature_k", None))  # the air density
        alt = self._alt
        if not (alt.screen_baro(s, p, t, self._t_us) and alt.repeat_ok(p, t)):
            return []
        batch = baro.control.add_sample(t, h_baro)
        if batch is None:
            return []
        past = self._past_state(batch[0])
        if past is None:
            past = ins
        nom = self._nom
        assert nom is not None
        baro.fuse(batch, past.alt_msl_m, nom.baro_bias_m, t, nom.baro_scale,
                  nom.baro_reference_alt_m)  # fmt: skip
        return []

    def _on_airspeed(self, s: AirspeedSample) -> list[NavEstimate]:
        t = self._screen.order("airspeed", s.time_us)
        if t is None:
            return []
        air = self._air
        if air is None:  # air data off, or a layout without the air-data block
            self._c.airspeed_ignored += 1
            return []
        if self._ins is None:
            return []
        air.add_sample(s, t)
        return []

    # the latest controls and propeller speed: inputs of a learned vehicle model
    def _on_controls(self, s: ActuatorSample) -> list[NavEstimate]:
        self._air_link.on_controls(s)
        return []

    def _on_rpm(self, s: RpmSample) -> list[NavEstimate]:
        self._air_link.on_rpm(s)
        return []

    def _on_mag(self, s: MagSample) -> list[NavEstimate]:
        t = self._screen.order("mag", s.time_us)
        if t is None:
            return []
        mag = self._mag
        field = mag.field(s)
        if field is None:
            return []
        if self._ins is None:
            self._aligner.add_mag(t, np.array(field))
            self._try_align()
            return []
        mag.fuse(field, t, self._ins, self._yaw_sigma)
        return []

    def _yaw_sigma(self) -> float:
        self._flush()
        a = self.layout.ATT + 2
        return math.sqrt(self._cov.P[a, a])

    # ------------------------------------------------------------------ output
    def _make_estimate(self) -> NavEstimate:
        # runs at the output rate (50 Hz default): no per-call dataclass __init__ where a
        # cached immutable part or the slot setters (new_estimate) do
        nom = self._nom
        assert nom is not None
        lat, lon, alt, v, q = nom.ins
        outage = self._outage
        corr = outage.correction
        if corr is not None:
            lt = earth.local_terms(lat, alt)
            dn, de, dd = corr.pos_ned_m
            lat -= dn / lt.rho_n_m
            lon -= de / (lt.rho_e_m * lt.cos_lat)
            alt += dd
            cv = corr.vel_ned_mps
            v = (v[0] - cv[0], v[1] - cv[1], v[2] - cv[2])
        vertical = self._alt.vertical() if self._loop_alt else None
        if vertical is not None:
            # loop methods: the vertical is the altitude channel's (it supersedes the EKF's
            # and any bridging correction's vertical)
            alt, vz = vertical
            v = (v[0], v[1], -vz)
        # one read-only array, the vector fields are views of it
        buf = np.array((*v, *q, *euler_from_quat(q), *nom.accel_bias_b_mps2, *nom.gyro_bias_b_rps,
                        *self._omega_b()))  # fmt: skip
        buf.setflags(write=False)
        P = self._cov.P
        p_diag = P.diagonal().copy()
        p_diag.setflags(write=False)
        p_nav = P[:9, :9].copy()
        p_nav.setflags(write=False)
        if self._aid_changed:
            aid = self._aid  # AidSource order: GNSS_POS, GNSS_VEL, BARO_HGT, MAG_HDG, ...
            self._est_ratios = TestRatios(
                aid[0].test_ratio, aid[1].test_ratio, aid[2].test_ratio, aid[3].test_ratio,
                aid[6].test_ratio,
            )
            self._est_aiding = AidingStatus(*aid)
            self._aid_changed = False
        t = self._t_us
        gctl = self._gnss_ctl
        mode = self._mode(t)
        return new_estimate(
            t, lat, lon, alt,
            buf[0:3], buf[3:7], buf[7:10],  # v_ned_mps, q_nb, euler_rad
            p_diag, mode,
            buf[10:13], buf[13:16],  # accel_bias_b_mps2, gyro_bias_b_rps
            nom.baro_bias_m,
            self._c.snapshot(), self._est_ratios,
            gctl.time_since_fused_s(t), self.layout.name,
            self._alt.status(), self.bridge.status, self._est_aiding, p_nav, self._air_link.status,
            buf[16:19],  # omega_b_rps
            self._alignment_status(),
        )  # fmt: skip


def _floats3(a: ArrayLike) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in np.asarray(a, dtype=float))
    return x, y, z
