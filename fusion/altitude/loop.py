"""P4's third-order baro-inertial damping loop: gains, pole placement, the discretised loop.

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
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from pydantic import PositiveFloat

from fusion.altitude.common import (
    OMEGA_S2,
    Frozen,
    check_dt,
    check_finite,
    zoh_discretise,
)

FloatArray = NDArray[np.float64]

P4_K1 = 3.00
"""P4's loop gain K1, 1/s."""
P4_K2 = 0.6452
"""P4's loop gain K2, 1/s²."""
P4_K3 = 0.8710
"""P4's loop gain K3, 1/s³."""

DEFAULT_LOOP_TAU_S = 3.0
"""Time constant of the default loop: a triple pole at ``−1/τ``, chosen on the tuning seeds
(1-5) of ``bench/altitude_jsbsim.py`` over P4's gains and τ = 1 s (see :class:`LoopGains`)."""


class LoopGains(Frozen):
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
            check_finite(name, v)
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
            check_dt(dt_s)
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
            check_finite(name, v)
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
        check_finite("delta_h_m", delta_h_m)
        self.h_m += delta_h_m
        if self._baro_h is not None:
            self._baro_h += delta_h_m

    def set_baro(self, baro_h_m: float) -> None:
        """Hold a new baro height (m) for the following steps."""
        check_finite("baro_h_m", baro_h_m)
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
