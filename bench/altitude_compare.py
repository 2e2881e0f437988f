"""Benchmark: P4's altitude methods ('loop', 'loop-mpc', 'loop-kf') through a 120 s GNSS outage.

Synthetic vertical profile (climb 5 m/s to ~1500 m, cruise, descent 4 m/s; 900 s), a consumer
MEMS vertical accelerometer (2 mg-class turn-on bias, Gauss-Markov bias, VRW 0.041 m/s/√h),
the simulator's barometer model (``sim.baro``, MS5611 preset: non-standard atmosphere with
dT, dP ~ U(±15 K), U(±15 hPa) per seed, 10 Pa / 600 s Gauss-Markov bias, 1.2 Pa noise, 1 Pa
resolution, 1.5 K self-heating; scenario "front": pressure falling 1 hPa / 10 min) and GNSS
height with the 'modern' preset's vertical error (Gauss-Markov 2.4 m / 120 s + 0.8 m white,
5 Hz). GNSS is absent from 540 s to 660 s (end of cruise and start of the descent). Every
method sees the *same* sensor data per seed.

Two set-ups: "gnss-calibrated" (the issue's design: P4's (s, b) learned from GNSS height while
GNSS is valid, for every method) and "p4-baro" (P4's own set-up: no GNSS in the baro
calibration, s from the sensed temperature only; GNSS reaches the altitude only through the
compensator).

Tuning: grid search per method and set-up on the tuning seeds only (objective: mean outage RMSE
over both weather scenarios); reported numbers come from separate reporting seeds, with paired
per-seed comparisons (mean difference ± standard error, seeds won).

    PYTHONPATH=. .venv/bin/python bench/altitude_compare.py

(about 30 min on 2 cores). The harness functions (:func:`simulate`, :func:`run_channel`,
:func:`metrics`, :func:`make_config`) are also used by ``tests/fusion/test_altitude.py``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import multiprocessing
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path
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
    # The issue's design: the baro is calibrated (s, b) from GNSS height while GNSS is valid.
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


def evaluate(
    method: AltitudeMethod,
    params: dict[str, Any],
    datasets: dict[str, list[SensorData]],
    setup: str = "gnss-calibrated",
) -> dict[str, dict[str, Any]]:
    """Mean metrics per scenario, plus per-seed outage RMSE and end error."""
    cfg = make_config(method, params, setup)
    out: dict[str, dict[str, Any]] = {}
    for name, ds in datasets.items():
        per: list[dict[str, float]] = [metrics(run_channel(cfg, d)[0], d) for d in ds]
        res: dict[str, Any] = {k: float(np.mean([m[k] for m in per])) for k in per[0]}
        res["per_seed_outage_rmse_m"] = [m["outage_rmse_m"] for m in per]
        res["per_seed_outage_end_error_m"] = [m["outage_end_error_m"] for m in per]
        out[name] = res
    return out


def objective(res: dict[str, dict[str, Any]]) -> float:
    """Tuning objective: mean outage RMSE over the scenarios (inf if it blew up)."""
    v = float(np.mean([r["outage_rmse_m"] for r in res.values()]))
    return v if math.isfinite(v) else math.inf


def grid(space: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """All combinations of a parameter grid."""
    keys = list(space)
    return [dict(zip(keys, vals, strict=True)) for vals in itertools.product(*space.values())]


_TUNE_DATA: dict[str, list[SensorData]] = {}


def _score(job: tuple[AltitudeMethod, dict[str, Any], str]) -> float:
    method, params, setup = job
    try:
        return objective(evaluate(method, params, _TUNE_DATA, setup))
    except ValueError:  # an unstable / singular MPC design: not a candidate
        return math.inf


def tune(
    method: AltitudeMethod,
    cands: list[dict[str, Any]],
    setup: str,
    pool: Any,
) -> tuple[dict[str, Any], float, int]:
    """Grid search on the tuning data; returns (best params, objective, grid size)."""
    scores = pool.map(_score, [(method, p, setup) for p in cands])
    i = int(np.argmin(scores))
    return cands[i], float(scores[i]), len(cands)


def _init_worker(seeds: list[int]) -> None:
    _TUNE_DATA.update({k: [simulate(sc, s) for s in seeds] for k, sc in SCENARIOS.items()})


def paired(a: list[float], b: list[float]) -> dict[str, float]:
    """Per-seed comparison of two methods' outage RMSE lists (a vs b)."""
    x, y = np.asarray(a), np.asarray(b)
    d = x - y
    return {
        "ratio_of_means": float(np.mean(x) / np.mean(y)),
        "mean_difference_m": float(np.mean(d)),
        "sem_difference_m": float(np.std(d, ddof=1) / math.sqrt(len(d))),
        "seeds_a_better": int(np.sum(d < 0.0)),
        "seeds": len(d),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--tuning-seeds", type=int, nargs="+", default=list(range(101, 107)))
    ap.add_argument("--report-seeds", type=int, nargs="+", default=list(range(1, 21)))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("bench/results/altitude_compare.json"))
    args = ap.parse_args()
    t_start = time.perf_counter()
    rep_data = {k: [simulate(sc, s) for s in args.report_seeds] for k, sc in SCENARIOS.items()}
    result: dict[str, Any] = {
        "benchmark": "altitude_compare",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "scenarios": {k: vars(v) for k, v in SCENARIOS.items()},
        "setups": SETUPS,
        "tuning_seeds": args.tuning_seeds,
        "report_seeds": args.report_seeds,
        "tuning_objective": "mean outage RMSE over the scenarios, tuning seeds",
        "metrics": {
            "outage_rmse_m": "RMSE of height error over the 120 s outage (IMU rate)",
            "outage_end_error_m": "|height error| at the end of the outage",
            "gnss_on_rmse_m": "RMSE with GNSS valid (after 120 s warm-up, 30 s after outage)",
            "osc_rms_d2_height_m": "RMS second difference of the estimated height, 10 Hz",
            "osc_rms_d2_error_m": "RMS second difference of (estimate - truth), 10 Hz",
        },
    }
    with multiprocessing.Pool(args.workers, _init_worker, (args.tuning_seeds,)) as pool:
        for setup in SETUPS:
            learns_b = SETUPS[setup]["use_gnss"]
            if learns_b:
                q_cands = [{"q_b": q} for q in (0.002, 0.005, 0.01, 0.02, 0.05, 0.1)]
                loop_p, loop_s, n_loop = tune("loop", q_cands, setup, pool)
            else:  # b is not learned: q_b has no effect
                loop_p, n_loop = {"q_b": 0.02}, 1
                loop_s = pool.apply(_score, (("loop", loop_p, setup),))
            q_bs = sorted({loop_p["q_b"], 0.02}) if learns_b else [loop_p["q_b"]]
            mpc_cands = grid(
                {
                    "q_b": q_bs,
                    "mpc.period_s": [0.2, 1.0, 5.0],
                    "mpc.pole": [0.0, 0.6],
                    "mpc.r_l": [0.01, 1.0, 10.0],
                }
            )
            mpc_p, mpc_s, n_mpc = tune("loop-mpc", mpc_cands, setup, pool)
            kf_cands = grid(
                {
                    "q_b": q_bs,
                    "kf.accel_noise_psd": [1e-6, 1e-4, 1e-3],
                    "kf.gnss_sigma_scale": [1.0, 3.0],
                    "kf.use_baro": [False],
                }
            ) + grid(
                {
                    "q_b": q_bs,
                    "kf.accel_noise_psd": [1e-6, 1e-4, 1e-3],
                    "kf.gnss_sigma_scale": [1.0, 3.0],
                    "kf.use_baro": [True],
                    "kf.baro_bias_sigma_m": [0.5, 2.0, 20.0, 100.0],
                    # 1e5 s: the bias is (nearly) a random constant, held through an outage
                    "kf.baro_bias_tau_s": [600.0, 1e5],
                }
            )
            kf_p, kf_s, n_kf = tune("loop-kf", kf_cands, setup, pool)
            tuned: dict[str, dict[str, Any]] = {"loop": loop_p, "loop-mpc": mpc_p, "loop-kf": kf_p}
            rows: dict[str, Any] = {}
            for m, p in tuned.items():
                rows[m] = evaluate(m, p, rep_data, setup)  # type: ignore[arg-type]
            q_b = loop_p["q_b"]
            extra: dict[str, tuple[AltitudeMethod, dict[str, Any]]] = {
                "loop, triple pole tau=1 s": ("loop", {"q_b": q_b, "loop_tau_s": 1.0}),
                "loop, triple pole tau=3 s": ("loop", {"q_b": q_b, "loop_tau_s": 3.0}),
                "loop-mpc defaults (a=0.5 N=4 Np=Nc=10 R_L=1 0.2 s)": ("loop-mpc", {"q_b": q_b}),
                "loop-mpc tuned, outage_mode=extrapolate": (
                    "loop-mpc",
                    {**mpc_p, "mpc.outage_mode": "extrapolate"},
                ),
                "loop-mpc tuned, outage_mode=coast": (
                    "loop-mpc",
                    {**mpc_p, "mpc.outage_mode": "coast"},
                ),
                "loop-kf defaults": ("loop-kf", {"q_b": q_b}),
            }
            for name, (m, p) in extra.items():
                rows[name] = evaluate(m, p, rep_data, setup)
            targets: dict[str, Any] = {}
            for sc in SCENARIOS:
                lp, mp, kp = (
                    rows[m][sc]["per_seed_outage_rmse_m"] for m in ("loop", "loop-mpc", "loop-kf")
                )
                vs_loop = paired(mp, lp)
                vs_kf = paired(mp, kp)
                targets[sc] = {
                    "mpc_rmse_le_half_loop": {**vs_loop, "ok": vs_loop["ratio_of_means"] <= 0.5},
                    "mpc_rmse_le_kf": {**vs_kf, "ok": vs_kf["ratio_of_means"] <= 1.0},
                }
            ends = rows["loop-mpc"]["front"]["per_seed_outage_end_error_m"]
            targets["front"]["mpc_end_error_le_5m"] = {
                "mean_m": float(np.mean(ends)),
                "max_m": float(np.max(ends)),
                "seeds_over_5m": int(np.sum(np.asarray(ends) > 5.0)),
                "ok": float(np.mean(ends)) <= 5.0,
            }
            d0 = rep_data["calm"][0]
            wall = {}
            for m, p in tuned.items():
                t0 = time.perf_counter()
                run_channel(make_config(m, p, setup), d0)  # type: ignore[arg-type]
                wall[m] = time.perf_counter() - t0
            result[setup] = {
                "tuned": {
                    "loop": {"params": loop_p, "tuning_objective_m": loop_s, "grid": n_loop},
                    "loop-mpc": {"params": mpc_p, "tuning_objective_m": mpc_s, "grid": n_mpc},
                    "loop-kf": {"params": kf_p, "tuning_objective_m": kf_s, "grid": n_kf},
                },
                "report": rows,
                "targets": targets,
                "wall_s_per_900s_run": wall,
            }
            print(f"== {setup}")
            for m, r in rows.items():
                print(
                    f"{m[:44]:44s} "
                    + "  ".join(
                        f"{sc}: rmse {r[sc]['outage_rmse_m']:.2f} end "
                        f"{r[sc]['outage_end_error_m']:.2f} on {r[sc]['gnss_on_rmse_m']:.2f} "
                        f"osc {r[sc]['osc_rms_d2_error_m'] * 1e3:.0f}mm"
                        for sc in SCENARIOS
                    )
                )
            print(json.dumps(targets))
    result["total_wall_s"] = time.perf_counter() - t_start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=float))


if __name__ == "__main__":
    main()
