"""Benchmark: JSBSim alone vs the full simulator chain (JSBSim + sensor models + MAVLink encode).

Both are timed in the same process at the same rate on the same flight plan. Writes JSON.
Target (issue 2): full chain >= 100x real time at 200 Hz, within 3x of JSBSim alone.
"JSBSim alone" is the flight adapter (JSBSim + guidance law + SI truth); the bare ``run()`` of
JSBSim with frozen controls is reported too. Times are CPU seconds of this process.

    python bench/sim_throughput.py --duration 300 --out bench/results/sim_throughput.json
    python bench/sim_throughput.py --duration 300 --wind 8,-4,0 --wind-shear 0.142857 \
        --out bench/results/sim_throughput_wind_shear.json

``--wind`` / ``--wind-shear`` fly in a steady wind / a power-law wind profile (the profile is
written to JSBSim at every step: its cost shows as the difference to a run without it).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from hil.pipeline import SimChain, SimSetup
from sim import presets
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan


def time_jsbsim_bare(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """JSBSim's own ``run()`` with the controls frozen at trim (no guidance, no truth)."""
    with Flight(cfg, load_plan(plan_name)) as flight:
        fdm = flight._fdm  # the bench measures the library underneath the adapter
        n = round(duration_s * cfg.rate_hz)
        t0 = time.process_time()
        for _ in range(n):
            fdm.run()
        return time.process_time() - t0


def time_jsbsim(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """The flight adapter: JSBSim + guidance law + SI truth."""
    plan = load_plan(plan_name)
    with Flight(cfg, plan) as flight:
        n = round(duration_s * cfg.rate_hz)
        t0 = time.process_time()
        for _ in range(n):
            flight.step()
        return time.process_time() - t0


def time_chain(cfg: FlightConfig, plan_name: str, duration_s: float) -> tuple[float, int]:
    """The simulator half of the pipeline (:class:`hil.pipeline.SimChain`): JSBSim + guidance
    + sensor models + MAVLink encode."""
    setup = SimSetup(flight=cfg, plan=load_plan(plan_name), sensors=presets.suite_config(),
                     duration_s=duration_s, seed=1)
    frames = 0
    with SimChain(setup) as chain:
        t0 = time.process_time()
        for step in chain.steps():
            frames += len(step.frames)
        return time.process_time() - t0, frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--plan", default="racetrack")
    ap.add_argument("--wind", default="0,0,0", help="steady wind N,E,D, m/s")
    ap.add_argument("--wind-shear", type=float, default=0.0, help="power-law shear exponent")
    ap.add_argument("--out", type=Path, default=Path("bench/results/sim_throughput.json"))
    args = ap.parse_args()
    wn, we, wd = (float(v) for v in args.wind.split(","))
    cfg = FlightConfig(rate_hz=args.rate, wind_ned_mps=(wn, we, wd),
                       wind_shear_exponent=args.wind_shear)
    wall_bare = time_jsbsim_bare(cfg, args.plan, args.duration)
    wall_jsb = time_jsbsim(cfg, args.plan, args.duration)
    wall_chain, frames = time_chain(cfg, args.plan, args.duration)
    steps = round(args.duration * args.rate)
    result = {
        "benchmark": "sim_throughput",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "rate_hz": args.rate,
        "plan": args.plan,
        "wind_ned_mps": [wn, we, wd],
        "wind_shear_exponent": args.wind_shear,
        "sim_duration_s": args.duration,
        "timer": "process_time (CPU seconds of this process)",
        "load_average_1m": os.getloadavg()[0],
        "jsbsim_bare_run": {
            "cpu_s": wall_bare,
            "us_per_step": wall_bare / steps * 1e6,
            "realtime_factor": args.duration / wall_bare,
        },
        "jsbsim_only": {
            "wall_s": wall_jsb,
            "us_per_step": wall_jsb / steps * 1e6,
            "realtime_factor": args.duration / wall_jsb,
        },
        "full_chain": {
            "wall_s": wall_chain,
            "us_per_step": wall_chain / steps * 1e6,
            "realtime_factor": args.duration / wall_chain,
            "frames": frames,
        },
        "chain_over_jsbsim_time_ratio": wall_chain / wall_jsb,
        "targets": {"full_chain_realtime_factor_min": 100.0, "time_ratio_max": 3.0},
    }
    result["meets_targets"] = (
        result["full_chain"]["realtime_factor"] >= 100.0
        and result["chain_over_jsbsim_time_ratio"] <= 3.0
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
