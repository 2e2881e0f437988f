"""Benchmark: is the filter's covariance honest? The error budget of its consistency.

The filter is judged by ``rms(error / sigma)`` per state axis (1 for a consistent filter) and
by NEES over the 9 position / velocity / attitude errors (9), with GNSS on. To find *which*
unmodelled sensor errors make it overconfident, the simulator's IMU is flown with error terms
switched off one group at a time (same seed, same trajectory and noise otherwise), and the
filter is run both in its default layout and with scale-factor states:

- IMU variants: ``full`` (the preset), ``no-scale`` (scale factors 0), ``no-misalignment``
  (misalignment 0), ``no-scale-no-misalignment``.
- Filter layouts: the commands' default for the receiver (``ins16+gnss``) and ``ins22+gnss``
  (accelerometer and gyro scale-factor states).

Every run goes through the pipeline (frames recorded by :func:`hil.pipeline.fly`, fused by
:func:`hil.pipeline.fuse_frames`, the filter from :func:`hil.pipeline.filter_config`) and is
scored by :func:`scenarios.summary.score_run` (its ``nees`` section) plus the per-axis
``rms(error / sigma)`` over the GNSS-on mask. No GNSS outage is flown: this is the aided
filter's consistency. Seeds default to 100-102 (held out: the filter's tuning never saw them).

    python bench/consistency.py [--seeds 100,101,102] [--plans racetrack,manoeuvre,climb-descent]
        [--duration 400] [--imu industrial-mems] [--jobs 2] [--out bench/results/consistency.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SETTLE_S = 60.0
#: IMU variants: the error terms switched off (a tuple of field names) or every error term
#: scaled (a float: the true sensor that much worse than the preset the filter assumes)
VARIANTS: dict[str, tuple[str, ...] | float] = {
    "full": (),
    "no-scale": ("scale_factor_ppm",),
    "no-misalignment": ("misalignment_mrad",),
    "no-scale-no-misalignment": ("scale_factor_ppm", "misalignment_mrad"),
    "x0.5": 0.5,
    "x2": 2.0,
}
#: the error terms a mismatch scales (noise, bias instability, random walk, turn-on bias, scale
#: factor, misalignment); ranges, correlation times and resolution stay the preset's
ERROR_TERMS = (
    "angle_random_walk_deg_per_rth", "velocity_random_walk_mps_per_rth",
    "bias_instability_deg_per_h", "bias_instability_ug", "rate_random_walk_deg_per_h_per_rth",
    "rate_random_walk_ug_per_rth", "turn_on_bias_deg_per_h", "turn_on_bias_mg",
    "scale_factor_ppm", "misalignment_mrad",
)  # fmt: skip
LAYOUTS = ("ins16+gnss", "ins22+gnss", "default")
AXES = ("pn", "pe", "pd", "vn", "ve", "vd", "tilt_n", "tilt_e", "tilt_d")
"""Per-axis ``rms(error / sigma)``: position and velocity N/E/D, attitude as the filter's tilt
about N/E/D (tilt D is the heading error)."""


def run_one(job: tuple[str, int, float, str, tuple[str, ...], tuple[str, ...]]
            ) -> list[dict[str, Any]]:
    """Fly one plan and seed with every IMU variant; every filter layout on each; one row per
    (variant, layout)."""
    import numpy as np

    from hil.pipeline import SimSetup, filter_config, fly, fuse_frames
    from scenarios import metrics
    from scenarios.summary import RunInfo, score_run
    from sim.presets import gnss_preset

    plan, seed, duration_s, imu, variants, layouts = job
    base = SimSetup.build(plan=plan, imu=imu, duration_s=duration_s, seed=seed)
    rows = []
    for variant in variants:
        change = VARIANTS[variant]
        sim_imu = base.sensors.imu

        def vary(triad: Any, change: tuple[str, ...] | float = change) -> Any:
            fields = type(triad).model_fields
            if isinstance(change, float):
                return triad.model_copy(update={k: getattr(triad, k) * change
                                                for k in ERROR_TERMS if k in fields})
            return triad.model_copy(update={k: 0.0 for k in change if k in fields})

        sim_imu = sim_imu.model_copy(update={"gyro": vary(sim_imu.gyro),
                                             "accel": vary(sim_imu.accel)})
        setup = dataclasses.replace(base, sensors=base.sensors.model_copy(update={"imu": sim_imu}))
        frames: list[tuple[int, bytes]] = []
        flown = fly(setup, lambda t, f, keep=frames: keep.append((t, f)))
        for layout in layouts:
            cfg = filter_config(imu, gnss_preset("modern"))
            if layout != "default":
                cfg = cfg.model_copy(update={"state_layout": layout})
            run = fuse_frames(frames, cfg)
            info = RunInfo(scenario=plan, seed=seed, sim_duration_s=flown.sim_duration_s,
                           wall_s=0.0, bridge="none", altitude="ekf")
            scored = score_run(run, info, settle_s=SETTLE_S)
            err = scored.errors
            on = metrics.gnss_on_mask(err.time_s, scored.outages, settle_s=SETTLE_S)
            assert err.sigma is not None
            e9 = err.nav9()[on]
            z9 = e9 / np.maximum(err.sigma[on], 1e-12)
            nees = scored.summary["nees"]
            rows.append({
                "plan": plan, "seed": seed, "imu_variant": variant, "layout": layout,
                "filter_layout": run.nav.layout.name,
                "nees_mean": nees.get("nees_mean"),
                "rms_z_pos": nees.get("rms_z_pos"), "rms_z_vel": nees.get("rms_z_vel"),
                "rms_z_att": nees.get("rms_z_att"),
                "rms_z_axis": dict(zip(AXES, np.sqrt(np.mean(z9 * z9, axis=0)).tolist(),
                                       strict=True)),
                "att_rmse_deg": np.degrees(np.sqrt(np.mean(err.att_rad[on] ** 2, axis=0))
                                           ).tolist(),
                "horizontal_rmse_m": scored.summary["gnss_on"]["horizontal_rmse_m"],
                # no fault is flown: every fix is within the receiver's error model, so a
                # rejection is a good fix lost (the 0.995 gate alone rejects ~0.5 %)
                "fixes": run.collector.n_fixes if run.collector else 0,
                "gnss_rejected": run.nav.health.gnss_rejected,
            })
    return rows


def _mean(rows: list[dict[str, Any]], key: str, sub: str | None = None) -> float:
    vals = [r[key][sub] if sub else r[key] for r in rows]
    return float(sum(vals) / len(vals))


def aggregate(rows: list[dict[str, Any]], by_plan: bool = False) -> list[dict[str, Any]]:
    """Mean over seeds (and plans unless ``by_plan``) per (IMU variant, layout)."""
    out = []
    plans: list[str | None] = list(dict.fromkeys(r["plan"] for r in rows)) if by_plan else [None]
    for plan in plans:
        for variant in VARIANTS:
            for layout in dict.fromkeys(r["layout"] for r in rows):
                group = [r for r in rows if r["imu_variant"] == variant
                         and r["layout"] == layout and plan in (None, r["plan"])]
                if group:
                    out.append(_row(group, plan or "all"))
    return out


def _row(group: list[dict[str, Any]], plan: str) -> dict[str, Any]:
    return {
                "plan": plan,
                "imu_variant": group[0]["imu_variant"], "layout": group[0]["filter_layout"],
                "runs": len(group),
                "nees_mean": _mean(group, "nees_mean"),
                **{f"rms_z_{g}": _mean(group, f"rms_z_{g}") for g in ("pos", "vel", "att")},
                **{f"rms_z_{a}": _mean(group, "rms_z_axis", a) for a in AXES},
                "att_rmse_deg": [_mean([{"v": r["att_rmse_deg"][k]} for r in group], "v")
                                 for k in range(3)],
                "horizontal_rmse_m": _mean(group, "horizontal_rmse_m"),
                "gnss_rejected": sum(r["gnss_rejected"] for r in group),
                "fixes": sum(r["fixes"] for r in group),
            }


def markdown(table: list[dict[str, Any]]) -> str:
    head = ("| plan | IMU simulated | filter | NEES (9) | z pos | z vel | z att | z vd "
            "| z tilt N / E / D | roll / pitch / yaw RMSE ° | horiz. RMSE m | fixes rejected "
            "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n")
    return head + "".join(
        f"| {r['plan']} | {r['imu_variant']} | {r['layout']} | {r['nees_mean']:.1f} "
        f"| {r['rms_z_pos']:.2f} | {r['rms_z_vel']:.2f} | {r['rms_z_att']:.2f} "
        f"| {r['rms_z_vd']:.2f} | {r['rms_z_tilt_n']:.2f} / {r['rms_z_tilt_e']:.2f} / "
        f"{r['rms_z_tilt_d']:.2f} | {' / '.join(f'{a:.3f}' for a in r['att_rmse_deg'])} "
        f"| {r['horizontal_rmse_m']:.2f} | {r['gnss_rejected']} of {r['fixes']} |\n"
        for r in table)


def main(argv: list[str] | None = None) -> int:
    from scenarios.jsonable import write_json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100,101,102")
    ap.add_argument("--plans", default="racetrack,manoeuvre,climb-descent")
    ap.add_argument("--duration", type=float, default=400.0)
    ap.add_argument("--imu", default="industrial-mems")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"IMU variants to fly (of {', '.join(VARIANTS)})")
    ap.add_argument("--layouts", default=",".join(LAYOUTS),
                    help="filter layouts ('default' = the commands' default for the receiver)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "consistency.json")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    plans = [p.strip() for p in args.plans.split(",") if p.strip()]
    variants = tuple(v.strip() for v in args.variants.split(",") if v.strip())
    layouts = tuple(v.strip() for v in args.layouts.split(",") if v.strip())
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f"unknown variant(s) {', '.join(unknown)}; valid: {', '.join(VARIANTS)}")
    jobs = [(p, s, args.duration, args.imu, variants, layouts) for p in plans for s in seeds]
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for part in pool.map(run_one, jobs):
            rows.extend(part)
            print(f"{part[0]['plan']} seed {part[0]['seed']} done", file=sys.stderr, flush=True)
    table = aggregate(rows)
    per_plan = aggregate(rows, by_plan=True)
    write_json({
        "bench": "consistency", "seeds": seeds, "plans": plans, "duration_s": args.duration,
        "imu": args.imu, "settle_s": SETTLE_S, "wall_s": time.perf_counter() - t0,
        "load_average": [list(load0), list(os.getloadavg())],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "table": table, "per_plan": per_plan, "rows": rows,
    }, args.out)
    sys.stdout.write(markdown(table) + "\n" + markdown(per_plan))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
