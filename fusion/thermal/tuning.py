"""The thermal strategy's settings, the calibration polynomial, and the blind filter's noise.

Human units never appear here: a calibration file is read and converted by the shell
(:mod:`hil.thermal_cal`); a part's temperature coefficients come from its datasheet through
:mod:`hil.tuning`.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    model_validator,
)

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_G = 9.80665


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ThermalPolynomial(_Frozen):
    """One sensor's bias-versus-temperature polynomial, as PX4 and ArduPilot store it.

    ``offset(T) = c0 + c1 x + c2 x^2 + c3 x^3`` per axis with ``x = clamp(T, t_min_k,
    t_max_k) - t_ref_k``; the corrected sample is ``raw - (offset(T) - offset(T_cal))`` where
    ``T_cal`` is ``cal_temp_k`` (ArduPilot: the temperature of the ordinary offset
    calibration) or, when it is ``None``, the offset is absolute (PX4: ``corrected = raw -
    offset(T)``).
    """

    coeffs: tuple[Vec3, Vec3, Vec3, Vec3]
    """``c0..c3`` (ascending powers), each per axis, SI per K^i (rad/s or m/s^2)."""
    t_ref_k: float
    t_min_k: float
    t_max_k: float
    cal_temp_k: float | None = None

    def offset(self, temperature_k: float) -> Vec3:
        """What to subtract from a raw sample at ``temperature_k``."""
        o = _eval(self.coeffs, self._x(temperature_k))
        if self.cal_temp_k is None:
            return o
        o0 = _eval(self.coeffs, self._x(self.cal_temp_k))
        return (o[0] - o0[0], o[1] - o0[1], o[2] - o0[2])

    def _x(self, t_k: float) -> float:
        return min(max(t_k, self.t_min_k), self.t_max_k) - self.t_ref_k


class ThermalCalibration(_Frozen):
    """A unit's thermal calibration: the gyro and the accelerometer polynomial."""

    source: Literal["px4", "ardupilot"]
    gyro: ThermalPolynomial
    """rad/s."""
    accel: ThermalPolynomial
    """m/s^2."""

    def offsets(self, temperature_k: float) -> tuple[Vec3, Vec3]:
        """``(gyro rad/s, accel m/s^2)`` to subtract from a raw sample at ``temperature_k``."""
        return self.gyro.offset(temperature_k), self.accel.offset(temperature_k)


def _eval(poly: tuple[Vec3, Vec3, Vec3, Vec3], x: float) -> Vec3:
    c0, c1, c2, c3 = poly
    return (
        c0[0] + x * (c1[0] + x * (c2[0] + x * c3[0])),
        c0[1] + x * (c1[1] + x * (c2[1] + x * c3[1])),
        c0[2] + x * (c1[2] + x * (c2[2] + x * c3[2])),
    )


class ThermalTuning(_Frozen):
    """The thermal strategy (``mode``) and what it assumes about the part and its temperature.

    The defaults are Bosch BMI088's datasheet figures (BST-BMI088-DS001, rev. 1.9: gyro zero
    rate offset change over temperature 0.015 deg/s/K, accelerometer offset temperature drift
    0.2 mg/K, temperature sensor 0.125 K/LSB updated every 1.28 s, operating range -40..85
    degC); :func:`hil.tuning.thermal_tuning` sets them from the simulated part.
    """

    mode: Literal["off", "blind", "states", "cal"] = "off"
    gyro_tempco_rps_per_k: PositiveFloat = math.radians(0.015)
    """Gyro bias temperature coefficient (1 sigma over units), rad/s/K."""
    accel_tempco_mps2_per_k: PositiveFloat = 0.2e-3 * _G
    """Accelerometer bias temperature coefficient (1 sigma over units), m/s^2/K."""
    rate_k_per_s: PositiveFloat = 0.02
    """Plausible die-temperature rate (1 sigma) the blind noise admits: a warm-up of ~10 K
    over a ~500 s time constant starts at 0.02 K/s; a climb at 5 m/s through the standard
    lapse rate (6.5 K/km) gives 0.03 K/s of air temperature, lagged by the case, K/s."""
    horizon_s: PositiveFloat = 300.0
    """Time over which the blind random walk must reach the drift a steady rate makes, s."""
    residual_states: NonNegativeFloat = 0.5
    """Share of the blind thermal noise kept with ``states`` (what a line in temperature does
    not model: the curve's bend, hysteresis)."""
    residual_cal: NonNegativeFloat = 0.3
    """Share of the blind thermal noise kept with ``cal`` (hysteresis and ageing the factory
    cubic does not follow)."""
    tempco_walk_share: NonNegativeFloat = 0.2
    """``states``: how far the coefficient may move over ``horizon_s``, as a share of the
    tempco (a line re-fitted to a curve changes slope as the temperature moves along it)."""
    min_k: float = 233.15
    """Lowest plausible die temperature (the part's operating range), K."""
    max_k: float = 358.15
    """Highest plausible die temperature, K."""
    max_slew_k_per_s: PositiveFloat = 1.0
    """Fastest plausible die-temperature change; a faster jump is a bad reading, K/s."""
    quantum_k: NonNegativeFloat = 0.125
    """The temperature sensor's resolution (a jump test allows two), K."""
    update_period_s: PositiveFloat = 1.28
    """The temperature sensor's update period, s."""
    stuck_updates: PositiveInt = 100
    """A reading identical for this many update periods is stuck (a live die with a 0.125 K
    sensor and noise changes its last bit far more often), counted and rejected."""
    stuck_min_s: PositiveFloat = 128.0
    """...and for at least this long: a part that updates with every sample repeats a coarse
    reading for many updates while its die warms by less than a quantum, s."""
    calibration: ThermalCalibration | None = None
    """``cal``: the calibration polynomial (required in that mode)."""

    @model_validator(mode="after")
    def _check(self) -> ThermalTuning:
        if self.mode == "cal" and self.calibration is None:
            raise ValueError("thermal mode 'cal' needs a calibration")
        if not self.min_k < self.max_k:
            raise ValueError("thermal min_k must be below max_k")
        return self

    def thermal_rate_density(self) -> tuple[float, float]:
        """``(gyro, accel)`` random-walk density of the blind filter's thermal part,
        (rad/s)^2/s and (m/s^2)^2/s: a drift at ``tempco * rate`` reaches ``tempco * rate *
        horizon`` after ``horizon_s``; a random walk of density ``q`` reaches
        ``sqrt(q horizon)`` at 1 sigma, so ``q = (tempco rate)^2 horizon``."""
        rg = self.gyro_tempco_rps_per_k * self.rate_k_per_s
        ra = self.accel_tempco_mps2_per_k * self.rate_k_per_s
        return rg * rg * self.horizon_s, ra * ra * self.horizon_s

    def residual_share(self) -> float:
        """The share of the blind thermal noise the mode keeps (0 with ``off``)."""
        return {"off": 0.0, "blind": 1.0, "states": self.residual_states,
                "cal": self.residual_cal}[self.mode]  # fmt: skip

    def tempco_walk_density(self) -> tuple[float, float]:
        """``states``: random-walk density of the gyro and accelerometer coefficients,
        (rad/s/K)^2/s and (m/s^2/K)^2/s."""
        s = self.tempco_walk_share
        g = s * self.gyro_tempco_rps_per_k
        a = s * self.accel_tempco_mps2_per_k
        return g * g / self.horizon_s, a * a / self.horizon_s


def widened_bias_sigma(sigma: float, tau_s: float, q_extra: float) -> float:
    """The Gauss-Markov sigma whose driving noise (``2 sigma^2 / tau`` per second, the random
    walk of :mod:`fusion.error_model`) is that of ``sigma`` plus ``q_extra`` ((unit)^2/s)."""
    return math.sqrt(sigma * sigma + 0.5 * q_extra * tau_s)
