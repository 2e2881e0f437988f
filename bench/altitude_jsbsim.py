"""Benchmark: the altitude methods inside NavFilter on JSBSim flights.

Flights: ``SimSetup.build(plan="climb-descent", alt_msl_m=1500)``, Cessna 172 at 50 m/s,
JSBSim at 100 Hz, the IMU at 50 Hz (P0's INS rate; half the filter cost of 100 Hz),
``industrial-mems`` IMU, ``modern`` GNSS (Gauss-Markov vertical error 2.4 m / 120 s + 0.8 m
white), ``ms5611`` barometer at 50 Hz, ``consumer`` magnetometer at 10 Hz, 660 s. GNSS is
switched off for fixes valid in [480 s, 600 s): the 120 s outage covers the end of a climb,
level flight at 1700 m and the first half of a descent. Frames go through the MAVLink path
(``SensorStreamer`` -> ``Decoder``) into ``NavFilter`` (``filter_config_for_imu``), one filter
per method, every filter of a seed on the same sensor data.

Barometer variants (same seed: identical IMU, GNSS, magnetometer and baro noise; the suite
draws each sensor from its own generator):

- ``calm``: the preset (standard atmosphere; 10 Pa / 600 s Gauss-Markov sensor bias).
- ``front``: sea-level pressure falling 6 hPa/h (1 hPa per 10 min) for the whole flight
  (``sim.baro`` drifts from the first sample; during the outage that is 0.2 hPa, ~1.7 m).
- ``day``: non-standard day, ``dT = +15 K``, ``dP = -10 hPa`` (P4's ``s = 0.052``,
  ``b = -83.2 m``); the flight is at 1500-1800 m.

Set-ups of the loop methods (``tests.helpers.altitude_synth.SETUPS``): ``gnss-calibrated``
(hilnav's design: P4's ``(s, b)`` learned from GNSS height while GNSS is valid) and ``p4-baro``
(P4's own set-up: ``s`` from the sensor's temperature only, ``b`` not learned; GNSS reaches the
altitude only through the compensator's reference ``dh_ref = h - h_GNSS``).

Parts (a-d):

(a) ``calm``: vertical RMSE over the outage per method (ekf, loop, loop-mpc, loop-kf), error at
    the outage's end, and the oscillation: RMS of the second difference of the estimated
    height (and of its error) at 10 Hz over the outage. Targets: loop-mpc <= 0.5 x loop and
    <= loop-kf (outage RMSE, ratio of the means over the seeds).
(b) ``front``: the same; target: loop-mpc's error at the end of the outage <= 5 m.
(c) ``day``: barometric altitude bias (baro height minus true height), at the level segment
    near 1500 m, over the GNSS-on part and through the outage (calibration frozen):
    raw ISA pressure altitude (no calibration, no QNH); an altimeter set to QNH = P0 + dP;
    P4's temperature-only correction; P4's calibration against GNSS height (the loop-mpc
    run's calibrated baro height inside NavFilter, and its replay); the same calibration fed
    the *true* height at the same epochs (replay), which separates what the receiver's own
    vertical error (``modern``: Gauss-Markov 2.4 m / 120 s + 0.8 m white) contributes; and
    that GNSS error averaged over the calibration's memory. Also the analytic ISA error of
    the day at 0 / 1500 / 3000 m (dT and dP push in opposite directions and cancel near
    1500 m). Target: from tens of metres to <= 2 m. The day is also flown with ``ekf``, and
    ``loop`` / ``loop-kf`` replayed on the loop-mpc run's inputs.
(d) ``day`` in P4's set-up (``p4-baro``): loop, loop-mpc and loop-kf as the paper compares
    them (P4's loop gains, Laguerre MPC with Np = Nc = 10; KF on the same error model).

Also: the horizontal solution of every loop method against ``ekf`` (must not degrade), the
baro health counters, and the check that the altitude channel's inputs recorded inside
NavFilter are identical for all loop methods (the EKF does not depend on the altitude method
with a healthy barometer, as designed) and that replaying them through a fresh
``AltitudeChannel`` reproduces the filter's output altitude exactly.

Tuning: any parameter is chosen on seeds 1-5 only (``--tuning-seeds``), by grid search over
the channel parameters (baro-calibration random walk ``q_b``, loop gains, MPC period / pole /
R_L, KF noises / bias model), objective: mean outage RMSE (``gnss-calibrated``: over calm and
front; ``p4-baro``: day). The grid is evaluated by replaying the channel inputs recorded inside
NavFilter on the tuning flights (exact, see above; a full filter run per candidate would cost
~100x more). Reported numbers come from full NavFilter runs on held-out seeds 100-109.

    python bench/altitude_jsbsim.py [--report-seeds 100 ... 109] \
        [--out bench/results/altitude_jsbsim.json]

(about 10-15 min on 2 cores; the load average is recorded in the JSON).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # tests.helpers (the altitude channel's configurations)
    sys.path.insert(0, str(ROOT))

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # two workers must not fight over two cores

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from _altitude_flight import (  # noqa: E402
    DAY_DP_HPA,
    DAY_DT_K,
    DURATION_S,
    IMU,
    IMU_RATE_HZ,
    LOOP_METHODS,
    OUTAGE,
    PLAN,
    SIM_RATE_HZ,
    START_ALT_M,
    VARIANTS,
    FloatArray,
    RunSpec,
    baro_bias,
    fly,
    gnss_vertical_error,
    horizontal_metrics,
    isa_bias_analytic,
    isa_height,
    replay,
    replay_mismatch,
    vertical_metrics,
)

from fusion.altitude.atmosphere import (  # noqa: E402
    geometric_from_geopotential,
    nonstandard_scale_bias,
    qnh_altitude_m,
)
from fusion.altitude.channel import AltitudeChannelConfig  # noqa: E402
from physconst import ISA_P0_PA  # noqa: E402
from tests.helpers.altitude_synth import make_config  # noqa: E402


def grid(space: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """All combinations of a parameter grid."""
    keys = list(space)
    return [dict(zip(keys, vals, strict=True)) for vals in itertools.product(*space.values())]


def candidates(method: str, setup: str, loop: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """The tuning grid of one method and set-up.

    The compensators run on the tuned loop: they get its parameters (calibration random walk
    ``q_b``, which has no effect in ``p4-baro`` where ``b`` is not learned, and loop gains), so
    that loop-mpc and loop-kf differ from loop by the compensator alone.
    """
    base = loop or {"q_b": 0.02}
    q_b = base["q_b"]
    if method == "loop":
        qs = [0.005, 0.02, 0.05] if setup == "gnss-calibrated" else [0.02]
        return grid({"q_b": qs}) + grid({"q_b": qs, "loop_tau_s": [1.0, 3.0]})
    if method == "loop-mpc":
        cands = grid(
            {
                "q_b": [q_b],
                "mpc.period_s": [0.2, 1.0, 5.0],
                "mpc.pole": [0.0, 0.6],
                "mpc.r_l": [0.01, 1.0, 10.0],
            }
        )
        return [{**base, **c} for c in cands]
    kf_common = {
        "q_b": [q_b],
        "kf.accel_noise_psd": [1e-6, 1e-4],
        "kf.gnss_sigma_scale": [1.0, 3.0],
    }
    cands = grid({**kf_common, "kf.use_baro": [False]}) + grid(
        {
            **kf_common,
            "kf.use_baro": [True],
            "kf.baro_bias_sigma_m": [0.5, 2.0, 20.0],
            "kf.baro_bias_tau_s": [600.0, 1e5],
        }
    )
    return [{**base, **c} for c in cands]


TUNE_VARIANTS = {"gnss-calibrated": ("calm", "front"), "p4-baro": ("day",)}
_TUNE: list[dict[str, Any]] = []


def _init_tune(data: list[dict[str, Any]]) -> None:
    _TUNE[:] = data


def _score(job: tuple[str, dict[str, Any], str]) -> float:
    method, params, setup = job
    try:
        cfg = make_config(method, params, setup)  # type: ignore[arg-type]
    except ValueError:  # an unstable MPC design is not a candidate
        return math.inf
    vals: list[float] = []
    for d in _TUNE:
        for v in TUNE_VARIANTS[setup]:
            t, h = replay(cfg, d["logs"][v])
            ok = np.isfinite(h)
            vals.append(vertical_metrics(t[ok], h[ok], d["truth"])["outage_rmse_m"])
    score = float(np.mean(vals))
    return score if math.isfinite(score) else math.inf


def _tune_flight(seed: int) -> dict[str, Any]:
    # One recorder per variant; the recorded inputs do not depend on the channel settings.
    runs = [RunSpec(f"rec-{v}", v, "loop-mpc") for v in VARIANTS]
    res = fly(seed, runs)
    cfg = make_config("loop-mpc", {}, "gnss-calibrated")
    check = {
        v: replay_mismatch(cfg, res["logs"][f"rec-{v}"], res["tracks"][f"rec-{v}"])
        for v in VARIANTS
    }
    return {
        "seed": seed,
        "truth": res["truth"],
        "logs": {v: res["logs"][f"rec-{v}"] for v in VARIANTS},
        "replay_vs_navfilter_max_diff_m": check,
        "wall_s": res["wall_s"],
    }


# ---------------------------------------------------------------------------------------------
# Reporting
# ---------------------------------------------------------------------------------------------


def report_runs(tuned: dict[str, dict[str, dict[str, Any]]]) -> list[RunSpec]:
    cal, p4 = tuned["gnss-calibrated"], tuned["p4-baro"]
    runs = []
    for v in ("calm", "front"):
        runs.append(RunSpec(f"{v}/ekf", v, "ekf"))
        runs += [RunSpec(f"{v}/{m}", v, m, "gnss-calibrated", cal[m]) for m in LOOP_METHODS]
    runs.append(RunSpec("day/ekf", "day", "ekf"))
    runs.append(RunSpec("day/loop-mpc", "day", "loop-mpc", "gnss-calibrated", cal["loop-mpc"]))
    runs += [RunSpec(f"day-p4/{m}", "day", m, "p4-baro", p4[m]) for m in LOOP_METHODS]
    return runs


def _report_seed(job: tuple[int, dict[str, dict[str, dict[str, Any]]]]) -> dict[str, Any]:
    seed, tuned = job
    runs = report_runs(tuned)
    res = fly(seed, runs)
    truth = res["truth"]
    out: dict[str, Any] = {"seed": seed, "wall_s": res["wall_s"], "ended_early": res["ended_early"]}
    rows: dict[str, Any] = {}
    for r in runs:
        tr = res["tracks"][r.name]
        t, h = np.asarray(tr.t), np.asarray(tr.alt)
        row: dict[str, Any] = {**vertical_metrics(t, h, truth), **horizontal_metrics(tr, truth)}
        row["filter_cpu_s"] = res["filter_cpu_s"][r.name]
        hl = res["health"][r.name]
        row["health"] = {
            k: hl[k]
            for k in (
                "baro_invalid",
                "baro_frozen",
                "baro_glitches",
                "baro_realignments",
                "baro_rejected",
                "altitude_gnss_rejected",
                "altitude_calibration_updates",
            )
        }
        rows[r.name] = row
    # Secondary rows: channel replays of the recorded inputs (exact, see module docstring).
    cal_loop = {k: v for k, v in tuned["gnss-calibrated"]["loop"].items() if k == "q_b"}
    extra: dict[str, tuple[str, str, dict[str, Any], str]] = {
        # the same calibration, P4's loop gains instead of the tuned ones
        "calm/loop P4 gains (replay)": ("calm/loop", "loop", cal_loop, "gnss-calibrated"),
        "front/loop P4 gains (replay)": ("front/loop", "loop", cal_loop, "gnss-calibrated"),
        # P4's loop gains, MPC a=0.5 N=4 Np=Nc=10 R_L=1 at 0.2 s, KF with tau_b=600 s
        "calm/loop-mpc P4 defaults (replay)": ("calm/loop-mpc", "loop-mpc", {}, "gnss-calibrated"),
        "front/loop-mpc P4 defaults (replay)": (
            "front/loop-mpc",
            "loop-mpc",
            {},
            "gnss-calibrated",
        ),
        "day-p4/loop-mpc P4 defaults (replay)": ("day-p4/loop-mpc", "loop-mpc", {}, "p4-baro"),
        "day-p4/loop-kf P4 defaults (replay)": ("day-p4/loop-kf", "loop-kf", {}, "p4-baro"),
    }
    for name, (src, m, p, setup) in extra.items():
        t, h = replay(make_config(m, p, setup), res["logs"][src])  # type: ignore[arg-type]
        ok = np.isfinite(h)
        rows[name] = vertical_metrics(t[ok], h[ok], truth)
    # The shipped defaults (AltitudeChannelConfig()): equal to the tuned rows when the tuning
    # picks what the defaults say.
    for v in ("calm", "front"):
        for m in LOOP_METHODS:
            t, h = replay(AltitudeChannelConfig(method=m), res["logs"][f"{v}/{m}"])  # type: ignore[arg-type]
            ok = np.isfinite(h)
            rows[f"{v}/{m} defaults (replay)"] = vertical_metrics(t[ok], h[ok], truth)
    # The non-standard day with the GNSS-calibrated loop and KF: replays of the day/loop-mpc
    # run's inputs (identical for every loop method, checked below for the other variants).
    for m in ("loop", "loop-kf"):
        cfg_d = make_config(m, tuned["gnss-calibrated"][m])  # type: ignore[arg-type]
        t, h = replay(cfg_d, res["logs"]["day/loop-mpc"])
        ok = np.isfinite(h)
        rows[f"day/{m} (replay)"] = vertical_metrics(t[ok], h[ok], truth)
    out["rows"] = rows

    # Channel inputs identical across loop methods (the EKF ignores the altitude method)?
    def inputs(name: str) -> list[tuple[Any, ...]]:  # the reads ("h") differ by design
        return [e for e in res["logs"][name].entries if e[0] != "h"]

    same = {}
    for v in ("calm", "front"):
        ref = inputs(f"{v}/loop")
        same[v] = all(inputs(f"{v}/{m}") == ref for m in ("loop-mpc", "loop-kf"))
    ref = inputs("day-p4/loop")
    same["day"] = all(
        inputs(n) == ref for n in ("day/loop-mpc", "day-p4/loop-mpc", "day-p4/loop-kf")
    )
    out["replay_vs_navfilter_max_diff_m"] = {
        r.name: replay_mismatch(
            make_config(r.method, r.params, r.setup),  # type: ignore[arg-type]
            res["logs"][r.name],
            res["tracks"][r.name],
        )
        for r in runs
        if r.method != "ekf"
    }
    out["channel_inputs_identical_across_methods"] = same
    # (c): baro bias before / after calibration on the non-standard day.
    tb, pb = res["baro"]["day"][:, 0], res["baro"]["day"][:, 1]
    tr_c = res["tracks"]["day/loop-mpc"]
    tr_p4 = res["tracks"]["day-p4/loop-mpc"]
    tc = np.asarray(tr_c.t)
    k_out = int(np.searchsorted(tc, OUTAGE[0])) - 1
    day_cfg = make_config("loop-mpc", tuned["gnss-calibrated"]["loop-mpc"])
    day_log = res["logs"]["day/loop-mpc"]
    t_rg, h_rg = replay(day_cfg, day_log, baro=True)
    t_rt, h_rt = replay(day_cfg, day_log, baro=True, truth=truth)
    qnh = ISA_P0_PA + DAY_DP_HPA * 100.0  # the day's sea-level offset, set as a pilot would
    out["baro_bias"] = {
        # (a) raw: ISA pressure altitude, no calibration, no QNH
        "isa_pressure_altitude": baro_bias(tb, isa_height(pb), truth),
        # (a') altimeter set to QNH = P0 + dP (only the temperature error left)
        "qnh_set": baro_bias(
            tb,
            np.array([geometric_from_geopotential(qnh_altitude_m(float(x), qnh)) for x in pb]),
            truth,
        ),
        "p4_temperature_only": baro_bias(np.asarray(tr_p4.t), np.asarray(tr_p4.baro_h), truth),
        # (b) P4's calibration against GNSS height (inside NavFilter)
        "p4_calibrated_from_gnss": baro_bias(tc, np.asarray(tr_c.baro_h), truth),
        # (b) replayed (must equal the line above) and (c) the same against the true height
        "p4_calibrated_from_gnss_replay": baro_bias(t_rg, h_rg, truth),
        "p4_calibrated_from_truth": baro_bias(t_rt, h_rt, truth),
        "gnss_vertical_error": gnss_vertical_error(day_log, truth),
        "estimated_scale_at_outage_start": tr_c.scale[k_out],
        "estimated_bias_m_at_outage_start": tr_c.bias[k_out],
    }
    return out


def _summ(values: list[float]) -> dict[str, float]:
    a = np.asarray(values, dtype=float)
    return {"mean": float(np.mean(a)), "max": float(np.max(a)), "min": float(np.min(a))}


def aggregate(per_seed: list[dict[str, Any]]) -> dict[str, Any]:
    """Means / extremes over the report seeds, target checks."""
    names = list(per_seed[0]["rows"])
    agg: dict[str, Any] = {}
    for n in names:
        keys = [k for k, v in per_seed[0]["rows"][n].items() if isinstance(v, float)]
        agg[n] = {k: _summ([s["rows"][n][k] for s in per_seed]) for k in keys}
        agg[n]["per_seed_outage_rmse_m"] = [s["rows"][n]["outage_rmse_m"] for s in per_seed]
        agg[n]["per_seed_outage_end_error_m"] = [
            s["rows"][n]["outage_end_error_m"] for s in per_seed
        ]
    targets: dict[str, Any] = {}

    def ratio(a: str, b: str, key: str = "outage_rmse_m") -> dict[str, Any]:
        x = np.asarray([s["rows"][a][key] for s in per_seed])
        y = np.asarray([s["rows"][b][key] for s in per_seed])
        return {
            "ratio_of_means": float(x.mean() / y.mean()),
            "seeds_a_better": int(np.sum(x < y)),
            "seeds": len(x),
        }

    for v in ("calm", "front", "day-p4"):
        r1 = ratio(f"{v}/loop-mpc", f"{v}/loop")
        r2 = ratio(f"{v}/loop-mpc", f"{v}/loop-kf")
        o1 = ratio(f"{v}/loop-mpc", f"{v}/loop", "osc_rms_d2_height_m")
        o2 = ratio(f"{v}/loop-mpc", f"{v}/loop-kf", "osc_rms_d2_height_m")
        targets[v] = {
            "mpc_rmse_le_half_loop": {**r1, "ok": r1["ratio_of_means"] <= 0.5},
            "mpc_rmse_le_kf": {**r2, "ok": r2["ratio_of_means"] <= 1.0},
            "mpc_oscillation_le_half_loop": {**o1, "ok": o1["ratio_of_means"] <= 0.5},
            "mpc_oscillation_le_kf": {**o2, "ok": o2["ratio_of_means"] <= 1.0},
        }
    ends = np.abs(agg["front/loop-mpc"]["per_seed_outage_end_error_m"])
    targets["front"]["mpc_end_error_le_5m"] = {
        "mean_abs_m": float(ends.mean()),
        "max_abs_m": float(ends.max()),
        "seeds_over_5m": int(np.sum(ends > 5.0)),
        "ok": bool(ends.max() <= 5.0),
    }

    def bb(key: str, w: str = "level_1500m_mean_m") -> FloatArray:
        return np.asarray([s["baro_bias"][key][w] for s in per_seed], dtype=float)

    after, after_t = bb("p4_calibrated_from_gnss"), bb("p4_calibrated_from_truth")
    after_out, after_t_out = (
        bb("p4_calibrated_from_gnss", "outage_mean_m"),
        bb("p4_calibrated_from_truth", "outage_mean_m"),
    )
    g_mem = bb("gnss_vertical_error", "memory_before_level_end_mean_m")
    g_mem_out = bb("gnss_vertical_error", "memory_before_outage_mean_m")
    s_true, b_true = nonstandard_scale_bias(DAY_DT_K, DAY_DP_HPA * 100.0)
    targets["day_calibration_bias_le_2m"] = {
        "before_isa_level_1500m_mean_m": float(np.mean(bb("isa_pressure_altitude"))),
        "before_qnh_set_level_1500m_mean_m": float(np.mean(bb("qnh_set"))),
        "before_p4_temperature_only_level_1500m_mean_m": float(np.mean(bb("p4_temperature_only"))),
        "isa_bias_analytic_m": {
            str(h): isa_bias_analytic(DAY_DT_K, DAY_DP_HPA * 100.0, h)
            for h in (0.0, 1500.0, 3000.0)
        },
        "isa_bias_analytic_1500m_dp_only_m": isa_bias_analytic(0.0, DAY_DP_HPA * 100.0, 1500.0),
        "isa_bias_analytic_1500m_dt_only_m": isa_bias_analytic(DAY_DT_K, 0.0, 1500.0),
        "after_gnss_abs_level_1500m_mean_m": float(np.mean(np.abs(after))),
        "after_gnss_abs_level_1500m_max_m": float(np.max(np.abs(after))),
        "after_gnss_abs_outage_mean_m": float(np.mean(np.abs(after_out))),
        "after_gnss_abs_outage_max_m": float(np.max(np.abs(after_out))),
        "after_truth_abs_level_1500m_mean_m": float(np.mean(np.abs(after_t))),
        "after_truth_abs_level_1500m_max_m": float(np.max(np.abs(after_t))),
        "after_truth_abs_outage_mean_m": float(np.mean(np.abs(after_t_out))),
        "after_truth_abs_outage_max_m": float(np.max(np.abs(after_t_out))),
        # how much of (b) - (c) the GNSS error averaged over the calibration's memory explains
        "gnss_minus_truth_vs_gnss_error_corr_level": float(
            np.corrcoef(after - after_t, g_mem)[0, 1]
        ),
        "gnss_minus_truth_vs_gnss_error_corr_outage": float(
            np.corrcoef(after_out - after_t_out, g_mem_out)[0, 1]
        ),
        "gnss_error_memory_mean_abs_m": float(np.mean(np.abs(g_mem))),
        "ok": bool(np.max(np.abs(after)) <= 2.0),
        "ok_against_truth": bool(np.max(np.abs(after_t)) <= 2.0),
        "true_scale": s_true,
        "true_bias_m": b_true,
    }
    hor: dict[str, Any] = {}
    for v in ("calm", "front"):
        e = [s["rows"][f"{v}/ekf"] for s in per_seed]
        for m in LOOP_METHODS:
            r = [s["rows"][f"{v}/{m}"] for s in per_seed]
            hor[f"{v}/{m}"] = {
                k: float(max(abs(a[k] - b[k]) for a, b in zip(r, e, strict=True)))
                for k in ("outage_horizontal_rmse_m", "gnss_on_horizontal_rmse_m")
            }
    targets["horizontal_max_abs_difference_vs_ekf_m"] = hor
    bias_keys = (
        "isa_pressure_altitude",
        "qnh_set",
        "p4_temperature_only",
        "p4_calibrated_from_gnss",
        "p4_calibrated_from_gnss_replay",
        "p4_calibrated_from_truth",
        "gnss_vertical_error",
    )
    bias: dict[str, Any] = {
        k: {w: _summ([s["baro_bias"][k][w] for s in per_seed]) for w in per_seed[0]["baro_bias"][k]}
        for k in bias_keys
    }
    bias["estimated_scale_at_outage_start"] = _summ(
        [s["baro_bias"]["estimated_scale_at_outage_start"] for s in per_seed]
    )
    bias["estimated_bias_m_at_outage_start"] = _summ(
        [s["baro_bias"]["estimated_bias_m_at_outage_start"] for s in per_seed]
    )
    bias["true_scale"], bias["true_bias_m"] = s_true, b_true
    return {"rows": agg, "targets": targets, "baro_bias": bias}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tuning-seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--report-seeds", type=int, nargs="+", default=list(range(100, 110)))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("bench/results/altitude_jsbsim.json"))
    ap.add_argument(
        "--aggregate-only",
        action="store_true",
        help="recompute the aggregates and targets of an existing --out file from its per-seed "
        "rows (no flights)",
    )
    args = ap.parse_args()
    if args.aggregate_only:
        saved = json.loads(args.out.read_text())
        saved.update(aggregate(saved["per_seed"]))
        args.out.write_text(json.dumps(saved, indent=2, default=float))
        print(json.dumps(saved["targets"], indent=1))
        return
    t_start = time.perf_counter()
    load0 = os.getloadavg()
    ctx = multiprocessing.get_context("spawn")
    result: dict[str, Any] = {
        "benchmark": "altitude_jsbsim",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "workers": args.workers,
        "load_average_start": load0,
        "flight": {
            "plan": PLAN,
            "start_alt_msl_m": START_ALT_M,
            "duration_s": DURATION_S,
            "sim_rate_hz": SIM_RATE_HZ,
            "imu_rate_hz": IMU_RATE_HZ,
            "imu": IMU,
            "gnss": "modern",
            "baro": "ms5611",
            "gnss_off_s": OUTAGE,
        },
        "variants": VARIANTS,
        "tuning_seeds": args.tuning_seeds,
        "report_seeds": args.report_seeds,
    }
    with ctx.Pool(args.workers) as pool:
        tune_data = pool.map(_tune_flight, args.tuning_seeds)
    result["tuning_replay_vs_navfilter_max_diff_m"] = {
        d["seed"]: d["replay_vs_navfilter_max_diff_m"] for d in tune_data
    }
    t_tuned = time.perf_counter()
    tuned: dict[str, dict[str, dict[str, Any]]] = {}
    tuning: dict[str, Any] = {}
    with ctx.Pool(args.workers, _init_tune, (tune_data,)) as pool:
        for setup in TUNE_VARIANTS:
            tuned[setup], tuning[setup] = {}, {}
            for m in LOOP_METHODS:
                cands = candidates(m, setup, tuned[setup].get("loop"))
                scores = pool.map(_score, [(m, p, setup) for p in cands])
                i = int(np.argmin(scores))
                tuned[setup][m] = cands[i]
                tuning[setup][m] = {
                    "params": cands[i],
                    "objective_m": scores[i],
                    "grid": len(cands),
                }
                print(f"tuned {setup} {m}: {cands[i]} -> {scores[i]:.2f} m", flush=True)
    del tune_data
    result["tuning"] = tuning
    result["tuning_wall_s"] = time.perf_counter() - t_start
    result["grid_wall_s"] = time.perf_counter() - t_tuned
    with ctx.Pool(args.workers) as pool:
        per_seed = pool.map(_report_seed, [(s, tuned) for s in args.report_seeds])
    result["per_seed"] = per_seed
    result["load_average_end"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    # saved before aggregating, so --aggregate-only can redo a failed aggregation
    args.out.write_text(json.dumps(result, indent=2, default=float))
    result.update(aggregate(per_seed))
    result["total_wall_s"] = time.perf_counter() - t_start
    result["load_average_end"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=float))
    for n, r in result["rows"].items():
        print(
            f"{n:40s} outage rmse {r['outage_rmse_m']['mean']:6.2f} end "
            f"{r['outage_end_abs_error_m']['mean']:6.2f} on {r['gnss_on_rmse_m']['mean']:5.2f}"
            f" osc {r['osc_rms_d2_height_m']['mean'] * 1e3:5.1f} mm"
        )
    print(json.dumps(result["targets"], indent=1))
    print(f"total {result['total_wall_s']:.0f} s")


if __name__ == "__main__":
    main()

