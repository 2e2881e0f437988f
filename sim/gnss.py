"""GNSS receiver model: position and velocity fixes with Gauss–Markov plus white errors.

Error model (NED, metres and m/s), for each fix at time ``t``::

    e_pos = x_pos(t) + w_pos,   x_pos: first-order Gauss–Markov (sigma_gm, tau), per axis
    e_vel = x_vel(t) + w_vel,   x_vel: first-order Gauss–Markov (sigma_gm, tau), per axis

with separate horizontal (N, E) and vertical (D) figures. The Gauss–Markov states are
propagated exactly over the actual time between fixes and start from their stationary
distribution, so the error statistics are stationary from the first fix.

Reported accuracy: ``eph_m`` is the **per-axis** 1-sigma horizontal accuracy,
``sqrt(sigma_gm_h² + sigma_white_h²)`` (the standard deviation of the north error, and of the
east error), which is how PX4's EKF2 uses ``eph`` / u-blox ``hAcc`` (one variance for both
horizontal axes); ``epv_m`` likewise for the vertical, ``speed_accuracy_mps`` for the
horizontal velocity. ``accuracy_report_scale`` ≠ 1 makes the receiver over- or
under-report (to test a filter's robustness to a dishonest receiver).

The error state (:class:`GnssErrorState`) is separate from the measurement: a fault-injection
layer can call :meth:`GnssModel.advance_errors`, alter the returned :class:`GnssErrors`
(spoofing offsets, a jump) and build the fix with :meth:`GnssModel.make_fix`, or drop fixes
(outage) while the receiver's errors keep evolving.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from sim._sensor_common import (
    NonNegative,
    Positive,
    SensorConfigModel,
    gauss_markov_coefficients,
    meridian_prime_radii_m,
)
from sim.samples import GnssFix, Truth


class GnssConfig(SensorConfigModel):
    """GNSS receiver figures (1-sigma, per axis).

    Attributes
    ----------
    rate_hz : fix rate, Hz.
    latency_s : delay between a fix's time of validity and its output, s.
    fix_type : GPS_FIX_TYPE reported (3 = 3D).
    satellites_visible : satellite count reported.
    horizontal_gm_sigma_m, horizontal_gm_tau_s : Gauss–Markov position error, N and E.
    horizontal_white_sigma_m : white position noise, N and E, m.
    vertical_gm_sigma_m, vertical_gm_tau_s, vertical_white_sigma_m : the same, Down.
    velocity_gm_sigma_mps, velocity_gm_tau_s, velocity_white_sigma_mps : horizontal velocity.
    vertical_velocity_gm_sigma_mps, vertical_velocity_white_sigma_mps : vertical velocity
        (same correlation time as the horizontal).
    accuracy_report_scale : reported accuracies = scale × the true model sigmas.
    """

    rate_hz: Positive = 5.0
    latency_s: NonNegative = 0.0
    fix_type: int = Field(default=3, ge=0, le=8)
    satellites_visible: int = Field(default=12, ge=0, le=255)
    horizontal_gm_sigma_m: NonNegative
    horizontal_gm_tau_s: Positive
    horizontal_white_sigma_m: NonNegative
    vertical_gm_sigma_m: NonNegative
    vertical_gm_tau_s: Positive
    vertical_white_sigma_m: NonNegative
    velocity_gm_sigma_mps: NonNegative
    velocity_gm_tau_s: Positive
    velocity_white_sigma_mps: NonNegative
    vertical_velocity_gm_sigma_mps: NonNegative
    vertical_velocity_white_sigma_mps: NonNegative
    accuracy_report_scale: Positive = 1.0


@dataclass(frozen=True)
class GnssParams:
    """A :class:`GnssConfig` in SI arrays, order ``[pN, pE, pD, vN, vE, vD]``, shapes (6,)."""

    gm_sigma: NDArray[np.float64]
    gm_tau_s: NDArray[np.float64]
    white_sigma: NDArray[np.float64]
    latency_us: int
    eph_m: float
    epv_m: float
    speed_accuracy_mps: float

    @classmethod
    def from_config(cls, c: GnssConfig) -> GnssParams:
        """Convert once."""
        h, v = c.horizontal_gm_sigma_m, c.vertical_gm_sigma_m
        vh, vv = c.velocity_gm_sigma_mps, c.vertical_velocity_gm_sigma_mps
        k = c.accuracy_report_scale
        return cls(
            gm_sigma=np.array([h, h, v, vh, vh, vv]),
            gm_tau_s=np.array(
                [c.horizontal_gm_tau_s] * 2 + [c.vertical_gm_tau_s] + [c.velocity_gm_tau_s] * 3
            ),
            white_sigma=np.array(
                [c.horizontal_white_sigma_m] * 2
                + [c.vertical_white_sigma_m]
                + [c.velocity_white_sigma_mps] * 2
                + [c.vertical_velocity_white_sigma_mps]
            ),
            latency_us=round(c.latency_s * 1e6),
            eph_m=k * math.hypot(h, c.horizontal_white_sigma_m),
            epv_m=k * math.hypot(v, c.vertical_white_sigma_m),
            speed_accuracy_mps=k * math.hypot(vh, c.velocity_white_sigma_mps),
        )


@dataclass
class GnssErrorState:
    """Mutable Gauss–Markov state of the receiver errors.

    Attributes
    ----------
    gm : ndarray (6,)
        ``[pN, pE, pD (m), vN, vE, vD (m/s)]`` correlated error components.
    last_time_us : int or None
        Time of validity the state refers to (None before the first fix).
    """

    gm: NDArray[np.float64] = field(default_factory=lambda: np.zeros(6))
    last_time_us: int | None = None


@dataclass(frozen=True, slots=True)
class GnssErrors:
    """Errors applied to one fix: position NED (3,) m and velocity NED (3,) m/s."""

    pos_ned_m: NDArray[np.float64]
    vel_ned_mps: NDArray[np.float64]


class GnssModel:
    """GNSS receiver error model with its own random generator.

    Parameters
    ----------
    config : GnssConfig
    rng : numpy.random.Generator
        Used only by this model.

    Attributes
    ----------
    params : GnssParams
    state : GnssErrorState
    """

    def __init__(self, config: GnssConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.params = GnssParams.from_config(config)
        self._rng = rng
        self.state = GnssErrorState(gm=rng.standard_normal(6) * self.params.gm_sigma)

    def advance_errors(self, time_us: int) -> GnssErrors:
        """Propagate the error state to ``time_us`` and draw this fix's errors.

        Parameters
        ----------
        time_us : int
            Time of validity of the fix, µs (non-decreasing between calls).

        Returns
        -------
        GnssErrors
        """
        p, st = self.params, self.state
        z = self._rng.standard_normal(12)
        if st.last_time_us is not None:
            dt = (time_us - st.last_time_us) * 1e-6
            if dt < 0.0:
                raise ValueError("GNSS fix times must not go backwards")
            for j in range(6):
                phi, q = gauss_markov_coefficients(float(p.gm_sigma[j]), float(p.gm_tau_s[j]), dt)
                st.gm[j] = phi * st.gm[j] + q * z[j]
        st.last_time_us = time_us
        err = st.gm + z[6:] * p.white_sigma
        return GnssErrors(pos_ned_m=err[:3], vel_ned_mps=err[3:])

    def make_fix(self, truth: Truth, errors: GnssErrors) -> GnssFix:
        """Build a fix from the truth and the given errors (time of validity = truth time).

        Parameters
        ----------
        truth : Truth
        errors : GnssErrors

        Returns
        -------
        GnssFix
        """
        r_m, r_n = meridian_prime_radii_m(truth.lat_rad)
        dn, de, dd = (float(x) for x in errors.pos_ned_m)
        p = self.params
        return GnssFix(
            time_us=truth.time_us,
            lat_rad=truth.lat_rad + dn / (r_m + truth.alt_msl_m),
            lon_rad=truth.lon_rad + de / ((r_n + truth.alt_msl_m) * math.cos(truth.lat_rad)),
            alt_msl_m=truth.alt_msl_m - dd,
            v_ned_mps=np.asarray(truth.v_ned_mps, dtype=np.float64) + errors.vel_ned_mps,
            eph_m=p.eph_m,
            epv_m=p.epv_m,
            speed_accuracy_mps=p.speed_accuracy_mps,
            fix_type=self.config.fix_type,
            satellites_visible=self.config.satellites_visible,
        )

    def measure(self, truth: Truth) -> GnssFix:
        """One fix valid at ``truth.time_us`` (errors advanced, then applied)."""
        return self.make_fix(truth, self.advance_errors(truth.time_us))
