"""A learned pitot-static position error: the airspeed error against the flow angles, online.

A static port sits in the pressure field of the airframe, and a total-pressure tube reads the
full impact pressure only when it points into the flow: the measured true airspeed carries an
error that moves with the angle of attack, the sideslip and the airspeed itself
(:mod:`fusion.aiding.position_error` is the physics term, a slope against the angle of
attack). :class:`OnlinePitotErrorModel` learns that error with no assumed form: a GMDH network
(:class:`fusion.gmdh.GmdhRegressor`) refitted on a sliding window of pairs

    inputs  (alpha, beta, TAS):  the flow angles of the air-relative velocity
                                 ``a = v - w_mean`` in body axes and the measured TAS
    target  TAS - |a|:           the measured airspeed minus the airspeed the GNSS-aided
                                 velocity and the mean-wind estimate predict

taken while GNSS is good and the mean wind has converged (:mod:`fusion.aiding.airspeed`). The
target holds the whole error, the part proportional to the airspeed (the filter's scale state
``k``) included: with GNSS the scale and the mean wind are random walks that follow a slowly
changing position error part of the way, so a target taken against ``(1 + k) |a|`` would hide
the part they have absorbed, which in an outage (where they are held) comes back.

The angles are the kinematic ones the filter already has (INS velocity and attitude, the
mean-wind estimate), the same angle of attack the physics fit uses: they need no airframe
constants, and in an outage the body-axis angle of attack follows the attitude and the
baro-held vertical velocity, so it degrades slowly. An angle of attack from the specific force
(the load factor over the dynamic pressure: a lift-coefficient proxy) would also see vertical
gusts, but it needs the wing loading or must be learned too, and it carries the vibration and
gust load of every accelerometer sample.

With GNSS lost the filter removes from each measured TAS the learned error's *change* from
the conditions the scale state last absorbed, ``e(alpha, beta, TAS) - e_ref`` with ``e_ref``
the mean of ``e`` over the last ``reference_s`` of the window (``--bridge gmdh-pitot``); the
scale state keeps the level, as the physics fit's reference angle of attack does. Whatever the
network learned of the wind estimate's own errors has no level of its own to add. The
correction is used only

- behind the skill gate: each refit trains on the older ``1 - validation_fraction`` of the
  window and scores the most recent part (in time order: the future it will be used on) as it
  would be used, the scale state's ``k |a|`` plus the change from the end of the fitted part;
  that must predict ``TAS - |a|`` with an RMS error below ``skill_ratio`` times that of
  ``k |a|`` alone, on ``skill_refits`` refits in a row. Without a position error (or where
  the gusts hide it) the scale state already does as well, and the gate stays shut;
- inside the inputs' trained range (each input within ``range_margin`` of its span beyond the
  values seen in training): off elsewhere, never extrapolated.

Its status reports the state, the pairs, the refits, the held-out error and the selected
polynomial.

Pure: no I/O, no clocks; time comes from the samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.airspeed_model import AirspeedModelStatus, Regressor, TrainingWindow

FloatArray = NDArray[np.float64]

PITOT_INPUTS: tuple[str, ...] = ("alpha_rad", "beta_rad", "tas_mps")
"""The model's input columns, in order."""


@dataclass(frozen=True, slots=True)
class PitotInputs:
    """One air-data epoch's inputs (:data:`PITOT_INPUTS`): angle of attack ``atan2(a_z, a_x)``
    and sideslip ``asin(a_y / |a|)`` of the air-relative velocity in body axes (rad), and the
    measured true airspeed (m/s)."""

    alpha_rad: float
    beta_rad: float
    tas_mps: float

    def as_tuple(self) -> tuple[float, ...]:
        return (self.alpha_rad, self.beta_rad, self.tas_mps)


class OnlinePitotErrorModel:
    """Learns the airspeed error against :class:`PitotInputs` (module docstring).

    Parameters
    ----------
    make_regressor : callable
        Returns a fresh, unfitted regressor for every refit.
    method : str
        Name reported in the status.
    train_rate_hz : float
        Training pairs kept per second.
    window_s : float
        Sliding training window, s.
    refit_interval_s : float
        Time between refits, s.
    min_samples : int
        Pairs needed before the first fit.
    validation_fraction : float
        Most recent share of the window held out to score the fit.
    skill_ratio : float
        The correction is used only while the held-out RMS error is below this times the
        filter's own (scale-state) prediction's. Chosen on tuning cases: a learnable position
        error (the unit tests' sweep) scores 0.26-0.58; a network fitted to the noise of a
        pitot without one (the air-data tests' synthetic flight, seeds 43-45) 0.82-0.88, and
        opening the gate there cost up to 1.8x at the end of a 100 s outage.
    skill_refits : int
        Consecutive refits that must pass the skill ratio before the correction is used (and
        any failing one shuts it again). A network fitted to noise scores 0.61-2.4 from one
        refit to the next on those flights; a learnable error (the unit tests' sweep, target
        noise up to 0.1 m/s) 0.18-0.59 on every refit after its first two: one lucky window
        must not open the gate.
    range_margin : float
        An input may lie this fraction of its trained span outside the trained range.
    reference_s : float
        The correction is the learned error's change from its mean over the last
        ``reference_s`` of the window (the conditions the scale state has absorbed; by
        default the whole window, as the physics fit's reference angle of attack).
    describe : callable, optional
        The fitted regressor as readable text, for the status.
    """

    def __init__(
        self,
        make_regressor: Callable[[], Regressor],
        *,
        method: str = "gmdh-pitot",
        train_rate_hz: float = 1.0,
        window_s: float = 600.0,
        refit_interval_s: float = 20.0,
        min_samples: int = 60,
        validation_fraction: float = 0.25,
        skill_ratio: float = 0.7,
        skill_refits: int = 2,
        range_margin: float = 0.1,
        reference_s: float = 600.0,
        describe: Callable[[Regressor], str] | None = None,
    ) -> None:
        # pairs: (time, inputs, target TAS - |a|, the filter's own prediction of it k |a|)
        self._window = TrainingWindow(train_rate_hz, window_s, refit_interval_s, min_samples)
        if not 0.0 < validation_fraction < 1.0:
            raise ValueError(f"validation_fraction must be in (0, 1) (got {validation_fraction})")
        self.method = method
        self._make = make_regressor
        self._describe = describe
        self._val_fraction = validation_fraction
        self._skill = skill_ratio
        if skill_refits < 1:
            raise ValueError(f"skill_refits must be at least 1 (got {skill_refits})")
        self._skill_refits = skill_refits
        self._streak = 0  # consecutive refits within the skill ratio
        self._margin = range_margin
        self._model: Regressor | None = None
        self._lo: tuple[float, ...] = ()
        self._hi: tuple[float, ...] = ()
        self._val_rmse = math.nan
        self._filter_rmse = math.nan
        self._refits = 0
        self._ref_us = int(reference_s * 1e6)
        self._ref_mps = 0.0
        self.active = False
        """The last :meth:`correction` was applied (trained, skilled, in range)."""
        self.corrections = 0
        """Corrections applied."""
        self.out_of_range = 0
        """Corrections refused: an input outside the trained range."""

    # ------------------------------------------------------------------ learning
    def observe(self, time_us: int, inputs: PitotInputs, error_mps: float,
                filter_error_mps: float) -> None:  # fmt: skip
        """A training pair (GNSS good): the inputs, the measured TAS minus ``|a|`` and the
        filter's own prediction of that difference (``k |a|``), m/s. Non-finite values are
        not learned."""
        x = inputs.as_tuple()
        if not (math.isfinite(error_mps) and math.isfinite(filter_error_mps)
                and all(math.isfinite(v) for v in x)):  # fmt: skip
            return
        if self._window.add(time_us, (time_us, x, error_mps, filter_error_mps)):
            self._refit(time_us)

    def _reference(self, model: Regressor, t_us: NDArray[np.int64], X: FloatArray) -> float:
        """The mean learned error over the last ``reference_s`` of ``X`` (the conditions the
        scale state has absorbed), m/s."""
        recent = t_us >= t_us[-1] - self._ref_us
        return float(np.mean(model.predict(X[recent])))

    def _refit(self, time_us: int) -> None:
        self._window.fitted(time_us)
        pairs = self._window.pairs
        t = np.array([p[0] for p in pairs], dtype=np.int64)
        X = np.array([p[1] for p in pairs], dtype=np.float64)
        y = np.array([p[2] for p in pairs], dtype=np.float64)
        k = np.array([p[3] for p in pairs], dtype=np.float64)
        n_val = max(round(self._val_fraction * len(y)), 4)
        n_fit = len(y) - n_val
        model = self._make()
        try:
            with np.errstate(all="ignore"):
                model.fit(X[:n_fit], y[:n_fit])
                # scored as it is used: the scale state's prediction plus the learned change
                # from the conditions at the end of the fitted part
                ref = self._reference(model, t[:n_fit], X[:n_fit])
                pred = k[n_fit:] + np.asarray(model.predict(X[n_fit:]), dtype=np.float64) - ref
                ref = self._reference(model, t, X)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
            return
        rmse = float(np.sqrt(np.mean((pred - y[n_fit:]) ** 2)))
        if not (math.isfinite(rmse) and math.isfinite(ref)):
            return
        self._model = model
        self._ref_mps = ref
        self._val_rmse = rmse
        self._filter_rmse = float(np.sqrt(np.mean((k[n_fit:] - y[n_fit:]) ** 2)))
        self._streak = self._streak + 1 if rmse < self._skill * self._filter_rmse else 0
        self._lo = tuple(X[:n_fit].min(axis=0).tolist())
        self._hi = tuple(X[:n_fit].max(axis=0).tolist())
        self._refits += 1

    # ------------------------------------------------------------------ correction
    @property
    def skilled(self) -> bool:
        """The last ``skill_refits`` fits each predicted their held-out airspeeds better than
        the filter's scale state by the skill ratio."""
        return self._streak >= self._skill_refits

    def correction_mps(self, inputs: PitotInputs) -> float | None:
        """The airspeed correction now (m/s): the learned error ``TAS - |a|`` at ``inputs``
        minus its mean over the last ``reference_s`` of the window; ``None`` before a skilled
        fit, outside the trained range or for non-finite inputs."""
        self.active = False
        model = self._model
        if model is None or not self.skilled:
            return None
        x = inputs.as_tuple()
        if not all(math.isfinite(v) for v in x):
            return None
        for v, a, b in zip(x, self._lo, self._hi, strict=True):
            m = self._margin * max(b - a, 1e-9)
            if not a - m <= v <= b + m:
                self.out_of_range += 1
                return None
        fast = getattr(model, "predict_one", None)
        e = float(fast(x)) if callable(fast) else float(model.predict(np.array([x]))[0])
        if not math.isfinite(e):
            return None
        self.active = True
        self.corrections += 1
        return e - self._ref_mps

    @property
    def status(self) -> AirspeedModelStatus:
        """State, pairs, refits, held-out RMS error (and the filter's on the same part, as
        ``constant_rmse_mps``) and the selected polynomial."""
        if self._model is not None:
            state = "trained"
        elif self._window.pairs:
            state = "untrained"
        else:
            state = "no inputs"
        poly = ""
        if self._model is not None and self._describe is not None:
            poly = self._describe(self._model)
        return AirspeedModelStatus(
            method=self.method, state=state, samples=len(self._window.pairs), refits=self._refits,
            validation_rmse_mps=self._val_rmse, polynomial=poly,
            constant_rmse_mps=self._filter_rmse,
        )  # fmt: skip
