"""Standard and non-standard atmosphere: pressure, temperature and density versus altitude.

Pure functions, SI units. Every function accepts a Python float or a NumPy array and returns
the same kind (a float for a float, an array of the same shape for an array).

Model
-----
*Standard atmosphere*: the ICAO / US Standard Atmosphere 1976 layers from -5 km to 47 km
geopotential altitude (troposphere, tropopause, two lower-stratosphere layers). The
altitude argument of the ``isa_*`` functions is **geopotential** altitude ``H``; convert a
geometric height above mean sea level with :func:`geopotential_from_geometric` (the two differ
by ``h²/r0``: 0.16 m at 1 km, 16 m at 10 km). Within the troposphere the inverse is exactly
the pressure-altitude formula of paper P4::

    Hp = (T0 / L) * ((Ps / P0) ** (-L * R / g) - 1) + H0,   L = -0.0065 K/m, H0 = 0.

*Non-standard atmosphere* (paper P4): with sea-level temperature and pressure offsets
``dT``, ``dP`` from standard, the true altitude ``H`` and the pressure altitude ``Hp`` are
related by::

    H = Hp + s * (Hp - H0) + b,   s = dT / T0,   b = (R * T0 / g) * (dP / P0).

hilnav *defines* its simulated non-standard atmosphere by this relation, used in both
directions: the pressure at altitude ``H`` is the standard pressure at
``Hp = (H - b + s * H0) / (1 + s)``, so :func:`pressure_from_altitude` and
:func:`altitude_from_pressure` round-trip exactly and a fusion filter that inverts P4's
relation sees no model error beyond the sensor's own. The temperature that keeps this
atmosphere hydrostatic (``dp/dH = -p g / (R T)``) is ``T(H) = T_isa(Hp) * (1 + s)``, which is
``T0 + dT`` at sea level when ``dP = 0``; with ``dP`` ≠ 0 it is ``T0 + dT - L*b`` there (P4's
bias shifts the whole profile by ``b``: 0.5 K for 9 hPa). The relation is exact for a pure
temperature offset (same lapse rate, warmer sea level) and first-order in ``dP / P0`` for a
pressure offset: against an atmosphere with the same lapse rate and a sea-level pressure
10 hPa higher it differs by 0.3 m at sea level, 2 m at 1 km and 6 m at 3 km.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import cast

import numpy as np
from numpy.typing import NDArray

from physconst import (
    G0_MPS2,
    ISA_H0_M,
    ISA_H_MAX_M,
    ISA_H_MIN_M,
    ISA_P0_PA,
    ISA_R_AIR_JPKGK,
    ISA_T0_K,
    isa,
)
from physconst.isa import FloatOrArray, geometric_from_geopotential, geopotential_from_geometric

__all__ = [
    "P_MAX_PA",
    "P_MIN_PA",
    "FloatOrArray",
    "TroposphereBaro",
    "altitude_from_pressure",
    "altitude_from_pressure_altitude",
    "density_from_altitude",
    "geometric_from_geopotential",
    "geopotential_from_geometric",
    "isa_pressure_pa",
    "isa_temperature_k",
    "nonstandard_scale_bias",
    "pressure_altitude_from_altitude",
    "pressure_altitude_m",
    "pressure_from_altitude",
    "temperature_from_altitude",
]

P_MAX_PA = isa.ISA_P_MAX_PA
"""Pressure at :data:`ISA_H_MIN_M`, Pa (highest pressure the model accepts)."""
P_MIN_PA = isa.ISA_P_MIN_PA
"""Pressure at :data:`ISA_H_MAX_M`, Pa (lowest pressure the model accepts)."""


def _each(f: Callable[[float], float], x: FloatOrArray) -> FloatOrArray:
    """``f`` (one of :mod:`physconst.isa`'s scalar functions) on a float, or on every element of
    an array: element by element, so an array gives the same bits as its floats one by one."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0:
        return cast(FloatOrArray, f(float(arr)))
    out = np.fromiter((f(v) for v in arr.ravel().tolist()), dtype=np.float64, count=arr.size)
    return cast(FloatOrArray, out.reshape(arr.shape))


def _check_altitude(h: NDArray[np.float64], name: str) -> None:
    if not np.all(np.isfinite(h)):
        raise ValueError(f"{name} must be finite")
    if np.any(h < ISA_H_MIN_M) or np.any(h > ISA_H_MAX_M):
        raise ValueError(
            f"{name} outside the atmosphere model range [{ISA_H_MIN_M:.0f}, {ISA_H_MAX_M:.0f}] m "
            f"(got {float(np.min(h)):.1f} .. {float(np.max(h)):.1f} m)"
        )


def _check_pressure(p: NDArray[np.float64]) -> None:
    if not np.all(np.isfinite(p)):
        raise ValueError("pressure must be finite")
    if np.any(p <= 0.0):
        raise ValueError(f"pressure must be > 0 Pa (got {float(np.min(p))!r})")
    if np.any(p < P_MIN_PA) or np.any(p > P_MAX_PA):
        raise ValueError(
            f"pressure outside the atmosphere model range [{P_MIN_PA:.1f}, {P_MAX_PA:.1f}] Pa "
            f"(got {float(np.min(p)):.1f} .. {float(np.max(p)):.1f} Pa)"
        )


def isa_temperature_k(h_gp_m: FloatOrArray) -> FloatOrArray:
    """Standard-atmosphere temperature (:func:`physconst.isa.isa_temperature_k`), range-checked.

    Parameters
    ----------
    h_gp_m : float or ndarray, any shape
        Geopotential altitude, m, within [-5000, 47000].

    Returns
    -------
    float or ndarray, same shape
        Temperature, K.

    Raises
    ------
    ValueError
        Altitude outside the model range or not finite.
    """
    _check_altitude(np.asarray(h_gp_m, dtype=np.float64), "altitude")
    return _each(isa.isa_temperature_k, h_gp_m)


def isa_pressure_pa(h_gp_m: FloatOrArray) -> FloatOrArray:
    """Standard-atmosphere static pressure (:func:`physconst.isa.isa_pressure_pa`), range-checked.

    Parameters
    ----------
    h_gp_m : float or ndarray, any shape
        Geopotential altitude, m, within [-5000, 47000].

    Returns
    -------
    float or ndarray, same shape
        Static pressure, Pa (101325 at 0 m, 22632.04 at 11 000 m).

    Raises
    ------
    ValueError
        Altitude outside the model range or not finite.
    """
    _check_altitude(np.asarray(h_gp_m, dtype=np.float64), "altitude")
    return _each(isa.isa_pressure_pa, h_gp_m)


def pressure_altitude_m(pressure_pa: FloatOrArray) -> FloatOrArray:
    """Pressure altitude (:func:`physconst.isa.pressure_altitude_m`), range-checked.

    In the troposphere this is P4's formula
    ``Hp = (T0/L)·((Ps/P0)^(−L·R/g) − 1) + H0``; above 11 km the matching layer formula.

    Parameters
    ----------
    pressure_pa : float or ndarray, any shape
        Static pressure, Pa.

    Returns
    -------
    float or ndarray, same shape
        Pressure altitude ``Hp``, m (geopotential).

    Raises
    ------
    ValueError
        Pressure ≤ 0, not finite, or outside the model range (about 111 Pa .. 177.7 kPa).
    """
    _check_pressure(np.asarray(pressure_pa, dtype=np.float64))
    return _each(isa.pressure_altitude_m, pressure_pa)


def nonstandard_scale_bias(sea_level_dt_k: float, sea_level_dp_pa: float) -> tuple[float, float]:
    """P4's scale and bias of the non-standard atmosphere.

    Parameters
    ----------
    sea_level_dt_k : float
        Sea-level temperature offset from standard ``dT``, K (> −T0).
    sea_level_dp_pa : float
        Sea-level pressure offset from standard ``dP``, Pa.

    Returns
    -------
    s : float
        Scale ``dT / T0``, dimensionless.
    b : float
        Bias ``(R·T0/g)·(dP/P0)``, m.

    Raises
    ------
    ValueError
        Offsets not finite, or ``dT ≤ −T0`` (the relation would fold).
    """
    if not (math.isfinite(sea_level_dt_k) and math.isfinite(sea_level_dp_pa)):
        raise ValueError("sea-level temperature and pressure offsets must be finite")
    if sea_level_dt_k <= -ISA_T0_K:
        raise ValueError(f"sea-level temperature offset must be > {-ISA_T0_K} K")
    s = sea_level_dt_k / ISA_T0_K
    b = (ISA_R_AIR_JPKGK * ISA_T0_K / G0_MPS2) * (sea_level_dp_pa / ISA_P0_PA)
    return s, b


def altitude_from_pressure_altitude(
    pressure_altitude: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """True altitude from pressure altitude in the non-standard atmosphere (P4).

    ``H = Hp + s·(Hp − H0) + b``.

    Parameters
    ----------
    pressure_altitude : float or ndarray, any shape
        Pressure altitude ``Hp``, m.
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard.

    Returns
    -------
    float or ndarray, same shape
        Altitude ``H``, m (geopotential).
    """
    s, b = nonstandard_scale_bias(sea_level_dt_k, sea_level_dp_pa)
    return cast(FloatOrArray, pressure_altitude + s * (pressure_altitude - ISA_H0_M) + b)


def pressure_altitude_from_altitude(
    altitude_m: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """Inverse of :func:`altitude_from_pressure_altitude`: ``Hp = (H − b + s·H0)/(1 + s)``.

    Parameters
    ----------
    altitude_m : float or ndarray, any shape
        Altitude ``H``, m (geopotential).
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard.

    Returns
    -------
    float or ndarray, same shape
        Pressure altitude ``Hp``, m.
    """
    s, b = nonstandard_scale_bias(sea_level_dt_k, sea_level_dp_pa)
    return cast(FloatOrArray, (altitude_m - b + s * ISA_H0_M) / (1.0 + s))


def pressure_from_altitude(
    altitude_m: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """Static pressure at an altitude in the (non-)standard atmosphere.

    Parameters
    ----------
    altitude_m : float or ndarray, any shape
        Geopotential altitude ``H``, m.
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard; zero gives ISA.

    Returns
    -------
    float or ndarray, same shape
        Static pressure, Pa.

    Raises
    ------
    ValueError
        The implied pressure altitude is outside the model range, or bad offsets.
    """
    hp = pressure_altitude_from_altitude(altitude_m, sea_level_dt_k, sea_level_dp_pa)
    return isa_pressure_pa(hp)


def altitude_from_pressure(
    pressure_pa: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """Altitude of a static pressure in the (non-)standard atmosphere (P4, both steps).

    Parameters
    ----------
    pressure_pa : float or ndarray, any shape
        Static pressure, Pa (> 0).
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard.

    Returns
    -------
    float or ndarray, same shape
        Geopotential altitude ``H``, m.

    Raises
    ------
    ValueError
        Pressure ≤ 0 or outside the model range, or bad offsets.
    """
    hp = pressure_altitude_m(pressure_pa)
    return altitude_from_pressure_altitude(hp, sea_level_dt_k, sea_level_dp_pa)


def temperature_from_altitude(
    altitude_m: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """Air temperature of the (non-)standard atmosphere, ``T_isa(Hp)·(1 + dT/T0)``.

    This is the temperature that makes the P4 atmosphere hydrostatic; at sea level it is
    ``T0 + dT`` when ``dP = 0`` and ``T0 + dT − L·b`` otherwise (the bias ``b`` shifts the
    whole profile).

    Parameters
    ----------
    altitude_m : float or ndarray, any shape
        Geopotential altitude ``H``, m.
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard.

    Returns
    -------
    float or ndarray, same shape
        Temperature, K.
    """
    s, _ = nonstandard_scale_bias(sea_level_dt_k, sea_level_dp_pa)
    hp = pressure_altitude_from_altitude(altitude_m, sea_level_dt_k, sea_level_dp_pa)
    return cast(FloatOrArray, isa_temperature_k(hp) * (1.0 + s))


def density_from_altitude(
    altitude_m: FloatOrArray, sea_level_dt_k: float = 0.0, sea_level_dp_pa: float = 0.0
) -> FloatOrArray:
    """Air density ``p / (R·T)`` of the (non-)standard atmosphere.

    Parameters
    ----------
    altitude_m : float or ndarray, any shape
        Geopotential altitude ``H``, m.
    sea_level_dt_k, sea_level_dp_pa : float
        Sea-level temperature (K) and pressure (Pa) offsets from standard.

    Returns
    -------
    float or ndarray, same shape
        Density, kg/m³ (1.225 at sea level, ISA).
    """
    p = pressure_from_altitude(altitude_m, sea_level_dt_k, sea_level_dp_pa)
    t = temperature_from_altitude(altitude_m, sea_level_dt_k, sea_level_dp_pa)
    return cast(FloatOrArray, p / (ISA_R_AIR_JPKGK * t))


class TroposphereBaro:
    """Scalar pressure / temperature for the barometer's hot loop.

    Same model as :func:`pressure_from_altitude` / :func:`temperature_from_altitude` with
    fixed ``dT``; ``dP`` may change per call (a weather front). Works on floats, without the
    array functions' checks inside the model's range (outside it those raise).

    Parameters
    ----------
    sea_level_dt_k : float
        Sea-level temperature offset from standard, K.
    """

    __slots__ = ("_s", "_t_scale")

    def __init__(self, sea_level_dt_k: float) -> None:
        s, _ = nonstandard_scale_bias(sea_level_dt_k, 0.0)
        self._s = s
        self._t_scale = 1.0 + s

    def pressure_temperature(
        self, altitude_m: float, sea_level_dp_pa: float
    ) -> tuple[float, float]:
        """Pressure (Pa) and temperature (K) at geopotential altitude ``altitude_m`` (m)."""
        b = (ISA_R_AIR_JPKGK * ISA_T0_K / G0_MPS2) * (sea_level_dp_pa / ISA_P0_PA)
        hp = (altitude_m - b + self._s * ISA_H0_M) / self._t_scale
        if not ISA_H_MIN_M <= hp <= ISA_H_MAX_M:  # out of range (or NaN): the checked form raises
            return float(isa_pressure_pa(hp)), float(isa_temperature_k(hp)) * self._t_scale
        return isa.isa_pressure_pa(hp), isa.isa_temperature_k(hp) * self._t_scale
