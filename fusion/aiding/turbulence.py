"""Turbulence intensity from the air-data residuals, estimated in flight.

The gust states of the air-data block (:mod:`fusion.aiding.airspeed`) are a first-order
Gauss-Markov process whose sigma is the turbulence intensity. A fixed sigma is wrong on most
days: too large in calm air (the airspeed then hardly holds the velocity in an outage, its
innovations go to the gust), too small in strong turbulence (overconfident). While GNSS is good
the INS velocity is known to a few cm/s, so the airspeed residual against the *mean* wind,

    r = (1 + k) |v - w_mean| - TAS_measured,

is the gust along the air-relative velocity plus the pitot's own noise (and what the airspeed
model leaves out). Its variance over an exponential window, less the sensor's share, is the
gust variance along track; MIL-F-8785C's low-altitude model has the same sigma across track
(``sigma_u = sigma_v``), so it sets both gust axes.

The filter uses the conservative prior (``AirspeedTuning.gust_sigma_mps``) until
``turbulence_min_residuals`` residuals have been seen; the estimate itself is the residuals'
alone (a running variance, then the window), so the prior does not linger in calm air. It is
bounded by a floor (still air is never taken as perfectly still) and a ceiling: a scatter
above the ceiling is not plausible air but a pitot or model fault, flagged and answered with
the ceiling. The estimate sets the gust sigma in still air (at most
``outage_hold_max_turbulence_mps``); above it the filter keeps the prior unless
``gust_sigma_estimated_above_still_air`` (the config field says why). In an outage nothing
is added: the turbulence does not change because GNSS went away, so the last estimate holds.
"""

from __future__ import annotations

import math

from fusion.config import AirspeedTuning


class TurbulenceEstimator:
    """Windowed estimate of the gust sigma (module docstring).

    Parameters
    ----------
    cfg : AirspeedTuning
        ``gust_sigma_mps`` (prior and fixed value), ``adaptive_turbulence``,
        ``gust_sigma_min_mps`` / ``gust_sigma_max_mps``, ``turbulence_window_s``,
        ``turbulence_min_residuals``, ``fuse_rate_hz`` (the residuals' rate).
    """

    __slots__ = ("_alpha_min", "_cfg", "_mean", "_var", "count", "saturated")

    def __init__(self, cfg: AirspeedTuning) -> None:
        self._cfg = cfg
        self._alpha_min = 1.0 / max(1.0, cfg.turbulence_window_s * cfg.fuse_rate_hz)
        self._mean = 0.0
        self._var = 0.0  # gust variance (the sensor's share removed)
        self.count = 0
        """Residuals taken in."""
        self.saturated = False
        """The raw estimate is above the ceiling (flagged ``turbulence_saturated``)."""

    def add(self, residual_mps: float, sensor_variance: float) -> None:
        """One airspeed residual against the mean wind (GNSS good), m/s, and the variance of
        the pitot's own noise in it, m^2/s^2."""
        if not (math.isfinite(residual_mps) and math.isfinite(sensor_variance)):
            return
        self.count += 1
        a = max(self._alpha_min, 1.0 / self.count)
        d = residual_mps - self._mean
        self._mean += a * d
        # exponentially weighted variance about the moving mean (the mean takes a slowly
        # converging scale error and the mean wind's lag, not turbulence)
        self._var += a * ((1.0 - a) * d * d - sensor_variance - self._var)
        self.saturated = self.raw_sigma_mps > self._cfg.gust_sigma_max_mps

    @property
    def raw_sigma_mps(self) -> float:
        """The unbounded estimate, m/s (0 when the residuals are all sensor noise)."""
        return math.sqrt(max(self._var, 0.0))

    @property
    def estimate_mps(self) -> float:
        """The estimate within its floor and ceiling, m/s (NaN before enough residuals)."""
        cfg = self._cfg
        if self.count < cfg.turbulence_min_residuals:
            return math.nan
        return min(cfg.gust_sigma_max_mps, max(cfg.gust_sigma_min_mps, self.raw_sigma_mps))

    @property
    def sigma_mps(self) -> float:
        """The gust sigma the filter uses, m/s (module docstring and :attr:`source`)."""
        cfg, source = self._cfg, self.source
        if source == "saturated":
            return cfg.gust_sigma_max_mps
        return self.estimate_mps if source == "estimated" else cfg.gust_sigma_mps

    @property
    def source(self) -> str:
        """Where the gust sigma in use comes from: ``default`` (the prior: not adaptive, or
        too few residuals yet), ``estimated`` (the estimate: still air, or any air with
        ``gust_sigma_estimated_above_still_air``), ``turbulent`` (the estimate is above
        still air: the prior) or ``saturated`` (the ceiling)."""
        cfg = self._cfg
        if not cfg.adaptive_turbulence or self.count < cfg.turbulence_min_residuals:
            return "default"
        if self.saturated:
            return "saturated"
        if (self.estimate_mps <= cfg.outage_hold_max_turbulence_mps
                or cfg.gust_sigma_estimated_above_still_air):  # fmt: skip
            return "estimated"
        return "turbulent"
