"""An IMU with a temperature: die temperature, and bias and scale factor that move with it.

Pure (no I/O, no clocks). :class:`ImuThermalModel` is stepped by the sensor suite with the
simulated time and the true altitude; it returns, per axis ``[fx, fy, fz, wx, wy, wz]``, the
thermal bias (m/s², rad/s) and scale-factor error to add to the IMU's other errors
(:mod:`sim.imu`), and the temperature the part reports.

Temperatures
------------
All in kelvin inside; the configuration is in °C (``_c``) and kelvin differences (``_k``).
Per thermal step ``h`` (:data:`THERMAL_STEP_S`), with exact first-order discretisations::

    T_air  = T_atm(H_gp; dT_day) + dT_bay                 air around the IMU
    target = max(T_air, T_set)  while a heater works,  T_air otherwise
    T_case <- target + (T_case - target)·exp(-h/tau)      tau = tau_heater when the heater
                                                           drives, tau_ambient otherwise
    H      <- dT_self + (H - dT_self)·exp(-h/tau_warm)    self-heating after power-on
    T_die  = T_case + H

``T_atm`` is the (non-)standard atmosphere of :mod:`sim.atmosphere` at the truth's altitude, so
the die follows climbs and descents through the case's lag; ``dT_day`` is the day's sea-level
temperature offset (the barometer's ``sea_level_temperature_offset_k``), ``dT_bay`` the
avionics bay's offset above the outside air (a hot day on the ground, a warm fuselage). The
case starts at the configured start temperature (a cold soak) or in equilibrium with the air
(with a working heater: at the set point). ``H`` starts at
``dT_self·(1 - exp(power_on_s/tau_warm))`` (``power_on_s <= 0``: powered on that long before
the start).

Bias and scale factor
---------------------
Per axis ``i``, with the die temperature ``T``, its rate ``dT/dt`` (K/s) and the state ``p`` of
a play operator of half-width ``w`` (``p <- clip(p, T - w, T + w)``, started at ``T``)::

    g_i(T) = s0_i·(T - T_ref) + s1_i·W_i·[tanh((T - Tk_i)/W_i) - tanh((T_ref - Tk_i)/W_i)]
    b_i    = g_i(T) + eta_i·(T - p)/w + rho_i·dT/dt
    sf_i   = q0_i·(T - T_ref) + q1_i·W_i·[tanh((T - Tk_i)/W_i) - tanh((T_ref - Tk_i)/W_i)]

- ``g_i`` is zero at the factory calibration temperature ``T_ref``; its slope is ``s0 + s1``
  at the knee ``Tk`` and ``s0`` far from it: a smooth curve with a knee.
- ``(T - p)/w`` is +1 after ``2w`` of steady heating and -1 after ``2w`` of cooling, so the
  heating and cooling branches differ by ``2·eta`` at the same temperature (hysteresis, a
  one-operator Preisach model); a reversal crosses over within ``2w`` kelvin.
- ``rho·dT/dt``: a thermal-gradient term, present only while the temperature changes.

**This family is deliberately not a low-order polynomial in (T, dT/dt)**: the knee is a
``tanh`` and the hysteresis is a memory of the path, not a function of the present
temperature and its rate at all. A learned model whose hypothesis space is polynomials in
those two inputs (GMDH) can approximate the curve over the range it saw, but never contains
the truth; a world whose error were GMDH's own polynomial family would hand it the answer.

Per-unit variation: ``s0 ~ N(0, (0.85·c)²)``, ``s1 ~ N(0, (1.5·c)²)`` with ``c`` the part's
temperature coefficient (averaged over a -40..85 °C range with a 10 K knee this gives a
1σ slope of about ``c``), ``Tk ~ N(knee, spread²)``, ``W = width·exp(0.25·z)``,
``eta ~ N(0, (gap/2)²)`` (``gap``: the 1σ heating-to-cooling difference), ``rho ~ N(0, r²)``,
``q0 ~ N(0, (0.85·k)²)``, ``q1 ~ N(0, (1.5·k)²)`` (``k``: the scale-factor coefficient), and
the temperature sensor's offset. All drawn at construction from the model's own generator, in
a fixed order, so a seed gives the same unit every time.

The temperature the part reports is sampled every ``temperature_update_s`` (held in between),
with the sensor's offset and noise, rounded to its resolution about its zero (e.g. BMI088:
``0.125·n + 23`` °C, every 1.28 s) and clipped to its range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field

from physconst import ISA_R0_GEOPOTENTIAL_M
from sim._sensor_common import Finite, NonNegative, Positive, SensorConfigModel
from sim.atmosphere import TroposphereBaro

KELVIN_AT_0_C = 273.15
DEG = math.pi / 180.0
MG_MPS2 = 9.80665e-3
THERMAL_STEP_S = 0.1
"""The thermal state advances in steps of this length (its time constants are minutes)."""
SLOPE_FAR_RATIO = 0.85
"""1σ slope of the linear part over the part's temperature coefficient."""
SLOPE_KNEE_RATIO = 1.5
"""1σ of the knee's extra slope over the part's temperature coefficient."""


class ImuThermalPart(SensorConfigModel):
    """Thermal figures of an IMU part (a preset: :func:`sim.presets.imu_thermal_preset`).

    Attributes
    ----------
    gyro_tempco_dps_per_k : gyro bias temperature coefficient, 1σ, °/s/K.
    accel_tempco_mg_per_k : accelerometer bias temperature coefficient, 1σ, mg/K.
    gyro_scale_tempco_ppm_per_k : gyro scale-factor temperature coefficient, 1σ, ppm/K.
    accel_scale_tempco_ppm_per_k : accelerometer scale-factor temperature coefficient, 1σ,
        ppm/K.
    gyro_hysteresis_dps : heating-to-cooling gyro bias difference at one temperature, 1σ, °/s.
    accel_hysteresis_mg : the same for the accelerometer, 1σ, mg.
    hysteresis_width_k : half-width of the play operator, K (a reversal crosses over within
        twice this).
    gyro_rate_dps_per_k_per_min : gyro bias per rate of temperature change, 1σ, °/s per K/min.
    accel_rate_mg_per_k_per_min : accelerometer bias per rate of temperature change, 1σ, mg per
        K/min.
    reference_temperature_c : factory calibration temperature, where the curve is zero, °C.
    knee_temperature_c : mean temperature of the curve's knee, °C.
    knee_spread_k : unit-to-unit spread of the knee temperature, 1σ, K.
    knee_width_k : width of the knee, K.
    self_heating_k : steady-state rise of the die above its case after power-on, K.
    warmup_time_constant_s : time constant of that rise, s.
    ambient_time_constant_s : time constant of the case following the air, s.
    heater_time_constant_s : time constant of a heater driving the case to its set point, s.
    temperature_resolution_k : LSB of the temperature the part reports, K (0 = none).
    temperature_zero_c : the reported temperature is ``zero + n·LSB``, °C.
    temperature_update_s : period at which the part updates its temperature, s.
    temperature_noise_k : white noise of the reported temperature, 1σ, K.
    temperature_offset_k : unit-to-unit offset of the temperature sensor, 1σ, K.
    temperature_min_c, temperature_max_c : range of the temperature sensor, °C (clipped).
    """

    gyro_tempco_dps_per_k: NonNegative
    accel_tempco_mg_per_k: NonNegative
    gyro_scale_tempco_ppm_per_k: NonNegative = 0.0
    accel_scale_tempco_ppm_per_k: NonNegative = 0.0
    gyro_hysteresis_dps: NonNegative = 0.0
    accel_hysteresis_mg: NonNegative = 0.0
    hysteresis_width_k: Positive = 3.0
    gyro_rate_dps_per_k_per_min: NonNegative = 0.0
    accel_rate_mg_per_k_per_min: NonNegative = 0.0
    reference_temperature_c: Finite = 25.0
    knee_temperature_c: Finite = 20.0
    knee_spread_k: NonNegative = 15.0
    knee_width_k: Positive = 10.0
    self_heating_k: NonNegative = 8.0
    warmup_time_constant_s: Positive = 300.0
    ambient_time_constant_s: Positive = 900.0
    heater_time_constant_s: Positive = 120.0
    temperature_resolution_k: NonNegative = 0.0
    temperature_zero_c: Finite = 25.0
    temperature_update_s: NonNegative = 0.0
    temperature_noise_k: NonNegative = 0.0
    temperature_offset_k: NonNegative = 0.0
    temperature_min_c: Finite = -40.0
    temperature_max_c: Finite = 85.0


class ImuThermalConfig(SensorConfigModel):
    """A thermal IMU in its environment: the part's figures and the flight's thermal state.

    Attributes
    ----------
    part : the part's thermal figures.
    preset : name of the part's preset (reported, not used by the model).
    start_temperature_c : temperature of the IMU's case at the start, °C (a cold soak); None:
        in equilibrium with the air (with a working heater: at its set point).
    power_on_s : when the IMU was powered on, s from the start (<= 0: before it); the die
        warms by ``self_heating_k`` from then on.
    ambient_offset_k : air around the IMU minus the outside air, K (a hot day, a warm bay).
    heater_setpoint_c : a heated IMU holds its case at least at this temperature, °C; None:
        no heater.
    heater_fails_at_s : when the heater stops, s from the start; None: it never does.
    """

    part: ImuThermalPart
    preset: str = ""
    start_temperature_c: Finite | None = None
    power_on_s: Annotated[float, Field(le=0.0, allow_inf_nan=False)] = 0.0
    ambient_offset_k: Finite = 0.0
    heater_setpoint_c: Finite | None = None
    heater_fails_at_s: NonNegative | None = None


@dataclass(frozen=True)
class ThermalUnit:
    """One unit's drawn thermal coefficients, per axis ``[fx, fy, fz, wx, wy, wz]``, SI.

    ``slope_far``, ``slope_knee``: bias per K (m/s²/K, rad/s/K); ``knee_k``, ``width_k``: K;
    ``hysteresis``: half the heating-to-cooling difference (m/s², rad/s); ``rate``: bias per
    K/s; ``scale_far``, ``scale_knee``: scale-factor error per K; ``sensor_offset_k``: the
    temperature sensor's offset. Arrays of shape (6,).
    """

    slope_far: np.ndarray
    slope_knee: np.ndarray
    knee_k: np.ndarray
    width_k: np.ndarray
    hysteresis: np.ndarray
    rate: np.ndarray
    scale_far: np.ndarray
    scale_knee: np.ndarray
    sensor_offset_k: float

    @classmethod
    def draw(cls, part: ImuThermalPart, rng: np.random.Generator) -> ThermalUnit:
        """Draw a unit from the part's figures (fixed order of draws)."""

        def pair(acc: float, gyr: float) -> np.ndarray:
            return np.array([acc, acc, acc, gyr, gyr, gyr], dtype=np.float64)

        tempco = pair(part.accel_tempco_mg_per_k * MG_MPS2, part.gyro_tempco_dps_per_k * DEG)
        gap = pair(part.accel_hysteresis_mg * MG_MPS2, part.gyro_hysteresis_dps * DEG)
        rate = pair(part.accel_rate_mg_per_k_per_min * MG_MPS2 * 60.0,
                    part.gyro_rate_dps_per_k_per_min * DEG * 60.0)
        scale = pair(part.accel_scale_tempco_ppm_per_k * 1e-6,
                     part.gyro_scale_tempco_ppm_per_k * 1e-6)
        z = rng.standard_normal((9, 6))
        knee = part.knee_temperature_c + KELVIN_AT_0_C + part.knee_spread_k * z[2]
        return cls(
            slope_far=SLOPE_FAR_RATIO * tempco * z[0],
            slope_knee=SLOPE_KNEE_RATIO * tempco * z[1],
            knee_k=knee,
            width_k=part.knee_width_k * np.exp(0.25 * z[3]),
            hysteresis=0.5 * gap * z[4],
            rate=rate * z[5],
            scale_far=SLOPE_FAR_RATIO * scale * z[6],
            scale_knee=SLOPE_KNEE_RATIO * scale * z[7],
            sensor_offset_k=float(part.temperature_offset_k * z[8][0]),
        )


def static_curve(
    unit: ThermalUnit, temperature_k: float | np.ndarray, reference_k: float,
    *, scale: bool = False,
) -> np.ndarray:
    """The curve ``g_i(T)`` (bias, or the scale-factor error with ``scale``) of every axis.

    Parameters
    ----------
    unit : ThermalUnit
    temperature_k : float or ndarray of shape (m,)
        Die temperature, K.
    reference_k : float
        Calibration temperature, K (the curve is zero there).
    scale : bool
        The scale-factor curve instead of the bias curve.

    Returns
    -------
    ndarray, shape (6,) for a float, (m, 6) for an array
        Bias (m/s², rad/s) or scale-factor error (dimensionless).
    """
    t = np.asarray(temperature_k, dtype=np.float64)[..., None]
    far, knee = (unit.scale_far, unit.scale_knee) if scale else (unit.slope_far, unit.slope_knee)
    w = unit.width_k
    bend = np.tanh((t - unit.knee_k) / w) - np.tanh((reference_k - unit.knee_k) / w)
    out: np.ndarray = far * (t - reference_k) + knee * w * bend
    return out


class ImuThermalModel:
    """Die temperature, thermal bias and scale factor of one IMU, stepped with the flight.

    Parameters
    ----------
    config : ImuThermalConfig
    rng : numpy.random.Generator
        Used only by this model: the unit's draws at construction, then the temperature
        sensor's noise.
    sea_level_temperature_offset_k : float
        The day's sea-level temperature offset of the atmosphere, K (the barometer's
        ``sea_level_temperature_offset_k``: one day for every sensor).

    Attributes
    ----------
    unit : ThermalUnit
    bias : list of 6 float
        Thermal bias of the last step, ``[f (m/s²), ω (rad/s)]``.
    scale : list of 6 float
        Thermal scale-factor error of the last step.
    die_temperature_k, case_temperature_k, air_temperature_k : float
        True temperatures of the last step, K.
    rate_k_per_s : float
        Rate of change of the die temperature over the last step, K/s.
    reported_temperature_k : float
        What the part reports (quantised, held between its updates), K.
    """

    def __init__(
        self, config: ImuThermalConfig, rng: np.random.Generator,
        sea_level_temperature_offset_k: float = 0.0,
    ) -> None:
        self.config = config
        part = config.part
        self._rng = rng
        self.unit = ThermalUnit.draw(part, rng)
        self._ref_k = part.reference_temperature_c + KELVIN_AT_0_C
        self._atm = TroposphereBaro(sea_level_temperature_offset_k)
        self._setpoint_k = (None if config.heater_setpoint_c is None
                            else config.heater_setpoint_c + KELVIN_AT_0_C)
        self._fail_s = config.heater_fails_at_s
        self._phi_warm = math.exp(-THERMAL_STEP_S / part.warmup_time_constant_s)
        self._phi_amb = math.exp(-THERMAL_STEP_S / part.ambient_time_constant_s)
        self._phi_heat = math.exp(-THERMAL_STEP_S / part.heater_time_constant_s)
        self._w_k = part.hysteresis_width_k
        self._t0_us: int | None = None
        self._next_us = 0
        self._next_report_us = 0
        self._report_period_us = round(part.temperature_update_s * 1e6)
        self.bias = [0.0] * 6
        self.scale = [0.0] * 6
        self.die_temperature_k = math.nan
        self.case_temperature_k = math.nan
        self.air_temperature_k = math.nan
        self.rate_k_per_s = 0.0
        self.reported_temperature_k = math.nan
        self._heat_k = 0.0
        self._play_k = math.nan

    # ------------------------------------------------------------------ state
    def air_temperature(self, alt_msl_m: float) -> float:
        """Air around the IMU at the geometric MSL altitude ``alt_msl_m``, K."""
        h_gp = ISA_R0_GEOPOTENTIAL_M * alt_msl_m / (ISA_R0_GEOPOTENTIAL_M + alt_msl_m)
        return self._atm.pressure_temperature(h_gp, 0.0)[1] + self.config.ambient_offset_k

    def _heater_target(self, t_s: float, air_k: float) -> tuple[float, bool]:
        """Where the case is driven and whether the heater drives it."""
        sp = self._setpoint_k
        working = sp is not None and (self._fail_s is None or t_s < self._fail_s)
        if working and sp is not None and sp > air_k:
            return sp, True
        return air_k, False

    def _start(self, time_us: int, alt_msl_m: float) -> None:
        c = self.config
        part = c.part
        self._t0_us = time_us
        air = self.air_temperature(alt_msl_m)
        target, _ = self._heater_target(0.0, air)
        self.case_temperature_k = (target if c.start_temperature_c is None
                                   else c.start_temperature_c + KELVIN_AT_0_C)
        self._heat_k = part.self_heating_k * (
            1.0 - math.exp(min(0.0, c.power_on_s) / part.warmup_time_constant_s))
        self.air_temperature_k = air
        self.die_temperature_k = self.case_temperature_k + self._heat_k
        self._play_k = self.die_temperature_k
        self.rate_k_per_s = 0.0
        self._next_us = time_us
        self._next_report_us = time_us

    def _advance(self, t_s: float, alt_msl_m: float) -> None:
        """One thermal step of length :data:`THERMAL_STEP_S` ending at ``t_s``."""
        part = self.config.part
        air = self.air_temperature(alt_msl_m)
        target, heating = self._heater_target(t_s, air)
        phi = self._phi_heat if heating else self._phi_amb
        self.case_temperature_k = target + (self.case_temperature_k - target) * phi
        if t_s >= self.config.power_on_s:
            rise = part.self_heating_k
            self._heat_k = rise + (self._heat_k - rise) * self._phi_warm
        die = self.case_temperature_k + self._heat_k
        self.rate_k_per_s = (die - self.die_temperature_k) / THERMAL_STEP_S
        self.die_temperature_k = die
        self.air_temperature_k = air
        w = self._w_k
        self._play_k = min(max(self._play_k, die - w), die + w)

    def _errors(self) -> None:
        u = self.unit
        t = self.die_temperature_k
        g = static_curve(u, t, self._ref_k)
        memory = (t - self._play_k) / self._w_k
        b = g + u.hysteresis * memory + u.rate * self.rate_k_per_s
        self.bias = b.tolist()
        self.scale = static_curve(u, t, self._ref_k, scale=True).tolist()

    def _report(self) -> None:
        part = self.config.part
        t_c = (self.die_temperature_k - KELVIN_AT_0_C + self.unit.sensor_offset_k
               + part.temperature_noise_k * float(self._rng.standard_normal()))
        q = part.temperature_resolution_k
        if q > 0.0:
            z = part.temperature_zero_c
            t_c = z + round((t_c - z) / q) * q
        t_c = min(max(t_c, part.temperature_min_c), part.temperature_max_c)
        self.reported_temperature_k = t_c + KELVIN_AT_0_C

    def step(self, time_us: int, alt_msl_m: float) -> None:
        """Advance to ``time_us`` (simulated, µs) at the true geometric MSL altitude (m).

        Updates :attr:`bias`, :attr:`scale`, the temperatures and
        :attr:`reported_temperature_k`. The first call sets the start.
        """
        if self._t0_us is None:
            self._start(time_us, alt_msl_m)
            self._errors()
        step_us = round(THERMAL_STEP_S * 1e6)
        changed = False
        t0 = self._t0_us
        assert t0 is not None
        while time_us >= self._next_us + step_us:
            self._next_us += step_us
            self._advance((self._next_us - t0) * 1e-6, alt_msl_m)
            changed = True
        if changed:
            self._errors()
        if time_us >= self._next_report_us:
            self._report()
            period = self._report_period_us
            if period <= 0:
                self._next_report_us = time_us + 1
            else:
                while self._next_report_us <= time_us:
                    self._next_report_us += period
