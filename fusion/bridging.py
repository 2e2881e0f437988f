"""GNSS-outage bridging strategies (papers P0-P3), one interface, selectable by name.

:func:`make_bridge` builds a strategy for :class:`fusion.filter.NavFilter` by name
(:data:`BRIDGE_METHODS`):

========================  =====================================================================
``none``                  plain filter (free-inertial coasting, :class:`fusion.bridge.NoBridge`)
``gmdh``                  P0: six GMDH networks, one per N/E/D position and velocity error
                          component; their prediction is subtracted from the filter's *output*
                          during an outage (the INS and the filter are left alone)
``gmdh-pseudo``           P3: the same networks give pseudo-GNSS position and velocity (the free
                          INS minus the predicted drift), fused by the filter's GNSS update
``mlp``                   P1: NARX MLP (35 tanh neurons, current and previous inputs plus its own
                          previous output, Levenberg-Marquardt), horizontal components only
``rbf``                   P0's comparator: 15 Gaussian neurons per component
``bp-parallel``           P2: one small sigmoid network per component; inputs the component
                          (since the outage start) and its rate
========================  =====================================================================

What the networks learn
-----------------------
With ``BridgeConfig.training = "virtual"`` (the default) the training pairs are *virtual
outages* (:class:`fusion.bridge.ShadowBank`): shadow strapdown INS copies re-seeded from the
filter every ``virtual_outage_s`` (staggered), whose error against each GNSS fix is the drift
of an INS left alone for ``elapsed`` seconds. In a real outage the same inputs, with the time
since the last fused fix, give the predicted drift. ``training = "fix"`` uses paper P0's
pairs instead — the filter's INS-minus-GNSS error at each fix — which in a closed-loop filter
is only the drift over one GNSS interval; it is kept so the comparison with P0 is honest
(``bench/bridging.py`` measures both).

Inputs (``BridgeConfig.features``; a pair is (elapsed ``t``, the INS features at the outage's
start, the INS features now)):

``t``, ``t2``, ``t3``
    time since the (virtual) outage start and its powers, s, s^2, s^3;
``fn``, ``fe``, ``fd``
    specific force in NED, m/s^2; ``sinpsi``, ``cospsi``: heading now; ``sinpsi0``,
    ``cospsi0``: heading at the start; ``roll``, ``pitch``, rad;
``vn``, ``ve``, ``vd``
    velocity, m/s; ``wx``, ``wy``, ``wz``: body rate, rad/s;
``dn``, ``de``, ``dvn``, ``dve``
    horizontal displacement (m) and velocity change (m/s) since the start;
``bax`` … ``bgz``
    the filter's accelerometer (m/s^2) and gyro (rad/s) bias estimates;
``own``, ``own_rel``, ``own_rate``
    the corrected component's own INS value (P0's input: position N/E/D from a fixed origin,
    or velocity), the same relative to the start, and its rate (velocity for a position
    component, specific force plus gravity for a velocity component; P2's epoch-to-epoch
    difference per second).

Training inside the fusion loop
-------------------------------
Pairs go into a sliding window (``window_s``, capped ring buffer). A component's network is
refitted every ``refit_period_s``; the components take turns (one fit per
``refit_period_s / n`` of GNSS time), so no fix pays for more than one fit, and each fit sees
at most ``max_samples`` pairs (the window thinned evenly). Everything is deterministic for a
given input stream (no threads, no clocks). Each fit is judged on held-out virtual outages
(every fourth outage of the window, ``validation_fraction``): a component whose validation
RMSE is not below the RMS of its target — the error of predicting zero correction — falls
back to ``none``. Fitting failures (singular data the ridge cannot save, non-finite output)
keep the component in fallback; they never raise. Inputs are clipped to their training range
before prediction, so a polynomial never extrapolates past the longest virtual outage seen.
:attr:`LearnedBridge.status` (:class:`fusion.bridge.BridgeStatus`) reports the state.

What it achieves (``bench/bridging.py``, held-out seeds and plans; ``bench/README.md``)
--------------------------------------------------------------------------------------
A negative result, stated plainly: on 120 held-out 25 s outages the learned corrections
*increase* the plain filter's horizontal RMSE (``gmdh`` 1.45x the summed RMSE, worst single
outage 9.5x; ``gmdh-pseudo`` 1.08x; ``rbf`` 1.20x, ``mlp`` 1.38x, ``bp-parallel`` 1.43x) and do
not help 60 s into a 60 s outage (``gmdh`` 1.12x). P0's own pairs (``training="fix"``) learn
about zero and change nothing (1.00x), as the closed loop predicts. The filter's drift in a
real outage is set by its error state at the outage's start, which a well-tuned filter has
already made unpredictable from what it has seen; the drift of past virtual outages does not
carry over. Keep ``none`` as the default; the strategies are here to measure that claim.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.bridge import (
    COMPONENTS,
    Bridge,
    BridgeAction,
    BridgeEpoch,
    BridgeStatus,
    InsError,
    NoBridge,
    OutputCorrection,
    PseudoGnss,
)
from fusion.config import BRIDGE_FEATURES, BridgeConfig
from fusion.gmdh import GmdhRegressor
from fusion.regressors import BpNet, NarxMLP, RbfNet

FloatArray = NDArray[np.float64]

BRIDGE_METHODS: tuple[str, ...] = ("none", "gmdh", "gmdh-pseudo", "mlp", "rbf", "bp-parallel")
"""Names accepted by :func:`make_bridge`."""

GMDH_FEATURES: tuple[str, ...] = ("t", "t2", "sinpsi", "cospsi")
"""Default inputs of the GMDH, RBF and MLP networks: time into the outage, its square and the
heading. Chosen with ``python bench/bridging.py --tune`` (seeds 1-5 of racetrack and survey,
17 feature sets and settings): the best 25 s outage RMSE (1.01x the plain filter's) with
0.85x at 60 s; P0's own input alone (``own``) gave 1.51x and 0.94x (``bench/README.md``)."""
P0_FEATURES: tuple[str, ...] = ("own",)
"""Paper P0's inputs: the component's own INS value."""
MLP_FEATURES: tuple[str, ...] = GMDH_FEATURES
"""P1's NARX MLP inputs: the same as GMDH's (azimuth and time; P1's NARX structure — current
and previous inputs plus its own previous output — is kept). Few inputs on purpose:
Levenberg-Marquardt costs O(samples x weights^2)."""
BP_FEATURES: tuple[str, ...] = ("own_rel", "own_rate")
"""P2's inputs: the component and its epoch-to-epoch difference (per second)."""

DEFAULT_FEATURES: dict[str, tuple[str, ...]] = {
    "gmdh": GMDH_FEATURES,
    "gmdh-pseudo": GMDH_FEATURES,
    "rbf": GMDH_FEATURES,
    "mlp": MLP_FEATURES,
    "bp-parallel": BP_FEATURES,
}

METHOD_DEFAULTS: dict[str, dict[str, Any]] = {
    "mlp": {"refit_period_s": 60.0},
    "bp-parallel": {"refit_period_s": 30.0, "max_samples": 1000},
}
"""Per-method changes to ``BridgeConfig()`` when :func:`make_bridge` gets no config: the slow
trainers (Levenberg-Marquardt, back-propagation) refit less often and on fewer pairs."""

_G = 9.80665

# ------------------------------------------------------------------------------ base row layout
# Every training pair and prediction epoch is first reduced to one row of these quantities;
# features are columns of it (or sin / cos / powers of a column).
(_T, _FN, _FE, _FD, _PSI, _PSI0, _ROLL, _PITCH, _VN, _VE, _VD, _WX, _WY, _WZ,
 _DN, _DE, _DVN, _DVE) = range(18)  # fmt: skip
_BA = 18
_BG = 21
_OWN = 24  # 6 columns: position N/E/D from the origin, velocity N/E/D
_OWN_REL = 30  # 6: position change N/E/D since the start, velocity change
_OWN_RATE = 36  # 6: velocity N/E/D, specific force + gravity N/E/D
_NB = 42

_SIMPLE: dict[str, tuple[str, int]] = {
    "t": ("id", _T), "t2": ("sq", _T), "t3": ("cube", _T),
    "fn": ("id", _FN), "fe": ("id", _FE), "fd": ("id", _FD),
    "sinpsi": ("sin", _PSI), "cospsi": ("cos", _PSI),
    "sinpsi0": ("sin", _PSI0), "cospsi0": ("cos", _PSI0),
    "roll": ("id", _ROLL), "pitch": ("id", _PITCH),
    "vn": ("id", _VN), "ve": ("id", _VE), "vd": ("id", _VD),
    "wx": ("id", _WX), "wy": ("id", _WY), "wz": ("id", _WZ),
    "dn": ("id", _DN), "de": ("id", _DE), "dvn": ("id", _DVN), "dve": ("id", _DVE),
    "bax": ("id", _BA), "bay": ("id", _BA + 1), "baz": ("id", _BA + 2),
    "bgx": ("id", _BG), "bgy": ("id", _BG + 1), "bgz": ("id", _BG + 2),
}  # fmt: skip
_PER_COMPONENT = {"own": _OWN, "own_rel": _OWN_REL, "own_rate": _OWN_RATE}
assert set(_SIMPLE) | set(_PER_COMPONENT) == set(BRIDGE_FEATURES)

Spec = tuple[tuple[str, int], ...]


def feature_spec(names: tuple[str, ...], component: int) -> Spec:
    """``(operation, base column)`` per feature for one component (0..5, :data:`COMPONENTS`).

    Raises
    ------
    ValueError
        For a name not in :data:`fusion.config.BRIDGE_FEATURES` or a bad component.
    """
    if not 0 <= component < 6:
        raise ValueError(f"component must be 0..5, got {component}")
    out: list[tuple[str, int]] = []
    for n in names:
        if n in _SIMPLE:
            out.append(_SIMPLE[n])
        elif n in _PER_COMPONENT:
            out.append(("id", _PER_COMPONENT[n] + component))
        else:
            raise ValueError(f"unknown feature {n!r}; valid: {', '.join(BRIDGE_FEATURES)}")
    return tuple(out)


def features_row(base: list[float], spec: Spec) -> list[float]:
    """Features of one base row (plain floats: the prediction path runs per outage epoch)."""
    out = []
    for op, col in spec:
        x = base[col]
        if op == "id":
            out.append(x)
        elif op == "sin":
            out.append(math.sin(x))
        elif op == "cos":
            out.append(math.cos(x))
        elif op == "sq":
            out.append(x * x)
        else:
            out.append(x * x * x)
    return out


def compile_features(
    spec: Spec, lo: list[float], hi: list[float]
) -> Callable[[list[float]], list[float]]:
    """:func:`features_row` followed by clipping to ``[lo, hi]``, as one straight-line Python
    function (the prediction path runs at the bridge rate; a generic loop costs ~10x more).

    Only numbers computed by a fit (exact ``repr``) and the fixed operations are written into
    the source.
    """
    exprs = []
    for (op, col), a, b in zip(spec, lo, hi, strict=True):
        x = f"b[{int(col)}]"
        val = {"id": x, "sin": f"_sin({x})", "cos": f"_cos({x})", "sq": f"{x} * {x}",
               "cube": f"{x} * {x} * {x}"}[op]
        exprs.append(f"_min(_max({val}, {float(a)!r}), {float(b)!r})")
    src = "def features(b):\n    return [" + ", ".join(exprs) + "]\n"
    namespace: dict[str, Any] = {"_sin": math.sin, "_cos": math.cos, "_min": min, "_max": max}
    exec(compile(src, "<bridging features>", "exec"), namespace)
    fn: Callable[[list[float]], list[float]] = namespace["features"]
    return fn


def features_matrix(B: FloatArray, spec: Spec) -> FloatArray:
    """Features of many base rows ``B`` (n, 42) -> (n, len(spec)); same values as
    :func:`features_row` row by row."""
    cols = []
    for op, col in spec:
        x = B[:, col]
        if op == "id":
            cols.append(x)
        elif op == "sin":
            cols.append(np.sin(x))
        elif op == "cos":
            cols.append(np.cos(x))
        elif op == "sq":
            cols.append(x * x)
        else:
            cols.append(x * x * x)
    return np.column_stack(cols)


class _Origin:
    """Local tangent origin for the ``own`` features (the first epoch a strategy sees)."""

    __slots__ = ("alt", "ke", "kn", "lat", "lon")

    def __init__(self, epoch: BridgeEpoch) -> None:
        lt = earth.local_terms(epoch.lat_rad, epoch.alt_msl_m)
        self.lat, self.lon, self.alt = epoch.lat_rad, epoch.lon_rad, epoch.alt_msl_m
        self.kn, self.ke = lt.rho_n_m, lt.rho_e_m * lt.cos_lat


def base_row(t: float, start: BridgeEpoch, ep: BridgeEpoch, origin: _Origin) -> list[float]:
    """The 42 base quantities of one pair (see the module docstring for the features)."""
    kn, ke = origin.kn, origin.ke
    v, v0, f = ep.v_ned_mps, start.v_ned_mps, ep.f_n_mps2
    dn = (ep.lat_rad - start.lat_rad) * kn
    de = (ep.lon_rad - start.lon_rad) * ke
    dd = start.alt_msl_m - ep.alt_msl_m
    roll, pitch, yaw = ep.euler_rad
    w, ba, bg = ep.omega_ib_b_rps, ep.accel_bias_b, ep.gyro_bias_b
    return [
        t, f[0], f[1], f[2], yaw, start.euler_rad[2], roll, pitch,
        v[0], v[1], v[2], w[0], w[1], w[2],
        dn, de, v[0] - v0[0], v[1] - v0[1],
        ba[0], ba[1], ba[2], bg[0], bg[1], bg[2],
        (ep.lat_rad - origin.lat) * kn, (ep.lon_rad - origin.lon) * ke,
        origin.alt - ep.alt_msl_m, v[0], v[1], v[2],
        dn, de, dd, v[0] - v0[0], v[1] - v0[1], v[2] - v0[2],
        v[0], v[1], v[2], f[0], f[1], f[2] + _G,
    ]  # fmt: skip


# ---------------------------------------------------------------------------------- models
class ComponentModel(Protocol):
    """One component's regressor behind a uniform face (fit, batch validation, one step)."""

    def fit(self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64]) -> None: ...

    def predict_groups(self, X: FloatArray, groups: NDArray[np.int64]) -> FloatArray: ...

    def reset(self) -> None: ...

    def predict_one(self, x: list[float]) -> float: ...


class _Stateless:
    """GMDH / RBF / BP: a plain regressor, one prediction per epoch."""

    def __init__(self, factory: Callable[[], Any]) -> None:
        self._factory = factory
        self._model: Any = None
        self._fast: Callable[[list[float]], float] | None = None

    def fit(self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64]) -> None:
        model = self._factory().fit(X, y)
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


class _Narx:
    """P1's NARX MLP: previous inputs and its own previous output (closed loop in an outage,
    started from zero correction)."""

    def __init__(self, factory: Callable[[], NarxMLP]) -> None:
        self._factory = factory
        self._model: NarxMLP | None = None
        self.reset()

    def fit(self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64]) -> None:
        # one series: the outages one after the other (a boundary row's history belongs to the
        # previous outage: ~1 row in 400)
        self._model = self._factory().fit(X, y)

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


# ---------------------------------------------------------------------------------- strategy
class LearnedBridge:
    """A learned bridging strategy (the methods other than ``none``; see module docstring).

    Parameters
    ----------
    name : str
        Method name (reported in the status).
    config : BridgeConfig
    model_factory : callable ``() -> ComponentModel``
        A fresh, unfitted model for one component.
    features : tuple of str
        Input names (:data:`fusion.config.BRIDGE_FEATURES`).
    components : tuple of int
        Indices into :data:`fusion.bridge.COMPONENTS` that get a network; the others are never
        corrected.
    pseudo_gnss : bool
        Return :class:`~fusion.bridge.PseudoGnss` (P3) instead of an
        :class:`~fusion.bridge.OutputCorrection`.
    """

    def __init__(
        self,
        name: str,
        config: BridgeConfig,
        model_factory: Callable[[], ComponentModel],
        features: tuple[str, ...],
        components: tuple[int, ...] = (0, 1, 2, 3, 4, 5),
        *,
        pseudo_gnss: bool = False,
        max_samples: int | None = None,
    ) -> None:
        self._name = name
        self.config = config
        self.features = features
        self._virtual = config.training == "virtual"
        self._components = tuple(sorted(set(components)))
        self._specs = [feature_spec(features, k) for k in range(6)]
        self._factory = model_factory
        self._pseudo = pseudo_gnss
        self._budget = int(max_samples if max_samples is not None else config.max_samples)
        count = config.virtual_outage_count if self._virtual else 1
        # capacity for GNSS up to 10 Hz over the window (older pairs are overwritten first)
        self._cap = int(config.window_s * 10.0 * count * 1.25) + 256
        self._B = np.zeros((self._cap, _NB))
        self._Y = np.zeros((self._cap, 6))
        self._key = np.zeros(self._cap, dtype=np.int64)
        self._tfix = np.zeros(self._cap, dtype=np.int64)
        self._n = 0  # pairs written so far (ring index = n % cap)
        self._window_us = round(config.window_s * 1e6)
        self._fit_every_us = round(config.refit_period_s * 1e6 / max(1, len(self._components)))
        self._stale_us = round(config.stale_after_s * 1e6)
        self._origin: _Origin | None = None
        self._warmup_us = round(config.warmup_s * 1e6)
        self._learn_from_us = 0
        self._start: BridgeEpoch | None = None
        self._now_us = 0
        self._models: list[ComponentModel | None] = [None] * 6
        self._feat: list[Callable[[list[float]], list[float]] | None] = [None] * 6
        self._yrange: list[tuple[float, float]] = [(0.0, 0.0)] * 6
        self._fallback = [True] * 6
        self._val_rmse = [math.nan] * 6
        self._zero_rmse = [math.nan] * 6
        self._fitted: set[int] = set()
        self._rr = 0
        self._next_fit_us: int | None = None
        self._last_fit_us: int | None = None
        self._refits = 0
        self._last_fit_samples = 0
        self._horizon_s = 0.0
        self._active = False
        self._status = BridgeStatus(name, "untrained")
        self._in_window = 0
        self._state = "untrained"

    # -- LearningBridge protocol --------------------------------------------------------------
    @property
    def name(self) -> str:
        """Method name."""
        return self._name

    @property
    def virtual_outage_s(self) -> float:
        """Virtual-outage length asked of the filter (0 with ``training="fix"``)."""
        return self.config.virtual_outage_s if self._virtual else 0.0

    @property
    def virtual_outage_count(self) -> int:
        """Number of staggered shadow INS copies asked of the filter."""
        return self.config.virtual_outage_count if self._virtual else 0

    @property
    def status(self) -> BridgeStatus:
        """Current :class:`~fusion.bridge.BridgeStatus` (rebuilt at each hook call)."""
        return self._status

    # -- training ------------------------------------------------------------------------
    def _push(self, key: int, t_fix_us: int, row: list[float], target: list[float]) -> None:
        if not all(math.isfinite(x) for x in row) or not all(math.isfinite(x) for x in target):
            return
        i = self._n % self._cap
        self._B[i] = row
        self._Y[i] = target
        self._key[i] = key
        self._tfix[i] = t_fix_us
        self._n += 1

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        """Store the training pairs of one fix; refit one component when one is due."""
        self._now_us = epoch.time_us
        if self._origin is None:
            self._origin = _Origin(epoch)
            self._learn_from_us = epoch.time_us + self._warmup_us
        origin = self._origin
        if not (error.pos_accepted and error.vel_accepted):
            self._refresh()
            return
        self._start = epoch
        if self._virtual:
            for v in error.virtual:
                if v.start.time_us < self._learn_from_us:
                    continue  # the filter was still converging when this shadow started
                self._push(
                    v.start.time_us * 64 + v.shadow % 64,
                    epoch.time_us,
                    base_row(v.elapsed_s, v.start, v.epoch, origin),
                    [*v.pos_ned_m, *v.vel_ned_mps],
                )
        else:
            # P0: the filter's own innovation at the fix, features of the INS at the fix
            if epoch.time_us < self._learn_from_us:
                self._maybe_fit()
                self._refresh()
                return
            self._push(
                0, epoch.time_us,
                base_row(epoch.time_since_gnss_s, epoch, epoch, origin),
                [*error.pos_ned_m, *error.vel_ned_mps],
            )  # fmt: skip
        self._maybe_fit()
        self._refresh()

    def _window(self) -> NDArray[np.intp]:
        """Indices of the pairs inside the sliding window, sorted by outage then time."""
        m = min(self._n, self._cap)
        idx = np.arange(m)
        idx = idx[self._tfix[:m] >= self._now_us - self._window_us]
        order = np.lexsort((self._tfix[idx], self._key[idx]))
        out: NDArray[np.intp] = idx[order]
        return out

    def _maybe_fit(self) -> None:
        now = self._now_us
        if self._next_fit_us is not None and now < self._next_fit_us:
            return
        idx = self._window()
        if len(idx) < self.config.min_samples:
            return
        horizon = float(self._B[idx, _T].max())
        if self._virtual and horizon < self.config.min_horizon_s:
            return
        self._horizon_s = horizon
        k = self._components[self._rr % len(self._components)]
        self._rr += 1
        self._fit_component(k, idx)
        # the first round fits a component per fix; afterwards they take turns over the period
        first_round = len(self._fitted) < len(self._components) and self._rr < 2 * len(
            self._components
        )
        self._next_fit_us = now if first_round else now + self._fit_every_us

    def _split(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Training and validation indices, validation *after* training in time: the most
        recent virtual outages that reached ``min_horizon_s`` (newest first, until they hold
        ``validation_fraction`` of the pairs), or the most recent pairs of one series."""
        n_val = max(1, round(self.config.validation_fraction * len(idx)))
        val = np.zeros(len(idx), dtype=bool)
        keys = self._key[idx]
        uniq = np.unique(keys)
        if self._virtual and len(uniq) >= 2:
            t = self._B[idx, _T]
            taken = 0
            for j in range(len(uniq) - 1, -1, -1):  # keys grow with the seed time
                m = keys == uniq[j]
                if float(t[m].max()) < self.config.min_horizon_s:
                    continue  # still young: its long-horizon part is not known yet
                val |= m
                taken += int(m.sum())
                if taken >= n_val:
                    break
            if taken and taken < len(idx):
                return idx[~val], idx[val]
            val[:] = False
        # one series (P0 pairs, or too few outages yet): hold out its most recent part
        tf = self._tfix[idx]
        val[np.argsort(tf, kind="stable")[len(idx) - n_val :]] = True
        return idx[~val], idx[val]

    def _thin(self, rows: NDArray[np.intp]) -> NDArray[np.intp]:
        if len(rows) > self._budget:
            rows = rows[:: math.ceil(len(rows) / self._budget)]
        return rows

    def _fit_rows(
        self, k: int, rows: NDArray[np.intp]
    ) -> tuple[ComponentModel, list[float], list[float], tuple[float, float]]:
        """Fit component ``k`` on ``rows``; returns the model, the input range and the target
        range (predictions are clipped to both)."""
        X = features_matrix(self._B[rows], self._specs[k])
        y = self._Y[rows, k]
        model = self._factory()
        with np.errstate(all="ignore"):
            model.fit(X, y, self._key[rows])
        return model, X.min(axis=0).tolist(), X.max(axis=0).tolist(), (
            float(y.min()), float(y.max()))  # fmt: skip

    def _fit_component(self, k: int, idx: NDArray[np.intp]) -> None:
        """Fit on the older part, judge on the newer (:meth:`_split`); if it beats a zero
        correction, refit on the whole window for use, else fall back."""
        train, val = self._split(idx)
        train = self._thin(train)
        spec = self._specs[k]
        Xv = features_matrix(self._B[val], spec)
        yv = self._Y[val, k]
        try:
            model, lo, hi, _ = self._fit_rows(k, train)
            with np.errstate(all="ignore"):
                pred = model.predict_groups(np.clip(Xv, lo, hi), self._key[val])
            err = float(np.sqrt(np.mean((pred - yv) ** 2)))
        except (ValueError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
            err = math.nan
        zero = float(np.sqrt(np.mean(yv * yv))) if len(yv) else math.nan
        self._refits += 1
        self._last_fit_samples = len(train)
        self._last_fit_us = self._now_us
        self._fitted.add(k)
        self._val_rmse[k] = err
        self._zero_rmse[k] = zero
        self._models[k] = None
        self._fallback[k] = True
        if not (math.isfinite(err) and err < self.config.validation_margin * zero):
            return
        try:
            model, lo, hi, yr = self._fit_rows(k, self._thin(idx))
        except (ValueError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
            return
        self._models[k] = model
        self._feat[k] = compile_features(spec, lo, hi)
        self._yrange[k] = yr
        self._fallback[k] = False

    # -- outage ------------------------------------------------------------------------------
    def _predict(self, epoch: BridgeEpoch) -> list[float] | None:
        start, origin = self._start, self._origin
        if start is None or origin is None:
            return None
        base = base_row(epoch.time_since_gnss_s, start, epoch, origin)
        out = [0.0] * 6
        any_active = False
        for k in self._components:
            model = self._models[k]
            feat = self._feat[k]
            if model is None or self._fallback[k] or feat is None:
                continue
            # inputs clipped to the training range: no extrapolation past what was seen
            y = model.predict_one(feat(base))
            if math.isfinite(y):
                # never beyond the drift seen in training (GMDH pairs of clipped inputs can
                # still combine into values no training pair had)
                y_lo, y_hi = self._yrange[k]
                out[k] = min(max(y, y_lo), y_hi)
                any_active = True
        return out if any_active else None

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        """The predicted drift as an output correction (or a pseudo-fix); ``None`` while
        untrained or when every component falls back."""
        self._now_us = epoch.time_us
        pred = None if self._state == "untrained" else self._predict(epoch)
        self._active = pred is not None
        self._refresh(count=False)
        if pred is None:
            return None
        if not self._pseudo:
            return OutputCorrection((pred[0], pred[1], pred[2]), (pred[3], pred[4], pred[5]))
        free = epoch.free_state
        lat, lon, alt = epoch.lat_rad, epoch.lon_rad, epoch.alt_msl_m
        v = epoch.v_ned_mps
        if free is not None:
            lat, lon, alt, v = free.lat_rad, free.lon_rad, free.alt_msl_m, free.v_ned_mps
        lt = earth.local_terms(lat, alt)
        cfg = self.config
        pos_err = [self._val_rmse[k] for k in (0, 1) if not self._fallback[k]]
        vel_err = [self._val_rmse[k] for k in (3, 4) if not self._fallback[k]]
        return PseudoGnss(
            lat - pred[0] / lt.rho_n_m,
            lon - pred[1] / (lt.rho_e_m * lt.cos_lat),
            alt + pred[2],
            (v[0] - pred[3], v[1] - pred[4], v[2] - pred[5]),
            max([cfg.pseudo_min_sigma_pos_m, *pos_err]),
            max([cfg.pseudo_min_sigma_vel_mps, *vel_err]),
        )

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        """End of the outage: forget the recurrent history, stop correcting."""
        self._now_us = epoch.time_us
        self._active = False
        for m in self._models:
            if m is not None:
                m.reset()
        self._refresh()

    # -- status --------------------------------------------------------------------------
    def _refresh(self, count: bool = True) -> None:
        """Rebuild :attr:`status` (``count``: recount the pairs in the window first; skipped in
        an outage, where the window does not change)."""
        n_fit = len(self._fitted)
        if n_fit == 0:
            state = "untrained"
        elif n_fit < len(self._components):
            state = "training"
        elif self._last_fit_us is not None and self._now_us - self._last_fit_us > self._stale_us:
            state = "stale"
        else:
            state = "trained"
        if not count and state == self._state and self._active == self._status.active:
            return
        self._state = state
        if count:
            m = min(self._n, self._cap)
            self._in_window = int(
                np.count_nonzero(self._tfix[:m] >= self._now_us - self._window_us)
            )
        f, v, z = self._fallback, self._val_rmse, self._zero_rmse
        self._status = BridgeStatus(
            self._name, state, self._in_window, self._refits,
            (v[0], v[1], v[2], v[3], v[4], v[5]), (z[0], z[1], z[2], z[3], z[4], z[5]),
            (f[0], f[1], f[2], f[3], f[4], f[5]), self._last_fit_samples, self._horizon_s,
            self._active,
        )  # fmt: skip


# ---------------------------------------------------------------------------------- factory
def make_bridge(name: str, config: BridgeConfig | None = None) -> Bridge:
    """Build the bridging strategy ``name`` (one of :data:`BRIDGE_METHODS`).

    Parameters
    ----------
    name : str
        ``none``, ``gmdh``, ``gmdh-pseudo``, ``mlp``, ``rbf`` or ``bp-parallel``.
    config : BridgeConfig, optional
        Training and model settings. Fields not set explicitly take the method's
        :data:`METHOD_DEFAULTS`, then ``BridgeConfig``'s defaults; ``features=None`` picks
        the method's default inputs (:data:`DEFAULT_FEATURES`).

    Returns
    -------
    Bridge
        A fresh strategy (give each :class:`~fusion.filter.NavFilter` its own).

    Raises
    ------
    ValueError
        For an unknown name (the message lists the methods).
    """
    if name not in BRIDGE_METHODS:
        raise ValueError(
            f"unknown bridging method {name!r}; valid methods: {', '.join(BRIDGE_METHODS)}"
        )
    if name == "none":
        return NoBridge()
    # the method's defaults fill in whatever the caller did not set explicitly
    given = {} if config is None else config.model_dump(include=config.model_fields_set)
    cfg = BridgeConfig(**{**METHOD_DEFAULTS.get(name, {}), **given})
    features = cfg.features if cfg.features is not None else DEFAULT_FEATURES[name]
    factory: Callable[[], ComponentModel]
    components: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    budget = None
    if name in ("gmdh", "gmdh-pseudo"):

        def factory() -> ComponentModel:
            return _Stateless(lambda: GmdhRegressor(
                max_layers=cfg.gmdh_max_layers, max_neurons=cfg.gmdh_max_neurons,
                alpha=cfg.gmdh_alpha, split="tail", ridge=1e-6))  # fmt: skip

    elif name == "rbf":

        def factory() -> ComponentModel:
            return _Stateless(lambda: RbfNet(n_centers=cfg.rbf_centers))

    elif name == "bp-parallel":

        def factory() -> ComponentModel:
            return _Stateless(lambda: BpNet(n_hidden=cfg.bp_hidden, n_epochs=cfg.bp_epochs))

    else:  # mlp: P1 works on the horizontal motion only

        def factory() -> ComponentModel:
            return _Narx(lambda: NarxMLP(
                n_hidden=cfg.mlp_hidden, n_input_lags=1, n_output_lags=1,
                max_nfev=cfg.mlp_max_nfev))  # fmt: skip

        components = (0, 1, 3, 4)
        budget = cfg.mlp_max_samples
    return LearnedBridge(
        name, cfg, factory, features, components,
        pseudo_gnss=name == "gmdh-pseudo", max_samples=budget,
    )  # fmt: skip


__all__ = [
    "BRIDGE_METHODS",
    "COMPONENTS",
    "DEFAULT_FEATURES",
    "LearnedBridge",
    "make_bridge",
]
