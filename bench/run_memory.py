"""Benchmark: where the memory of a long ``hilnav run`` goes, phase by phase.

Runs ``hilnav run SCENARIO --out DIR --quiet`` in this process (the CLI's own command, on the
copy of the scenario that ``bench/run_end_to_end.py`` uses: ``--duration`` simulated seconds,
one 60 s GNSS outage every 120 s) with the scoring steps wrapped by a probe that reads the
kernel's resident set size of the process (``/proc/self/status``: ``VmRSS`` now, ``VmHWM`` the
peak) when each step starts and ends, and resets the peak (``/proc/self/clear_refs``) at every
boundary, so each step's own peak is known. Steps (nested ones are counted in their caller's
peak as well):

- ``flight``: from the start to the scoring (JSBSim, sensors, encode, decode, filter,
  collector), read when ``scenarios.runner.score`` is entered;
- ``score``: all of the scoring and the report files (``scenarios.runner.score``);
- ``columns``: the collector's tracks (``Collector.end_s`` / ``estimate_track`` /
  ``truth_track`` / ``series``);
- ``errors``: ``scenarios.metrics.errors``; ``consistency``: ``scenarios.metrics.consistency``;
- ``summary``: ``scenarios.summary.build_summary`` (errors, outages, consistency, events);
- ``plots``: ``scenarios.report.write_plots``; ``report``: ``scenarios.html.write_html``.

The code measured is whatever is checked out: run it at two commits for a before / after.

    python bench/run_memory.py --duration 3600 --out bench/results/run_memory.json
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import resource
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import run_end_to_end

ROOT = Path(__file__).resolve().parent.parent
MB = 1024.0 * 1024.0


def _status_kb() -> dict[str, int]:
    out = {}
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith(("VmRSS:", "VmHWM:")):
                key, value = line.split(":", 1)
                out[key] = int(value.split()[0])
    return out


def _reset_peak() -> bool:
    """Reset VmHWM to the current RSS (Linux >= 4.0); False when the kernel refuses."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
        return True
    except OSError:
        return False


@dataclass
class _Frame:
    name: str
    rss_before_kb: int
    peak_kb: int


@dataclass
class Probe:
    """RSS at the boundaries of the wrapped steps and each step's peak."""

    peak_resettable: bool = True
    rows: dict[str, dict[str, Any]] = field(default_factory=dict)
    _open: list[_Frame] = field(default_factory=list)
    t0: float = field(default_factory=time.perf_counter)

    def _boundary(self) -> dict[str, int]:
        s = _status_kb()
        for f in self._open:
            f.peak_kb = max(f.peak_kb, s["VmHWM"])
        if self.peak_resettable:
            self.peak_resettable = _reset_peak()
        return s

    def enter(self, name: str) -> None:
        s = self._boundary()
        self._open.append(_Frame(name, s["VmRSS"], s["VmRSS"]))

    def leave(self) -> None:
        s = self._boundary()
        f = self._open.pop()
        row = self.rows.setdefault(f.name, {"calls": 0, "rss_before_mb": f.rss_before_kb / 1024,
                                            "peak_mb": 0.0, "peak_over_before_mb": 0.0})
        row["calls"] += 1
        row["rss_after_mb"] = s["VmRSS"] / 1024
        row["peak_mb"] = max(row["peak_mb"], f.peak_kb / 1024)
        row["peak_over_before_mb"] = max(row["peak_over_before_mb"],
                                         (f.peak_kb - f.rss_before_kb) / 1024)
        row["seconds_from_start"] = time.perf_counter() - self.t0

    def mark(self, name: str, **extra: Any) -> None:
        """A point reading: the RSS now and the peak since the last boundary."""
        s = _status_kb()
        self.rows[name] = {"rss_mb": s["VmRSS"] / 1024, "peak_mb": s["VmHWM"] / 1024,
                           "seconds_from_start": time.perf_counter() - self.t0, **extra}
        if self.peak_resettable:
            self.peak_resettable = _reset_peak()

    def wrap(self, owner: Any, attr: str, name: str,
             before: Callable[..., None] | None = None) -> None:
        fn = getattr(owner, attr)

        @functools.wraps(fn)
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            if before is not None:
                before(*args, **kwargs)
            self.enter(name)
            try:
                return fn(*args, **kwargs)
            finally:
                self.leave()

        setattr(owner, attr, wrapped)


def install(probe: Probe) -> None:
    """Wrap the scoring steps (module attributes, looked up when called)."""
    import scenarios.html
    import scenarios.metrics
    import scenarios.report
    import scenarios.runner
    import scenarios.summary
    from hil.tracks import Collector

    def at_flight_end(_scenario: Any, run: Any, *_a: Any, **_k: Any) -> None:
        col = run.collector
        probe.mark("flight", collector_compact_mb=col.compact_nbytes / MB,
                   estimates=col.n_estimates, truths=col.n_truths, fixes=col.n_fixes)

    probe.wrap(scenarios.runner, "score", "score", before=at_flight_end)
    for attr in ("end_s", "estimate_track", "truth_track", "series"):
        probe.wrap(Collector, attr, "columns")
    probe.wrap(scenarios.metrics, "errors", "errors")
    probe.wrap(scenarios.metrics, "consistency", "consistency")
    probe.wrap(scenarios.summary, "build_summary", "summary")
    probe.wrap(scenarios.report, "write_plots", "plots")
    probe.wrap(scenarios.html, "write_html", "report")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/run_memory.json")
    args = ap.parse_args()
    if args.duration < 60:
        sys.exit("--duration must be >= 60 s")
    from scenarios.cli.app import app

    probe = Probe()
    install(probe)
    load_before = os.getloadavg()[0]
    cpu0 = time.process_time()
    with tempfile.TemporaryDirectory(prefix="hilnav-mem-") as tmp:
        folder = Path(tmp)
        scn = run_end_to_end.scenario_copy(run_end_to_end.LIBRARY / f"{args.scenario}.yaml",
                                           args.duration, folder)
        try:
            code = app(["run", str(scn), "--out", str(folder / "run"), "--quiet"],
                       standalone_mode=False)
        except SystemExit as exc:
            code = exc.code
        # 1: the criteria failed, still a complete run
        if code not in (0, 1, None) or not (folder / "run" / "summary.json").is_file():
            sys.exit(f"hilnav run failed ({code})")
        probe.mark("end")
        summary = json.loads((folder / "run" / "summary.json").read_text(encoding="utf-8"))
    result: dict[str, Any] = {
        "benchmark": "run_memory",
        "command": f"python bench/run_memory.py --duration {args.duration:g}",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "scenario": args.scenario,
        "sim_duration_s": summary["sim_duration_s"],
        "cpu_s": time.process_time() - cpu0,
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        # resetting VmHWM resets what ru_maxrss reports too: the peak is the phases' largest
        "peak_rss_mb": max([resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0]
                           + [row["peak_mb"] for row in probe.rows.values()]),
        "peak_per_phase": probe.peak_resettable,
        "phases": probe.rows,
        "target_peak_rss_mb_1h": 500.0,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
