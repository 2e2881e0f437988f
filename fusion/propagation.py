"""Covariance propagation of the error-state filter: ``P <- Phi P Phi^T + Q`` over accumulated
IMU intervals, the growth over an IMU gap, and the Gauss-Markov decay of the bias estimates.

The transition is first order (``Phi = I + F T``, :meth:`fusion.error_model.ErrorModel.
first_order_transition`) at the operating point of the end of the interval, with the mean
specific force of the interval recovered from the INS velocity change (``v' = f + g -
(2 omega_ie + omega_en) × v``). IMU samples are accumulated until ``1 / covariance_rate_hz``
has passed (or every sample). Over an IMU gap (a time jump the INS coasts over at constant
velocity) the covariance is propagated in sub-steps of at most 0.1 s and grown by an assumed
unknown manoeuvre.

The IMU bias, scale-factor and misalignment *estimates* are held, not decayed: a real sensor's
bias is a turn-on constant plus a zero-mean in-run process, and decaying the estimate of the
constant part towards zero (tau ~ 100 s for MEMS datasheets) makes the filter forget what it
learned and fight every GNSS fix. Their covariance is that of a random constant plus a random
walk for the same reason (:mod:`fusion.error_model`). The baro bias and the GNSS position bias
are zero-mean processes: their estimates decay (:meth:`CovariancePropagator.propagate` returns
the baro factor, :func:`decay_gnss_bias`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.config import ImuTuning
from fusion.error_model import ErrorModel
from fusion.rotations import dcm_from_quat
from fusion.strapdown import InsState

FloatArray = NDArray[np.float64]
Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_TWO_RATE = 2.0 * earth.RATE
_dot = np.dot


class CovariancePropagator:
    """The error covariance ``P`` and its time update.

    Parameters
    ----------
    model : ErrorModel
        F, Phi and Q of the layout.
    period_s : float
        Propagation interval (``1 / covariance_rate_hz``; 0: every IMU sample), s.
    imu : ImuTuning
        The unknown manoeuvre assumed over an IMU gap.
    baro_bias_tau_s : float
        Correlation time of the baro bias, s.

    Attributes
    ----------
    P : ndarray, shape (n, n)
        The covariance as of the last propagation (the update funnel replaces it).
    acc_dt : float
        IMU time accumulated since the last propagation, s.
    v0 : 3 floats
        INS velocity at the start of the accumulated interval (or after the last feedback),
        m/s NED.
    f_n : 3 floats
        Mean specific force of the last propagated interval, m/s^2 NED.
    air_offset : int or None
        Offset of the air-data block once the filter activated it (its process noise is
        added from then on, :meth:`fusion.error_model.ErrorModel.air_process_noise`);
        ``None``: dormant or absent.
    airspeed_mps : float
        Air-relative speed that sets the gust correlation time (the filter updates it at
        its air-data epochs), m/s.
    gust_sigma_mps : float
        Gust sigma that drives the gust states (the filter's turbulence estimate, set at its
        air-data epochs), m/s.
    air_noise : tuple of float
        Factors on the level-flight and the climb-driven wind random walk and on the scale
        random walk (1 in turbulence; still air and the outage hold lower them),
        :meth:`fusion.error_model.ErrorModel.air_process_noise`.
    thermal_dt_k : float
        Die-temperature change since the last propagation (``+therm`` layouts: the filter
        adds each accepted change), K.
    gust_decay : float
        Product of the gust decay factors since the filter last took it
        (:meth:`take_gust_decay`): the nominal gust decays with its error.
    """

    def __init__(
        self, model: ErrorModel, period_s: float, imu: ImuTuning, baro_bias_tau_s: float
    ) -> None:
        self.model = model
        self.layout = lay = model.layout
        self.period_s = period_s
        self._scale = lay.has_scale_factors
        self._gap_accel_sigma = imu.gap_accel_sigma_mps2
        self._gap_rate_sigma = imu.gap_rate_sigma_rps
        self._tau_baro = baro_bias_tau_s
        self._decay_cache: dict[float, float] = {}
        n = lay.n
        self.P: FloatArray = np.zeros((n, n))
        self.acc_dt = 0.0
        self.v0: Sequence[float] = _ZERO3
        self._acc_f = [0.0, 0.0, 0.0]
        self._acc_w = [0.0, 0.0, 0.0]
        self.f_n: Vec3 = (0.0, 0.0, -earth.GE)
        self.air_offset: int | None = None
        self.airspeed_mps = 0.0
        self.gust_sigma_mps = model.noise.gust_sigma_mps
        self.air_noise = (1.0, 1.0, 1.0)
        self.gust_decay = 1.0
        self._gust_cache: dict[tuple[float, float, float], tuple[float, float]] = {}
        self._therm = lay.has_thermal
        self.thermal_dt_k = 0.0

    def take_gust_decay(self) -> float:
        """The gust decay since the last call (the nominal gust is multiplied by it)."""
        d, self.gust_decay = self.gust_decay, 1.0
        return d

    def restart(self, cov: FloatArray, v0: Sequence[float]) -> None:
        """Start from covariance ``cov`` (symmetrised) with nothing accumulated."""
        self.P = 0.5 * (cov + cov.T)
        self.air_offset = None  # the air-data block starts dormant
        self.gust_decay = 1.0
        self.acc_dt = 0.0
        self.v0 = v0
        self._acc_f = [0.0, 0.0, 0.0]
        self._acc_w = [0.0, 0.0, 0.0]

    def accumulate_body(self, dtheta_b: Sequence[float], dv_b: Sequence[float]) -> None:
        """Add one IMU interval's compensated increments to the interval means the
        scale-factor blocks need (layouts with scale factors only)."""
        af, aw = self._acc_f, self._acc_w
        af[0] += dv_b[0]
        af[1] += dv_b[1]
        af[2] += dv_b[2]
        aw[0] += dtheta_b[0]
        aw[1] += dtheta_b[1]
        aw[2] += dtheta_b[2]

    def baro_decay(self, dt_s: float) -> float:
        """Gauss-Markov decay factor of the baro-bias estimate over ``dt_s``."""
        k = self._decay_cache.get(dt_s)
        if k is None:
            k = math.exp(-dt_s / self._tau_baro)
            if len(self._decay_cache) < 64:
                self._decay_cache[dt_s] = k
        return k

    def propagate(self, ins: InsState) -> float:
        """``P <- Phi P Phi^T + Q`` over the accumulated interval ending at ``ins``.

        Parameters
        ----------
        ins : InsState
            The INS at the end of the interval.

        Returns
        -------
        float
            The decay factor of the baro-bias estimate over the same interval (the caller
            owns the estimate).
        """
        T = self.acc_dt
        lat, _, h, v, q = ins
        vn, ve, vd = v
        v0n, v0e, v0d = self.v0
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
        self.f_n = f_n
        c_nb = dcm_from_quat(q)
        if self._scale:
            af, aw = self._acc_f, self._acc_w
            f_b = (af[0] / T, af[1] / T, af[2] / T)
            w_b = (aw[0] / T, aw[1] / T, aw[2] / T)
            self._acc_f = [0.0, 0.0, 0.0]
            self._acc_w = [0.0, 0.0, 0.0]
        else:
            f_b = w_b = _ZERO3
        model = self.model
        Phi = model.first_order_transition(lat, h, v, c_nb, f_n, T, f_b, w_b, lt, scratch=True)
        if self._therm:
            # b = b0 + k (T - T_ref): the bias moved by k dT over the interval, so its error
            # by dk dT (every propagation writes these entries of the cached matrix)
            lay, d_t = self.layout, self.thermal_dt_k
            self.thermal_dt_k = 0.0
            for i in range(3):
                Phi[lay.BA + i, lay.KA + i] = d_t
                Phi[lay.BG + i, lay.KG + i] = d_t
        # P = Phi P Phi^T + Q  (Q diagonal: white sensor noise and Gauss-Markov driving noise)
        # (np.dot: the same GEMMs as @, with less dispatch overhead on these small matrices.
        # Phi^T stays a transposed view: a contiguous copy is a little faster at 43 states but
        # its bit identity rests on how one BLAS build tiles its kernel)
        P = _dot(_dot(Phi, self.P), Phi.T)
        a = self.air_offset
        if a is None:
            model.add_process_noise(P, T)
        else:
            # wind random walk driven harder when climbing (the wind changes with height)
            qw, qk = model.air_process_noise(T, vd, *self.air_noise)
            # gusts: first-order Gauss-Markov, decaying with the distance flown through the air
            # (phi and q depend on T, the airspeed and the gust sigma, which change at the
            # air-data epochs only)
            key = (T, self.airspeed_mps, self.gust_sigma_mps)
            gust = self._gust_cache.get(key)
            if gust is None:
                gust = model.gust_transition(T, self.airspeed_mps, self.gust_sigma_mps)
                if len(self._gust_cache) >= 64:
                    self._gust_cache.clear()
                self._gust_cache[key] = gust
            phi, qg = gust
            # P += Q, then the air block's noise and the gusts' decay (in that order)
            model.add_process_noise(P, T, a, qw, qk, phi, qg)
            self.gust_decay *= phi
        self.P = P
        k = self.baro_decay(T)
        self.acc_dt = 0.0
        self.v0 = ins.v_ned_mps
        return k

    def coast(self, ins: InsState, v0: Sequence[float], gap_s: float) -> list[float]:
        """Propagate over an IMU gap of ``gap_s`` the INS coasted over (constant velocity
        ``v0``, ending at ``ins``), then grow ``P`` by the unknown manoeuvre.

        The first-order transition is fine for 10 ms, not for seconds: the gap is propagated
        in sub-steps of at most 0.1 s (at most 100). The sensors did not see what the vehicle
        did meanwhile: position and velocity grow by ``gap_accel_sigma_mps2`` of unknown
        acceleration, attitude by ``gap_rate_sigma_rps`` of unknown rotation.

        Returns
        -------
        list of float
            The baro-bias decay factor of each sub-step, in order.
        """
        n_sub = min(100, max(1, math.ceil(gap_s / 0.1)))
        decays = []
        for _ in range(n_sub):
            self.v0 = v0
            self.acc_dt = gap_s / n_sub
            decays.append(self.propagate(ins))
        self.add_unknown_motion(gap_s)
        return decays

    def add_unknown_motion(self, span_s: float) -> None:
        """Grow ``P`` by ``span_s`` of motion the sensors did not see: position and velocity by
        ``gap_accel_sigma_mps2`` of unknown acceleration, attitude by ``gap_rate_sigma_rps``
        of unknown rotation (an IMU gap, or an interval integrated from a held sample)."""
        lay = self.layout
        sa, sw = self._gap_accel_sigma, self._gap_rate_sigma
        P = self.P.copy()
        idx = np.arange(3)
        P[lay.POS + idx, lay.POS + idx] += (0.5 * sa * span_s * span_s) ** 2
        P[lay.VEL + idx, lay.VEL + idx] += (sa * span_s) ** 2
        P[lay.POS + idx, lay.VEL + idx] += 0.5 * sa * sa * span_s**3
        P[lay.VEL + idx, lay.POS + idx] += 0.5 * sa * sa * span_s**3
        P[lay.ATT + idx, lay.ATT + idx] += (sw * span_s) ** 2
        self.P = P


def decay_gnss_bias(
    bias_ned_m: Sequence[float], dt_s: float, tau_h_s: float, tau_v_s: float
) -> tuple[float, float, float]:
    """The GNSS position-bias estimate ``dt_s`` later: between fixes (and through outages) it
    relaxes to zero as its Gauss-Markov mean does.

    Parameters
    ----------
    bias_ned_m : 3 floats
        Estimate, m NED.
    dt_s : float
        Elapsed time, s (> 0).
    tau_h_s, tau_v_s : float
        Horizontal and vertical correlation times, s.

    Returns
    -------
    tuple of 3 floats
    """
    kh, kv = math.exp(-dt_s / tau_h_s), math.exp(-dt_s / tau_v_s)
    b = bias_ned_m
    return (b[0] * kh, b[1] * kh, b[2] * kv)
