"""Pitot-static differential-pressure sensor: the impact pressure a pitot-static probe and a
differential-pressure sensor (TE MS4525DO, Sensirion SDP3x) report, with its errors.

Measurement chain, per sample at time ``t``::

    q_c   = impact_pressure_pa(TAS, p, T)                       (physconst.airdata, isentropic)
    g     = max(0, 1 − k_α·(α − α_probe)² − k_β·β²)             probe misalignment
    e_s   = c_s·(α − α_probe)                                   static-source position error
    q_p   = q_c · (g − e_s) · (1 + s)                           scale error s
    q_lag = first-order lag of q_p with time constant τ         pneumatic line / sensor filter
    q_out = Q( clip( q_lag + b0 + b_gm(t) + b_rw(t) + n ) ),   n ~ N(0, noise²)

- ``TAS`` is the truth's true airspeed (JSBSim's ``vtrue``: the speed relative to the air mass,
  winds and turbulence included), ``p`` and ``T`` its static pressure and temperature.
- Probe misalignment: an open total-pressure tube reads the full impact pressure only when
  it points into the flow; the loss grows with the square of the flow angle for small
  angles (Gracey, *Measurement of Aircraft Speed and Altitude*, NASA RP-1046, 1980, ch. 10:
  a simple open-ended tube stays within about 1 % of ``q_c`` up to roughly ±10° of
  inclination, i.e. ``k ≈ 0.3 /rad²``; shielded Kiel probes are flat much further). The
  quadratic form is the small-angle expansion of the cosine-type loss ``cos²θ ≈ 1 − θ²``
  (``k = 1``), which a real tube beats. ``α`` and ``β`` are the truth's angle of attack and
  sideslip (JSBSim ``aero/alpha-rad``, ``aero/beta-rad``); where they are not finite (truth
  decoded from MAVLink carries none) the misalignment term is 0.
- Static-source position error: the static port sits in the pressure field of the airframe,
  so it senses ``p + Δp`` and the sensor ``p_t − p − Δp``; ``Δp / q_c`` follows the flow
  around the fuselage and so the lift coefficient, linear in the angle of attack over the
  normal flight envelope (Gracey, NASA RP-1046, 1980, ch. 9 on static-pressure errors; the
  position-error calibration of FAA AC 23-8C, section 23.1323). Off (``c_s = 0``) unless a
  preset or scenario sets ``static_error_alpha_per_rad``. 14 CFR 23.1323(b) allows a system
  error of 3 % of the calibrated airspeed; ``c_s = 0.3 /rad`` (the ``-pe`` presets) moves the
  airspeed by 0.15 % per degree of angle of attack, 1.5 % over a 10° range: inside the
  limit, as a certified installation is.
- Scale error ``s``: a fixed part plus a turn-on draw ``N(0, scale_error_sigma²)`` (span
  accuracy of the sensor and the installation's pressure coefficient, the error ArduPilot's
  ``ARSPD_RATIO`` calibration absorbs).
- Offset: a fixed part plus a turn-on draw ``b0 ~ N(0, offset_sigma_pa²)`` (what is left after
  the autopilot zeroes the sensor at power-on), a first-order Gauss–Markov drift ``b_gm``
  (thermal drift of the zero) and an optional random walk ``b_rw`` (Pa/√s).
- ``clip``: the sensor's range ±``full_scale_pa`` (a reading beyond it saturates); ``Q``:
  rounding to the output resolution.

Temperature: the air temperature plus an offset (the sensor sits in the fuselage), white noise
and rounding (MAVLink carries only the barometer's temperature; see ``hil.codec``).

A sample's randomness comes from this model's own generator only, drawn in blocks (as the
other sensors do), so the other sensors' streams do not change when a pitot is configured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from physconst.airdata import impact_pressure_pa
from sim._sensor_common import (
    BLOCK_STEPS,
    Finite,
    NonNegative,
    Positive,
    SensorConfigModel,
    gauss_markov_coefficients,
)
from sim.samples import AirspeedSample, Truth

__all__ = [
    "PitotConfig",
    "PitotModel",
    "PitotParams",
    "air_velocity_b_mps",
    "probe_misalignment_factor",
]


class PitotConfig(SensorConfigModel):
    """Pitot-static probe and differential-pressure sensor figures.

    Attributes
    ----------
    noise_pa : white noise of the differential pressure per sample, 1σ, Pa.
    resolution_pa : output LSB, Pa (0 = none).
    full_scale_pa : the sensor's range ±full_scale_pa, Pa (None = unlimited).
    lag_time_constant_s : first-order lag of the sensed pressure (tubing and sensor
        filter), s (0 = none).
    offset_pa : constant zero offset, Pa.
    offset_sigma_pa : turn-on zero offset, 1σ, Pa (one draw per seed).
    offset_gm_sigma_pa, offset_gm_tau_s : Gauss–Markov drift of the zero, 1σ Pa and
        correlation time s.
    offset_random_walk_pa_per_rth : random walk of the zero, Pa/√s (0 = none).
    scale_error : constant scale error of the impact pressure, fraction (0.01 = +1 %).
    scale_error_sigma : turn-on scale error, 1σ, fraction (one draw per seed).
    k_alpha_per_rad2, k_beta_per_rad2 : probe misalignment loss, fraction of the impact
        pressure per rad² of angle of attack (from the probe's axis) and of sideslip.
    probe_incidence_deg : angle of attack at which the probe points into the flow, deg.
    static_error_alpha_per_rad : static-source position error, fraction of the impact
        pressure per rad of angle of attack from ``probe_incidence_deg`` (0 = none).
    temperature_offset_k : sensor temperature minus air temperature, K.
    temperature_noise_k : white temperature noise, 1σ, K.
    temperature_resolution_k : temperature LSB, K (0 = none).
    """

    noise_pa: NonNegative
    resolution_pa: NonNegative = 0.0
    full_scale_pa: Positive | None = None
    lag_time_constant_s: NonNegative = 0.0
    offset_pa: Finite = 0.0
    offset_sigma_pa: NonNegative = 0.0
    offset_gm_sigma_pa: NonNegative = 0.0
    offset_gm_tau_s: Positive = 600.0
    offset_random_walk_pa_per_rth: NonNegative = 0.0
    scale_error: Finite = 0.0
    scale_error_sigma: NonNegative = 0.0
    k_alpha_per_rad2: NonNegative = 0.0
    k_beta_per_rad2: NonNegative = 0.0
    probe_incidence_deg: Finite = 0.0
    static_error_alpha_per_rad: Finite = 0.0
    temperature_offset_k: Finite = 0.0
    temperature_noise_k: NonNegative = 0.0
    temperature_resolution_k: NonNegative = 0.0


@dataclass(frozen=True)
class PitotParams:
    """A :class:`PitotConfig` in SI (Pa, rad, s, K); ``full_scale_pa`` inf when unlimited."""

    noise_pa: float
    resolution_pa: float
    full_scale_pa: float
    lag_time_constant_s: float
    offset_pa: float
    offset_sigma_pa: float
    offset_gm_sigma_pa: float
    offset_gm_tau_s: float
    offset_random_walk_pa_per_rth: float
    scale_error: float
    scale_error_sigma: float
    k_alpha_per_rad2: float
    k_beta_per_rad2: float
    probe_incidence_rad: float
    static_error_alpha_per_rad: float
    temperature_offset_k: float
    temperature_noise_k: float
    temperature_resolution_k: float

    @classmethod
    def from_config(cls, c: PitotConfig) -> PitotParams:
        """Convert once."""
        return cls(
            noise_pa=c.noise_pa,
            resolution_pa=c.resolution_pa,
            full_scale_pa=math.inf if c.full_scale_pa is None else c.full_scale_pa,
            lag_time_constant_s=c.lag_time_constant_s,
            offset_pa=c.offset_pa,
            offset_sigma_pa=c.offset_sigma_pa,
            offset_gm_sigma_pa=c.offset_gm_sigma_pa,
            offset_gm_tau_s=c.offset_gm_tau_s,
            offset_random_walk_pa_per_rth=c.offset_random_walk_pa_per_rth,
            scale_error=c.scale_error,
            scale_error_sigma=c.scale_error_sigma,
            k_alpha_per_rad2=c.k_alpha_per_rad2,
            k_beta_per_rad2=c.k_beta_per_rad2,
            probe_incidence_rad=math.radians(c.probe_incidence_deg),
            static_error_alpha_per_rad=c.static_error_alpha_per_rad,
            temperature_offset_k=c.temperature_offset_k,
            temperature_noise_k=c.temperature_noise_k,
            temperature_resolution_k=c.temperature_resolution_k,
        )


def air_velocity_b_mps(truth: Truth) -> tuple[float, float, float]:
    """The air-relative velocity ``(u, v, w)`` in body FRD, m/s, from the truth's true
    airspeed, angle of attack and sideslip (JSBSim's definitions: ``α = atan2(w, u)``,
    ``β = asin(v / V)``); non-finite angles count as 0."""
    v_mps = truth.airspeed_mps
    a = truth.alpha_rad if math.isfinite(truth.alpha_rad) else 0.0
    b = truth.beta_rad if math.isfinite(truth.beta_rad) else 0.0
    cb = math.cos(b)
    return v_mps * math.cos(a) * cb, v_mps * math.sin(b), v_mps * math.sin(a) * cb


def probe_misalignment_factor(
    alpha_rad: float,
    beta_rad: float,
    k_alpha_per_rad2: float,
    k_beta_per_rad2: float,
    probe_incidence_rad: float = 0.0,
) -> float:
    """Fraction of the impact pressure a misaligned probe senses (see the module docstring).

    ``max(0, 1 − k_α·(α − α_probe)² − k_β·β²)``; a non-finite angle counts as 0 (no loss).
    """
    a = alpha_rad - probe_incidence_rad if math.isfinite(alpha_rad) else 0.0
    b = beta_rad if math.isfinite(beta_rad) else 0.0
    return max(0.0, 1.0 - k_alpha_per_rad2 * a * a - k_beta_per_rad2 * b * b)


class PitotModel:
    """Pitot-static differential-pressure sensor with its own random generator.

    Parameters
    ----------
    config : PitotConfig
    rng : numpy.random.Generator
        Used only by this model: two turn-on draws (offset, scale error) at construction,
        then blocks of per-sample normals.

    Attributes
    ----------
    turn_on_offset_pa : float
        ``offset_pa`` plus this seed's turn-on draw, Pa.
    scale : float
        ``1 + s``, this seed's total scale factor of the impact pressure.
    """

    def __init__(self, config: PitotConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.params = p = PitotParams.from_config(config)
        self._rng = rng
        z_offset, z_scale, z_gm = (float(v) for v in rng.standard_normal(3))
        self.turn_on_offset_pa = p.offset_pa + p.offset_sigma_pa * z_offset
        self.scale = 1.0 + p.scale_error + p.scale_error_sigma * z_scale
        self._gm = z_gm * p.offset_gm_sigma_pa
        self._rw = 0.0
        self._noise: list[list[float]] = []
        self._idx = 0
        self._first = True
        self._t_last_us = 0
        self._q_lag = 0.0

    def measure(self, truth: Truth) -> AirspeedSample:
        """One sample at ``truth.time_us`` from the truth's air data.

        Parameters
        ----------
        truth : Truth
            ``airspeed_mps`` (true airspeed), ``static_pressure_pa``, ``temperature_k``,
            ``alpha_rad``, ``beta_rad``.

        Returns
        -------
        AirspeedSample
        """
        p = self.params
        if self._idx >= len(self._noise):
            self._noise = self._rng.standard_normal((BLOCK_STEPS, 4)).tolist()
            self._idx = 0
        z_noise, z_temp, z_gm, z_rw = self._noise[self._idx]
        self._idx += 1
        t = truth.time_us
        q_c = impact_pressure_pa(
            max(0.0, truth.airspeed_mps), truth.static_pressure_pa, truth.temperature_k
        )
        g = probe_misalignment_factor(
            truth.alpha_rad, truth.beta_rad, p.k_alpha_per_rad2, p.k_beta_per_rad2,
            p.probe_incidence_rad,
        )
        if p.static_error_alpha_per_rad and math.isfinite(truth.alpha_rad):
            g -= p.static_error_alpha_per_rad * (truth.alpha_rad - p.probe_incidence_rad)
        q_probe = q_c * g * self.scale
        dt = (t - self._t_last_us) * 1e-6
        if self._first or p.lag_time_constant_s <= 0.0:
            self._q_lag = q_probe
        else:
            self._q_lag += (1.0 - math.exp(-dt / p.lag_time_constant_s)) * (q_probe - self._q_lag)
        if not self._first and dt > 0.0:
            if p.offset_gm_sigma_pa > 0.0:
                phi, q = gauss_markov_coefficients(p.offset_gm_sigma_pa, p.offset_gm_tau_s, dt)
                self._gm = phi * self._gm + q * z_gm
            if p.offset_random_walk_pa_per_rth > 0.0:
                self._rw += p.offset_random_walk_pa_per_rth * math.sqrt(dt) * z_rw
        self._first = False
        self._t_last_us = t
        dp = self._q_lag + self.turn_on_offset_pa + self._gm + self._rw + p.noise_pa * z_noise
        dp = min(p.full_scale_pa, max(-p.full_scale_pa, dp))
        if p.resolution_pa > 0.0:
            dp = round(dp / p.resolution_pa) * p.resolution_pa
        temperature = truth.temperature_k + p.temperature_offset_k + p.temperature_noise_k * z_temp
        if p.temperature_resolution_k > 0.0:
            temperature = (
                round(temperature / p.temperature_resolution_k) * p.temperature_resolution_k
            )
        return AirspeedSample(time_us=t, diff_pressure_pa=dp, temperature_k=temperature)

    @property
    def offset_drift_pa(self) -> float:
        """The zero's current drift (Gauss–Markov plus random walk), Pa."""
        return self._gm + self._rw
