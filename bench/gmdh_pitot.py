"""Benchmark: the learned pitot position error (``--bridge gmdh-pitot``) against the physics fit.

Each flight: Cessna 172 (c172x) on one plan, ``modern`` GNSS, ``ms5611`` baro, ``consumer``
magnetometer, ``industrial-mems`` IMU, steady wind drawn per seed (speed uniform in [0, 10] m/s,
direction uniform, no turbulence: :func:`bench.air_data.weather`'s draw), GNSS switched off from
240 s for 300 s. The pitot is ``ms4525do-pe`` (a static-source position error of 0.3 of the
impact pressure per radian of angle of attack, :mod:`sim.pitot`) or ``ms4525do`` (none); both
carry the probe's misalignment loss, quadratic in the angle of attack and the sideslip. The
flight is flown once (lockstep, real MAVLink 2 bytes, decoded once) and the same samples go to
every row:

- ``air-data``: the default air-data filter, its physics position-error fit on
  (:mod:`fusion.aiding.position_error`): the strong rival;
- ``air-data-no-fit``: the same filter with the fit off;
- ``gmdh-pitot``: the default air-data filter with ``--bridge gmdh-pitot``
  (:mod:`fusion.pitot_model`).

Reported per row and group: the horizontal RMSE over the outage, the error 60 s and 300 s into
it (median over flights), the ratio of the summed RMSEs to ``air-data``'s and the worst
single-outage ratio; per flight the physics slope taken, whether the learned correction was
applied and its selected polynomial. Cost: a GMDH refit on the learned model's own window
(median of repeats) and one prediction, against the filter's mean cost per IMU sample.

``--cost`` times a refit on a full window and a prediction through the whole correction path
against a filter step measured in the same process (the flights' own timings above are taken
while other jobs share the machine, and their prediction is mostly the gate's early return):

    python bench/gmdh_pitot.py --cost [--out bench/results/gmdh_pitot_cost.json]

Seeds and plans, decided before any held-out run: the flights must change their angle of
attack (climbs, descents, pitch and bank changes), so ``climb-descent`` and ``manoeuvre``;
the learned model's settings (window, skill ratio, range margin, inputs) were looked at on
tuning seeds 1-3 of ``climb-descent`` and seed 1 of ``manoeuvre`` with the position error on
(``--seed-base 1 --seeds 3 --groups pe-on``) and on the air-data tests' synthetic flight
(seeds 43-45, no position error); the reported rows are held-out seeds 200-202. (Seeds 100-101
of ``climb-descent`` were flown once with an earlier version whose gate opened on noise; the
gate was changed on the tuning cases above and the reported seeds moved to 200 on.)

    python bench/gmdh_pitot.py --out bench/results/gmdh_pitot.json [--seeds 3]
        [--seed-base 200] [--plans climb-descent,manoeuvre] [--jobs 2]

Targets: ``gmdh-pitot`` <= 0.8x ``air-data`` (RMSE over the outage) with the position error on,
never > 1.05x in any single outage; a refit <= 50 ms; a prediction <= 0.3x a filter step.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

OUTAGE_START_S = 240.0
OUTAGE_S = 300.0
MAX_WIND_MPS = 10.0
PITOTS = {"pe-on": "ms4525do-pe", "pe-off": "ms4525do"}
METHODS = ("air-data", "air-data-no-fit", "gmdh-pitot")
TARGET_RATIO = 0.8
TARGET_WORST = 1.05


def weather(seed: int) -> tuple[tuple[float, float, float], float]:
    """The seed's steady wind (N, E, D m/s): drawn, never chosen (the air-data bench's draw
    with no turbulence)."""
    rng = np.random.default_rng([18, seed])
    speed = float(rng.uniform(0.0, MAX_WIND_MPS))
    direction = float(rng.uniform(0.0, 2.0 * math.pi))
    return (speed * math.cos(direction), speed * math.sin(direction), 0.0), 0.0


def _costs(model: Any, step_s: float) -> dict[str, Any]:
    """A refit of the learned model on its own window and one prediction, timed (median of
    repeats), against the filter's cost per IMU sample."""
    from fusion.pitot_model import PitotInputs

    pairs = list(model._pairs)
    if len(pairs) < 8:
        return {"pairs": len(pairs)}
    t_last = pairs[-1][0]
    fits = []
    for _ in range(5):
        t0 = time.perf_counter()
        model._refit(t_last)
        fits.append(time.perf_counter() - t0)
    x = PitotInputs(*pairs[-1][1])
    n = 2000
    t0 = time.perf_counter()
    for _ in range(n):
        model.correction_mps(x)
    pred = (time.perf_counter() - t0) / n
    return {
        "pairs": len(pairs), "refit_ms": 1e3 * statistics.median(fits),
        "predict_us": 1e6 * pred, "filter_step_us": 1e6 * step_s,
        "predict_over_step": pred / step_s if step_s > 0 else None,
    }  # fmt: skip


def run_cost(out: Path, argv: list[str] | None) -> int:
    """``--cost``: a refit on a full window (600 pairs: ten minutes of an angle-of-attack
    sweep with a position error, the unit tests' case) and one prediction through the whole
    path (skilled, in range), against a filter step (the air-data filter on the air-data
    tests' synthetic flight, per IMU sample) measured in the same process."""
    from fusion.bridging.registry import make_bridge
    from fusion.filter import NavFilter
    from fusion.pitot_model import PitotInputs
    from tests.fusion.test_airspeed import CFG, ERRORS, TAS_NOISE_MPS, WIND
    from tests.fusion.test_pitot_model import _fly
    from tests.helpers.nav_synth import Flight, airspeed_samples, make_scenario, merge, prepare

    bridge = make_bridge("gmdh-pitot")
    model = bridge.pitot_model
    assert model is not None
    _fly(model, np.random.default_rng(1), 0.05)
    x = PitotInputs(math.radians(3.0), 0.0, 31.0)
    assert model.correction_mps(x) is not None, "the cost case must be skilled and in range"
    t_last = model._pairs[-1][0]
    fits = []
    for _ in range(7):
        t0 = time.perf_counter()
        model._refit(t_last)
        fits.append(time.perf_counter() - t0)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        model.correction_mps(x)
    pred_s = (time.perf_counter() - t0) / n
    prep = prepare(Flight(duration_s=120.0, speed_mps=30.0, wind_ne_mps=WIND,
                          turns=[(20.0, 35.0, 0.2), (60.0, 75.0, -0.2)]))  # fmt: skip
    rng = np.random.default_rng(1)
    sc = make_scenario(prep, rng, ERRORS)
    samples = merge(sc.samples, airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS))
    n_imu = sum(1 for s in sc.samples if type(s).__name__ == "ImuSample")
    steps = []
    for _ in range(3):
        nav = NavFilter(CFG)
        t0 = time.perf_counter()
        for s in samples:
            nav.step(s)  # type: ignore[arg-type]
        steps.append((time.perf_counter() - t0) / n_imu)
    step_s = min(steps)
    result = {
        "bench": "gmdh_pitot_cost",
        "command": "python bench/gmdh_pitot.py " + " ".join(argv or sys.argv[1:]),
        "pairs": len(model._pairs), "refit_ms_median": 1e3 * statistics.median(fits),
        "refit_ms_max": 1e3 * max(fits), "predict_us": 1e6 * pred_s,
        "filter_step_us": 1e6 * step_s, "predict_over_step": pred_s / step_s,
        "targets": {"refit_ms": 50.0, "predict_over_step": 0.3},
        "load_average": os.getloadavg(), "machine": platform.processor() or platform.machine(),
    }  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result))
    return 0


def run_flight(task: dict[str, Any]) -> dict[str, Any]:
    """Fly one flight and run every row on its samples."""
    from hil.codec import Decoder
    from hil.pipeline import FusionRun, SimSetup, filter_config, fly
    from scenarios import metrics
    from sim import presets
    from sim.samples import ImuSample

    plan, seed, group = task["plan"], task["seed"], task["group"]
    wind, turbulence = weather(seed)
    setup = SimSetup.build(
        plan=plan, imu="industrial-mems", gnss="modern", seed=seed, pitot=PITOTS[group],
        duration_s=OUTAGE_START_S + OUTAGE_S + 5.0,
        wind=",".join(f"{w:.3f}" for w in wind), turbulence=turbulence,
        gnss_off=[f"{OUTAGE_START_S}:{OUTAGE_S + 10.0}"],
    )  # fmt: skip
    frames: list[bytes] = []
    fly(setup, lambda _t, f: frames.append(f))
    dec = Decoder()
    items = [d.sample for f in frames for d in dec.feed(f)]
    n_imu = sum(isinstance(s, ImuSample) for s in items)
    receiver = presets.gnss_preset("modern")
    row: dict[str, Any] = {"group": group, "plan": plan, "seed": seed, "pitot": PITOTS[group],
                           "wind_speed_mps": math.hypot(wind[0], wind[1]), "methods": {}}
    end_s = OUTAGE_START_S + OUTAGE_S
    for name in METHODS:
        cfg = filter_config("industrial-mems", receiver, airspeed="on")
        if name == "air-data-no-fit":
            cfg = cfg.model_copy(update={"airspeed": cfg.airspeed.model_copy(
                update={"position_error_fit": False})})
        run = FusionRun(cfg, "gmdh-pitot" if name == "gmdh-pitot" else "none")
        t1 = time.perf_counter()
        run.feed(iter(items))
        wall = time.perf_counter() - t1
        col = run.collector
        assert col is not None
        err = metrics.errors(col.estimate_track(), col.truth_track())
        h = err.horizontal_m
        inside = (err.time_s >= OUTAGE_START_S) & (err.time_s <= end_s)
        out: dict[str, Any] = {
            "h_rmse_outage_m": float(np.sqrt(np.mean(h[inside] ** 2))),
            "h_err_60s_m": float(np.interp(OUTAGE_START_S + 60.0, err.time_s, h)),
            "h_err_300s_m": float(np.interp(end_s, err.time_s, h)),
            "position_error_per_rad": run.nav.air_data.position_error_per_rad,
            "filter_wall_s": wall,
        }
        if name == "gmdh-pitot":
            model = run.nav.bridge.pitot_model
            assert model is not None
            st = model.status
            out.update({
                "state": st.state, "pairs": st.samples, "refits": st.refits,
                "held_out_rmse_mps": st.validation_rmse_mps,
                "filter_rmse_mps": st.constant_rmse_mps, "skilled": model.skilled,
                "corrections": model.corrections, "out_of_range": model.out_of_range,
                "polynomial": st.polynomial,
                "cost": _costs(model, wall / max(1, n_imu)),
            })  # fmt: skip
        row["methods"][name] = out
    return row


def _run_star(task: dict[str, Any]) -> dict[str, Any]:
    row = run_flight(task)
    parts = " ".join(f"{k}={v['h_rmse_outage_m']:.0f}" for k, v in row["methods"].items())
    g = row["methods"]["gmdh-pitot"]
    print(f"  {row['group']} {row['plan']} seed {row['seed']}: rmse {parts}; "
          f"slope {row['methods']['air-data']['position_error_per_rad']:.3f}/rad, "
          f"gmdh skilled {g['skilled']} corrections {g['corrections']}",
          file=sys.stderr, flush=True)  # fmt: skip
    return row


def _median(v: list[float]) -> float | None:
    return float(np.median(v)) if v else None


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per group and row: median RMSE / 60 s / 300 s, ratios to ``air-data``."""
    out: dict[str, Any] = {}
    for group in dict.fromkeys(r["group"] for r in rows):
        rs = [r for r in rows if r["group"] == group]
        base = [r["methods"]["air-data"]["h_rmse_outage_m"] for r in rs]
        agg: dict[str, Any] = {}
        for m in METHODS:
            rmse = [r["methods"][m]["h_rmse_outage_m"] for r in rs]
            per = [a / b for a, b in zip(rmse, base, strict=True)]
            agg[m] = {
                "h_rmse_outage_m_median": _median(rmse),
                "h_err_60s_m_median": _median([r["methods"][m]["h_err_60s_m"] for r in rs]),
                "h_err_300s_m_median": _median([r["methods"][m]["h_err_300s_m"] for r in rs]),
                "rmse_ratio_vs_air_data": sum(rmse) / sum(base),
                "worst_rmse_ratio_vs_air_data": max(per),
                "best_rmse_ratio_vs_air_data": min(per),
                "per_outage_ratio_vs_air_data": [round(p, 3) for p in per],
            }
        g = [r["methods"]["gmdh-pitot"] for r in rs]
        agg["gmdh-pitot"]["flights_corrected"] = sum(1 for x in g if x["corrections"] > 0)
        agg["air-data"]["flights_with_slope"] = sum(
            1 for r in rs if r["methods"]["air-data"]["position_error_per_rad"] != 0.0)
        out[group] = agg
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("bench/results/gmdh_pitot.json"))
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed-base", type=int, default=200)
    ap.add_argument("--plans", default="climb-descent,manoeuvre")
    ap.add_argument("--groups", default="pe-on,pe-off")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--cost", action="store_true",
                    help="only the cost of a refit and a prediction against a filter step "
                         "(run_cost; default --out bench/results/gmdh_pitot_cost.json)")
    args = ap.parse_args(argv)
    if args.cost:
        out = args.out if "--out" in (argv or sys.argv) else Path(
            "bench/results/gmdh_pitot_cost.json")
        return run_cost(out, argv)
    groups = args.groups.split(",")
    if bad := set(groups) - set(PITOTS):
        ap.error(f"unknown groups {sorted(bad)}; known: {', '.join(PITOTS)}")
    tasks = [{"group": g, "plan": p, "seed": args.seed_base + i}
             for g in groups for p in args.plans.split(",") for i in range(args.seeds)]
    t0 = time.perf_counter()
    if args.jobs > 1:
        with mp.get_context("spawn").Pool(args.jobs) as pool:
            rows = pool.map(_run_star, tasks, chunksize=1)
    else:
        rows = [_run_star(t) for t in tasks]
    summary = summarise(rows)
    costs = [r["methods"]["gmdh-pitot"]["cost"] for r in rows
             if "refit_ms" in r["methods"]["gmdh-pitot"]["cost"]]
    cost = {
        "refit_ms_median": _median([c["refit_ms"] for c in costs]),
        "refit_ms_max": max((c["refit_ms"] for c in costs), default=None),
        "predict_us_median": _median([c["predict_us"] for c in costs]),
        "filter_step_us_median": _median([c["filter_step_us"] for c in costs]),
        "predict_over_step_median": _median([c["predict_over_step"] for c in costs]),
    }
    result = {
        "bench": "gmdh_pitot",
        "command": "python bench/gmdh_pitot.py " + " ".join(argv or sys.argv[1:]),
        "tuned_on": "seeds 1-3 of climb-descent and seed 1 of manoeuvre (position error on); "
                    "the air-data tests' synthetic flight, seeds 43-45",
        "plans": args.plans.split(","), "seeds": [args.seed_base, args.seed_base + args.seeds - 1],
        "outage_start_s": OUTAGE_START_S, "outage_s": OUTAGE_S, "max_wind_mps": MAX_WIND_MPS,
        "targets": {"ratio_vs_air_data": TARGET_RATIO, "worst_ratio": TARGET_WORST,
                    "refit_ms": 50.0, "predict_over_step": 0.3},
        "summary": summary, "cost": cost, "rows": rows,
        "wall_s": time.perf_counter() - t0,
        "load_average": os.getloadavg(), "machine": platform.processor() or platform.machine(),
    }  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    for g, agg in summary.items():
        for m, a in agg.items():
            print(f"{g:>7} {m:>16}: rmse {a['h_rmse_outage_m_median']:.1f} m, 60 s "
                  f"{a['h_err_60s_m_median']:.1f}, 300 s {a['h_err_300s_m_median']:.1f}; "
                  f"x{a['rmse_ratio_vs_air_data']:.3f} "
                  f"(worst {a['worst_rmse_ratio_vs_air_data']:.3f})")
    print(json.dumps(cost))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
