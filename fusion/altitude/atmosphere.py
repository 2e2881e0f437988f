"""The standard atmosphere for barometric altitude: pressure altitude, QNH, P4's non-standard
atmosphere, geopotential heights.

Pure scalar functions, SI units. ``fusion`` does not import ``sim``; the standard atmosphere
itself is :mod:`physconst.isa`, the one definition both use (here with range checks), and P4's
non-standard atmosphere is defined as in ``sim.atmosphere``; the tests check the round trip.

Heights
-------
The atmosphere is layered in **geopotential** altitude ``H`` (``r0·h/(r0 + h)``,
r0 = 6 356 766 m); navigation uses **geometric** height above mean sea level ``h``. The two
differ by ``h²/r0``: 0.16 m at 1 km, 16 m at 10 km. Everything below computes in geopotential
and converts to geometric MSL height only at the output (:func:`geometric_from_geopotential`).

Standard atmosphere (P4 eq. 1)
    ``Hp = (T0/L)·((Ps/P0)^(−L·R/g) − 1) + H0`` with ``L = −0.0065 K/m`` (temperature falling
    upwards), ``T0 = 288.15 K``, ``P0 = 101 325 Pa``, ``H0 = 0``; above 11 km the layer formulas of
    the US Standard Atmosphere 1976 up to 47 km (:func:`pressure_altitude_m`).
QNH (what pilots set)
    A mechanical altimeter with its sub-scale set to QNH shows ``Hp(Ps) − Hp(QNH)``: the pressure
    altitude with its zero shifted to the level where the pressure is QNH
    (:func:`qnh_altitude_m`). To first order this is P4's bias ``b`` with ``ΔP = QNH − P0``.
Non-standard atmosphere (P4 eq. 2-3)
    ``H = Hp + s·(Hp − H0) + b``, ``s = ΔT/T0``, ``b = (R·T0/g)·(ΔP/P0)``
    (:func:`calibrated_altitude_m`). In the hydrostatic atmosphere that this relation defines
    (the simulator's), the air temperature is ``T = T_isa(Hp)·(1 + s)``, so the sensed
    temperature gives ``s = T/T_isa(Hp) − 1`` directly (:func:`scale_from_temperature`).
P4 eq. 4 (sea-level values from the sensor)
    ``Ti = Ts + L·Hp``, ``Pi = Ps + ρ·g·Hp``. The temperature half (with the sign of ``L`` taken so
    that sea level is warmer) is sound. The pressure half is not usable as printed: it reduces the
    measured pressure to sea level over the *pressure altitude*, which by construction maps
    ``Ps`` back to ``P0`` (a tautology), and the linear hydrostatic step adds a spurious
    offset (−548 Pa, i.e. −46 m, at 1 km in a perfectly standard atmosphere).
    :func:`p4_sea_level_conditions` implements it for reference; hilnav estimates ``b`` (and
    ``s``) from GNSS height instead (:class:`BaroCalibration`), which is what ``ΔP`` really needs:
    an independent altitude.

GNSS height and the geoid
-------------------------
Receivers output height above the WGS-84 ellipsoid; ``h_msl = h_ell − N`` with ``N`` the geoid
undulation (−106 m ... +85 m worldwide). P4 saw a 60 m offset between calibrated baro
height and GNSS height and attributed it to the geoid. :meth:`BaroCalibration.update` takes
the reference explicitly (``reference="msl"`` or ``"ellipsoid"`` with ``geoid_undulation_m``):
feeding an ellipsoidal height as if it were MSL puts ``N`` into ``b`` (and reports a sea-level
pressure offset that is ``N·P0·g/(R·T0)`` ≈ 7 hPa wrong for ``N`` = 60 m).
"""

from __future__ import annotations

import math

from physconst import (
    G0_MPS2,
    ISA_H0_M,
    ISA_H_MAX_M,
    ISA_H_MIN_M,
    ISA_L0_KPM,
    ISA_P0_PA,
    ISA_R_AIR_JPKGK,
    ISA_T0_K,
    isa,
)
from physconst.isa import geometric_from_geopotential, geopotential_from_geometric

__all__ = [
    "BIAS_PER_PRESSURE_M_PER_PA",
    "P_MAX_PA",
    "P_MIN_PA",
    "calibrated_altitude_m",
    "check_pressure",
    "geometric_from_geopotential",
    "geopotential_from_geometric",
    "isa_pressure_pa",
    "isa_temperature_k",
    "nonstandard_scale_bias",
    "p4_sea_level_conditions",
    "pressure_altitude_m",
    "qnh_altitude_m",
    "scale_from_temperature",
    "sea_level_offsets",
]

BIAS_PER_PRESSURE_M_PER_PA = ISA_R_AIR_JPKGK * ISA_T0_K / (G0_MPS2 * ISA_P0_PA)
"""P4's ``b/ΔP = R·T0/(g·P0)``, m/Pa (8.32 m per hPa)."""

P_MAX_PA = isa.ISA_P_MAX_PA
"""Pressure at :data:`ISA_H_MIN_M` (≈ 177.7 kPa): the highest pressure the model accepts, Pa."""
P_MIN_PA = isa.ISA_P_MIN_PA
"""Pressure at :data:`ISA_H_MAX_M` (≈ 110.9 Pa): the lowest pressure the model accepts, Pa."""


def check_pressure(pressure_pa: float) -> None:
    """Raise ``ValueError`` unless ``pressure_pa`` is finite and inside the model's range.

    Parameters
    ----------
    pressure_pa : float
        Static pressure, Pa; valid range [:data:`P_MIN_PA`, :data:`P_MAX_PA`].

    Raises
    ------
    ValueError
        Not finite, ≤ 0, or outside the atmosphere model (−5 km ... 47 km).
    """
    if not math.isfinite(pressure_pa):
        raise ValueError(f"pressure_pa must be finite (got {pressure_pa!r})")
    if pressure_pa <= 0.0:
        raise ValueError(f"pressure_pa must be > 0 Pa (got {pressure_pa!r})")
    if not P_MIN_PA <= pressure_pa <= P_MAX_PA:
        raise ValueError(
            f"pressure_pa = {pressure_pa:.1f} Pa outside the atmosphere model range "
            f"[{P_MIN_PA:.1f}, {P_MAX_PA:.1f}] Pa (-5 km .. 47 km)"
        )


def _check_altitude(h_gp_m: float, name: str) -> None:
    if not math.isfinite(h_gp_m):
        raise ValueError(f"{name} must be finite (got {h_gp_m!r})")
    if not ISA_H_MIN_M <= h_gp_m <= ISA_H_MAX_M:
        raise ValueError(
            f"{name} = {h_gp_m:.1f} m outside the atmosphere model range "
            f"[{ISA_H_MIN_M:.0f}, {ISA_H_MAX_M:.0f}] m"
        )


def isa_temperature_k(h_gp_m: float) -> float:
    """Standard-atmosphere temperature (K) at geopotential altitude ``h_gp_m`` (m)
    (:func:`physconst.isa.isa_temperature_k`).

    Raises
    ------
    ValueError
        Altitude not finite or outside [−5000, 47000] m.
    """
    _check_altitude(h_gp_m, "h_gp_m")
    return isa.isa_temperature_k(h_gp_m)


def isa_pressure_pa(h_gp_m: float) -> float:
    """Standard-atmosphere static pressure (Pa) at geopotential altitude ``h_gp_m`` (m)
    (:func:`physconst.isa.isa_pressure_pa`).

    Raises
    ------
    ValueError
        Altitude not finite or outside [−5000, 47000] m.
    """
    _check_altitude(h_gp_m, "h_gp_m")
    return isa.isa_pressure_pa(h_gp_m)


def pressure_altitude_m(pressure_pa: float) -> float:
    """Pressure altitude ``Hp`` (m, geopotential) of a static pressure (Pa), refusing pressures
    outside the model: :func:`physconst.isa.pressure_altitude_m` (P4 eq. 1 in the troposphere,
    the layers of the US Standard Atmosphere 1976 above 11 km; 0 at 101 325 Pa).

    Raises
    ------
    ValueError
        Pressure ≤ 0, not finite, or outside the model range (:func:`check_pressure`).
    """
    check_pressure(pressure_pa)
    return isa.pressure_altitude_m(pressure_pa)


def qnh_altitude_m(pressure_pa: float, qnh_pa: float) -> float:
    """Altitude shown by an altimeter set to QNH: ``Hp(Ps) − Hp(QNH)`` (geopotential, m).

    Parameters
    ----------
    pressure_pa : float
        Static pressure, Pa.
    qnh_pa : float
        Altimeter setting (sea-level pressure reduced with the standard atmosphere), Pa;
        plausible values 87 000 ... 108 500 Pa.

    Raises
    ------
    ValueError
        Bad pressure, or ``qnh_pa`` outside 80 000 ... 110 000 Pa.
    """
    if not (math.isfinite(qnh_pa) and 80000.0 <= qnh_pa <= 110000.0):
        raise ValueError(f"qnh_pa must be within 80000 .. 110000 Pa (got {qnh_pa!r})")
    return pressure_altitude_m(pressure_pa) - pressure_altitude_m(qnh_pa)


def nonstandard_scale_bias(sea_level_dt_k: float, sea_level_dp_pa: float) -> tuple[float, float]:
    """P4 eq. 3: scale ``s = ΔT/T0`` (-) and bias ``b = (R·T0/g)·(ΔP/P0)`` (m).

    Parameters
    ----------
    sea_level_dt_k : float
        Sea-level temperature offset from standard, K (> −T0).
    sea_level_dp_pa : float
        Sea-level pressure offset from standard, Pa.

    Raises
    ------
    ValueError
        Offsets not finite, or ``ΔT ≤ −T0``.
    """
    if not (math.isfinite(sea_level_dt_k) and math.isfinite(sea_level_dp_pa)):
        raise ValueError("sea_level_dt_k and sea_level_dp_pa must be finite")
    if sea_level_dt_k <= -ISA_T0_K:
        raise ValueError(f"sea_level_dt_k must be > {-ISA_T0_K} K (got {sea_level_dt_k!r})")
    return sea_level_dt_k / ISA_T0_K, BIAS_PER_PRESSURE_M_PER_PA * sea_level_dp_pa


def sea_level_offsets(scale: float, bias_m: float) -> tuple[float, float]:
    """Inverse of :func:`nonstandard_scale_bias`: ``(ΔT, ΔP)`` in (K, Pa) from ``(s, b)``."""
    return scale * ISA_T0_K, bias_m / BIAS_PER_PRESSURE_M_PER_PA


def calibrated_altitude_m(pressure_altitude: float, scale: float, bias_m: float) -> float:
    """P4 eq. 2: ``H = Hp + s·(Hp − H0) + b`` (geopotential, m).

    Parameters
    ----------
    pressure_altitude : float
        ``Hp``, m.
    scale : float
        ``s``, dimensionless.
    bias_m : float
        ``b``, m.
    """
    return pressure_altitude + scale * (pressure_altitude - ISA_H0_M) + bias_m


def scale_from_temperature(temperature_k: float, pressure_altitude: float) -> float:
    """Scale ``s`` from the air temperature at the sensor, ``s = T/T_isa(Hp) − 1``.

    Exact in the hydrostatic atmosphere defined by P4 eq. 2 (``T = T_isa(Hp)·(1 + s)``). P4's
    eq. 4 (``ΔT = Ts − L·Hp − T0``, ``s = ΔT/T0``) is the same to first order; it differs by the
    factor ``T_isa(Hp)/T0`` (2 % at 1 km).

    Parameters
    ----------
    temperature_k : float
        Air temperature at the sensor, K (> 0). A self-heated sensor biases ``s`` by
        ``ΔT_sensor/T_isa`` (0.35 % per K: 3.5 m at 1 km).
    pressure_altitude : float
        ``Hp`` of the same sample, m.

    Raises
    ------
    ValueError
        Temperature not finite or ≤ 0.
    """
    if not (math.isfinite(temperature_k) and temperature_k > 0.0):
        raise ValueError(f"temperature_k must be finite and > 0 K (got {temperature_k!r})")
    return temperature_k / isa_temperature_k(pressure_altitude) - 1.0


def p4_sea_level_conditions(pressure_pa: float, temperature_k: float) -> tuple[float, float]:
    """P4 eq. 4 as printed (sign of ``L`` fixed): sea-level ``(Ti, Pi)`` from one sample.

    ``Ti = Ts + 0.0065·Hp``, ``Pi = Ps + ρ·g·Hp`` with ``ρ = Ps/(R·Ts)``. Kept for reference
    and for the tests that document its flaw (see the module docstring): ``Pi − P0`` is not the
    sea-level pressure offset. Do not use ``Pi`` for calibration.

    Returns
    -------
    ti_k, pi_pa : float
        Sea-level temperature (K) and pressure (Pa) per P4 eq. 4.
    """
    hp = pressure_altitude_m(pressure_pa)
    if not (math.isfinite(temperature_k) and temperature_k > 0.0):
        raise ValueError(f"temperature_k must be finite and > 0 K (got {temperature_k!r})")
    rho = pressure_pa / (ISA_R_AIR_JPKGK * temperature_k)
    return temperature_k - ISA_L0_KPM * hp, pressure_pa + rho * G0_MPS2 * hp
