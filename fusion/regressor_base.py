"""The scikit-learn estimator contract in plain Python, shared by the bridging regressors
(:mod:`fusion.gmdh`, :mod:`fusion.regressors`): parameters, input validation,
standardisation, the fitted-state check and the R² score.

The regressors follow scikit-learn's contract (hyperparameters stored unchanged in
``__init__``, ``fit`` returns ``self``, learned attributes end in ``_``, ``predict``,
``score`` = R², ``get_params``/``set_params``) and pass ``sklearn.utils.estimator_checks``,
without importing scikit-learn at run time: :class:`RegressorBase` implements the protocol in
plain Python. Two hooks talk to scikit-learn only when the *caller* has it loaded already:
``__sklearn_tags__`` (called only by scikit-learn itself) imports its tag classes, and
:class:`NotFittedError` / :class:`DataConversionWarning` are raised as subclasses of
scikit-learn's classes of the same name when ``sklearn`` is already in ``sys.modules``, so
scikit-learn tooling recognises them. ``fusion`` itself never imports scikit-learn.
"""

from __future__ import annotations

import inspect
import sys
import warnings
from typing import Any, ClassVar, NamedTuple, Self, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

class NotFittedError(ValueError, AttributeError):
    """A model was used before :meth:`fit` (same bases as scikit-learn's NotFittedError)."""

    def __reduce__(self) -> tuple[Any, ...]:
        # The scikit-learn-compatible alias is created at run time and cannot be pickled by
        # name; unpickle as this class.
        return (NotFittedError, self.args)


class DataConversionWarning(UserWarning):
    """Input data was converted (a column-vector ``y`` was flattened)."""


_T = TypeVar("_T", bound=type)
_SKLEARN_ALIASES: dict[tuple[type, str], type] = {}


def _sklearn_compatible(ours: _T, sklearn_name: str) -> _T:
    """``ours``, or a subclass of ``ours`` and ``sklearn.exceptions.<sklearn_name>`` when the
    caller has already imported scikit-learn (it is never imported here)."""
    sk_exceptions = sys.modules.get("sklearn.exceptions")
    theirs = getattr(sk_exceptions, sklearn_name, None) if sk_exceptions is not None else None
    if not isinstance(theirs, type) or issubclass(ours, theirs):
        return ours
    key = (ours, sklearn_name)
    if key not in _SKLEARN_ALIASES:
        _SKLEARN_ALIASES[key] = type(ours.__name__, (ours, theirs), {"__module__": __name__})
    return _SKLEARN_ALIASES[key]  # type: ignore[return-value]


def _is_sparse(obj: object) -> bool:
    """True for scipy.sparse matrices and arrays, detected without importing scipy."""
    return type(obj).__module__.startswith("scipy.sparse") or hasattr(obj, "tocsr")


def _as_float_2d(X: ArrayLike, name: str, owner: str) -> FloatArray:
    """Validate a design matrix: dense, real, 2-D, non-empty, finite; returned as float64."""
    if _is_sparse(X):
        raise TypeError(
            f"{owner} does not accept sparse input {name}; pass a dense array (X.toarray())."
        )
    if X is None:
        raise ValueError(f"{owner}: input {name} is None; expected a 2-D array.")
    arr = np.asarray(X)
    if np.iscomplexobj(arr):
        raise ValueError(f"Complex data not supported: {owner} got complex {name}.")
    # object arrays holding numbers convert; anything else raises float()'s TypeError
    arr = arr.astype(np.float64, copy=False)
    if arr.ndim == 1:
        raise ValueError(
            f"{owner}: expected a 2-D array {name}, got a 1-D array of shape {arr.shape}. "
            "Reshape your data either using X.reshape(-1, 1) if it has a single feature or "
            "X.reshape(1, -1) if it contains a single sample."
        )
    if arr.ndim != 2:
        raise ValueError(f"{owner}: expected a 2-D array {name}, got shape {arr.shape}.")
    n, m = arr.shape
    if n == 0:
        raise ValueError(
            f"Found array with 0 sample(s) (shape={arr.shape}) while a minimum of 1 is "
            f"required by {owner}."
        )
    if m == 0:
        raise ValueError(
            f"Found array with 0 feature(s) (shape={arr.shape}) while a minimum of 1 is "
            f"required by {owner}."
        )
    if not np.isfinite(arr).all():
        what = "NaN" if np.isnan(arr).any() else "infinity"
        raise ValueError(f"Input {name} contains {what}; {owner} needs finite values.")
    return arr


def _as_float_1d_target(y: ArrayLike | None, n_samples: int, owner: str) -> FloatArray:
    """Validate a single-output target of length ``n_samples``; returned as float64."""
    if y is None:
        raise ValueError(f"{owner} requires y to be passed, but the target y is None.")
    if _is_sparse(y):
        raise TypeError(f"{owner} does not accept a sparse target y.")
    arr = np.asarray(y)
    if np.iscomplexobj(arr):
        raise ValueError(f"Complex data not supported: {owner} got complex y.")
    arr = arr.astype(np.float64, copy=False)
    if arr.ndim == 2 and arr.shape[1] == 1:
        warnings.warn(
            "A column-vector y was passed when a 1d array was expected. Please change the "
            "shape of y to (n_samples,), for example using ravel().",
            _sklearn_compatible(DataConversionWarning, "DataConversionWarning"),
            stacklevel=3,
        )
        arr = arr[:, 0]
    if arr.ndim != 1:
        raise ValueError(f"{owner}: y should be a 1d array (single output), got shape {arr.shape}.")
    if arr.shape[0] != n_samples:
        raise ValueError(
            "Found input variables with inconsistent numbers of samples: "
            f"[{n_samples}, {arr.shape[0]}] (X, y)."
        )
    if not np.isfinite(arr).all():
        what = "NaN" if np.isnan(arr).any() else "infinity"
        raise ValueError(f"Input y contains {what}; {owner} needs finite values.")
    return arr


def standardise(a: FloatArray, axis: int = 0) -> tuple[FloatArray, FloatArray]:
    """Mean and scale of ``a`` along ``axis`` for ``(a − mean) / scale``.

    The scale is the standard deviation, or 1 where that is ~0 (a constant column maps to
    zeros, never to inf/NaN).
    """
    mean = a.mean(axis=axis)
    std = a.std(axis=axis)
    scale = np.where(std > 1e-12 * np.maximum(1.0, np.abs(mean)), std, 1.0)
    return mean, scale


class Scaling(NamedTuple):
    """Input and target standardisation of a fit (:func:`standardise`)."""

    x_mean: FloatArray
    x_scale: FloatArray
    y_mean: float
    y_scale: float


class RegressorBase:
    """scikit-learn's regressor protocol in plain numpy (no scikit-learn import).

    Subclasses list their hyperparameters as keyword arguments of ``__init__`` and store them
    unchanged; fitted state goes into attributes ending in ``_`` (``n_features_in_`` marks a
    fitted model).
    """

    _estimator_type: ClassVar[str] = "regressor"
    # fitted standardisation (set by _store_scaling; declared, not defined, so an unfitted
    # model has none of them)
    n_features_in_: int
    x_mean_: FloatArray
    x_scale_: FloatArray
    y_mean_: float
    y_scale_: float

    # -- parameters -------------------------------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return sorted(
            p.name
            for p in sig.parameters.values()
            if p.name != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)
        )

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Hyperparameters as a dict (``deep`` is accepted for API compatibility; there are
        no nested estimators)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params: Any) -> Self:
        """Set hyperparameters by name (validated at :meth:`fit`); returns ``self``."""
        valid = self._param_names()
        for name in params:
            if name not in valid:
                raise ValueError(
                    f"Invalid parameter {name!r} for {type(self).__name__}; valid: {valid}."
                )
        for name, value in params.items():
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        parts = []
        for p in sig.parameters.values():
            if p.name == "self" or not hasattr(self, p.name):
                continue
            value = getattr(self, p.name)
            if p.default is inspect.Parameter.empty or not _same(value, p.default):
                parts.append(f"{p.name}={value!r}")
        return f"{type(self).__name__}({', '.join(parts)})"

    # -- scikit-learn hooks -----------------------------------------------------------------
    def __sklearn_tags__(self) -> Any:
        """Estimator tags for scikit-learn (only scikit-learn calls this, so it is loaded)."""
        from sklearn.utils import InputTags, RegressorTags, Tags, TargetTags

        return Tags(
            estimator_type="regressor",
            target_tags=TargetTags(required=True, single_output=True, multi_output=False),
            regressor_tags=RegressorTags(),
            input_tags=InputTags(),
        )

    def __sklearn_is_fitted__(self) -> bool:
        """Fitted iff :meth:`fit` has run."""
        return hasattr(self, "n_features_in_")

    # -- validation shared by subclasses ---------------------------------------------------
    def _validate_fit(
        self, X: ArrayLike, y: ArrayLike | None, min_samples: int
    ) -> tuple[FloatArray, FloatArray]:
        name = type(self).__name__
        Xa = _as_float_2d(X, "X", name)
        ya = _as_float_1d_target(y, Xa.shape[0], name)
        if Xa.shape[0] < min_samples:
            raise ValueError(
                f"{name} needs at least {min_samples} samples, got n_samples={Xa.shape[0]}."
            )
        return Xa, ya

    def _standardised_fit_data(
        self, X: ArrayLike, y: ArrayLike, min_samples: int
    ) -> tuple[FloatArray, FloatArray, Scaling]:
        """Validate ``(X, y)`` and standardise both: ``(U, v, scaling)`` with
        ``U = (X - x_mean) / x_scale`` and ``v = (y - y_mean) / y_scale``. Nothing is stored
        (a fit that fails later must not look fitted): :meth:`_store_scaling` at the end."""
        Xa, ya = self._validate_fit(X, y, min_samples=min_samples)
        x_mean, x_scale = standardise(Xa)
        y_mean, y_scale = standardise(ya)
        sc = Scaling(x_mean, x_scale, float(y_mean), float(y_scale))
        return (Xa - x_mean) / x_scale, (ya - sc.y_mean) / sc.y_scale, sc

    def _store_scaling(self, sc: Scaling) -> None:
        """Set ``n_features_in_``, ``x_mean_``, ``x_scale_``, ``y_mean_``, ``y_scale_``."""
        self.n_features_in_ = int(sc.x_mean.shape[0])
        self.x_mean_ = sc.x_mean
        self.x_scale_ = sc.x_scale
        self.y_mean_ = sc.y_mean
        self.y_scale_ = sc.y_scale

    def _standardised_input(self, X: ArrayLike) -> FloatArray:
        """Validated ``X`` in the fit's standardised units."""
        Xa = self._validate_predict(X)
        out: FloatArray = (Xa - self.x_mean_) / self.x_scale_
        return out

    def _target_units(self, z: FloatArray) -> FloatArray:
        """Standardised network output back to target units."""
        out: FloatArray = self.y_mean_ + self.y_scale_ * z
        return out

    def _stored_scaling(self) -> Scaling:
        """The standardisation of the last fit (for a warm start)."""
        return Scaling(self.x_mean_, self.x_scale_, self.y_mean_, self.y_scale_)

    def _check_fitted(self) -> None:
        if not hasattr(self, "n_features_in_"):
            raise _sklearn_compatible(NotFittedError, "NotFittedError")(
                f"This {type(self).__name__} instance is not fitted yet; call 'fit' first."
            )

    def _validate_predict(self, X: ArrayLike) -> FloatArray:
        self._check_fitted()
        name = type(self).__name__
        Xa = _as_float_2d(X, "X", name)
        n_expected: int = self.n_features_in_
        if Xa.shape[1] != n_expected:
            raise ValueError(
                f"X has {Xa.shape[1]} features, but {name} is expecting {n_expected} "
                "features as input."
            )
        return Xa

    # -- common API ------------------------------------------------------------------------
    def fit(self, X: ArrayLike, y: ArrayLike) -> Self:  # pragma: no cover - abstract
        """Fit the model to ``(X, y)``; returns ``self``."""
        raise NotImplementedError

    def predict(self, X: ArrayLike) -> FloatArray:  # pragma: no cover - abstract
        """Predict targets for ``X``."""
        raise NotImplementedError

    def score(self, X: ArrayLike, y: ArrayLike) -> float:
        """Coefficient of determination R² of :meth:`predict` on ``(X, y)``."""
        pred = self.predict(X)
        ya = _as_float_1d_target(y, pred.shape[0], type(self).__name__)
        ss_res = float(np.sum((ya - pred) ** 2))
        ss_tot = float(np.sum((ya - ya.mean()) ** 2))
        if ss_tot == 0.0:
            return 1.0 if ss_res == 0.0 else 0.0
        return 1.0 - ss_res / ss_tot


def _same(a: object, b: object) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:
        return a is b


# ---------------------------------------------------------------------------------------------
# GMDH
# ---------------------------------------------------------------------------------------------
