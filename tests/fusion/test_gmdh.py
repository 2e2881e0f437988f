"""GMDH polynomial network (fusion.gmdh): estimator contract, layer building, selection,
external criterion, stopping, robustness, readable polynomial, fast single-sample path."""

from __future__ import annotations

import itertools
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
from fusion.gmdh_layer import eval_neurons, pool_values, split_masks
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


@pytest.mark.parametrize("make", [GmdhRegressor, GmdhRegressor.paper])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_raises(bad: float, make: Callable[[], GmdhRegressor]) -> None:
    X, y = _quad_of_quad(50, 10)
    X_bad = X.copy()
    X_bad[3, 1] = bad
    with pytest.raises(ValueError, match="Input X contains"):
        make().fit(X_bad, y)
    model = make().fit(X, y)
    with pytest.raises(ValueError, match="Input X contains"):
        model.predict(X_bad)
    with pytest.raises(ValueError, match="NaN or infinity"):
        model.predict_one(X_bad[3])
    y_bad = y.copy()
    y_bad[0] = bad
    with pytest.raises(ValueError, match="Input y contains"):
        make().fit(X, y_bad)


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
     ("validation_fraction", 1.0), ("tol", -0.1), ("ridge", float("nan")),
     ("min_survivors", 0), ("max_correlation", 0.0), ("inputs", "all"), ("significance", -1.0),
     ("clip_margin", -0.1)],
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


@pytest.mark.parametrize("split", ["random", "interleaved", "blocked", "tail"])
def test_deterministic_for_a_given_random_state(split: str) -> None:
    X, y = _quad_of_quad(600, 15)
    y = y + 0.05 * np.random.default_rng(16).normal(size=600)
    a = GmdhRegressor(split=split, random_state=3).fit(X, y).predict(X)
    b = GmdhRegressor(split=split, random_state=3).fit(X, y).predict(X)
    np.testing.assert_array_equal(a, b)
    if split == "random":
        c = GmdhRegressor(split=split, random_state=4).fit(X, y).predict(X)
        assert not np.array_equal(a, c)


# --- the regressor defaults against P0 ------------------------------------------------------------

_NOISE = 0.02


def _polynomial_problem(degree: int, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """6 inputs uniform in [-1, 1]; noiseless target of degree 2 or 4."""
    X = np.random.default_rng(seed).uniform(-1.0, 1.0, (n, 6))
    x0, x1, x2, x3, x4 = (X[:, k] for k in range(5))
    if degree == 2:
        return X, 1.0 + 2.0 * x0 - x1 + 0.5 * x0 * x2 - 0.8 * x3**2
    return X, (x0 * x1 + 0.5 * x2) ** 2 - x3 * x4


def _noisy(y: np.ndarray, seed: int) -> np.ndarray:
    return y + _NOISE * np.random.default_rng(seed).normal(size=y.shape)


def test_defaults_recover_a_degree_two_polynomial_to_the_noise_floor() -> None:
    X, f = _polynomial_problem(2, 3000, 21)
    X_test, f_test = _polynomial_problem(2, 3000, 22)
    model = GmdhRegressor().fit(X, _noisy(f, 23))
    excess = np.sqrt(np.mean((model.predict(X_test) - f_test) ** 2))  # against the truth
    # the network can represent the target exactly (a neuron per pair of its terms, then a
    # linear combination), so what is left is estimation noise: p coefficients fitted on
    # n_train noisy samples leave an RMS error of about sigma·sqrt(p / n_train); allow 3x
    n_coefs = sum(layer.coefs.size for layer in model.network_)
    n_train = round(0.7 * 3000)
    assert excess <= 3.0 * _NOISE * np.sqrt(n_coefs / n_train)
    assert excess < 0.5 * _NOISE
    # P0's selection chains the layers (5, 4, 3, 2, 1 survivors): many times the
    # noise floor on the same data
    paper = GmdhRegressor.paper().fit(X, _noisy(f, 23))
    assert np.sqrt(np.mean((paper.predict(X_test) - f_test) ** 2)) > 5.0 * _NOISE


def test_defaults_model_a_degree_four_target_below_the_noise() -> None:
    # (x0·x1 + 0.5·x2)² - x3·x4: no neuron fitted to the target carries x0·x1 (the target
    # has no quadratic component along it); the product offered as an input term does
    X, f = _polynomial_problem(4, 3000, 24)
    X_test, f_test = _polynomial_problem(4, 3000, 25)
    model = GmdhRegressor().fit(X, _noisy(f, 26))
    excess = np.sqrt(np.mean((model.predict(X_test) - f_test) ** 2))
    # the signal's standard deviation is ~17 sigma; P0 leaves ~13 sigma (0.26); the
    # defaults must model it to below the noise level (estimation noise alone is ~0.2 sigma)
    assert excess < _NOISE
    assert np.std(f_test) > 15 * _NOISE
    features_only = GmdhRegressor(inputs="every-layer").fit(X, _noisy(f, 26))
    assert np.sqrt(np.mean((features_only.predict(X_test) - f_test) ** 2)) > 5 * _NOISE


@pytest.mark.parametrize("case", ["noisy", "constant-columns", "tiny"])
def test_selection_never_leaves_fewer_than_min_survivors(case: str) -> None:
    rng = np.random.default_rng(27)
    if case == "noisy":
        X = rng.normal(size=(400, 5))
        y = X[:, 0] * X[:, 1] + np.sin(X[:, 2]) + 0.1 * rng.normal(size=400)
    elif case == "constant-columns":
        x = rng.normal(size=300)
        X = np.column_stack([x, np.full(300, 3.0), x, np.zeros(300), rng.normal(size=300)])
        y = x**2 + X[:, 4] + 0.01 * rng.normal(size=300)
    else:
        X = rng.normal(size=(12, 3))
        y = X[:, 0] - X[:, 2] ** 2
    # alpha = 1 alone keeps one neuron per layer (P0's chain); min_survivors overrides it
    model = GmdhRegressor(alpha=1.0, min_survivors=6, max_neurons=8, significance=0.0,
                          tol=0.0).fit(X, y)  # fmt: skip
    for layer in model.layers_:
        assert layer.pairs.shape[0] == 6
    assert np.all(np.isfinite(model.predict(X)))


def test_survivors_are_not_near_duplicates() -> None:
    # three copies of x0: every pair-neuron on x0 exists three times over
    rng = np.random.default_rng(28)
    a, b, c = rng.uniform(-1, 1, (3, 1000))
    X = np.column_stack([a, a, a, b, c])
    y = a * b + 0.5 * c**2 + 0.02 * rng.normal(size=1000)
    model = GmdhRegressor(max_layers=1, min_survivors=6, max_neurons=6).fit(X, y)
    layer = model.layers_[0]
    # their validation errors, as the selection saw them
    val = split_masks(1000, 0.3, "blocked", 0)
    U = (X[val] - model.x_mean_) / model.x_scale_
    Z = eval_neurons(pool_values(U, model.pool_), layer.pairs, layer.coefs)
    resid = Z - ((y[val] - model.y_mean_) / model.y_scale_)[:, None]
    corr = np.corrcoef(resid.T)
    off_diagonal = corr[~np.eye(len(corr), dtype=bool)]
    assert np.max(np.abs(off_diagonal)) <= model.max_correlation
    # without the check the copies crowd the layer: identical errors
    crowded = GmdhRegressor(max_layers=1, min_survivors=6, max_neurons=6,
                            max_correlation=1.0).fit(X, y).layers_[0]  # fmt: skip
    Zc = eval_neurons(pool_values(U, model.pool_), crowded.pairs, crowded.coefs)
    corr_c = np.corrcoef((Zc - ((y[val] - model.y_mean_) / model.y_scale_)[:, None]).T)
    assert np.max(np.abs(corr_c[~np.eye(len(corr_c), dtype=bool)])) > 1.0 - 1e-9


@pytest.mark.parametrize("n", [2, 3, 7, 10, 11, 99, 1000, 1003])
@pytest.mark.parametrize("fraction", [0.1, 0.3, 0.5, 0.9])
def test_blocked_split_uses_contiguous_blocks(n: int, fraction: float) -> None:
    mask = split_masks(n, fraction, "blocked", None)
    assert 1 <= mask.sum() <= n - 1  # both parts non-empty
    # runs of validation samples: at most one per block, each a whole block
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    starts, stops = edges[::2], edges[1::2]
    n_blocks = min(10, n)
    assert len(starts) <= n_blocks
    block = n / n_blocks
    assert np.all(stops - starts >= np.floor(block))
    if n >= 100:
        # the share is that of whole blocks: within one block of the requested fraction
        assert abs(mask.mean() - fraction) <= 1.0 / n_blocks + 1.0 / n


def _p0_reference(X: np.ndarray, y: np.ndarray, X_new: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """P0's GMDH written plainly (per-pair least squares, no standardisation, no moments):
    interleaved 30 % validation, survivors under alpha·e_min + (1-alpha)·e_max, at most 10,
    5 layers, stop when the best criterion does not improve by 0.1 %."""
    n = len(y)
    n_val = round(0.3 * n)
    val = np.zeros(n, dtype=bool)
    val[np.floor((np.arange(n_val) + 0.5) * n / n_val).astype(int)] = True
    Zt, Zv, Zn = X[~val], X[val], X_new
    yt, yv = y[~val], y[val]

    def design(Z: np.ndarray, i: int, j: int) -> np.ndarray:
        a, b = Z[:, i], Z[:, j]
        if i == j:  # a single input: a quadratic in it
            return np.column_stack([np.ones(len(a)), a, a * a])
        return np.column_stack([np.ones(len(a)), a, b, a * a, b * b, a * b])

    best_prev, out, counts = np.inf, Zn[:, 0], []
    for _ in range(5):
        fits = []
        m = Zt.shape[1]
        for i, j in itertools.combinations(range(m), 2) if m > 1 else [(0, 0)]:
            c = np.linalg.lstsq(design(Zt, i, j), yt, rcond=None)[0]
            fits.append((float(np.mean((design(Zv, i, j) @ c - yv) ** 2)), i, j, c))
        crit = np.array([f[0] for f in fits])
        e_c = 0.6 * crit.min() + 0.4 * crit.max()
        kept = sorted((f for f in fits if f[0] <= e_c), key=lambda f: f[0])[:10]
        if not kept[0][0] < best_prev * (1 - 1e-3):
            break
        best_prev = kept[0][0]
        counts.append(len(kept))
        Zt, Zv, Zn = (np.column_stack([design(Z, i, j) @ c for _, i, j, c in kept])
                      for Z in (Zt, Zv, Zn))  # fmt: skip
        out = Zn[:, 0]
    return out, counts


def test_paper_preset_is_p0() -> None:
    # the preset reproduces P0's algorithm (the bridges' comparisons depend on it)
    rng = np.random.default_rng(30)
    X = rng.uniform(-1, 1, (800, 5))
    y = np.sin(2 * X[:, 0]) * X[:, 1] + X[:, 2] ** 2 - 0.5 * X[:, 3] + 0.05 * rng.normal(size=800)
    X_new = rng.uniform(-1, 1, (200, 5))
    model = GmdhRegressor.paper().fit(X, y)
    ref, counts = _p0_reference(X, y, X_new)
    assert [layer.pairs.shape[0] for layer in model.layers_] == counts
    # same selections; the fits differ only by the 1e-8 relative ridge and rounding
    np.testing.assert_allclose(model.predict(X_new), ref, rtol=0, atol=1e-6 * np.std(y))
    assert GmdhRegressor.paper().get_params() == {
        **GmdhRegressor().get_params(),
        "max_layers": 5, "max_neurons": 10, "alpha": 0.6, "min_survivors": 1,
        "max_correlation": 1.0, "inputs": "first-layer", "split": "interleaved",
        "significance": 0.0, "clip_margin": None,
    }  # fmt: skip
    assert GmdhRegressor.paper(split="tail").split == "tail"


def test_features_reach_every_layer() -> None:
    X, y = _quad_of_quad(1500, 31)
    y = y + 0.01 * np.random.default_rng(32).normal(size=1500)
    model = GmdhRegressor(inputs="every-layer").fit(X, y)
    assert model.n_layers_ >= 2
    for prev, layer in itertools.pairwise(model.layers_):
        n_prev = prev.pairs.shape[0]
        assert layer.pairs.max() < n_prev + X.shape[1]  # survivors, then the 4 features
        assert np.all(layer.pairs[:, 0] < n_prev)  # at least one learned input per neuron
    # some neuron after layer 1 pairs a learned neuron with a raw feature
    assert any((layer.pairs[:, 1] >= prev.pairs.shape[0]).any()
               for prev, layer in itertools.pairwise(model.layers_))  # fmt: skip
    # P0: a layer sees only the previous layer's survivors
    paper = GmdhRegressor.paper().fit(X, y)
    for prev, layer in itertools.pairwise(paper.layers_):
        assert layer.pairs.max() < prev.pairs.shape[0]


def test_outputs_are_clipped_to_the_fitted_range_outside_the_data() -> None:
    X, y = _quad_of_quad(1000, 33)
    model = GmdhRegressor().fit(X, y)
    far = np.full((20, 4), 1e3) * np.linspace(-1, 1, 20)[:, None]  # far outside [0, 1]⁴
    pred = model.predict(far)
    assert np.all(np.isfinite(pred))
    # the output neuron is held within its fitted range widened by clip_margin each side
    lo, hi = model.network_[-1].bounds[0]
    span = (hi - lo) / (1 + 2 * model.clip_margin)
    assert np.all(pred >= model.y_mean_ + model.y_scale_ * lo - 1e-9 * span)
    assert np.all(pred <= model.y_mean_ + model.y_scale_ * hi + 1e-9 * span)
    assert np.ptp(pred) <= model.y_scale_ * (hi - lo) * (1 + 1e-9)
    # inside the data clipping changes nothing, and the scalar path agrees bitwise
    unclipped = GmdhRegressor(clip_margin=None).fit(X, y)
    np.testing.assert_array_equal(model.predict(X), unclipped.predict(X))
    assert [model.predict_one(row) for row in far] == pred.tolist()
