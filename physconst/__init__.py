"""Physical constants shared by the simulator (``sim``) and the filter (``fusion``).

``sim`` and ``fusion`` never import each other; the numbers both need are defined here once.
This module holds constants only: no state, no I/O, no imports of the project. SI units, and
the names carry them.
"""

from __future__ import annotations

import math
from typing import Final

# ---- WGS-84 (NIMA TR8350.2) -------------------------------------------------------------------
WGS84_A_M: Final = 6378137.0
"""Semi-major axis, m."""
WGS84_F: Final = 1.0 / 298.257223563
"""Flattening."""
WGS84_B_M: Final = WGS84_A_M * (1.0 - WGS84_F)
"""Semi-minor axis, m."""
WGS84_E2: Final = WGS84_F * (2.0 - WGS84_F)
"""First eccentricity squared."""
EARTH_RATE_RPS: Final = 7.292115e-5
"""Earth rotation rate with respect to inertial space, rad/s."""
WGS84_GM_M3PS2: Final = 3.986004418e14
"""Earth's gravitational constant GM (with atmosphere), m³/s²."""

# ---- standard gravity (3rd CGPM, 1901) ------------------------------------------------------
G0_MPS2: Final = 9.80665
"""Standard gravity, m/s² (also the g of MAVLink's mG and of datasheet 'g' and 'mg')."""

# ---- US Standard Atmosphere 1976 / ISO 2533 ---------------------------------------------------
ISA_R_AIR_JPKGK: Final = 287.05287
"""Specific gas constant of dry air, J/(kg·K)."""
ISA_T0_K: Final = 288.15
"""Sea-level standard temperature, K."""
ISA_P0_PA: Final = 101325.0
"""Sea-level standard pressure, Pa."""
ISA_L0_KPM: Final = -0.0065
"""Tropospheric temperature gradient dT/dH, K/m (P4's ``L``)."""
ISA_H0_M: Final = 0.0
"""Reference (base) altitude of the standard atmosphere, m (P4's ``H0``)."""
ISA_R0_GEOPOTENTIAL_M: Final = 6356766.0
"""Earth radius of the geopotential altitude definition, m."""
ISA_LAYER_BASE_M: Final = (0.0, 11000.0, 20000.0, 32000.0)
"""Base geopotential altitudes of the troposphere and the first three stratospheric layers, m."""
ISA_LAYER_LAPSE_KPM: Final = (ISA_L0_KPM, 0.0, 0.001, 0.0028)
"""Temperature gradient of each layer, K/m."""
ISA_H_MIN_M: Final = -5000.0
"""Lowest geopotential altitude of the model, m (the ICAO table starts at -5 km)."""
ISA_H_MAX_M: Final = 47000.0
"""Highest geopotential altitude of the model, m (top of the second stratospheric layer)."""


def _layer_bases() -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Base temperature and pressure of each layer, by continuity from sea level."""
    temps = [ISA_T0_K]
    pressures = [ISA_P0_PA]
    for i in range(1, len(ISA_LAYER_BASE_M)):
        dh = ISA_LAYER_BASE_M[i] - ISA_LAYER_BASE_M[i - 1]
        lapse = ISA_LAYER_LAPSE_KPM[i - 1]
        t_prev, p_prev = temps[-1], pressures[-1]
        t_next = t_prev + lapse * dh
        if lapse == 0.0:
            p_next = p_prev * math.exp(-G0_MPS2 * dh / (ISA_R_AIR_JPKGK * t_prev))
        else:
            p_next = p_prev * (t_next / t_prev) ** (-G0_MPS2 / (lapse * ISA_R_AIR_JPKGK))
        temps.append(t_next)
        pressures.append(p_next)
    return tuple(temps), tuple(pressures)


ISA_LAYER_T_K, ISA_LAYER_P_PA = _layer_bases()
"""Base temperature (K) and pressure (Pa) of each layer of :data:`ISA_LAYER_BASE_M`."""
