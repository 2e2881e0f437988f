"""Benchmark: campaign throughput (runs per minute) with 1 and 2 local Dask workers.

The same set of runs (one 120 s racetrack scenario at 200 Hz with a 30 s GNSS outage, seeds
1..N) is flown as a fresh campaign on a local cluster of 1 worker process and then of 2, each
into its own empty folder. Runs per minute are counted from the first submission to the last
result (``execution.run_s``: cluster start-up is reported apart, it is paid once per campaign);
the speed-up is the ratio of the two rates. ``cpu_share_per_worker`` (CPU seconds the workers
spent in runs / (workers x wall seconds)) shows how much of a core each worker really got.
The two campaigns' aggregates are also compared: they must be identical, whatever the number
of workers.

Wall-clock numbers: they depend on what else the machine runs, so the 1-minute load average
is recorded before and after each measurement. ``--repeats`` alternates 1, 2, 1, 2... and
keeps every measurement.

    python bench/campaign_scaling.py --runs 6 --out bench/results/campaign_scaling.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from scenarios.campaign import run_campaign

SCENARIO = """\
name: campaign-bench
description: 120 s racetrack, 30 s GNSS outage (campaign scaling benchmark).
aircraft: c172x
plan: racetrack
duration_s: {duration}
sim_rate_hz: 200
sensors:
  imu: {{preset: industrial-mems}}
  gnss: {{preset: modern}}
fusion: {{bridge: none, altitude: ekf}}
events:
  - {{type: gnss_outage, at: {outage_at}, duration: 30}}
"""


def measure(scenario: Path, seeds: list[int], workers: int, root: Path) -> dict[str, Any]:
    """One fresh campaign on a local cluster of ``workers`` processes."""
    out = Path(tempfile.mkdtemp(prefix=f"w{workers}-", dir=root))
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    result = run_campaign([scenario], seeds, {}, out, workers=workers)
    total = time.perf_counter() - t0
    ex = result.report["execution"]
    per_run_wall = [json.loads((out / "runs" / r["id"] / "summary.json").read_text())["wall_s"]
                    for r in result.report["runs"] if r["status"] != "error"]
    return {
        "workers": ex["workers"],
        "runs": len(seeds),
        "errors": len(result.report["failed"]),
        "run_s": ex["run_s"],
        "runs_per_minute": ex["runs_per_minute"],
        "campaign_wall_s": total,
        "startup_and_reports_s": total - ex["run_s"],
        "mean_wall_s_per_run": statistics.fmean(per_run_wall) if per_run_wall else None,
        "worker_cpu_s": ex["worker_cpu_s"],
        "cpu_s_per_run": ex["worker_cpu_s"] / len(seeds),
        # CPU seconds the workers got per second of wall time each: 1.0 = nothing else ran
        "cpu_share_per_worker": ex["worker_cpu_s"] / (ex["workers"] * ex["run_s"]),
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "_groups": result.report["groups"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=6, help="runs per campaign (seeds 1..N)")
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=1, help="measurements per worker count")
    ap.add_argument("--out", type=Path, default=Path("bench/results/campaign_scaling.json"))
    args = ap.parse_args()
    if args.runs < 2 or args.repeats < 1:
        ap.error("--runs must be >= 2 and --repeats >= 1")
    seeds = list(range(1, args.runs + 1))
    with tempfile.TemporaryDirectory(prefix="hilnav-campaign-bench-") as tmp:
        root = Path(tmp)
        scenario = root / "campaign-bench.yaml"
        scenario.write_text(SCENARIO.format(duration=args.duration,
                                            outage_at=max(10.0, args.duration - 40.0)))
        rows: list[dict[str, Any]] = []
        for _ in range(args.repeats):
            for workers in (1, 2):
                row = measure(scenario, seeds, workers, root)
                print(f"{workers} worker(s): {row['runs_per_minute']:.2f} runs/min "
                      f"(load {row['load_average_1m_before']:.1f})", flush=True)
                rows.append(row)
    groups = [r.pop("_groups") for r in rows]
    rate = {w: statistics.median(r["runs_per_minute"] for r in rows if r["workers"] == w)
            for w in (1, 2)}
    result = {
        "benchmark": "campaign_scaling",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "scenario": {"plan": "racetrack", "aircraft": "c172x", "sim_rate_hz": 200,
                     "duration_s": args.duration, "outage_s": 30, "bridge": "none"},
        "runs_per_campaign": args.runs,
        "timer": "wall clock, first submission to last result",
        "measurements": rows,
        "runs_per_minute": {"1_worker": rate[1], "2_workers": rate[2]},
        "speedup_2_over_1": rate[2] / rate[1],
        # each 1-worker measurement against the 2-worker one right after it (same load, roughly)
        "speedup_2_over_1_per_repeat": [
            b["runs_per_minute"] / a["runs_per_minute"] for a, b in zip(rows[::2], rows[1::2],
                                                                         strict=True)],
        # CPU cost of a run with 1 and 2 workers: equal means the parallel overhead is nil and
        # the wall-clock speed-up is limited only by the CPU the machine can give
        "cpu_s_per_run": {f"{w}_worker{'s' if w > 1 else ''}": statistics.median(
            r["cpu_s_per_run"] for r in rows if r["workers"] == w) for w in (1, 2)},
        "same_aggregate_for_every_worker_count": all(g == groups[0] for g in groups),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "measurements"}, indent=2))


if __name__ == "__main__":
    main()
