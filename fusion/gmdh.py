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

Why the defaults differ from P0: on ``y = 1 + 2 x0 − x1 + 0.5 x0 x2 − 0.8 x3²``
(6 inputs, noise 0.02) P0's rule left 5, 4, 3, 2, 1 survivors and 0.27 RMSE against 0.020
for polynomial ridge; on ``(x0 x1 + 0.5 x2)² − x3 x4`` no neuron fitted to the target carries
``x0 x1`` (the target has no quadratic component along it) until the product is offered as
an input term. ``GmdhRegressor.paper()`` is P0 (5 layers, 10 neurons, ``α = 0.6``, features
in layer 1 only, interleaved split); the bridging methods use it. ``bench/gmdh_quality.py``
compares both with ridge and an MLP.

Implementation notes
--------------------
- Inputs and target are standardised inside :meth:`GmdhRegressor.fit`; neurons work on the
  standardised values ``u_k = (x_k − x_mean_k) / x_scale_k``. A constant column gets scale 1
  (it becomes all zeros, so its neurons are just rank-deficient and the ridge handles them).
- One layer's building blocks (input terms, the training / validation split, fitting every
  pair-neuron at once, choosing the survivors) are :mod:`fusion.gmdh_layer`; the fitted
  network's pruning and its scalar evaluation for :meth:`GmdhRegressor.predict_one` are
  :mod:`fusion.gmdh_network`.

The estimator plumbing (scikit-learn contract, input validation, standardisation) is
:class:`fusion.regressor_base.RegressorBase`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Self

import numpy as np
from numpy.typing import ArrayLike

from fusion.gmdh_layer import (
    GmdhLayer,
    eval_neurons,
    fit_pairs,
    pairs_for,
    pool_terms,
    pool_values,
    split_masks,
    square_pairs,
    survivors,
    threshold_count,
)
from fusion.gmdh_network import ScalarNetwork, layer_inputs, prune_network
from fusion.regressor_base import FloatArray, RegressorBase

__all__ = ["GmdhLayer", "GmdhRegressor"]

_SPLITS = ("interleaved", "blocked", "tail", "random")
_INPUTS = ("first-layer", "every-layer", "quadratic")
# The survivors (diversity on) are picked among this many times max_neurons candidates, best
# estimated criterion first.
_CANDIDATES = 8
# A validation MSE below this share of the target variance (relative RMS error 1e-6) counts
# as an exact fit: further layers could only fit rounding and the ridge's bias.
_EXACT_FIT = 1e-12
# Batches up to this many rows are predicted row by row with the scalar path.
_FEW_ROWS = 8


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
        val = split_masks(len(v), float(self.validation_fraction), self.split, self.random_state)
        pool = pool_terms(U.shape[1], str(self.inputs))
        reuse = self.inputs != "first-layer"
        Pt, Pv = pool_values(U[~val], pool), pool_values(U[val], pool)
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
            pairs = pairs_for(n_prev, pool.shape[0] if (reuse or not layers) else 0)
            square = None if layers else square_pairs(pool, pairs)
            # a later layer with input terms: every pair starts with a learned neuron
            lead = n_prev if (reuse and layers) else 0
            coefs, crit = fit_pairs(Zt, yt, Zv, yv, pairs, float(self.ridge), square, lead)
            n_finite = int(np.count_nonzero(np.isfinite(crit)))
            n_keep = min(max(threshold_count(crit, float(self.alpha)), n_keep_min), n_keep_max)
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
            Zv_cand = eval_neurons(Zv, pairs[cand], coefs[cand])
            with np.errstate(all="ignore"):
                resid = Zv_cand - yv[:, None]
                exact = np.mean(resid**2, axis=0)
            exact = np.where(np.isfinite(exact), exact, np.inf)
            rank = np.argsort(exact, kind="stable")
            cand, Zv_cand, exact, resid = cand[rank], Zv_cand[:, rank], exact[rank], resid[:, rank]
            if diverse:
                pick = survivors(resid[:, np.isfinite(exact)], n_keep, float(self.max_correlation))
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
            Zt_next = eval_neurons(Zt, pairs[keep], coefs[keep])
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
        self.network_ = prune_network(layers, pool.shape[0] if reuse else 0)
        self._fast = ScalarNetwork(
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
        P = pool_values((Xa - self.x_mean_) / self.x_scale_, self.pool_)
        Z = P
        for li, layer in enumerate(self.network_):
            if li and self._reuse:
                Z = np.hstack([Z, P])
            Z = eval_neurons(Z, layer.pairs, layer.coefs)
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
        columns = layer_inputs(self.network_, self.pool_, self._reuse)
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


def _is_int(v: object) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def _is_real(v: object) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        return False
    return math.isfinite(float(v))
