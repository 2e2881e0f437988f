"""Barometric-inertial altitude channel of paper P4: damping loop, error model, MPC and KF.

Pure, deterministic, steppable objects (no I/O, no clock, no randomness). Heights are geometric
heights above mean sea level in metres, **up positive**; vertical speed ``vz`` is up positive
(``vz = −v_D``).

Vertical acceleration input ``az``
    ``az_up = f_up − g(φ, 0)``: the specific force along the local vertical (up positive; in NED
    ``f_up = −f_D``), minus the *sea-level* normal gravity at the latitude. Gravity falls with
    height by ``2ωs²·h`` (free-air gradient, ``ωs² = g/R``, the squared Schuler frequency), so
    the true vertical acceleration is ``az_up + 2ωs²·h``; the loop adds that term itself, as in
    P4 eq. 5. This term is what makes the free inertial vertical channel unstable (error growth
    ``cosh(√2·ωs·t)``, time constant 570 s). A caller that already used height-dependent
    gravity must pass ``omega_s2=0`` to :class:`ThirdOrderLoop`.

Third-order damping loop (P4 eq. 5), ``e = h − H`` with ``H`` the calibrated baro height::

    ḣ   = vz − K1·e
    v̇z  = az − a_c + 2ωs²·h − K2·e
    ȧ_c = K3·e

Error dynamics ``δḣ = δvz − K1 δh``, ``δv̇z = (2ωs² − K2) δh − δa_c``, ``δȧ_c = K3 δh`` give the
characteristic polynomial ``s³ + K1·s² + (K2 − 2ωs²)·s + K3`` (the ``2ωs²`` term enters with a
minus sign; it is 3.1e-6 s⁻² and negligible next to any useful ``K2``). Hurwitz iff all
coefficients are positive and ``K1·(K2 − 2ωs²) > K3``. P4's gains K1 = 3.00, K2 = 0.6452,
K3 = 0.8710 (from Ausman 1991, taken as s⁻¹, s⁻², s⁻³) put one real pole at −2.881 s⁻¹ and a
lightly damped pair at −0.0595 ± 0.5466j s⁻¹ (ωn = 0.550 rad/s, ζ = 0.108: an 11.5 s ringing
that decays with a 16.8 s time constant). :meth:`ThirdOrderLoop.from_time_constant` places a
triple pole at ``−1/τ`` instead (``K1 = 3/τ``, ``K2 = 3/τ² + 2ωs²``, ``K3 = 1/τ³``);
:meth:`ThirdOrderLoop.from_poles` any set.

Error model (P4 eq. 6-9), state ``X = [δVz, δh, b]``::

    δV̇z = 2ωs²·δh + u + w_a,    δḣ = δVz,    ḃ = −β·b + sqrt(2βσ²)·w_b

P4 prints the Gauss–Markov driving term in the ``δh`` row of its input matrix (eq. 9), which
contradicts its eq. 7; it belongs in the ``b`` row (:class:`VerticalErrorModel`).

Compensators (P4 §4-7): the MPC drives the error model with the acceleration ``u`` so that its
output ``δh`` tracks the reference ``δh_ref = h − h_GNSS``; corrected height ``h_T = h − δh``.
During GNSS outages it has no reference and keeps its last model (``outage_mode``). The Kalman
comparator estimates the same ``X`` from ``z = h − h_GNSS = δh + v`` (GNSS) and
``z = h − H = δh − b + v`` (baro, P4 eq. 18).

P4's horizons are short: with ``Np = 10`` the receding-horizon loop on this (double-integrator)
model is *unstable* for ``R_L ≳ 100`` (finite horizon, no terminal cost);
:class:`MpcCompensator` checks the closed-loop spectral radius and refuses such a design.
A slower compensator needs a longer ``period_s`` (or ``np_horizon``).

What an MPC learned while GNSS was valid can do in an outage: only extrapolate its own state.
With ``hold`` it keeps the offset ``h − h_GNSS`` it saw last (which contains the GNSS error of
that moment); with ``coast``/``extrapolate`` it also continues the learned trend. It cannot see
a weather front that starts or changes during the outage.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, PositiveInt

from fusion.baro_altitude import (
    BaroAltimeter,
    BaroAltimeterConfig,
    BaroCalibrationConfig,
    BaroHealth,
    BaroMonitor,
    BaroMonitorConfig,
    geometric_from_geopotential,
    geopotential_from_geometric,
)
from fusion.laguerre import LaguerreMPC
from physconst import G0_MPS2

FloatArray = NDArray[np.float64]


EARTH_MEAN_RADIUS_M = 6371008.8
"""Mean Earth radius (IUGG), m."""
OMEGA_S2 = G0_MPS2 / EARTH_MEAN_RADIUS_M
"""Squared Schuler frequency ``ωs² = g/R``, 1/s² (1.54e-6; ``ωs`` = 1.24e-3 rad/s)."""

P4_K1 = 3.00
"""P4's loop gain K1, 1/s."""
P4_K2 = 0.6452
"""P4's loop gain K2, 1/s²."""
P4_K3 = 0.8710
"""P4's loop gain K3, 1/s³."""

DEFAULT_LOOP_TAU_S = 3.0
"""Time constant of the default loop: a triple pole at ``−1/τ``, chosen on the tuning seeds
(1-5) of ``bench/altitude_jsbsim.py`` over P4's gains and τ = 1 s (see :class:`LoopGains`)."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


def _check_finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite (got {value!r})")


def _check_dt(dt_s: float) -> None:
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"dt_s must be finite and > 0 (got {dt_s!r})")


def zoh_discretise(a: FloatArray, b: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """Exact zero-order-hold discretisation of ``ẋ = A x + B u``.

    Parameters
    ----------
    a : ndarray, shape (n, n)
    b : ndarray, shape (n, m)
    dt_s : float
        Step, s (> 0).

    Returns
    -------
    phi : ndarray, shape (n, n)
        ``exp(A·dt)``.
    gamma : ndarray, shape (n, m)
        ``∫₀^dt exp(A·τ) dτ · B``.
    """
    _check_dt(dt_s)
    n, m = a.shape[0], b.shape[1]
    blk = np.zeros((n + m, n + m))
    blk[:n, :n] = a * dt_s
    blk[:n, n:] = b * dt_s
    e = scipy.linalg.expm(blk)
    return e[:n, :n], e[:n, n:]


# ============================================================================================
# Third-order damping loop
# ============================================================================================


class LoopGains(_Frozen):
    """Gains of the third-order loop, SI (1/s, 1/s², 1/s³).

    Default: a triple pole at ``−1/τ`` with ``τ = 3 s`` (:data:`DEFAULT_LOOP_TAU_S`;
    ``K1 = 1.0``, ``K2 = 0.3333``, ``K3 = 0.0370``), chosen on the tuning seeds of
    ``bench/altitude_jsbsim.py`` (JSBSim climb-descent, 120 s GNSS outage, objective the mean
    outage RMSE over calm and weather-front flights; candidates P4's gains, τ = 1 s, τ = 3 s).
    P4's gains (eq. 17: K1 = 3.00, K2 = 0.6452, K3 = 0.8710, a real pole at −2.88/s and a
    pair with ζ = 0.11 that rings for ~17 s) are :meth:`p4`; :meth:`triple_pole` gives any τ.
    """

    k1: PositiveFloat = 3.0 / DEFAULT_LOOP_TAU_S
    k2: PositiveFloat = 3.0 / DEFAULT_LOOP_TAU_S**2 + 2.0 * OMEGA_S2
    k3: PositiveFloat = 1.0 / DEFAULT_LOOP_TAU_S**3

    @classmethod
    def p4(cls) -> LoopGains:
        """P4's gains K1 = 3.00 /s, K2 = 0.6452 /s², K3 = 0.8710 /s³ (paper eq. 17)."""
        return cls(k1=P4_K1, k2=P4_K2, k3=P4_K3)

    @classmethod
    def triple_pole(cls, tau_s: float, omega_s2: float = OMEGA_S2) -> LoopGains:
        """Triple pole at ``−1/τ``: ``K1 = 3/τ``, ``K2 = 3/τ² + 2ωs²``, ``K3 = 1/τ³``.

        Parameters
        ----------
        tau_s : float
            Time constant, s (> 0).
        omega_s2 : float
            ``ωs²``, 1/s².
        """
        if not (math.isfinite(tau_s) and tau_s > 0.0):
            raise ValueError(f"tau_s must be finite and > 0 (got {tau_s!r})")
        return cls(k1=3.0 / tau_s, k2=3.0 / tau_s**2 + 2.0 * omega_s2, k3=1.0 / tau_s**3)


def gains_from_poles(
    poles: Sequence[complex] | NDArray[np.complex128], omega_s2: float = OMEGA_S2
) -> tuple[float, float, float]:
    """Loop gains whose characteristic polynomial has the given roots.

    ``Π(s − p_i) = s³ + c2·s² + c1·s + c0`` is matched to ``s³ + K1·s² + (K2 − 2ωs²)·s + K3``:
    ``K1 = c2``, ``K2 = c1 + 2ωs²``, ``K3 = c0``.

    Parameters
    ----------
    poles : sequence of 3 complex
        Closed-loop poles, 1/s; complex ones in conjugate pairs, all with negative real part.
    omega_s2 : float
        ``ωs²``, 1/s².

    Returns
    -------
    k1, k2, k3 : float

    Raises
    ------
    ValueError
        Not three poles, not conjugate-symmetric, or not all in the open left half-plane.
    """
    p = np.asarray(poles, dtype=np.complex128)
    if p.shape != (3,):
        raise ValueError(f"need exactly 3 poles (got {p.shape})")
    if not np.all(np.isfinite(p)) or np.any(p.real >= 0.0):
        raise ValueError("poles must be finite with negative real parts")
    coeffs = np.poly(p)
    if np.max(np.abs(coeffs.imag)) > 1e-9 * max(1.0, float(np.max(np.abs(coeffs)))):
        raise ValueError("complex poles must come in conjugate pairs")
    c = coeffs.real
    return float(c[1]), float(c[2] + 2.0 * omega_s2), float(c[3])


class ThirdOrderLoop:
    """P4's third-order baro-inertial damping loop (eq. 5), discretised exactly (ZOH).

    State ``h`` (m, MSL, up), ``vz`` (m/s, up), ``a_c`` (m/s², the loop's estimate of the
    vertical-acceleration error, subtracted from ``az``).

    Parameters
    ----------
    k1, k2, k3 : float
        Gains, 1/s, 1/s², 1/s³ (default P4's).
    h0_m, vz0_mps, ac0_mps2 : float
        Initial state.
    omega_s2 : float
        ``ωs²`` used for the free-air gravity gradient, 1/s² (0 if ``az`` already accounts
        for gravity at height).
    max_hold_s : float
        A baro height is held (zero-order) for this long after its sample; with no fresher one
        the loop runs open (free inertial, ``a_c`` frozen), s.
    """

    def __init__(
        self,
        k1: float = P4_K1,
        k2: float = P4_K2,
        k3: float = P4_K3,
        *,
        h0_m: float = 0.0,
        vz0_mps: float = 0.0,
        ac0_mps2: float = 0.0,
        omega_s2: float = OMEGA_S2,
        max_hold_s: float = 1.0,
    ) -> None:
        for name, v in (("k1", k1), ("k2", k2), ("k3", k3)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and ≥ 0 (got {v!r})")
        for name, v in (("h0_m", h0_m), ("vz0_mps", vz0_mps), ("ac0_mps2", ac0_mps2)):
            _check_finite(name, v)
        if not (math.isfinite(omega_s2) and omega_s2 >= 0.0):
            raise ValueError(f"omega_s2 must be finite and ≥ 0 (got {omega_s2!r})")
        if not (math.isfinite(max_hold_s) and max_hold_s >= 0.0):
            raise ValueError(f"max_hold_s must be finite and ≥ 0 (got {max_hold_s!r})")
        self.k1, self.k2, self.k3 = float(k1), float(k2), float(k3)
        self.omega_s2 = float(omega_s2)
        self.max_hold_s = float(max_hold_s)
        self.h_m = float(h0_m)
        self.vz_mps = float(vz0_mps)
        self.ac_mps2 = float(ac0_mps2)
        self._baro_h: float | None = None
        self._baro_age_s = math.inf
        self.damped = False
        """Whether the last step used baro feedback."""
        self._cache: dict[tuple[float, bool], tuple[list[list[float]], list[list[float]]]] = {}

    # ---- design ------------------------------------------------------------------------
    @classmethod
    def from_gains(cls, gains: LoopGains, **kwargs: float) -> ThirdOrderLoop:
        """Loop from a :class:`LoopGains` model; ``kwargs`` as for the constructor."""
        return cls(gains.k1, gains.k2, gains.k3, **kwargs)

    @classmethod
    def from_time_constant(
        cls, tau_s: float, *, omega_s2: float = OMEGA_S2, **kwargs: float
    ) -> ThirdOrderLoop:
        """Triple pole at ``−1/τ`` (gains as :meth:`LoopGains.triple_pole`)."""
        return cls.from_gains(LoopGains.triple_pole(tau_s, omega_s2), omega_s2=omega_s2, **kwargs)

    @classmethod
    def from_poles(
        cls,
        poles: Sequence[complex] | NDArray[np.complex128],
        *,
        omega_s2: float = OMEGA_S2,
        **kwargs: float,
    ) -> ThirdOrderLoop:
        """Loop with the given closed-loop poles (see :func:`gains_from_poles`)."""
        k1, k2, k3 = gains_from_poles(poles, omega_s2)
        return cls(k1, k2, k3, omega_s2=omega_s2, **kwargs)

    def characteristic_polynomial(self) -> FloatArray:
        """``[1, K1, K2 − 2ωs², K3]``: coefficients of the error dynamics, highest first."""
        return np.array([1.0, self.k1, self.k2 - 2.0 * self.omega_s2, self.k3])

    def poles(self) -> NDArray[np.complex128]:
        """Closed-loop poles (roots of :meth:`characteristic_polynomial`), 1/s."""
        return np.roots(self.characteristic_polynomial()).astype(np.complex128)

    def system_matrices(self, damped: bool = True) -> tuple[FloatArray, FloatArray]:
        """Continuous ``(A, B)`` of the loop, state ``[h, vz, a_c]``.

        Returns
        -------
        a : ndarray, shape (3, 3)
        b : ndarray, shape (3, 2) if ``damped`` (inputs ``[az, H]``) else (3, 1) (``[az]``)
        """
        w2 = 2.0 * self.omega_s2
        if damped:
            k1, k2, k3 = self.k1, self.k2, self.k3
            a = np.array([[-k1, 1.0, 0.0], [w2 - k2, 0.0, -1.0], [k3, 0.0, 0.0]])
            b = np.array([[0.0, k1], [1.0, k2], [0.0, -k3]])
        else:
            a = np.array([[0.0, 1.0, 0.0], [w2, 0.0, -1.0], [0.0, 0.0, 0.0]])
            b = np.array([[0.0], [1.0], [0.0]])
        return a, b

    def _discrete(self, dt_s: float, damped: bool) -> tuple[list[list[float]], list[list[float]]]:
        key = (dt_s, damped)
        hit = self._cache.get(key)
        if hit is None:
            _check_dt(dt_s)
            a, b = self.system_matrices(damped)
            phi, gam = zoh_discretise(a, b, dt_s)
            if len(self._cache) > 64:  # jittery dt: keep the cache bounded
                self._cache.clear()
            hit = (phi.tolist(), gam.tolist())
            self._cache[key] = hit
        return hit

    # ---- running -----------------------------------------------------------------------
    def reset(self, h_m: float, vz_mps: float = 0.0, ac_mps2: float = 0.0) -> None:
        """Set the state (and forget the held baro height)."""
        for name, v in (("h_m", h_m), ("vz_mps", vz_mps), ("ac_mps2", ac_mps2)):
            _check_finite(name, v)
        self.h_m, self.vz_mps, self.ac_mps2 = float(h_m), float(vz_mps), float(ac_mps2)
        self._baro_h = None
        self._baro_age_s = math.inf

    def snapshot(self) -> tuple[float, float, float, float | None, float, bool]:
        """The loop's complete state (for :meth:`restore`)."""
        return (self.h_m, self.vz_mps, self.ac_mps2, self._baro_h, self._baro_age_s, self.damped)

    def restore(self, state: tuple[float, float, float, float | None, float, bool]) -> None:
        """Go back to a state taken with :meth:`snapshot`."""
        self.h_m, self.vz_mps, self.ac_mps2, self._baro_h, self._baro_age_s, self.damped = state

    def shift(self, delta_h_m: float) -> None:
        """Move the height datum by ``delta_h_m`` (state and held baro height alike), m."""
        _check_finite("delta_h_m", delta_h_m)
        self.h_m += delta_h_m
        if self._baro_h is not None:
            self._baro_h += delta_h_m

    def set_baro(self, baro_h_m: float) -> None:
        """Hold a new baro height (m) for the following steps."""
        _check_finite("baro_h_m", baro_h_m)
        self._baro_h = float(baro_h_m)
        self._baro_age_s = 0.0

    def step(self, az_mps2: float, baro_h_m: float | None, dt_s: float) -> tuple[float, float]:
        """Advance by ``dt_s``.

        Parameters
        ----------
        az_mps2 : float
            ``az_up = f_up − g(φ, 0)``, m/s², **up positive** (see the module docstring),
            held over the step.
        baro_h_m : float or None
            A fresh calibrated baro height (m, MSL) sampled at the start of the step, or
            ``None`` to keep using the held one; either is advanced by ``vz·(age + dt/2)``
            (held up to ``max_hold_s``; after that the loop runs undamped).
        dt_s : float
            Step, s (> 0).

        Returns
        -------
        h_m, vz_mps : float
        """
        if not math.isfinite(az_mps2):
            raise ValueError(f"az_mps2 must be finite (got {az_mps2!r})")
        if baro_h_m is not None:
            self.set_baro(baro_h_m)
        damped = self._baro_h is not None and self._baro_age_s <= self.max_hold_s
        phi, gam = self._discrete(dt_s, damped)
        h, v, ac = self.h_m, self.vz_mps, self.ac_mps2
        p0, p1, p2 = phi
        if damped:
            assert self._baro_h is not None
            # Bring the held sample to the middle of this step with the loop's own vertical
            # speed, so a held (or gap-bridging) sample does not pull the loop back while
            # climbing or descending (and the zero-order hold adds no vz·dt/2 lag).
            hb = self._baro_h + v * (self._baro_age_s + 0.5 * dt_s)
            g0, g1, g2 = gam
            self.h_m = p0[0] * h + p0[1] * v + p0[2] * ac + g0[0] * az_mps2 + g0[1] * hb
            self.vz_mps = p1[0] * h + p1[1] * v + p1[2] * ac + g1[0] * az_mps2 + g1[1] * hb
            self.ac_mps2 = p2[0] * h + p2[1] * v + p2[2] * ac + g2[0] * az_mps2 + g2[1] * hb
        else:
            self.h_m = p0[0] * h + p0[1] * v + p0[2] * ac + gam[0][0] * az_mps2
            self.vz_mps = p1[0] * h + p1[1] * v + p1[2] * ac + gam[1][0] * az_mps2
        self.damped = damped
        self._baro_age_s += dt_s
        return self.h_m, self.vz_mps


# ============================================================================================
# Error model
# ============================================================================================


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
        _check_dt(dt_s)
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


# ============================================================================================
# Compensators
# ============================================================================================

OutageMode = Literal["hold", "coast", "extrapolate"]


class MpcConfig(_Frozen):
    """P4's Laguerre-MPC compensator on the error model.

    ``outage_mode`` (no reference): ``hold`` keeps ``δh`` and the model frozen; ``coast`` runs
    the model on with the last control held (``Δu = 0``); ``extrapolate`` runs it with ``u = 0``
    (``δh`` continues along the learned ``δVz``).

    Defaults: P4's horizons ``Np = Nc = 10``; period 0.2 s, Laguerre pole 0.6 and ``R_L = 1``
    as chosen on the tuning seeds of ``bench/altitude_jsbsim.py`` (grid: period 0.2 / 1 / 5 s,
    pole 0 / 0.6, ``R_L`` 0.01 / 1 / 10). P4 gives no pole or ``N``; :meth:`p4` is the
    untuned design used before (pole 0.5).
    """

    period_s: PositiveFloat = 0.2
    pole: float = Field(default=0.6, ge=0.0, lt=1.0)
    n_terms: PositiveInt = 4
    np_horizon: PositiveInt = 10
    nc_horizon: PositiveInt | None = 10
    r_l: float = Field(default=1.0, ge=0.0)
    delta_u_max_mps2: PositiveFloat | None = None
    """Bound on each acceleration move, m/s² per step (real QP when set)."""
    u_max_mps2: PositiveFloat | None = None
    """Bound on the compensator's acceleration, m/s²."""
    baro_bias_tau_s: PositiveFloat = 600.0
    baro_bias_sigma_m: float = Field(default=1.0, ge=0.0)
    outage_mode: OutageMode = "hold"
    warm_start: bool = True
    """Start the model at ``δh = r`` with the first reference (no pull-in transient)."""

    @classmethod
    def p4(cls) -> MpcConfig:
        """The untuned design: ``Np = Nc = 10`` (P4), pole 0.5, 4 terms, ``R_L = 1``, 0.2 s,
        P4's Gauss–Markov baro bias (τ 600 s)."""
        return cls(pole=0.5)


class MpcCompensator:
    """Laguerre-MPC driving P4's error model so that ``δh`` tracks ``h − h_GNSS``.

    The third state ``b`` is neither driven by ``u`` nor seen in ``δh``; its MPC gain is zero
    and it only decays. Kept so the model is P4's.

    Parameters
    ----------
    config : MpcConfig
    omega_s2 : float
        ``ωs²``, 1/s².
    """

    def __init__(self, config: MpcConfig | None = None, omega_s2: float = OMEGA_S2) -> None:
        self.config = cfg = config or MpcConfig()
        model = VerticalErrorModel(cfg.baro_bias_tau_s, cfg.baro_bias_sigma_m, 0.0, omega_s2)
        phi, gam, _ = model.discretise(cfg.period_s)
        self.model = model
        self.mpc = LaguerreMPC(
            phi,
            gam,
            [0.0, 1.0, 0.0],
            pole=cfg.pole,
            n_terms=cfg.n_terms,
            np_horizon=cfg.np_horizon,
            nc_horizon=cfg.nc_horizon,
            r_l=cfg.r_l,
            delta_u_min=None if cfg.delta_u_max_mps2 is None else -cfg.delta_u_max_mps2,
            delta_u_max=cfg.delta_u_max_mps2,
            u_min=None if cfg.u_max_mps2 is None else -cfg.u_max_mps2,
            u_max=cfg.u_max_mps2,
        )
        rho = float(np.max(np.abs(self.mpc.closed_loop_poles())))
        if rho >= 1.0:
            # A finite horizon without terminal cost does not guarantee stability: with the
            # double integrator of the error model, a heavy r_l makes Np steps too short to
            # act in and the receding-horizon loop diverges (e.g. Np = 10, r_l ≥ 100).
            raise ValueError(
                f"MPC design unstable (closed-loop spectral radius {rho:.4f}): decrease r_l "
                f"({cfg.r_l}) or lengthen np_horizon ({cfg.np_horizon}) / period_s"
            )
        self._phi: list[list[float]] = phi.tolist()
        self._gam: list[float] = gam.tolist()
        self.x = [0.0, 0.0, 0.0]
        self._dx = [0.0, 0.0, 0.0]
        self.u = 0.0
        self.started = False
        self.qp_active = 0

    @property
    def delta_h_m(self) -> float:
        """The model's height error ``δh``, m."""
        return self.x[1]

    @property
    def delta_vz_mps(self) -> float:
        """The model's vertical-speed error ``δVz``, m/s."""
        return self.x[0]

    def delta_at(self, frac: float) -> tuple[float, float]:
        """``(δh, δVz)`` a fraction ``frac`` ∈ [0, 1] into the current period.

        After :meth:`step` at time ``k`` the model holds ``x(k+1)``; between steps the output is
        interpolated linearly from ``x(k)`` to ``x(k+1)`` (first-order hold), so the correction
        has the right timing and no staircase at long periods.
        """
        back = 1.0 - min(1.0, max(0.0, frac))
        return self.x[1] - back * self._dx[1], self.x[0] - back * self._dx[0]

    def snapshot(self) -> tuple[tuple[float, ...], tuple[float, ...], float, bool]:
        """The compensator's state (for :meth:`restore`)."""
        return (tuple(self.x), tuple(self._dx), self.u, self.started)

    def restore(self, state: tuple[tuple[float, ...], tuple[float, ...], float, bool]) -> None:
        """Go back to a state taken with :meth:`snapshot`."""
        x, dx, self.u, self.started = state
        self.x, self._dx = list(x), list(dx)

    def _propagate(self, u: float) -> None:
        p, g, x = self._phi, self._gam, self.x
        n0 = p[0][0] * x[0] + p[0][1] * x[1] + p[0][2] * x[2] + g[0] * u
        n1 = p[1][0] * x[0] + p[1][1] * x[1] + p[1][2] * x[2] + g[1] * u
        n2 = p[2][0] * x[0] + p[2][1] * x[1] + p[2][2] * x[2] + g[2] * u
        self._dx = [n0 - x[0], n1 - x[1], n2 - x[2]]
        self.x = [n0, n1, n2]

    def step(self, reference_m: float | None) -> float:
        """One compensator period.

        Parameters
        ----------
        reference_m : float or None
            ``δh_ref = h − h_GNSS`` (m) while GNSS is valid, ``None`` during outages.

        Returns
        -------
        float
            ``δh`` after the step, m.
        """
        if reference_m is None:
            if not self.started:
                return self.x[1]
            mode = self.config.outage_mode
            if mode == "coast":
                self._propagate(self.u)
            elif mode == "extrapolate":
                self.u = 0.0
                self._propagate(0.0)
            else:
                self._dx = [0.0, 0.0, 0.0]
            return self.x[1]
        _check_finite("reference_m", reference_m)
        if not self.started:
            self.started = True
            if self.config.warm_start:
                self.x = [0.0, reference_m, 0.0]
                self._dx = [0.0, 0.0, 0.0]
        if self.mpc.constrained:
            eta, res = self.mpc.solve(self._dx, self.x[1], reference_m, self.u)
            du = float(self.mpc.laguerre[0] @ eta)
            self.qp_active += int(res.active)
        else:
            du = self.mpc.first_move_fast(self._dx, self.x[1] - reference_m)
        self.u += du
        self._propagate(self.u)
        return self.x[1]


class VerticalKfConfig(_Frozen):
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
        _check_finite("residual_m", residual_m)
        if not self.started:
            # Start at the first residual (the same warm start the MPC gets).
            self.kf.x[1, 0] = residual_m
            self.started = True
        s = sigma_m * self.config.gnss_sigma_scale
        self.kf.update(np.array([[residual_m]]), R=np.array([[s * s]]), H=self._h_gnss)

    def update_baro(self, residual_m: float) -> None:
        """Fuse ``z = h − H = δh − b + v`` (m)."""
        _check_finite("residual_m", residual_m)
        self.kf.update(np.array([[residual_m]]), R=self._r_baro, H=self._h_baro)


# ============================================================================================
# The channel
# ============================================================================================

AltitudeMethod = Literal["loop", "loop-mpc", "loop-kf"]


class AltitudeChannelConfig(_Frozen):
    """Everything an :class:`AltitudeChannel` needs (SI)."""

    method: AltitudeMethod = "loop-mpc"
    loop: LoopGains = LoopGains()
    baro: BaroAltimeterConfig = BaroAltimeterConfig()
    monitor: BaroMonitorConfig = BaroMonitorConfig()
    mpc: MpcConfig = MpcConfig()
    kf: VerticalKfConfig = VerticalKfConfig()
    gnss_timeout_s: PositiveFloat = 1.0
    """GNSS counts as valid while its last height is at most this old, s."""
    baro_hold_s: PositiveFloat = 1.0
    """The loop holds the last accepted baro height (advanced with its own ``vz``) this long
    across missing or rejected samples, then runs undamped (free inertial, ``a_c`` frozen), s."""
    max_baro_gnss_skew_s: PositiveFloat = 0.5
    """Calibrate only with a baro sample at most this far from the GNSS time, s."""
    freeze_rollback_m: PositiveFloat = 0.5
    """When a frozen sensor is declared, the loop is rolled back (see :class:`AltitudeChannel`)
    if its repeated readings had moved the loop's height by more than this (more than baro
    noise can: in level flight a stuck reading is harmless and the loop keeps its damped
    state), m."""
    freeze_rollback_mps: PositiveFloat = 0.2
    """... or its vertical speed by more than this, m/s."""
    omega_s2: float = Field(default=OMEGA_S2, ge=0.0)

    @classmethod
    def p4(
        cls, method: AltitudeMethod = "loop-mpc", *, gnss_calibration: bool = False
    ) -> AltitudeChannelConfig:
        """Paper P4's channel: its loop gains (K1 = 3.00, K2 = 0.6452, K3 = 0.8710), the
        untuned MPC (:meth:`MpcConfig.p4`) and P4's KF (:meth:`VerticalKfConfig.p4`).

        Parameters
        ----------
        method : {"loop", "loop-mpc", "loop-kf"}
        gnss_calibration : bool
            ``False`` (P4's set-up): the baro scale ``s`` comes from the sensed temperature
            only and ``b`` is not learned; GNSS reaches the altitude only through the
            compensator. ``True``: ``(s, b)`` learned from GNSS height as in the defaults, with
            the earlier (untuned) random walk of ``b``, 0.02 m/√s.
        """
        cal = BaroCalibrationConfig(
            bias_random_walk_m_per_rth_s=0.02,
            use_gnss=gnss_calibration,
            use_temperature=not gnss_calibration,
        )
        return cls(
            method=method,
            loop=LoopGains.p4(),
            baro=BaroAltimeterConfig(calibration=cal),
            mpc=MpcConfig.p4(),
            kf=VerticalKfConfig.p4(),
        )


@dataclass(slots=True)
class AltitudeHealth:
    """Counters and flags of an :class:`AltitudeChannel`."""

    baro: BaroHealth = field(default_factory=BaroHealth)
    gnss_updates: int = 0
    gnss_rejected: int = 0
    calibration_updates: int = 0
    compensator_steps: int = 0
    qp_active: int = 0
    undamped: bool = False
    """The loop ran without baro feedback at the last IMU step."""
    freeze_rollbacks: int = 0
    """Frozen-sensor declarations that rolled the loop back (see :class:`AltitudeChannel`)."""
    initialised: bool = False


class AltitudeChannel:
    """Baro-inertial altitude: altimeter + monitor + third-order loop + compensator.

    Methods (``config.method``): ``loop`` (P4's damping loop alone), ``loop-mpc`` (P4: loop
    plus the Laguerre-MPC compensator, ``h_T = h − δh``), ``loop-kf`` (loop plus P4's Kalman
    comparator). (The fourth method of the issue, ``ekf``, is the main filter's own baro
    update, not here.) In every method the barometer is calibrated for the non-standard
    atmosphere from GNSS height while GNSS is valid and frozen during outages; a calibration
    step moves the loop's datum with it (so it never shows as a loop transient or a gate
    rejection). ``BaroCalibrationConfig(use_gnss=False)`` reproduces P4's set-up instead, where
    GNSS reaches the altitude only through the compensator.

    Baro faults never raise: a sample out of the atmosphere model, a frozen sensor (identical
    readings for ``freeze_time_s``) or a jump beyond ``gate_m`` from the loop's height is
    counted in :attr:`health` and skipped; the loop bridges with the held sample, then
    inertially. A step that persists ``realign_after_rejected_s`` is taken as a new baro datum:
    the calibration bias is moved so that the baro agrees with the loop's height (no jump), and
    GNSS re-calibrates it when valid. GNSS heights that fail the calibration's innovation gate
    are counted (``gnss_rejected``) and not used.

    A frozen sensor is recognised only after ``freeze_time_s`` of identical readings, and until
    then its readings look valid. When the freeze is declared, the loop is rolled back to its
    state before the first repeated reading and re-run from there on the recorded IMU steps
    (and datum shifts) without them, as if they had been rejected at once: with P4's stiff
    gains two seconds of a stuck barometer in a 5 m/s climb leave the loop with a vertical
    speed ~3 m/s and an ``a_c`` ~2 m/s² wrong and, undamped afterwards, put the altitude
    hundreds of metres off. The rollback is applied only if the repeated readings had moved the
    loop by more than ``freeze_rollback_m`` / ``freeze_rollback_mps`` (in level flight they
    are harmless and the damped state is the better one). The compensator (MPC or KF) is rolled
    back with the loop: to its state at the checkpoint, then run on without measurements for
    the periods since (MPC: its outage mode; KF: prediction only), because its GNSS references
    and baro residuals in that time were taken against the corrupted loop. So is the baro
    calibration, which had fitted GNSS heights to the stuck pressure altitude (the datum shifts
    it made meanwhile are undone).

    Call order: :meth:`update_imu` at the IMU rate; :meth:`update_baro` and
    :meth:`update_gnss_height` as samples arrive (time-ordered, same time base as the IMU's).
    The channel initialises on the first accepted baro sample.

    Parameters
    ----------
    config : AltitudeChannelConfig
    start_time_s : float
        Time of the first IMU sample's start, s.
    """

    def __init__(self, config: AltitudeChannelConfig | None = None, start_time_s: float = 0.0):
        self.config = cfg = config or AltitudeChannelConfig()
        _check_finite("start_time_s", start_time_s)
        self.health = AltitudeHealth()
        self.altimeter = BaroAltimeter(cfg.baro)
        self.monitor = BaroMonitor(cfg.monitor, self.health.baro)
        self.loop = ThirdOrderLoop.from_gains(
            cfg.loop, omega_s2=cfg.omega_s2, max_hold_s=cfg.baro_hold_s
        )
        self.mpc = MpcCompensator(cfg.mpc, cfg.omega_s2) if cfg.method == "loop-mpc" else None
        self.kf = VerticalKalman(cfg.kf, cfg.omega_s2) if cfg.method == "loop-kf" else None
        period = cfg.mpc.period_s if cfg.method == "loop-mpc" else cfg.kf.period_s
        self._comp_period = period
        self.time_s = float(start_time_s)
        self._next_comp_s = self.time_s + period
        self._last_gnss_s: float | None = None
        self._residual: float | None = None
        self._residual_sum = 0.0
        self._residual_n = 0
        self._residual_sigma = 1.0
        self._last_hp: float | None = None
        self._last_hp_time = -math.inf
        self._last_temperature: float | None = None
        self._last_baro_h: float | None = None
        self._last_baro_time = -math.inf
        self._pending_baro: float | None = None
        # Frozen-sensor rollback: loop state, pending baro height and last baro (height, time)
        # when the latest fresh (changed) reading was accepted, and since then the IMU steps
        # (az, dt) and datum shifts (None, delta) applied to the loop; also the calibration's
        # state and the pressure altitude (Hp, time) it calibrates against at that moment.
        self._run_p: float | None = None
        self._ckpt: (
            tuple[tuple[float, float, float, float | None, float, bool], float, float, float] | None
        ) = None
        self._cal_ckpt: (
            tuple[tuple[float, float, float, float, float, float | None, bool], float | None, float]
            | None
        ) = None
        self._since_ckpt: list[tuple[float | None, float]] = []
        # ... and the compensator's state at (or, unchanged, before) that checkpoint, with the
        # number of compensator periods run since the snapshot.
        self._comp_ckpt: object = None
        self._comp_steps_since = 0

    # ---- outputs -----------------------------------------------------------------------
    @property
    def method(self) -> AltitudeMethod:
        """The configured method."""
        return self.config.method

    @property
    def gnss_valid(self) -> bool:
        """A GNSS height arrived within ``gnss_timeout_s``."""
        return (
            self._last_gnss_s is not None
            and self.time_s - self._last_gnss_s <= self.config.gnss_timeout_s
        )

    def _period_fraction(self) -> float:
        return 1.0 - (self._next_comp_s - self.time_s) / self._comp_period

    @property
    def correction_m(self) -> float:
        """The compensator's ``δh`` now (0 for ``loop``), m."""
        if self.mpc is not None:
            return self.mpc.delta_at(self._period_fraction())[0]
        if self.kf is not None:
            return self.kf.delta_h_m
        return 0.0

    @property
    def loop_height_m(self) -> float:
        """The damping loop's own height ``h``, m."""
        return self.loop.h_m

    @property
    def height_m(self) -> float:
        """Best height above MSL, m: ``h − δh`` (NaN before initialisation)."""
        if not self.health.initialised:
            return math.nan
        return self.loop.h_m - self.correction_m

    @property
    def vz_mps(self) -> float:
        """Best vertical speed, up positive, m/s (NaN before initialisation)."""
        if not self.health.initialised:
            return math.nan
        if self.mpc is not None:
            return self.loop.vz_mps - self.mpc.delta_at(self._period_fraction())[1]
        if self.kf is not None:
            return self.loop.vz_mps - self.kf.delta_vz_mps
        return self.loop.vz_mps

    @property
    def baro_height_m(self) -> float:
        """Last calibrated baro height that passed the checks, m (NaN if none)."""
        return math.nan if self._last_baro_h is None else self._last_baro_h

    # ---- inputs ------------------------------------------------------------------------
    def update_imu(self, az_up_mps2: float, dt_s: float) -> None:
        """Advance the loop by one IMU interval.

        Parameters
        ----------
        az_up_mps2 : float
            ``f_up − g(φ, 0)``, m/s², up positive (module docstring).
        dt_s : float
            Interval, s (> 0).

        Raises
        ------
        ValueError
            Non-finite ``az`` or bad ``dt_s``.
        """
        if not math.isfinite(az_up_mps2):
            raise ValueError(f"az_up_mps2 must be finite (got {az_up_mps2!r})")
        _check_dt(dt_s)
        self.time_s += dt_s
        if not self.health.initialised:
            return
        baro, self._pending_baro = self._pending_baro, None
        self.loop.step(az_up_mps2, baro, dt_s)
        self.health.undamped = not self.loop.damped
        if self._ckpt is not None:
            if self.time_s - self._ckpt[3] > self.config.monitor.freeze_time_s + 2.0:
                self._ckpt, self._since_ckpt = None, []  # no baro any more: nothing to undo
            else:
                self._since_ckpt.append((az_up_mps2, dt_s))
        gnss_ok = self.gnss_valid
        if gnss_ok:
            self.altimeter.unfreeze()
        else:
            self.altimeter.freeze()
        while self.time_s >= self._next_comp_s - 1e-9:
            self._next_comp_s += self._comp_period
            self._compensator_step(gnss_ok)

    def _compensator_step(self, gnss_ok: bool) -> None:
        if self.mpc is None and self.kf is None:
            return
        self.health.compensator_steps += 1
        self._comp_steps_since += 1
        fresh = self._residual_n > 0
        if fresh:
            self._residual = self._residual_sum / self._residual_n
            self._residual_sum, self._residual_n = 0.0, 0
        ref = self._residual if (gnss_ok and self._residual is not None) else None
        if self.mpc is not None:
            before = self.mpc.qp_active
            self.mpc.step(ref)
            self.health.qp_active += self.mpc.qp_active - before
        elif self.kf is not None:
            kf = self.kf
            if kf.started:
                kf.predict()
            if gnss_ok and fresh and self._residual is not None:
                kf.update_gnss(self._residual, self._residual_sigma)
            if (
                kf.started
                and kf.config.use_baro
                and self._last_baro_h is not None
                and self.time_s - self._last_baro_time <= self.config.baro_hold_s
            ):
                kf.update_baro(self.loop.h_m - self._last_baro_h)

    def update_baro(self, pressure_pa: float, temperature_k: float | None, time_s: float) -> bool:
        """One barometer sample.

        Bad samples (pressure ≤ 0, out of the atmosphere model, non-finite, a frozen sensor,
        a jump beyond the gate) are counted in :attr:`health` and not used; never raised.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa.
        temperature_k : float or None
            Sensor temperature, K.
        time_s : float
            Sample time, s.

        Returns
        -------
        bool
            Whether the sample was used.
        """
        hb = self.health.baro
        n_freeze = hb.freeze_events
        hp = self.monitor.check(pressure_pa, time_s)
        if hb.freeze_events != n_freeze:
            self._rollback()
        if hp is None:
            return False
        fresh = self._run_p is None or (
            abs(pressure_pa - self._run_p) > self.config.monitor.freeze_tolerance_pa
        )
        if fresh:
            self._run_p = pressure_pa
        self._last_hp, self._last_hp_time = hp, time_s
        if temperature_k is not None and math.isfinite(temperature_k) and temperature_k > 0.0:
            self._last_temperature = temperature_k
        h_baro = self.altimeter.altitude_from_hp(hp)
        if not self.health.initialised:
            self.loop.reset(h_baro)
            self.loop.set_baro(h_baro)
            self.health.initialised = True
            self.health.baro.accepted += 1
            self._last_baro_h, self._last_baro_time = h_baro, time_s
            return True
        if not self.monitor.gate(h_baro, self.loop.h_m, time_s):
            if fresh:
                self._ckpt, self._since_ckpt = None, []
            if self.monitor.rejecting_for_s(time_s) < self.config.monitor.realign_after_rejected_s:
                return False
            # A persistent step (sensor change, re-zeroed, cabin pressure): move the baro datum
            # onto the loop's height so the altitude stays continuous; GNSS re-calibrates it.
            shift = geopotential_from_geometric(self.loop.h_m) - geopotential_from_geometric(h_baro)
            self.altimeter.calibration.shift_bias(shift)
            self.monitor.clear_rejection()
            self.health.baro.realignments += 1
            h_baro = self.altimeter.altitude_from_hp(hp)
        if fresh:
            self._ckpt = (self.loop.snapshot(), h_baro, h_baro, time_s)
            self._cal_ckpt = (self.altimeter.calibration.snapshot(), hp, time_s)
            self._since_ckpt = []
            if self._comp_steps_since or self._comp_ckpt is None:
                # The compensator changes only at its period (0.2 s): a new snapshot only if
                # it stepped since the last one (baro samples come at up to 50 Hz).
                self._comp_ckpt = self._comp_snapshot()
                self._comp_steps_since = 0
        self._pending_baro = h_baro
        self._last_baro_h, self._last_baro_time = h_baro, time_s
        return True

    def _rollback(self) -> None:
        """Undo the repeated readings of a sensor just declared frozen (see class docstring)."""
        ck = self._ckpt
        if ck is None:
            return
        state, pending, last_h, last_t = ck
        loop = self.loop
        current = loop.snapshot()
        loop.restore(state)
        baro: float | None = pending
        for az, x in self._since_ckpt:
            if az is None:  # a calibration step moved the datum meanwhile
                loop.shift(x)
                last_h += x
                if baro is not None:
                    baro += x
            else:
                loop.step(az, baro, x)
                baro = None
        cfg = self.config
        if (
            abs(current[0] - loop.h_m) <= cfg.freeze_rollback_m
            and abs(current[1] - loop.vz_mps) <= cfg.freeze_rollback_mps
        ):
            loop.restore(current)  # the repeats agreed with inertia: keep the damped state
            self._ckpt, self._since_ckpt = None, []
            return
        self.health.freeze_rollbacks += 1
        self._comp_rollback()
        if self._cal_ckpt is not None:
            # The calibration had learned from GNSS heights against the stuck Hp: back to its
            # state at the checkpoint, and the datum shifts it made since are undone.
            cal_state, self._last_hp, self._last_hp_time = self._cal_ckpt
            self.altimeter.calibration.restore(cal_state)
            undo = -sum(x for az, x in self._since_ckpt if az is None)
            if undo:
                loop.shift(undo)
                last_h += undo
                if baro is not None:
                    baro += undo
        if baro is not None:  # no IMU step since the checkpoint: still to be applied
            self._pending_baro = baro
        else:
            self._pending_baro = None
        self.health.undamped = not loop.damped
        self._last_baro_h, self._last_baro_time = last_h, last_t
        self._ckpt, self._since_ckpt = None, []

    def _comp_snapshot(self) -> object:
        if self.mpc is not None:
            return self.mpc.snapshot()
        if self.kf is not None:
            return self.kf.snapshot()
        return None

    def _comp_rollback(self) -> None:
        """Roll the compensator back with the loop: restore its state at the checkpoint and
        re-run the periods since without measurements. Its references and baro residuals in
        that time were made against the loop the stuck readings had pulled away; kept, they
        would carry that error into ``h − δh`` after the loop itself was repaired."""
        state, n = self._comp_ckpt, self._comp_steps_since
        if state is None:
            return
        if self.mpc is not None:
            self.mpc.restore(state)  # type: ignore[arg-type]
            for _ in range(n):
                self.mpc.step(None)  # the outage behaviour (hold by default)
        elif self.kf is not None:
            self.kf.restore(state)  # type: ignore[arg-type]
            if self.kf.started:
                for _ in range(n):
                    self.kf.predict()
        # Residuals gathered since were against the wrong loop height: drop them.
        self._residual = None
        self._residual_sum, self._residual_n = 0.0, 0
        self._comp_ckpt, self._comp_steps_since = None, 0  # re-snapshot at the next checkpoint

    def update_gnss_height(
        self,
        height_m: float,
        sigma_m: float,
        time_s: float,
        *,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> None:
        """One GNSS height.

        Parameters
        ----------
        height_m : float
            GNSS height, m (above MSL or above the ellipsoid, per ``reference``).
        sigma_m : float
            Its 1σ (e.g. ``epv``), m (> 0).
        time_s : float
            Time of validity, s (same time base as the IMU; treated as "now").
        reference : {"msl", "ellipsoid"}
        geoid_undulation_m : float
            ``N`` for ``reference="ellipsoid"``, m.

        Raises
        ------
        ValueError
            Non-finite values, ``sigma_m ≤ 0``, unknown ``reference``.
        """
        for name, v in (
            ("height_m", height_m),
            ("time_s", time_s),
            ("geoid_undulation_m", geoid_undulation_m),
        ):
            _check_finite(name, v)
        if not (math.isfinite(sigma_m) and sigma_m > 0.0):
            raise ValueError(f"sigma_m must be finite and > 0 (got {sigma_m!r})")
        if reference == "ellipsoid":
            h_msl = height_m - geoid_undulation_m
        elif reference == "msl":
            h_msl = height_m
        else:
            raise ValueError(f"reference must be 'msl' or 'ellipsoid' (got {reference!r})")
        self._last_gnss_s = time_s
        self.health.gnss_updates += 1
        self.altimeter.unfreeze()
        cal = self.altimeter.calibration
        if (
            self.config.baro.mode == "calibrated"
            and self._last_hp is not None
            and abs(time_s - self._last_hp_time) <= self.config.max_baro_gnss_skew_s
        ):
            # Bring the last Hp to the GNSS time with the loop's vertical speed.
            hp = self._last_hp + self.loop.vz_mps * (time_s - self._last_hp_time) / (
                1.0 + cal.scale
            )
            h_before = self.altimeter.altitude_from_hp(hp)
            upd = cal.update(
                h_msl, hp, time_s, sigma_m=sigma_m, temperature_k=self._last_temperature
            )
            if upd.rejected:
                self.health.gnss_rejected += 1
                return
            if upd.delta_altitude_m != 0.0:
                self.health.calibration_updates += 1
                shift = (
                    geometric_from_geopotential(
                        geopotential_from_geometric(h_before) + upd.delta_altitude_m
                    )
                    - h_before
                )
                if self.health.initialised:
                    # The datum moved: carry the loop with it (no transient, no gate trip).
                    self.loop.shift(shift)
                    if self._ckpt is not None:
                        self._since_ckpt.append((None, shift))
                    if self._last_baro_h is not None:
                        self._last_baro_h += shift
                    if self._pending_baro is not None:
                        self._pending_baro += shift
        if self.health.initialised:
            # The compensators get the mean residual since their last step.
            self._residual_sum += self.loop.h_m - h_msl
            self._residual_n += 1
            self._residual_sigma = sigma_m
