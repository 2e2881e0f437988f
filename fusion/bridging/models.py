"""Bridging models: one component's regressor behind a uniform face, and the fitted candidate
that clips its inputs and outputs to what training saw."""

from __future__ import annotations

import bisect
import copy
import math
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from fusion.bridging.features import COL_T, Spec, compile_features, features_matrix
from fusion.regressors import NarxMLP

FloatArray = NDArray[np.float64]

class ComponentModel(Protocol):
    """One component's regressor behind a uniform face (fit, batch prediction over outages,
    one step)."""

    def fit(
        self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64],
        previous: ComponentModel | None,
    ) -> None: ...  # fmt: skip

    def predict_groups(self, X: FloatArray, groups: NDArray[np.int64]) -> FloatArray: ...

    def reset(self) -> None: ...

    def predict_one(self, x: list[float]) -> float: ...


def _continued(model: Any, previous: Any) -> Any:
    """``model``, or a copy of ``previous`` set to continue training (``warm_start``) when
    both are of the same kind. A shallow copy suffices: the regressors' fits assign fresh
    arrays, so ``previous`` (which the gate may still be judging) is never changed."""
    if previous is None or type(previous) is not type(model):
        return model
    if "warm_start" not in model.get_params() or model.get_params() != {
        **previous.get_params(), "warm_start": model.get_params()["warm_start"]
    }:
        return model
    cont = copy.copy(previous)
    cont.set_params(warm_start=True)
    return cont


class StatelessModel:
    """GMDH / RBF / BP: a plain regressor, one prediction per epoch."""

    def __init__(self, factory: Callable[[], Any]) -> None:
        self._factory = factory
        self._model: Any = None
        self._fast: Callable[[list[float]], float] | None = None

    def fit(
        self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64],
        previous: ComponentModel | None,
    ) -> None:  # fmt: skip
        prev = previous._model if isinstance(previous, StatelessModel) else None
        model = _continued(self._factory(), prev).fit(X, y)
        self._model = model
        fast = getattr(model, "predict_one", None)
        self._fast = fast if callable(fast) else None

    def predict_groups(self, X: FloatArray, groups: NDArray[np.int64]) -> FloatArray:
        out: FloatArray = np.asarray(self._model.predict(X), dtype=float)
        return out

    def reset(self) -> None:
        """No history."""

    def predict_one(self, x: list[float]) -> float:
        if self._fast is not None:
            return float(self._fast(x))
        return float(self._model.predict(np.array([x]))[0])


class NarxModel:
    """P1's NARX MLP: previous inputs and its own previous output (closed loop in an outage,
    started from zero correction). Each fit continues the previous one's weights (bounded
    Levenberg-Marquardt work per refit, training proceeds across refits)."""

    def __init__(self, factory: Callable[[], NarxMLP]) -> None:
        self._factory = factory
        self._model: NarxMLP | None = None
        self.reset()

    def fit(
        self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64],
        previous: ComponentModel | None,
    ) -> None:  # fmt: skip
        # one series: the outages one after the other (a boundary row's history belongs to the
        # previous outage: ~1 row in 400)
        prev = previous._model if isinstance(previous, NarxModel) else None
        self._model = _continued(self._factory(), prev).fit(X, y)

    def predict_groups(self, X: FloatArray, groups: NDArray[np.int64]) -> FloatArray:
        assert self._model is not None
        out = np.empty(len(X))
        for g in np.unique(groups):
            m = groups == g
            out[m] = self._model.predict(X[m], y_init=np.zeros(self._model.n_output_lags))
        return out

    def reset(self) -> None:
        self._x_prev: list[float] | None = None
        self._y_prev = 0.0

    def predict_one(self, x: list[float]) -> float:
        assert self._model is not None
        xp = self._x_prev if self._x_prev is not None else x
        y = self._model.predict_one(x, x_prev=[xp], y_prev=[self._y_prev])
        self._x_prev = x
        self._y_prev = y
        return y


ENVELOPE_TIME_FACTOR = 1.25
"""A prediction ``t`` s into an outage may not exceed the largest error seen in training up
to ``ENVELOPE_TIME_FACTOR * t + ENVELOPE_TIME_SLACK_S`` s into a (virtual) outage..."""
ENVELOPE_TIME_SLACK_S = 2.0
ENVELOPE_GAIN = 1.5
"""...times this factor (a drift never corrected by more than anything seen at that stage)."""


class Candidate:
    """A fitted component model with its input and output ranges: predictions are made on
    inputs clipped to the training range, then clipped to the targets seen and to the
    elapsed-time envelope of the training errors (a polynomial or network far from its data
    can return a correction of hundreds of metres a few seconds into an outage)."""

    __slots__ = ("env", "env_list", "env_t", "env_t_list", "feat", "hi", "lo", "model", "y_hi",
                 "y_lo")

    def __init__(
        self, model: ComponentModel, lo: FloatArray, hi: FloatArray, y_lo: float, y_hi: float,
        spec: Spec, t_s: FloatArray, y: FloatArray,
    ) -> None:  # fmt: skip
        self.model = model
        self.lo, self.hi = lo, hi
        self.y_lo, self.y_hi = y_lo, y_hi
        self.feat = compile_features(spec, lo.tolist(), hi.tolist())
        order = np.argsort(t_s, kind="stable")
        self.env_t: FloatArray = np.asarray(t_s, dtype=float)[order]
        self.env: FloatArray = ENVELOPE_GAIN * np.maximum.accumulate(np.abs(y[order]))
        # plain lists for the per-sample path (bisect on a list: ~1 us, numpy: ~20 us)
        self.env_t_list: list[float] = self.env_t.tolist()
        self.env_list: list[float] = self.env.tolist()

    def _envelope(self, t_s: FloatArray) -> FloatArray:
        """Largest correction allowed ``t_s`` s into an outage (0 before any training pair)."""
        i = np.searchsorted(self.env_t, ENVELOPE_TIME_FACTOR * t_s + ENVELOPE_TIME_SLACK_S,
                            side="right")  # fmt: skip
        out: FloatArray = np.where(i > 0, self.env[np.maximum(i - 1, 0)], 0.0)
        return out

    def predict_one(self, base: list[float]) -> float:
        y = self.model.predict_one(self.feat(base))
        if not math.isfinite(y):
            return math.nan
        i = bisect.bisect_right(
            self.env_t_list, ENVELOPE_TIME_FACTOR * base[COL_T] + ENVELOPE_TIME_SLACK_S)
        env = self.env_list[i - 1] if i > 0 else 0.0
        return min(max(y, self.y_lo, -env), self.y_hi, env)

    def predict_rows(self, B: FloatArray, spec: Spec, groups: NDArray[np.int64]) -> FloatArray:
        """Same values as :meth:`predict_one` over rows of one outage each group (batch)."""
        X = np.clip(features_matrix(B, spec), self.lo, self.hi)
        with np.errstate(all="ignore"):
            y = self.model.predict_groups(X, groups)
        env = self._envelope(B[:, COL_T])
        out: FloatArray = np.clip(np.clip(y, self.y_lo, self.y_hi), -env, env)
        return out


Snapshot = tuple["Candidate | None", ...]
