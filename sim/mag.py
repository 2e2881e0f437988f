"""Magnetometer model: a constant Earth field rotated into body axes, noise, hard iron.

Earth field
-----------
No model file is downloaded: the field is the **centred tilted dipole** given by the
first-degree IGRF Gauss coefficients (IGRF-13, epoch 2020.0, nT)::

    g10 = -29404.8,  g11 = -1450.9,  h11 = 4652.5,  reference radius a = 6371.2 km

whose potential ``V = a·(a/r)²·(g10·cosθ + (g11·cosφ + h11·sinφ)·sinθ)`` gives, in ECEF,
``B = (a/r)³·(3·(g·r̂)·r̂ − g)`` with ``g = (g11, h11, g10)``; it is rotated to the local NED
frame with the geodetic latitude. The dipole carries about 90 % of the main field's energy at
the surface but ignores the higher degrees: at 47°N 8°E it gives 48.4 µT and an inclination of
65.2° (IGRF 2020: ≈ 48 µT, ≈ 63.5°) but a declination of −13.7° where the real one is about
+3°: the non-dipole field matters for declination. Secular variation is ignored
(tens of nT per year). Where the exact local field matters, give ``field_ned_ut`` (e.g. from
a WMM/IGRF calculator) and the dipole is not used.

The field is computed once, for the start location, and held constant: over a flight of a
few hundred km it changes by a few per cent, which is below what hilnav uses the
magnetometer for (heading aiding).

Measurement: ``m_b = Q( C_bn·B_n + hard_iron + n )``, ``n ~ N(0, noise²)`` per axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim._sensor_common import (
    BLOCK_STEPS,
    Finite,
    NonNegative,
    SensorConfigModel,
    ecef_from_geodetic_m,
)
from sim.samples import MagSample

IGRF_EPOCH = 2020.0
"""Epoch of the dipole coefficients below (IGRF-13)."""
IGRF_G10_NT = -29404.8
IGRF_G11_NT = -1450.9
IGRF_H11_NT = 4652.5
IGRF_REFERENCE_RADIUS_M = 6371200.0


class MagConfig(SensorConfigModel):
    """Magnetometer figures.

    Attributes
    ----------
    noise_ut : white noise per axis per sample, 1σ, µT.
    resolution_ut : output LSB, µT (0 = none).
    hard_iron_ut : constant offset in body axes (x, y, z), µT.
    field_ned_ut : Earth field in NED, µT, overriding the IGRF dipole; None = use the dipole.
    """

    noise_ut: NonNegative
    resolution_ut: NonNegative = 0.0
    hard_iron_ut: tuple[Finite, Finite, Finite] = (0.0, 0.0, 0.0)
    field_ned_ut: tuple[Finite, Finite, Finite] | None = None


def dipole_field_ned_tesla(lat_rad: float, lon_rad: float, alt_m: float) -> NDArray[np.float64]:
    """Earth magnetic field of the IGRF-13 (2020.0) centred dipole, in local NED.

    Parameters
    ----------
    lat_rad, lon_rad : float
        Geodetic latitude and longitude, rad (WGS-84).
    alt_m : float
        Height, m (MSL is used as ellipsoidal height; the difference is immaterial here).

    Returns
    -------
    ndarray, shape (3,)
        Field ``[B_N, B_E, B_D]``, tesla.
    """
    x, y, z = ecef_from_geodetic_m(lat_rad, lon_rad, alt_m)
    r = math.sqrt(x * x + y * y + z * z)
    rx, ry, rz = x / r, y / r, z / r
    g = (IGRF_G11_NT, IGRF_H11_NT, IGRF_G10_NT)
    gr = g[0] * rx + g[1] * ry + g[2] * rz
    k = (IGRF_REFERENCE_RADIUS_M / r) ** 3
    b_e = np.array([3.0 * gr * rx - g[0], 3.0 * gr * ry - g[1], 3.0 * gr * rz - g[2]]) * k
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    so, co = math.sin(lon_rad), math.cos(lon_rad)
    c_ne = np.array(
        [
            [-sl * co, -sl * so, cl],
            [-so, co, 0.0],
            [-cl * co, -cl * so, -sl],
        ]
    )
    return np.asarray(c_ne @ b_e * 1e-9, dtype=np.float64)


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
        Start location (geodetic rad, MSL m) whose Earth field is held constant.

    Attributes
    ----------
    field_ned_tesla : ndarray (3,)
        The Earth field used, NED, tesla.
    """

    def __init__(
        self,
        config: MagConfig,
        rng: np.random.Generator,
        lat_rad: float,
        lon_rad: float,
        alt_m: float,
    ) -> None:
        if not all(math.isfinite(v) for v in (lat_rad, lon_rad, alt_m)):
            raise ValueError("magnetometer start location must be finite")
        if abs(lat_rad) > math.pi / 2:
            raise ValueError(f"latitude must be within ±π/2 rad (got {lat_rad!r})")
        self.config = config
        self.params = MagParams.from_config(config)
        self._rng = rng
        if config.field_ned_ut is not None:
            self.field_ned_tesla = np.array(config.field_ned_ut, dtype=np.float64) * 1e-6
        else:
            self.field_ned_tesla = dipole_field_ned_tesla(lat_rad, lon_rad, alt_m)
        self._bn = tuple(float(v) for v in self.field_ned_tesla)
        self._noise: list[list[float]] = []
        self._idx = 0

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
