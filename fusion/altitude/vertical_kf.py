"""P4's Kalman comparator: a linear KF (filterpy) on the vertical error model with P4's GNSS
and baro measurements ``z = h − h_GNSS = δh + v`` and ``z = h − H = δh − b + v`` (eq. 18)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from pydantic import PositiveFloat

from fusion.altitude.common import OMEGA_S2, Frozen, check_finite
from fusion.altitude.vertical_model import VerticalErrorModel

FloatArray = NDArray[np.float64]


class VerticalKfConfig(Frozen):
    """P4's Kalman comparator on ``[δVz, δh, b]`` (filterpy ``KalmanFilter``).

    Defaults as chosen on the tuning seeds of ``bench/altitude_jsbsim.py`` (GNSS-calibrated
    baro): ``q_a`` 1e-6 m²/s³, GNSS sigma ×3 (its error is time-correlated), baro fused with a
    near-constant bias (σ 0.5 m, τ 1e5 s). :meth:`p4` is P4's model (Gauss–Markov bias τ 600 s,
    σ 1 m; ``q_a`` 1e-4), with which the KF forgets the bias during a long outage.
    """

    period_s: PositiveFloat = 0.2
    accel_noise_psd: PositiveFloat = 1e-6
    """``q_a``, m²/s³ (covers the loop's model mismatch too: it is a tuning knob)."""
    baro_bias_tau_s: PositiveFloat = 1e5
    baro_bias_sigma_m: PositiveFloat = 0.5
    baro_noise_m: PositiveFloat = 0.3
    """1σ of the baro measurement ``h − H``, m."""
    use_baro: bool = True
    """Fuse P4 eq. 18 ``z = h − H = δh − b + v`` at every period."""
    gnss_sigma_scale: PositiveFloat = 3.0
    initial_sigmas: tuple[PositiveFloat, PositiveFloat, PositiveFloat] = (0.5, 5.0, 1.0)
    """Initial 1σ of ``[δVz, δh, b]`` (m/s, m, m)."""

    @classmethod
    def p4(cls) -> VerticalKfConfig:
        """P4's comparator: Gauss–Markov baro bias τ 600 s, σ 1 m; ``q_a`` 1e-4; GNSS sigma as
        reported."""
        return cls(
            accel_noise_psd=1e-4, baro_bias_tau_s=600.0, baro_bias_sigma_m=1.0, gnss_sigma_scale=1.0
        )


class VerticalKalman:
    """Kalman filter on P4's error model with P4's measurements (filterpy)."""

    def __init__(self, config: VerticalKfConfig | None = None, omega_s2: float = OMEGA_S2):
        self.config = cfg = config or VerticalKfConfig()
        self.model = VerticalErrorModel(
            cfg.baro_bias_tau_s, cfg.baro_bias_sigma_m, cfg.accel_noise_psd, omega_s2
        )
        phi, _, q_d = self.model.discretise(cfg.period_s)
        # Imported here, not at module level: only loop-kf needs filterpy, and importing it
        # costs ~2 s of CPU in every process that imports fusion (the live service included).
        from filterpy.kalman import KalmanFilter

        kf = KalmanFilter(dim_x=3, dim_z=1)
        kf.F = phi
        kf.Q = q_d
        kf.P = np.diag(np.square(cfg.initial_sigmas))
        kf.x = np.zeros((3, 1))
        self.kf = kf
        # z = δh (GNSS) and z = δh − b (baro, P4 eq. 18)
        self._h_gnss = np.array([[0.0, 1.0, 0.0]])
        self._h_baro = np.array([[0.0, 1.0, -1.0]])
        self._r_baro = np.array([[cfg.baro_noise_m**2]])
        self.started = False

    @property
    def delta_h_m(self) -> float:
        """Estimated ``δh``, m."""
        return float(self.kf.x[1, 0])

    @property
    def delta_vz_mps(self) -> float:
        """Estimated ``δVz``, m/s."""
        return float(self.kf.x[0, 0])

    @property
    def baro_bias_m(self) -> float:
        """Estimated ``b``, m."""
        return float(self.kf.x[2, 0])

    def snapshot(self) -> tuple[FloatArray, FloatArray, bool]:
        """The filter's state ``(x, P, started)`` (copies, for :meth:`restore`)."""
        return (self.kf.x.copy(), self.kf.P.copy(), self.started)

    def restore(self, state: tuple[FloatArray, FloatArray, bool]) -> None:
        """Go back to a state taken with :meth:`snapshot`."""
        x, p, self.started = state
        self.kf.x = x.copy()
        self.kf.P = p.copy()

    def predict(self) -> None:
        """Propagate one period."""
        self.kf.predict()

    def update_gnss(self, residual_m: float, sigma_m: float) -> None:
        """Fuse ``z = h − h_GNSS = δh + v`` (m), 1σ ``sigma_m``."""
        check_finite("residual_m", residual_m)
        if not self.started:
            # Start at the first residual (the same warm start the MPC gets).
            self.kf.x[1, 0] = residual_m
            self.started = True
        s = sigma_m * self.config.gnss_sigma_scale
        self.kf.update(np.array([[residual_m]]), R=np.array([[s * s]]), H=self._h_gnss)

    def update_baro(self, residual_m: float) -> None:
        """Fuse ``z = h − H = δh − b + v`` (m)."""
        check_finite("residual_m", residual_m)
        self.kf.update(np.array([[residual_m]]), R=self._r_baro, H=self._h_baro)
