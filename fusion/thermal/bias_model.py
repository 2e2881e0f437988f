"""``gmdh-thermal``: the IMU bias against (die temperature, its rate), learned online.

While GNSS is good the filter's own bias estimate is the target: :meth:`ThermalBiasModel.add`
stores ``(T, dT/dt) -> (accel bias xyz, gyro bias xyz)`` once per ``pair_period_s`` (1 s; a
part that updates its temperature more slowly gives one pair per update), whether the reading
changes every sample or holds for tens of seconds, so the window spans the same stretch of
temperature history on every part (600 pairs: 10 min or more); every ``refit_period_s`` a
GMDH network per axis (:class:`fusion.gmdh.GmdhRegressor`, :data:`SURVIVORS` per layer) is
refitted on the window. During an outage the filter moves its bias estimate by the model's
predicted *change* since the outage began (:mod:`fusion.thermal.link`), so the constant
part stays the filter's.

Behind the bridging gate (:class:`fusion.bridging.gate.FallbackGate`, its rule and
``BridgeConfig.gate_*`` settings): each refit opens a held-out trial; ``horizon_s`` later,
with GNSS still good, the change the filter's estimate really made is compared with the
change the model of the trial's start predicted (the error left) and with no change at all
(what the blind filter assumes); an axis feeds forward only while the gate has seen it win.
Outside the temperature range it was trained on, widened by ``margin_k``, the model predicts
nothing and the bias holds (1.00x of the filter underneath); the same rule holds in the
trials: one whose start or end lies outside its model's range is not scored, so the gate
judges the model only where it would act.

Pure: no I/O, no clocks; time comes from the samples.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from fusion.bridging.gate import FallbackGate
from fusion.config import BridgeConfig
from fusion.gmdh import GmdhRegressor

AXES: tuple[str, ...] = ("ax", "ay", "az", "gx", "gy", "gz")
"""The six learned biases: accelerometer x/y/z (m/s^2), gyro x/y/z (rad/s), body frame."""

SURVIVORS = 6
"""Survivors per GMDH layer: two inputs give five input terms (``T``, ``dT/dt``, their squares
and product), and six survivors plus those five make 55 candidate neurons per layer instead
of the 136 of the regressor's many-input default of 12; a refit of the six axes costs a third
as much, and on the tuning flights the gate let the same axes through."""


@dataclass(frozen=True, slots=True)
class ThermalModelStatus:
    """What the learned bias model reports in the bridging status."""

    state: str
    samples: int
    refits: int
    polynomial: str
    t_min_k: float
    t_max_k: float
    on_axes: tuple[bool, ...]
    active: bool


class _Fitted:
    """One refit: a network per axis and the inputs' trained range."""

    __slots__ = ("nets", "t_max", "t_min")

    def __init__(self, nets: list[GmdhRegressor | None], t_min: float, t_max: float) -> None:
        self.nets = nets
        self.t_min = t_min
        self.t_max = t_max

    def covers(self, temp_k: float, margin_k: float) -> bool:
        """``temp_k`` lies inside the trained temperature range widened by ``margin_k``: the
        one rule of where the model predicts (an outage's feed-forward and the gate's trials
        alike)."""
        return self.t_min - margin_k <= temp_k <= self.t_max + margin_k

    def predict(self, temp_k: float, rate: float) -> list[float]:
        x = [temp_k, rate]
        return [math.nan if n is None else n.predict_one(x) for n in self.nets]


class ThermalBiasModel:
    """The online bias-versus-temperature model (module docstring).

    Parameters
    ----------
    config : BridgeConfig, optional
        The gate's settings (``gate_*``).
    window : int
        Training pairs kept (600 at one per ``pair_period_s``: 10 min).
    pair_period_s : float
        Least time between two stored pairs, s.
    refit_period_s : float
        Time between refits, s.
    min_samples : int
        Pairs before the first fit.
    horizon_s : float
        How far ahead a held-out trial is scored, s.
    margin_k : float
        How far outside its trained temperature range the model still predicts, K.
    """

    def __init__(self, config: BridgeConfig | None = None, *, window: int = 600,
                 pair_period_s: float = 1.0, refit_period_s: float = 30.0, min_samples: int = 40,
                 horizon_s: float = 120.0, margin_k: float = 1.0) -> None:  # fmt: skip
        cfg = config if config is not None else BridgeConfig()
        self.gate = FallbackGate(cfg, tuple(range(6)))
        self._X: deque[tuple[float, float]] = deque(maxlen=window)
        self._Y: deque[tuple[float, ...]] = deque(maxlen=window)
        self._T: deque[int] = deque(maxlen=window)
        self._pair_us = round(pair_period_s * 1e6)
        self.refit_period_s = refit_period_s
        self.min_samples = min_samples
        self.horizon_s = horizon_s
        self.margin_k = margin_k
        self.fitted: _Fitted | None = None
        self.refits = 0
        self.has_inputs = False
        """A good temperature has been read (``no inputs`` until then)."""
        self.active = False
        """The filter is feeding the predicted bias change forward now."""
        self._next_fit_us: int | None = None
        # held-out trials: (start time, model, inputs at the start, bias at the start)
        self._trials: deque[tuple[int, _Fitted, float, float, tuple[float, ...]]] = deque()

    def add(self, time_us: int, temp_k: float, rate: float, bias: tuple[float, ...]) -> None:
        """A training pair (GNSS good): the filter's bias estimate at ``temp_k``, ``rate``."""
        if not (math.isfinite(temp_k) and math.isfinite(rate)):
            return
        if self._T and time_us - self._T[-1] < self._pair_us:
            return
        self._X.append((temp_k, rate))
        self._Y.append(tuple(bias))
        self._T.append(time_us)
        self._score(time_us, temp_k, rate, bias)
        nxt = self._next_fit_us
        if nxt is None:
            self._next_fit_us = nxt = time_us + round(self.refit_period_s * 1e6)
        if time_us >= nxt and len(self._X) >= self.min_samples:
            self._next_fit_us = time_us + round(self.refit_period_s * 1e6)
            self.refit()
            fitted = self.fitted
            if fitted is not None:
                self._trials.append((time_us, fitted, temp_k, rate, tuple(bias)))

    @property
    def window_span_s(self) -> float:
        """Time from the oldest to the newest training pair in the window, s."""
        return (self._T[-1] - self._T[0]) * 1e-6 if self._T else 0.0

    def refit(self) -> None:
        """Fit one GMDH network per axis on the window."""
        X = np.array(self._X)
        Y = np.array(self._Y)
        nets: list[GmdhRegressor | None] = []
        for k in range(6):
            y = Y[:, k]
            if float(np.ptp(y)) <= 0.0 or float(np.ptp(X[:, 0])) <= 0.0:
                nets.append(None)
                continue
            try:
                nets.append(GmdhRegressor(max_layers=3, max_neurons=SURVIVORS,
                                           min_survivors=SURVIVORS).fit(X, y))
            except (ValueError, np.linalg.LinAlgError):
                nets.append(None)
        if all(n is None for n in nets):
            return  # nothing varied (a constant temperature teaches nothing)
        self.fitted = _Fitted(nets, float(X[:, 0].min()), float(X[:, 0].max()))
        self.refits += 1

    def _score(self, time_us: int, temp_k: float, rate: float, bias: tuple[float, ...]) -> None:
        trials = self._trials
        horizon_us = round(self.horizon_s * 1e6)
        gate = self.gate
        scored = False
        while trials and time_us - trials[0][0] >= horizon_us:
            _, model, t0, r0, b0 = trials.popleft()
            if not (model.covers(t0, self.margin_k) and model.covers(temp_k, self.margin_k)):
                continue  # outside its range the model predicts nothing: nothing to score
            p0 = model.predict(t0, r0)
            p1 = model.predict(temp_k, rate)
            for k in range(6):
                actual = bias[k] - b0[k]
                pred = p1[k] - p0[k]
                if math.isfinite(pred):
                    gate.scores[k].append(((actual - pred) ** 2, actual * actual))
                    scored = True
        if scored:
            fitted = self.fitted
            cands = [None if fitted is None or fitted.nets[k] is None else fitted
                     for k in range(6)]  # fmt: skip
            gate.judge(cands)  # type: ignore[arg-type]

    def outage_restart(self) -> None:
        """GNSS was lost: trials under way cannot be scored against the filter's estimate."""
        self._trials.clear()

    def predict(self, temp_k: float, rate: float) -> tuple[float, ...] | None:
        """The predicted bias per axis (0 for the axes the gate holds off, so their change is
        nil); ``None`` outside the trained range (plus ``margin_k``) or before a fit."""
        f = self.fitted
        if f is None or not f.covers(temp_k, self.margin_k):
            return None
        p = f.predict(temp_k, rate)
        off = self.gate.fallback
        return tuple(0.0 if off[k] or not math.isfinite(p[k]) else p[k] for k in range(6))

    @property
    def status(self) -> ThermalModelStatus:
        """State, pairs, refits, the selected polynomials, the trained range, the axes on."""
        f = self.fitted
        if f is None:
            state = "untrained" if self.has_inputs else "no inputs"
            poly = ""
            t_min = t_max = math.nan
        else:
            state = "trained"
            pairs = zip(AXES, f.nets, strict=True)
            poly = "; ".join(f"{a}: {net.polynomial(4)}" for a, net in pairs if net is not None)
            t_min, t_max = f.t_min, f.t_max
        return ThermalModelStatus(state, len(self._X), self.refits, poly, t_min, t_max,
                                  tuple(not x for x in self.gate.fallback),
                                  self.active)  # fmt: skip
