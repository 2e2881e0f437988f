"""Barometer model: static pressure and temperature from the true altitude.

Pressure chain, per sample at time ``t``::

    p_air = pressure_from_altitude(H_gp, dT, dP0 + drift·(t − t_first))    (sim.atmosphere)
    p_lag = first-order lag of p_air with time constant tau_lag
    p_out = Q( p_lag + bias + b_gm(t) + n ),   n ~ N(0, noise²)

- ``H_gp`` is the geopotential altitude of the truth's geometric MSL height (the physical
  atmosphere is layered in geopotential; the difference is 0.16 m at 1 km).
- ``dT``, ``dP0``: the sea-level offsets of P4's non-standard atmosphere; a weather front is a
  linear change of the sea-level pressure offset at ``drift`` hPa/h. At sea level the output
  drifts at exactly that rate; aloft at ``drift·ρ(H)/ρ0`` (the same shift of pressure altitude).
- ``b_gm``: optional first-order Gauss–Markov bias (P4's baro error model), plus a constant
  ``bias``.
- ``Q``: rounding to the output resolution, if one is given.

Temperature: the non-standard atmosphere's air temperature plus an offset (self-heating of
the sensor), white noise and rounding.

Static-port position error (optional, off by default): the static source of a moving
aircraft does not sense the ambient pressure exactly; the error is proportional to the
dynamic pressure and depends on the direction of the air-relative velocity. The model is
ArduPilot's barometer wind-coefficient compensation (``AP_Baro_Wind.cpp``, parameters
``BAROn_WCF_FWD/BCK/RGT/LFT``) run forwards::

    Δp = ½ ρ · (c_x·u² + c_y·v² + c_z·w²)

with ``(u, v, w)`` the air-relative velocity in body FRD (from the truth's true airspeed,
angle of attack and sideslip), ``c_x`` = ``position_error_fwd`` when ``u > 0`` else
``position_error_bck``, ``c_y`` = ``position_error_rgt`` / ``position_error_lft`` by the sign
of ``v``, and ``c_z`` = ``position_error_dn`` (``w > 0``: positive angle of attack) /
``position_error_up`` -- the z pair is hilnav's addition, for a port whose error varies with
angle of attack. ``ρ`` is the density of the model's own air (p, T). A negative coefficient
lowers the sensed pressure (the baro altitude rises with speed, ArduPilot's sign). The error
enters before the lag (it is a pneumatic pressure at the port).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from physconst import ISA_R0_GEOPOTENTIAL_M
from physconst.airdata import air_density_kgpm3
from sim._sensor_common import (
    BLOCK_STEPS,
    Finite,
    NonNegative,
    Positive,
    SensorConfigModel,
    gauss_markov_coefficients,
)
from sim.atmosphere import TroposphereBaro
from sim.samples import BaroSample

Vec3Like = tuple[float, float, float]


class BaroConfig(SensorConfigModel):
    """Barometer and weather figures.

    Attributes
    ----------
    noise_pa : white pressure noise per sample, 1σ, Pa.
    resolution_pa : output LSB, Pa (0 = none).
    lag_time_constant_s : first-order lag of the sensed pressure, s (0 = none).
    bias_hpa : constant pressure offset of this sensor, hPa.
    bias_gm_sigma_pa, bias_gm_tau_s : Gauss–Markov bias, 1σ Pa and correlation time s.
    sea_level_temperature_offset_k : ``dT`` of the non-standard atmosphere, K.
    sea_level_pressure_offset_hpa : ``dP`` at the start, hPa.
    pressure_drift_hpa_per_h : weather front, rate of change of ``dP``, hPa/h.
    temperature_offset_k : sensor temperature minus air temperature, K.
    temperature_noise_k : white temperature noise, 1σ, K.
    temperature_resolution_k : temperature LSB, K (0 = none).
    position_error_fwd, position_error_bck : static-port pressure error over dynamic
        pressure for air-relative velocity along +x (forward) / -x, fraction (ArduPilot
        ``WCF_FWD`` / ``WCF_BCK``).
    position_error_rgt, position_error_lft : the same along +y / -y (``WCF_RGT`` / ``WCF_LFT``).
    position_error_dn, position_error_up : the same along +z (positive angle of attack) / -z.
    """

    noise_pa: NonNegative
    resolution_pa: NonNegative = 0.0
    lag_time_constant_s: NonNegative = 0.0
    bias_hpa: Finite = 0.0
    bias_gm_sigma_pa: NonNegative = 0.0
    bias_gm_tau_s: Positive = 600.0
    sea_level_temperature_offset_k: Finite = 0.0
    sea_level_pressure_offset_hpa: Finite = 0.0
    pressure_drift_hpa_per_h: Finite = 0.0
    temperature_offset_k: Finite = 0.0
    temperature_noise_k: NonNegative = 0.0
    temperature_resolution_k: NonNegative = 0.0
    position_error_fwd: Finite = 0.0
    position_error_bck: Finite = 0.0
    position_error_rgt: Finite = 0.0
    position_error_lft: Finite = 0.0
    position_error_dn: Finite = 0.0
    position_error_up: Finite = 0.0

    @property
    def has_position_error(self) -> bool:
        """True when any static-port position-error coefficient is non-zero."""
        return any(
            v != 0.0
            for v in (
                self.position_error_fwd, self.position_error_bck, self.position_error_rgt,
                self.position_error_lft, self.position_error_dn, self.position_error_up,
            )
        )


@dataclass(frozen=True)
class BaroParams:
    """A :class:`BaroConfig` in SI (Pa, Pa/s, K, s)."""

    noise_pa: float
    resolution_pa: float
    lag_time_constant_s: float
    bias_pa: float
    bias_gm_sigma_pa: float
    bias_gm_tau_s: float
    sea_level_dt_k: float
    sea_level_dp_pa: float
    drift_pa_per_s: float
    temperature_offset_k: float
    temperature_noise_k: float
    temperature_resolution_k: float
    position_error: tuple[float, float, float, float, float, float]
    """(fwd, bck, rgt, lft, dn, up) coefficients."""

    @classmethod
    def from_config(cls, c: BaroConfig) -> BaroParams:
        """Convert once."""
        return cls(
            noise_pa=c.noise_pa,
            resolution_pa=c.resolution_pa,
            lag_time_constant_s=c.lag_time_constant_s,
            bias_pa=100.0 * c.bias_hpa,
            bias_gm_sigma_pa=c.bias_gm_sigma_pa,
            bias_gm_tau_s=c.bias_gm_tau_s,
            sea_level_dt_k=c.sea_level_temperature_offset_k,
            sea_level_dp_pa=100.0 * c.sea_level_pressure_offset_hpa,
            drift_pa_per_s=100.0 * c.pressure_drift_hpa_per_h / 3600.0,
            temperature_offset_k=c.temperature_offset_k,
            temperature_noise_k=c.temperature_noise_k,
            temperature_resolution_k=c.temperature_resolution_k,
            position_error=(
                c.position_error_fwd, c.position_error_bck, c.position_error_rgt,
                c.position_error_lft, c.position_error_dn, c.position_error_up,
            ),
        )


class BaroModel:
    """Barometer with its own random generator; scalar float arithmetic (hot loop).

    Parameters
    ----------
    config : BaroConfig
    rng : numpy.random.Generator
        Used only by this model.

    Raises
    ------
    ValueError
        Bad atmosphere offsets (e.g. ``dT ≤ −288.15 K``).
    """

    def __init__(self, config: BaroConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.params = p = BaroParams.from_config(config)
        self._rng = rng
        self._atm = TroposphereBaro(p.sea_level_dt_k)
        self._gm = float(rng.standard_normal()) * p.bias_gm_sigma_pa
        self._noise: list[list[float]] = []
        self._idx = 0
        self._t_first_us: int | None = None
        self._t_last_us = 0
        self._p_lag = 0.0
        self._position_error = config.has_position_error

    def sea_level_pressure_offset_pa(self, time_us: int) -> float:
        """The weather's sea-level pressure offset ``dP(t)``, Pa (drift from the first sample)."""
        t0 = self._t_first_us if self._t_first_us is not None else time_us
        return self.params.sea_level_dp_pa + self.params.drift_pa_per_s * (time_us - t0) * 1e-6

    def position_error_pa(
        self, pressure_pa: float, temperature_k: float, air_velocity_b_mps: Vec3Like
    ) -> float:
        """Static-port position error ``Δp`` (Pa) for the air-relative body velocity (m/s)
        ``(u, v, w)`` in air of ``pressure_pa`` and ``temperature_k`` (module docstring)."""
        fwd, bck, rgt, lft, dn, up = self.params.position_error
        u, v, w = air_velocity_b_mps
        s = (fwd if u > 0.0 else bck) * u * u
        s += (rgt if v > 0.0 else lft) * v * v
        s += (dn if w > 0.0 else up) * w * w
        return 0.5 * air_density_kgpm3(pressure_pa, temperature_k) * s

    def measure(
        self,
        time_us: int,
        alt_msl_m: float,
        air_velocity_b_mps: Vec3Like | None = None,
    ) -> BaroSample:
        """One barometer sample at ``time_us`` for the true geometric MSL altitude (m).

        ``air_velocity_b_mps``: the air-relative velocity in body FRD, m/s, for the
        static-port position error (ignored when the configuration has none; None: no
        position error).

        Raises
        ------
        ValueError
            Altitude outside the atmosphere model.
        """
        p = self.params
        if self._idx >= len(self._noise):
            self._noise = self._rng.standard_normal((BLOCK_STEPS, 3)).tolist()
            self._idx = 0
        z0, z1, z2 = self._noise[self._idx]
        self._idx += 1
        first = self._t_first_us is None
        if first:
            self._t_first_us = time_us
        d_p = self.sea_level_pressure_offset_pa(time_us)
        h_gp = ISA_R0_GEOPOTENTIAL_M * alt_msl_m / (ISA_R0_GEOPOTENTIAL_M + alt_msl_m)
        p_air, t_air = self._atm.pressure_temperature(h_gp, d_p)
        if air_velocity_b_mps is not None and self._position_error:
            p_air += self.position_error_pa(p_air, t_air, air_velocity_b_mps)
        dt = (time_us - self._t_last_us) * 1e-6
        if first or p.lag_time_constant_s <= 0.0:
            self._p_lag = p_air
        else:
            self._p_lag += (1.0 - math.exp(-dt / p.lag_time_constant_s)) * (p_air - self._p_lag)
        if not first and p.bias_gm_sigma_pa > 0.0:
            phi, q = gauss_markov_coefficients(p.bias_gm_sigma_pa, p.bias_gm_tau_s, dt)
            self._gm = phi * self._gm + q * z2
        self._t_last_us = time_us
        pressure = self._p_lag + p.bias_pa + self._gm + p.noise_pa * z0
        temperature = t_air + p.temperature_offset_k + p.temperature_noise_k * z1
        if p.resolution_pa > 0.0:
            pressure = round(pressure / p.resolution_pa) * p.resolution_pa
        if p.temperature_resolution_k > 0.0:
            temperature = (
                round(temperature / p.temperature_resolution_k) * p.temperature_resolution_k
            )
        return BaroSample(time_us=time_us, pressure_pa=pressure, temperature_k=temperature)
