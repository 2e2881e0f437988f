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
at most ``max_samples`` pairs (the window thinned evenly). The slow trainers do bounded work
per refit and continue from the previous weights (warm start): the NARX MLP runs
``mlp_max_nfev`` Levenberg-Marquardt evaluations per refit, the BP network ``bp_epochs``
epochs, so training proceeds across refits instead of stalling one fix. Everything is
deterministic for a given input stream (no threads, no clocks). Fitting failures (singular
data the ridge cannot save, non-finite output) leave the component without a model; they
never raise. Inputs are clipped to their training range before prediction and outputs to the
drift seen in training.

The fallback gate
-----------------
A fitted network is only a *candidate*. Whether its correction is applied is decided by what
it would have done on data it never saw: every virtual outage, once over, is replayed through
the candidates that were in use when it *started* (the shadows give exactly that: the error
left after the correction against the INS left uncorrected, over the first
``gate_horizon_s``), and the first fix after each real outage scores the candidates' last
prediction against the drift GNSS then reveals (output corrections only). A component is on
only while, over its last ``gate_outages`` scored outages (at least ``gate_min_outages``),
the RMS error left is at most ``gate_margin`` times that of no correction (over the summed
squares *and* as the geometric mean of the per-outage ratios), it won in at least
``gate_min_wins`` of them, and it won the most recent one: it turns off at the first loss.
``gmdh-pseudo`` sends a pseudo-fix only while all four horizontal components are on.
:attr:`LearnedBridge.status` (:class:`fusion.bridge.BridgeStatus`) reports the state, the
gate's RMS errors and the fallback flags.

What it achieves (``bench/bridging.py``, held-out seeds and plans; ``bench/README.md``)
--------------------------------------------------------------------------------------
A negative result, stated plainly. Without the gate the learned corrections *increased* the
plain filter's 25 s outage RMSE (``gmdh`` 1.45x, worst single outage 9.5x; ``rbf`` 1.20x,
``mlp`` 1.38x, ``bp-parallel`` 1.43x, ``gmdh-pseudo`` 1.08x). With the gate every method
is 1.00x on 120 held-out 25 s outages with no outage worse than 1.2x (``bp-parallel`` worst
1.05x; it is the only method the gate let through noticeably: 5 outages changed, two gained,
0.86x and 0.55x, both in cruise); 60 s into the 60 s outage 0.98x (``bp-parallel``) to 1.00x.
The ``gmdh`` target (0.3x) is missed: the filter's drift in a real outage is set by its error
state at the outage's start, which a well-tuned closed-loop filter has already made
unpredictable from what it saw, and the drift of the shadows' virtual outages does not carry
over to real ones (on the tuning flights, the virtual outages said "win" far more often than
the real outages then confirmed). Keep ``none`` as the default.
"""

from __future__ import annotations

import bisect
import copy
import math
from collections import deque
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
from physconst import G0_MPS2

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
    "mlp": {"refit_period_s": 20.0},
    "bp-parallel": {"refit_period_s": 20.0, "max_samples": 1000},
}
"""Per-method changes to ``BridgeConfig()`` when :func:`make_bridge` gets no config: the slow
trainers (Levenberg-Marquardt, back-propagation) refit less often and on fewer pairs; each of
their refits is a bounded continuation of the previous one (``mlp_max_nfev``,
``bp_epochs``)."""


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
        v[0], v[1], v[2], f[0], f[1], f[2] + G0_MPS2,
    ]  # fmt: skip


# ---------------------------------------------------------------------------------- models
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


class _Stateless:
    """GMDH / RBF / BP: a plain regressor, one prediction per epoch."""

    def __init__(self, factory: Callable[[], Any]) -> None:
        self._factory = factory
        self._model: Any = None
        self._fast: Callable[[list[float]], float] | None = None

    def fit(
        self, X: FloatArray, y: FloatArray, groups: NDArray[np.int64],
        previous: ComponentModel | None,
    ) -> None:  # fmt: skip
        prev = previous._model if isinstance(previous, _Stateless) else None
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


class _Narx:
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
        prev = previous._model if isinstance(previous, _Narx) else None
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


class _Candidate:
    """A fitted component model with its input and output ranges: predictions are made on
    inputs clipped to the training range, then clipped to the targets seen and to the
    elapsed-time envelope of the training errors (a polynomial or network far from its data
    can return a correction of hundreds of metres 10 s into an outage; seen on a consumer
    MEMS, seed 100 of the P0 scenario)."""

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
            self.env_t_list, ENVELOPE_TIME_FACTOR * base[_T] + ENVELOPE_TIME_SLACK_S)
        env = self.env_list[i - 1] if i > 0 else 0.0
        return min(max(y, self.y_lo, -env), self.y_hi, env)

    def predict_rows(self, B: FloatArray, spec: Spec, groups: NDArray[np.int64]) -> FloatArray:
        """Same values as :meth:`predict_one` over rows of one outage each group (batch)."""
        X = np.clip(features_matrix(B, spec), self.lo, self.hi)
        with np.errstate(all="ignore"):
            y = self.model.predict_groups(X, groups)
        env = self._envelope(B[:, _T])
        out: FloatArray = np.clip(np.clip(y, self.y_lo, self.y_hi), -env, env)
        return out


Snapshot = tuple["_Candidate | None", ...]


def _log_ratio(left: float, uncorrected: float) -> float:
    """``log(left / uncorrected)`` of one scored outage (+inf when the correction added error
    to a zero one or is not finite, 0 when both are zero)."""
    if not math.isfinite(left):
        return math.inf
    if uncorrected <= 0.0:
        return 0.0 if left <= 0.0 else math.inf
    return math.log(max(left, 1e-300) / uncorrected)


class _Tracked:
    """A virtual outage under way: the candidates in use at its start, its longest elapsed."""

    __slots__ = ("elapsed", "snapshot")

    def __init__(self, snapshot: Snapshot) -> None:
        self.snapshot = snapshot
        self.elapsed = 0.0


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
    max_samples : int, optional
        Pairs per fit (default ``config.max_samples``).
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
        self._cand: list[_Candidate | None] = [None] * 6
        self._fallback = [True] * 6
        self._val_rmse = [math.nan] * 6
        self._zero_rmse = [math.nan] * 6
        # the gate's record per component: (mean square left, mean square uncorrected)
        self._scores: list[deque[tuple[float, float]]] = [
            deque(maxlen=config.gate_outages) for _ in range(6)
        ]
        # the last real outage is the judge that counts: virtual outages (shadow INS without
        # the filter's mag/baro aiding) can drift unlike real ones, so a component whose
        # prediction lost the last real outage stays off until it wins one again
        self._real_lost = [False] * 6
        self._real_scored = False
        self._judged: set[int] = set()  # virtual outages already scored (keys)
        self._judged_order: deque[int] = deque()
        self._tracked: dict[int, _Tracked] = {}
        self._outage_pred: list[float] | None = None  # candidates' last prediction, real outage
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
    def _push(self, key: int, t_fix_us: int, row: list[float], target: list[float]) -> bool:
        if not all(math.isfinite(x) for x in row) or not all(math.isfinite(x) for x in target):
            return False
        i = self._n % self._cap
        self._B[i] = row
        self._Y[i] = target
        self._key[i] = key
        self._tfix[i] = t_fix_us
        self._n += 1
        return True

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        """Score the last real outage (first fix after it), store the training pairs of one
        fix, judge finished virtual outages, refit one component when one is due."""
        self._now_us = epoch.time_us
        if self._origin is None:
            self._origin = _Origin(epoch)
            self._learn_from_us = epoch.time_us + self._warmup_us
        origin = self._origin
        if self._outage_pred is not None:
            self._score_real_outage(error)
        if not (error.pos_accepted and error.vel_accepted):
            self._refresh()
            return
        self._start = epoch
        if self._virtual:
            seen: set[int] = set()
            for v in error.virtual:
                if v.start.time_us < self._learn_from_us:
                    continue  # the filter was still converging when this shadow started
                key = v.start.time_us * 64 + v.shadow % 64
                if not self._push(
                    key, epoch.time_us, base_row(v.elapsed_s, v.start, v.epoch, origin),
                    [*v.pos_ned_m, *v.vel_ned_mps],
                ):  # fmt: skip
                    continue
                seen.add(key)
                tr = self._tracked.get(key)
                if tr is None:
                    if key in self._judged:
                        # scored already: a shadow runs on past the gate horizon, and tracking
                        # it again would score the same outage once per fix, with models that
                        # have trained on it
                        continue
                    # the models in use now have seen nothing of this outage
                    tr = self._tracked[key] = _Tracked(tuple(self._cand))
                tr.elapsed = max(tr.elapsed, v.elapsed_s)
            if seen:
                for key in list(self._tracked):
                    tr = self._tracked[key]
                    if key not in seen or tr.elapsed >= self.config.gate_horizon_s:
                        self._score_virtual_outage(key, self._tracked.pop(key))
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

    # -- the gate ---------------------------------------------------------------------------
    def _score_virtual_outage(self, key: int, tr: _Tracked) -> None:
        """Replay a finished virtual outage through the candidates of its start."""
        self._judged.add(key)
        self._judged_order.append(key)
        if len(self._judged_order) > 256:
            self._judged.discard(self._judged_order.popleft())
        if tr.elapsed < self.config.min_horizon_s or not any(tr.snapshot):
            return  # too short to say anything (or nothing was fitted at its start)
        m = min(self._n, self._cap)
        rows = np.flatnonzero(self._key[:m] == key)
        rows = rows[np.argsort(self._tfix[rows], kind="stable")]
        rows = rows[self._B[rows, _T] <= self.config.gate_horizon_s]
        if len(rows) < 2:
            return
        B = self._B[rows]
        groups = np.zeros(len(rows), dtype=np.int64)
        for k in self._components:
            cand = tr.snapshot[k]
            if cand is None:
                continue
            y = self._Y[rows, k]
            pred = cand.predict_rows(B, self._specs[k], groups)
            left = float(np.mean((y - pred) ** 2))
            self._scores[k].append((left if math.isfinite(left) else math.inf,
                                    float(np.mean(y * y))))  # fmt: skip
        self._judge()

    def _score_real_outage(self, error: InsError) -> None:
        """The first fix after a real outage measures the INS error at its end: what the
        candidates' last prediction would have left of it. Output corrections only (a
        pseudo-GNSS strategy has moved the INS, so the fix no longer sees the drift)."""
        pred, self._outage_pred = self._outage_pred, None
        # once per outage, at its first fix, whether or not the filter's gate took it: after a
        # long outage the gate may refuse good fixes for seconds (until its reset), and those
        # are exactly the outages where a bad correction must be caught
        if self._pseudo or pred is None or self._real_scored:
            return
        self._real_scored = True
        err = [*error.pos_ned_m, *error.vel_ned_mps]
        for k in self._components:
            if math.isfinite(pred[k]) and math.isfinite(err[k]):
                self._scores[k].append(((err[k] - pred[k]) ** 2, err[k] ** 2))
                self._real_lost[k] = (err[k] - pred[k]) ** 2 >= err[k] ** 2
        self._judge()

    def _judge(self) -> None:
        """Turn each component on or off from its record (``BridgeConfig.gate_*``)."""
        cfg = self.config
        for k in self._components:
            sc = self._scores[k]
            if sc:
                self._val_rmse[k] = math.sqrt(sum(s[0] for s in sc) / len(sc))
                self._zero_rmse[k] = math.sqrt(sum(s[1] for s in sc) / len(sc))
            on = False
            if self._cand[k] is not None and len(sc) >= cfg.gate_min_outages:
                left = sum(s[0] for s in sc)
                unc = sum(s[1] for s in sc)
                wins = sum(1 for s in sc if s[0] < s[1])
                # per outage too (geometric mean of the ratios): the sums alone are ruled by
                # the largest drifts, and a correction that wins the big outages can still
                # multiply the error of the small ones
                log_ratio = sum(_log_ratio(a, b) for a, b in sc) / len(sc)
                on = (
                    left <= cfg.gate_margin**2 * unc
                    and log_ratio <= 2.0 * math.log(cfg.gate_margin)
                    and wins >= cfg.gate_min_wins * len(sc)
                    and sc[-1][0] < sc[-1][1]
                    and not self._real_lost[k]
                )
            self._fallback[k] = not on

    # -- fitting -------------------------------------------------------------------------
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

    def _fit_component(self, k: int, idx: NDArray[np.intp]) -> None:
        """One bounded fit of component ``k`` on the window (thinned to the budget), warm
        started from its previous model where the regressor supports it. Whether its
        correction is applied is the gate's business (:meth:`_judge`)."""
        if len(idx) > self._budget:
            idx = idx[:: math.ceil(len(idx) / self._budget)]
        spec = self._specs[k]
        X = features_matrix(self._B[idx], spec)
        y = self._Y[idx, k]
        prev = self._cand[k]
        model = self._factory()
        try:
            with np.errstate(all="ignore"):
                model.fit(X, y, self._key[idx], None if prev is None else prev.model)
            cand: _Candidate | None = _Candidate(
                model, X.min(axis=0), X.max(axis=0), float(y.min()), float(y.max()), spec,
                self._B[idx, _T], y)
            # a fit that predicts garbage on its own training inputs is no candidate
            probe = model.predict_groups(X[:1], self._key[idx[:1]])
            if not np.all(np.isfinite(probe)):
                cand = None
        except (ValueError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
            cand = None
        self._refits += 1
        self._last_fit_samples = len(idx)
        self._last_fit_us = self._now_us
        self._fitted.add(k)
        self._cand[k] = cand
        self._judge()

    # -- outage ------------------------------------------------------------------------------
    def _predict(self, epoch: BridgeEpoch) -> list[float] | None:
        """Every candidate's prediction (NaN: no candidate), remembered for scoring the
        outage when GNSS returns; ``None`` before the first pair."""
        start, origin = self._start, self._origin
        if start is None or origin is None:
            return None
        base = base_row(epoch.time_since_gnss_s, start, epoch, origin)
        out = [math.nan] * 6
        for k in self._components:
            cand = self._cand[k]
            if cand is not None:
                # inputs clipped to the training range (no extrapolation past what was seen),
                # output to the drift seen in training
                out[k] = cand.predict_one(base)
        return out

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        """The predicted drift of the components the gate lets through, as an output
        correction (or a pseudo-fix); ``None`` while untrained or when the gate lets none
        through."""
        self._now_us = epoch.time_us
        pred = None if self._state == "untrained" else self._predict(epoch)
        self._outage_pred = pred
        use = [0.0] * 6
        on = False
        if pred is not None:
            for k in self._components:
                if not self._fallback[k] and math.isfinite(pred[k]):
                    use[k] = pred[k]
                    on = True
            if self._pseudo:
                # a pseudo-fix asserts the whole horizontal state: every horizontal component
                # must have earned it
                on = all(not self._fallback[k] and math.isfinite(pred[k]) for k in (0, 1, 3, 4))
        self._active = on
        self._refresh(count=False)
        if not on:
            return None
        if not self._pseudo:
            return OutputCorrection((use[0], use[1], use[2]), (use[3], use[4], use[5]))
        free = epoch.free_state
        lat, lon, alt = epoch.lat_rad, epoch.lon_rad, epoch.alt_msl_m
        v = epoch.v_ned_mps
        if free is not None:
            lat, lon, alt, v = free.lat_rad, free.lon_rad, free.alt_msl_m, free.v_ned_mps
        lt = earth.local_terms(lat, alt)
        cfg = self.config
        pos_err = [self._val_rmse[k] for k in (0, 1)]
        vel_err = [self._val_rmse[k] for k in (3, 4)]
        return PseudoGnss(
            lat - use[0] / lt.rho_n_m,
            lon - use[1] / (lt.rho_e_m * lt.cos_lat),
            alt + use[2],
            (v[0] - use[3], v[1] - use[4], v[2] - use[5]),
            max([cfg.pseudo_min_sigma_pos_m, *pos_err]),
            max([cfg.pseudo_min_sigma_vel_mps, *vel_err]),
        )

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        """End of the outage: forget the recurrent history, stop correcting."""
        self._now_us = epoch.time_us
        self._active = False
        self._real_scored = False
        for c in self._cand:
            if c is not None:
                c.model.reset()
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
