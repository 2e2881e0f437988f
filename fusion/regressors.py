"""Neural-network regressors of papers P0-P2, the comparators of the GMDH bridge.

- :class:`NarxMLP` (P1): one tanh hidden layer (35 neurons), NARX inputs (current and lagged
  features plus the network's own previous outputs), Levenberg-Marquardt training through
  ``scipy.optimize.least_squares(method="lm")``.
- :class:`RbfNet` (P0's RBF comparator): 15 Gaussian neurons, centres by a few seeded k-means
  iterations, widths from the centre spacing, output weights by regularised least squares.
- :class:`BpNet` (P2): one small sigmoid hidden layer, linear output, plain back-propagation
  (full-batch gradient descent with Adam steps, fixed epochs).

All follow the estimator contract of :class:`fusion.regressor_base.RegressorBase` (scikit-learn
compatible without importing it), standardise inputs and target inside ``fit`` and are
deterministic for a given ``random_state`` (``numpy.random.default_rng(random_state)``).
"""

from __future__ import annotations

from typing import Self

import numpy as np
from numpy.typing import ArrayLike

from fusion.regressor_base import FloatArray, RegressorBase

__all__ = ["BpNet", "NarxMLP", "RbfNet"]


def _param_error(owner: object, name: str, rule: str) -> ValueError:
    return ValueError(
        f"{type(owner).__name__}: parameter {name}={getattr(owner, name)!r} must be {rule}."
    )


def _require_int(owner: object, name: str, minimum: int) -> int:
    v = getattr(owner, name)
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise _param_error(owner, name, f"an integer >= {minimum}")
    return int(v)


def _require_real(
    owner: object, name: str, low: float, high: float = np.inf, low_open: bool = False
) -> float:
    v = getattr(owner, name)
    ok = not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
    if ok:
        f = float(v)
        ok = bool(np.isfinite(f)) and (f > low if low_open else f >= low) and f <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise _param_error(owner, name, f"a finite number in {bracket}{low}, {high}]")
    return float(v)


# ---------------------------------------------------------------------------------------------
# NARX MLP (P1)
# ---------------------------------------------------------------------------------------------


class NarxMLP(RegressorBase):
    """NARX multilayer perceptron trained by Levenberg-Marquardt (paper P1).

    The rows of ``X`` are consecutive samples of a time series. At step ``t`` the network
    sees ``[x_t, x_{t-1}, …, x_{t-n_input_lags}, y_{t-1}, …, y_{t-n_output_lags}]``
    (standardised) and outputs ``ŷ_t = w₂·tanh(W₁ r_t + b₁) + b₂``.

    - Training uses *teacher forcing*: the lagged outputs are the true previous targets.
      The first ``max(n_input_lags, n_output_lags)`` rows have no complete history and only
      serve as history.
    - Prediction runs *closed loop*: the lagged outputs are the network's own previous
      predictions, started from ``y_init`` (default: the training-target mean), and the
      input history before ``X[0]`` is ``x_init`` (default: ``X[0]`` repeated). So
      :meth:`predict` depends on row order and on where the sequence starts, by design.
    - :meth:`predict_one` is a stateless single step with explicit history, for the filter.

    Cost: MINPACK's LM factorises the full ``(m + p) × p`` Jacobian (``m`` samples, ``p``
    weights; ``p = 526`` for 6 features, one lag each, 35 neurons) with an unblocked QR every
    iteration, ``O(m·p²)``: about 1.5 s per iteration at ``m = 6000`` on a 2-core machine.
    ``max_nfev`` bounds the fit; train on GNSS-rate data (a few hundred samples), not on
    IMU-rate data.

    Parameters
    ----------
    n_hidden : int, default 35
        Hidden tanh neurons (P1 uses 35).
    n_input_lags : int ≥ 0, default 1
        Previous feature rows fed to the network.
    n_output_lags : int ≥ 0, default 1
        Previous outputs fed back (0 makes a plain feed-forward time-delay network).
    max_nfev : int, default 100
        Bound on the LM function evaluations of one :meth:`fit` call, so a fit is
        time-bounded (MINPACK counts the first evaluation; 2 allow about one LM step).
    warm_start : bool, default False
        Continue from the weights and the standardisation of the previous :meth:`fit`
        (scikit-learn's meaning) when the architecture and the feature count match; training
        then proceeds across successive bounded fits. Otherwise start from the seeded
        initialisation.
    l2 : float ≥ 0, default 1e-4
        Weight decay, added as residuals ``sqrt(l2)·w`` (keeps LM well posed even with fewer
        samples than weights, which MINPACK's LM otherwise refuses).
    random_state : int, Generator or None, default 0
        Seed of the weight initialisation.

    Attributes
    ----------
    n_features_in_ : int
    x_mean_, x_scale_ : (n_features,) ; y_mean_, y_scale_ : float
        Standardisation.
    W1_ : (n_hidden, n_inputs) ; b1_ : (n_hidden,) ; w2_ : (n_hidden,) ; b2_ : float
        Weights (standardised units); ``n_inputs = n_features·(1 + n_input_lags) +
        n_output_lags``, ordered ``[x_t, x_{t-1}, …, y_{t-1}, …]``.
    n_iter_ : int
        Function evaluations used by LM in the last fit.
    n_iter_total_ : int
        Function evaluations over all fits continued by ``warm_start``.
    cost_ : float
        Final LM cost ``½‖r‖²`` (standardised units, weight decay included).
    """

    W1_: FloatArray
    b1_: FloatArray
    w2_: FloatArray
    b2_: float

    def __init__(
        self,
        n_hidden: int = 35,
        n_input_lags: int = 1,
        n_output_lags: int = 1,
        max_nfev: int = 100,
        l2: float = 1e-4,
        random_state: int | None = 0,
        warm_start: bool = False,
    ) -> None:
        self.n_hidden = n_hidden
        self.n_input_lags = n_input_lags
        self.n_output_lags = n_output_lags
        self.max_nfev = max_nfev
        self.l2 = l2
        self.random_state = random_state
        self.warm_start = warm_start

    # -- helpers ---------------------------------------------------------------------------
    def _lagged_inputs(self, U: FloatArray, history: FloatArray) -> FloatArray:
        """``[u_t, u_{t-1}, …]`` rows for every t; ``history`` are the rows before ``U[0]``
        (most recent last)."""
        k = int(self.n_input_lags)
        full = np.vstack([history, U]) if k else U
        n = U.shape[0]
        return np.hstack([full[k - lag : k - lag + n] for lag in range(k + 1)])

    @staticmethod
    def _unpack(
        theta: FloatArray, n_hidden: int, n_in: int
    ) -> tuple[FloatArray, FloatArray, FloatArray, float]:
        a = n_hidden * n_in
        W1 = theta[:a].reshape(n_hidden, n_in)
        b1 = theta[a : a + n_hidden]
        w2 = theta[a + n_hidden : a + 2 * n_hidden]
        return W1, b1, w2, float(theta[-1])

    # -- fitting ---------------------------------------------------------------------------
    def fit(self, X: ArrayLike, y: ArrayLike) -> Self:
        """Train on one time series (rows of ``X`` in time order) with teacher forcing.

        Parameters
        ----------
        X : (n_samples, n_features) array_like
            Features in time order.
        y : (n_samples,) array_like
            Target in time order.

        Returns
        -------
        self
        """
        n_hidden = _require_int(self, "n_hidden", 1)
        n_in_lags = _require_int(self, "n_input_lags", 0)
        n_out_lags = _require_int(self, "n_output_lags", 0)
        max_nfev = _require_int(self, "max_nfev", 1)
        l2 = _require_real(self, "l2", 0.0)
        lag = max(n_in_lags, n_out_lags)
        U, v, sc = self._standardised_fit_data(X, y, min_samples=lag + 1)
        n, f = U.shape
        n_in = f * (1 + n_in_lags) + n_out_lags
        warm = self._warm_theta(n_hidden, n_in)
        if warm is not None:
            # continue in the previous fit's units (its weights mean nothing in new ones)
            old = self._stored_scaling()
            U = U * sc.x_scale / old.x_scale + (sc.x_mean - old.x_mean) / old.x_scale
            v = v * sc.y_scale / old.y_scale + (sc.y_mean - old.y_mean) / old.y_scale
            sc = old

        # regressors for rows lag..n-1, every lag genuinely observed (teacher forcing)
        R_x = self._lagged_inputs(U[lag:], U[lag - n_in_lags : lag] if n_in_lags else U[:0])
        R_y = (
            np.column_stack([v[lag - k : n - k] for k in range(1, n_out_lags + 1)])
            if n_out_lags
            else np.empty((n - lag, 0))
        )
        R = np.hstack([R_x, R_y])
        t = v[lag:]

        if warm is not None:
            theta0 = warm
        else:
            rng = np.random.default_rng(self.random_state)
            theta0 = np.concatenate(
                [
                    rng.normal(0.0, 1.0 / np.sqrt(n_in), n_hidden * n_in),  # fan-in scaled
                    rng.normal(0.0, 0.5, n_hidden),
                    rng.normal(0.0, 1.0 / np.sqrt(n_hidden), n_hidden),
                    [0.0],
                ]
            )
        sqrt_l2 = np.sqrt(l2)
        n_par = theta0.size

        def residuals(theta: FloatArray) -> FloatArray:
            W1, b1, w2, b2 = self._unpack(theta, n_hidden, n_in)
            H = np.tanh(R @ W1.T + b1)
            return np.concatenate([H @ w2 + b2 - t, sqrt_l2 * theta])

        def jacobian(theta: FloatArray) -> FloatArray:
            W1, b1, w2, _ = self._unpack(theta, n_hidden, n_in)
            H = np.tanh(R @ W1.T + b1)
            D = (1.0 - H * H) * w2  # ∂ŷ/∂(pre-activation), (m, n_hidden)
            J = np.empty((len(t) + n_par, n_par))
            m = len(t)
            J[:m, : n_hidden * n_in] = (D[:, :, None] * R[:, None, :]).reshape(m, -1)
            J[:m, n_hidden * n_in : n_hidden * (n_in + 1)] = D
            J[:m, n_hidden * (n_in + 1) : n_hidden * (n_in + 2)] = H
            J[:m, -1] = 1.0
            J[m:] = sqrt_l2 * np.eye(n_par)
            return J

        # scipy.optimize (~0.2 CPU s to import) only when a network is trained: the filter
        # imports this module for its bridging registry in every run
        from scipy.optimize import least_squares

        sol = least_squares(residuals, theta0, jac=jacobian, method="lm", max_nfev=max_nfev)
        W1, b1, w2, b2 = self._unpack(sol.x, n_hidden, n_in)

        total = int(getattr(self, "n_iter_total_", 0)) if warm is not None else 0
        self._store_scaling(sc)
        # fresh arrays: a copy of this model taken before the fit keeps its own weights
        self.W1_ = W1.copy()
        self.b1_ = b1.copy()
        self.w2_ = w2.copy()
        self.b2_ = b2
        self.n_iter_ = int(sol.nfev)
        self.n_iter_total_ = total + int(sol.nfev)
        self.cost_ = float(sol.cost)
        return self

    def _warm_theta(self, n_hidden: int, n_in: int) -> FloatArray | None:
        """The previous fit's weights as LM's start vector, or ``None`` for a cold start."""
        if not (self.warm_start and hasattr(self, "W1_")):
            return None
        if self.W1_.shape != (n_hidden, n_in):
            return None
        out: FloatArray = np.concatenate([self.W1_.ravel(), self.b1_, self.w2_, [self.b2_]])
        return out

    # -- prediction ------------------------------------------------------------------------
    def predict(
        self,
        X: ArrayLike,
        *,
        x_init: ArrayLike | None = None,
        y_init: ArrayLike | None = None,
    ) -> FloatArray:
        """Closed-loop prediction over a sequence.

        Parameters
        ----------
        X : (n_samples, n_features_in_) array_like
            Features in time order.
        x_init : (n_input_lags, n_features_in_) array_like, optional
            Feature rows before ``X[0]``, most recent last (default ``X[0]`` repeated).
        y_init : (n_output_lags,) array_like, optional
            Outputs before ``X[0]``, most recent last, target units (default: the training
            target mean), e.g. the last GNSS-observed values at the start of an outage.

        Returns
        -------
        (n_samples,) float64
        """
        U = self._standardised_input(X)
        k_in, k_out = int(self.n_input_lags), int(self.n_output_lags)
        hist_x = self._x_history(x_init, U[0], k_in)
        hist_y = self._y_history(y_init, k_out)
        n_x = U.shape[1] * (k_in + 1)
        # the exogenous part of every pre-activation at once; only the feedback is sequential
        A = self._lagged_inputs(U, hist_x) @ self.W1_[:, :n_x].T + self.b1_
        out = np.empty(U.shape[0])
        if k_out == 0:
            out[:] = np.tanh(A) @ self.w2_ + self.b2_
        else:
            Wy = self.W1_[:, n_x:]
            fb = list(hist_y[::-1])  # most recent first, like the regressor layout
            w2, b2 = self.w2_, self.b2_
            for i in range(U.shape[0]):
                z = float(np.tanh(A[i] + Wy @ fb) @ w2) + b2
                out[i] = z
                fb = [z, *fb[:-1]]
        return self._target_units(out)

    def predict_one(
        self,
        x: ArrayLike,
        x_prev: ArrayLike | None = None,
        y_prev: ArrayLike | None = None,
    ) -> float:
        """One closed-loop step with explicit history (stateless).

        Parameters
        ----------
        x : (n_features_in_,) array_like
            Current features.
        x_prev : (n_input_lags, n_features_in_) array_like, optional
            Previous feature rows, most recent last (default ``x`` repeated).
        y_prev : (n_output_lags,) array_like, optional
            Previous outputs (target units), most recent last (default: training mean).

        Returns
        -------
        float
        """
        xa = np.asarray(x, dtype=np.float64)
        if xa.ndim != 1:
            raise ValueError(f"NarxMLP.predict_one: x must be 1-D, got shape {xa.shape}.")
        Xa = self._validate_predict(xa[None, :])
        u = (Xa[0] - self.x_mean_) / self.x_scale_
        k_in, k_out = int(self.n_input_lags), int(self.n_output_lags)
        hx = self._x_history(x_prev, u, k_in)
        hy = self._y_history(y_prev, k_out)
        r = np.concatenate([u, hx[::-1].ravel(), hy[::-1]])
        z = float(np.tanh(self.W1_ @ r + self.b1_) @ self.w2_) + self.b2_
        return self.y_mean_ + self.y_scale_ * z

    def _x_history(self, x_init: ArrayLike | None, first: FloatArray, k: int) -> FloatArray:
        """Standardised ``(k, n_features)`` history, most recent last."""
        if x_init is None:
            return np.tile(first, (k, 1))
        h = np.asarray(x_init, dtype=np.float64)
        if h.shape != (k, self.n_features_in_) or not np.isfinite(h).all():
            raise ValueError(
                f"NarxMLP: x_init must be finite with shape ({k}, {self.n_features_in_}), "
                f"got {h.shape}."
            )
        out: FloatArray = (h - self.x_mean_) / self.x_scale_
        return out

    def _y_history(self, y_init: ArrayLike | None, k: int) -> FloatArray:
        """Standardised ``(k,)`` output history, most recent last."""
        if y_init is None:
            return np.zeros(k)
        h = np.asarray(y_init, dtype=np.float64).reshape(-1)
        if h.shape != (k,) or not np.isfinite(h).all():
            raise ValueError(f"NarxMLP: y_init must be finite with shape ({k},), got {h.shape}.")
        out: FloatArray = (h - self.y_mean_) / self.y_scale_
        return out


# ---------------------------------------------------------------------------------------------
# RBF network (P0 comparator)
# ---------------------------------------------------------------------------------------------


def _sq_dist(A: FloatArray, C: FloatArray) -> FloatArray:
    """Squared Euclidean distances ``(len(A), len(C))``, clipped at 0 against rounding."""
    d = (A * A).sum(1)[:, None] - 2.0 * A @ C.T + (C * C).sum(1)[None, :]
    out: FloatArray = np.maximum(d, 0.0)
    return out


class RbfNet(RegressorBase):
    """Gaussian radial-basis-function network (P0's RBF comparator).

    Centres: ``n_centers`` distinct training points drawn with ``random_state``, refined by
    ``n_kmeans_iter`` Lloyd (k-means) iterations in standardised input space. Width of each
    Gaussian ``σ_k = width_factor ×`` distance to its nearest other centre (the mean of those
    spacings where a centre has a duplicate, 1 for a single centre). Output: bias plus
    weighted Gaussians, weights by ridge-regularised least squares (P0 trains the output
    weights by gradient descent; the least-squares solution is that descent's fixed point).

    Parameters
    ----------
    n_centers : int, default 15
    width_factor : float > 0, default 1.0
    ridge : float ≥ 0, default 1e-6
        Ridge on the output weights (relative to the number of samples).
    n_kmeans_iter : int ≥ 0, default 10
    random_state : int, Generator or None, default 0

    Attributes
    ----------
    n_features_in_ : int
    x_mean_, x_scale_, y_mean_, y_scale_ : standardisation
    centers_ : (k, n_features) standardised centres (k = min(n_centers, distinct samples))
    widths_ : (k,) Gaussian σ in standardised units
    weights_ : (k,) output weights ; bias_ : float
    """

    def __init__(
        self,
        n_centers: int = 15,
        width_factor: float = 1.0,
        ridge: float = 1e-6,
        n_kmeans_iter: int = 10,
        random_state: int | None = 0,
    ) -> None:
        self.n_centers = n_centers
        self.width_factor = width_factor
        self.ridge = ridge
        self.n_kmeans_iter = n_kmeans_iter
        self.random_state = random_state

    def fit(self, X: ArrayLike, y: ArrayLike) -> Self:
        """Place the centres and solve the output weights.

        Parameters
        ----------
        X : (n_samples, n_features) array_like
        y : (n_samples,) array_like

        Returns
        -------
        self
        """
        n_centers = _require_int(self, "n_centers", 1)
        width_factor = _require_real(self, "width_factor", 0.0, low_open=True)
        ridge = _require_real(self, "ridge", 0.0)
        n_iter = _require_int(self, "n_kmeans_iter", 0)
        U, v, sc = self._standardised_fit_data(X, y, min_samples=1)

        rng = np.random.default_rng(self.random_state)
        distinct = np.unique(U, axis=0)
        k = min(n_centers, len(distinct))
        C = distinct[rng.choice(len(distinct), size=k, replace=False)]
        for _ in range(n_iter):
            label = np.argmin(_sq_dist(U, C), axis=1)
            counts = np.bincount(label, minlength=k)
            sums = np.column_stack(
                [np.bincount(label, weights=U[:, d], minlength=k) for d in range(U.shape[1])]
            )
            moved = counts > 0  # an empty cluster keeps its centre
            C_new = C.copy()
            C_new[moved] = sums[moved] / counts[moved, None]
            if np.array_equal(C_new, C):
                break
            C = C_new
        widths = self._widths(C, width_factor)

        Phi = self._design(U, C, widths)
        n = len(v)
        # ridge-regularised least squares as an augmented lstsq (robust when Phi is singular);
        # the bias column is not penalised
        lam = np.sqrt(ridge * n)
        reg = np.hstack([np.zeros((k, 1)), lam * np.eye(k)])
        sol = np.linalg.lstsq(np.vstack([Phi, reg]), np.concatenate([v, np.zeros(k)]), rcond=None)[
            0
        ]

        self._store_scaling(sc)
        self.centers_ = C
        self.widths_ = widths
        self.bias_ = float(sol[0])
        self.weights_ = sol[1:]
        return self

    @staticmethod
    def _widths(C: FloatArray, factor: float) -> FloatArray:
        if len(C) == 1:
            return np.array([factor])
        d = np.sqrt(_sq_dist(C, C))
        np.fill_diagonal(d, np.inf)
        nearest = d.min(axis=1)
        positive = nearest[nearest > 1e-12]
        fill = positive.mean() if positive.size else 1.0
        out: FloatArray = factor * np.where(nearest > 1e-12, nearest, fill)
        return out

    @staticmethod
    def _design(U: FloatArray, C: FloatArray, widths: FloatArray) -> FloatArray:
        G = np.exp(-_sq_dist(U, C) / (2.0 * widths**2))
        return np.hstack([np.ones((len(U), 1)), G])

    def predict(self, X: ArrayLike) -> FloatArray:
        """Predict the target for every row of ``X``.

        Parameters
        ----------
        X : (n_samples, n_features_in_) array_like

        Returns
        -------
        (n_samples,) float64
        """
        U = self._standardised_input(X)
        G = np.exp(-_sq_dist(U, self.centers_) / (2.0 * self.widths_**2))
        return self._target_units(G @ self.weights_ + self.bias_)


# ---------------------------------------------------------------------------------------------
# BP network (P2)
# ---------------------------------------------------------------------------------------------


def _sigmoid(a: FloatArray) -> FloatArray:
    # clipped so exp never overflows; beyond ±60 the logistic is 0 or 1 to double precision
    out: FloatArray = 1.0 / (1.0 + np.exp(-np.clip(a, -60.0, 60.0)))
    return out


class BpNet(RegressorBase):
    """Back-propagation network of paper P2: one sigmoid hidden layer, linear output.

    Trained by full-batch gradient descent on the mean squared error with Adam steps for a
    fixed number of epochs from a seeded Glorot-uniform initialisation.

    Parameters
    ----------
    n_hidden : int, default 8
    n_epochs : int, default 500
    learning_rate : float > 0, default 0.02
    l2 : float ≥ 0, default 0.0
        Weight decay on the weights (not the biases).
    random_state : int, Generator or None, default 0
    warm_start : bool, default False
        Continue from the weights and the standardisation of the previous :meth:`fit` (fresh
        Adam moments) when the shapes match, so ``n_epochs`` bounds one fit and training
        proceeds across successive fits.

    Attributes
    ----------
    n_features_in_ : int
    x_mean_, x_scale_, y_mean_, y_scale_ : standardisation
    W1_ : (n_hidden, n_features) ; b1_ : (n_hidden,) ; w2_ : (n_hidden,) ; b2_ : float
    loss_curve_ : (n_epochs,) training MSE (standardised units) before each step
    n_iter_ : int
        Epochs run.
    """

    W1_: FloatArray
    b1_: FloatArray
    w2_: FloatArray
    b2_: float

    def __init__(
        self,
        n_hidden: int = 8,
        n_epochs: int = 500,
        learning_rate: float = 0.02,
        l2: float = 0.0,
        random_state: int | None = 0,
        warm_start: bool = False,
    ) -> None:
        self.n_hidden = n_hidden
        self.n_epochs = n_epochs
        self.learning_rate = learning_rate
        self.l2 = l2
        self.random_state = random_state
        self.warm_start = warm_start

    def fit(self, X: ArrayLike, y: ArrayLike) -> Self:
        """Train by back-propagation.

        Parameters
        ----------
        X : (n_samples, n_features) array_like
        y : (n_samples,) array_like

        Returns
        -------
        self
        """
        n_hidden = _require_int(self, "n_hidden", 1)
        n_epochs = _require_int(self, "n_epochs", 1)
        lr = _require_real(self, "learning_rate", 0.0, low_open=True)
        l2 = _require_real(self, "l2", 0.0)
        U, v, sc = self._standardised_fit_data(X, y, min_samples=1)
        n, f = U.shape

        if self.warm_start and getattr(self, "W1_", np.empty(0)).shape == (n_hidden, f):
            # continue in the previous fit's units; copies, so a copy of this model taken
            # before the fit keeps its own weights
            old = self._stored_scaling()
            U = U * sc.x_scale / old.x_scale + (sc.x_mean - old.x_mean) / old.x_scale
            v = v * sc.y_scale / old.y_scale + (sc.y_mean - old.y_mean) / old.y_scale
            sc = old
            params = [self.W1_.copy(), self.b1_.copy(), self.w2_.copy(), np.array([self.b2_])]
        else:
            rng = np.random.default_rng(self.random_state)
            lim1 = np.sqrt(6.0 / (f + n_hidden))
            lim2 = np.sqrt(6.0 / (n_hidden + 1))
            params = [
                rng.uniform(-lim1, lim1, (n_hidden, f)),
                np.zeros(n_hidden),
                rng.uniform(-lim2, lim2, n_hidden),
                np.zeros(1),
            ]
        m = [np.zeros_like(p) for p in params]
        s = [np.zeros_like(p) for p in params]
        beta1, beta2, eps = 0.9, 0.999, 1e-8
        losses = np.empty(n_epochs)
        for epoch in range(1, n_epochs + 1):
            W1, b1, w2, b2 = params
            H = _sigmoid(U @ W1.T + b1)
            e = H @ w2 + b2[0] - v
            losses[epoch - 1] = float(e @ e) / n
            # back-propagation of the MSE
            g_out = (2.0 / n) * e
            dH = np.outer(g_out, w2) * H * (1.0 - H)
            grads = [
                dH.T @ U + 2 * l2 * W1,
                dH.sum(0),
                H.T @ g_out + 2 * l2 * w2,
                np.array([g_out.sum()]),
            ]
            for p, g, mi, si in zip(params, grads, m, s, strict=True):
                mi *= beta1
                mi += (1 - beta1) * g
                si *= beta2
                si += (1 - beta2) * g * g
                m_hat = mi / (1 - beta1**epoch)
                s_hat = si / (1 - beta2**epoch)
                p -= lr * m_hat / (np.sqrt(s_hat) + eps)

        self._store_scaling(sc)
        self.W1_, self.b1_, self.w2_ = params[0], params[1], params[2]
        self.b2_ = float(params[3][0])
        self.loss_curve_ = losses
        self.n_iter_ = n_epochs
        return self

    def predict(self, X: ArrayLike) -> FloatArray:
        """Predict the target for every row of ``X``.

        Parameters
        ----------
        X : (n_samples, n_features_in_) array_like

        Returns
        -------
        (n_samples,) float64
        """
        U = self._standardised_input(X)
        H = _sigmoid(U @ self.W1_.T + self.b1_)
        return self._target_units(H @ self.w2_ + self.b2_)
