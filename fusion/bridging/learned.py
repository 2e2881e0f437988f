"""Learned bridging strategies: networks that learn the INS drift while GNSS is good and
correct it during an outage (papers P0-P3).

What the networks learn
-----------------------
With ``BridgeConfig.training = "virtual"`` (the default) the training pairs are *virtual
outages* (:mod:`fusion.bridging.virtual_outages`): strapdown INS copies re-seeded from the
filter every ``virtual_outage_s`` (staggered), whose error against each GNSS fix is the drift
of an INS left alone for ``elapsed`` seconds. In a real outage the same inputs
(:mod:`fusion.bridging.features`), with the time since the last fused fix, give the predicted
drift. ``training = "fix"`` uses paper P0's pairs instead — the filter's INS-minus-GNSS error
at each fix — which in a closed-loop filter is only the drift over one GNSS interval; it is
kept so the comparison with P0 is honest.

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
drift seen in training (:class:`fusion.bridging.models.Candidate`).

Whether a fitted network's correction is applied is decided by the fallback gate
(:mod:`fusion.bridging.gate`); ``gmdh-pseudo`` sends a pseudo-fix only while all four
horizontal components are on. :attr:`LearnedBridge.status`
(:class:`fusion.bridging.interface.BridgeStatus`) reports the state, the gate's RMS errors and
the fallback flags.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.airspeed_model import OnlineAirspeedModel
from fusion.bridging.features import (
    BASE_COLUMNS,
    COL_T,
    Origin,
    base_row,
    feature_spec,
    features_matrix,
)
from fusion.bridging.gate import FallbackGate
from fusion.bridging.interface import (
    BridgeAction,
    BridgeEpoch,
    BridgeStatus,
    InsError,
    OutputCorrection,
    PseudoGnss,
)
from fusion.bridging.models import Candidate, ComponentModel
from fusion.config import BridgeConfig
from fusion.pitot_model import OnlinePitotErrorModel
from fusion.wind_model import OnlineWindModel

if TYPE_CHECKING:  # the model imports the bridging gate, which imports this module
    from fusion.thermal.bias_model import ThermalBiasModel

FloatArray = NDArray[np.float64]


class LearnedBridge:
    """A learned bridging strategy (the methods other than ``none``; see the module docstring).

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
        Indices into :data:`fusion.bridging.interface.COMPONENTS` that get a network; the
        others are never corrected.
    pseudo_gnss : bool
        Return :class:`~fusion.bridging.interface.PseudoGnss` (P3) instead of an
        :class:`~fusion.bridging.interface.OutputCorrection`.
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
        self._B = np.zeros((self._cap, BASE_COLUMNS))
        self._Y = np.zeros((self._cap, 6))
        self._key = np.zeros(self._cap, dtype=np.int64)
        self._tfix = np.zeros(self._cap, dtype=np.int64)
        self._n = 0  # pairs written so far (ring index = n % cap)
        self._window_us = round(config.window_s * 1e6)
        self._fit_every_us = round(config.refit_period_s * 1e6 / max(1, len(self._components)))
        self._stale_us = round(config.stale_after_s * 1e6)
        self._origin: Origin | None = None
        self._warmup_us = round(config.warmup_s * 1e6)
        self._learn_from_us = 0
        self._start: BridgeEpoch | None = None
        self._now_us = 0
        self._cand: list[Candidate | None] = [None] * 6
        self._gate = FallbackGate(config, self._components)
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

    # -- Bridge protocol -----------------------------------------------------------------------
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
        """Number of staggered virtual-outage INS copies asked of the filter."""
        return self.config.virtual_outage_count if self._virtual else 0

    airspeed_model: OnlineAirspeedModel | None = None
    wind_model: OnlineWindModel | None = None
    pitot_model: OnlinePitotErrorModel | None = None
    thermal_model: ThermalBiasModel | None = None
    """These strategies correct position and velocity, not the air data."""

    @property
    def status(self) -> BridgeStatus:
        """Current :class:`~fusion.bridging.interface.BridgeStatus` (rebuilt at each hook
        call)."""
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
            self._origin = Origin(epoch)
            self._learn_from_us = epoch.time_us + self._warmup_us
        origin = self._origin
        if self._outage_pred is not None:
            pred, self._outage_pred = self._outage_pred, None
            if not self._pseudo:
                self._gate.score_real(pred, error, self._cand)
        if not (error.pos_accepted and error.vel_accepted):
            self._refresh()
            return
        self._start = epoch
        if self._virtual:
            seen: set[int] = set()
            for v in error.virtual:
                if v.start.time_us < self._learn_from_us:
                    continue  # the filter was still converging when this copy started
                key = v.start.time_us * 64 + v.index % 64
                if not self._push(
                    key, epoch.time_us, base_row(v.elapsed_s, v.start, v.epoch, origin),
                    [*v.pos_ned_m, *v.vel_ned_mps],
                ):  # fmt: skip
                    continue
                seen.add(key)
                self._gate.track(key, v.elapsed_s, self._cand)
            if seen:
                for key, tr in self._gate.finished(seen):
                    self._gate.score_virtual(key, tr, self._outage_rows, self._specs, self._cand)
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

    def _outage_rows(self, key: int) -> tuple[FloatArray, FloatArray]:
        """Base rows and targets of the virtual outage ``key`` in the window, in time order."""
        m = min(self._n, self._cap)
        rows = np.flatnonzero(self._key[:m] == key)
        rows = rows[np.argsort(self._tfix[rows], kind="stable")]
        return self._B[rows], self._Y[rows]

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
        horizon = float(self._B[idx, COL_T].max())
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
        correction is applied is the gate's business (:class:`FallbackGate`)."""
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
            cand: Candidate | None = Candidate(
                model, X.min(axis=0), X.max(axis=0), float(y.min()), float(y.max()), spec,
                self._B[idx, COL_T], y)
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
        self._gate.judge(self._cand)

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
        fallback = self._gate.fallback
        if pred is not None:
            for k in self._components:
                if not fallback[k] and math.isfinite(pred[k]):
                    use[k] = pred[k]
                    on = True
            if self._pseudo:
                # a pseudo-fix asserts the whole horizontal state: every horizontal component
                # must have earned it
                on = all(not fallback[k] and math.isfinite(pred[k]) for k in (0, 1, 3, 4))
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
        pos_err = [self._gate.val_rmse[k] for k in (0, 1)]
        vel_err = [self._gate.val_rmse[k] for k in (3, 4)]
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
        self._gate.outage_ended()
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
        f, v, z = self._gate.fallback, self._gate.val_rmse, self._gate.zero_rmse
        self._status = BridgeStatus(
            self._name, state, self._in_window, self._refits,
            (v[0], v[1], v[2], v[3], v[4], v[5]), (z[0], z[1], z[2], z[3], z[4], z[5]),
            (f[0], f[1], f[2], f[3], f[4], f[5]), self._last_fit_samples, self._horizon_s,
            self._active,
        )  # fmt: skip
