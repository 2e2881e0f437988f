"""Benchmark: navigation through long GNSS denial on air data.

Each flight: Cessna 172 (c172x) on one plan, ``ms4525do`` pitot, ``modern`` GNSS, ``ms5611``
baro, ``consumer`` magnetometer, and the IMU preset given (``industrial-mems`` by default);
wind drawn per seed (speed uniform in [0, ``--max-wind``] m/s, direction uniform) with
turbulence uniform in [0, 0.4] (JSBSim MIL-F-8785C severity, ``sim.flight``); GNSS switched
off from ``--outage-start`` (240 s: four minutes of GNSS to learn the wind and the vehicle) for
``--outage`` s (300). The flight is flown once (lockstep, real MAVLink 2 bytes, decoded once)
and the same samples go to every method:

- ``inertial``: the filter with air data off (``--airspeed off``): baro, magnetometer and the
  IMU; the free-inertial baseline every target is relative to;
- ``air-data``: the default filter (``--airspeed on``): TAS + synthetic sideslip with wind and
  airspeed-scale states; dead-reckoning in the outage;
- ``no-pitot``: the stream without its airspeed samples (the same aircraft without a pitot)
  and ArduPilot-style synthetic airspeed from the last wind estimate (``--airspeed
  synthetic``): the baseline a learned vehicle model must beat;
- ``gmdh-airspeed``: the stream without a pitot and the learned vehicle model
  (``--bridge gmdh-airspeed``), when that method exists;
- ``gmdh-wind``: the pitot filter with the learned wind profile (``--bridge gmdh-wind``): the
  residual the physics filter leaves, the wind's change with height (``--wind-shear``).

``--methods`` runs a subset (``inertial`` is always run: every ratio is relative to it).
``--wind-shear P`` gives the flights a power-law shear ``w(h) = w_ref (h / h_ref)^P`` (the
drawn wind at the start height; P = 1/7 is the neutral boundary layer), ``--start-alt`` the
start height (m above the flat terrain: the shear is larger near the ground).

Reported per method: the horizontal error 25 s, 60 s and 300 s into the outage (linear
interpolation of the 10 Hz estimate error; 900 s too with ``--outage 900``), per flight and as
median / p95 over flights; each method's ratio to ``inertial`` (ratio of the summed errors,
and the worst single-flight ratio); the mean 9-state NEES inside the outage; the filter mode
at the end of the outage; the error curve (median over flights, every 5 s) for the plot.

Seeds and plans: the filter's air-data settings were chosen on tuning seeds 1-5 of
``manoeuvre`` and ``cruise`` (``--seed-base 1 --plans manoeuvre,cruise``); the reported rows
are held-out seeds 100.. on ``survey``, ``climb-descent`` and ``racetrack``. The settings of the
turbulence estimate and the outage hold (``AirspeedTuning.gust_sigma_min_mps``,
``outage_noise_factor``, ``outage_hold_max_turbulence_mps``) were chosen on seeds 1-3 of
``manoeuvre`` and ``cruise`` in steady wind and turbulence; ``--air-rows`` reports held-out
seeds 100-102, one flight per plan. The still-air wind random walk, the outage hold's
factor on its climb-driven part and where the turbulence estimate sets the gust sigma
(``AirspeedTuning.still_air_wind_noise_mps2_rthz``, ``outage_climb_noise_factor``,
``gust_sigma_estimated_above_still_air``) were chosen on ``manoeuvre`` seeds 1 and 3 and
``cruise`` seed 2 (``--air-rows --groups steady,turbulent --seeds 3 --seed-base 1 --plans
manoeuvre,cruise``), before any held-out flight was flown with them.

``--variants 'SECTION.FIELD=VALUE[;...],...'`` (``--air-rows``) adds the air-data filter
with those configuration fields set as methods named ``air-data:...``, on the same samples:
candidate settings on tuning flights, today's settings beside the default on held-out ones.

    python bench/air_data.py --out bench/results/air_data.json [--seeds 10] [--seed-base 100]
        [--plans survey,climb-descent,racetrack] [--imu industrial-mems] [--outage 300]
        [--methods inertial,air-data,...] [--wind-shear 0.143] [--start-alt 1000]
        [--jobs 2] [--plot docs/air_data_outage.png]

``--synthetic`` runs the same question on the synthetic flight of the filter's tests instead
(no JSBSim; pitot faults too, see :func:`run_synthetic`):

    python bench/air_data.py --synthetic [--seeds 5] [--out bench/results/air_data_synthetic.json]

Targets: ``air-data`` <= 0.3x ``inertial`` 300 s into the outage and <= 1.05x at 25 s and
60 s, outage NEES in its chi-square band, industrial p95 <= 150 m at 300 s; ``gmdh-airspeed``
<= 0.5x the latched synthetic airspeed; ``gmdh-wind`` <= 0.8x ``air-data`` in shear; a
blocked pitot detected within 10 s and adding <= 30 m at 300 s (``--synthetic``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing as mp
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # tests.helpers (the synthetic flight of --synthetic)
    sys.path.insert(0, str(ROOT))

HORIZONS_S = (25.0, 60.0, 300.0, 900.0)
CURVE_STEP_S = 5.0
MAX_TURBULENCE = 0.4


FIXED_AIR = {"adaptive_turbulence": False, "outage_hold": False, "position_error_fit": False}
"""``air-data-fixed``: the air-data filter with a fixed turbulence sigma, no outage hold and no
position-error fit (:class:`fusion.config.AirspeedTuning` switches)."""


VARIANT_PREFIX = "air-data:"
"""``--variants``: a method named ``air-data:SECTION.FIELD=VALUE[;...]`` is the default
air-data filter with those configuration fields set (:func:`variant_config`)."""


def variant_config(cfg: Any, variant: str) -> Any:
    """``cfg`` with the fields of ``variant`` (``SECTION.FIELD=VALUE`` joined by ``;``) set;
    ValueError names a malformed item or an unknown field."""
    for item in variant.split(";"):
        key, sep, value = item.partition("=")
        sec, dot, field = key.partition(".")
        sub = getattr(cfg, sec, None) if sep and dot else None
        if sub is None or field not in type(sub).model_fields:
            raise ValueError(f"bad variant {item!r}: expected SECTION.FIELD=VALUE of the "
                             "filter configuration")
        old = getattr(sub, field)
        try:  # validated (the field's bounds), not model_copy's unchecked update
            val: Any = value in ("1", "true") if isinstance(old, bool) else type(old)(value)
            new = type(sub).model_validate({**sub.model_dump(), field: val})
        except ValueError as exc:
            errors = getattr(exc, "errors", None)
            why = errors()[0]["msg"] if callable(errors) else str(exc)
            raise ValueError(f"bad variant {item!r}: {why}") from None
        cfg = cfg.model_copy(update={sec: new})
    return cfg


def _methods() -> list[tuple[str, str, str, bool]]:
    """(name, --airspeed, --bridge, keep the pitot samples)."""
    from fusion.bridging.registry import BRIDGE_METHODS

    rows = [
        ("inertial", "off", "none", True),
        ("air-data", "on", "none", True),
        ("air-data-fixed", "on", "none", True),
        ("no-pitot", "synthetic", "none", False),
    ]
    if "gmdh-airspeed" in BRIDGE_METHODS:
        rows.append(("gmdh-airspeed", "synthetic", "gmdh-airspeed", False))
    if "gmdh-wind" in BRIDGE_METHODS:
        rows.append(("gmdh-wind", "on", "gmdh-wind", True))
    return rows


def weather(
    seed: int, max_wind_mps: float, turbulence_range: tuple[float, float] | None = None
) -> tuple[tuple[float, float, float], float]:
    """The seed's wind (N, E, D m/s) and turbulence severity: drawn, never chosen
    (``turbulence_range``: drawn uniformly in it instead of [0, 0.4])."""
    rng = np.random.default_rng([18, seed])
    speed = float(rng.uniform(0.0, max_wind_mps))
    direction = float(rng.uniform(0.0, 2.0 * math.pi))
    turbulence = float(rng.uniform(0.0, MAX_TURBULENCE))
    if turbulence_range is not None:
        lo, hi = turbulence_range
        turbulence = lo + (hi - lo) * float(rng.uniform())
    return (speed * math.cos(direction), speed * math.sin(direction), 0.0), turbulence


def run_flight(task: dict[str, Any]) -> dict[str, Any]:
    """Fly one flight and run every method on its samples; one result row."""
    from hil.codec import Decoder
    from hil.pipeline import FusionRun, SimSetup, filter_config, fly
    from scenarios import metrics
    from sim import presets
    from sim.samples import AirspeedSample

    plan, seed, imu = task["plan"], task["seed"], task["imu"]
    start_s, outage_s = task["outage_start_s"], task["outage_s"]
    wind, turbulence = weather(seed, task["max_wind_mps"], task.get("turbulence"))
    factor = task.get("sensor_factor", 1.0)
    setup = SimSetup.build(
        plan=plan, imu=imu, gnss="modern", seed=seed, pitot=task.get("pitot", "ms4525do"),
        duration_s=start_s + outage_s + 5.0,
        wind=",".join(f"{w:.3f}" for w in wind), turbulence=turbulence,
        wind_shear_exponent=task.get("wind_shear", 0.0), alt_msl_m=task.get("start_alt_m", 1000.0),
        gnss_off=[f"{start_s}:{outage_s + 10.0}"],
    )  # fmt: skip
    if factor != 1.0:  # the sensors fly worse than their preset; the filter keeps the preset
        setup = dataclasses.replace(setup, sensors=worse_sensors(setup.sensors, factor))
    t0 = time.perf_counter()
    frames: list[bytes] = []
    flown = fly(setup, lambda _t, f: frames.append(f))
    dec = Decoder()
    items = [d.sample for f in frames for d in dec.feed(f)]
    sim_wall = time.perf_counter() - t0
    receiver = presets.gnss_preset("modern")
    row: dict[str, Any] = {
        "plan": plan, "seed": seed, "imu": imu, "wind_ned_mps": wind,
        "wind_speed_mps": math.hypot(wind[0], wind[1]), "turbulence": turbulence,
        "sim_s": flown.sim_duration_s, "sim_wall_s": sim_wall, "methods": {},
        "sensor_factor": factor,
    }  # fmt: skip
    end_s = start_s + outage_s
    variants = [(v, "on", "none", True) for v in task.get("variants", ())]
    for name, airspeed, bridge, keep_pitot in [*_methods(), *variants]:
        if name not in task.get("methods", (name,)) and name not in task.get("variants", ()):
            continue
        cfg = filter_config(imu, receiver, airspeed=airspeed)
        if name == "air-data-fixed":
            cfg = cfg.model_copy(update={"airspeed": cfg.airspeed.model_copy(update=FIXED_AIR)})
        elif name.startswith(VARIANT_PREFIX):
            cfg = variant_config(cfg, name.removeprefix(VARIANT_PREFIX))
        run = FusionRun(cfg, bridge)
        t1 = time.perf_counter()
        # the mean-wind estimate and its sigma at 1 Hz (the wind group's consistency)
        wind_track: list[tuple[float, float, float, float, float]] = []
        feed = [s for s in items if keep_pitot or not isinstance(s, AirspeedSample)]
        for k in range(0, len(feed), 5000):
            for e in run.feed(feed[k:k + 5000]):
                _wind_point(run.nav, e, wind_track)
        wall = time.perf_counter() - t1
        col = run.collector
        assert col is not None
        err = metrics.errors(col.estimate_track(), col.truth_track())
        h = err.horizontal_m
        at = {
            f"h_err_{int(d)}s_m": (float(np.interp(start_s + d, err.time_s, h))
                                   if start_s + d <= min(end_s, err.time_s[-1]) else None)
            for d in HORIZONS_S
        }  # fmt: skip
        inside = (err.time_s >= start_s) & (err.time_s <= end_s)
        nees = metrics.consistency(err, inside)
        aided = metrics.consistency(err, (err.time_s >= 120.0) & (err.time_s < start_s))
        air = run.nav.air_data
        grid = np.arange(0.0, outage_s + 1e-9, CURVE_STEP_S)
        curve = np.interp(start_s + grid, err.time_s, h).tolist()
        modes = col.modes()
        times = col.estimate_track().time_s
        k = int(np.searchsorted(times, end_s - 1.0))
        row["methods"][name] = {
            **at,
            "nees_mean": nees.get("nees_mean"),
            "h_rmse_outage_m": float(np.sqrt(np.mean(h[inside] ** 2))),
            "rms_z_outage": {g: nees.get(f"rms_z_{g}") for g in ("pos", "vel", "att")},
            "rms_z_gnss_on": {g: aided.get(f"rms_z_{g}") for g in ("pos", "vel", "att")},
            "nees_gnss_on": aided.get("nees_mean"),
            "nees_group_outage": _group_nees(err, inside),
            "wind": _wind_consistency(wind_track, wind, turbulence, start_s, end_s),
            "turbulence_mps": air.turbulence_mps, "turbulence_source": air.turbulence_source,
            "turbulence_estimate_mps": air.turbulence_estimate_mps,
            "position_error_per_rad": air.position_error_per_rad, "air_flags": air.flags,
            "mode_at_end": modes[min(k, len(modes) - 1)] if modes else None,
            "curve_m": curve,
            "filter_wall_s": wall,
        }
    return row


def worse_sensors(sensors: Any, factor: float) -> Any:
    """The suite with its IMU's and pitot's noise and bias terms times ``factor`` (white
    noise, bias instability, rate random walk, turn-on bias; the pitot's noise, offsets and
    scale error): sensors worse than the preset the filter is tuned for."""
    g, a = sensors.imu.gyro, sensors.imu.accel
    gyro = g.model_copy(update={k: getattr(g, k) * factor for k in (
        "angle_random_walk_deg_per_rth", "bias_instability_deg_per_h",
        "rate_random_walk_deg_per_h_per_rth", "turn_on_bias_deg_per_h")})
    accel = a.model_copy(update={k: getattr(a, k) * factor for k in (
        "velocity_random_walk_mps_per_rth", "bias_instability_ug", "rate_random_walk_ug_per_rth",
        "turn_on_bias_mg")})
    update: dict[str, Any] = {"imu": sensors.imu.model_copy(update={"gyro": gyro, "accel": accel})}
    p = sensors.pitot
    if p is not None:
        update["pitot"] = p.model_copy(update={k: getattr(p, k) * factor for k in (
            "noise_pa", "offset_sigma_pa", "offset_gm_sigma_pa", "offset_random_walk_pa_per_rth",
            "scale_error_sigma")})
    return sensors.model_copy(update=update)


def _wind_point(nav: Any, e: Any, track: list[tuple[float, float, float, float, float]]) -> None:
    """Append (t, wind N, E, sigma N, E) of an estimate with running wind states, at 1 Hz."""
    air = e.air_data
    t = e.time_us * 1e-6
    if air is None or not air.wind_active or (track and t - track[-1][0] < 1.0):
        return
    w = nav.layout.WIND
    pn, pe = float(e.P_diag[w]), float(e.P_diag[w + 1])
    track.append((t, air.wind_ne_mps[0], air.wind_ne_mps[1], math.sqrt(max(pn, 0.0)),
                  math.sqrt(max(pe, 0.0))))


def _wind_consistency(
    track: list[tuple[float, float, float, float, float]], wind: tuple[float, float, float],
    turbulence: float, start_s: float, end_s: float,
) -> dict[str, float | None]:  # fmt: skip
    """rms(error / sigma) of the mean-wind estimate with GNSS on (from 120 s) and in the
    outage, and its mean 2-dof NEES in the outage; only in steady air, where the truth is the
    drawn wind (in turbulence the air at the aircraft is not one mean wind)."""
    out: dict[str, float | None] = {"rms_z_gnss_on": None, "rms_z_outage": None,
                                    "nees_outage": None, "rmse_outage_mps": None}
    if turbulence > 0.0 or not track:
        return out
    arr = np.array(track)
    zn = (arr[:, 1] - wind[0]) / np.maximum(arr[:, 3], 1e-9)
    ze = (arr[:, 2] - wind[1]) / np.maximum(arr[:, 4], 1e-9)
    on = (arr[:, 0] >= 120.0) & (arr[:, 0] < start_s)
    off = (arr[:, 0] >= start_s) & (arr[:, 0] <= end_s)
    for key, m in (("rms_z_gnss_on", on), ("rms_z_outage", off)):
        if m.any():
            out[key] = float(np.sqrt(np.mean(np.concatenate([zn[m], ze[m]]) ** 2)))
    if off.any():
        out["nees_outage"] = float(np.mean(zn[off] ** 2 + ze[off] ** 2))
        en, ee = arr[off, 1] - wind[0], arr[off, 2] - wind[1]
        out["rmse_outage_mps"] = float(np.sqrt(np.mean(en**2 + ee**2)))
    return out


def _group_nees(err: Any, mask: Any) -> dict[str, float | None]:
    """Mean NEES of each 3-dof group (position, velocity, attitude) in the mask (expected 3),
    from the 3x3 blocks of the covariance the filter reported."""
    from scenarios import metrics

    out: dict[str, float | None] = {"pos": None, "vel": None, "att": None}
    if err.cov is None or not mask.any():
        return out
    att = err.tilt_rad if err.tilt_rad is not None else err.att_rad
    cov9 = err.cov[np.flatnonzero(mask)]
    for name, e, sl in (("pos", err.pos_ned_m, slice(0, 3)), ("vel", err.vel_ned_mps, slice(3, 6)),
                        ("att", att, slice(6, 9))):  # fmt: skip
        cov = np.ascontiguousarray(cov9[:, sl, sl])
        out[name] = float(np.mean(metrics.nees(np.ascontiguousarray(e[mask]), cov)))
    return out


def _run_star(task: dict[str, Any]) -> dict[str, Any]:
    row = run_flight(task)
    m = row["methods"]
    parts = " ".join(
        f"{k}={v['h_err_300s_m'] if v['h_err_300s_m'] is not None else float('nan'):.0f}"
        for k, v in m.items()
    )
    print(f"  {row['plan']} seed {row['seed']} wind {row['wind_speed_mps']:.1f} m/s: "
          f"h err at 300 s {parts}", file=sys.stderr, flush=True)
    return row


def _fly_all(tasks: list[dict[str, Any]], jobs: int) -> list[dict[str, Any]]:
    """Every task's row, in order (``jobs`` processes)."""
    if jobs > 1:
        with mp.get_context("spawn").Pool(jobs) as pool:
            return pool.map(_run_star, tasks, chunksize=1)
    return [_run_star(t) for t in tasks]


def _quantile(values: list[float], q: float) -> float | None:
    return float(np.quantile(values, q)) if values else None


def summarise(rows: list[dict[str, Any]], outage_s: float) -> dict[str, Any]:
    methods = list(rows[0]["methods"]) if rows else []
    out: dict[str, Any] = {}
    for name in methods:
        agg: dict[str, Any] = {}
        for d in HORIZONS_S:
            if d > outage_s:
                continue
            key = f"h_err_{int(d)}s_m"
            vals = [r["methods"][name][key] for r in rows if r["methods"][name][key] is not None]
            base = [r["methods"]["inertial"][key] for r in rows
                    if r["methods"][name][key] is not None]
            agg[key] = {"median": _quantile(vals, 0.5), "p95": _quantile(vals, 0.95),
                        "max": max(vals) if vals else None}
            if name != "inertial" and vals:
                per = [v / b for v, b in zip(vals, base, strict=True) if b > 0]
                agg[key]["ratio_vs_inertial"] = sum(vals) / sum(base)
                agg[key]["worst_ratio_vs_inertial"] = max(per) if per else None
        nees = [r["methods"][name]["nees_mean"] for r in rows
                if r["methods"][name]["nees_mean"] is not None]
        agg["nees_mean_median"] = _quantile(nees, 0.5)
        curves = np.array([r["methods"][name]["curve_m"] for r in rows])
        agg["curve_median_m"] = np.median(curves, axis=0).tolist() if len(curves) else []
        agg["modes_at_end"] = sorted({r["methods"][name]["mode_at_end"] for r in rows}
                                     - {None})
        out[name] = agg
    return out


def plot(summary: dict[str, Any], outage_s: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=120)
    grid = np.arange(0.0, outage_s + 1e-9, CURVE_STEP_S)
    for name, agg in summary.items():
        if agg["curve_median_m"]:
            ax.plot(grid, agg["curve_median_m"], label=name)
    ax.set_xlabel("time into GNSS outage, s")
    ax.set_ylabel("horizontal error (median over flights), m")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=None,
                    help="default bench/results/air_data.json (--synthetic: "
                         "air_data_synthetic.json)")
    ap.add_argument("--synthetic", action="store_true",
                    help="the tests' synthetic flight with pitot faults instead of JSBSim "
                         "(run_synthetic; --seeds 5 there)")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--seed-base", type=int, default=100)
    ap.add_argument("--plans", default="survey,climb-descent,racetrack")
    ap.add_argument("--imu", default="industrial-mems")
    ap.add_argument("--outage-start", type=float, default=240.0)
    ap.add_argument("--outage", type=float, default=300.0)
    ap.add_argument("--max-wind", type=float, default=12.0)
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--plot", type=Path, default=None)
    ap.add_argument("--methods", default=None, help="comma-separated subset (default: all)")
    ap.add_argument("--wind-shear", type=float, default=0.0)
    ap.add_argument("--start-alt", type=float, default=1000.0)
    ap.add_argument("--air-rows", action="store_true",
                    help="rows per kind of air, IMU and pitot (calm, steady wind, turbulent; "
                         "position error on/off): free inertial, air-data-fixed and air-data "
                         "side by side (run_air_rows; --seeds per row, plans cycled)")
    ap.add_argument("--variants", default=None,
                    help="--air-rows: also these air-data filter variants, comma-separated, "
                         "each SECTION.FIELD=VALUE[;...] (e.g. airspeed.outage_hold=false)")
    ap.add_argument("--groups", default=None,
                    help="--air-rows: only these kinds of air (comma-separated: "
                         "calm, steady, steady-pe, turbulent)")
    args = ap.parse_args(argv)
    if args.air_rows:
        return run_air_rows(args, argv)
    if args.synthetic:
        return run_synthetic(args.seeds, args.seed_base,
                             args.out or Path("bench/results/air_data_synthetic.json"))
    args.out = args.out or Path("bench/results/air_data.json")
    known = [m[0] for m in _methods()]
    methods = known if args.methods is None else ["inertial", *(
        m for m in args.methods.split(",") if m != "inertial")]
    if unknown := set(methods) - set(known):
        ap.error(f"unknown methods {sorted(unknown)}; known: {', '.join(known)}")
    tasks = [
        {"plan": p, "seed": args.seed_base + i, "imu": args.imu,
         "outage_start_s": args.outage_start, "outage_s": args.outage,
         "max_wind_mps": args.max_wind, "methods": methods,
         "wind_shear": args.wind_shear, "start_alt_m": args.start_alt}
        for p in args.plans.split(",") for i in range(args.seeds)
    ]  # fmt: skip
    t0 = time.perf_counter()
    rows = _fly_all(tasks, args.jobs)
    summary = summarise(rows, args.outage)
    result = {
        "bench": "air_data",
        "command": "python bench/air_data.py " + " ".join(argv or sys.argv[1:]),
        "imu": args.imu, "plans": args.plans.split(","),
        "seeds": [args.seed_base, args.seed_base + args.seeds - 1],
        "outage_start_s": args.outage_start, "outage_s": args.outage,
        "max_wind_mps": args.max_wind, "max_turbulence": MAX_TURBULENCE,
        "wind_shear_exponent": args.wind_shear, "start_alt_m": args.start_alt,
        "summary": summary, "rows": rows,
        "wall_s": time.perf_counter() - t0,
        "load_average": os.getloadavg(), "machine": platform.processor() or platform.machine(),
    }  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    for name, agg in summary.items():
        cells = []
        for d in HORIZONS_S:
            a = agg.get(f"h_err_{int(d)}s_m")
            if a and a["median"] is not None:
                r = a.get("ratio_vs_inertial")
                cells.append(f"{int(d)} s: med {a['median']:.1f} p95 {a['p95']:.1f}"
                             + (f" x{r:.2f}" if r is not None else ""))
        print(f"{name:>14}: " + "; ".join(cells) + f"; NEES {agg['nees_mean_median']}")
    if args.plot is not None:
        plot(summary, args.outage, args.plot)
    return 0


AIR_ROWS: tuple[tuple[str, float, tuple[float, float], str, tuple[str, ...], float], ...] = (
    # (air, max wind m/s, turbulence range, pitot, IMUs, sensor factor)
    ("calm", 0.0, (0.0, 0.0), "ms4525do", ("industrial-mems", "consumer-mems"), 1.0),
    ("steady", 10.0, (0.0, 0.0), "ms4525do", ("industrial-mems", "consumer-mems"), 1.0),
    ("steady-pe", 10.0, (0.0, 0.0), "ms4525do-pe", ("industrial-mems",), 1.0),
    ("turbulent", 12.0, (0.1, 0.4), "ms4525do", ("industrial-mems", "consumer-mems"), 1.0),
    ("steady-2x", 10.0, (0.0, 0.0), "ms4525do", ("industrial-mems", "consumer-mems"), 2.0),
    ("turbulent-2x", 12.0, (0.1, 0.4), "ms4525do", ("industrial-mems", "consumer-mems"), 2.0),
)
"""The ``--air-rows`` groups: the air (calm; steady wind without turbulence; turbulence
0.1-0.4), the pitot (``-pe``: with the static-source position error of
:mod:`sim.pitot`), the IMUs flown and the sensor factor (``-2x``: the IMU's and the pitot's
noise and bias terms twice their preset's, :func:`worse_sensors`, while the filter keeps the
preset's model: the consistency rows)."""
ROW_METHODS = ("inertial", "air-data-fixed", "air-data")


def run_air_rows(args: argparse.Namespace, argv: list[str] | None) -> int:
    """``--air-rows``: one group per kind of air, pitot and IMU (:data:`AIR_ROWS`), ``--seeds``
    flights each (seeds from ``--seed-base``, plans cycled), free inertial, today's fixed
    air-data filter and the adaptive one on the same samples. Per group: the ratio of the
    summed outage RMSEs to free inertial's, median / p95 / max error at 300 s, the largest
    error in the outage, and rms(error / sigma) per group (position, velocity, attitude; the
    mean wind in steady air) in the outage and with GNSS on (median and worst flight), and
    the mean NEES per 3-dof group in the outage (worst flight; 3 is consistent)."""
    plans = args.plans.split(",")
    only = set(args.groups.split(",")) if args.groups else None
    variants = tuple(VARIANT_PREFIX + v for v in args.variants.split(",")) if args.variants else ()
    methods = (*ROW_METHODS, *variants)
    from hil.pipeline import filter_config
    from sim import presets

    try:  # a malformed variant: one line before any flight
        for v in variants:
            variant_config(filter_config("industrial-mems", presets.gnss_preset("modern")),
                           v.removeprefix(VARIANT_PREFIX))
    except (ValueError, TypeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    tasks = []
    for air, max_wind, turb, pitot, imus, factor in AIR_ROWS:
        if only is not None and air not in only:
            continue
        for imu in imus:
            for i in range(args.seeds):
                tasks.append({
                    "group": f"{air}/{imu}", "plan": plans[i % len(plans)],
                    "seed": args.seed_base + i, "imu": imu, "pitot": pitot,
                    "outage_start_s": args.outage_start, "outage_s": args.outage,
                    "max_wind_mps": max_wind, "turbulence": turb, "methods": ROW_METHODS,
                    "variants": variants, "sensor_factor": factor,
                })  # fmt: skip
    t0 = time.perf_counter()
    rows = _fly_all(tasks, args.jobs)
    for t, r in zip(tasks, rows, strict=True):
        r["group"], r["pitot"] = t["group"], t["pitot"]
    groups: dict[str, Any] = {}
    for g in dict.fromkeys(t["group"] for t in tasks):
        rs = [r for r in rows if r["group"] == g]
        groups[g] = {m: _row_summary(rs, m) for m in methods}
    result = {
        "bench": "air_data_rows",
        "command": "python bench/air_data.py " + " ".join(argv or sys.argv[1:]),
        "tuned_on": "seeds 1-3 of manoeuvre and cruise (steady wind and turbulence 0.15-0.3, "
                    "industrial and consumer MEMS)",
        "plans": plans, "seeds": [args.seed_base, args.seed_base + args.seeds - 1],
        "outage_start_s": args.outage_start, "outage_s": args.outage,
        "groups": groups, "rows": rows, "wall_s": time.perf_counter() - t0,
        "load_average": os.getloadavg(), "machine": platform.processor() or platform.machine(),
    }  # fmt: skip
    out = args.out or Path("bench/results/air_data_rows.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    for g, ms in groups.items():
        for m, a in ms.items():
            print(f"{g:>28} {m:>15}: rmse {a['h_rmse_outage_m_median']:.0f} m "
                  f"x{a.get('rmse_ratio_vs_inertial') or 1.0:.2f}; "
                  f"300 s med {a['h_err_300s_median']} p95 {a['h_err_300s_p95']}; "
                  f"max {a['h_max_m']:.0f}; "
                  f"rms z out {a['rms_z_outage_max']} on {a['rms_z_gnss_on_max']} "
                  f"nees3 out {a['nees_group_outage_max']} "
                  f"wind z on {a['wind_rms_z_gnss_on_max']} out {a['wind_rms_z_outage_max']}")
    return 0


def _row_summary(rows: list[dict[str, Any]], method: str) -> dict[str, Any]:
    """One method over one group's flights (:func:`run_air_rows`)."""
    ms = [r["methods"][method] for r in rows]
    rmse = [m["h_rmse_outage_m"] for m in ms]
    e300 = [m["h_err_300s_m"] for m in ms if m["h_err_300s_m"] is not None]
    out: dict[str, Any] = {
        "h_rmse_outage_m_median": _quantile(rmse, 0.5),
        "h_err_300s_median": _quantile(e300, 0.5), "h_err_300s_p95": _quantile(e300, 0.95),
        "h_max_m": max(max(m["curve_m"]) for m in ms),
        "turbulence_mps": [m["turbulence_mps"] for m in ms],
    }  # fmt: skip
    if method != "inertial":
        base = [r["methods"]["inertial"]["h_rmse_outage_m"] for r in rows]
        out["rmse_ratio_vs_inertial"] = sum(rmse) / sum(base)
        out["worst_rmse_ratio_vs_inertial"] = max(a / b for a, b in zip(rmse, base, strict=True))
    for key in ("rms_z_outage", "rms_z_gnss_on"):
        out[f"{key}_median"] = {g: _round(_quantile([m[key][g] for m in ms
                                                     if m[key][g] is not None], 0.5))
                                for g in ("pos", "vel", "att")}  # fmt: skip
        out[f"{key}_max"] = {g: _round(max((m[key][g] for m in ms if m[key][g] is not None),
                                           default=None))
                             for g in ("pos", "vel", "att")}  # fmt: skip
    out["nees_group_outage_max"] = {g: _round(max(
        (m["nees_group_outage"][g] for m in ms if m["nees_group_outage"][g] is not None),
        default=None)) for g in ("pos", "vel", "att")}  # fmt: skip
    for key in ("rms_z_gnss_on", "rms_z_outage", "nees_outage", "rmse_outage_mps"):
        out[f"wind_{key}_max"] = _round(max((m["wind"][key] for m in ms
                                             if m["wind"][key] is not None), default=None))
    return out


def _round(x: float | None) -> float | None:
    return None if x is None else round(x, 2)


def run_synthetic(seeds: int, seed_base: int, out: Path) -> int:
    """``--synthetic``: air-data dead reckoning and pitot faults on the tests' synthetic flight.

    The flight of ``tests/fusion/test_airspeed.py`` (400 s at 30 m/s through a steady wind, a
    turn every minute, a climb, a descent, a 2 m/s airspeed wave; IMU, GNSS and baro errors
    drawn from the filter's own model, ``tests.helpers.nav_synth``), GNSS lost from 100 s to
    400 s, a pitot at 20 Hz. Per seed, the horizontal error at the end of the 300 s outage for
    ``free`` (air data off), ``air`` (the pitot fused), ``zero`` (the pitot reads ~0 from
    200 s: detection time and error), ``stuck`` (the pitot latches at 200 s) and
    ``no_pitot_synthetic`` (no pitot, synthetic airspeed from the wind estimate). The
    synthetic-airspeed settings were chosen on seeds 31-34 of the tests; the reported seeds
    are 100 on.
    """
    import numpy as np

    from fusion.config import AirspeedTuning, FilterConfig
    from fusion.filter import NavFilter
    from tests.fusion.test_airspeed import (
        CFG,
        ERRORS,
        OUTAGE,
        TAS_NOISE_MPS,
        WIND,
        horizontal_error_m,
    )
    from tests.helpers.nav_synth import Flight, airspeed_samples, make_scenario, merge, prepare

    turns = [(20.0, 35.0, 0.2), (60.0, 75.0, -0.2), (130.0, 145.0, 0.2), (190.0, 205.0, 0.2),
             (250.0, 265.0, -0.2), (310.0, 325.0, 0.2), (360.0, 375.0, -0.2)]  # fmt: skip
    prep = prepare(Flight(duration_s=OUTAGE[1], speed_mps=30.0, wind_ne_mps=WIND, turns=turns,
                          climbs=[(80.0, 95.0, 3.0), (220.0, 235.0, -3.0)],
                          speed_wave_mps=2.0))  # fmt: skip
    t_fault = 200.0

    def cfg(**kw: Any) -> FilterConfig:
        return CFG.model_copy(update={"airspeed": AirspeedTuning(**kw)})

    def fly(samples: list[Any], config: FilterConfig) -> tuple[NavFilter, list[Any]]:
        nav = NavFilter(config)
        out: list[Any] = []
        for s in samples:
            out.extend(nav.step(s))
        return nav, out

    def zero(t: float, qc: float) -> float:
        return qc if t < t_fault else float(np.random.default_rng(int(t * 1e3)).normal(0, 1.0))

    rows = []
    t0 = time.perf_counter()
    for seed in range(seed_base, seed_base + seeds):
        held: list[float] = []

        def stuck(t: float, qc: float, held: list[float] = held) -> float:
            if t < t_fault:
                return qc
            if not held:
                held.append(qc)
            return held[0]

        row: dict[str, Any] = {"seed": seed}
        for name, fault in (("air", None), ("zero", zero), ("stuck", stuck)):
            rng = np.random.default_rng(seed)
            sc = make_scenario(prep, rng, ERRORS, gnss_outages=[OUTAGE])
            air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS, fault=fault)
            _, est = fly(merge(sc.samples, air), CFG)
            row[f"{name}_error_m"] = horizontal_error_m(sc, est[-1])
            row[f"{name}_mode_end"] = str(est[-1].mode)
            if fault is not None:
                blocked = [e.time_us * 1e-6 for e in est if e.time_us * 1e-6 >= t_fault
                           and e.air_data is not None and e.air_data.state == "blocked"]
                row[f"{name}_detected_after_s"] = blocked[0] - t_fault if blocked else None
                row[f"{name}_fault"] = est[-1].air_data.fault if est[-1].air_data else ""
        rng = np.random.default_rng(seed)
        sc = make_scenario(prep, rng, ERRORS, gnss_outages=[OUTAGE])
        _, est = fly(sc.samples, cfg(enabled=False))
        row["free_error_m"] = horizontal_error_m(sc, est[-1])
        _, est = fly(sc.samples, cfg(synthetic_when_no_pitot=True))
        row["no_pitot_synthetic_error_m"] = horizontal_error_m(sc, est[-1])
        for k in ("air", "zero", "stuck", "no_pitot_synthetic"):
            row[f"{k}_over_free"] = row[f"{k}_error_m"] / row["free_error_m"]
        rows.append(row)
        print(json.dumps({k: (round(v, 2) if isinstance(v, float) else v)
                          for k, v in row.items()}), flush=True)

    def stats(key: str) -> dict[str, float]:
        v = np.array([r[key] for r in rows if r.get(key) is not None], dtype=float)
        return {"mean": float(v.mean()), "max": float(v.max()), "min": float(v.min())}

    result = {
        "benchmark": "air_data_synthetic",
        "flight": "tests/fusion/test_airspeed.py long_flight (400 s, 30 m/s, wind 6,-4 m/s)",
        "outage_s": list(OUTAGE),
        "fault_at_s": t_fault,
        "seeds": [r["seed"] for r in rows],
        "rows": rows,
        "summary": {k: stats(k) for k in (
            "free_error_m", "air_error_m", "air_over_free", "zero_over_free", "stuck_over_free",
            "no_pitot_synthetic_over_free", "zero_detected_after_s", "stuck_detected_after_s")},
        "added_error_m": {
            "zero": stats_diff(rows, "zero_error_m", "air_error_m"),
            "stuck": stats_diff(rows, "stuck_error_m", "air_error_m"),
        },
        "wall_s": time.perf_counter() - t0,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    print(json.dumps(result["added_error_m"], indent=1), f"-> {out}")
    return 0


def stats_diff(rows: list[dict[str, Any]], a: str, b: str) -> dict[str, float]:
    """Mean / max / min of ``row[a] - row[b]`` over the rows."""
    d = [r[a] - r[b] for r in rows]
    return {"mean": sum(d) / len(d), "max": max(d), "min": min(d)} if d else {
        "mean": math.nan, "max": math.nan, "min": math.nan}


if __name__ == "__main__":
    raise SystemExit(main())
