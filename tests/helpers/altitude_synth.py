"""A synthetic vertical channel for the altitude tests and ``bench/altitude_compare.py``.

An analytic climb-cruise-descent profile, a consumer MEMS vertical accelerometer, the
simulator's barometer model (``sim.baro``) and GNSS height with a preset's vertical error;
:func:`run_channel` feeds one seed's streams through an :class:`AltitudeChannel` and
:func:`metrics` scores the height over the GNSS outage. :func:`make_config` builds a channel
configuration from a flat parameter dict, so a tuning grid point means the same whatever the
channel's defaults are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.altitude.altimeter import BaroAltimeterConfig
from fusion.altitude.calibration import BaroCalibrationConfig
from fusion.altitude.channel import AltitudeChannel, AltitudeChannelConfig, AltitudeMethod
from fusion.altitude.common import OMEGA_S2
from fusion.altitude.loop import LoopGains, gains_from_poles
from fusion.altitude.mpc import MpcConfig
from fusion.altitude.vertical_kf import VerticalKfConfig
from sim import presets
from sim.baro import BaroModel

FloatArray = NDArray[np.float64]


# ---------------------------------------------------------------------------------------------
# Scenario and synthetic sensors
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Scenario:
    """Synthetic vertical-channel scenario (SI)."""

    duration_s: float = 900.0
    imu_rate_hz: float = 100.0
    baro_rate_hz: float = 25.0
    gnss_rate_hz: float = 5.0
    h0_m: float = 300.0
    # (start time s, new vertical speed m/s); each change is a raised-cosine ramp.
    speed_changes: tuple[tuple[float, float], ...] = (
        (60.0, 5.0),
        (300.0, 0.0),
        (620.0, -4.0),
        (860.0, 0.0),
    )
    ramp_s: float = 20.0
    outage: tuple[float, float] = (540.0, 660.0)
    weather_drift_hpa_per_h: float = 0.0  # -6 = falling 1 hPa / 10 min (a front)
    sea_level_dt_k_range: float = 15.0  # dT ~ U(-r, r) per seed
    sea_level_dp_hpa_range: float = 15.0  # dP ~ U(-r, r) per seed
    baro_self_heating_k: float = 1.5
    accel_bias_sigma_mps2: float = 0.02  # ~2 mg turn-on residual, per seed
    accel_bias_gm_sigma_mps2: float = 50e-6 * 9.80665
    accel_bias_gm_tau_s: float = 100.0
    accel_vrw_mps_per_rth: float = 0.041  # consumer MEMS (m/s/sqrt(h))
    gnss_preset: str = "modern"


@dataclass
class SensorData:
    """Truth and sensor streams of one seed."""

    t_imu: FloatArray  # end time of each IMU interval, s
    dt_imu: float
    az: FloatArray  # az_up = f_up - g(0), m/s^2
    h_true: FloatArray  # at t_imu, m (geometric MSL)
    t_baro: FloatArray
    p_baro: FloatArray
    temp_baro: FloatArray
    t_gnss: FloatArray
    h_gnss: FloatArray
    sigma_gnss: float
    outage: tuple[float, float]
    # indices into t_imu at which baro / gnss samples are delivered (after that IMU step)
    baro_at: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    gnss_at: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))


def profile(sc: Scenario, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Height (m), vertical speed (m/s) and acceleration (m/s²) at times ``t`` (analytic)."""
    h = np.full_like(t, sc.h0_m)
    v = np.zeros_like(t)
    a = np.zeros_like(t)
    v_prev = 0.0
    tr = sc.ramp_s
    for t_i, v_new in sc.speed_changes:
        dv = v_new - v_prev
        s = np.clip(t - t_i, 0.0, tr)
        inside = (t > t_i) & (t < t_i + tr)
        # speed step dv over the ramp: dv * 0.5 * (1 - cos(pi s / tr))
        v += dv * 0.5 * (1.0 - np.cos(np.pi * s / tr))
        a += np.where(inside, dv * 0.5 * np.pi / tr * np.sin(np.pi * s / tr), 0.0)
        ramp_int = 0.5 * (s - tr / np.pi * np.sin(np.pi * s / tr))
        h += dv * (ramp_int + np.maximum(t - t_i - tr, 0.0))
        v_prev = v_new
    return h, v, a


def simulate(sc: Scenario, seed: int) -> SensorData:
    """Draw one seed's truth and sensor streams."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / sc.imu_rate_hz
    n = round(sc.duration_s * sc.imu_rate_hz)
    t_imu: FloatArray = (np.arange(n, dtype=np.float64) + 1.0) * dt
    h_true, _, _ = profile(sc, t_imu)
    h_mid, _, a_mid = profile(sc, t_imu - 0.5 * dt)
    # Accelerometer along the vertical: true acceleration minus the free-air gravity term
    # (the loop adds 2 ws^2 h back), turn-on bias, Gauss-Markov bias, white noise.
    bias0 = rng.normal(0.0, sc.accel_bias_sigma_mps2)
    phi = math.exp(-dt / sc.accel_bias_gm_tau_s)
    q = sc.accel_bias_gm_sigma_mps2 * math.sqrt(1.0 - phi * phi)
    gm = np.empty(n)
    x = rng.normal(0.0, sc.accel_bias_gm_sigma_mps2)
    w = rng.standard_normal(n)
    for k in range(n):
        x = phi * x + q * w[k]
        gm[k] = x
    white = sc.accel_vrw_mps_per_rth / 60.0 / math.sqrt(dt)
    az = a_mid - 2.0 * OMEGA_S2 * h_mid + bias0 + gm + white * rng.standard_normal(n)
    # Barometer: the simulator's model.
    base = presets.baro_preset("ms5611")
    cfg = base.model_copy(
        update={
            "sea_level_temperature_offset_k": float(
                rng.uniform(-sc.sea_level_dt_k_range, sc.sea_level_dt_k_range)
            ),
            "sea_level_pressure_offset_hpa": float(
                rng.uniform(-sc.sea_level_dp_hpa_range, sc.sea_level_dp_hpa_range)
            ),
            "pressure_drift_hpa_per_h": sc.weather_drift_hpa_per_h,
            "temperature_offset_k": sc.baro_self_heating_k,
        }
    )
    baro = BaroModel(cfg, np.random.default_rng(rng.integers(2**63)))
    baro_every = round(sc.imu_rate_hz / sc.baro_rate_hz)
    baro_at = np.arange(baro_every - 1, n, baro_every)
    t_baro: FloatArray = t_imu[baro_at]
    p = np.empty(len(baro_at))
    temp = np.empty(len(baro_at))
    for i, kb in enumerate(baro_at.tolist()):
        s = baro.measure(round(t_baro[i] * 1e6), float(h_true[kb]))
        p[i], temp[i] = s.pressure_pa, s.temperature_k
    # GNSS height: Gauss-Markov + white, the preset's vertical figures; none in the outage.
    g = presets.gnss_preset(sc.gnss_preset)
    gnss_every = round(sc.imu_rate_hz / sc.gnss_rate_hz)
    all_at = np.arange(gnss_every - 1, n, gnss_every)
    dt_g = 1.0 / sc.gnss_rate_hz
    phi_g = math.exp(-dt_g / g.vertical_gm_tau_s)
    q_g = g.vertical_gm_sigma_m * math.sqrt(1.0 - phi_g * phi_g)
    e = rng.normal(0.0, g.vertical_gm_sigma_m)
    err = np.empty(len(all_at))
    wg = rng.standard_normal((len(all_at), 2))
    for i in range(len(all_at)):
        e = phi_g * e + q_g * wg[i, 0]
        err[i] = e + g.vertical_white_sigma_m * wg[i, 1]
    t_all = t_imu[all_at]
    keep = (t_all < sc.outage[0]) | (t_all >= sc.outage[1])
    gnss_at = all_at[keep]
    return SensorData(
        t_imu=t_imu,
        dt_imu=dt,
        az=az,
        h_true=h_true,
        t_baro=t_baro,
        p_baro=p,
        temp_baro=temp,
        t_gnss=np.asarray(t_imu[gnss_at], dtype=np.float64),
        h_gnss=h_true[gnss_at] + err[keep],
        sigma_gnss=math.hypot(g.vertical_gm_sigma_m, g.vertical_white_sigma_m),
        outage=sc.outage,
        baro_at=baro_at,
        gnss_at=gnss_at,
    )


# ---------------------------------------------------------------------------------------------
# Running and scoring
# ---------------------------------------------------------------------------------------------


def run_channel(
    config: AltitudeChannelConfig, data: SensorData
) -> tuple[FloatArray, AltitudeChannel]:
    """Feed one seed's data through a channel; returns the height after every IMU step."""
    ch = AltitudeChannel(config)
    n = len(data.t_imu)
    out = np.empty(n)
    baro_at = data.baro_at.tolist()
    gnss_at = data.gnss_at.tolist()
    ib = ig = 0
    nb, ng = len(baro_at), len(gnss_at)
    az = data.az.tolist()
    dt = data.dt_imu
    p_b, t_b, tmp_b = data.p_baro.tolist(), data.t_baro.tolist(), data.temp_baro.tolist()
    t_g, h_g = data.t_gnss.tolist(), data.h_gnss.tolist()
    sg = data.sigma_gnss
    for k in range(n):
        ch.update_imu(az[k], dt)
        while ib < nb and baro_at[ib] == k:
            ch.update_baro(p_b[ib], tmp_b[ib], t_b[ib])
            ib += 1
        while ig < ng and gnss_at[ig] == k:
            ch.update_gnss_height(h_g[ig], sg, t_g[ig])
            ig += 1
        out[k] = ch.height_m
    return out, ch


def metrics(est: FloatArray, data: SensorData, warmup_s: float = 120.0) -> dict[str, float]:
    """Outage RMSE / max / end error, GNSS-on RMSE and oscillation (m)."""
    t = data.t_imu
    err = est - data.h_true
    t0, t1 = data.outage
    in_out = (t >= t0) & (t < t1)
    k_end = int(np.searchsorted(t, t1)) - 1
    on = (t >= warmup_s) & ((t < t0) | (t >= t1 + 30.0))
    # Oscillation: RMS of the second difference of the estimated height at 10 Hz, after the
    # warm-up; and the same for the error (the profile's own curvature removed).
    step = max(1, round(0.1 / data.dt_imu))
    sel = np.arange(round(warmup_s / data.dt_imu), len(t), step)
    d2_est = np.diff(est[sel], 2)
    d2_err = np.diff(err[sel], 2)
    sel_o = sel[(t[sel] >= t0) & (t[sel] < t1)]
    return {
        "outage_rmse_m": float(np.sqrt(np.mean(err[in_out] ** 2))),
        "outage_max_m": float(np.max(np.abs(err[in_out]))),
        "outage_end_error_m": float(abs(err[k_end])),
        "outage_start_error_m": float(abs(err[int(np.searchsorted(t, t0))])),
        "gnss_on_rmse_m": float(np.sqrt(np.mean(err[on] ** 2))),
        "osc_rms_d2_height_m": float(np.sqrt(np.mean(d2_est**2))),
        "osc_rms_d2_error_m": float(np.sqrt(np.mean(d2_err**2))),
        "osc_rms_d2_error_outage_m": float(np.sqrt(np.mean(np.diff(err[sel_o], 2) ** 2))),
    }


SETUPS: dict[str, dict[str, Any]] = {
    # hilnav's design: the baro is calibrated (s, b) from GNSS height while GNSS is valid.
    "gnss-calibrated": {"use_gnss": True, "use_temperature": False},
    # P4's set-up: no GNSS in the baro calibration (s from the sensed temperature only, b not
    # learned); GNSS reaches the altitude only through the compensator.
    "p4-baro": {"use_gnss": False, "use_temperature": True},
}


def make_config(
    method: AltitudeMethod, params: dict[str, Any], setup: str = "gnss-calibrated"
) -> AltitudeChannelConfig:
    """Channel config from a flat parameter dict (keys: q_b, loop_tau_s, mpc.*, kf.*).

    Keys not given take the values of P4's preset (:meth:`AltitudeChannelConfig.p4`: P4's loop
    gains, the untuned MPC, P4's KF, ``q_b`` 0.02), not the channel's defaults (which are the
    result of tuning), so a grid point means the same whatever the defaults are.
    """
    cal = BaroCalibrationConfig(
        bias_random_walk_m_per_rth_s=params.get("q_b", 0.02), **SETUPS[setup]
    )
    mpc = MpcConfig.p4().model_copy(
        update={k[4:]: v for k, v in params.items() if k.startswith("mpc.")}
    )
    kf = VerticalKfConfig.p4().model_copy(
        update={k[3:]: v for k, v in params.items() if k.startswith("kf.")}
    )
    # model_copy does not validate: round-trip so bad grid values still raise
    mpc = MpcConfig.model_validate(mpc.model_dump())
    kf = VerticalKfConfig.model_validate(kf.model_dump())
    loop = LoopGains.p4()
    if "loop_tau_s" in params:  # triple pole at -1/tau instead of P4's gains
        tau = params["loop_tau_s"]
        k1, k2, k3 = gains_from_poles([-1.0 / tau] * 3)
        loop = LoopGains(k1=k1, k2=k2, k3=k3)
    return AltitudeChannelConfig(
        method=method, loop=loop, baro=BaroAltimeterConfig(calibration=cal), mpc=mpc, kf=kf
    )


SCENARIOS = {
    "calm": Scenario(weather_drift_hpa_per_h=0.0),
    "front": Scenario(weather_drift_hpa_per_h=-6.0),
}
