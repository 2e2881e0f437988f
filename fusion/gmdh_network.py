"""The fitted GMDH network (:mod:`fusion.gmdh`): pruning to the neurons the output depends
on, each layer's input columns, and the pruned network on one sample with plain Python floats.

:class:`ScalarNetwork` is what :meth:`fusion.gmdh.GmdhRegressor.predict_one` and small batches
run (no numpy dispatch): the neurons' inputs and coefficients are laid out as float tuples at
fit time and evaluated in a loop, with the same operations in the same order as the batch path.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fusion.gmdh_layer import GmdhLayer, IntArray
from fusion.regressor_base import FloatArray


def prune_network(layers: list[GmdhLayer], n_pool: int) -> list[GmdhLayer]:
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


def layer_inputs(
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


class ScalarNetwork:
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
        columns = layer_inputs(network, pool, reuse)
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
