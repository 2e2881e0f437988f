"""Shared scenarios and helpers of the NavFilter tests (test_filter*.py)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from fusion import earth
from fusion.config import FilterConfig
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from sim.samples import GnssFix
from tests.helpers.nav_synth import Scenario, SensorErrors

CFG = FilterConfig()
ERRORS = SensorErrors.from_config(CFG)


def run(nav: NavFilter, samples: Iterable[object]) -> list[NavEstimate]:
    out: list[NavEstimate] = []
    for s in samples:
        out.extend(nav.step(s))
    return out


def errors_at(sc: Scenario, est: NavEstimate) -> tuple[np.ndarray, np.ndarray, float]:
    """Position (NED m) and velocity errors and the yaw error (rad) of an estimate."""
    kin = sc.traj(np.array([est.time_us * 1e-6]))
    pos = np.array(earth.ned_offset_m(est.lat_rad, est.lon_rad, est.alt_msl_m, *kin.lla[0]))
    vel = est.v_ned_mps - kin.v_ned_mps[0]
    from fusion.rotations import quat_to_euler

    yaw_true = quat_to_euler(kin.q_nb[0])[2]
    dyaw = (est.euler_rad[2] - yaw_true + math.pi) % (2 * math.pi) - math.pi
    return pos, vel, float(dyaw)


def earth_distance_m(lat0: float, lon0: float, lat1: float, lon1: float) -> float:
    n, e, _ = earth.ned_offset_m(lat1, lon1, 0.0, lat0, lon0, 0.0)
    return math.hypot(n, e)


def with_gm_gnss_error(
    sc: Scenario, rng: np.random.Generator, sigma_h: float, sigma_v: float, tau_s: float,
    b0: np.ndarray,
) -> tuple[Scenario, dict[int, np.ndarray]]:
    """The scenario with a Gauss-Markov position error (N, E, D; starting at ``b0``) added to
    every fix, the fixes reporting the total accuracy (white part as generated plus the GM
    sigma in quadrature, as a receiver's eph does). Returns it and the bias at each fix time."""
    sig = np.array([sigma_h, sigma_h, sigma_v])
    b = np.asarray(b0, dtype=float).copy()
    last: int | None = None
    biases: dict[int, np.ndarray] = {}
    out: list[object] = []
    for smp in sc.samples:
        if isinstance(smp, GnssFix):
            if last is not None:
                k = math.exp(-(smp.time_us - last) * 1e-6 / tau_s)
                b = k * b + math.sqrt(1.0 - k * k) * sig * rng.standard_normal(3)
            last = smp.time_us
            biases[smp.time_us] = b.copy()
            t = earth.local_terms(smp.lat_rad, smp.alt_msl_m)
            smp = dataclasses.replace(
                smp,
                lat_rad=smp.lat_rad + b[0] / t.rho_n_m,
                lon_rad=smp.lon_rad + b[1] / (t.rho_e_m * t.cos_lat),
                alt_msl_m=smp.alt_msl_m - b[2],
                eph_m=math.hypot(smp.eph_m, sigma_h),
                epv_m=math.hypot(smp.epv_m, sigma_v),
            )
        out.append(smp)
    return dataclasses.replace(sc, samples=out), biases
