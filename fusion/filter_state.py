"""The state of :class:`fusion.filter.NavFilter` and the one way it changes by a measurement.

:class:`FilterState` holds what the filter knows (the nominal state
:class:`~fusion.nominal.NominalState`, the error covariance and its propagator, the INS
history for delayed measurements) and the measurement-update funnel every aiding source goes
through: a chi-square gated Joseph-form update (:mod:`fusion.kalman`) whose accepted error
estimate is fed back into the nominal state at once (:mod:`fusion.feedback`), the resets to a
measurement, and the record of each update (:attr:`FilterState.innovations`, the aiding status
of the estimate). *When* each source is fused, the time update and the output are
:class:`~fusion.filter.NavFilter`'s (its subclass), which also owns the aiding sources.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion import kalman
from fusion.aiding import Observation
from fusion.aiding.airspeed import AirspeedAiding
from fusion.config import FilterConfig
from fusion.error_model import ErrorModel
from fusion.estimate import (
    AidSource,
    AidSourceStatus,
    Health,
    HealthCounters,
    Innovation,
    new_innovation,
)
from fusion.feedback import (
    feedback,
    nav_corrections,
    reset_baro_bias,
    reset_block,
    reset_position_with_bias,
    sensor_inverses,
)
from fusion.history import InsHistory, span_capacity
from fusion.nominal import NominalState, with_baro_bias
from fusion.propagation import CovariancePropagator, decay_gnss_bias
from fusion.state_layout import StateLayout, layout_for, with_thermal
from fusion.strapdown import InsState
from fusion.thermal.link import ThermalLink

FloatArray = NDArray[np.float64]
_ZERO3 = (0.0, 0.0, 0.0)
_IDENTITY9: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
_with_baro_bias = with_baro_bias
_AID_INDEX = {s: i for i, s in enumerate(AidSource)}


class FilterState:
    """The filter's state and its measurement-update funnel (module docstring).

    Parameters
    ----------
    config : FilterConfig
    """

    _air: AirspeedAiding | None
    """The air-data aiding source (the subclass's), whose wind and gust estimates the
    feedback corrects too."""

    def __init__(self, config: FilterConfig) -> None:
        self.config = config
        layout = layout_for(config.state_layout)
        self.layout: StateLayout = (
            with_thermal(layout) if config.thermal.mode == "states" else layout
        )
        self._thermal: ThermalLink | None = None  # the subclass's, when a strategy needs it
        self._model = ErrorModel(self.layout, config.process_noise())
        self._misalign = self.layout.has_misalignment
        self._gnss_bias_states = self.layout.has_gnss_bias
        self._x0 = np.zeros(self.layout.n)
        rc = config.rates
        self._cov_period_s = 0.0 if rc.covariance_rate_hz is None else 1.0 / rc.covariance_rate_hz

    def _restart_state(self, counters: HealthCounters) -> None:
        """Forget everything the state holds (the configuration stays); count in
        ``counters``."""
        cfg = self.config
        self._c = counters
        self._cov = CovariancePropagator(self._model, self._cov_period_s, cfg.imu,
                                         cfg.baro.bias_tau_s)  # fmt: skip
        # the INS and the sensor-error estimates (None before alignment); the GNSS bias in it
        # is decayed with its Gauss-Markov time constant only when used (_gnss_bias), not on
        # the IMU path
        self._nom: NominalState | None = None
        self._t_us = 0
        self._prev_dth: tuple[float, float, float] = _ZERO3
        self._prev_dv: tuple[float, float, float] = _ZERO3
        self._last_dt = 0.0
        # the sensor-model inverses of the misalignment layouts, kept with the estimates
        self._ta_inv: tuple[float, ...] = _IDENTITY9
        self._tg_inv: tuple[float, ...] = _IDENTITY9
        self._history = InsHistory(span_capacity(cfg.gnss.max_delay_s))
        self._vel_corr = [0.0, 0.0, 0.0]  # sum of the feedback's velocity corrections, m/s
        # the updates of the current step, and each source's status (in AidSource order)
        self._innovations: list[Innovation] = []
        self._aid = [AidSourceStatus(s) for s in AidSource]
        self._aid_changed = True

    def _propagate(self) -> None:
        """Covariance over the accumulated interval; decay of the baro-bias estimate."""
        nom = self._nom
        assert nom is not None
        self._nom = _with_baro_bias(nom, nom.baro_bias_m * self._cov.propagate(nom.ins))

    def _flush(self) -> None:
        if self._cov.acc_dt > 0.0 and self._nom is not None:
            self._propagate()

    def _correct(
        self, obs: Observation, gate: float, source: AidSource, time_us: int
    ) -> kalman.Correction:
        """The single update funnel: gated Joseph-form update; on acceptance the error
        estimate is fed back at once. Records the :class:`~fusion.estimate.Innovation` and
        the source's status."""
        self._flush()
        cov = self._cov
        res = kalman.correct(self._x0, cov.P, obs.z, obs.H, obs.R, gate)
        fused = res.test_ratio <= 1.0
        if fused:
            cov.P = res.P
            self._feedback(res.x)
        inn = new_innovation(time_us, source, res.innovation, res.S, res.test_ratio, fused)
        self._innovations.append(inn)
        aid, i = self._aid, _AID_INDEX[source]
        aid[i] = aid[i].after(inn)
        self._aid_changed = True
        return res

    def _feedback(self, dx: FloatArray) -> None:
        """Move the error estimate into the INS and the sensor-error estimates."""
        if self._gnss_bias_states:
            self._gnss_bias()  # the estimate the error refers to is the current one
        nom = self._nom
        assert nom is not None
        lay = self.layout
        nom = self._nom = feedback(lay, nom, dx)
        d = dx.tolist()
        air = self._air
        if air is not None and air.state.active:
            air.state.correct(d, lay)
        therm = self._thermal
        if therm is not None and lay.has_thermal:
            therm.correct_tempco(d)
        if self._misalign:
            self._ta_inv, self._tg_inv = sensor_inverses(
                nom.accel_scale_b, nom.accel_misalignment_b, nom.gyro_scale_b,
                nom.gyro_misalignment_b)  # fmt: skip
        nav_dx = nav_corrections(lay, d)
        self._history.add_correction(nav_dx)
        vc = self._vel_corr
        vc[0] -= nav_dx[3]
        vc[1] -= nav_dx[4]
        vc[2] -= nav_dx[5]
        self._cov.v0 = nom.ins.v_ned_mps

    def _reset_velocity(self, z: FloatArray, variances: FloatArray) -> None:
        """Velocity reset to the fix (``z`` its velocity innovation)."""
        self._flush()
        dx, P = reset_block(self._cov.P, self.layout.n, self.layout.vel, z, variances)
        self._feedback(dx)
        self._cov.P = P

    def _reset_position(self, z: FloatArray, variances: FloatArray) -> None:
        """Position reset to the fix (``z`` its position innovation, ``variances`` the white
        part); with the GNSS bias states the bias goes back to its prior
        (:func:`fusion.feedback.reset_position_with_bias`)."""
        self._flush()
        lay = self.layout
        if not lay.has_gnss_bias:
            dx, P = reset_block(self._cov.P, lay.n, lay.pos, z, variances)
        else:
            g = self.config.gnss
            sb2 = np.array([g.bias_sigma_h_m**2] * 2 + [g.bias_sigma_v_m**2])
            dx, P = reset_position_with_bias(self._cov.P, lay, z, variances, self._gnss_bias(),
                                             sb2)  # fmt: skip
        self._feedback(dx)
        self._cov.P = P

    def _current_covariance(self) -> FloatArray:
        """The covariance propagated to the current time (read-only use)."""
        self._flush()
        return self._cov.P

    def _velocity_corrections(self) -> tuple[float, float, float]:
        """Sum of every velocity correction the feedback made (new minus old), m/s NED."""
        vc = self._vel_corr
        return (vc[0], vc[1], vc[2])

    def _activate_air(
        self, wind_ne_mps: tuple[float, float], wind_variance: float, scale_variance: float
    ) -> None:
        """Start the air-data block: mean-wind and scale estimates with uncorrelated variances,
        no gust (its steady-state variance), their process noise from now on."""
        self._flush()
        lay, air = self.layout, self._air
        assert air is not None
        w, g = lay.WIND, lay.GUST
        P = self._cov.P.copy()
        P[lay.air, :] = 0.0
        P[:, lay.air] = 0.0
        P[w, w] = P[w + 1, w + 1] = wind_variance
        P[w + 2, w + 2] = scale_variance
        P[g, g] = P[g + 1, g + 1] = air.turbulence.sigma_mps**2
        cov = self._cov
        cov.P = P
        cov.air_offset = w
        cov.take_gust_decay()
        air.state.start(wind_ne_mps)
        if self._nom is not None:
            cov.airspeed_mps = air.air_speed_mps(self._nom.ins.v_ned_mps)

    def _init_baro_bias(self, bias_m: float, reference_alt_m: float) -> None:
        """``b^ = h_baro - h^`` at the INS height ``reference_alt_m``, from then on the baro
        scale factor's reference (:func:`fusion.feedback.reset_baro_bias`)."""
        self._flush()
        nom = self._nom
        assert nom is not None
        self._nom = nom._replace(baro_bias_m=bias_m, baro_reference_alt_m=reference_alt_m)
        self._cov.P = reset_baro_bias(self._cov.P, self.layout, self.config.baro.noise_m)

    def _gnss_bias(self) -> tuple[float, float, float]:
        """The GNSS position-bias estimate (NED, m) decayed to the current time (and kept so
        in the nominal state)."""
        nom = self._nom
        assert nom is not None
        dt = (self._t_us - nom.gnss_bias_time_us) * 1e-6
        if dt > 0.0:
            g = self.config.gnss
            b = decay_gnss_bias(nom.gnss_bias_ned_m, dt, g.bias_tau_h_s, g.bias_tau_v_s)
            nom = self._nom = nom._replace(gnss_bias_ned_m=b, gnss_bias_time_us=self._t_us)
        return nom.gnss_bias_ned_m

    @property
    def _ins(self) -> InsState | None:
        """The INS state now (``None`` before alignment)."""
        nom = self._nom
        return None if nom is None else nom.ins

    def _past_state(self, time_us: int) -> InsState | None:
        if time_us >= self._t_us:
            nom = self._nom
            return None if nom is None else nom.ins
        return self._history.at(time_us)

    def _omega_b(self) -> tuple[float, float, float]:
        dt = self._last_dt
        if dt <= 0.0:
            return _ZERO3
        a = self._prev_dth
        return (a[0] / dt, a[1] / dt, a[2] / dt)

    @property
    def innovations(self) -> tuple[Innovation, ...]:
        """The gated updates made by the last :meth:`step` call, in order (empty if none)."""
        return tuple(self._innovations)

    @property
    def health(self) -> Health:
        """Counters snapshot."""
        return self._c.snapshot()

    @property
    def ins_state(self) -> InsState | None:
        """The INS state (IMU position, velocity, attitude) at the current time."""
        nom = self._nom
        return None if nom is None else nom.ins

    @property
    def nominal_state(self) -> NominalState | None:
        """The INS state and every sensor-error estimate at the current time (``None``
        before alignment; its GNSS bias estimate refers to ``gnss_bias_time_us``)."""
        return self._nom

    @property
    def gnss_bias_ned_m(self) -> tuple[float, float, float] | None:
        """Estimated time-correlated GNSS position error (NED, m) at the current time;
        ``None`` without the GNSS bias states (a layout without ``+gnss``)."""
        if not self.layout.has_gnss_bias:
            return None
        if self._nom is None:
            return _ZERO3
        return self._gnss_bias()

    @property
    def covariance(self) -> FloatArray:
        """Copy of the error-state covariance (propagated to the current time)."""
        self._flush()
        return self._cov.P.copy()

    @property
    def time_us(self) -> int:
        """INS time (0 before alignment)."""
        return self._t_us
