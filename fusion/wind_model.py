"""A learned wind profile: the mean wind the filter estimated, as a function of height.

What the physics filter leaves in its air-data channel is the wind's dependence on height:
its mean wind is a random walk (:mod:`fusion.error_model`), so with GNSS it follows the wind
wherever the aircraft flies, and with GNSS lost nothing tells it that the wind changed when
the aircraft climbed or descended (wind shear: a power law ``w(h) = w_ref (h / h_ref)^p``
near the ground, a sounding aloft). While GNSS is good :class:`OnlineWindModel` learns the
filter's mean-wind estimate North and East against the height (two
:class:`~fusion.airspeed_model.OnlineAirspeedModel` learners, GMDH by default, on a sliding
window long enough to hold the heights flown); with GNSS lost the filter moves its mean wind
by the profile's change as the height changes: a learned input of the wind's process model
(:mod:`fusion.aiding.airspeed`; ``--bridge gmdh-wind``). Outside the heights it was trained
on the GMDH neurons are clipped to their fitted range, so the profile is flat there and
nothing moves. An axis whose profile does not beat a constant on the held-out (most recent)
part of its window by ``skill_ratio`` is held flat too: without shear the estimates' noise,
or the wind estimate still converging while the aircraft climbs, would otherwise be learned
as a profile.

Pure: no I/O, no clocks; time comes from the samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from fusion.airspeed_model import (
    MODEL_STATES,
    AirspeedModelStatus,
    OnlineAirspeedModel,
    Regressor,
)


@dataclass(frozen=True, slots=True)
class WindInputs:
    """The wind model's input: the height (MSL, m; the baro-inertial height without GNSS)."""

    alt_msl_m: float

    def as_tuple(self) -> tuple[float, ...]:
        return (self.alt_msl_m,)


@dataclass(frozen=True, slots=True)
class WindPrediction:
    """A predicted mean wind North, East and its 1-sigma per axis, m/s; NaN on an axis whose
    profile has no skill (held flat)."""

    wind_ne_mps: tuple[float, float]
    sigma_ne_mps: tuple[float, float]


class OnlineWindModel:
    """Learns the mean wind North and East against height (module docstring).

    Parameters
    ----------
    make_regressor : callable
        Returns a fresh, unfitted regressor for every refit.
    method : str
        Name reported in the status.
    window_s : float
        Sliding training window, s: long enough to hold the climbs and descents flown
        (default 600 s).
    min_change_m : float
        The model is used only once its training heights span at least this much (below it
        the wind at one height is all it knows, and the filter's own estimate holds that).
    skill_ratio : float
        An axis's profile is used only while its held-out RMS error is below this times a
        constant's (otherwise that axis is flat: the training mean).
    describe : callable, optional
        The fitted regressor as readable text, for the status.
    """

    def __init__(
        self,
        make_regressor: Callable[[], Regressor],
        *,
        method: str = "gmdh-wind",
        window_s: float = 600.0,
        refit_interval_s: float = 20.0,
        min_samples: int = 120,
        sigma_floor_mps: float = 0.2,
        min_change_m: float = 30.0,
        skill_ratio: float = 0.8,
        describe: Callable[[Regressor], str] | None = None,
    ) -> None:
        def learner() -> OnlineAirspeedModel:
            return OnlineAirspeedModel(
                make_regressor, method=method, window_s=window_s,
                refit_interval_s=refit_interval_s, min_samples=min_samples,
                sigma_floor_mps=sigma_floor_mps, describe=describe, non_negative=False,
            )  # fmt: skip

        self.method = method
        self._north, self._east = learner(), learner()
        self._min_change_m = min_change_m
        self._skill_ratio = skill_ratio
        self._lo_m = math.inf
        self._hi_m = -math.inf

    def observe(self, time_us: int, alt_msl_m: float, wind_ne_mps: tuple[float, float]) -> None:
        """A training pair: the height and the filter's mean-wind estimate then."""
        if not (math.isfinite(alt_msl_m) and all(map(math.isfinite, wind_ne_mps))):
            return
        x = WindInputs(alt_msl_m)
        self._north.observe(time_us, x, wind_ne_mps[0])
        self._east.observe(time_us, x, wind_ne_mps[1])
        self._lo_m = min(self._lo_m, alt_msl_m)
        self._hi_m = max(self._hi_m, alt_msl_m)

    def predict(self, alt_msl_m: float) -> WindPrediction | None:
        """The mean wind at ``alt_msl_m`` with its sigma; ``None`` before both learners fit or
        while the heights flown span less than ``min_change_m``; NaN on an axis without skill
        (``skill_ratio``)."""
        if self._hi_m - self._lo_m < self._min_change_m:
            return None
        x = WindInputs(alt_msl_m)
        n, e = self._north.predict(x), self._east.predict(x)
        if n is None or e is None:
            return None
        r = self._skill_ratio
        wn = n.tas_mps if self._north.held_out_ratio < r else math.nan
        we = e.tas_mps if self._east.held_out_ratio < r else math.nan
        return WindPrediction((wn, we), (n.sigma_mps, e.sigma_mps))

    @property
    def status(self) -> AirspeedModelStatus:
        """Both learners as one: the weaker state, the pairs, the refits, the larger held-out
        error, and the two polynomials (``north: ...``, ``east: ...``)."""
        n, e = self._north.status, self._east.status
        state = min(n.state, e.state, key=MODEL_STATES.index)
        poly = f"north:\n{n.polynomial}\neast:\n{e.polynomial}" if n.polynomial else ""
        return AirspeedModelStatus(
            method=self.method, state=state, samples=n.samples, refits=n.refits,
            validation_rmse_mps=max(n.validation_rmse_mps, e.validation_rmse_mps),
            polynomial=poly,
        )  # fmt: skip
