"""Multilayer GMDH polynomial network (paper P0), a regressor with scikit-learn's contract.

GMDH (Group Method of Data Handling, Ivakhnenko) builds a polynomial network layer by layer:

1. every pair ``(i, j)`` of the layer's inputs gets a quadratic *neuron*
   ``z = c0 + c1·a + c2·b + c3·a² + c4·b² + c5·a·b`` (``a = input i``, ``b = input j``),
   its coefficients fitted by least squares on the *training* part of the data;
2. each neuron is scored by an *external* criterion, the regularity criterion: its mean
   squared error on the *validation* part, data it was not fitted on;
3. the neurons whose criterion exceeds ``e_c = α·e_min + (1 − α)·e_max`` are removed
   (``α`` is the selection pressure: ``α = 1`` keeps only the best, ``α = 0`` keeps all),
   and at most ``max_neurons`` of the best survivors feed the next layer;
4. layers are added while the best criterion of a layer improves on the previous layer's
   (relative improvement ``> tol``), up to ``max_layers``; the model is the best neuron of the
   last accepted layer, and only the neurons it depends on are kept for prediction.

P0's settings are the defaults: 5 layers, 10 neurons, ``α = 0.6``.

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

_SPLITS = ("interleaved", "tail", "random")
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
    """

    pairs: IntArray
    coefs: FloatArray
    criterion: FloatArray


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


def _moments(Z: FloatArray, y: FloatArray) -> FloatArray:
    """Moment matrix ``BᵀB`` of ``B = [1, Z, Z², Z³, y·Z, y]`` (see :func:`_gram_index`)."""
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
    rows = max(32, _GEMM_SINGLE_THREAD // (c * c))
    S: FloatArray = np.zeros((c, c))
    for start in range(0, n, rows):
        block = B[start : start + rows]
        S += block.T @ block
    return S


def _fit_pairs(
    Zt: FloatArray, yt: FloatArray, Zv: FloatArray, yv: FloatArray, pairs: IntArray, ridge: float
) -> tuple[FloatArray, FloatArray]:
    """Fit all pair-neurons on the training part and estimate their regularity criterion.

    The normal equations of every pair come from one moment matrix of the training part
    (a single GEMM, ``O(n·m²)``) instead of a per-pair design matrix; the validation MSE of
    every pair comes the same way from the validation moments,
    ``(cᵀG_v c − 2cᵀr_v + Σy²) / n_v``. That form loses relative precision for near-perfect
    fits, so it only ranks candidates; survivors are re-scored exactly by the caller.
    Returns coefficients ``(k, 6)`` and estimated criteria ``(k,)`` (inf where non-finite).
    """
    m = Zt.shape[1]
    row, column, r_row, r_col = _gram_index(m, pairs)
    St = _moments(Zt, yt)
    Sv = _moments(Zv, yv)
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
    with np.errstate(all="ignore"):
        coefs = _solve_batched(G, r, ridge)
        Gv = Sv[row, column]
        rv = Sv[r_row, r_col]
        yy = Sv[-1, -1]
        quad = np.einsum("ki,kij,kj->k", coefs, Gv, coefs)
        crit = np.maximum(quad - 2.0 * np.einsum("ki,ki->k", coefs, rv) + yy, 0.0) / len(yv)
    crit = np.where(np.isfinite(crit) & np.isfinite(coefs).all(axis=1), crit, np.inf)
    return coefs, crit


def _select(crit: FloatArray, alpha: float, max_neurons: int) -> IntArray:
    """Survivors, best first: criterion ≤ α·e_min + (1−α)·e_max, at most ``max_neurons``."""
    order = np.argsort(crit, kind="stable")
    finite = crit[np.isfinite(crit)]
    if finite.size == 0:
        return order[:0]
    e_min, e_max = float(finite.min()), float(finite.max())
    e_c = alpha * e_min + (1.0 - alpha) * e_max
    # a hair of slack so that alpha = 1 keeps the best neuron despite rounding in e_c
    keep = order[crit[order] <= e_c + 1e-12 * max(abs(e_c), 1e-300)]
    return keep[:max_neurons]


def _pairs_for(m: int) -> IntArray:
    if m == 1:
        return np.zeros((1, 2), dtype=np.intp)
    return np.array(list(itertools.combinations(range(m), 2)), dtype=np.intp)


def _split_masks(n: int, fraction: float, split: str, random_state: Any) -> NDArray[np.bool_]:
    """Boolean validation mask of length ``n`` (≥ 1 validation and ≥ 1 training sample)."""
    n_val = min(max(round(fraction * n), 1), n - 1)
    mask = np.zeros(n, dtype=bool)
    if split == "tail":
        mask[n - n_val :] = True
    elif split == "random":
        rng = np.random.default_rng(random_state)
        mask[rng.choice(n, size=n_val, replace=False)] = True
    else:  # interleaved: evenly spread, the classic GMDH alternating split
        mask[np.unique(np.floor((np.arange(n_val) + 0.5) * n / n_val).astype(np.intp))] = True
    return mask


class GmdhRegressor(RegressorBase):
    """Multilayer GMDH network of Ivakhnenko quadratic neurons (paper P0).

    Parameters
    ----------
    max_layers : int, default 5
        Maximum number of layers.
    max_neurons : int, default 10
        Maximum number of survivors per layer (the inputs of the next layer).
    alpha : float in [0, 1], default 0.6
        Selection pressure: survivors have criterion ≤ ``α·e_min + (1−α)·e_max``.
    validation_fraction : float in (0, 1), default 0.3
        Share of the samples held out for the regularity criterion.
    split : {"interleaved", "tail", "random"}, default "interleaved"
        How the validation part is chosen: evenly interleaved samples; the last samples
        in time (a stricter test of extrapolation for autocorrelated series); or a random
        subset drawn with ``random_state``.
    tol : float ≥ 0, default 1e-3
        A new layer is kept only if it lowers the best criterion by more than this fraction.
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
        max_layers: int = 5,
        max_neurons: int = 10,
        alpha: float = 0.6,
        validation_fraction: float = 0.3,
        split: str = "interleaved",
        tol: float = 1e-3,
        ridge: float = 1e-8,
        random_state: int | None = 0,
    ) -> None:
        self.max_layers = max_layers
        self.max_neurons = max_neurons
        self.alpha = alpha
        self.validation_fraction = validation_fraction
        self.split = split
        self.tol = tol
        self.ridge = ridge
        self.random_state = random_state

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
        if not _is_real(self.validation_fraction) or not 0.0 < self.validation_fraction < 1.0:
            raise bad("validation_fraction", "a number in (0, 1)")
        if self.split not in _SPLITS:
            raise bad("split", f"one of {_SPLITS}")
        if not _is_real(self.tol) or not 0.0 <= self.tol < 1.0:
            raise bad("tol", "a number in [0, 1)")
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
        Zt, Zv, yt, yv = U[~val], U[val], v[~val], v[val]

        layers: list[GmdhLayer] = []
        best: list[float] = []
        for _ in range(int(self.max_layers)):
            pairs = _pairs_for(Zt.shape[1])
            coefs, crit = _fit_pairs(Zt, yt, Zv, yv, pairs, float(self.ridge))
            keep = _select(crit, float(self.alpha), int(self.max_neurons))
            if keep.size == 0:
                break
            # exact regularity criterion of the survivors (their validation outputs are the
            # next layer's inputs anyway); best first
            Zv_next = _eval_neurons(Zv, pairs[keep], coefs[keep])
            with np.errstate(all="ignore"):
                exact = np.mean((Zv_next - yv[:, None]) ** 2, axis=0)
            exact = np.where(np.isfinite(exact), exact, np.inf)
            order = np.argsort(exact, kind="stable")
            keep, Zv_next, exact = keep[order], Zv_next[:, order], exact[order]
            e_best = float(exact[0])
            if not np.isfinite(e_best):
                break
            if best and not e_best < best[-1] * (1.0 - float(self.tol)):
                break  # the external criterion stopped improving: keep the previous layer
            layer = GmdhLayer(pairs[keep], coefs[keep], exact)
            layers.append(layer)
            best.append(e_best)
            if e_best <= _EXACT_FIT:
                break  # nothing left for another layer to improve but rounding
            Zt = _eval_neurons(Zt, layer.pairs, layer.coefs)
            Zv = Zv_next

        if not layers:
            # every neuron non-finite: only possible with pathological ridge=0 inputs
            raise ValueError("GmdhRegressor: no neuron of the first layer could be fitted.")

        self._store_scaling(sc)
        self.layers_ = layers
        self.n_layers_ = len(layers)
        self.criterion_ = np.array(best) * self.y_scale_**2
        self.network_ = _prune(layers)
        self._fast = _ScalarNetwork(
            self.network_, sc.x_mean, sc.x_scale, self.y_mean_, self.y_scale_
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
        Z = (Xa - self.x_mean_) / self.x_scale_
        for layer in self.network_:
            Z = _eval_neurons(Z, layer.pairs, layer.coefs)
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

        One line per standardised input used, one per neuron (``z<layer>_<k>``), and the
        output ``y``. ``exec`` the text with ``x`` bound to the feature columns
        (``x[k]`` = column ``k``) to re-evaluate it; ``digits`` sets the significant digits
        (17 reproduces :meth:`predict` to rounding).

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
        used = sorted({int(i) for i in self.network_[0].pairs.ravel()})
        names = [f"u{k}" for k in range(self.n_features_in_)]
        for k in used:
            mean = float(self.x_mean_[k])
            shift = f"x[{k}] {'-' if mean >= 0 else '+'} {num(abs(mean))}"
            lines.append(f"u{k} = ({shift}) / {num(float(self.x_scale_[k]))}")
        for li, layer in enumerate(self.network_, start=1):
            new_names = []
            for n, ((i, j), c) in enumerate(zip(layer.pairs, layer.coefs, strict=True)):
                a, b = names[int(i)], names[int(j)]
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


def _prune(layers: list[GmdhLayer]) -> list[GmdhLayer]:
    """Keep only the neurons the best neuron of the last layer depends on, re-indexed."""
    needed = [np.array([0], dtype=np.intp)]  # survivors are sorted: index 0 is the best
    for layer in reversed(layers[1:]):
        needed.insert(0, np.unique(layer.pairs[needed[0]].ravel()))
    pruned: list[GmdhLayer] = []
    prev_index: IntArray | None = None
    for layer, idx in zip(layers, needed, strict=True):
        pairs = layer.pairs[idx]
        if prev_index is not None:
            pairs = np.searchsorted(prev_index, pairs)
        pruned.append(
            GmdhLayer(pairs.astype(np.intp), layer.coefs[idx].copy(), layer.criterion[idx].copy())
        )
        prev_index = idx
    return pruned


class _ScalarNetwork:
    """The pruned network on one sample with plain Python floats (what :meth:`GmdhRegressor.
    predict_one` and small batches run): the same operations in the same order as
    :func:`_eval_neurons`, so the results are bitwise equal to :meth:`GmdhRegressor.predict`.

    Registers ``r``: the standardised features, then one per neuron in network order (a
    neuron's inputs are registers of the previous layer).
    """

    __slots__ = ("_inputs", "_message", "_n", "_neurons", "_y_mean", "_y_scale")

    def __init__(
        self,
        network: list[GmdhLayer],
        x_mean: FloatArray,
        x_scale: FloatArray,
        y_mean: float,
        y_scale: float,
    ) -> None:
        n = int(x_mean.shape[0])
        self._n = n
        self._message = f"X has %d features, but GmdhRegressor is expecting {n} features as input."
        used = sorted({int(i) for i in network[0].pairs.ravel()})
        self._inputs = [(k, float(x_mean[k]), float(x_scale[k])) for k in used]
        neurons: list[tuple[int, int, float, float, float, float, float, float]] = []
        base, width = 0, n
        for layer in network:
            for (i, j), c in zip(layer.pairs.tolist(), layer.coefs.tolist(), strict=True):
                c0, c1, c2, c3, c4, c5 = (float(v) for v in c)
                neurons.append((base + i, base + j, c0, c1, c2, c3, c4, c5))
            base += width
            width = layer.pairs.shape[0]
        self._neurons = neurons
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
