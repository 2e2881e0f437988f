"""Synthetic navigation scenarios for the fusion tests: analytic trajectories, ideal IMU from
them, and sensor errors drawn *exactly* from the filter's own error model (white noise plus
first-order Gauss-Markov biases), so statistical tests judge the filter, not model mismatch.

Everything is deterministic for a given ``numpy.random.Generator``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.config import FilterConfig
from fusion.filter import NavFilter
from fusion.rotations import dcm_to_rotvec, euler_to_quat, quat_to_dcm
from fusion.trajectory import SplineTrajectory, ideal_increments, imu_rates
from physconst.airdata import impact_pressure_pa
from physconst.geomag import DEFAULT_DECIMAL_YEAR, magnetic_field_ned_t
from physconst.isa import isa_pressure_pa as height_to_pressure
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample

FloatArray = NDArray[np.float64]
#: Earth field at the flights' start (47.4 N 8.5 E, 600 m) on the default date, NED, tesla: the
#: World Magnetic Model's, the filter's default reference (declination 3.5 deg, inclination
#: 63.5 deg). Held constant: over the few km of a test flight the model changes by < 0.02 deg.
FIELD_N_T = np.array(
    magnetic_field_ned_t(math.radians(47.4), math.radians(8.5), 600.0, DEFAULT_DECIMAL_YEAR).ned_t
)


def smooth_pulse(t: FloatArray, t0: float, t1: float, ramp: float) -> FloatArray:
    """0 outside [t0, t1], 1 inside, with raised-cosine ramps of length ``ramp``."""
    up = np.clip((t - t0) / ramp, 0.0, 1.0)
    down = np.clip((t1 - t) / ramp, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * up)) * 0.5 * (1.0 - np.cos(np.pi * down))


@dataclass
class Flight:
    """A fixed-wing-like flight: constant airspeed-ish ground speed, coordinated turns, climbs.

    ``turns``: (start_s, end_s, rate_rps); ``climbs``: (start_s, end_s, rate_mps, up positive).
    ``crab_rad``: heading minus track (a steady crosswind), ``aoa_rad``: pitch minus flight path.
    """

    duration_s: float
    speed_mps: float = 40.0
    heading0_rad: float = 0.3
    turns: list[tuple[float, float, float]] = field(default_factory=list)
    climbs: list[tuple[float, float, float]] = field(default_factory=list)
    crab_rad: float = 0.0
    aoa_rad: float = 0.04
    lat0_rad: float = math.radians(47.4)
    lon0_rad: float = math.radians(8.5)
    alt0_m: float = 600.0
    speed_wave_mps: float = 0.0
    """Amplitude of a slow speed oscillation (longitudinal acceleration), m/s."""
    ramp_s: float = 3.0
    wind_ne_mps: tuple[float, float] = (0.0, 0.0)
    """Steady horizontal wind, m/s: with it ``speed`` and the heading are air-relative (the
    aircraft flies ``speed`` through the air along its heading, zero sideslip) and the ground
    velocity is that plus the wind."""

    def turn_rate(self, t: FloatArray) -> FloatArray:
        out = np.zeros_like(t)
        for t0, t1, r in self.turns:
            out += r * smooth_pulse(t, t0, t1, self.ramp_s)
        return out

    def climb_rate(self, t: FloatArray) -> FloatArray:
        out = np.zeros_like(t)
        for t0, t1, r in self.climbs:
            out += r * smooth_pulse(t, t0, t1, self.ramp_s)
        return out

    def speed(self, t: FloatArray) -> FloatArray:
        return self.speed_mps + self.speed_wave_mps * np.sin(2.0 * np.pi * t / 40.0)

    def truth(self, rate_hz: float = 100.0) -> SplineTrajectory:
        """Integrate the kinematics on a fine grid and spline them (knots at ``rate_hz``)."""
        fine = 10
        t = np.arange(0.0, self.duration_s + 1e-9, 1.0 / (rate_hz * fine))
        dt = t[1] - t[0]
        psi_dot = self.turn_rate(t)
        psi = self.heading0_rad + np.concatenate(
            [[0.0], np.cumsum(0.5 * (psi_dot[1:] + psi_dot[:-1]) * dt)]
        )
        spd = self.speed(t)
        climb = self.climb_rate(t)
        wn, we = self.wind_ne_mps
        v = np.column_stack([spd * np.cos(psi) + wn, spd * np.sin(psi) + we, -climb])
        h = self.alt0_m + np.concatenate([[0.0], np.cumsum(0.5 * (climb[1:] + climb[:-1]) * dt)])
        lat = np.empty_like(t)
        lon = np.empty_like(t)
        lat[0], lon[0] = self.lat0_rad, self.lon0_rad
        # trapezoid on the geodetic rates (second order; the spline below is what counts)
        for k in range(1, len(t)):
            r_m, r_n = earth.principal_radii(lat[k - 1])
            dlat = v[k - 1, 0] / (r_m + h[k - 1])
            dlon = v[k - 1, 1] / ((r_n + h[k - 1]) * math.cos(lat[k - 1]))
            lat_p = lat[k - 1] + dlat * dt
            r_m2, r_n2 = earth.principal_radii(lat_p)
            dlat2 = v[k, 0] / (r_m2 + h[k])
            dlon2 = v[k, 1] / ((r_n2 + h[k]) * math.cos(lat_p))
            lat[k] = lat[k - 1] + 0.5 * (dlat + dlat2) * dt
            lon[k] = lon[k - 1] + 0.5 * (dlon + dlon2) * dt
        roll = np.arctan(spd * psi_dot / 9.81)
        pitch = np.arctan2(climb, spd) + self.aoa_rad
        yaw = psi + self.crab_rad
        q = euler_to_quat(np.column_stack([roll, pitch, yaw]))
        sel = slice(None, None, fine)
        return SplineTrajectory(t[sel], np.column_stack([lat, lon, h])[sel], v[sel], q[sel])


@dataclass
class SensorErrors:
    """Sensor error model (SI) matching ``FilterConfig``'s."""

    gyro_noise: float
    accel_noise: float
    gyro_bias_sigma: float
    gyro_bias_tau_s: float
    accel_bias_sigma: float
    accel_bias_tau_s: float
    baro_noise_m: float
    baro_bias_sigma_m: float
    baro_bias_tau_s: float
    accel_turn_on_sigma: float = 0.0
    """Run-to-run accelerometer bias (a random constant on top of the Gauss-Markov part),
    m/s^2; drawn only when > 0 (so scenarios without it keep their random streams)."""
    gyro_turn_on_sigma: float = 0.0
    """Run-to-run gyro bias, rad/s (drawn only when > 0)."""

    @classmethod
    def from_config(cls, cfg: FilterConfig, *, turn_on: bool = False) -> SensorErrors:
        """The filter's own error model; ``turn_on`` adds its turn-on bias sigmas (a real
        sensor's run-to-run bias, which a stationary alignment cannot tell from tilt)."""
        i = cfg.imu
        return cls(
            i.gyro_noise_density_rps_rthz,
            i.accel_noise_density_mps2_rthz,
            i.gyro_bias_sigma_rps,
            i.gyro_bias_tau_s,
            i.accel_bias_sigma_mps2,
            i.accel_bias_tau_s,
            cfg.baro.noise_m,
            cfg.baro.bias_sigma_m,
            cfg.baro.bias_tau_s,
            i.accel_turn_on_sigma_mps2 if turn_on else 0.0,
            i.gyro_turn_on_sigma_rps if turn_on else 0.0,
        )


def gauss_markov(
    rng: np.random.Generator, n: int, dim: int, sigma: float, tau: float, dt: float
) -> FloatArray:
    """Stationary first-order Gauss-Markov sequence (n, dim), exact discretisation."""
    a = math.exp(-dt / tau)
    s = sigma * math.sqrt(1.0 - a * a)
    out = np.empty((n, dim))
    x = rng.normal(0.0, sigma, dim)
    w = rng.normal(0.0, s, (n, dim))
    for k in range(n):
        out[k] = x
        x = a * x + w[k]
    return out


@dataclass
class Prepared:
    """The noise-free part of a scenario (expensive: compute once, reuse for every seed)."""

    flight: Flight
    traj: SplineTrajectory
    imu_rate_hz: float
    edges_us: NDArray[np.int64]
    f_b: FloatArray
    """(K, 3) ideal specific force (interval means)."""
    w_b: FloatArray
    """(K, 3) ideal angular rate (interval means)."""


def prepare(flight: Flight, imu_rate_hz: float = 100.0) -> Prepared:
    traj = flight.truth()
    n = round(flight.duration_s * imu_rate_hz)
    period_us = round(1e6 / imu_rate_hz)
    edges_us = period_us * np.arange(n + 1, dtype=np.int64)
    inc = ideal_increments(traj, edges_us * 1e-6)
    dt = period_us * 1e-6
    return Prepared(flight, traj, imu_rate_hz, edges_us, inc.dv_b / dt, inc.dtheta_b / dt)


@dataclass
class Scenario:
    """Samples in arrival order plus what the tests need to judge the filter."""

    samples: list[object]
    traj: SplineTrajectory
    imu_time_s: FloatArray
    accel_bias: FloatArray
    """(K, 3) true accelerometer bias at each IMU sample."""
    gyro_bias: FloatArray
    baro_bias_time_s: FloatArray
    baro_bias: FloatArray

    def true_bias_at(self, t_s: float) -> tuple[FloatArray, FloatArray, float]:
        """True accelerometer bias, gyro bias and baro bias at ``t_s`` (nearest sample)."""
        k = int(np.clip(np.searchsorted(self.imu_time_s, t_s - 1e-9), 0, len(self.imu_time_s) - 1))
        if len(self.baro_bias_time_s):
            j = int(
                np.clip(
                    np.searchsorted(self.baro_bias_time_s, t_s - 1e-9),
                    0,
                    len(self.baro_bias_time_s) - 1,
                )
            )
            bb = float(self.baro_bias[j])
        else:
            bb = math.nan
        return self.accel_bias[k], self.gyro_bias[k], bb


def make_scenario(
    prep: Prepared | Flight,
    rng: np.random.Generator,
    errors: SensorErrors | None,
    *,
    imu_rate_hz: float = 100.0,
    gnss_rate_hz: float = 5.0,
    gnss_sigma_h_m: float = 1.5,
    gnss_sigma_v_m: float = 2.5,
    gnss_sigma_vel_mps: float = 0.15,
    gnss_latency_s: float = 0.0,
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    baro_rate_hz: float | None = 25.0,
    baro_offset_m: float = 30.0,
    mag_rate_hz: float | None = None,
    mag_noise_t: float = 0.2e-6,
    gnss_outages: list[tuple[float, float]] | None = None,
    gnss_glitches: dict[int, FloatArray] | None = None,
    mag_hard_iron_t: tuple[float, float, float] = (0.0, 0.0, 0.0),
    vibration_accel_mps2: float = 0.0,
    vibration_gyro_rps: float = 0.0,
) -> Scenario:
    """Ideal IMU from the flight plus sensor errors; GNSS/baro/mag from the truth plus noise.

    ``errors=None`` means perfect sensors (no noise, no bias). ``gnss_glitches`` maps a fix
    index (0 = first fix) to the NED offset (m) of that fix from the true antenna position
    (replacing its noise, so the glitch size is exact). ``mag_hard_iron_t``: a constant
    body-axis offset of the magnetometer (T). ``vibration_*``: extra white noise per IMU
    sample (a hovering multicopter's propellers), 1-sigma; drawn only when > 0.
    """
    if isinstance(prep, Flight):
        prep = prepare(prep, imu_rate_hz)
    traj, edges_us = prep.traj, prep.edges_us
    n = len(edges_us) - 1
    dt = (edges_us[1] - edges_us[0]) * 1e-6
    f, w = prep.f_b, prep.w_b
    if errors is not None:
        ba = gauss_markov(rng, n, 3, errors.accel_bias_sigma, errors.accel_bias_tau_s, dt)
        bg = gauss_markov(rng, n, 3, errors.gyro_bias_sigma, errors.gyro_bias_tau_s, dt)
        if errors.accel_turn_on_sigma > 0.0:
            ba = ba + rng.normal(0.0, errors.accel_turn_on_sigma, 3)
        if errors.gyro_turn_on_sigma > 0.0:
            bg = bg + rng.normal(0.0, errors.gyro_turn_on_sigma, 3)
        f = f + ba + rng.normal(0.0, errors.accel_noise / math.sqrt(dt), (n, 3))
        w = w + bg + rng.normal(0.0, errors.gyro_noise / math.sqrt(dt), (n, 3))
        if vibration_accel_mps2 > 0.0:
            f = f + rng.normal(0.0, vibration_accel_mps2, (n, 3))
        if vibration_gyro_rps > 0.0:
            w = w + rng.normal(0.0, vibration_gyro_rps, (n, 3))
    else:
        ba = np.zeros((n, 3))
        bg = np.zeros((n, 3))
    timed: list[tuple[int, int, object]] = []
    for k, t_us in enumerate(edges_us[1:].tolist()):
        timed.append((t_us, 0, ImuSample(t_us, dt, f[k], w[k])))
    # GNSS
    g_period = round(1e6 / gnss_rate_hz)
    g_times = np.arange(g_period, int(edges_us[-1]) + 1, g_period, dtype=np.int64)
    kin = traj(g_times * 1e-6)
    arm = np.asarray(lever_arm_b_m, dtype=float)
    c_nb = quat_to_dcm(kin.q_nb)
    omega_all, _ = imu_rates(kin)
    for i, t_us in enumerate(g_times.tolist()):
        ts = t_us * 1e-6
        if gnss_outages and any(a <= ts < b for a, b in gnss_outages):
            continue
        arm_n = c_nb[i] @ arm
        lat, lon, h = kin.lla[i]
        rho = earth.local_terms(lat, h)
        v_ant = (
            kin.v_ned_mps[i]
            + c_nb[i] @ np.cross(omega_all[i], arm)
            - np.cross(omega_in_n(lat, h, kin.v_ned_mps[i]), arm_n)
        )
        if errors is None:
            noise = np.zeros(3)
            vnoise = np.zeros(3)
        else:
            noise = rng.normal(0.0, 1.0, 3) * [gnss_sigma_h_m, gnss_sigma_h_m, gnss_sigma_v_m]
            vnoise = rng.normal(0.0, gnss_sigma_vel_mps, 3)
        d = arm_n + noise
        if gnss_glitches and i in gnss_glitches:
            # a glitch replaces the noise: the fix is exactly this far from the truth
            d = arm_n + gnss_glitches[i]
        fix = GnssFix(
            time_us=t_us,
            lat_rad=float(lat + d[0] / rho.rho_n_m),
            lon_rad=float(lon + d[1] / (rho.rho_e_m * rho.cos_lat)),
            alt_msl_m=float(h - d[2]),
            v_ned_mps=v_ant + vnoise,
            eph_m=gnss_sigma_h_m,
            epv_m=gnss_sigma_v_m,
            speed_accuracy_mps=gnss_sigma_vel_mps,
            fix_type=3,
        )
        # delivered after the IMU sample of its arrival time
        timed.append((t_us + round(gnss_latency_s * 1e6), 1, fix))
    baro_t = np.zeros(0)
    baro_b = np.zeros(0)
    if baro_rate_hz is not None:
        b_period = round(1e6 / baro_rate_hz)
        b_times = np.arange(b_period, int(edges_us[-1]) + 1, b_period, dtype=np.int64)
        hk = traj(b_times * 1e-6).lla[:, 2]
        if errors is not None:
            baro_b = baro_offset_m + gauss_markov(
                rng, len(b_times), 1, errors.baro_bias_sigma_m, errors.baro_bias_tau_s,
                b_period * 1e-6,
            )[:, 0]  # fmt: skip
            hb = hk + baro_b + rng.normal(0.0, errors.baro_noise_m, len(b_times))
        else:
            baro_b = np.full(len(b_times), baro_offset_m)
            hb = hk + baro_b
        baro_t = b_times * 1e-6
        for t_us, hh in zip(b_times.tolist(), hb.tolist(), strict=True):
            timed.append((t_us, 2, BaroSample(t_us, height_to_pressure(hh), 288.15)))
    if mag_rate_hz is not None:
        m_period = round(1e6 / mag_rate_hz)
        m_times = np.arange(m_period, int(edges_us[-1]) + 1, m_period, dtype=np.int64)
        cm = quat_to_dcm(traj(m_times * 1e-6).q_nb)
        for i, t_us in enumerate(m_times.tolist()):
            m_b = cm[i].T @ FIELD_N_T + np.asarray(mag_hard_iron_t)
            if errors is not None:
                m_b = m_b + rng.normal(0.0, mag_noise_t, 3)
            timed.append((t_us, 3, MagSample(t_us, m_b)))
    timed.sort(key=lambda e: (e[0], e[1]))
    return Scenario(
        [s for _, _, s in timed],
        traj,
        edges_us[1:] * 1e-6,
        ba,
        bg,
        baro_t,
        baro_b,
    )


def airspeed_samples(
    sc: Scenario,
    wind_ne_mps: tuple[float, float],
    rng: np.random.Generator | None,
    *,
    rate_hz: float = 20.0,
    noise_pa: float = 1.0,
    tas_noise_mps: float = 0.0,
    temperature_k: float = 288.15,
    fault: Callable[[float, float], float] | None = None,
) -> list[AirspeedSample]:
    """Pitot samples from the truth: impact pressure of ``|v - w|`` plus white noise
    ``tas_noise_mps`` (turbulence, position error) through the isentropic relation (ISA static
    pressure at the true height, ``temperature_k``), plus white sensor noise ``noise_pa``.

    ``fault(t_s, q_c)`` may replace the reading (a blockage: stuck, zero, NaN...).
    """
    period_us = round(1e6 / rate_hz)
    end_us = round(float(sc.imu_time_s[-1]) * 1e6)
    times = np.arange(period_us, end_us + 1, period_us, dtype=np.int64)
    kin = sc.traj(times * 1e-6)
    out = []
    for i, t_us in enumerate(times.tolist()):
        v = kin.v_ned_mps[i]
        tas = math.sqrt((v[0] - wind_ne_mps[0]) ** 2 + (v[1] - wind_ne_mps[1]) ** 2 + v[2] ** 2)
        if rng is not None and tas_noise_mps > 0.0:
            tas += float(rng.normal(0.0, tas_noise_mps))
        qc = impact_pressure_pa(tas, height_to_pressure(float(kin.lla[i, 2])), temperature_k)
        if rng is not None:
            qc += float(rng.normal(0.0, noise_pa))
        if fault is not None:
            qc = fault(t_us * 1e-6, qc)
        out.append(AirspeedSample(t_us, qc, temperature_k))
    return out


def merge(samples: list[object], extra: list[object]) -> list[object]:
    """``samples`` with ``extra`` inserted in time order (an extra sample goes after the
    samples of the same time)."""
    out: list[object] = []
    j = 0
    for s in samples:
        t = s.time_us  # type: ignore[attr-defined]
        while j < len(extra) and extra[j].time_us < t:  # type: ignore[attr-defined]
            out.append(extra[j])
            j += 1
        out.append(s)
    out.extend(extra[j:])
    return out


def omega_in_n(lat: float, h: float, v: FloatArray) -> FloatArray:
    return earth.earth_rate_n(lat) + earth.transport_rate_n(lat, h, v)


def run(nav: Callable[[object], list], samples: list[object]) -> list:
    """Feed samples to ``nav`` (e.g. ``NavFilter().step``), collect the estimates."""
    out: list = []
    for s in samples:
        out.extend(nav(s))
    return out


def error_state(nav: NavFilter, sc: Scenario) -> FloatArray:
    """True error of the filter's current state, in its layout (estimated minus true)."""
    ins = nav.ins_state
    assert ins is not None
    t = nav.time_us * 1e-6
    kin = sc.traj(np.array([t]))
    lay = nav.layout
    e = np.zeros(lay.n)
    e[lay.pos] = earth.ned_offset_m(ins.lat_rad, ins.lon_rad, ins.alt_msl_m, *kin.lla[0])
    e[lay.vel] = np.asarray(ins.v_ned_mps) - kin.v_ned_mps[0]
    e[lay.att] = dcm_to_rotvec(quat_to_dcm(ins.q_nb) @ quat_to_dcm(kin.q_nb[0]).T)
    est = nav.estimate()
    assert est is not None
    ba, bg, bb = sc.true_bias_at(t)
    e[lay.ba] = est.accel_bias_b_mps2 - ba
    e[lay.bg] = est.gyro_bias_b_rps - bg
    e[lay.baro] = est.baro_bias_m - bb
    return e


def run_nees(
    nav: NavFilter, sc: Scenario, eval_times_s: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Run the filter over the scenario; at each evaluation time (first IMU epoch at or after
    it) return the true error and the filter's covariance: ``errors (M, n)``, ``covs (M, n, n)``."""
    errs = []
    covs = []
    k = 0
    targets = [round(t * 1e6) for t in eval_times_s]
    for s in sc.samples:
        nav.step(s)
        if k < len(targets) and isinstance(s, ImuSample) and s.time_us >= targets[k]:
            errs.append(error_state(nav, sc))
            covs.append(nav.covariance)
            k += 1
    return np.array(errs), np.array(covs)
