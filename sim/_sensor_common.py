"""Pieces shared by the sensor models: the config base class, field types, WGS-84 radii,
Gauss–Markov discretisation and the sample-rate schedule. Private to ``sim``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, Self

from pydantic import BaseModel, ConfigDict, Field

from physconst import WGS84_A_M, WGS84_E2

NonNegative = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
"""A finite float ≥ 0 (noise and error magnitudes)."""
Positive = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
"""A finite float > 0 (rates, ranges, correlation times)."""
Finite = Annotated[float, Field(allow_inf_nan=False)]
"""A finite float of either sign (offsets)."""

BLOCK_STEPS = 1024
"""Random numbers are drawn in blocks of this many samples (hot-loop cost, see sensors.py).
Changing it changes every sensor stream for a given seed."""



def _deep_merge(base: dict[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in update.items():
        if isinstance(value, BaseModel):
            value = value.model_dump()
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


class SensorConfigModel(BaseModel):
    """Frozen, strict base of every sensor configuration model.

    Unknown keys are rejected (``extra="forbid"``). :meth:`model_copy` with ``update``
    re-validates (pydantic's own does not), and merges nested dictionaries, so
    ``cfg.model_copy(update={"gyro": {"angle_random_walk_deg_per_rth": 0.3}})`` changes one
    field of a sub-model and a negative value raises a ``ValidationError`` naming it.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    def model_copy(self, *, update: Mapping[str, Any] | None = None, deep: bool = False) -> Self:
        """Copy with validated (and deep-merged) updates; see the class docstring."""
        if not update:
            return super().model_copy(deep=deep)
        return self.model_validate(_deep_merge(self.model_dump(), update))


def meridian_prime_radii_m(lat_rad: float) -> tuple[float, float]:
    """WGS-84 meridian (R_M) and prime-vertical (R_N) radii of curvature, m."""
    s = math.sin(lat_rad)
    w2 = 1.0 - WGS84_E2 * s * s
    r_n = WGS84_A_M / math.sqrt(w2)
    r_m = r_n * (1.0 - WGS84_E2) / w2
    return r_m, r_n


def ecef_from_geodetic_m(
    lat_rad: float, lon_rad: float, alt_m: float
) -> tuple[float, float, float]:
    """WGS-84 geodetic (rad, rad, m above the ellipsoid) to ECEF (m)."""
    _, r_n = meridian_prime_radii_m(lat_rad)
    cl, sl = math.cos(lat_rad), math.sin(lat_rad)
    return (
        (r_n + alt_m) * cl * math.cos(lon_rad),
        (r_n + alt_m) * cl * math.sin(lon_rad),
        (r_n * (1.0 - WGS84_E2) + alt_m) * sl,
    )


def gauss_markov_coefficients(sigma: float, tau_s: float, dt_s: float) -> tuple[float, float]:
    """Exact discretisation of a first-order Gauss–Markov process.

    ``x[k+1] = phi·x[k] + q·w[k]``, ``w ~ N(0, 1)``, keeps the stationary standard deviation
    ``sigma`` for any step: ``phi = exp(−dt/τ)``, ``q = sigma·sqrt(1 − phi²)``.
    """
    phi = math.exp(-dt_s / tau_s)
    return phi, sigma * math.sqrt(max(0.0, 1.0 - phi * phi))


class RateSchedule:
    """Decides at which simulation steps a sensor running at ``rate_hz`` samples.

    The k-th sample is due at ``t0 + round(k·1e6/rate_hz)`` µs, ``t0`` being the time of the
    first step seen; a step samples when its time has reached the next due time (so there is
    no drift from rounding the period). At most one sample per step.
    """

    __slots__ = ("_k", "_period_us", "_t0_us", "next_us")

    def __init__(self, rate_hz: float) -> None:
        self._period_us = 1e6 / rate_hz
        self._t0_us: int | None = None
        self._k = 0
        # Next due time, µs; callers may test ``time_us >= next_us`` before calling due().
        self.next_us = -(2**62)

    def due(self, time_us: int) -> bool:
        """True when a sample is due at simulation time ``time_us``; advances the schedule."""
        if self._t0_us is None:
            self._t0_us = time_us
            self.next_us = time_us
        if time_us < self.next_us:
            return False
        # Skip every due time up to now (only one sample per step).
        while self.next_us <= time_us:
            self._k += 1
            self.next_us = self._t0_us + round(self._k * self._period_us)
        return True
