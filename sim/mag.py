"""Magnetometer model: the Earth's field at the vehicle rotated into body axes, noise, hard iron.

Earth field
-----------
The World Magnetic Model (:mod:`physconst.geomag`, the one definition of the Earth's field
that the filter's heading reference uses too) at the vehicle's position and the simulated
date (``decimal_year``, default :data:`physconst.geomag.DEFAULT_DECIMAL_YEAR`). Over a
flight the field changes slowly with position (about 0.1 deg of declination per 10 km in
central Europe, more near the poles): it is re-evaluated whenever the vehicle has moved more
than :data:`physconst.geomag.REEVALUATE_DISTANCE_M` (500 m) from the point of the last
evaluation, horizontally or in height (~0.01 deg of declination away from the poles).
Crustal anomalies and secular variation within a flight are not modelled. Where a fixed
local field is wanted (e.g. to reproduce a bench measurement), give ``field_ned_ut`` and the
model is not used.

Measurement: ``m_b = Q( C_bn·B_n + hard_iron + n )``, ``n ~ N(0, noise²)`` per axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from physconst.geomag import (
    DEFAULT_DECIMAL_YEAR,
    REEVALUATE_DISTANCE_M,
    magnetic_field_ned_t,
    moved_beyond,
)
from sim._sensor_common import (
    BLOCK_STEPS,
    Finite,
    NonNegative,
    SensorConfigModel,
)
from sim.samples import MagSample


class MagConfig(SensorConfigModel):
    """Magnetometer figures.

    Attributes
    ----------
    noise_ut : white noise per axis per sample, 1σ, µT.
    resolution_ut : output LSB, µT (0 = none).
    hard_iron_ut : constant offset in body axes (x, y, z), µT.
    field_ned_ut : Earth field in NED, µT, overriding the World Magnetic Model; None = the
        model at the vehicle's position and the simulated date.
    """

    noise_ut: NonNegative
    resolution_ut: NonNegative = 0.0
    hard_iron_ut: tuple[Finite, Finite, Finite] = (0.0, 0.0, 0.0)
    field_ned_ut: tuple[Finite, Finite, Finite] | None = None


@dataclass(frozen=True)
class MagParams:
    """A :class:`MagConfig` in SI (tesla)."""

    noise_t: float
    resolution_t: float
    hard_iron_t: tuple[float, float, float]

    @classmethod
    def from_config(cls, c: MagConfig) -> MagParams:
        """Convert once."""
        hx, hy, hz = c.hard_iron_ut
        return cls(c.noise_ut * 1e-6, c.resolution_ut * 1e-6, (hx * 1e-6, hy * 1e-6, hz * 1e-6))


class MagModel:
    """Magnetometer with its own random generator.

    Parameters
    ----------
    config : MagConfig
    rng : numpy.random.Generator
        Used only by this model.
    lat_rad, lon_rad, alt_m : float
        Start position (geodetic rad, m above the ellipsoid); later ones via :meth:`move_to`.
    decimal_year : float
        The simulated date, e.g. 2026.5 (:func:`physconst.geomag.decimal_year`).

    Attributes
    ----------
    field_ned_tesla : ndarray (3,)
        The Earth field in use (at the last evaluation point), NED, tesla.
    """

    def __init__(
        self,
        config: MagConfig,
        rng: np.random.Generator,
        lat_rad: float,
        lon_rad: float,
        alt_m: float,
        decimal_year: float = DEFAULT_DECIMAL_YEAR,
    ) -> None:
        if not math.isfinite(decimal_year):
            raise ValueError(f"the simulated date must be finite (got {decimal_year!r})")
        self.config = config
        self.params = MagParams.from_config(config)
        self.decimal_year = float(decimal_year)
        self._rng = rng
        self._fixed = config.field_ned_ut is not None
        self._at = (math.nan, math.nan, math.nan)
        self.field_ned_tesla = np.zeros(3)
        self._bn = (0.0, 0.0, 0.0)
        self.move_to(lat_rad, lon_rad, alt_m)
        self._noise: list[list[float]] = []
        self._idx = 0

    def move_to(self, lat_rad: float, lon_rad: float, alt_m: float) -> None:
        """The vehicle is at this geodetic position (rad, rad, m above the ellipsoid): the
        field is re-evaluated when it moved more than ``REEVALUATE_DISTANCE_M`` since the last
        evaluation. ValueError for a non-finite position or a latitude beyond ±π/2."""
        if not all(math.isfinite(v) for v in (lat_rad, lon_rad, alt_m)):
            raise ValueError("magnetometer position must be finite")
        if abs(lat_rad) > math.pi / 2:
            raise ValueError(f"latitude must be within ±π/2 rad (got {lat_rad!r})")
        here = (lat_rad, lon_rad, alt_m)
        if not moved_beyond(self._at, here, REEVALUATE_DISTANCE_M):
            return
        self._at = here
        if self._fixed:
            assert self.config.field_ned_ut is not None
            self.field_ned_tesla = np.array(self.config.field_ned_ut, dtype=np.float64) * 1e-6
        else:
            f = magnetic_field_ned_t(lat_rad, lon_rad, alt_m, self.decimal_year)
            self.field_ned_tesla = np.array(f.ned_t, dtype=np.float64)
        self._bn = (float(self.field_ned_tesla[0]), float(self.field_ned_tesla[1]),
                    float(self.field_ned_tesla[2]))

    def measure(self, time_us: int, q_nb: NDArray[np.float64]) -> MagSample:
        """One sample for attitude ``q_nb`` (4,) [w, x, y, z], body FRD -> NED."""
        if self._idx >= len(self._noise):
            noise = self._rng.standard_normal((BLOCK_STEPS, 3)) * self.params.noise_t
            self._noise = noise.tolist()
            self._idx = 0
        nx, ny, nz = self._noise[self._idx]
        self._idx += 1
        w, x, y, z = q_nb.tolist()
        bn, be, bd = self._bn
        # B_b = C_nbᵀ·B_n, C_nb from the Hamilton quaternion, written out on floats (cheaper
        # than NumPy on 3-vectors).
        bx = (1 - 2 * (y * y + z * z)) * bn + 2 * (x * y + w * z) * be + 2 * (x * z - w * y) * bd
        by = 2 * (x * y - w * z) * bn + (1 - 2 * (x * x + z * z)) * be + 2 * (y * z + w * x) * bd
        bz = 2 * (x * z + w * y) * bn + 2 * (y * z - w * x) * be + (1 - 2 * (x * x + y * y)) * bd
        hx, hy, hz = self.params.hard_iron_t
        mx, my, mz = bx + hx + nx, by + hy + ny, bz + hz + nz
        lsb = self.params.resolution_t
        if lsb > 0.0:
            mx, my, mz = round(mx / lsb) * lsb, round(my / lsb) * lsb, round(mz / lsb) * lsb
        return MagSample(time_us=time_us, field_b_tesla=np.array([mx, my, mz]))
