"""Multilayer GMDH polynomial network, a regressor with scikit-learn's contract; paper P0's
network as a preset.

GMDH (Group Method of Data Handling, Ivakhnenko) builds a polynomial network layer by layer:

1. every pair ``(i, j)`` of the layer's inputs gets a quadratic *neuron*
   ``z = c0 + c1·a + c2·b + c3·a² + c4·b² + c5·a·b`` (``a = input i``, ``b = input j``),
   its coefficients fitted by least squares on the *training* part of the data;
2. each neuron is scored by an *external* criterion, the regularity criterion: its mean
   squared error on the *validation* part, data it was not fitted on;
3. survivors: P0 removes the neurons whose criterion exceeds
   ``e_c = α·e_min + (1 − α)·e_max`` (``α = 1`` keeps only the best, ``α = 0`` all) and keeps
   at most ``max_neurons`` of the best; the defaults keep at least ``min_survivors`` too,
   half by criterion and half by how much of the best neuron's validation error they explain
   (the next layer pairs them with it), and skip near-duplicates (validation errors
   correlated above ``max_correlation``);
4. layer inputs: P0 feeds layer k + 1 with the survivors of layer k only; the defaults also
   offer every layer the standardised features and their products ``u_i·u_j`` (the *input
   terms*), so a neuron can pair a learned neuron with a raw input;
5. layers are added while the best criterion of a layer improves on the previous layer's
   (relative improvement ``> tol`` and, by default, more than ``significance`` standard
   errors of the paired per-sample gain), up to ``max_layers``; the model is the best neuron
   of the last accepted layer, and only the neurons it depends on are kept for prediction;
   by default each neuron's output is clipped at prediction to its fitted range, widened
   by ``clip_margin``.

Why the defaults differ from P0 (issue 18): on ``y = 1 + 2 x0 − x1 + 0.5 x0 x2 − 0.8 x3²``
(6 inputs, noise 0.02) P0's rule left 5, 4, 3, 2, 1 survivors and 0.27 RMSE against 0.020
for polynomial ridge; on ``(x0 x1 + 0.5 x2)² − x3 x4`` no neuron fitted to the target carries
``x0 x1`` (the target has no quadratic component along it) until the product is offered as
an input term. ``GmdhRegressor.paper()`` is P0 (5 layers, 10 neurons, ``α = 0.6``, features
in layer 1 only, interleaved split), bit for bit the earlier behaviour; the bridging methods
use it. ``bench/gmdh_quality.py`` compares both with ridge and an MLP.

Implementation notes
--------------------
- Inputs and target are standardised inside :meth:`GmdhRegressor.fit`; neurons work on the
  standardised values ``u_k = (x_k − x_mean_k) / x_scale_k``. A constant column gets scale 1
  (it becomes all zeros, so its neurons are just rank-deficient and the ridge handles them).
- All pair-neurons of a layer are fitted at once: the six monomials of every pair are stacked
  into a ``(n_pairs, 6, n_train)`` array, the normal equations ``(MMᵀ + λI) c = M y`` are
  formed with one batched matmul and solved with one batched ``numpy.linalg.solve``.
  ``λ = ridge · trace(MMᵀ) / 6`` keeps singular systems (duplicated or constant inputs)
  solvable; if a system still fails, the pseudo-inverse is used. Fitting never crashes on
  singular data; a neuron with non-finite output gets an infinite criterion and is dropped.
- A layer with a single input (one feature, or one survivor) has one neuron on the pair
  ``(u, u)``: a quadratic ``c0 + c1·u + c3·u²`` in that input (the duplicated monomials are
  dropped from its normal equations, so the printed polynomial shows no redundant terms).
- With product input terms, the first-layer pair ``(u_k, u_k·u_k)`` has ``a² = b``: its
  ``a²`` monomial is dropped (a quartic in ``u_k``), likewise without leaving it to the ridge.
- Input terms already paired with each other in layer 1 are not paired again in later
  layers (the same neurons); a later layer's neurons have at least one learned input.
- :meth:`GmdhRegressor.predict_one` evaluates the pruned network on one sample with plain
  Python floats (no numpy dispatch): the neurons' inputs and coefficients are laid out as
  float tuples at fit time and evaluated in a loop, with the same operations in the same
  order as the batch path.

The estimator plumbing (scikit-learn contract, input validation, standardisation) is
:class:`fusion.regressor_base.RegressorBase`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.regressor_base import FloatArray, RegressorBase

IntArray = NDArray[np.intp]

_SPLITS = ("interleaved", "blocked", "tail", "random")
_INPUTS = ("first-layer", "every-layer", "quadratic")
# Contiguous blocks of split="blocked".
_BLOCKS = 10
# The survivors (diversity on) are picked among this many times max_neurons candidates, best
# estimated criterion first.
_CANDIDATES = 8
# A validation MSE below this share of the target variance (relative RMS error 1e-6) counts
# as an exact fit: further layers could only fit rounding and the ridge's bias.
_EXACT_FIT = 1e-12
# Batches up to this many rows are predicted row by row with the scalar path.
_FEW_ROWS = 8
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
    """Where, in the moment matrix of :func:`_fit_pairs`, each normal-equation entry sits.

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


def _eval_neurons(Z: FloatArray, pairs: IntArray, coefs: FloatArray) -> FloatArray:
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
    # thread on a busy 2-core machine cost 100+ ms per call instead of < 1 ms.
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


def _fit_pairs(
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


def _threshold_count(crit: FloatArray, alpha: float) -> int:
    """How many neurons pass P0's rule: criterion ≤ ``e_c = α·e_min + (1−α)·e_max``."""
    finite = crit[np.isfinite(crit)]
    if finite.size == 0:
        return 0
    e_min, e_max = float(finite.min()), float(finite.max())
    e_c = alpha * e_min + (1.0 - alpha) * e_max
    # a hair of slack so that alpha = 1 keeps the best neuron despite rounding in e_c
    return int(np.count_nonzero(crit <= e_c + 1e-12 * max(abs(e_c), 1e-300)))


def _survivors(resid: FloatArray, n_keep: int, max_correlation: float) -> IntArray:
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


def _pairs_for(n_neurons: int, n_pool: int) -> IntArray:
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


def _pool_terms(n_features: int, inputs: str) -> IntArray:
    """The input terms offered to the network, ``(P, 2)``: ``(k, -1)`` is standardised
    feature ``u_k``; ``(i, j)`` with ``j ≥ 0`` is the product ``u_i·u_j`` (``inputs`` =
    ``"quadratic"``: every ``i ≤ j``)."""
    terms = [(k, -1) for k in range(n_features)]
    if inputs == "quadratic":
        terms += [(i, j) for i in range(n_features) for j in range(i, n_features)]
    return np.array(terms, dtype=np.intp).reshape(-1, 2)


def _square_pairs(pool: IntArray, pairs: IntArray) -> NDArray[np.bool_]:
    """First-layer pairs ``(u_k, u_k·u_k)`` of input terms (see :func:`_pool_terms`)."""
    a, b = pool[pairs[:, 0]], pool[pairs[:, 1]]
    return (a[:, 1] < 0) & (b[:, 0] == a[:, 0]) & (b[:, 1] == a[:, 0])


def _pool_values(U: FloatArray, terms: IntArray) -> FloatArray:
    """Columns of the input terms (see :func:`_pool_terms`) on standardised features ``U``."""
    linear = terms[:, 1] < 0
    if linear.all():
        return U[:, terms[:, 0]]
    out = np.empty((U.shape[0], terms.shape[0]))
    out[:, linear] = U[:, terms[linear, 0]]
    prod = ~linear
    out[:, prod] = U[:, terms[prod, 0]] * U[:, terms[prod, 1]]
    return out


def _split_masks(n: int, fraction: float, split: str, random_state: Any) -> NDArray[np.bool_]:
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


class GmdhRegressor(RegressorBase):
    """Multilayer GMDH network of Ivakhnenko quadratic neurons.

    The defaults are a regressor that holds its own against polynomial ridge and an MLP
    (``bench/gmdh_quality.py``); :meth:`paper` gives P0's settings (the papers' comparisons in
    :mod:`fusion.bridging` use them).

    Parameters
    ----------
    max_layers : int, default 8
        Maximum number of layers.
    max_neurons : int, default 12
        Maximum number of survivors per layer (the neuron inputs of the next layer).
    alpha : float in [0, 1], default 0.6
        Selection pressure: survivors have criterion ≤ ``α·e_min + (1−α)·e_max`` ...
    min_survivors : int ≥ 1, default 12
        ... but at least this many survive (at most ``max_neurons``; fewer only if fewer
        neurons have a finite criterion), so the selection never narrows a layer to a chain.
        P0: 1 (the rule alone, which on a 6-input problem left 5, 4, 3, 2, 1 survivors).
    max_correlation : float in (0, 1], default 0.995
        Diversity of the survivors: a neuron whose validation error correlates above this
        with a better survivor's is a near-duplicate and is skipped (unless too few are
        distinct). 1 disables the check (P0).
    inputs : {"every-layer", "quadratic", "first-layer"}, default "quadratic"
        Where the standardised features enter: ``"first-layer"`` (P0: layer k sees only the
        survivors of layer k − 1); ``"every-layer"``: every layer's neurons may also pair a
        learned neuron with a raw feature; ``"quadratic"``: as ``"every-layer"``, and the
        products ``u_i·u_j`` (``i ≤ j``) are offered as raw terms too. Neurons fitted to
        the target never carry an intermediate such as ``x0·x1`` when the target has no
        quadratic component along it (``(x0·x1 + x2)²``): offering the products lets a
        neuron square them.
    validation_fraction : float in (0, 1), default 0.3
        Share of the samples held out for the regularity criterion.
    split : {"blocked", "interleaved", "tail", "random"}, default "blocked"
        How the validation part is chosen: ``"blocked"``: 10 contiguous blocks, the
        validation blocks spread evenly (honest for autocorrelated series: a validation
        sample's neighbours are mostly validation samples too); ``"interleaved"``: evenly
        interleaved samples (P0; neighbours of a smooth series leak into the criterion);
        ``"tail"``: the last samples in time (the strictest test of extrapolation);
        ``"random"``: a random subset drawn with ``random_state``.
    tol : float ≥ 0, default 1e-3
        A new layer is kept only if it lowers the best criterion by more than this fraction
        ...
    significance : float ≥ 0, default 2.0
        ... and by more than this many standard errors of the paired per-sample difference
        of squared validation errors (new best neuron against the previous layer's): the
        layer's best is the best of many candidates on the same validation samples, so a
        smaller gain is selection luck (on a linear target the criterion kept "improving"
        0.5 % a layer for 7 layers). Building stops when the external criterion stops
        improving. 0 disables the test (P0).
    clip_margin : float ≥ 0 or None, default 0.1
        At prediction each neuron's output is clipped to its range on the fitting data,
        widened by this share of the range on either side. A network of 8 quadratic layers
        is a polynomial of degree up to 2⁸: outside the data it was fitted on (a flight
        leaving the trained envelope) an unclipped one can reach 1e250. None: no clipping
        (P0).
    ridge : float ≥ 0, default 1e-8
        Relative ridge ``λ = ridge·trace(G)/6`` on each neuron's normal equations.
    random_state : int, numpy Generator or None, default 0
        Seed for ``split="random"`` (unused otherwise).

    Attributes
    ----------
    n_features_in_ : int
    x_mean_, x_scale_ : (n_features,) float
        Input standardisation ``u = (x − x_mean_) / x_scale_``.
    y_mean_, y_scale_ : float
        Target standardisation; the network output ``z`` maps to ``y_mean_ + y_scale_·z``.
    pool_ : (P, 2) int
        The input terms (see ``inputs``): ``(k, -1)`` is ``u_k``, ``(i, j)`` is ``u_i·u_j``.
        Layer 1's inputs are these terms; a later layer's inputs are the previous layer's
        survivors, followed by these terms unless ``inputs="first-layer"``.
    layers_ : list of GmdhLayer
        All survivors of every accepted layer.
    network_ : list of GmdhLayer
        The pruned network: only neurons the output depends on; the last layer has one.
    n_layers_ : int
        Number of accepted layers.
    criterion_ : (n_layers_,) float
        Best regularity criterion per accepted layer, validation MSE in target units².
    """

    def __init__(
        self,
        max_layers: int = 8,
        max_neurons: int = 12,
        alpha: float = 0.6,
        min_survivors: int = 12,
        max_correlation: float = 0.995,
        inputs: str = "quadratic",
        validation_fraction: float = 0.3,
        split: str = "blocked",
        tol: float = 1e-3,
        significance: float = 2.0,
        clip_margin: float | None = 0.1,
        ridge: float = 1e-8,
        random_state: int | None = 0,
    ) -> None:
        self.max_layers = max_layers
        self.max_neurons = max_neurons
        self.alpha = alpha
        self.min_survivors = min_survivors
        self.max_correlation = max_correlation
        self.inputs = inputs
        self.validation_fraction = validation_fraction
        self.split = split
        self.tol = tol
        self.significance = significance
        self.clip_margin = clip_margin
        self.ridge = ridge
        self.random_state = random_state

    @classmethod
    def paper(cls, **overrides: Any) -> GmdhRegressor:
        """P0's GMDH: 5 layers, 10 neurons, ``α = 0.6`` alone deciding the survivors, no
        diversity check, features in the first layer only, interleaved split.

        Parameters
        ----------
        **overrides
            Any constructor parameter, applied on top of the preset (e.g. ``split="tail"``).

        Returns
        -------
        GmdhRegressor
        """
        params: dict[str, Any] = {
            "max_layers": 5, "max_neurons": 10, "alpha": 0.6, "min_survivors": 1,
            "max_correlation": 1.0, "inputs": "first-layer", "split": "interleaved",
            "significance": 0.0, "clip_margin": None,
        }  # fmt: skip
        params.update(overrides)
        return cls(**params)

    # -- fitting ---------------------------------------------------------------------------
    def _check_params(self) -> None:
        def bad(name: str, rule: str) -> ValueError:
            return ValueError(
                f"GmdhRegressor: parameter {name}={getattr(self, name)!r} must be {rule}."
            )

        if not _is_int(self.max_layers) or self.max_layers < 1:
            raise bad("max_layers", "an integer >= 1")
        if not _is_int(self.max_neurons) or self.max_neurons < 1:
            raise bad("max_neurons", "an integer >= 1")
        if not _is_real(self.alpha) or not 0.0 <= self.alpha <= 1.0:
            raise bad("alpha", "a number in [0, 1]")
        if not _is_int(self.min_survivors) or self.min_survivors < 1:
            raise bad("min_survivors", "an integer >= 1")
        if not _is_real(self.max_correlation) or not 0.0 < self.max_correlation <= 1.0:
            raise bad("max_correlation", "a number in (0, 1]")
        if self.inputs not in _INPUTS:
            raise bad("inputs", f"one of {_INPUTS}")
        if not _is_real(self.validation_fraction) or not 0.0 < self.validation_fraction < 1.0:
            raise bad("validation_fraction", "a number in (0, 1)")
        if self.split not in _SPLITS:
            raise bad("split", f"one of {_SPLITS}")
        if not _is_real(self.tol) or not 0.0 <= self.tol < 1.0:
            raise bad("tol", "a number in [0, 1)")
        if not _is_real(self.significance) or self.significance < 0.0:
            raise bad("significance", "a number >= 0")
        if self.clip_margin is not None and (
            not _is_real(self.clip_margin) or self.clip_margin < 0.0
        ):
            raise bad("clip_margin", "None or a number >= 0")
        if not _is_real(self.ridge) or not 0.0 <= self.ridge < 1.0:
            raise bad("ridge", "a number in [0, 1)")

    def fit(self, X: ArrayLike, y: ArrayLike) -> Self:
        """Build the network on ``(X, y)``.

        Parameters
        ----------
        X : (n_samples, n_features) array_like
            Finite real features (any units; standardised internally).
        y : (n_samples,) array_like
            Finite real target.

        Returns
        -------
        self
        """
        self._check_params()
        U, v, sc = self._standardised_fit_data(X, y, min_samples=2)
        val = _split_masks(len(v), float(self.validation_fraction), self.split, self.random_state)
        pool = _pool_terms(U.shape[1], str(self.inputs))
        reuse = self.inputs != "first-layer"
        Pt, Pv = _pool_values(U[~val], pool), _pool_values(U[val], pool)
        yt, yv = v[~val], v[val]
        n_keep_max = int(self.max_neurons)
        n_keep_min = min(int(self.min_survivors), n_keep_max)
        diverse = float(self.max_correlation) < 1.0

        layers: list[GmdhLayer] = []
        best: list[float] = []
        r_prev = np.zeros(0)  # validation error of the previous layer's best neuron
        Zt, Zv = Pt, Pv  # layer inputs: layer 1 sees the input terms
        for _ in range(int(self.max_layers)):
            n_prev = layers[-1].pairs.shape[0] if layers else 0
            pairs = _pairs_for(n_prev, pool.shape[0] if (reuse or not layers) else 0)
            square = None if layers else _square_pairs(pool, pairs)
            # a later layer with input terms: every pair starts with a learned neuron
            lead = n_prev if (reuse and layers) else 0
            coefs, crit = _fit_pairs(Zt, yt, Zv, yv, pairs, float(self.ridge), square, lead)
            n_finite = int(np.count_nonzero(np.isfinite(crit)))
            n_keep = min(max(_threshold_count(crit, float(self.alpha)), n_keep_min), n_keep_max)
            n_keep = min(n_keep, n_finite)
            if n_keep == 0:
                break
            # candidates, best estimated criterion first; P0 re-scores only its survivors,
            # the diversity check looks further down the ranking for distinct neurons
            order = np.argsort(crit, kind="stable")
            n_cand = min(n_finite, _CANDIDATES * n_keep_max) if diverse else n_keep
            cand = order[:n_cand]
            # exact regularity criterion of the candidates (the survivors' validation outputs
            # are the next layer's inputs anyway); best first
            Zv_cand = _eval_neurons(Zv, pairs[cand], coefs[cand])
            with np.errstate(all="ignore"):
                resid = Zv_cand - yv[:, None]
                exact = np.mean(resid**2, axis=0)
            exact = np.where(np.isfinite(exact), exact, np.inf)
            rank = np.argsort(exact, kind="stable")
            cand, Zv_cand, exact, resid = cand[rank], Zv_cand[:, rank], exact[rank], resid[:, rank]
            if diverse:
                pick = _survivors(resid[:, np.isfinite(exact)], n_keep, float(self.max_correlation))
            else:
                pick = np.arange(n_keep)
            keep, Zv_next, exact = cand[pick], Zv_cand[:, pick], exact[pick]
            e_best = float(exact[0])
            if not np.isfinite(e_best):
                break
            if best and not e_best < best[-1] * (1.0 - float(self.tol)):
                break  # the external criterion stopped improving: keep the previous layer
            r_best = Zv_next[:, 0] - yv
            if best and float(self.significance) > 0.0:
                # paired per-sample improvement over the previous layer's best neuron: the
                # criterion is the best of many candidates on the same validation samples,
                # so a gain within its sampling noise is selection, not a better model
                d = r_prev**2 - r_best**2
                se = float(np.std(d)) / math.sqrt(len(d))
                if not float(np.mean(d)) > float(self.significance) * se:
                    break
            r_prev = r_best
            Zt_next = _eval_neurons(Zt, pairs[keep], coefs[keep])
            bounds = None
            if self.clip_margin is not None:
                lo = np.minimum(Zt_next.min(axis=0), Zv_next.min(axis=0))
                hi = np.maximum(Zt_next.max(axis=0), Zv_next.max(axis=0))
                pad = float(self.clip_margin) * (hi - lo)
                bounds = np.column_stack([lo - pad, hi + pad])
            layer = GmdhLayer(pairs[keep], coefs[keep], exact, bounds)
            layers.append(layer)
            best.append(e_best)
            if e_best <= _EXACT_FIT:
                break  # nothing left for another layer to improve but rounding
            if reuse:
                Zt, Zv = np.hstack([Zt_next, Pt]), np.hstack([Zv_next, Pv])
            else:
                Zt, Zv = Zt_next, Zv_next

        if not layers:
            # every neuron non-finite: only possible with pathological ridge=0 inputs
            raise ValueError("GmdhRegressor: no neuron of the first layer could be fitted.")

        self._store_scaling(sc)
        self.pool_ = pool
        self._reuse = reuse
        self.layers_ = layers
        self.n_layers_ = len(layers)
        self.criterion_ = np.array(best) * self.y_scale_**2
        self.network_ = _prune(layers, pool.shape[0] if reuse else 0)
        self._fast = _ScalarNetwork(
            self.network_, pool, reuse, sc.x_mean, sc.x_scale, self.y_mean_, self.y_scale_
        )
        return self

    # -- prediction ------------------------------------------------------------------------
    def predict(self, X: ArrayLike) -> FloatArray:
        """Predict the target for every row of ``X``.

        Parameters
        ----------
        X : (n_samples, n_features_in_) array_like

        Returns
        -------
        (n_samples,) float64
        """
        Xa = self._validate_predict(X)
        if Xa.shape[0] <= _FEW_ROWS:
            # numpy's per-call overhead dominates tiny batches: use the scalar path, which
            # computes the same operations in the same order (bitwise-equal results)
            return np.array([self._fast(row) for row in Xa.tolist()])
        P = _pool_values((Xa - self.x_mean_) / self.x_scale_, self.pool_)
        Z = P
        for li, layer in enumerate(self.network_):
            if li and self._reuse:
                Z = np.hstack([Z, P])
            Z = _eval_neurons(Z, layer.pairs, layer.coefs)
            if layer.bounds is not None:
                np.clip(Z, layer.bounds[:, 0], layer.bounds[:, 1], out=Z)
        out: FloatArray = self.y_mean_ + self.y_scale_ * Z[:, 0]
        return out

    def predict_one(self, x: FloatArray | Sequence[float]) -> float:
        """Fast prediction for one sample: the pruned network on plain Python floats (no numpy
        dispatch).

        Gives the same float as :meth:`predict` on that row (same operations, same order).

        Parameters
        ----------
        x : (n_features_in_,) array_like
            One finite feature vector.

        Returns
        -------
        float
        """
        try:
            fast = self._fast
        except AttributeError:
            self._check_fitted()
            raise
        return fast(x.tolist() if isinstance(x, np.ndarray) else x)

    # -- inspection ------------------------------------------------------------------------
    def polynomial(self, digits: int = 6) -> str:
        """The selected model as readable, executable Python assignments.

        One line per standardised input used, one per product input term used
        (``u<i>_<j>``), one per neuron (``z<layer>_<k>``), and the output ``y``. ``exec``
        the text with ``x`` bound to the feature columns (``x[k]`` = column ``k``) to
        re-evaluate it; ``digits`` sets the significant digits (17 reproduces
        :meth:`predict` to rounding, up to the clipping, which the text does not show).

        Returns
        -------
        str
        """
        self._check_fitted()

        def num(v: float) -> str:
            return f"{v:.{digits}g}"

        def term(c: float, mono: str) -> str:
            sign = "-" if c < 0 else "+"
            return f" {sign} {num(abs(c))}*{mono}" if mono else f" {sign} {num(abs(c))}"

        lines = [
            f"# GMDH: {self.n_layers_} layer(s), regularity criterion (validation MSE) "
            f"{num(float(self.criterion_[-1]))}",
        ]
        columns = _layer_inputs(self.network_, self.pool_, self._reuse)
        terms = sorted(
            {
                columns[li][int(c)][1]
                for li, layer in enumerate(self.network_)
                for c in layer.pairs.ravel()
                if columns[li][int(c)][0] == "p"
            }
        )
        used = sorted({int(f) for k in terms for f in self.pool_[k] if f >= 0})
        for k in used:
            mean = float(self.x_mean_[k])
            shift = f"x[{k}] {'-' if mean >= 0 else '+'} {num(abs(mean))}"
            lines.append(f"u{k} = ({shift}) / {num(float(self.x_scale_[k]))}")
        term_names: dict[int, str] = {}
        for k in terms:
            i, j = (int(v) for v in self.pool_[k])
            if j < 0:
                term_names[k] = f"u{i}"
            else:
                term_names[k] = f"u{i}_{j}"
                lines.append(f"u{i}_{j} = u{i}*u{j}")
        names: list[str] = []
        for li, layer in enumerate(self.network_, start=1):
            cols = [
                names[i] if kind == "z" else term_names.get(i, "") for kind, i in columns[li - 1]
            ]
            new_names = []
            for n, ((i, j), c) in enumerate(zip(layer.pairs, layer.coefs, strict=True)):
                a, b = cols[int(i)], cols[int(j)]
                monos = ["", a, b, f"{a}**2", f"{b}**2", f"{a}*{b}"]
                body = "".join(
                    term(float(cv), m)
                    for cv, m in zip(c, monos, strict=True)
                    if cv != 0.0 or m == ""
                )
                body = body[3:] if body.startswith(" + ") else "-" + body[3:]
                name = f"z{li}_{n}"
                lines.append(f"{name} = {body}")
                new_names.append(name)
            names = new_names
        out = f"y = {num(self.y_mean_)} + {num(self.y_scale_)}*{names[0]}"
        lines.append(out.replace("+ -", "- "))
        return "\n".join(lines)


def _prune(layers: list[GmdhLayer], n_pool: int) -> list[GmdhLayer]:
    """Keep only the neurons the best neuron of the last layer depends on, re-indexed.

    A layer's inputs are the previous layer's survivors followed by ``n_pool`` input terms
    (layer 1: the input terms alone); input-term indices shift with the pruned survivors."""
    needed = [np.array([0], dtype=np.intp)]  # survivors are sorted: index 0 is the best
    for layer, below in zip(reversed(layers[1:]), reversed(layers[:-1]), strict=True):
        used = np.unique(layer.pairs[needed[0]].ravel())
        needed.insert(0, used[used < below.pairs.shape[0]])
    pruned: list[GmdhLayer] = []
    prev_index: IntArray | None = None
    n_prev = 0
    for layer, idx in zip(layers, needed, strict=True):
        pairs = layer.pairs[idx]
        if prev_index is not None:
            from_prev = pairs < n_prev
            pairs = np.where(
                from_prev, np.searchsorted(prev_index, pairs), pairs - n_prev + len(prev_index)
            )
        bounds = None if layer.bounds is None else layer.bounds[idx].copy()
        pruned.append(
            GmdhLayer(
                pairs.astype(np.intp), layer.coefs[idx].copy(), layer.criterion[idx].copy(), bounds
            )
        )
        prev_index = idx
        n_prev = layer.pairs.shape[0]
    return pruned


def _layer_inputs(
    network: list[GmdhLayer], pool: IntArray, reuse: bool
) -> list[list[tuple[str, int]]]:
    """For each layer of a (pruned) network, what its input columns are: ``("z", i)`` is
    neuron ``i`` of the previous layer, ``("p", k)`` is input term ``k`` of the pool."""
    out: list[list[tuple[str, int]]] = []
    n_prev = 0
    for li, layer in enumerate(network):
        cols = [("z", i) for i in range(n_prev)] if li else []
        if li == 0 or reuse:
            cols += [("p", k) for k in range(pool.shape[0])]
        out.append(cols)
        n_prev = layer.pairs.shape[0]
    return out


class _ScalarNetwork:
    """The pruned network on one sample with plain Python floats (what :meth:`GmdhRegressor.
    predict_one` and small batches run): the same operations in the same order as
    :meth:`GmdhRegressor.predict`, so the results are bitwise equal.

    Registers ``r``: the standardised features, then the product terms the network uses, then
    one per neuron in network order.
    """

    __slots__ = (
        "_bounds", "_clip", "_inputs", "_message", "_n", "_neurons", "_products", "_y_mean",
        "_y_scale",
    )  # fmt: skip

    def __init__(
        self,
        network: list[GmdhLayer],
        pool: IntArray,
        reuse: bool,
        x_mean: FloatArray,
        x_scale: FloatArray,
        y_mean: float,
        y_scale: float,
    ) -> None:
        n = int(x_mean.shape[0])
        self._n = n
        self._message = f"X has %d features, but GmdhRegressor is expecting {n} features as input."
        columns = _layer_inputs(network, pool, reuse)
        used_terms = sorted(
            {
                columns[li][int(c)][1]
                for li, layer in enumerate(network)
                for c in layer.pairs.ravel()
                if columns[li][int(c)][0] == "p"
            }
        )
        used_features = sorted({int(f) for k in used_terms for f in pool[k] if f >= 0})
        self._inputs = [(k, float(x_mean[k]), float(x_scale[k])) for k in used_features]
        register: dict[int, int] = {}  # pool term -> register
        products: list[tuple[int, int]] = []
        for k in used_terms:
            i, j = (int(v) for v in pool[k])
            if j < 0:
                register[k] = i
            else:
                register[k] = n + len(products)
                products.append((i, j))
        self._products = products
        neurons: list[tuple[int, int, float, float, float, float, float, float]] = []
        clipped: list[tuple[float, float]] = []
        base = n + len(products)
        prev_base = 0
        for li, layer in enumerate(network):
            cols = columns[li]

            def reg(c: int, cols: list[tuple[str, int]] = cols, pb: int = prev_base) -> int:
                kind, idx = cols[c]
                return pb + idx if kind == "z" else register[idx]

            k = layer.pairs.shape[0]
            lims = [(-math.inf, math.inf)] * k if layer.bounds is None else layer.bounds.tolist()
            for (i, j), c, (lo, hi) in zip(
                layer.pairs.tolist(), layer.coefs.tolist(), lims, strict=True
            ):
                c0, c1, c2, c3, c4, c5 = (float(v) for v in c)
                neurons.append((reg(i), reg(j), c0, c1, c2, c3, c4, c5))
                clipped.append((float(lo), float(hi)))
            prev_base = base
            base += k
        self._neurons = neurons
        self._clip = any(layer.bounds is not None for layer in network)
        self._bounds = clipped
        self._y_mean = float(y_mean)
        self._y_scale = float(y_scale)

    def __call__(self, x: Sequence[float]) -> float:
        n = self._n
        if len(x) != n:
            raise ValueError(self._message % len(x))
        # finite * 0 is 0; NaN or +-inf gives NaN (no overflow, unlike a plain sum)
        for v in x:
            if v * 0.0 != 0.0:
                raise ValueError("Input x contains NaN or infinity; GmdhRegressor needs finite x.")
        r = [0.0] * n
        for k, mean, scale in self._inputs:
            r[k] = (x[k] - mean) / scale
        append = r.append
        for i, j in self._products:
            append(r[i] * r[j])
        if self._clip:
            # min(max(v, lo), hi) is numpy.clip's value for finite v
            for (i, j, c0, c1, c2, c3, c4, c5), (lo, hi) in zip(
                self._neurons, self._bounds, strict=True
            ):
                a = r[i]
                b = r[j]
                append(min(max(c0 + a * (c1 + c3 * a + c5 * b) + b * (c2 + c4 * b), lo), hi))
            return self._y_mean + self._y_scale * r[-1]
        for i, j, c0, c1, c2, c3, c4, c5 in self._neurons:
            a = r[i]
            b = r[j]
            append(c0 + a * (c1 + c3 * a + c5 * b) + b * (c2 + c4 * b))
        return self._y_mean + self._y_scale * r[-1]


def _is_int(v: object) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def _is_real(v: object) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        return False
    return math.isfinite(float(v))
