"""P4's vertical error model (eq. 6-9): state ``X = [δVz, δh, b]`` and its exact discretisation.

::

    δV̇z = 2ωs²·δh + u + w_a,    δḣ = δVz,    ḃ = −β·b + sqrt(2βσ²)·w_b

P4 prints the Gauss–Markov driving term in the ``δh`` row of its input matrix (eq. 9), which
contradicts its eq. 7; it belongs in the ``b`` row (:class:`VerticalErrorModel`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from fusion.altitude.common import OMEGA_S2, check_dt, zoh_discretise

FloatArray = NDArray[np.float64]


class VerticalErrorModel:
    """P4's vertical error model, state ``X = [δVz, δh, b]`` (m/s, m, m).

    ``Ẋ = A X + B_u u + G w`` with ``A = [[0, 2ωs², 0], [1, 0, 0], [0, 0, −β]]``,
    ``B_u = [1, 0, 0]ᵀ`` (acceleration input, m/s²), ``G = [[1, 0], [0, 0], [0, 1]]`` and white
    noises of spectral densities ``q_a`` (acceleration, m²/s³) and ``2βσ²`` (baro bias, m²/s).

    Parameters
    ----------
    baro_bias_tau_s : float
        ``1/β``, s (> 0).
    baro_bias_sigma_m : float
        Stationary 1σ of ``b``, m (≥ 0).
    accel_noise_psd : float
        ``q_a``, m²/s³ (≥ 0).
    omega_s2 : float
        ``ωs²``, 1/s².
    """

    DVZ, DH, BIAS = 0, 1, 2
    """State indices."""

    def __init__(
        self,
        baro_bias_tau_s: float = 600.0,
        baro_bias_sigma_m: float = 1.0,
        accel_noise_psd: float = 1e-4,
        omega_s2: float = OMEGA_S2,
    ) -> None:
        if not (math.isfinite(baro_bias_tau_s) and baro_bias_tau_s > 0.0):
            raise ValueError(f"baro_bias_tau_s must be > 0 (got {baro_bias_tau_s!r})")
        for name, v in (
            ("baro_bias_sigma_m", baro_bias_sigma_m),
            ("accel_noise_psd", accel_noise_psd),
            ("omega_s2", omega_s2),
        ):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and ≥ 0 (got {v!r})")
        self.beta = 1.0 / baro_bias_tau_s
        self.sigma_b = baro_bias_sigma_m
        self.q_a = accel_noise_psd
        self.a = np.array([[0.0, 2.0 * omega_s2, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -self.beta]])
        self.b_u = np.array([[1.0], [0.0], [0.0]])
        self.g = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
        self.q_c = np.diag([self.q_a, 2.0 * self.beta * self.sigma_b**2])

    def discretise(self, dt_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Exact discretisation for step ``dt_s`` (s).

        Returns
        -------
        phi : ndarray, shape (3, 3)
            ``exp(A·dt)``.
        gamma_u : ndarray, shape (3,)
            ZOH input vector for ``u``.
        q_d : ndarray, shape (3, 3)
            ``∫₀^dt exp(Aτ) G Q_c Gᵀ exp(Aτ)ᵀ dτ`` (Van Loan).
        """
        check_dt(dt_s)
        phi, gam = zoh_discretise(self.a, self.b_u, dt_s)
        n = 3
        vl = np.zeros((2 * n, 2 * n))
        vl[:n, :n] = -self.a * dt_s
        vl[:n, n:] = self.g @ self.q_c @ self.g.T * dt_s
        vl[n:, n:] = self.a.T * dt_s
        e = scipy.linalg.expm(vl)
        phi_vl = e[n:, n:].T
        q_d = phi_vl @ e[:n, n:]
        q_d = 0.5 * (q_d + q_d.T)
        return phi, gam[:, 0], q_d
