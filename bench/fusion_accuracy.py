"""Benchmark: navigation-filter accuracy with GNSS and free-inertial drift in GNSS outages.

Each run flies one flight plan (default: racetrack and manoeuvre, 600 s, Cessna 172 at 50 m/s)
with the ``industrial-mems`` IMU, the ``modern`` GNSS receiver, the ``ms5611`` barometer and
the ``consumer`` magnetometer. GNSS is switched off (no HIL_GPS sent) for a 30 s outage at
200 s and a 60 s outage at 400 s. The flight goes through the pipeline of every command
(:func:`hil.pipeline.fly` into a :class:`hil.pipeline.FusionRun`: MAVLink encode, decode,
:class:`fusion.filter.NavFilter` with no bridging method, so outages are flown
free-inertial), scored by the one scorer (:func:`scenarios.summary.score_run`).

The filter is tuned from the IMU and GNSS presets' datasheets only
(:func:`hil.tuning.filter_config_for_presets`: IMU noise and bias model, the GNSS receiver's
correlated position error as the filter's GNSS bias states), never from truth. Its hand-set
defaults were tuned on seeds 1-2 of the racetrack (the GNSS bias default on seeds 1-5), so the
reported seeds default to 100-109, held out from that tuning. ``--gnss-bias off`` flies the
filter without the GNSS bias states (each fix fused as white noise), for comparison.

Reported per run and aggregated (mean, p95 across seeds; per plan and overall):

- ``gnss_on``: horizontal / vertical RMSE and roll / pitch / yaw RMSE while GNSS is fused.
  As in ``summary.json``, this excludes the first 60 s and the 60 s after each outage
  (``settle_s``), so convergence and re-acquisition transients are not in it.
- ``raw_gnss_horizontal_rmse_m``: the decoded GNSS fixes against the truth interpolated at
  each fix's time of validity, over the same GNSS-on mask (the filter must not be worse than
  its aiding); ``filter_over_raw`` is the ratio of the two.
- free-inertial drift: the horizontal error 30 s into the 30 s outage and 60 s into the 60 s
  outage (outage windows found from the fix times, as replay does: last fix before the gap to
  first fix after it), plus each outage's maximum and RMSE. These are the baseline the GMDH
  bridging must beat.
- ``nees_mean`` (9 dof: position, velocity, attitude) while GNSS is on, and
  ``rms_z_{pos,vel,att}`` = rms(error / sigma) per state group and ``rms_z_axis`` per axis
  (N, E, D position and velocity; roll-, pitch-, yaw-axis attitude in NED): 1 if consistent.

Targets (``meets_targets``): horizontal RMSE (GNSS on) <= raw GNSS horizontal RMSE of the same
run (ratio <= 1), roll and pitch RMSE <= 0.2 deg, yaw RMSE <= 1 deg; each judged on the mean,
on the p95 and on every run.

    python bench/fusion_accuracy.py --out bench/results/fusion_accuracy.json \
        [--seeds 10] [--seed-base 100] [--plans racetrack,manoeuvre] [--duration 600] [--jobs 2]
        [--gnss-bias default|on|off] [--mag-reference wmm|learned]

Each run is independent; ``--jobs`` runs them in that many processes (spawned, with one BLAS
thread each so two jobs do not fight over two cores).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

IMU = "industrial-mems"
GNSS = "modern"
OUTAGES: tuple[tuple[float, float], ...] = ((200.0, 30.0), (400.0, 60.0))
"""(start_s, duration_s) of the GNSS outages; each needs >= 60 s of GNSS after it."""
SETTLE_S = 60.0
TUNING_SEEDS = (
    "racetrack seeds 1-2 (filter defaults hand-tuned on them); GNSS bias states on/off "
    "decided on racetrack and manoeuvre seed 1"
)
TARGETS: dict[str, tuple[str, float]] = {
    "horizontal_rmse_vs_raw_gnss": ("filter_over_raw", 1.0),
    "roll_rmse_deg": ("roll_rmse_deg", 0.2),
    "pitch_rmse_deg": ("pitch_rmse_deg", 0.2),
    "yaw_rmse_deg": ("yaw_rmse_deg", 1.0),
}
"""Target name -> (row key, limit): the row value must be <= limit."""


def _quantile(values: list[float], q: float) -> float:
    import numpy as np

    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.quantile(v, q)) if v else float("nan")


def run_one(plan: str, seed: int, duration_s: float, gnss_bias: str = "default",
            mag_reference: str = "wmm") -> dict[str, Any]:
    """Fly one plan with one seed and score the filter; returns one row of the results.

    Parameters
    ----------
    plan : str
        Flight plan name (``sim.plans``).
    seed : int
        Scenario seed (flight turbulence and all sensor noise).
    duration_s : float
        Simulated flight time, s.
    gnss_bias : str
        ``default`` (the configuration's), ``on`` or ``off``: the filter's GNSS bias states.
    mag_reference : str
        ``wmm`` (the default: World Magnetic Model at the filter's position) or ``learned``
        (learned in flight): the magnetometer's reference field.

    Returns
    -------
    dict
        Flat metrics of the run (see the module docstring), plus the full ``summary``.
    """
    import numpy as np

    from hil.pipeline import FusionRun, SimSetup, fly
    from hil.tracks import Track
    from hil.tuning import filter_config_for_presets
    from scenarios import metrics
    from scenarios.summary import RunInfo, score_run

    setup = SimSetup.build(
        plan=plan, imu=IMU, gnss=GNSS, duration_s=duration_s, seed=seed,
        gnss_off=[f"{s}:{d}" for s, d in OUTAGES])
    cfg = filter_config_for_presets(IMU, GNSS)
    if gnss_bias != "default":
        base = "ins22" if cfg.state_layout.startswith("ins22") else "ins16"
        cfg = cfg.model_copy(
            update={"state_layout": f"{base}+gnss" if gnss_bias == "on" else base})
    cfg = cfg.model_copy(update={"mag": cfg.mag.model_copy(update={"reference": mag_reference})})
    run = FusionRun(cfg, keep_objects=True)
    report = fly(setup, run)
    nav, col = run.nav, run.collector
    assert col is not None
    fixes = col.fixes
    fusion_s = run.fuse_s
    info = RunInfo(scenario=plan, seed=seed, sim_duration_s=report.sim_duration_s,
                   wall_s=report.wall_s, bridge="none", altitude="ekf")
    scored = score_run(run, info, settle_s=SETTLE_S)
    summary, err, truth, outages = scored.summary, scored.errors, scored.truth, scored.outages

    # Raw GNSS: the fixes as a track (attitude unused), scored like the filter.
    gnss_track = Track(
        time_s=np.array([f.time_us for f in fixes], dtype=float) * 1e-6,
        lat_rad=np.array([f.lat_rad for f in fixes]),
        lon_rad=np.array([f.lon_rad for f in fixes]),
        alt_m=np.array([f.alt_msl_m for f in fixes]),
        v_ned_mps=np.array([f.v_ned_mps for f in fixes]),
        euler_rad=np.zeros((len(fixes), 3)),
    )
    gnss_err = metrics.errors(gnss_track, truth)
    gnss_on = metrics.gnss_on_mask(gnss_err.time_s, outages, settle_s=SETTLE_S)
    raw_h = metrics.rms(gnss_err.horizontal_m[gnss_on])
    raw_v = metrics.rms(gnss_err.pos_ned_m[gnss_on, 2])

    on = summary["gnss_on"]
    # rms(error / sigma) per axis over the GNSS-on mask (the summary has it per group)
    on_mask = metrics.gnss_on_mask(err.time_s, outages, settle_s=SETTLE_S)
    rms_z_axis: list[float | None] = [None] * 9
    if err.sigma is not None and on_mask.any():
        e9 = err.nav9()[on_mask]
        z9 = e9 / np.maximum(err.sigma[on_mask], 1e-12)
        rms_z_axis = [float(v) for v in np.sqrt(np.mean(z9 * z9, axis=0))]
    row: dict[str, Any] = {
        "plan": plan,
        "seed": seed,
        "sim_duration_s": report.sim_duration_s,
        "ended_early": None if report.ended is None else str(report.ended),
        "wall_s": report.wall_s,
        "fusion_wall_s": fusion_s,
        "horizontal_rmse_m": on["horizontal_rmse_m"],
        "vertical_rmse_m": on["vertical_rmse_m"],
        "roll_rmse_deg": on["roll_rmse_deg"],
        "pitch_rmse_deg": on["pitch_rmse_deg"],
        "yaw_rmse_deg": on["yaw_rmse_deg"],
        "raw_gnss_horizontal_rmse_m": raw_h,
        "raw_gnss_vertical_rmse_m": raw_v,
        "filter_over_raw": on["horizontal_rmse_m"] / raw_h if raw_h > 0 else float("nan"),
        "nees_mean": summary["nees"].get("nees_mean", float("nan")),
        "rms_z_pos": summary["nees"].get("rms_z_pos", float("nan")),
        "rms_z_vel": summary["nees"].get("rms_z_vel", float("nan")),
        "rms_z_att": summary["nees"].get("rms_z_att", float("nan")),
        "rms_z_axis": rms_z_axis,
        "filter_layout": nav.layout.name,
        "n_outages_found": len(summary["outages"]),
        "gnss_rejected": nav.health.gnss_rejected,
        "gnss_resets": nav.health.gnss_resets,
    }
    # Match the found outages to the planned ones by start time (a found outage starts at the
    # last fix before the planned window, i.e. <= 1 fix interval earlier).
    for start, dur in OUTAGES:
        tag = f"outage{int(dur)}"
        match = [o for o in summary["outages"] if abs(o["start_s"] - start) < 1.0]
        o = match[0] if match else None
        at = None if o is None else o["horizontal_error_m_at"].get(str(int(dur)))
        row[f"{tag}_h_err_at_end_m"] = at
        row[f"{tag}_h_max_m"] = None if o is None else o["horizontal_max_m"]
        row[f"{tag}_h_rmse_m"] = None if o is None else o["horizontal_rmse_m"]
        row[f"{tag}_v_rmse_m"] = None if o is None else o["vertical_rmse_m"]
        row[f"{tag}_window_s"] = None if o is None else [o["start_s"], o["end_s"]]
    row["meets_targets"] = {
        name: bool(row[key] is not None and math.isfinite(row[key]) and row[key] <= limit)
        for name, (key, limit) in TARGETS.items()
    }
    row["summary"] = summary
    return row


def _run_star(args: tuple[str, int, float, str, str]) -> dict[str, Any]:
    plan, seed, duration, gnss_bias, mag_reference = args
    t0 = time.perf_counter()
    try:
        row = run_one(plan, seed, duration, gnss_bias, mag_reference)
    except Exception as exc:  # a failed run is reported, not allowed to sink the others
        row = {"plan": plan, "seed": seed, "error": f"{type(exc).__name__}: {exc}"}
    row["run_wall_s"] = time.perf_counter() - t0
    print(f"  {plan:10s} seed {seed:4d}: {row.get('horizontal_rmse_m', float('nan')):.2f} m "
          f"on, {row.get('outage60_h_err_at_end_m') or float('nan'):.1f} m @60 s outage "
          f"({row['run_wall_s']:.0f} s)", flush=True)
    return row


AGG_KEYS = (
    "horizontal_rmse_m", "vertical_rmse_m", "roll_rmse_deg", "pitch_rmse_deg", "yaw_rmse_deg",
    "raw_gnss_horizontal_rmse_m", "filter_over_raw", "nees_mean",
    "rms_z_pos", "rms_z_vel", "rms_z_att",
    "outage30_h_err_at_end_m", "outage30_h_max_m", "outage30_h_rmse_m",
    "outage60_h_err_at_end_m", "outage60_h_max_m", "outage60_h_rmse_m",
)


def aggregate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean, p95 and max across the rows of each metric in :data:`AGG_KEYS`."""
    import numpy as np

    good = [r for r in rows if "error" not in r]
    out: dict[str, Any] = {"runs": len(good), "failed_runs": len(rows) - len(good)}
    for k in AGG_KEYS:
        v = [float(r[k]) for r in good if r.get(k) is not None and math.isfinite(r[k])]
        out[k] = {
            "mean": float(np.mean(v)) if v else float("nan"),
            "p95": _quantile(v, 0.95),
            "max": float(np.max(v)) if v else float("nan"),
            "n": len(v),
        }
    return out


def targets(rows: list[dict[str, Any]], agg: dict[str, Any]) -> dict[str, Any]:
    """Per target: limit, mean / p95 / worst value and whether each is within the limit."""
    good = [r for r in rows if "error" not in r]
    out = {}
    for name, (key, limit) in TARGETS.items():
        a = agg[key]
        out[name] = {
            "metric": key,
            "limit": limit,
            "mean": a["mean"],
            "p95": a["p95"],
            "max": a["max"],
            "ok_mean": bool(a["mean"] <= limit),
            "ok_p95": bool(a["p95"] <= limit),
            "ok_all_runs": bool(good) and all(r["meets_targets"][name] for r in good)
            and len(good) == len(rows),
            "failing_runs": [f"{r['plan']}:{r['seed']}" for r in good
                             if not r["meets_targets"][name]],
        }
    return out


def _table(result: dict[str, Any]) -> str:
    cols = [
        ("horiz m", "horizontal_rmse_m", ".2f"), ("raw m", "raw_gnss_horizontal_rmse_m", ".2f"),
        ("ratio", "filter_over_raw", ".2f"), ("vert m", "vertical_rmse_m", ".2f"),
        ("roll°", "roll_rmse_deg", ".3f"), ("pitch°", "pitch_rmse_deg", ".3f"),
        ("yaw°", "yaw_rmse_deg", ".3f"), ("NEES", "nees_mean", ".1f"),
        ("z pos", "rms_z_pos", ".2f"), ("z vel", "rms_z_vel", ".2f"), ("z att", "rms_z_att", ".2f"),
        ("30s@30 m", "outage30_h_err_at_end_m", ".1f"),
        ("60s@60 m", "outage60_h_err_at_end_m", ".1f"),
        ("60s max m", "outage60_h_max_m", ".1f"),
    ]
    head = f"{'group':22s}" + "".join(f"{c[0]:>10s}" for c in cols)
    lines = [head, "-" * len(head)]
    groups = [(f"{p}", a) for p, a in result["aggregate"]["per_plan"].items()]
    groups.append(("all", result["aggregate"]["overall"]))
    for name, agg in groups:
        for stat in ("mean", "p95"):
            cells = "".join(f"{format(agg[k][stat], f):>10s}" for _, k, f in cols)
            lines.append(f"{name + ' ' + stat:22s}{cells}")
    lines.append("")
    for tname, t in result["meets_targets"].items():
        lines.append(f"target {tname:28s} <= {t['limit']:<5g} mean {t['mean']:.3f} p95 "
                     f"{t['p95']:.3f} max {t['max']:.3f}  ok(mean/p95/all) "
                     f"{t['ok_mean']}/{t['ok_p95']}/{t['ok_all_runs']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=10, help="number of seeds per plan")
    ap.add_argument("--seed-base", type=int, default=100, help="first seed (held out: >= 3)")
    ap.add_argument("--plans", default="racetrack,manoeuvre", help="comma-separated plans")
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--out", type=Path, default=Path("bench/results/fusion_accuracy.json"))
    ap.add_argument("--gnss-bias", choices=("default", "on", "off"), default="default",
                    help="the filter's GNSS position-bias states (default: as configured)")
    ap.add_argument("--mag-reference", choices=("wmm", "learned"), default="wmm",
                    help="the magnetometer's reference field (learned: learned in flight)")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.jobs < 1:
        ap.error("--seeds and --jobs must be >= 1")
    if args.seed_base < 0:
        ap.error("--seed-base must be >= 0")
    last_end = OUTAGES[-1][0] + OUTAGES[-1][1]
    if args.duration < last_end + SETTLE_S:
        ap.error(f"--duration must be >= {last_end + SETTLE_S:g} s (outages end at "
                 f"{last_end:g} s, then {SETTLE_S:g} s of GNSS)")
    plans = [p.strip() for p in args.plans.split(",") if p.strip()]
    seeds = list(range(args.seed_base, args.seed_base + args.seeds))
    tasks = [(p, s, args.duration, args.gnss_bias, args.mag_reference)
             for p in plans for s in seeds]

    load0 = os.getloadavg()
    t0 = time.perf_counter()
    print(f"{len(tasks)} runs ({len(plans)} plans x {len(seeds)} seeds, {args.duration:g} s) "
          f"on {args.jobs} process(es)", flush=True)
    if args.jobs == 1:
        rows = [_run_star(t) for t in tasks]
    else:
        with mp.get_context("spawn").Pool(args.jobs) as pool:
            rows = list(pool.imap(_run_star, tasks))
    wall = time.perf_counter() - t0

    import numpy as np

    per_plan = {p: aggregate([r for r in rows if r["plan"] == p]) for p in plans}
    overall = aggregate(rows)
    result: dict[str, Any] = {
        "benchmark": "fusion_accuracy",
        "imu": IMU,
        "gnss": GNSS,
        "plans": plans,
        "seeds": seeds,
        "seeds_note": f"held-out reporting seeds; tuning used {TUNING_SEEDS}",
        "duration_s": args.duration,
        "outages": [{"start_s": s, "duration_s": d} for s, d in OUTAGES],
        "settle_s": SETTLE_S,
        "gnss_on_note": (
            "gnss_on metrics (filter and raw GNSS) exclude the first 60 s and the 60 s after "
            "each outage end, as summary.json does"),
        "outage_note": (
            "free-inertial (bridge none); outage windows from fix-time gaps (last fix before "
            "to first fix after); *_h_err_at_end_m is the horizontal error 30 s into the 30 s "
            "outage / 60 s into the 60 s outage"),
        "filter_tuning": "hil.tuning.filter_config_for_presets(IMU, GNSS) (datasheet, not truth)",
        "gnss_bias": args.gnss_bias,
        "mag_reference": args.mag_reference,
        "filter_layouts": sorted({r["filter_layout"] for r in rows if "filter_layout" in r}),
        "targets": {k: {"metric": m, "limit": lim} for k, (m, lim) in TARGETS.items()},
        "machine": {
            "python": platform.python_version(), "numpy": np.__version__,
            "cpu_count": os.cpu_count(), "jobs": args.jobs,
            "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
            "load_average_at_start": list(load0), "load_average_at_end": list(os.getloadavg()),
        },
        "wall_s": wall,
        "aggregate": {"per_plan": per_plan, "overall": overall},
        "meets_targets": targets(rows, overall),
        "meets_targets_per_plan": {p: targets([r for r in rows if r["plan"] == p], per_plan[p])
                                   for p in plans},
        "runs": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from scenarios.jsonable import json_safe

    args.out.write_text(json.dumps(json_safe(result), indent=1) + "\n")
    failed = [r for r in rows if "error" in r]
    for r in failed:
        print(f"FAILED {r['plan']} seed {r['seed']}: {r['error']}", file=sys.stderr)
    print(_table(result))
    print(f"wall {wall:.0f} s -> {args.out}")
    return 1 if failed else 0


if __name__ == "__main__":
    # One BLAS thread per process (inherited by spawned workers): small matrices, 2 cores.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
