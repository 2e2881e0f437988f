"""Barometric altitude: standard atmosphere, QNH, P4's non-standard calibration, baro health.

Pure scalar functions and small steppable objects, SI units. ``fusion`` does not import ``sim``;
the inverse formulas here are written to match ``sim.atmosphere`` exactly (same constants, same
layers, same definition of P4's non-standard atmosphere), and the tests check the round trip.

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
from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, PositiveFloat

from physconst import (
    G0_MPS2,
    ISA_H0_M,
    ISA_H_MAX_M,
    ISA_H_MIN_M,
    ISA_L0_KPM,
    ISA_LAYER_BASE_M,
    ISA_LAYER_LAPSE_KPM,
    ISA_LAYER_P_PA,
    ISA_LAYER_T_K,
    ISA_P0_PA,
    ISA_R0_GEOPOTENTIAL_M,
    ISA_R_AIR_JPKGK,
    ISA_T0_K,
)

BIAS_PER_PRESSURE_M_PER_PA = ISA_R_AIR_JPKGK * ISA_T0_K / (G0_MPS2 * ISA_P0_PA)
"""P4's ``b/ΔP = R·T0/(g·P0)``, m/Pa (8.32 m per hPa)."""



def _pressure_in_layer(i: int, h_gp_m: float) -> float:
    dh = h_gp_m - ISA_LAYER_BASE_M[i]
    lapse = ISA_LAYER_LAPSE_KPM[i]
    if lapse == 0.0:
        return ISA_LAYER_P_PA[i] * math.exp(-G0_MPS2 * dh / (ISA_R_AIR_JPKGK * ISA_LAYER_T_K[i]))
    t = ISA_LAYER_T_K[i] + lapse * dh
    return ISA_LAYER_P_PA[i] * (t / ISA_LAYER_T_K[i]) ** (-G0_MPS2 / (lapse * ISA_R_AIR_JPKGK))


P_MAX_PA = _pressure_in_layer(0, ISA_H_MIN_M)
"""Pressure at :data:`ISA_H_MIN_M` (≈ 177.7 kPa): the highest pressure the model accepts, Pa."""
P_MIN_PA = _pressure_in_layer(len(ISA_LAYER_BASE_M) - 1, ISA_H_MAX_M)
"""Pressure at :data:`ISA_H_MAX_M` (≈ 110.9 Pa): the lowest pressure the model accepts, Pa."""


def _layer_of_altitude(h_gp_m: float) -> int:
    i = 0
    while i + 1 < len(ISA_LAYER_BASE_M) and h_gp_m >= ISA_LAYER_BASE_M[i + 1]:
        i += 1
    return i


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


def geopotential_from_geometric(h_m: float) -> float:
    """Geopotential altitude ``r0·h/(r0 + h)`` (m) from geometric height above MSL (m)."""
    return ISA_R0_GEOPOTENTIAL_M * h_m / (ISA_R0_GEOPOTENTIAL_M + h_m)


def geometric_from_geopotential(h_gp_m: float) -> float:
    """Geometric height above MSL ``r0·H/(r0 − H)`` (m) from geopotential altitude (m)."""
    return ISA_R0_GEOPOTENTIAL_M * h_gp_m / (ISA_R0_GEOPOTENTIAL_M - h_gp_m)


def isa_temperature_k(h_gp_m: float) -> float:
    """Standard-atmosphere temperature (K) at geopotential altitude ``h_gp_m`` (m).

    Raises
    ------
    ValueError
        Altitude not finite or outside [−5000, 47000] m.
    """
    _check_altitude(h_gp_m, "h_gp_m")
    i = _layer_of_altitude(h_gp_m)
    return ISA_LAYER_T_K[i] + ISA_LAYER_LAPSE_KPM[i] * (h_gp_m - ISA_LAYER_BASE_M[i])


def isa_pressure_pa(h_gp_m: float) -> float:
    """Standard-atmosphere static pressure (Pa) at geopotential altitude ``h_gp_m`` (m).

    Raises
    ------
    ValueError
        Altitude not finite or outside [−5000, 47000] m.
    """
    _check_altitude(h_gp_m, "h_gp_m")
    return _pressure_in_layer(_layer_of_altitude(h_gp_m), h_gp_m)


def pressure_altitude_m(pressure_pa: float) -> float:
    """Pressure altitude ``Hp``: the standard-atmosphere geopotential altitude of a pressure.

    In the troposphere this is P4 eq. 1; above 11 km the matching layer of the US Standard
    Atmosphere 1976 (isothermal layers by the logarithmic form).

    Parameters
    ----------
    pressure_pa : float
        Static pressure, Pa.

    Returns
    -------
    float
        ``Hp``, m (geopotential; 0 at 101 325 Pa, 11 000 at 22 632.06 Pa).

    Raises
    ------
    ValueError
        Pressure ≤ 0, not finite, or outside the model range (:func:`check_pressure`).
    """
    check_pressure(pressure_pa)
    i = 0
    while i + 1 < len(ISA_LAYER_P_PA) and pressure_pa <= ISA_LAYER_P_PA[i + 1]:
        i += 1
    base_h, base_t, base_p = ISA_LAYER_BASE_M[i], ISA_LAYER_T_K[i], ISA_LAYER_P_PA[i]
    lapse = ISA_LAYER_LAPSE_KPM[i]
    if lapse == 0.0:
        return base_h - (ISA_R_AIR_JPKGK * base_t / G0_MPS2) * math.log(pressure_pa / base_p)
    return (
        base_h
        + (base_t / lapse) * ((pressure_pa / base_p) ** (-lapse * ISA_R_AIR_JPKGK / G0_MPS2) - 1.0)
        + ISA_H0_M
    )


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


# --------------------------------------------------------------------------------------------
# Online calibration of (s, b) against GNSS height.
# --------------------------------------------------------------------------------------------


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class BaroCalibrationConfig(_Frozen):
    """Online estimator of P4's ``(s, b)``: a two-state Kalman filter with random-walk states.

    A Kalman filter rather than RLS with a forgetting factor: the regressor ``[Hp, 1]`` is
    poorly excited in level flight, and exponential forgetting then winds the covariance of
    ``s`` up without bound; random-walk process noise keeps it bounded and gives the same
    fading memory for ``b``. The memory of ``b`` is about ``σ_meas/(q_b·√f)`` for GNSS heights
    at rate ``f`` (e.g. 2.5 m at 5 Hz: 224 s with the default q_b = 0.005 m/√s, 56 s with 0.02).
    """

    scale_sigma0: PositiveFloat = 0.05
    """Prior 1σ of ``s`` (±14 K of sea-level temperature offset)."""
    bias_sigma0_m: PositiveFloat = 150.0
    """Prior 1σ of ``b``, m (±18 hPa; ignored in QNH initialisation, see below)."""
    qnh_bias_sigma0_m: PositiveFloat = 10.0
    """Prior 1σ of ``b`` when initialised from a QNH setting, m."""
    scale_random_walk_per_rth_s: float = Field(default=1e-5, ge=0.0)
    """Random walk of ``s``, 1/√s (the air mass changes slowly)."""
    bias_random_walk_m_per_rth_s: float = Field(default=0.005, ge=0.0)
    """Random walk of ``b``, m/√s: weather (1 hPa per 10 min ≈ 0.014 m/s) and sensor drift.
    0.005 was chosen on the tuning seeds of ``bench/altitude_jsbsim.py`` (over 0.02 and 0.05;
    calm and weather-front flights): a memory of ~200 s averages the GNSS receiver's
    time-correlated vertical error better than 0.02 (~56 s) does."""
    min_gnss_sigma_m: PositiveFloat = 0.5
    """Floor on the GNSS height sigma used, m."""
    gnss_sigma_scale: PositiveFloat = 1.0
    """Multiplier on the reported GNSS sigma (GNSS height errors are time-correlated)."""
    use_gnss: bool = True
    """Learn ``(s, b)`` from GNSS height. ``False`` reproduces P4's set-up, where GNSS reaches
    the altitude only through the compensator (``b`` stays at its initial value, e.g. from QNH;
    ``s`` only from the temperature if ``use_temperature``)."""
    use_temperature: bool = False
    """Also fuse ``s = T/T_isa(Hp) − 1`` from the sensor temperature (see
    :func:`scale_from_temperature`; biased by the sensor's self-heating)."""
    temperature_sigma_k: PositiveFloat = 3.0
    """1σ of the sensed air temperature for that, K (self-heating dominates)."""
    gate_sigma: PositiveFloat = 5.0
    """GNSS height innovations beyond this many σ are rejected (counted), not fused."""
    max_abs_scale: PositiveFloat = 0.3
    """``|s|`` is clipped to this (|ΔT| ≤ 86 K); a guard against a diverging estimate."""


@dataclass(frozen=True, slots=True)
class CalibrationUpdate:
    """Result of one :meth:`BaroCalibration.update`.

    Attributes
    ----------
    accepted : whether the GNSS height was fused.
    rejected : whether it failed the innovation gate (an outlier; counted).
    innovation_m : GNSS geopotential height minus calibrated baro height before the update, m.
    innovation_sigma_m : its predicted 1σ, m.
    delta_altitude_m : change of the calibrated altitude at this ``Hp`` caused by the update, m
        (0 when rejected or frozen).
    """

    accepted: bool
    rejected: bool
    innovation_m: float
    innovation_sigma_m: float
    delta_altitude_m: float


class BaroCalibration:
    """Online estimate of P4's non-standard-atmosphere scale ``s`` and bias ``b``.

    Measurement model (geopotential metres)::

        H_gnss − Hp = s·(Hp − H0) + b + v,     v ~ N(0, σ²)

    with ``H_gnss`` the GNSS height above MSL converted to geopotential. ``s`` and ``b`` are
    random walks. :meth:`freeze` stops learning during GNSS outages (the estimate and its
    covariance are kept); :meth:`unfreeze` resumes.

    Parameters
    ----------
    config : BaroCalibrationConfig
    scale0, bias0_m : float
        Initial ``s`` and ``b``.
    bias_sigma0_m : float or None
        Prior 1σ of ``b``; ``None`` takes ``config.bias_sigma0_m``.
    """

    def __init__(
        self,
        config: BaroCalibrationConfig | None = None,
        scale0: float = 0.0,
        bias0_m: float = 0.0,
        bias_sigma0_m: float | None = None,
    ) -> None:
        self.config = cfg = config or BaroCalibrationConfig()
        if not (math.isfinite(scale0) and math.isfinite(bias0_m)):
            raise ValueError("scale0 and bias0_m must be finite")
        sb = cfg.bias_sigma0_m if bias_sigma0_m is None else bias_sigma0_m
        if not sb > 0.0:
            raise ValueError(f"bias_sigma0_m must be > 0 (got {sb!r})")
        self.scale = scale0
        self.bias_m = bias0_m
        # Covariance of [s, b], kept as three floats (symmetric 2x2) for speed.
        self._pss = cfg.scale_sigma0**2
        self._psb = 0.0
        self._pbb = sb * sb
        self._t_last_s: float | None = None
        self.frozen = False
        self.n_updates = 0
        self.n_rejected = 0

    # ---- state -------------------------------------------------------------------------
    @property
    def covariance(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Covariance of ``[s, b]`` (2×2, units 1 and m)."""
        return ((self._pss, self._psb), (self._psb, self._pbb))

    @property
    def sea_level_dt_k(self) -> float:
        """Estimated sea-level temperature offset ``ΔT = s·T0``, K."""
        return self.scale * ISA_T0_K

    @property
    def sea_level_dp_pa(self) -> float:
        """Estimated sea-level pressure offset ``ΔP = b·g·P0/(R·T0)``, Pa."""
        return self.bias_m / BIAS_PER_PRESSURE_M_PER_PA

    def altitude_gp_m(self, pressure_altitude: float) -> float:
        """Calibrated geopotential altitude ``Hp + s·(Hp − H0) + b``, m."""
        return pressure_altitude + self.scale * (pressure_altitude - ISA_H0_M) + self.bias_m

    def freeze(self) -> None:
        """Stop learning (GNSS outage). The estimate stays; covariance stops growing."""
        self.frozen = True

    def unfreeze(self) -> None:
        """Resume learning; the covariance grows by the random walk over the frozen time."""
        self.frozen = False

    def snapshot(self) -> tuple[float, float, float, float, float, float | None, bool]:
        """The estimator's state ``(s, b, Pss, Psb, Pbb, t_last, frozen)`` (for :meth:`restore`)."""
        return (
            self.scale,
            self.bias_m,
            self._pss,
            self._psb,
            self._pbb,
            self._t_last_s,
            self.frozen,
        )

    def restore(self, state: tuple[float, float, float, float, float, float | None, bool]) -> None:
        """Go back to a state taken with :meth:`snapshot` (the counters are kept)."""
        (
            self.scale,
            self.bias_m,
            self._pss,
            self._psb,
            self._pbb,
            self._t_last_s,
            self.frozen,
        ) = state

    def shift_bias(self, delta_m: float) -> None:
        """Add ``delta_m`` to ``b`` (re-alignment of the datum after a baro step), m."""
        if not math.isfinite(delta_m):
            raise ValueError("delta_m must be finite")
        self.bias_m += delta_m

    # ---- learning ----------------------------------------------------------------------
    def _propagate(self, time_s: float) -> None:
        if self._t_last_s is not None:
            dt = time_s - self._t_last_s
            if dt > 0.0:
                cfg = self.config
                self._pss += cfg.scale_random_walk_per_rth_s**2 * dt
                self._pbb += cfg.bias_random_walk_m_per_rth_s**2 * dt
        if self._t_last_s is None or time_s > self._t_last_s:
            self._t_last_s = time_s

    def _fuse(self, h0: float, h1: float, z: float, r: float) -> tuple[float, float]:
        # Scalar measurement z = [h0, h1]·[s, b] + v, Joseph-equivalent for scalar updates.
        pss, psb, pbb = self._pss, self._psb, self._pbb
        ph0 = pss * h0 + psb * h1  # (P Hᵀ)_s
        ph1 = psb * h0 + pbb * h1  # (P Hᵀ)_b
        s_innov = h0 * ph0 + h1 * ph1 + r
        k0, k1 = ph0 / s_innov, ph1 / s_innov
        nu = z - (h0 * self.scale + h1 * self.bias_m)
        self.scale += k0 * nu
        self.bias_m += k1 * nu
        # P = (I − K H) P (I − K H)ᵀ + K R Kᵀ, written out for the 2x2 symmetric case.
        a00, a01 = 1.0 - k0 * h0, -k0 * h1
        a10, a11 = -k1 * h0, 1.0 - k1 * h1
        t00 = a00 * pss + a01 * psb
        t01 = a00 * psb + a01 * pbb
        t10 = a10 * pss + a11 * psb
        t11 = a10 * psb + a11 * pbb
        self._pss = t00 * a00 + t01 * a01 + k0 * k0 * r
        self._psb = t00 * a10 + t01 * a11 + k0 * k1 * r
        self._pbb = t10 * a10 + t11 * a11 + k1 * k1 * r
        return nu, s_innov

    def update(
        self,
        gnss_height_m: float,
        pressure_altitude: float,
        time_s: float,
        *,
        sigma_m: float,
        temperature_k: float | None = None,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> CalibrationUpdate:
        """Fuse one GNSS height (and optionally the sensed temperature).

        Parameters
        ----------
        gnss_height_m : float
            GNSS height, m: above MSL (``reference="msl"``) or above the WGS-84 ellipsoid
            (``reference="ellipsoid"``), geometric.
        pressure_altitude : float
            ``Hp`` of the baro sample at the same time of validity, m.
        time_s : float
            Time of validity, s (monotonic; drives the random walk).
        sigma_m : float
            1σ of the GNSS height, m (> 0; e.g. the receiver's ``epv``).
        temperature_k : float or None
            Sensed air temperature, K; fused only with ``config.use_temperature``.
        reference : {"msl", "ellipsoid"}
            What ``gnss_height_m`` is measured from.
        geoid_undulation_m : float
            ``N`` (ellipsoid minus MSL), m; used with ``reference="ellipsoid"``.

        Returns
        -------
        CalibrationUpdate

        Raises
        ------
        ValueError
            Non-finite inputs, ``sigma_m ≤ 0``, unknown ``reference``.
        """
        if not (
            math.isfinite(gnss_height_m)
            and math.isfinite(pressure_altitude)
            and math.isfinite(time_s)
            and math.isfinite(geoid_undulation_m)
        ):
            raise ValueError("gnss_height_m, pressure_altitude, time_s, geoid must be finite")
        if not (math.isfinite(sigma_m) and sigma_m > 0.0):
            raise ValueError(f"sigma_m must be finite and > 0 (got {sigma_m!r})")
        if reference == "ellipsoid":
            h_msl = gnss_height_m - geoid_undulation_m
        elif reference == "msl":
            h_msl = gnss_height_m
        else:
            raise ValueError(f"reference must be 'msl' or 'ellipsoid' (got {reference!r})")
        cfg = self.config
        h_gp = geopotential_from_geometric(h_msl)
        h0 = pressure_altitude - ISA_H0_M
        before = self.altitude_gp_m(pressure_altitude)
        innovation = h_gp - before
        if self.frozen:
            return CalibrationUpdate(False, False, innovation, math.nan, 0.0)
        self._propagate(time_s)
        sigma = max(sigma_m * cfg.gnss_sigma_scale, cfg.min_gnss_sigma_m)
        r = sigma * sigma
        s_innov = h0 * h0 * self._pss + 2.0 * h0 * self._psb + self._pbb + r
        if cfg.use_gnss:
            if innovation * innovation > cfg.gate_sigma**2 * s_innov:
                self.n_rejected += 1
                return CalibrationUpdate(False, True, innovation, math.sqrt(s_innov), 0.0)
            self._fuse(h0, 1.0, h_gp - pressure_altitude, r)
        if cfg.use_temperature and temperature_k is not None:
            s_meas = scale_from_temperature(temperature_k, pressure_altitude)
            r_s = (cfg.temperature_sigma_k / isa_temperature_k(pressure_altitude)) ** 2
            self._fuse(1.0, 0.0, s_meas, r_s)
        if abs(self.scale) > cfg.max_abs_scale:
            self.scale = math.copysign(cfg.max_abs_scale, self.scale)
        self.n_updates += 1
        return CalibrationUpdate(
            cfg.use_gnss,
            False,
            innovation,
            math.sqrt(s_innov),
            self.altitude_gp_m(pressure_altitude) - before,
        )


# --------------------------------------------------------------------------------------------
# Barometric altimeter.
# --------------------------------------------------------------------------------------------

AltimeterMode = Literal["standard", "qnh", "calibrated"]


class BaroAltimeterConfig(_Frozen):
    """How pressure becomes height.

    ``standard``: pressure altitude (ISA). ``qnh``: altimeter set to ``qnh_pa``. ``calibrated``:
    P4's non-standard atmosphere with ``(s, b)`` learned online from GNSS height; starts from
    ``qnh_pa`` if given (``b = −Hp(QNH)``, ``s = 0``), else from the standard atmosphere.
    """

    mode: AltimeterMode = "calibrated"
    qnh_pa: float | None = Field(default=None, ge=80000.0, le=110000.0)
    calibration: BaroCalibrationConfig = BaroCalibrationConfig()


class BaroAltimeter:
    """Pressure (+ temperature) to geometric height above MSL.

    Parameters
    ----------
    config : BaroAltimeterConfig

    Raises
    ------
    ValueError
        ``mode="qnh"`` without ``qnh_pa``.
    """

    def __init__(self, config: BaroAltimeterConfig | None = None) -> None:
        self.config = cfg = config or BaroAltimeterConfig()
        if cfg.mode == "qnh" and cfg.qnh_pa is None:
            raise ValueError("mode='qnh' needs qnh_pa")
        if cfg.qnh_pa is not None:
            b0 = -pressure_altitude_m(cfg.qnh_pa)
            self.calibration = BaroCalibration(
                cfg.calibration, 0.0, b0, cfg.calibration.qnh_bias_sigma0_m
            )
        else:
            self.calibration = BaroCalibration(cfg.calibration)

    @property
    def mode(self) -> AltimeterMode:
        """The configured mode."""
        return self.config.mode

    def altitude_gp_from_hp(self, pressure_altitude: float) -> float:
        """Geopotential altitude (m) for a pressure altitude ``Hp`` (m) in the current mode."""
        mode = self.config.mode
        if mode == "standard":
            return pressure_altitude
        if mode == "qnh":
            assert self.config.qnh_pa is not None
            return pressure_altitude - pressure_altitude_m(self.config.qnh_pa)
        return self.calibration.altitude_gp_m(pressure_altitude)

    def altitude_from_hp(self, pressure_altitude: float) -> float:
        """Geometric height above MSL (m) for a pressure altitude ``Hp`` (m)."""
        return geometric_from_geopotential(self.altitude_gp_from_hp(pressure_altitude))

    def altitude_m(self, pressure_pa: float) -> float:
        """Geometric height above MSL of a static pressure, m.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa.

        Raises
        ------
        ValueError
            Pressure ≤ 0, not finite, or outside the model (:func:`check_pressure`).
        """
        return self.altitude_from_hp(pressure_altitude_m(pressure_pa))

    def calibrate(
        self,
        gnss_alt_m: float,
        pressure_pa: float,
        temperature_k: float | None = None,
        *,
        time_s: float,
        sigma_m: float,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> CalibrationUpdate:
        """Learn ``(s, b)`` from one GNSS height and a simultaneous baro sample.

        Only meaningful in ``calibrated`` mode (in the others the estimate is kept but unused).
        See :meth:`BaroCalibration.update` for the parameters.
        """
        return self.calibration.update(
            gnss_alt_m,
            pressure_altitude_m(pressure_pa),
            time_s,
            sigma_m=sigma_m,
            temperature_k=temperature_k,
            reference=reference,
            geoid_undulation_m=geoid_undulation_m,
        )

    def freeze(self) -> None:
        """Freeze the calibration (GNSS outage)."""
        self.calibration.freeze()

    def unfreeze(self) -> None:
        """Resume calibration."""
        self.calibration.unfreeze()


# --------------------------------------------------------------------------------------------
# Baro health: range, frozen sensor, innovation gate.
# --------------------------------------------------------------------------------------------


class BaroMonitorConfig(_Frozen):
    """When a baro sample is used."""

    freeze_time_s: PositiveFloat = 2.0
    """Bit-identical (within ``freeze_tolerance_pa``) readings for this long: sensor frozen.
    Sensors with a coarse output step hovering in still air repeat legitimately; raise it."""
    freeze_tolerance_pa: float = Field(default=0.0, ge=0.0)
    gate_m: PositiveFloat = 10.0
    """Samples whose height differs from the loop's prediction by more are rejected, m."""
    realign_after_rejected_s: PositiveFloat = 10.0
    """After this long of continuous gate rejections the baro datum is re-aligned (see
    :class:`fusion.altitude.AltitudeChannel`), s."""


@dataclass(slots=True)
class BaroHealth:
    """Counters and flags of the barometer path (monotonic counters, current flags)."""

    samples: int = 0
    accepted: int = 0
    range_errors: int = 0
    frozen_samples: int = 0
    freeze_events: int = 0
    gate_rejections: int = 0
    realignments: int = 0
    frozen: bool = False
    rejecting: bool = False


class BaroMonitor:
    """Range check, freeze detector and innovation gate for one barometer.

    Usage per sample: :meth:`check` (range + freeze; returns the pressure altitude or ``None``),
    then :meth:`gate` with the calibrated height and the loop's predicted height.

    Parameters
    ----------
    config : BaroMonitorConfig
    health : BaroHealth or None
        Counters to update (a fresh one if ``None``).
    """

    def __init__(self, config: BaroMonitorConfig | None = None, health: BaroHealth | None = None):
        self.config = config or BaroMonitorConfig()
        self.health = health if health is not None else BaroHealth()
        self._last_p: float | None = None
        self._same_since_s = 0.0
        self._rejecting_since_s: float | None = None

    def check(self, pressure_pa: float, time_s: float) -> float | None:
        """Range and freeze check of one sample.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa (any value: bad ones are counted, never raised).
        time_s : float
            Sample time, s.

        Returns
        -------
        float or None
            The pressure altitude ``Hp`` (m), or ``None`` if the sample must not be used.
        """
        h = self.health
        h.samples += 1
        try:
            hp = pressure_altitude_m(pressure_pa)
        except ValueError:
            h.range_errors += 1
            return None
        cfg = self.config
        if self._last_p is not None and abs(pressure_pa - self._last_p) <= cfg.freeze_tolerance_pa:
            if time_s - self._same_since_s >= cfg.freeze_time_s:
                if not h.frozen:
                    h.freeze_events += 1
                h.frozen = True
        else:
            self._last_p = pressure_pa
            self._same_since_s = time_s
            h.frozen = False
        if h.frozen:
            h.frozen_samples += 1
            return None
        return hp

    def gate(self, baro_height_m: float, predicted_height_m: float, time_s: float) -> bool:
        """Innovation gate: accept if ``|baro − predicted| ≤ gate_m``.

        Returns
        -------
        bool
            ``True`` when accepted. Rejections are counted; :attr:`rejecting_for_s` tells how
            long they have lasted without a break.
        """
        h = self.health
        if abs(baro_height_m - predicted_height_m) <= self.config.gate_m:
            h.accepted += 1
            h.rejecting = False
            self._rejecting_since_s = None
            return True
        h.gate_rejections += 1
        h.rejecting = True
        if self._rejecting_since_s is None:
            self._rejecting_since_s = time_s
        return False

    def rejecting_for_s(self, time_s: float) -> float:
        """How long the gate has rejected every sample, s (0 if the last one was accepted)."""
        return 0.0 if self._rejecting_since_s is None else time_s - self._rejecting_since_s

    def clear_rejection(self) -> None:
        """Forget the current run of rejections (after a datum re-alignment)."""
        self._rejecting_since_s = None
        self.health.rejecting = False
