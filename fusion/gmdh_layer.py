"""One layer of a GMDH network (:mod:`fusion.gmdh`): the input terms, the training /
validation split, fitting every pair-neuron of the layer at once, and choosing the survivors.

- The normal equations of every pair come from one moment matrix of the training part (one
  matrix product, :func:`fit_pairs`) and are solved with one batched ``numpy.linalg.solve``;
  ``λ = ridge · trace(G) / 6`` keeps singular systems (duplicated or constant inputs)
  solvable, and if a system still fails, the pseudo-inverse is used. Fitting never crashes on
  singular data; a neuron with non-finite output gets an infinite criterion and is dropped.
- A layer with a single input (one feature, or one survivor) has one neuron on the pair
  ``(u, u)``: a quadratic ``c0 + c1·u + c3·u²`` in that input (the duplicated monomials are
  dropped from its normal equations, so the printed polynomial shows no redundant terms).
- With product input terms, the first-layer pair ``(u_k, u_k·u_k)`` has ``a² = b``: its
  ``a²`` monomial is dropped (a quartic in ``u_k``), likewise without leaving it to the ridge.
- Input terms already paired with each other in layer 1 are not paired again in later
  layers (the same neurons); a later layer's neurons have at least one learned input.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.regressor_base import FloatArray

IntArray = NDArray[np.intp]

# Contiguous blocks of split="blocked".
_BLOCKS = 10
# Multiply-adds per matrix product below which OpenBLAS stays single-threaded.
_GEMM_SINGLE_THREAD = 200_000


@dataclass(frozen=True, slots=True, eq=False)  # arrays: no element-wise __eq__
class GmdhLayer:
    """One layer of polynomial neurons.

    Attributes
    ----------
    pairs : (k, 2) int
        Indices of each neuron's two inputs in the previous layer's outputs (layer 1: the
        standardised features). ``i == j`` marks a single-input quadratic neuron.
    coefs : (k, 6) float
        ``c0..c5`` of ``c0 + c1·a + c2·b + c3·a² + c4·b² + c5·a·b`` (standardised units).
    criterion : (k,) float
        Regularity criterion of each neuron: validation MSE in standardised target units.
    bounds : (k, 2) float or None
        ``[lo, hi]`` each neuron's output is clipped to at prediction (its range on the
        fitting data, widened by ``clip_margin``); None: no clipping (P0).
    """

    pairs: IntArray
    coefs: FloatArray
    criterion: FloatArray
    bounds: FloatArray | None = None


# Exponents (of a, of b) of the six monomials 1, a, b, a², b², ab.
_EXPONENTS = np.array([(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1)], dtype=np.intp)


def _gram_index(m: int, pairs: IntArray) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Where, in the moment matrix of :func:`fit_pairs`, each normal-equation entry sits.

    The moment matrix is ``BᵀB`` for ``B = [1, Z, Z², Z³, y·Z, y]`` (column blocks of width
    ``m``; ``1`` and ``y`` single columns). ``Σ a^p b^q`` with ``p, q ≤ 3`` is the entry
    (block p of column i, block q of column j); ``Σ a⁴`` is (a², a²). Returns row / column
    indices of the ``(k, 6, 6)`` Gram matrices and of the ``(k, 6)`` right-hand sides.
    """

    def col(power: IntArray, idx: IntArray) -> IntArray:
        # block 0 is the single ones column; blocks 1..3 are Z, Z², Z³
        return np.where(power == 0, 0, 1 + (power - 1) * m + idx)

    i = pairs[:, 0][:, None, None]
    j = pairs[:, 1][:, None, None]
    e = _EXPONENTS[None, :, None, :] + _EXPONENTS[None, None, :, :]  # (1, 6, 6, 2)
    p = np.broadcast_to(e[..., 0], (len(pairs), 6, 6))
    q = np.broadcast_to(e[..., 1], (len(pairs), 6, 6))
    ii = np.broadcast_to(i, p.shape)
    jj = np.broadcast_to(j, p.shape)
    # split Σ a^p b^q into (row factor, column factor), each power ≤ 3: a pure power
    # a^p is split as a^min(p,2) · a^(p−min(p,2)) (so a⁴ = a²·a²), likewise b^q
    p_row = np.minimum(p, 2)
    q_row = np.minimum(q, 2)
    row = np.where(q == 0, col(p_row, ii), np.where(p == 0, col(q_row, jj), col(p, ii)))
    column = np.where(q == 0, col(p - p_row, ii), np.where(p == 0, col(q - q_row, jj), col(q, jj)))
    # right-hand side Σ y·monomial: y·a^p·b^q with p + q ≤ 2
    y_block = 1 + 3 * m  # first column of y·Z
    y_col = 1 + 4 * m  # the y column
    ep, eq = _EXPONENTS[:, 0][None, :], _EXPONENTS[:, 1][None, :]
    i2, j2 = pairs[:, 0][:, None], pairs[:, 1][:, None]
    # y·1 → (y, 1); y·a → (y, a); y·b → (y, b); y·a² → (y·a, a); y·b² → (y·b, b);
    # y·ab → (y·a, b)
    r_row = np.where(ep + eq <= 1, y_col, np.where(ep > 0, y_block + i2, y_block + j2))
    r_col = np.where(
        ep + eq == 0,
        0,
        np.where(
            ep + eq == 1, np.where(ep == 1, 1 + i2, 1 + j2), np.where(eq == 0, 1 + i2, 1 + j2)
        ),
    )
    return row, column, r_row.astype(np.intp), r_col.astype(np.intp)


def eval_neurons(Z: FloatArray, pairs: IntArray, coefs: FloatArray) -> FloatArray:
    """Outputs ``(n, k)`` of neurons ``(pairs, coefs)`` on layer inputs ``Z`` ``(n, m)``."""
    a = Z[:, pairs[:, 0]]
    b = Z[:, pairs[:, 1]]
    c = coefs.T[:, None, :]  # (6, 1, k) broadcast over samples
    return c[0] + a * (c[1] + c[3] * a + c[5] * b) + b * (c[2] + c[4] * b)


def _solve_batched(G: FloatArray, r: FloatArray, ridge: float) -> FloatArray:
    """Solve ``(G_p + λ_p I) c_p = r_p`` for a stack of 6×6 systems, never raising."""
    lam = ridge * np.trace(G, axis1=1, axis2=2) / G.shape[1] + 1e-300
    A = G + lam[:, None, None] * np.eye(G.shape[1])
    try:
        c = np.linalg.solve(A, r[..., None])[..., 0]
    except np.linalg.LinAlgError:
        # exactly singular even with the ridge (e.g. ridge=0 on constant inputs)
        c = (np.linalg.pinv(A) @ r[..., None])[..., 0]
    return c


def _moments(Z: FloatArray, y: FloatArray, lead: int = 0) -> FloatArray:
    """Moment matrix ``BᵀB`` of ``B = [1, Z, Z², Z³, y·Z, y]`` (see :func:`_gram_index`).

    ``lead > 0``: only what pairs whose first input is one of the first ``lead`` columns
    need (a later layer: a learned neuron with any input): the rows of the ones column, of
    the ``y`` column and of every block of the lead columns, and each other column's own
    ``Σz³``, ``Σz⁴``, ``Σy·z²``; the cross moments of two input terms stay 0, unused.
    """
    n, m = Z.shape
    B = np.empty((n, 4 * m + 2))
    B[:, 0] = 1.0
    B[:, 1 : 1 + m] = Z
    np.multiply(Z, Z, out=B[:, 1 + m : 1 + 2 * m])
    np.multiply(B[:, 1 + m : 1 + 2 * m], Z, out=B[:, 1 + 2 * m : 1 + 3 * m])
    np.multiply(Z, y[:, None], out=B[:, 1 + 3 * m : 1 + 4 * m])
    B[:, 1 + 4 * m] = y
    # Accumulate over row blocks small enough that OpenBLAS runs each product on one thread
    # (its threshold is m·n·k ≈ 2.6e5): the product is tiny, and handing it to a second
    # thread on a busy machine costs far more than computing it.
    c = B.shape[1]
    if lead > 0:
        ks = np.arange(lead)
        R = np.concatenate([[0], 1 + ks, 1 + m + ks, 1 + 2 * m + ks, 1 + 3 * m + ks, [c - 1]])
        BR = B[:, R]
        rows = max(32, _GEMM_SINGLE_THREAD // (c * len(R)))
        part = np.zeros((len(R), c))
        for start in range(0, n, rows):
            part += BR[start : start + rows].T @ B[start : start + rows]
        S: FloatArray = np.zeros((c, c))
        S[R, :] = part
        S[:, R] = part.T
        j = np.arange(lead, m)
        Z1, Z2 = B[:, 1 + j], B[:, 1 + m + j]
        z3 = np.einsum("ij,ij->j", Z2, Z1)
        z4 = np.einsum("ij,ij->j", Z2, Z2)
        yz2 = np.einsum("ij,ij->j", B[:, 1 + 3 * m + j], Z1)
        S[1 + m + j, 1 + j] = S[1 + j, 1 + m + j] = z3
        S[1 + m + j, 1 + m + j] = z4
        S[1 + 3 * m + j, 1 + j] = S[1 + j, 1 + 3 * m + j] = yz2
        return S
    rows = max(32, _GEMM_SINGLE_THREAD // (c * c))
    S = np.zeros((c, c))
    for start in range(0, n, rows):
        block = B[start : start + rows]
        S += block.T @ block
    return S


def fit_pairs(
    Zt: FloatArray,
    yt: FloatArray,
    Zv: FloatArray,
    yv: FloatArray,
    pairs: IntArray,
    ridge: float,
    square: NDArray[np.bool_] | None = None,
    lead: int = 0,
) -> tuple[FloatArray, FloatArray]:
    """Fit all pair-neurons on the training part and estimate their regularity criterion.

    The normal equations of every pair come from one moment matrix of the training part
    (a single GEMM, ``O(n·m²)``) instead of a per-pair design matrix; the validation MSE of
    every pair comes the same way from the validation moments,
    ``(cᵀG_v c − 2cᵀr_v + Σy²) / n_v``. That form loses relative precision for near-perfect
    fits, so it only ranks candidates; survivors are re-scored exactly by the caller.
    ``square`` marks pairs whose second input is the square of the first (input terms
    ``u_k`` and ``u_k·u_k``). Returns coefficients ``(k, 6)`` and estimated criteria ``(k,)``
    (inf where non-finite).
    """
    m = Zt.shape[1]
    row, column, r_row, r_col = _gram_index(m, pairs)
    St = _moments(Zt, yt, lead)
    Sv = _moments(Zv, yv, lead)
    G = St[row, column]
    r = St[r_row, r_col]
    single = pairs[:, 0] == pairs[:, 1]
    if single.any():
        # (u, u): b duplicates a, so keep only 1, u, u² (c2 = c4 = c5 = 0) instead of leaving
        # the rank deficiency to the ridge
        dup = np.array([2, 4, 5])
        every = np.arange(6)
        G[np.ix_(single, dup, every)] = 0.0
        G[np.ix_(single, every, dup)] = 0.0
        G[np.ix_(single, dup, dup)] = np.eye(3)
        r[np.ix_(single, dup)] = 0.0
    if square is not None and square.any():
        # (u, u²): b duplicates a², so drop a² (c3 = 0): a quartic in u without the rank
        # deficiency
        G[square, 3, :] = 0.0
        G[square, :, 3] = 0.0
        G[square, 3, 3] = 1.0
        r[square, 3] = 0.0
    with np.errstate(all="ignore"):
        coefs = _solve_batched(G, r, ridge)
        Gv = Sv[row, column]
        rv = Sv[r_row, r_col]
        yy = Sv[-1, -1]
        quad = np.einsum("ki,kij,kj->k", coefs, Gv, coefs)
        crit = np.maximum(quad - 2.0 * np.einsum("ki,ki->k", coefs, rv) + yy, 0.0) / len(yv)
    crit = np.where(np.isfinite(crit) & np.isfinite(coefs).all(axis=1), crit, np.inf)
    return coefs, crit


def threshold_count(crit: FloatArray, alpha: float) -> int:
    """How many neurons pass P0's rule: criterion ≤ ``e_c = α·e_min + (1−α)·e_max``."""
    finite = crit[np.isfinite(crit)]
    if finite.size == 0:
        return 0
    e_min, e_max = float(finite.min()), float(finite.max())
    e_c = alpha * e_min + (1.0 - alpha) * e_max
    # a hair of slack so that alpha = 1 keeps the best neuron despite rounding in e_c
    return int(np.count_nonzero(crit <= e_c + 1e-12 * max(abs(e_c), 1e-300)))


def survivors(resid: FloatArray, n_keep: int, max_correlation: float) -> IntArray:
    """Pick ``n_keep`` survivors from candidates sorted best first, given their validation
    errors ``resid`` ``(n_val, k)``.

    Half the places (rounded up) go by the criterion, best first; the other half to the
    neurons that best explain what the best neuron leaves (largest ``|corr(z_c, r_best)|``
    on the validation part, ``z_c = r_c + y`` up to a constant): the next layer pairs them
    with it. Either way a neuron whose error correlates above ``max_correlation`` with a
    kept one's is a near-duplicate (combining the two gains nothing) and is skipped; if too
    few are distinct, the skipped ones fill up, best first, so a layer is never starved.
    Returns the picked columns, sorted (best first).
    """
    k = resid.shape[1]
    n_keep = min(n_keep, k)
    with np.errstate(all="ignore"):
        centred = resid - resid.mean(axis=0)
        norm = np.sqrt(np.einsum("ij,ij->j", centred, centred))
        unit = np.where(norm > 0.0, centred / np.where(norm > 0.0, norm, 1.0), 0.0)
        # z_c − z_best = r_c − r_best; corr(z_c, r_best) from centred errors
        r0 = centred[:, 0]
        dz = centred - r0[:, None]
        dz_norm = np.sqrt(np.einsum("ij,ij->j", dz, dz))
        gain = np.abs(dz.T @ r0) / np.where(dz_norm > 0.0, dz_norm, np.inf)
    gain = np.where(np.isfinite(gain), gain, 0.0)
    kept: list[int] = []
    skipped: list[int] = []

    def distinct(c: int) -> bool:
        return not kept or float(np.max(np.abs(unit[:, kept].T @ unit[:, c]))) <= max_correlation

    n_by_criterion = (n_keep + 1) // 2
    for c in range(k):
        if len(kept) == n_by_criterion:
            break
        (kept if distinct(c) else skipped).append(c)
    for c in np.argsort(-gain, kind="stable").tolist():
        if len(kept) == n_keep:
            break
        if c in kept or c in skipped:
            continue
        (kept if distinct(c) else skipped).append(c)
    for c in skipped + list(range(k)):
        if len(kept) == n_keep:
            break
        if c not in kept:
            kept.append(c)
    return np.array(sorted(kept), dtype=np.intp)


def pairs_for(n_neurons: int, n_pool: int) -> IntArray:
    """Neuron input pairs of a layer whose inputs are ``n_neurons`` previous-layer outputs
    followed by ``n_pool`` input terms: every pair with at least one previous-layer output
    (pairs of input terms alone were all tried in the first layer). Layer 1, or a layer
    without the input pool: every pair, or ``(0, 0)`` if there is a single input."""
    if n_neurons == 0 or n_pool == 0:
        m = n_neurons + n_pool
        if m == 1:
            return np.zeros((1, 2), dtype=np.intp)
        return np.array(list(itertools.combinations(range(m), 2)), dtype=np.intp)
    m = n_neurons + n_pool
    return np.array(
        [(i, j) for i, j in itertools.combinations(range(m), 2) if i < n_neurons],
        dtype=np.intp,
    )


def pool_terms(n_features: int, inputs: str) -> IntArray:
    """The input terms offered to the network, ``(P, 2)``: ``(k, -1)`` is standardised
    feature ``u_k``; ``(i, j)`` with ``j ≥ 0`` is the product ``u_i·u_j`` (``inputs`` =
    ``"quadratic"``: every ``i ≤ j``)."""
    terms = [(k, -1) for k in range(n_features)]
    if inputs == "quadratic":
        terms += [(i, j) for i in range(n_features) for j in range(i, n_features)]
    return np.array(terms, dtype=np.intp).reshape(-1, 2)


def square_pairs(pool: IntArray, pairs: IntArray) -> NDArray[np.bool_]:
    """First-layer pairs ``(u_k, u_k·u_k)`` of input terms (see :func:`pool_terms`)."""
    a, b = pool[pairs[:, 0]], pool[pairs[:, 1]]
    return (a[:, 1] < 0) & (b[:, 0] == a[:, 0]) & (b[:, 1] == a[:, 0])


def pool_values(U: FloatArray, terms: IntArray) -> FloatArray:
    """Columns of the input terms (see :func:`pool_terms`) on standardised features ``U``."""
    linear = terms[:, 1] < 0
    if linear.all():
        return U[:, terms[:, 0]]
    out = np.empty((U.shape[0], terms.shape[0]))
    out[:, linear] = U[:, terms[linear, 0]]
    prod = ~linear
    out[:, prod] = U[:, terms[prod, 0]] * U[:, terms[prod, 1]]
    return out


def split_masks(n: int, fraction: float, split: str, random_state: Any) -> NDArray[np.bool_]:
    """Boolean validation mask of length ``n`` (≥ 1 validation and ≥ 1 training sample)."""
    n_val = min(max(round(fraction * n), 1), n - 1)
    mask = np.zeros(n, dtype=bool)
    if split == "tail":
        mask[n - n_val :] = True
    elif split == "random":
        rng = np.random.default_rng(random_state)
        mask[rng.choice(n, size=n_val, replace=False)] = True
    elif split == "blocked":
        # contiguous blocks, the validation blocks spread evenly (the interleaved rule on
        # blocks): neighbours of an autocorrelated series mostly fall in the same part
        n_blocks = min(_BLOCKS, n)
        edges = np.round(np.linspace(0.0, n, n_blocks + 1)).astype(np.intp)
        val_blocks = _interleaved(n_blocks, min(max(round(fraction * n_blocks), 1), n_blocks - 1))
        for b in np.flatnonzero(val_blocks):
            mask[edges[b] : edges[b + 1]] = True
    else:  # interleaved: evenly spread, the classic GMDH alternating split
        mask = _interleaved(n, n_val)
    return mask


def _interleaved(n: int, n_val: int) -> NDArray[np.bool_]:
    mask = np.zeros(n, dtype=bool)
    mask[np.unique(np.floor((np.arange(n_val) + 0.5) * n / n_val).astype(np.intp))] = True
    return mask
