"""The standard atmosphere (ICAO / US Standard Atmosphere 1976, -5 km to 47 km): temperature
and pressure of a geopotential altitude, and its inverse, the pressure altitude.

The one definition of pressure altitude for the simulator's atmosphere (``sim.atmosphere``),
the filter's barometric height and altitude channel (``fusion.aiding.baro``,
``fusion.altitude.atmosphere``) and the ``pressure_alt`` field the MAVLink encoder sends.

Each layer ``i`` has a base altitude ``H_i``, temperature ``T_i``, pressure ``p_i`` and lapse
rate ``L_i`` (:data:`~physconst.ISA_LAYER_BASE_M` and the tables next to it)::

    T(H) = T_i + L_i (H - H_i)
    p(H) = p_i (T(H) / T_i)^(-g0 / (L_i R))          L_i != 0
    p(H) = p_i exp(-g0 (H - H_i) / (R T_i))           L_i == 0 (isothermal)

In the troposphere the inverse is paper P4's ``Hp = (T0/L)((Ps/P0)^(-L R/g0) - 1) + H0``.

Altitudes are **geopotential** (:func:`geopotential_from_geometric` converts a geometric height
above mean sea level; the two differ by 0.16 m at 1 km). Scalar functions on floats with
``math``, so a result does not depend on who computes it; they do not check the model's range
(below -5 km the tropospheric layer and above 47 km the top layer extend): callers that must
refuse out-of-range input check it against :data:`ISA_P_MIN_PA` / :data:`ISA_P_MAX_PA` or
:data:`~physconst.ISA_H_MIN_M` / :data:`~physconst.ISA_H_MAX_M`.
"""

from __future__ import annotations

import math
from typing import Final, TypeVar

import numpy as np
from numpy.typing import NDArray

from physconst import (
    G0_MPS2,
    ISA_H_MAX_M,
    ISA_H_MIN_M,
    ISA_L0_KPM,
    ISA_LAYER_BASE_M,
    ISA_LAYER_LAPSE_KPM,
    ISA_LAYER_P_PA,
    ISA_LAYER_T_K,
    ISA_R0_GEOPOTENTIAL_M,
    ISA_R_AIR_JPKGK,
)

FloatOrArray = TypeVar("FloatOrArray", float, NDArray[np.float64])

ISA_TROPOSPHERE_EXPONENT: Final = -ISA_L0_KPM * ISA_R_AIR_JPKGK / G0_MPS2
"""Exponent ``L R / g0`` (≈ 0.1902632) of the tropospheric pressure altitude
``Hp = (T0/L)(1 - (p/p0)^(L R / g0))``, ``L`` = 0.0065 K/m the temperature fall with height.
``R`` is the specific gas constant of dry air, the universal gas constant over the molar mass of
air (``R*/M`` = 8.31432 J/(mol K) / 0.0289644 kg/mol in the 1976 standard), so this is the
``R* L / (g0 M)`` of the textbooks; its six-figure rounding 0.190263 is the constant many
pressure-altitude formulas write out."""


def _layer_of_altitude(alt_gp_m: float) -> int:
    i = 0
    while i + 1 < len(ISA_LAYER_BASE_M) and alt_gp_m >= ISA_LAYER_BASE_M[i + 1]:
        i += 1
    return i


def _layer_of_pressure(pressure_pa: float) -> int:
    i = 0
    while i + 1 < len(ISA_LAYER_P_PA) and pressure_pa <= ISA_LAYER_P_PA[i + 1]:
        i += 1
    return i


def isa_temperature_k(alt_gp_m: float) -> float:
    """Standard-atmosphere temperature, K, at geopotential altitude ``alt_gp_m`` (m)."""
    i = _layer_of_altitude(alt_gp_m)
    return ISA_LAYER_T_K[i] + ISA_LAYER_LAPSE_KPM[i] * (alt_gp_m - ISA_LAYER_BASE_M[i])


def isa_pressure_pa(alt_gp_m: float) -> float:
    """Standard-atmosphere static pressure, Pa, at geopotential altitude ``alt_gp_m`` (m).

    101 325 Pa at 0 m, 22 632.04 Pa at 11 000 m; the inverse of :func:`pressure_altitude_m`.
    """
    i = _layer_of_altitude(alt_gp_m)
    dh = alt_gp_m - ISA_LAYER_BASE_M[i]
    lapse = ISA_LAYER_LAPSE_KPM[i]
    base_t = ISA_LAYER_T_K[i]
    if lapse == 0.0:
        return ISA_LAYER_P_PA[i] * math.exp(-G0_MPS2 * dh / (ISA_R_AIR_JPKGK * base_t))
    t = base_t + lapse * dh
    return ISA_LAYER_P_PA[i] * (t / base_t) ** (-G0_MPS2 / (lapse * ISA_R_AIR_JPKGK))


def pressure_altitude_m(pressure_pa: float) -> float:
    """Pressure altitude ``Hp``: the standard-atmosphere geopotential altitude of a pressure.

    Parameters
    ----------
    pressure_pa : float
        Static pressure, Pa.

    Returns
    -------
    float
        ``Hp``, m (0 at 101 325 Pa, 11 000 at 22 632.04 Pa); NaN for a pressure that is not
        ``> 0`` (NaN included).
    """
    if not pressure_pa > 0.0:
        return math.nan
    i = _layer_of_pressure(pressure_pa)
    base_h, base_t, base_p = ISA_LAYER_BASE_M[i], ISA_LAYER_T_K[i], ISA_LAYER_P_PA[i]
    lapse = ISA_LAYER_LAPSE_KPM[i]
    if lapse == 0.0:
        return base_h - (ISA_R_AIR_JPKGK * base_t / G0_MPS2) * math.log(pressure_pa / base_p)
    return base_h + (base_t / lapse) * (
        (pressure_pa / base_p) ** (-lapse * ISA_R_AIR_JPKGK / G0_MPS2) - 1.0
    )


ISA_P_MAX_PA: Final = isa_pressure_pa(ISA_H_MIN_M)
"""Pressure at :data:`~physconst.ISA_H_MIN_M` (≈ 177.7 kPa): the highest in the model, Pa."""
ISA_P_MIN_PA: Final = isa_pressure_pa(ISA_H_MAX_M)
"""Pressure at :data:`~physconst.ISA_H_MAX_M` (≈ 110.9 Pa): the lowest in the model, Pa."""


def geopotential_from_geometric(h_m: FloatOrArray) -> FloatOrArray:
    """Geopotential altitude ``r0 h / (r0 + h)``, m, of a geometric height above mean sea level
    (m; float or array of any shape, r0 = 6 356 766 m)."""
    return ISA_R0_GEOPOTENTIAL_M * h_m / (ISA_R0_GEOPOTENTIAL_M + h_m)


def geometric_from_geopotential(h_gp_m: FloatOrArray) -> FloatOrArray:
    """Geometric height above mean sea level ``r0 H / (r0 - H)``, m, of a geopotential altitude
    (m; float or array of any shape); the inverse of :func:`geopotential_from_geometric`."""
    return ISA_R0_GEOPOTENTIAL_M * h_gp_m / (ISA_R0_GEOPOTENTIAL_M - h_gp_m)
