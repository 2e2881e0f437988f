"""GMDH polynomial network (fusion.gmdh): estimator contract, layer building, selection,
external criterion, stopping, robustness, readable polynomial, fast single-sample path."""

from __future__ import annotations

import pickle
import re
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError as SkNotFittedError
from sklearn.utils.estimator_checks import parametrize_with_checks

from fusion.gmdh import GmdhRegressor
from fusion.regressor_base import NotFittedError

REPO = Path(__file__).resolve().parents[2]


def _quad_of_quad(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """y = (x0·x1 + x2)², x in [0, 1]⁴ (x3 is a distractor)."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 1.0, (n, 4))
    return X, (X[:, 0] * X[:, 1] + X[:, 2]) ** 2


# --- scikit-learn estimator contract -------------------------------------------------------


with warnings.catch_warnings():
    # fusion's estimators implement scikit-learn's protocol without inheriting BaseEstimator
    # (fusion must not import scikit-learn); the checks warn about that at collection
    warnings.filterwarnings("ignore", "Estimator .* does not inherit", UserWarning)
    _sklearn_checks = parametrize_with_checks([GmdhRegressor()], xfail_strict=True)


@_sklearn_checks
def test_sklearn_estimator_checks(estimator: GmdhRegressor, check: Callable[..., None]) -> None:
    check(estimator)


def test_fusion_runtime_does_not_import_sklearn() -> None:
    code = (
        "import sys, numpy as np\n"
        "from fusion.gmdh import GmdhRegressor\n"
        "from fusion.regressors import NarxMLP, RbfNet, BpNet\n"
        "X = np.random.default_rng(0).normal(size=(50, 3)); y = X[:, 0]\n"
        "GmdhRegressor().fit(X, y).predict(X)\n"
        "try:\n"
        "    GmdhRegressor().predict(X)\n"
        "except ValueError:\n"
        "    pass\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'sklearn'))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]"


def test_unfitted_errors_are_sklearn_not_fitted_errors_when_sklearn_is_loaded() -> None:
    model = GmdhRegressor()
    for call in (lambda: model.predict(np.zeros((2, 3))), lambda: model.predict_one([0.0]),
                 model.polynomial):
        with pytest.raises(NotFittedError) as info:
            call()
        assert isinstance(info.value, SkNotFittedError)
        # the run-time alias pickles as fusion's own class
        assert type(pickle.loads(pickle.dumps(info.value))) is NotFittedError


def test_clone_keeps_hyperparameters_and_drops_fit() -> None:
    X, y = _quad_of_quad(200, 0)
    model = GmdhRegressor(max_layers=3, alpha=0.8, split="tail").fit(X, y)
    copy = clone(model)
    assert copy.get_params() == model.get_params()
    assert not hasattr(copy, "network_")
    assert repr(copy) == "GmdhRegressor(max_layers=3, alpha=0.8, split='tail')"


# --- the GMDH method -------------------------------------------------------------------------


def test_two_layers_model_a_quadratic_of_quadratics_better_than_one() -> None:
    X, y = _quad_of_quad(2000, 1)
    X_test, y_test = _quad_of_quad(2000, 2)
    one = GmdhRegressor(max_layers=1).fit(X, y)
    deep = GmdhRegressor().fit(X, y)
    mse_one = np.mean((one.predict(X_test) - y_test) ** 2)
    mse_deep = np.mean((deep.predict(X_test) - y_test) ** 2)
    assert one.n_layers_ == 1
    assert deep.n_layers_ >= 2
    assert mse_deep < 0.5 * mse_one
    # every accepted layer improved the external criterion
    assert np.all(np.diff(deep.criterion_) < 0)


def test_selection_pressure_one_keeps_only_the_best_neuron() -> None:
    X, y = _quad_of_quad(500, 3)
    model = GmdhRegressor.paper(alpha=1.0).fit(X, y)
    assert all(layer.pairs.shape[0] == 1 for layer in model.layers_)


@pytest.mark.parametrize(("max_neurons", "expected"), [(20, 10), (4, 4)])
def test_selection_pressure_zero_keeps_all_up_to_max_neurons(
    max_neurons: int, expected: int
) -> None:
    rng = np.random.default_rng(4)
    X = rng.normal(size=(400, 5))  # 5 inputs -> 10 pair-neurons in layer 1
    y = X[:, 0] * X[:, 1] + np.sin(X[:, 2]) + 0.1 * rng.normal(size=400)
    model = GmdhRegressor.paper(alpha=0.0, max_neurons=max_neurons, max_layers=1).fit(X, y)
    layer = model.layers_[0]
    assert layer.pairs.shape[0] == expected
    assert np.all(np.diff(layer.criterion) >= 0)  # survivors are stored best first


def test_regularity_criterion_is_measured_on_the_validation_part() -> None:
    # x_spur equals y on the training part (first 40 %) only; x_true explains y everywhere.
    rng = np.random.default_rng(5)
    n = 500
    x_true = rng.uniform(-1, 1, n)
    y = x_true + 0.2 * rng.normal(size=n)
    x_spur = rng.normal(size=n)
    n_train = 200
    x_spur[:n_train] = y[:n_train]
    X = np.column_stack([x_spur, x_true, rng.normal(size=n)])
    model = GmdhRegressor(split="tail", validation_fraction=0.6).fit(X, y)

    # an internal (training-error) criterion would prefer the spurious pair: it fits exactly
    def train_mse(i: int, j: int) -> float:
        a, b = X[:n_train, i], X[:n_train, j]
        A = np.column_stack([np.ones(n_train), a, b, a * a, b * b, a * b])
        coef = np.linalg.lstsq(A, y[:n_train], rcond=None)[0]
        return float(np.mean((A @ coef - y[:n_train]) ** 2))

    assert train_mse(0, 2) < 1e-12 < train_mse(1, 2)
    # the regularity criterion rejects it: the best first-layer neuron uses x_true, not x_spur
    best_pair = set(model.layers_[0].pairs[0].tolist())
    assert 1 in best_pair and 0 not in best_pair
    X_new = np.column_stack([rng.normal(size=n), x_true, rng.normal(size=n)])
    assert model.score(X_new, x_true) > 0.9


def test_stops_after_one_layer_on_a_linear_target() -> None:
    rng = np.random.default_rng(6)
    X = rng.normal(size=(1000, 4))
    y = 2.0 * X[:, 0] - X[:, 1] + 0.5 + 0.05 * rng.normal(size=1000)
    model = GmdhRegressor().fit(X, y)
    assert model.n_layers_ == 1 < model.max_layers
    assert model.criterion_[0] == pytest.approx(0.05**2, rel=0.3)  # noise floor


def test_exact_fit_stops_immediately() -> None:
    rng = np.random.default_rng(7)
    X = rng.normal(size=(100, 3))
    y = 1.0 + X[:, 0] * X[:, 2] - 0.5 * X[:, 2] ** 2
    model = GmdhRegressor().fit(X, y)
    assert model.n_layers_ == 1
    np.testing.assert_allclose(model.predict(X), y, rtol=1e-7, atol=1e-7)


# --- robustness ------------------------------------------------------------------------------


@pytest.mark.parametrize("ridge", [1e-8, 0.0])
def test_constant_and_duplicated_columns_do_not_crash(ridge: float) -> None:
    rng = np.random.default_rng(8)
    x = rng.normal(size=300)
    X = np.column_stack([x, np.full(300, 3.0), x, np.zeros(300)])
    y = x**2 + 0.01 * rng.normal(size=300)
    model = GmdhRegressor(ridge=ridge).fit(X, y)
    pred = model.predict(X)
    assert np.all(np.isfinite(pred))
    assert model.score(X, y) > 0.99


def test_all_constant_inputs_predict_the_mean() -> None:
    X = np.ones((50, 3))
    y = np.arange(50.0)
    pred = GmdhRegressor().fit(X, y).predict(X)
    assert np.ptp(pred) < 1e-9  # a constant: the training-part mean
    assert abs(pred[0] - y.mean()) < 1.0


def test_single_feature_uses_a_quadratic_in_it() -> None:
    rng = np.random.default_rng(9)
    X = rng.uniform(-2, 2, (300, 1))
    y = 1.0 - 2.0 * X[:, 0] + 0.7 * X[:, 0] ** 2
    # the default offers u² as an input term too; its (u, u²) neuron is a quartic whose two
    # spare coefficients the relative ridge (1e-8 of the Gram trace, which the u⁸ moments
    # dominate) pulls off zero by ~1e-7: exact to that bias, not to rounding
    np.testing.assert_allclose(GmdhRegressor().fit(X, y).predict(X), y, rtol=0, atol=1e-5)
    model = GmdhRegressor.paper().fit(X, y)  # features in layer 1 only: the (u, u) neuron
    first = model.network_[0]
    assert first.pairs.tolist() == [[0, 0]]
    assert first.coefs[0, [2, 4, 5]].tolist() == [0.0, 0.0, 0.0]  # duplicates merged
    np.testing.assert_allclose(model.predict(X), y, rtol=1e-7, atol=1e-7)


def test_two_samples_fit_and_predict() -> None:
    model = GmdhRegressor().fit([[0.0, 1.0], [1.0, 3.0]], [1.0, 2.0])
    assert np.all(np.isfinite(model.predict([[0.5, 2.0]])))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_raises(bad: float) -> None:
    X, y = _quad_of_quad(50, 10)
    X_bad = X.copy()
    X_bad[3, 1] = bad
    with pytest.raises(ValueError, match="Input X contains"):
        GmdhRegressor().fit(X_bad, y)
    model = GmdhRegressor().fit(X, y)
    with pytest.raises(ValueError, match="Input X contains"):
        model.predict(X_bad)
    with pytest.raises(ValueError, match="NaN or infinity"):
        model.predict_one(X_bad[3])
    y_bad = y.copy()
    y_bad[0] = bad
    with pytest.raises(ValueError, match="Input y contains"):
        GmdhRegressor().fit(X, y_bad)


def test_wrong_feature_count_raises() -> None:
    X, y = _quad_of_quad(50, 11)
    model = GmdhRegressor().fit(X, y)
    with pytest.raises(ValueError, match="X has 3 features, but GmdhRegressor is expecting 4"):
        model.predict(X[:, :3])
    with pytest.raises(ValueError, match="X has 3 features"):
        model.predict_one(X[0, :3])


@pytest.mark.parametrize(
    ("param", "value"),
    [("alpha", 1.5), ("max_layers", 0), ("max_neurons", 2.5), ("split", "shuffle"),
     ("validation_fraction", 1.0), ("tol", -0.1), ("ridge", float("nan"))],
)
def test_bad_hyperparameter_names_the_parameter(param: str, value: Any) -> None:
    X, y = _quad_of_quad(50, 12)
    with pytest.raises(ValueError, match=f"parameter {param}="):
        GmdhRegressor(**{param: value}).fit(X, y)


# --- inspection and fast paths -------------------------------------------------------------


def test_printed_polynomial_re_evaluates_to_the_predictions() -> None:
    X, y = _quad_of_quad(1000, 13)
    model = GmdhRegressor().fit(X, y)
    text = model.polynomial(digits=17)
    namespace: dict[str, Any] = {"x": X.T}
    exec(text, namespace)
    np.testing.assert_allclose(namespace["y"], model.predict(X), rtol=1e-12, atol=1e-12)
    # the default form is short and readable: one line per used input, neuron, and output
    lines = model.polynomial().splitlines()
    n_neurons = sum(layer.pairs.shape[0] for layer in model.network_)
    n_features = sum(re.match(r"u\d+ = \(x\[\d+\]", line) is not None for line in lines)
    n_products = sum(re.match(r"u\d+_\d+ = u\d+\*u\d+$", line) is not None for line in lines)
    assert 1 <= n_features <= 4
    assert len(lines) == 1 + n_features + n_products + n_neurons + 1
    assert lines[-1].startswith("y = ")


def test_predict_one_matches_predict() -> None:
    X, y = _quad_of_quad(800, 14)
    model = GmdhRegressor().fit(X, y)
    batch = model.predict(X[:50])
    single = np.array([model.predict_one(row) for row in X[:50]])
    np.testing.assert_array_equal(single, batch)  # same operations in the same order
    assert model.predict_one(list(X[0])) == batch[0]
    # the compiled fast path survives pickling (it is rebuilt from its source)
    restored = pickle.loads(pickle.dumps(model))
    assert restored.predict_one(X[1]) == batch[1]


@pytest.mark.parametrize("split", ["random", "interleaved", "tail"])
def test_deterministic_for_a_given_random_state(split: str) -> None:
    X, y = _quad_of_quad(600, 15)
    y = y + 0.05 * np.random.default_rng(16).normal(size=600)
    a = GmdhRegressor(split=split, random_state=3).fit(X, y).predict(X)
    b = GmdhRegressor(split=split, random_state=3).fit(X, y).predict(X)
    np.testing.assert_array_equal(a, b)
    if split == "random":
        c = GmdhRegressor(split=split, random_state=4).fit(X, y).predict(X)
        assert not np.array_equal(a, c)
