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

Every run goes through the pipeline (:func:`hil.pipeline.fly` into a
:class:`hil.pipeline.FusionRun`, the filter from :func:`hil.pipeline.filter_config`) and is
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
VARIANTS: dict[str, tuple[str, ...]] = {
    "full": (),
    "no-scale": ("scale_factor_ppm",),
    "no-misalignment": ("misalignment_mrad",),
    "no-scale-no-misalignment": ("scale_factor_ppm", "misalignment_mrad"),
}
LAYOUTS = ("default", "ins22+gnss")
AXES = ("pn", "pe", "pd", "vn", "ve", "vd", "roll", "pitch", "yaw")


def run_one(job: tuple[str, int, float, str]) -> list[dict[str, Any]]:
    """Fly one plan and seed with every IMU variant; every filter layout on each; one row per
    (variant, layout)."""
    import numpy as np

    from hil.pipeline import FusionRun, SimSetup, filter_config, fly
    from scenarios import metrics
    from scenarios.summary import RunInfo, score_run
    from sim.presets import gnss_preset

    plan, seed, duration_s, imu = job
    base = SimSetup.build(plan=plan, imu=imu, duration_s=duration_s, seed=seed)
    rows = []
    for variant, zeroed in VARIANTS.items():
        sim_imu = base.sensors.imu
        update = dict.fromkeys(zeroed, 0.0)
        sim_imu = sim_imu.model_copy(update={"gyro": sim_imu.gyro.model_copy(update=update),
                                             "accel": sim_imu.accel.model_copy(update=update)})
        setup = dataclasses.replace(base, sensors=base.sensors.model_copy(update={"imu": sim_imu}))
        frames: list[tuple[int, bytes]] = []
        flown = fly(setup, lambda t, f, keep=frames: keep.append((t, f)))
        for layout in LAYOUTS:
            cfg = filter_config(imu, gnss_preset("modern"))
            if layout != "default":
                cfg = cfg.model_copy(update={"state_layout": layout})
            run = FusionRun(cfg)
            for _t, frame in frames:
                run.feed_frame(frame)
            info = RunInfo(scenario=plan, seed=seed, sim_duration_s=flown.sim_duration_s,
                           wall_s=0.0, bridge="none", altitude="ekf")
            scored = score_run(run, info, settle_s=SETTLE_S)
            err = scored.errors
            on = metrics.gnss_on_mask(err.time_s, scored.outages, settle_s=SETTLE_S)
            assert err.sigma is not None
            e9 = np.column_stack([err.pos_ned_m, err.vel_ned_mps, err.att_rad])[on]
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
            })
    return rows


def _mean(rows: list[dict[str, Any]], key: str, sub: str | None = None) -> float:
    vals = [r[key][sub] if sub else r[key] for r in rows]
    return float(sum(vals) / len(vals))


def aggregate(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Mean over plans and seeds per (IMU variant, layout)."""
    out = []
    for variant in VARIANTS:
        for layout in LAYOUTS:
            group = [r for r in rows if r["imu_variant"] == variant and r["layout"] == layout]
            if not group:
                continue
            out.append({
                "imu_variant": variant, "layout": group[0]["filter_layout"], "runs": len(group),
                "nees_mean": _mean(group, "nees_mean"),
                **{f"rms_z_{g}": _mean(group, f"rms_z_{g}") for g in ("pos", "vel", "att")},
                **{f"rms_z_{a}": _mean(group, "rms_z_axis", a) for a in AXES},
            })
    return out


def markdown(table: list[dict[str, Any]]) -> str:
    head = ("| IMU simulated | filter | NEES (9) | z pos | z vel | z att | z roll | z pitch "
            "| z yaw | z vd |\n|---|---|---|---|---|---|---|---|---|---|\n")
    return head + "".join(
        f"| {r['imu_variant']} | {r['layout']} | {r['nees_mean']:.1f} | {r['rms_z_pos']:.2f} "
        f"| {r['rms_z_vel']:.2f} | {r['rms_z_att']:.2f} | {r['rms_z_roll']:.2f} "
        f"| {r['rms_z_pitch']:.2f} | {r['rms_z_yaw']:.2f} | {r['rms_z_vd']:.2f} |\n"
        for r in table)


def main(argv: list[str] | None = None) -> int:
    from scenarios.jsonable import write_json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100,101,102")
    ap.add_argument("--plans", default="racetrack,manoeuvre,climb-descent")
    ap.add_argument("--duration", type=float, default=400.0)
    ap.add_argument("--imu", default="industrial-mems")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "consistency.json")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    plans = [p.strip() for p in args.plans.split(",") if p.strip()]
    jobs = [(p, s, args.duration, args.imu) for p in plans for s in seeds]
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for part in pool.map(run_one, jobs):
            rows.extend(part)
            print(f"{part[0]['plan']} seed {part[0]['seed']} done", file=sys.stderr, flush=True)
    table = aggregate(rows)
    write_json({
        "bench": "consistency", "seeds": seeds, "plans": plans, "duration_s": args.duration,
        "imu": args.imu, "settle_s": SETTLE_S, "wall_s": time.perf_counter() - t0,
        "load_average": [list(load0), list(os.getloadavg())],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "table": table, "rows": rows,
    }, args.out)
    sys.stdout.write(markdown(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
