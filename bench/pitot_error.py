"""Benchmark: what the simulated pitot-static sensor reports on a real JSBSim flight.

For each pitot preset and seed, flies the plan (racetrack with turns by default, optional wind
and turbulence) through :class:`hil.pipeline.SimChain` and compares the airspeed each
``AirspeedSample`` implies (``physconst.airdata.true_airspeed_mps`` with the truth's static
pressure and temperature) with the truth's true airspeed: mean, RMS and largest error, the
angle-of-attack / sideslip range flown and the probe-misalignment loss it caused. Also reports
the simulator's throughput with and without the pitot (CPU seconds). Writes JSON.

    python bench/pitot_error.py --duration 120 --seeds 1,2,3 --out bench/results/pitot_error.json
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from hil.pipeline import SimChain, SimSetup
from physconst.airdata import true_airspeed_mps
from sim.pitot import probe_misalignment_factor
from sim.presets import pitot_preset
from sim.samples import AirspeedSample


def fly(preset: str, seed: int, duration_s: float, plan: str, wind: str,
        turbulence: float) -> dict[str, Any]:
    setup = SimSetup.build(plan=plan, duration_s=duration_s, seed=seed, pitot=preset, wind=wind,
                           turbulence=turbulence)
    cfg = pitot_preset(preset)
    err, alpha, beta, loss = [], [], [], []
    t0 = time.process_time()
    with SimChain(setup) as chain:
        for step in chain.steps():
            tr = step.truth
            for s in step.samples:
                if isinstance(s, AirspeedSample):
                    v = true_airspeed_mps(s.diff_pressure_pa, tr.static_pressure_pa,
                                          tr.temperature_k)
                    err.append(v - tr.airspeed_mps)
                    alpha.append(tr.alpha_rad)
                    beta.append(tr.beta_rad)
                    if cfg is not None:
                        loss.append(1.0 - probe_misalignment_factor(
                            tr.alpha_rad, tr.beta_rad, cfg.k_alpha_per_rad2, cfg.k_beta_per_rad2,
                            math.radians(cfg.probe_incidence_deg)))
        ended = None if chain.ended is None else str(chain.ended)
        scale = None if chain.suite.pitot is None else chain.suite.pitot.scale
    cpu_s = time.process_time() - t0
    out: dict[str, Any] = {"preset": preset, "seed": seed, "cpu_s": cpu_s, "ended": ended,
                           "samples": len(err)}
    if err:
        e = np.asarray(err)
        out |= {
            "tas_error_mean_mps": float(e.mean()),
            "tas_error_rms_mps": float(np.sqrt(np.mean(e * e))),
            "tas_error_max_abs_mps": float(np.max(np.abs(e))),
            "seed_scale_factor": scale,
            "alpha_deg_range": [float(np.degrees(min(alpha))), float(np.degrees(max(alpha)))],
            "beta_deg_range": [float(np.degrees(min(beta))), float(np.degrees(max(beta)))],
            "misalignment_loss_max": float(max(loss)) if loss else 0.0,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--plan", default="racetrack")
    ap.add_argument("--presets", default="ms4525do,sdp33,none")
    ap.add_argument("--wind", default="0,0,0")
    ap.add_argument("--turbulence", type=float, default=0.0)
    ap.add_argument("--out", type=Path, default=Path("bench/results/pitot_error.json"))
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    runs = [fly(p, s, args.duration, args.plan, args.wind, args.turbulence)
            for p in args.presets.split(",") for s in seeds]
    result = {
        "bench": "pitot_error",
        "command": "python bench/pitot_error.py " + " ".join(
            f"--{k} {v}" for k, v in vars(args).items()),
        "plan": args.plan, "duration_s": args.duration, "wind_ned_mps": args.wind,
        "turbulence": args.turbulence, "machine": platform.platform(), "runs": runs,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    for r in runs:
        print({k: v for k, v in r.items() if k != "ended"})


if __name__ == "__main__":
    main()
