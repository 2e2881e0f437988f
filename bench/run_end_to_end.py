"""Benchmark: ``hilnav run`` end to end against bare JSBSim on the same flight and rate, and
the run's peak memory.

In one invocation it times

- ``jsbsim_bare``: JSBSim's own ``run()`` with the controls frozen at trim, for the scenario's
  aircraft, start, rate and duration (CPU seconds of this process);
- ``hilnav_run``: ``hilnav run SCENARIO --quiet`` as a child process on a copy of the scenario
  whose ``duration_s`` (and GNSS outages) are set by ``--duration``: the whole process
  (start-up, simulation, encode, decode, filter, scoring, plots, report) as the child's CPU
  seconds (``getrusage(RUSAGE_CHILDREN)``), its wall time, and its peak resident set size
  (``ru_maxrss``), plus the ``wall_s`` the run reports for itself in ``summary.json``.

The ratio ``hilnav_run cpu / jsbsim_bare cpu`` is the issue-15 figure (target <= 3); the peak
RSS of a 3600 s run is the memory figure (target < 500 MB). The load average is recorded
before and after.

    python bench/run_end_to_end.py --duration 300 --out bench/results/run_end_to_end.json
    python bench/run_end_to_end.py --duration 3600 --skip-bare \\
        --out bench/results/run_end_to_end_1h.json

The scenario (default ``turning-60s-outages``, 200 Hz) keeps its seed, sensors and plan; its
outage events are replaced by one 60 s outage every 120 s from 120 s on, so a long run has
outages throughout.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from scenarios.schema import load_scenario
from sim.flight import Flight

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "scenarios" / "library"


def scenario_copy(source: Path, duration_s: float, folder: Path) -> Path:
    """The scenario YAML with ``duration_s`` and one 60 s GNSS outage every 120 s."""
    doc: dict[str, Any] = yaml.safe_load(source.read_text(encoding="utf-8"))
    doc["duration_s"] = duration_s
    starts = range(120, int(duration_s) - 60, 120)
    doc["events"] = [{"type": "gnss_outage", "at": s, "duration": 60} for s in starts]
    path = folder / f"{doc['name']}-{int(duration_s)}s.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def time_jsbsim_bare(scenario_path: Path) -> tuple[float, int]:
    """CPU seconds of JSBSim's ``run()`` alone (controls frozen at trim) over the scenario's
    duration at its rate, and the number of steps."""
    scn = load_scenario(scenario_path)
    cfg = scn.flight_config()
    n = round(scn.duration_s * cfg.rate_hz)
    with Flight(cfg, scn.flight_plan()) as flight:
        fdm = flight._fdm  # the bench measures the library underneath the adapter
        t0 = time.process_time()
        for _ in range(n):
            fdm.run()
        return time.process_time() - t0, n


def time_hilnav_run(scenario_path: Path, out: Path) -> dict[str, Any]:
    """Run ``hilnav run --quiet`` as a child; its CPU, wall time, peak RSS and summary."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = [sys.executable, "-m", "scenarios.cli", "run", str(scenario_path), "--out", str(out),
           "--quiet"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):  # 1: criteria failed, still a complete run
        sys.exit(f"hilnav run failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {
        "command": "python -m scenarios.cli run SCENARIO --out DIR --quiet",
        "exit_code": proc.returncode,
        "cpu_s": cpu,
        "wall_s": wall,
        "peak_rss_mb": after.ru_maxrss / 1024.0,  # Linux: kilobytes
        "summary_wall_s": summary["wall_s"],
        "summary_realtime_factor": summary["realtime_factor"],
        "sim_duration_s": summary["sim_duration_s"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds")
    ap.add_argument("--skip-bare", action="store_true", help="only the hilnav run (memory)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/run_end_to_end.json")
    args = ap.parse_args()
    if args.duration < 60:
        sys.exit("--duration must be >= 60 s")
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hilnav-bench-") as tmp:
        folder = Path(tmp)
        scn_path = scenario_copy(LIBRARY / f"{args.scenario}.yaml", args.duration, folder)
        rate_hz = load_scenario(scn_path).flight_config().rate_hz
        bare_cpu, steps = (None, 0) if args.skip_bare else time_jsbsim_bare(scn_path)
        run = time_hilnav_run(scn_path, folder / "run")
    result: dict[str, Any] = {
        "benchmark": "run_end_to_end",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "scenario": args.scenario,
        "sim_duration_s": args.duration,
        "timer": "CPU seconds (process_time here, getrusage for the child)",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "hilnav_run": run,
        "rate_hz": rate_hz,
        "hilnav_run_us_per_step": run["cpu_s"] / (args.duration * rate_hz) * 1e6,
    }
    if bare_cpu is not None:
        result["jsbsim_bare"] = {"cpu_s": bare_cpu, "steps": steps,
                                 "us_per_step": bare_cpu / steps * 1e6,
                                 "realtime_factor": args.duration / bare_cpu}
        result["run_over_bare_cpu_ratio"] = run["cpu_s"] / bare_cpu
        result["run_inside_over_bare_ratio"] = run["summary_wall_s"] / bare_cpu
    result["targets"] = {"run_over_bare_cpu_ratio_max": 3.0, "peak_rss_mb_max_1h": 500.0}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
