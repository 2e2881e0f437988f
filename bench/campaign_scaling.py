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

Why a loaded machine cannot show the speed-up, and what else is recorded: Linux's
``sched_autogroup`` (on by default on desktop and many server kernels) shares the CPU fairly
between *sessions* first and between the processes of a session second. The bench and its
worker processes are one session, so with other busy sessions on the machine they get about
one session's share whatever the number of workers. ``calibration`` measures this at the same
moment: the same CPU-bound pure-Python loop (no hilnav, no Dask) in 1 and in 2 processes of
this session; its speed-up is the most any 2-process job of this session could get right then.
``scaling_efficiency`` = campaign speed-up / calibration speed-up separates our overhead
(Dask, start-up, data shipped back) from the machine's. Before the runs are submitted every
worker imports the run's modules (``execution.warm_up_s``, ~3 s, counted with the cluster's
start-up, as in a long campaign it is paid once per worker).

``--cluster dask-cli`` runs the same campaigns on a cluster of real ``dask scheduler`` /
``dask worker`` processes on 127.0.0.1 (the recipe of docs/scenarios.md, "On a Dask cluster",
reached through ``--scheduler``) instead of a ``LocalCluster``.

One command, on an idle machine (no other session busy; ``uptime`` near 0), from the
repository root (~8 min on 2 cores)::

    python bench/campaign_scaling.py

writes ``bench/results/campaign_scaling.json``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # tests.helpers (the loopback CLI cluster)
    sys.path.insert(0, str(ROOT))

from scenarios.campaign import run_campaign  # noqa: E402

_CALIBRATION_LOOPS = 60_000_000

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


def _burn(_: int) -> float:
    """A CPU-bound pure-Python loop; returns its CPU seconds."""
    c0 = time.process_time()
    x = 0
    for i in range(_CALIBRATION_LOOPS):
        x += i
    return time.process_time() - c0


def calibrate() -> dict[str, Any]:
    """The same loop once in 1 process, then twice in 2 processes at once (this session)."""
    out: dict[str, Any] = {"load_average_1m_before": os.getloadavg()[0]}
    ctx = multiprocessing.get_context("spawn")
    for n in (1, 2):
        with ctx.Pool(n) as pool:
            pool.map(_burn, range(n), chunksize=1)  # start-up and imports out of the timing
            t0 = time.perf_counter()
            cpu = pool.map(_burn, range(n), chunksize=1)
            wall = time.perf_counter() - t0
        out[f"{n}_process{'es' if n > 1 else ''}"] = {"wall_s": wall, "cpu_s": sum(cpu),
                                                       "loops_per_s": n / wall}
    out["speedup_2_over_1"] = (out["2_processes"]["loops_per_s"]
                               / out["1_process"]["loops_per_s"])
    out["load_average_1m_after"] = os.getloadavg()[0]
    return out


@contextlib.contextmanager
def cluster(kind: str, workers: int, root: Path) -> Iterator[dict[str, Any]]:
    """``run_campaign`` keyword arguments for a local cluster or a loopback CLI cluster."""
    if kind == "local":
        yield {"workers": workers}
        return
    from tests.helpers.dask_cluster import dask_cli_cluster

    with dask_cli_cluster(workers, Path(tempfile.mkdtemp(prefix="dask-", dir=root))) as address:
        yield {"scheduler": address}


def measure(scenario: Path, seeds: list[int], workers: int, root: Path,
            kind: str = "local") -> dict[str, Any]:
    """One fresh campaign on a cluster of ``workers`` processes."""
    out = Path(tempfile.mkdtemp(prefix=f"w{workers}-", dir=root))
    load_before = os.getloadavg()[0]
    with cluster(kind, workers, root) as where:
        t0 = time.perf_counter()
        result = run_campaign([scenario], seeds, {}, out, **where)
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
        "warm_up_s": ex["warm_up_s"],
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


def _autogroup() -> bool | None:
    path = Path("/proc/sys/kernel/sched_autogroup_enabled")
    return path.read_text().strip() == "1" if path.is_file() else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=6, help="runs per campaign (seeds 1..N)")
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=3, help="measurements per worker count")
    ap.add_argument("--cluster", choices=("local", "dask-cli"), default="local",
                    help="a LocalCluster, or dask scheduler/worker processes on 127.0.0.1")
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
        calibrations: list[dict[str, Any]] = []
        for _ in range(args.repeats):
            calibrations.append(calibrate())
            print(f"calibration: 2 processes {calibrations[-1]['speedup_2_over_1']:.2f}x "
                  f"1 process (load {calibrations[-1]['load_average_1m_before']:.1f})",
                  flush=True)
            for workers in (1, 2):
                row = measure(scenario, seeds, workers, root, args.cluster)
                print(f"{workers} worker(s): {row['runs_per_minute']:.2f} runs/min "
                      f"(load {row['load_average_1m_before']:.1f})", flush=True)
                rows.append(row)
    groups = [r.pop("_groups") for r in rows]
    rate = {w: statistics.median(r["runs_per_minute"] for r in rows if r["workers"] == w)
            for w in (1, 2)}
    speedups = [b["runs_per_minute"] / a["runs_per_minute"]
                for a, b in zip(rows[::2], rows[1::2], strict=True)]
    ceilings = [c["speedup_2_over_1"] for c in calibrations]
    result = {
        "benchmark": "campaign_scaling",
        "command": " ".join(["python", "bench/campaign_scaling.py", *sys.argv[1:]]),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "cluster": args.cluster,
        "nice": os.nice(0),
        "sched_autogroup_enabled": _autogroup(),
        "scenario": {"plan": "racetrack", "aircraft": "c172x", "sim_rate_hz": 200,
                     "duration_s": args.duration, "outage_s": 30, "bridge": "none"},
        "runs_per_campaign": args.runs,
        "timer": "wall clock, first submission to last result",
        "measurements": rows,
        "runs_per_minute": {"1_worker": rate[1], "2_workers": rate[2]},
        "speedup_2_over_1": rate[2] / rate[1],
        # each 1-worker measurement against the 2-worker one right after it (same load, roughly)
        "speedup_2_over_1_per_repeat": speedups,
        # the machine's own 2-over-1 ceiling for this session, measured just before each repeat
        "calibration": calibrations,
        "calibration_speedup_2_over_1_per_repeat": ceilings,
        # 1.0 = the campaign scales as well as a pure CPU loop could at that moment
        "scaling_efficiency_per_repeat": [s / c for s, c in zip(speedups, ceilings,
                                                                 strict=True)],
        "target_speedup_2_over_1": 1.8,
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
