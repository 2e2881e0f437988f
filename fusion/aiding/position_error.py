"""Pitot-static position error against angle of attack, fitted in flight.

A static port sits in the pressure field of the airframe: it senses the static pressure plus
a fraction of the impact pressure that follows the lift coefficient, and so the angle of
attack (Gracey, NASA RP-1046, 1980, ch. 9; the position-error calibration of FAA AC 23-8C).
To first order the measured true airspeed is

    TAS_measured = (1 + k + c (alpha - alpha_ref)) |a|,

with ``k`` the filter's airspeed scale state, ``a`` the air-relative velocity and ``alpha`` its
angle of attack in body axes, ``atan2(a_b,z, a_b,x)``. A constant part of the error is ``k``'s;
the part that moves with the angle of attack would otherwise look like turbulence to the filter
(in turns, climbs and speed changes) and, in an outage, like a scale error that comes and goes.

While GNSS is good ``|a|`` is known (the INS velocity minus the mean wind), so ``c`` is the
slope of the ratio ``TAS / |a|`` against ``alpha``: an exponentially weighted least-squares fit
over ``position_error_window_s``, used once the angle of attack has varied enough and the slope
stands out of its own uncertainty (twice its standard error, counting one independent point per
``_POINTS_PER_INDEPENDENT`` 1 Hz points: gusts are correlated over seconds, and in turbulence the
vertical gusts move the angle of attack while the horizontal ones move the ratio, which a
plain fit would take for a slope), bounded by ``position_error_max_per_rad``. ``alpha_ref`` is
the window's mean angle of attack, so the correction averages to zero where ``k`` is learned. The
measured TAS is divided by ``1 + c (alpha - alpha_ref)`` before it is fused. In an outage nothing
is added and the fit holds.
"""

from __future__ import annotations

import math

from fusion.config import AirspeedTuning

_MIN_ALPHA_SPREAD_RAD = math.radians(0.5)  # less spread than this: the slope is noise
_POINTS_PER_INDEPENDENT = 10.0  # 1 Hz points per independent one (gust correlation ~6-10 s)


class PositionErrorFit:
    """Exponentially weighted fit of the position-error slope (module docstring).

    Parameters
    ----------
    cfg : AirspeedTuning
        ``position_error_fit``, ``position_error_window_s``, ``position_error_max_per_rad``,
        ``fuse_rate_hz`` (the rate of the points).
    """

    __slots__ = ("_alpha", "_cfg", "_sxx", "_sxy", "_syy", "_y", "alpha_ref_rad", "count")

    def __init__(self, cfg: AirspeedTuning) -> None:
        self._cfg = cfg
        self._alpha = 1.0 / max(1.0, cfg.position_error_window_s * cfg.fuse_rate_hz)
        self._y = 0.0  # means of x = alpha and y = TAS / |a|, and the (co)variances
        self._sxx = 0.0
        self._sxy = 0.0
        self._syy = 0.0
        self.count = 0
        """Points taken in."""
        self.alpha_ref_rad = 0.0
        """Mean angle of attack of the window (the correction's reference), rad."""

    def add(self, alpha_rad: float, ratio: float) -> None:
        """One point with GNSS good: the angle of attack (rad) and ``TAS / |a|``."""
        if not (math.isfinite(alpha_rad) and math.isfinite(ratio)):
            return
        self.count += 1
        a = max(self._alpha, 1.0 / self.count)
        dx, dy = alpha_rad - self.alpha_ref_rad, ratio - self._y
        self.alpha_ref_rad += a * dx
        self._y += a * dy
        self._sxx = (1.0 - a) * (self._sxx + a * dx * dx)
        self._sxy = (1.0 - a) * (self._sxy + a * dx * dy)
        self._syy = (1.0 - a) * (self._syy + a * dy * dy)

    @property
    def coefficient_per_rad(self) -> float:
        """The slope ``c`` in use (0 when off, before the angle of attack has varied enough,
        with too few points, or when the slope is within twice its standard error), 1/rad."""
        cfg = self._cfg
        if (not cfg.position_error_fit or self.count < cfg.turbulence_min_residuals
                or self._sxx < _MIN_ALPHA_SPREAD_RAD**2):
            return 0.0
        c = self._sxy / self._sxx
        n_eff = min(float(self.count), 1.0 / self._alpha) / _POINTS_PER_INDEPENDENT
        residual_var = max(self._syy - c * self._sxy, 0.0)
        if c * c <= 4.0 * residual_var / (self._sxx * n_eff):
            return 0.0
        lim = cfg.position_error_max_per_rad
        return min(lim, max(-lim, c))

    def correct(self, tas_mps: float, alpha_rad: float) -> float:
        """The measured TAS with the position error at ``alpha_rad`` removed, m/s."""
        c = self.coefficient_per_rad
        if c == 0.0 or not math.isfinite(alpha_rad):
            return tas_mps
        return tas_mps / (1.0 + c * (alpha_rad - self.alpha_ref_rad))
