"""Pitot-static relations shared by the simulator's pitot model and the filter's airspeed fusion.

A pitot-static probe measures the *impact pressure* ``q_c = p_total - p_static`` (what a
differential-pressure sensor such as the TE MS4525DO or Sensirion SDP3x reads). For subsonic
flow the isentropic relation gives the Mach number from ``q_c`` and the static pressure ``p``:

    M = sqrt( 2/(γ-1) · ((q_c/p + 1)^((γ-1)/γ) - 1) ),        TAS = M · sqrt(γ R T)

(Anderson, *Introduction to Flight*, 7th ed., §4.11; the "Saint-Venant" relation), with
``T`` the static air temperature. Its inverse is :func:`impact_pressure_pa`. At 50 m/s near
sea level ``q_c`` exceeds the incompressible dynamic pressure ``ρ V²/2`` by ``M²/4`` ≈ 0.5 %.

Pure functions on floats, SI units; no state, no I/O.
"""

from __future__ import annotations

import math
from typing import Final

from physconst import ISA_P0_PA, ISA_R_AIR_JPKGK, ISA_T0_K

GAMMA_AIR: Final = 1.4
"""Ratio of specific heats of dry air (ISO 2533)."""

_K: Final = (GAMMA_AIR - 1.0) / GAMMA_AIR  # 2/7
_M2: Final = 2.0 / (GAMMA_AIR - 1.0)  # 5


def air_density_kgpm3(static_pressure_pa: float, temperature_k: float) -> float:
    """Density of dry air from the ideal-gas law, kg/m³."""
    return static_pressure_pa / (ISA_R_AIR_JPKGK * temperature_k)


def speed_of_sound_mps(temperature_k: float) -> float:
    """Speed of sound in dry air at static temperature ``temperature_k``, m/s."""
    return math.sqrt(GAMMA_AIR * ISA_R_AIR_JPKGK * temperature_k)


def impact_pressure_pa(
    true_airspeed_mps: float, static_pressure_pa: float, temperature_k: float
) -> float:
    """Impact pressure ``q_c`` (Pa) of subsonic flow at true airspeed ``true_airspeed_mps``."""
    mach = true_airspeed_mps / speed_of_sound_mps(temperature_k)
    # (1 + x)^a - 1 as expm1(a log1p(x)): no cancellation at low airspeed
    return static_pressure_pa * math.expm1(math.log1p(mach * mach / _M2) / _K)


def true_airspeed_mps(
    impact_pressure_pa: float, static_pressure_pa: float, temperature_k: float
) -> float:
    """True airspeed (m/s) from impact pressure, static pressure and static temperature.

    A non-positive impact pressure gives 0 (the probe reads no flow).
    """
    if impact_pressure_pa <= 0.0:
        return 0.0
    ratio = math.expm1(_K * math.log1p(impact_pressure_pa / static_pressure_pa))
    return math.sqrt(_M2 * ratio) * speed_of_sound_mps(temperature_k)


def calibrated_airspeed_mps(impact_pressure_pa: float) -> float:
    """Calibrated airspeed (m/s) of an impact pressure: the true airspeed that gives it in the
    ISA sea-level atmosphere (what an airspeed indicator shows)."""
    return true_airspeed_mps(impact_pressure_pa, ISA_P0_PA, ISA_T0_K)
