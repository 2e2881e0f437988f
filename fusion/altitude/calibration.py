"""Online calibration of P4's non-standard-atmosphere scale ``s`` and bias ``b`` against GNSS
height (a two-state Kalman filter)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import Field, PositiveFloat

from fusion.altitude.atmosphere import (
    BIAS_PER_PRESSURE_M_PER_PA,
    geopotential_from_geometric,
    isa_temperature_k,
    scale_from_temperature,
)
from fusion.altitude.common import Frozen
from physconst import (
    ISA_H0_M,
    ISA_T0_K,
)


class BaroCalibrationConfig(Frozen):
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

