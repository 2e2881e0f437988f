"""Benchmark diagnosis: where the air-data filter's outage error and its attitude inconsistency
come from, taken apart against the simulator's truth.

``--what outage`` (default): steady wind (drawn as in ``bench/air_data.py --air-rows``), no
turbulence, GNSS off from 240 s for 300 s. Per flight and filter variant: the heading error
with GNSS on (mean, rms, the filter's sigma) and in the outage (the same, and rms(error / sigma)
in both: whether the filter's heading sigma covers its error), the mean-wind error at the
outage start and its mean in the outage, the velocity error along and across the air-relative
track in the outage, the true sideslip (mean, rms), and the horizontal outage RMSE.

``--what attitude``: GNSS on throughout (300 s), free inertial (air data off); per flight and
simulator variant (the IMU's scale factors, misalignments or turn-on biases zeroed), the
roll/pitch/yaw-axis tilt error against the filter's sigma from 120 s on.

Variants: ``SECTION.FIELD=VALUE`` of the filter configuration (``--what outage``:
``airspeed.wind_noise_mps2_rthz=0.01``, ``mag.fuse_rate_hz=0.1``) or of the simulated IMU
(``--what attitude``: ``accel.misalignment_mrad=0``), several joined by ``;``; ``default``
is the filter / simulator as configured. Run on tuning flights (seeds 1-3 of ``manoeuvre``,
``cruise``, ``racetrack``), never on the held-out ones.

    python bench/air_data_truth.py --what outage --flights cruise:1,manoeuvre:2 \\
        --variants 'default,mag.fuse_rate_hz=0.1,airspeed.wind_noise_mps2_rthz=0.01'
    python bench/air_data_truth.py --what attitude --imu consumer-mems --flights racetrack:3 \\
        --variants 'default,...'
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "bench") not in sys.path:
    sys.path.insert(0, str(ROOT / "bench"))

OUTAGE_START_S = 240.0
OUTAGE_S = 300.0


def _fly(plan: str, seed: int, imu: str, duration_s: float, outage: bool,
         sim_variant: str) -> tuple[list[Any], np.ndarray, tuple[float, float, float]]:  # fmt: skip
    """Fly one flight: decoded samples, 5 Hz truth rows (t, beta, alpha, TAS, yaw, vN, vE, vD,
    wind N, E, D) and the drawn wind."""
    import air_data

    from fusion.rotations import euler_from_quat
    from hil.codec import Decoder
    from hil.pipeline import SimChain, SimSetup

    wind, _ = air_data.weather(seed, 10.0, (0.0, 0.0))
    setup = SimSetup.build(
        plan=plan, imu=imu, gnss="modern", seed=seed, pitot="ms4525do", duration_s=duration_s,
        wind=",".join(f"{w:.3f}" for w in wind), turbulence=0.0,
        gnss_off=[f"{OUTAGE_START_S}:{OUTAGE_S + 10.0}"] if outage else [],
    )  # fmt: skip
    if sim_variant != "default":
        imu_cfg = setup.sensors.imu
        upd: dict[str, dict[str, float]] = {}
        for item in sim_variant.split(";"):
            key, value = item.split("=")
            sec, field = key.split(".")
            upd.setdefault(sec, {})[field] = float(value)
        imu_cfg = imu_cfg.model_copy(update={
            "gyro": imu_cfg.gyro.model_copy(update=upd.get("gyro", {})),
            "accel": imu_cfg.accel.model_copy(update=upd.get("accel", {}))})  # fmt: skip
        setup = dataclasses.replace(
            setup, sensors=setup.sensors.model_copy(update={"imu": imu_cfg}))
    frames: list[bytes] = []
    truth: list[tuple[float, ...]] = []
    with SimChain(setup) as chain:
        for step in chain.steps(batch=200):
            frames.extend(f for _, f in step.frames)
            tr = step.truth
            if not truth or tr.time_us * 1e-6 - truth[-1][0] >= 0.2:
                truth.append((tr.time_us * 1e-6, tr.beta_rad, tr.alpha_rad, tr.airspeed_mps,
                              euler_from_quat(tuple(tr.q_nb))[2], *tr.v_ned_mps,
                              *tr.wind_ned_mps))  # fmt: skip
    dec = Decoder()
    items = [d.sample for f in frames for d in dec.feed(f)]
    return items, np.array(truth, dtype=float), wind


def _config(imu: str, airspeed: str, variant: str) -> Any:
    from hil.pipeline import filter_config
    from sim import presets

    cfg = filter_config(imu, presets.gnss_preset("modern"), airspeed=airspeed)
    if variant == "default":
        return cfg
    for item in variant.split(";"):
        key, value = item.split("=")
        sec, field = key.split(".")
        sub = getattr(cfg, sec)
        old = getattr(sub, field)
        val: Any = value in ("1", "true") if isinstance(old, bool) else type(old)(value)
        cfg = cfg.model_copy(update={sec: sub.model_copy(update={field: val})})
    return cfg


def outage_row(items: list[Any], truth: np.ndarray, imu: str, variant: str) -> dict[str, Any]:
    """The air-data filter's outage error taken apart against the truth."""
    from hil.pipeline import FusionRun
    from scenarios import metrics

    run = FusionRun(_config(imu, "on", variant), "none")
    est: list[tuple[float, ...]] = []
    att = run.nav.layout.ATT
    for k in range(0, len(items), 5000):
        for e in run.feed(items[k:k + 5000]):
            if est and e.time_us * 1e-6 - est[-1][0] < 0.2:
                continue
            a = e.air_data
            w = a.wind_ne_mps if a is not None else (math.nan, math.nan)
            est.append((e.time_us * 1e-6, e.v_ned_mps[0], e.v_ned_mps[1], e.euler_rad[2], w[0],
                        w[1], math.degrees(math.sqrt(float(e.P_diag[att + 2])))))  # fmt: skip
    col = run.collector
    assert col is not None
    err = metrics.errors(col.estimate_track(), col.truth_track())
    end_s = OUTAGE_START_S + OUTAGE_S
    inside = (err.time_s >= OUTAGE_START_S) & (err.time_s <= end_s)
    E = np.array(est)
    t = E[:, 0]
    tt = truth[:, 0]

    def at(col_: int) -> np.ndarray:
        return np.interp(t, tt, truth[:, col_])

    yaw_t = np.interp(t, tt, np.unwrap(truth[:, 4]))
    dyaw = np.degrees((E[:, 3] - yaw_t + math.pi) % (2 * math.pi) - math.pi)
    dv = np.stack([E[:, 1] - at(5), E[:, 2] - at(6)], axis=1)
    u = np.stack([np.cos(yaw_t), np.sin(yaw_t)], axis=1)
    along = np.sum(dv * u, axis=1)
    across = -dv[:, 0] * u[:, 1] + dv[:, 1] * u[:, 0]
    werr = np.hypot(E[:, 4] - at(8), E[:, 5] - at(9))
    on = (t >= 120.0) & (t < OUTAGE_START_S)
    out = (t >= OUTAGE_START_S) & (t <= end_s)
    beta = np.degrees(truth[:, 1])
    return {
        "heading_err_gnss_on_mean_deg": float(np.mean(dyaw[on])),
        "heading_err_gnss_on_rms_deg": float(np.sqrt(np.mean(dyaw[on] ** 2))),
        "heading_sigma_gnss_on_deg": float(np.mean(E[on, 6])),
        "heading_err_outage_mean_deg": float(np.mean(dyaw[out])),
        "heading_err_outage_rms_deg": float(np.sqrt(np.mean(dyaw[out] ** 2))),
        "heading_sigma_outage_deg": float(np.mean(E[out, 6])),
        "heading_rms_z_gnss_on": float(np.sqrt(np.mean((dyaw[on] / E[on, 6]) ** 2))),
        "heading_rms_z_outage": float(np.sqrt(np.mean((dyaw[out] / E[out, 6]) ** 2))),
        "wind_err_outage_start_mps": float(werr[out][0]),
        "wind_err_outage_mean_mps": float(np.nanmean(werr[out])),
        "vel_err_along_mean_mps": float(np.mean(along[out])),
        "vel_err_across_mean_mps": float(np.mean(across[out])),
        "sideslip_mean_deg": float(np.mean(beta)), "sideslip_rms_deg": float(
            np.sqrt(np.mean(beta**2))),
        "h_rmse_outage_m": float(np.sqrt(np.mean(err.horizontal_m[inside] ** 2))),
    }  # fmt: skip


def attitude_row(items: list[Any], imu: str) -> dict[str, Any]:
    """Free inertial with GNSS: the tilt error per axis against the filter's sigma."""
    from hil.pipeline import FusionRun
    from scenarios import metrics

    run = FusionRun(_config(imu, "off", "default"), "none")
    run.feed(items)
    col = run.collector
    assert col is not None
    err = metrics.errors(col.estimate_track(), col.truth_track())
    assert err.tilt_rad is not None and err.sigma is not None
    m = err.time_s >= 120.0
    z = err.tilt_rad[m] / err.sigma[m][:, 6:9]
    return {
        "tilt_rms_z_ned": np.sqrt(np.mean(z**2, axis=0)).round(2).tolist(),
        "tilt_rms_err_ned_deg": np.degrees(np.sqrt(np.mean(err.tilt_rad[m] ** 2, axis=0)))
        .round(3).tolist(),
        "tilt_rms_sigma_ned_deg": np.degrees(np.sqrt(np.mean(err.sigma[m][:, 6:9] ** 2, axis=0)))
        .round(3).tolist(),
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--what", choices=("outage", "attitude"), default="outage")
    ap.add_argument("--flights", default="cruise:1,manoeuvre:2", help="PLAN:SEED,...")
    ap.add_argument("--imu", default="industrial-mems")
    ap.add_argument("--variants", default="default")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    out = args.out or Path(f"bench/results/air_data_truth_{args.what}.json")
    t0 = time.perf_counter()
    rows = []
    for flight in args.flights.split(","):
        plan, seed = flight.split(":")
        variants = args.variants.split(",")
        if args.what == "outage":
            items, truth, wind = _fly(plan, int(seed), args.imu,
                                      OUTAGE_START_S + OUTAGE_S + 5.0, True, "default")
            for v in variants:
                row = {"plan": plan, "seed": int(seed), "variant": v,
                       "wind_ned_mps": wind, **outage_row(items, truth, args.imu, v)}
                rows.append(row)
                print(json.dumps({k: round(x, 3) if isinstance(x, float) else x
                                  for k, x in row.items()}), flush=True)  # fmt: skip
        else:
            for v in variants:
                items, _, _ = _fly(plan, int(seed), args.imu, 300.0, False, v)
                row = {"plan": plan, "seed": int(seed), "sim_variant": v,
                       **attitude_row(items, args.imu)}
                rows.append(row)
                print(json.dumps(row), flush=True)
    result = {
        "bench": f"air_data_truth_{args.what}",
        "command": "python bench/air_data_truth.py " + " ".join(argv or sys.argv[1:]),
        "imu": args.imu, "rows": rows, "wall_s": time.perf_counter() - t0,
        "load_average": os.getloadavg(),
    }  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"-> {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
