"""A learned pitot-static position error: the airspeed error against the flow angles, online.

A static port sits in the pressure field of the airframe, and a total-pressure tube reads the
full impact pressure only when it points into the flow: the measured true airspeed carries an
error that moves with the angle of attack, the sideslip and the airspeed itself
(:mod:`fusion.aiding.position_error` is the physics term, a slope against the angle of
attack). :class:`OnlinePitotErrorModel` learns that error with no assumed form: a GMDH network
(:class:`~fusion.airspeed_model.OnlineAirspeedModel`, regressor defaults of
:class:`fusion.gmdh.GmdhRegressor`) fitted on a sliding window of pairs

    inputs  (alpha, beta, TAS):  the flow angles of the air-relative velocity
                                 ``a = v - w_mean`` in body axes and the measured TAS
    target  TAS - (1 + k) |a|:   the measured airspeed minus the airspeed the GNSS-aided
                                 velocity, the mean wind and the scale state predict

taken while GNSS is good and the mean wind has converged (:mod:`fusion.aiding.airspeed`). The
angles are the kinematic ones the filter already has (INS velocity and attitude, the mean-wind
estimate), the same angle of attack the physics fit uses: they need no airframe constants, and
in an outage the body-axis angle of attack follows the attitude and the baro-held vertical
velocity, so it degrades slowly. An angle of attack from the specific force (the load factor
over the dynamic pressure: a lift-coefficient proxy) would also see vertical gusts, but it
needs the wing loading or must be learned too, and it carries the vibration and gust load of
every accelerometer sample.

With GNSS lost the filter removes the predicted error from each measured TAS before fusing it
(``--bridge gmdh-pitot``). The correction is used only

- behind the skill gate: the network's held-out RMS error (the most recent quarter of its
  window, in time order: the future it will be used on) is below ``skill_ratio`` times a
  constant's. Without a position error (or when the gusts hide it) the target is noise around
  the scale state's mean and the gate stays shut;
- inside the inputs' trained range (each input within ``range_margin`` of its span beyond the
  values seen in training): off elsewhere, never extrapolated.

Its status reports the state, the pairs, the refits, the held-out errors and the selected
polynomial.

Pure: no I/O, no clocks; time comes from the samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from fusion.airspeed_model import AirspeedModelStatus, OnlineAirspeedModel, Regressor

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
    window_s : float
        Sliding training window, s.
    refit_interval_s : float
        Time between refits, s.
    skill_ratio : float
        The correction is used only while the held-out RMS error is below this times a
        constant's.
    range_margin : float
        An input may lie this fraction of its trained span outside the trained range.
    describe : callable, optional
        The fitted regressor as readable text, for the status.
    """

    def __init__(
        self,
        make_regressor: Callable[[], Regressor],
        *,
        method: str = "gmdh-pitot",
        window_s: float = 600.0,
        refit_interval_s: float = 20.0,
        skill_ratio: float = 0.9,
        range_margin: float = 0.1,
        describe: Callable[[Regressor], str] | None = None,
    ) -> None:
        self._learner = OnlineAirspeedModel(
            make_regressor, method=method, train_rate_hz=1.0, window_s=window_s,
            refit_interval_s=refit_interval_s, min_samples=120, sigma_floor_mps=0.0,
            describe=describe, non_negative=False,
        )  # fmt: skip
        self._skill = skill_ratio
        self._margin = range_margin
        self.active = False
        """The last :meth:`correction` was applied (trained, skilled, in range)."""
        self.corrections = 0
        """Corrections applied."""
        self.out_of_range = 0
        """Corrections refused: an input outside the trained range."""

    def observe(self, time_us: int, inputs: PitotInputs, error_mps: float) -> None:
        """A training pair (GNSS good): the inputs and the measured TAS minus the predicted
        one, m/s. Non-finite values are not learned."""
        self._learner.observe(time_us, inputs, error_mps)

    @property
    def skilled(self) -> bool:
        """The last fit beats a constant on its held-out part by the skill ratio."""
        r = self._learner.held_out_ratio
        return math.isfinite(r) and r < self._skill

    def correction(self, inputs: PitotInputs) -> float:
        """The airspeed error to remove from the measured TAS now (m/s): 0 before a skilled
        fit, outside the trained range or for non-finite inputs."""
        self.active = False
        if not self.skilled:
            return 0.0
        rng = self._learner.training_range
        x = inputs.as_tuple()
        if rng is None or not all(math.isfinite(v) for v in x):
            return 0.0
        lo, hi = rng
        for v, a, b in zip(x, lo, hi, strict=True):
            m = self._margin * max(b - a, 1e-9)
            if not a - m <= v <= b + m:
                self.out_of_range += 1
                return 0.0
        pred = self._learner.predict(inputs)
        if pred is None or not math.isfinite(pred.tas_mps):
            return 0.0
        self.active = True
        self.corrections += 1
        return pred.tas_mps

    @property
    def status(self) -> AirspeedModelStatus:
        """The learner's state, pairs, refits, held-out errors and polynomial."""
        return self._learner.status
