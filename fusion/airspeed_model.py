"""A learned vehicle model: true airspeed from what the aircraft is doing, identified online.

An aircraft's airspeed is set by its controls and its state: in steady flight the lift needed
for the load factor fixes ``½ρV²·C_L(elevator, α)``, and thrust (throttle, propeller speed,
itself a function of airspeed) balances drag and the climb. While the airspeed is known (a
trusted pitot, or GNSS velocity minus the wind estimate), :class:`OnlineAirspeedModel` collects
pairs (inputs -> true airspeed) and fits a regressor (GMDH by default: a polynomial model of a
system, identified online, is its home ground) on a sliding window; when the airspeed is not
measured (no pitot, a failed pitot, GNSS lost with no pitot) its prediction is what the
filter fuses, with the model's own honest error as the measurement sigma.

Inputs (:data:`AIRSPEED_INPUTS`, one :class:`AirspeedInputs` per epoch): the normalised
controls (throttle, elevator = pitch control, aileron = roll control), propeller rpm, air
density (from the static pressure and temperature), roll and pitch, body specific force x/z
(longitudinal acceleration and load factor) and the climb rate (the baro-inertial vertical
channel holds it without GNSS). Inputs without a source (a stream with no controls, no
RAW_RPM) make the model report ``"no inputs"`` and predict nothing.

The honest error: each refit trains on the older ``1 - validation_fraction`` of the window and
measures the RMS error on the most recent part (blocked, in time order, as the model will be
used: on the future); that RMS, inflated by ``sigma_scale`` and floored at ``sigma_floor_mps``,
is the sigma of every prediction until the next refit. Outside the training range the sigma
grows with the distance outside (in units of that range); the inputs themselves are not
clipped, since clipping breaks the relations that do extrapolate (airspeed from rpm and
throttle is nearly linear), and bounding a polynomial's output is the regressor's job
(:class:`fusion.gmdh.GmdhRegressor` clips every neuron to its fitted range).

The learner itself is generic (any inputs with ``as_tuple()``, :class:`ModelInputs`): the
wind profile of ``gmdh-wind`` (:mod:`fusion.wind_model`) is two of them.

Pure: no I/O, no clocks; time comes from the samples.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

AIRSPEED_INPUTS: tuple[str, ...] = (
    "throttle",
    "elevator",
    "aileron",
    "rpm_krpm",
    "density_kgpm3",
    "roll_rad",
    "pitch_rad",
    "fx_b_mps2",
    "fz_b_mps2",
    "climb_rate_mps",
)
"""The model's input columns, in order (``elevator`` is PX4's pitch control: positive nose up)."""

MODEL_STATES: tuple[str, ...] = ("off", "no inputs", "untrained", "trained")
"""Values of :attr:`AirspeedModelStatus.state`."""


@dataclass(frozen=True, slots=True)
class AirspeedInputs:
    """One epoch's inputs (see :data:`AIRSPEED_INPUTS`; SI, rpm in thousands)."""

    throttle: float
    elevator: float
    aileron: float
    rpm_krpm: float
    density_kgpm3: float
    roll_rad: float
    pitch_rad: float
    fx_b_mps2: float
    fz_b_mps2: float
    climb_rate_mps: float

    def as_tuple(self) -> tuple[float, ...]:
        return (
            self.throttle, self.elevator, self.aileron, self.rpm_krpm, self.density_kgpm3,
            self.roll_rad, self.pitch_rad, self.fx_b_mps2, self.fz_b_mps2, self.climb_rate_mps,
        )  # fmt: skip


@dataclass(frozen=True, slots=True)
class AirspeedPrediction:
    """A predicted true airspeed and its 1-sigma error, m/s."""

    tas_mps: float
    sigma_mps: float


@dataclass(frozen=True, slots=True)
class AirspeedModelStatus:
    """What the model has learned, for health and the status topic.

    Attributes
    ----------
    method : str
    state : str
        One of :data:`MODEL_STATES`.
    samples : int
        Training pairs in the window.
    refits : int
    validation_rmse_mps : float
        RMS error of the last fit on the most recent (held-out) part of its window; NaN
        before the first fit.
    constant_rmse_mps : float
        RMS error of a constant (the mean of the training targets) on the same held-out
        part: what the model must beat to have learned anything.
    polynomial : str
        The selected model in readable form (empty before the first fit, or for a regressor
        that has no such form).
    """

    method: str
    state: str
    samples: int = 0
    refits: int = 0
    validation_rmse_mps: float = math.nan
    polynomial: str = ""
    constant_rmse_mps: float = math.nan


class ModelInputs(Protocol):
    """One epoch's inputs of a learner: its columns as floats, in a fixed order."""

    def as_tuple(self) -> tuple[float, ...]: ...


class Regressor(Protocol):
    """What the learner needs of a regressor (scikit-learn's contract)."""

    def fit(self, X: FloatArray, y: FloatArray) -> object: ...
    def predict(self, X: FloatArray) -> FloatArray: ...


class TrainingWindow:
    """The training pairs of an online learner: kept at most ``train_rate_hz`` per second
    over the last ``window_s`` (time going backwards is a new flight: the window starts
    afresh), and whether a refit is due (``refit_interval_s`` after the last, once
    ``min_samples`` pairs are held; never fewer than 8).

    Raises
    ------
    ValueError
        A rate, window or refit interval that is not > 0.
    """

    def __init__(self, train_rate_hz: float, window_s: float, refit_interval_s: float,
                 min_samples: int) -> None:
        if not (train_rate_hz > 0 and window_s > 0 and refit_interval_s > 0):
            raise ValueError("train_rate_hz, window_s and refit_interval_s must be > 0")
        self._period_us = int(1e6 / train_rate_hz)
        self._window_us = int(window_s * 1e6)
        self._refit_us = int(refit_interval_s * 1e6)
        self._min = max(int(min_samples), 8)
        self.pairs: deque[tuple[Any, ...]] = deque()
        """The pairs held, oldest first; each starts with its time (us)."""
        self._last_kept_us: int | None = None
        self._last_fit_us: int | None = None

    def add(self, time_us: int, pair: tuple[Any, ...]) -> bool:
        """Keep ``pair`` (whose first item is ``time_us``) when one is due; returns whether a
        refit is due now."""
        last = self._last_kept_us
        if last is not None and time_us - last < self._period_us:
            if time_us >= last:
                return False
            self.pairs.clear()  # time went backwards: a new flight
        self._last_kept_us = time_us
        self.pairs.append(pair)
        start = time_us - self._window_us
        while self.pairs and self.pairs[0][0] < start:
            self.pairs.popleft()
        due = self._last_fit_us is None or time_us - self._last_fit_us >= self._refit_us
        return due and len(self.pairs) >= self._min

    def fitted(self, time_us: int) -> None:
        """A refit was tried at ``time_us`` (the next is due ``refit_interval_s`` later)."""
        self._last_fit_us = time_us


class OnlineAirspeedModel:
    """Learns true airspeed from :class:`AirspeedInputs` on a sliding window (module docstring).

    Parameters
    ----------
    make_regressor : callable
        Returns a fresh, unfitted regressor for every refit.
    method : str
        Name reported in the status.
    train_rate_hz : float
        Training pairs kept per second (``observe`` may be called faster; the rest is
        dropped: neighbouring samples at 50 Hz carry no new information).
    window_s : float
        Length of the sliding training window, s.
    refit_interval_s : float
        Time between refits, s.
    min_samples : int
        Pairs needed before the first fit.
    validation_fraction : float
        Most recent share of the window held out to measure the model's error.
    sigma_scale, sigma_floor_mps : float
        Prediction sigma = max(floor, scale · validation RMS).
    describe : callable, optional
        The fitted regressor as readable text (e.g. ``GmdhRegressor.polynomial``), for the
        status.
    non_negative : bool
        Predictions are floored at zero (an airspeed; not a wind component).
    """

    def __init__(
        self,
        make_regressor: Callable[[], Regressor],
        *,
        method: str = "gmdh-airspeed",
        train_rate_hz: float = 2.0,
        window_s: float = 300.0,
        refit_interval_s: float = 20.0,
        min_samples: int = 120,
        validation_fraction: float = 0.25,
        sigma_scale: float = 1.5,
        sigma_floor_mps: float = 0.5,
        describe: Callable[[Regressor], str] | None = None,
        non_negative: bool = True,
    ) -> None:
        self._window = TrainingWindow(train_rate_hz, window_s, refit_interval_s, min_samples)
        if not 0.0 < validation_fraction < 1.0:
            raise ValueError(f"validation_fraction must be in (0, 1) (got {validation_fraction})")
        self._make = make_regressor
        self._describe = describe
        self._non_negative = non_negative
        self.method = method
        self._val_fraction = validation_fraction
        self._sigma_scale = sigma_scale
        self._sigma_floor = sigma_floor_mps
        self._model: Regressor | None = None
        self._lo: FloatArray | None = None
        self._hi: FloatArray | None = None
        self._span: FloatArray | None = None
        self._val_rmse = math.nan
        self._const_rmse = math.nan
        self._refits = 0
        self._has_inputs = False

    # ------------------------------------------------------------------ learning
    def observe(self, time_us: int, inputs: ModelInputs | None, tas_mps: float) -> None:
        """A training pair: the inputs at ``time_us`` and the true airspeed then (m/s).

        ``inputs=None`` (a stream without controls or rpm) leaves the model without inputs;
        non-finite inputs or airspeed are not learned (a NaN airspeed: inputs are there, the
        target is not known yet).
        """
        if inputs is None:
            return
        self._has_inputs = True
        x = inputs.as_tuple()
        if not (math.isfinite(tas_mps) and all(math.isfinite(v) for v in x)):
            return
        if self._window.add(time_us, (time_us, x, tas_mps)):
            self._refit(time_us)

    def _refit(self, time_us: int) -> None:
        self._window.fitted(time_us)
        pairs = self._window.pairs
        X = np.array([p[1] for p in pairs], dtype=np.float64)
        y = np.array([p[2] for p in pairs], dtype=np.float64)
        n_val = max(round(self._val_fraction * len(y)), 4)
        n_fit = len(y) - n_val
        model = self._make()
        try:
            model.fit(X[:n_fit], y[:n_fit])
            pred = model.predict(X[n_fit:])
        except (ValueError, np.linalg.LinAlgError):
            return
        rmse = float(np.sqrt(np.mean((pred - y[n_fit:]) ** 2)))
        if not math.isfinite(rmse):
            return
        self._const_rmse = float(np.sqrt(np.mean((y[n_fit:] - y[:n_fit].mean()) ** 2)))
        self._model = model
        self._lo = X[:n_fit].min(axis=0)
        self._hi = X[:n_fit].max(axis=0)
        self._span = np.maximum(self._hi - self._lo, 1e-9)
        self._val_rmse = rmse
        self._refits += 1

    # ------------------------------------------------------------------ prediction
    def predict(self, inputs: ModelInputs | None) -> AirspeedPrediction | None:
        """The predicted true airspeed with its sigma; ``None`` before the first fit, without
        inputs, or for non-finite inputs."""
        model, lo, hi, span = self._model, self._lo, self._hi, self._span
        if model is None or inputs is None or lo is None or hi is None or span is None:
            return None
        x = np.array(inputs.as_tuple(), dtype=np.float64)
        if not np.all(np.isfinite(x)):
            return None
        # distance outside the training range, in units of that range: each unit doubles sigma
        outside = float(np.max(np.abs(x - np.clip(x, lo, hi)) / span))
        tas = float(model.predict(x[None, :])[0])
        if not math.isfinite(tas):
            return None
        sigma = max(self._sigma_floor, self._sigma_scale * self._val_rmse) * (1.0 + outside)
        return AirspeedPrediction(max(tas, 0.0) if self._non_negative else tas, sigma)

    @property
    def held_out_ratio(self) -> float:
        """Held-out RMS error of the last fit over a constant's (< 1: it learned something;
        NaN before the first fit)."""
        c = self._const_rmse
        return self._val_rmse / c if c > 0.0 else math.nan

    @property
    def status(self) -> AirspeedModelStatus:
        if self._model is not None:
            state = "trained"
        elif not self._has_inputs:
            state = "no inputs"
        else:
            state = "untrained"
        poly = ""
        if self._model is not None and self._describe is not None:
            poly = self._describe(self._model)
        return AirspeedModelStatus(
            method=self.method,
            state=state,
            samples=len(self._window.pairs),
            refits=self._refits,
            validation_rmse_mps=self._val_rmse,
            polynomial=poly,
            constant_rmse_mps=self._const_rmse,
        )
