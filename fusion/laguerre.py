"""Discrete Laguerre functions and Laguerre-parameterised model predictive control (DMPC).

Notation follows Liuping Wang, *Model Predictive Control System Design and Implementation
Using MATLAB* (Springer, 2009), ch. 3, which paper P4 uses for its altitude compensator.

Laguerre network
    ``Γ_i(z) = sqrt(1 − a²)·(z⁻¹ − a)^(i−1) / (1 − a·z⁻¹)^i``, ``0 ≤ a < 1``. The impulse
    responses ``l_i(k)`` stacked as ``L(k) = [l_1(k) … l_N(k)]ᵀ`` obey ``L(k+1) = A_l·L(k)`` with
    ``L(0) = sqrt(β)·[1, −a, a², …, (−a)^(N−1)]ᵀ``, ``β = 1 − a²``, and ``A_l`` lower
    triangular: ``a`` on the diagonal, ``(−a)^(i−j−1)·β`` below it. They are orthonormal:
    ``Σ_k L(k)L(k)ᵀ = I``. With ``a = 0`` they are unit pulses and DMPC is classical MPC with
    control horizon ``N``.

Controller (single input, single output)
    Plant ``x_m(k+1) = A_m x_m(k) + B_m u(k)``, ``y = C_m x_m``. Augmented (velocity) form
    ``x(k) = [Δx_m(k); y(k)]``::

        A = [[A_m, 0], [C_m A_m, 1]],  B = [B_m; C_m B_m],  C = [0 … 0, 1]

    The future control increments are ``Δu(k+m) = L(m)ᵀ η`` (``m < Nc``; zero afterwards).
    Prediction ``x(k+m|k) = A^m x(k) + S(m) η`` with ``S(m) = Σ_{i<min(m,Nc)} A^(m−i−1) B L(i)ᵀ``.
    Stack ``F = [C A^m]`` (Np × n) and ``Φ = [C S(m)]`` (Np × N), m = 1 … Np. P4's cost::

        J = Σ_{m=1..Np} (r − y(k+m|k))² + ηᵀ R_L η = ‖r·1 − F x − Φ η‖² + ηᵀ R_L η

    Since ``F·e_y = 1`` (the augmented output is an integrator), ``r·1 − F x = −F x̃`` with
    ``x̃ = [Δx_m; y − r]``, and the unconstrained minimiser is ``η = −Ω⁻¹Ψ x̃`` with
    ``Ω = ΦᵀΦ + R_L``, ``Ψ = ΦᵀF`` (Wang eq. 3.23-3.26). Receding horizon: only
    ``Δu(k) = L(0)ᵀη = −K_mpc x̃`` is applied; ``K_mpc`` is precomputed.

Bounded moves
    Optional ``Δu_min ≤ Δu(k+m) ≤ Δu_max`` and ``u_min ≤ u(k+m) ≤ u_max`` for the first
    ``n_constrained`` moves are linear inequalities ``M η ≤ γ`` on ``η`` (not box bounds unless
    ``a = 0``), solved exactly as a small QP (:func:`solve_qp`: least-distance programming by
    non-negative least squares), with the unconstrained solution as the fast path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def _nnls(a: FloatArray, b: FloatArray) -> tuple[FloatArray, float]:
    """``scipy.optimize.nnls``, imported on first use: only the bounded (QP) MPC needs it, and
    importing scipy.optimize costs ~0.5 s in every process that imports fusion."""
    import scipy.optimize

    x, rnorm = scipy.optimize.nnls(a, b)
    return np.asarray(x, dtype=np.float64), float(rnorm)


def laguerre_network(pole: float, n_terms: int) -> tuple[FloatArray, FloatArray]:
    """State-space form of the discrete Laguerre network.

    Parameters
    ----------
    pole : float
        Laguerre pole ``a``, ``0 ≤ a < 1``.
    n_terms : int
        Number of functions ``N`` (≥ 1).

    Returns
    -------
    a_l : ndarray, shape (N, N)
        Transition matrix, ``L(k+1) = a_l @ L(k)``.
    l0 : ndarray, shape (N,)
        ``L(0)``.

    Raises
    ------
    ValueError
        ``a`` outside [0, 1) or ``N < 1``.
    """
    if not (math.isfinite(pole) and 0.0 <= pole < 1.0):
        raise ValueError(f"pole must be in [0, 1) (got {pole!r})")
    if int(n_terms) != n_terms or n_terms < 1:
        raise ValueError(f"n_terms must be an integer ≥ 1 (got {n_terms!r})")
    n = int(n_terms)
    beta = 1.0 - pole * pole
    a_l = np.zeros((n, n))
    for i in range(n):
        a_l[i, i] = pole
        for j in range(i):
            a_l[i, j] = (-pole) ** (i - j - 1) * beta
    l0 = math.sqrt(beta) * np.array([(-pole) ** i for i in range(n)])
    return a_l, l0


def laguerre_sequence(pole: float, n_terms: int, length: int) -> FloatArray:
    """Laguerre functions ``L(0) … L(length−1)`` as rows.

    Parameters
    ----------
    pole : float
        ``a`` in [0, 1).
    n_terms : int
        ``N`` ≥ 1.
    length : int
        Number of samples (≥ 1).

    Returns
    -------
    ndarray, shape (length, N)
        Row ``k`` is ``L(k)ᵀ``; column ``i`` is the impulse response of ``Γ_{i+1}(z)``.
    """
    if int(length) != length or length < 1:
        raise ValueError(f"length must be an integer ≥ 1 (got {length!r})")
    a_l, l0 = laguerre_network(pole, n_terms)
    out = np.empty((int(length), a_l.shape[0]))
    v = l0
    for k in range(int(length)):
        out[k] = v
        v = a_l @ v
    return out


@dataclass(frozen=True, slots=True)
class QpResult:
    """Outcome of one constrained solve.

    Attributes
    ----------
    active : some constraint was active (the unconstrained optimum was infeasible).
    relaxed : some bound was already violated at ``η = 0`` (the previous control lies outside
        its amplitude bounds) and was relaxed to "no worse than now" for this step.
    max_violation : largest ``M η − γ`` of the returned solution (≤ ~1e-12 when solved).
    """

    active: bool
    relaxed: bool
    max_violation: float


def solve_qp(
    e: FloatArray,
    f: FloatArray,
    m: FloatArray,
    gamma: FloatArray,
    *,
    r_inv: FloatArray | None = None,
) -> tuple[FloatArray, QpResult]:
    """Minimise ``½ηᵀEη + fᵀη`` subject to ``M η ≤ γ`` exactly.

    The strictly convex QP is turned into a least-distance problem and solved by non-negative
    least squares (Lawson & Hanson, *Solving Least Squares Problems*, ch. 23, algorithm LDP;
    ``scipy.optimize.nnls``): with ``E = RᵀR`` and ``z = Rη + R⁻ᵀf`` the cost is ``½|z|²`` +
    const and the constraints read ``G z ≥ h``, ``G = −M R⁻¹``, ``h = −γ + M η₀``
    (``η₀ = −E⁻¹f``, the unconstrained optimum). NNLS of ``[Gᵀ; hᵀ] u ≈ [0 … 0, 1]`` gives
    ``z = −r[:n]/r[n]`` from its residual ``r``. Finite and robust to the many nearly parallel
    constraints of Laguerre move bounds (on which Hildreth's dual coordinate ascent, used by
    Wang, needs thousands of sweeps and a textbook primal active set cycles). The unconstrained
    optimum is returned directly when feasible.

    Rows with ``γ_i < 0`` (``η = 0`` infeasible) are relaxed to ``γ_i = 0``, so the problem is
    always feasible; :attr:`QpResult.relaxed` reports it.

    Parameters
    ----------
    e : ndarray, shape (N, N)
        Symmetric positive definite.
    f : ndarray, shape (N,)
    m : ndarray, shape (n_c, N)
    gamma : ndarray, shape (n_c,)
    r_inv : ndarray, shape (N, N), optional
        Precomputed ``R⁻¹`` with ``E = RᵀR`` (``R`` upper triangular).

    Returns
    -------
    eta : ndarray, shape (N,)
    result : QpResult
    """
    eta0: FloatArray = np.asarray(np.linalg.solve(e, -f), dtype=np.float64)
    viol0 = m @ eta0 - gamma
    if np.all(viol0 <= 0.0):
        return eta0, QpResult(False, False, float(np.max(viol0)))
    relaxed = bool(np.any(gamma < 0.0))
    g_eff = np.maximum(gamma, 0.0) if relaxed else gamma
    if r_inv is None:
        r_inv = np.linalg.inv(np.linalg.cholesky(e).T)
    n = len(f)
    g = -m @ r_inv
    h = -g_eff + m @ eta0
    a = np.vstack([g.T, h[None, :]])
    b = np.zeros(n + 1)
    b[n] = 1.0
    u = np.asarray(_nnls(a, b)[0], dtype=np.float64)
    r = a @ u - b
    # r[n] = -(1 - hᵀu) < 0 for a feasible problem (always, after the relaxation)
    z = -r[:n] / r[n]
    eta: FloatArray = r_inv @ z + eta0
    return eta, QpResult(True, relaxed, float(np.max(m @ eta - g_eff)))


class LaguerreMPC:
    """Laguerre-parameterised MPC for a single-input single-output discrete model.

    Parameters
    ----------
    a_m : array_like, shape (n, n)
        Discrete plant transition matrix.
    b_m : array_like, shape (n,) or (n, 1)
        Discrete input vector.
    c_m : array_like, shape (n,) or (1, n)
        Output row.
    pole : float
        Laguerre pole ``a`` in [0, 1).
    n_terms : int
        Number of Laguerre functions ``N``.
    np_horizon : int
        Prediction horizon ``Np`` (P4: 10).
    nc_horizon : int or None
        Control horizon ``Nc``: moves beyond it are zero (P4: 10; ``None`` = no truncation,
        the Laguerre decay alone shapes the moves). With ``Nc ≥ Np`` it has no effect.
    r_l : float or array_like, shape (N, N)
        Weight ``R_L`` on ``η`` (scalar → ``r_l·I``); positive semi-definite, and
        ``ΦᵀΦ + R_L`` must be positive definite.
    delta_u_min, delta_u_max : float or None
        Bounds on each control increment (input units per step).
    u_min, u_max : float or None
        Bounds on the control amplitude.
    n_constrained : int or None
        How many future moves the bounds apply to (default ``min(Nc, Np)``).

    Attributes
    ----------
    a, b, c : augmented model (n+1 states).
    phi : ndarray, shape (Np, N)
        Wang's ``Φ`` (output response to ``η``).
    f : ndarray, shape (Np, n+1)
        Wang's ``F`` (free output response).
    omega, psi : ``Ω = ΦᵀΦ + R_L`` (N, N) and ``Ψ = ΦᵀF`` (N, n+1).
    gain_eta : ndarray, shape (N, n+1)
        ``Ω⁻¹Ψ``: unconstrained ``η = −gain_eta @ x̃``.
    gain : ndarray, shape (n+1,)
        ``K_mpc = L(0)ᵀΩ⁻¹Ψ``: first move ``Δu = −gain @ x̃``.
    """

    def __init__(
        self,
        a_m: ArrayLike,
        b_m: ArrayLike,
        c_m: ArrayLike,
        *,
        pole: float,
        n_terms: int,
        np_horizon: int = 10,
        nc_horizon: int | None = 10,
        r_l: float | ArrayLike = 1.0,
        delta_u_min: float | None = None,
        delta_u_max: float | None = None,
        u_min: float | None = None,
        u_max: float | None = None,
        n_constrained: int | None = None,
    ) -> None:
        am = np.atleast_2d(np.asarray(a_m, dtype=np.float64))
        n = am.shape[0]
        if am.shape != (n, n) or not np.all(np.isfinite(am)):
            raise ValueError(f"a_m must be a finite square matrix (got shape {am.shape})")
        bm = np.asarray(b_m, dtype=np.float64).reshape(-1)
        cm = np.asarray(c_m, dtype=np.float64).reshape(-1)
        if bm.shape != (n,) or cm.shape != (n,):
            raise ValueError(f"b_m and c_m must have {n} elements (single input and output)")
        if int(np_horizon) != np_horizon or np_horizon < 1:
            raise ValueError(f"np_horizon must be an integer ≥ 1 (got {np_horizon!r})")
        if nc_horizon is not None and (int(nc_horizon) != nc_horizon or nc_horizon < 1):
            raise ValueError(f"nc_horizon must be an integer ≥ 1 or None (got {nc_horizon!r})")
        laguerre_network(pole, n_terms)  # validates pole and n_terms
        self.pole = float(pole)
        self.n_terms = nt = int(n_terms)
        self.np_horizon = n_p = int(np_horizon)
        self.nc_horizon = n_p if nc_horizon is None else int(nc_horizon)
        n_moves = min(self.nc_horizon, n_p)
        # Augmented model.
        na = n + 1
        a = np.zeros((na, na))
        a[:n, :n] = am
        a[n, :n] = cm @ am
        a[n, n] = 1.0
        b = np.concatenate([bm, [cm @ bm]])
        c = np.zeros(na)
        c[n] = 1.0
        self.a, self.b, self.c = a, b, c
        self.n_model = n
        lseq = laguerre_sequence(pole, nt, max(n_p, 1))
        self.laguerre = lseq
        # S(m) recursion: S(m) = A S(m−1) + B L(m−1)ᵀ (the last term only for m−1 < Nc).
        s = np.zeros((na, nt))
        a_pow = np.eye(na)
        phi = np.zeros((n_p, nt))
        f = np.zeros((n_p, na))
        for m in range(1, n_p + 1):
            s = a @ s
            if m - 1 < n_moves:
                s += np.outer(b, lseq[m - 1])
            a_pow = a @ a_pow
            phi[m - 1] = c @ s
            f[m - 1] = c @ a_pow
        rl = np.asarray(r_l, dtype=np.float64)
        r_mat = rl * np.eye(nt) if rl.ndim == 0 else rl
        if r_mat.shape != (nt, nt) or not np.all(np.isfinite(r_mat)):
            raise ValueError(f"r_l must be a scalar or a finite ({nt}, {nt}) matrix")
        if not np.allclose(r_mat, r_mat.T) or np.min(np.linalg.eigvalsh(r_mat)) < 0.0:
            raise ValueError("r_l must be symmetric positive semi-definite")
        omega = phi.T @ phi + r_mat
        if np.min(np.linalg.eigvalsh(omega)) <= 1e-12 * max(1.0, float(np.max(np.abs(omega)))):
            raise ValueError("ΦᵀΦ + R_L is singular: increase r_l or reduce n_terms")
        self.phi, self.f, self.r_l = phi, f, r_mat
        self.omega = omega
        self.psi = phi.T @ f
        self.omega_inv = np.linalg.inv(omega)
        self.gain_eta = self.omega_inv @ self.psi
        self.gain = lseq[0] @ self.gain_eta
        self._gain_list: list[float] = self.gain.tolist()
        self._build_constraints(delta_u_min, delta_u_max, u_min, u_max, n_constrained, n_moves)

    # ---- constraints ---------------------------------------------------------------------
    def _build_constraints(
        self,
        du_min: float | None,
        du_max: float | None,
        u_min: float | None,
        u_max: float | None,
        n_constrained: int | None,
        n_moves: int,
    ) -> None:
        for name, v in (
            ("delta_u_min", du_min),
            ("delta_u_max", du_max),
            ("u_min", u_min),
            ("u_max", u_max),
        ):
            if v is not None and not math.isfinite(v):
                raise ValueError(f"{name} must be finite or None")
        if du_min is not None and du_max is not None and du_min > du_max:
            raise ValueError("delta_u_min must be ≤ delta_u_max")
        if u_min is not None and u_max is not None and u_min > u_max:
            raise ValueError("u_min must be ≤ u_max")
        nk = n_moves if n_constrained is None else int(n_constrained)
        if not 1 <= nk <= n_moves:
            raise ValueError(f"n_constrained must be in [1, {n_moves}] (got {n_constrained!r})")
        lseq = self.laguerre[:nk]
        cum = np.cumsum(lseq, axis=0)  # u(k+m) − u(k−1) = Σ_{i≤m} L(i)ᵀη
        rows: list[FloatArray] = []
        # gamma = g0 + g_u·u_prev (u bounds depend on the previous control)
        g0: list[float] = []
        gu: list[float] = []
        if du_max is not None:
            rows.append(lseq)
            g0 += [du_max] * nk
            gu += [0.0] * nk
        if du_min is not None:
            rows.append(-lseq)
            g0 += [-du_min] * nk
            gu += [0.0] * nk
        if u_max is not None:
            rows.append(cum)
            g0 += [u_max] * nk
            gu += [-1.0] * nk
        if u_min is not None:
            rows.append(-cum)
            g0 += [-u_min] * nk
            gu += [1.0] * nk
        self.constrained = bool(rows)
        if rows:
            self.m_con = np.vstack(rows)
            self._g0 = np.asarray(g0)
            self._gu = np.asarray(gu)
            # R⁻¹ for E = 2Ω = RᵀR (the QP's Hessian is constant) and the NNLS matrix
            # [Gᵀ; hᵀ] of the least-distance form, G = −M R⁻¹ (the last row changes per call).
            self._r_inv = np.linalg.inv(np.linalg.cholesky(2.0 * self.omega).T)
            nt = self.omega.shape[0]
            self._ldp_a = np.vstack([(-self.m_con @ self._r_inv).T, np.zeros(len(g0))])
            self._ldp_b = np.zeros(nt + 1)
            self._ldp_b[nt] = 1.0

        self.bounds = (du_min, du_max, u_min, u_max)

    # ---- solving -------------------------------------------------------------------------
    def augmented_error_state(self, dx_m: ArrayLike, y: float, r: float) -> FloatArray:
        """``x̃ = [Δx_m; y − r]``, shape (n+1,)."""
        dx = np.asarray(dx_m, dtype=np.float64).reshape(-1)
        if dx.shape != (self.n_model,):
            raise ValueError(f"dx_m must have {self.n_model} elements")
        return np.concatenate([dx, [y - r]])

    def cost(self, eta: ArrayLike, dx_m: ArrayLike, y: float, r: float) -> float:
        """P4's cost ``J(η)`` for the state ``[Δx_m; y]`` and the reference ``r``."""
        e = np.asarray(eta, dtype=np.float64)
        x = np.concatenate([np.asarray(dx_m, dtype=np.float64).reshape(-1), [y]])
        resid = r - self.f @ x - self.phi @ e
        return float(resid @ resid + e @ self.r_l @ e)

    def solve(
        self, dx_m: ArrayLike, y: float, r: float, u_prev: float = 0.0
    ) -> tuple[FloatArray, QpResult]:
        """Optimal ``η`` (with the bounds, if any).

        Parameters
        ----------
        dx_m : array_like, shape (n,)
            ``Δx_m(k) = x_m(k) − x_m(k−1)``.
        y : float
            Output ``y(k)``.
        r : float
            Reference (held constant over the horizon).
        u_prev : float
            ``u(k−1)`` (only used by amplitude bounds).

        Returns
        -------
        eta : ndarray, shape (N,)
        result : QpResult
        """
        xt = self.augmented_error_state(dx_m, y, r)
        if not self.constrained:
            return -self.gain_eta @ xt, QpResult(False, False, 0.0)
        gamma = self._g0 + self._gu * u_prev
        # J = ηᵀΩη + 2ηᵀΨx̃ + const: E = 2Ω, f = 2Ψx̃. Same algorithm as solve_qp, with the
        # constant parts (R⁻¹, G = −M R⁻¹, η₀ = −Ω⁻¹Ψx̃) precomputed.
        eta0 = -(self.gain_eta @ xt)
        m_eta0 = self.m_con @ eta0
        if np.all(m_eta0 <= gamma):
            return eta0, QpResult(False, False, float(np.max(m_eta0 - gamma)))
        relaxed = bool(np.any(gamma < 0.0))
        g_eff = np.maximum(gamma, 0.0) if relaxed else gamma
        a = self._ldp_a
        a[-1] = m_eta0 - g_eff
        w = np.asarray(_nnls(a, self._ldp_b)[0], dtype=np.float64)
        resid = a @ w - self._ldp_b
        eta = self._r_inv @ (-resid[:-1] / resid[-1]) + eta0
        return eta, QpResult(True, relaxed, float(np.max(self.m_con @ eta - g_eff)))

    def first_move(self, dx_m: ArrayLike, y: float, r: float, u_prev: float = 0.0) -> float:
        """Receding-horizon control increment ``Δu(k) = L(0)ᵀη`` (bounded if configured)."""
        if not self.constrained:
            return self.first_move_fast(np.asarray(dx_m, dtype=np.float64).tolist(), y - r)
        eta, _ = self.solve(dx_m, y, r, u_prev)
        return float(self.laguerre[0] @ eta)

    def first_move_fast(self, dx_m: list[float], y_minus_r: float) -> float:
        """Unconstrained ``Δu(k) = −K_mpc·x̃`` on plain floats (the hot path, ~1 µs).

        Parameters
        ----------
        dx_m : list of float, length n
            ``Δx_m(k)``.
        y_minus_r : float
            ``y(k) − r``.
        """
        g = self._gain_list
        acc = g[-1] * y_minus_r
        for i, v in enumerate(dx_m):
            acc += g[i] * v
        return -acc

    def closed_loop_poles(self) -> FloatArray:
        """Eigenvalues of the unconstrained closed loop ``A − B·K_mpc`` (augmented), complex."""
        return np.linalg.eigvals(self.a - np.outer(self.b, self.gain))
