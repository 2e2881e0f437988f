"""Running a campaign: one lockstep run per task on a Dask worker; resumable, failures kept."""

from __future__ import annotations

import json
import os
import tempfile
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from scenarios.campaign.aggregate import aggregate
from scenarios.campaign.plan import one_line, plan_runs
from scenarios.campaign.report import write_reports
from scenarios.schema import Scenario

# -- one run (executes on a Dask worker) -----------------------------------------------------


@dataclass(frozen=True)
class RunTask:
    """What a worker needs: a picklable, self-contained description of one run."""

    id: str
    scenario: Scenario
    tlog: bool = False
    reports: bool = False


@dataclass(frozen=True)
class RunOutcome:
    """What a worker sends back: the run folder's files, or the error."""

    id: str
    files: dict[str, bytes]
    error: str | None = None
    traceback: str | None = None
    worker_wall_s: float = 0.0
    worker_cpu_s: float = 0.0


def execute_run(task: RunTask) -> RunOutcome:
    """Fly one run in a private temporary folder and return its files (a pure function).

    Exceptions are caught and returned in the outcome, so a run that raises is reported with
    its traceback rather than retried on another worker (it would raise there too).
    """
    from scenarios.runner import run_scenario

    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix=f"hilnav-run-{task.id}-") as tmp:
        out = Path(tmp)
        try:
            run_scenario(task.scenario, out, tlog=task.tlog, reports=task.reports)
        except Exception as exc:
            return RunOutcome(task.id, {}, f"{type(exc).__name__}: {one_line(exc)}",
                              traceback.format_exc(), time.perf_counter() - t0,
                              time.process_time() - c0)
        files = {str(p.relative_to(out)): p.read_bytes()
                 for p in sorted(out.rglob("*")) if p.is_file()}
    return RunOutcome(task.id, files, worker_wall_s=time.perf_counter() - t0,
                      worker_cpu_s=time.process_time() - c0)


def warm_up() -> float:
    """Import what a run needs (JSBSim, scipy, the filter: ~3 s in a fresh process); returns
    the seconds it took (0 on a worker that already has them).

    Called once on every worker before the runs are submitted, so that this one-off cost is
    counted with the cluster's start-up, not in the first run of each worker (where it would
    make the runs-per-minute figure depend on how many runs a worker gets).
    """
    t0 = time.perf_counter()
    import scenarios.runner  # noqa: F401

    return time.perf_counter() - t0


def _write_outcome(run_dir: Path, outcome: RunOutcome) -> None:
    """Store a run's files; ``summary.json`` last and atomically, so it marks a finished run."""
    run_dir.mkdir(parents=True, exist_ok=True)
    error = run_dir / "error.txt"
    if outcome.error is not None:
        error.write_text(f"{outcome.error}\n\n{outcome.traceback or ''}")
        return
    for name, data in outcome.files.items():
        if name == "summary.json":
            continue
        dest = run_dir / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(data)
    if "summary.json" not in outcome.files:
        error.write_text("RuntimeError: the run wrote no summary.json\n")
        return
    tmp = run_dir / "summary.json.part"
    tmp.write_bytes(outcome.files["summary.json"])
    os.replace(tmp, run_dir / "summary.json")
    error.unlink(missing_ok=True)


# -- execution ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class ExecutionStats:
    """How the pending runs were executed (wall-clock figures: machine-dependent)."""

    workers: int = 0
    errors: dict[str, str] = field(default_factory=dict)
    run_s: float = 0.0  # first submission to last result
    worker_cpu_s: float = 0.0  # CPU seconds the workers spent in the runs
    warm_up_s: float = 0.0  # importing the run's modules on every worker, before the runs


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did and found (``report`` is ``campaign.json``)."""

    report: dict[str, Any]
    out_dir: Path
    executed: int
    resumed: int
    errored: int
    files: list[Path]

    @property
    def all_passed(self) -> bool:
        return not self.report["failed"] and not self.report["not_passed"]


ProgressFn = Callable[[int, int, str], None]


def _default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
               else (os.cpu_count() or 1))


def _execute(
    tasks: list[RunTask],
    out_dir: Path,
    *,
    scheduler: str | None,
    workers: int | None,
    progress: ProgressFn | None,
) -> ExecutionStats:
    """Run ``tasks`` on Dask; write each outcome as it arrives."""
    import logging

    from dask.distributed import Client, LocalCluster, as_completed

    errors: dict[str, str] = {}
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler}: "
                             f"{one_line(exc)}") from None
        cluster = None
    else:
        n = workers or _default_workers()
        # one single-threaded process per core: JSBSim and the filter hold the GIL
        cluster = LocalCluster(n_workers=min(n, max(1, len(tasks))), threads_per_worker=1,
                               processes=True, dashboard_address=None,
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        n_workers = len(client.scheduler_info(n_workers=-1).get("workers", {}))
        t_warm = time.perf_counter()
        try:  # every worker in parallel; a worker that joins later imports lazily
            client.run(warm_up)
        except Exception as exc:  # e.g. hilnav not installed on a remote worker
            raise ValueError(f"the Dask workers cannot import hilnav ({one_line(exc)}); "
                             "install the same hilnav on every worker") from None
        warm_up_s = time.perf_counter() - t_warm
        t0 = time.perf_counter()
        futures = [client.submit(execute_run, t, key=f"hilnav-run-{t.id}", pure=False)
                   for t in tasks]
        by_key = {f.key: t.id for f, t in zip(futures, tasks, strict=True)}
        if progress is not None:
            progress(0, len(tasks), "")
        done = 0
        cpu = 0.0
        for fut in as_completed(futures):
            rid = by_key[fut.key]
            if fut.status == "error":  # the worker died or could not unpickle the task
                lost = fut.exception()
                outcome = RunOutcome(rid, {}, f"{type(lost).__name__}: {one_line(lost)}",
                                     "".join(traceback.format_exception(lost)))
            else:
                outcome = fut.result()
            fut.release()
            _write_outcome(out_dir / "runs" / rid, outcome)
            cpu += outcome.worker_cpu_s
            if outcome.error is not None:
                errors[rid] = outcome.error
            done += 1
            if progress is not None:
                progress(done, len(tasks), rid)
        run_s = time.perf_counter() - t0
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return ExecutionStats(n_workers, errors, run_s, cpu, warm_up_s)


def run_campaign(
    scenarios: Sequence[Path],
    seeds: Sequence[int],
    vary: Mapping[str, Sequence[str]],
    out_dir: Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    keep_tlogs: bool = False,
    reports: bool = False,
    progress: ProgressFn | None = None,
) -> CampaignResult:
    """Plan, run (skipping finished runs), aggregate and report a campaign.

    Parameters
    ----------
    scenarios : scenario YAML files.
    seeds : seeds, each flown for every scenario and grid point.
    vary : grid, as returned by :func:`parse_vary`.
    out_dir : campaign folder (created; an existing one is resumed).
    scheduler : address of an existing Dask scheduler; None = a local cluster.
    workers : local cluster size (default: the usable cores); not with ``scheduler``.
    keep_tlogs : keep each run's MAVLink log ``run.tlog``.
    reports : write each run's plots, JUnit XML and HTML report.
    progress : ``progress(done, total, run_id)``: once with ``done`` 0 when the runs are
        submitted, then after each executed run.

    Raises
    ------
    ValueError
        Bad input (see :func:`plan_runs`), ``workers`` < 1 or given with ``scheduler``.
    """
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    if workers is not None and scheduler is not None:
        raise ValueError("--workers sizes the local cluster; it cannot be used with --scheduler")
    specs = plan_runs(scenarios, seeds, vary)
    out_dir = Path(out_dir)
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    pending: list[RunTask] = []
    for spec in specs:
        run_dir = out_dir / "runs" / spec.id
        run_dir.mkdir(exist_ok=True)
        (run_dir / "run.json").write_text(json.dumps(spec.describe(), indent=2) + "\n")
        if not (run_dir / "summary.json").is_file():
            pending.append(RunTask(spec.id, spec.scenario, tlog=keep_tlogs, reports=reports))
    resumed = len(specs) - len(pending)
    t0 = time.perf_counter()
    ex = ExecutionStats()
    if pending:
        ex = _execute(pending, out_dir, scheduler=scheduler, workers=workers, progress=progress)
    wall = time.perf_counter() - t0
    report = aggregate(specs, out_dir)
    report["vary"] = {k: list(v) for k, v in vary.items()}
    report["seeds"] = sorted({s.seed for s in specs})
    report["execution"] = {
        "scheduler": scheduler or "local",
        "workers": ex.workers,
        "executed": len(pending),
        "resumed": resumed,
        "errored": len(ex.errors),
        "wall_s": wall,  # including starting and stopping the cluster
        "warm_up_s": ex.warm_up_s,  # imports on every worker, before the first submission
        "run_s": ex.run_s,  # first submission to last result
        "runs_per_minute": 60.0 * len(pending) / ex.run_s if ex.run_s > 0 else None,
        "worker_cpu_s": ex.worker_cpu_s,
    }
    files = write_reports(report, out_dir)
    return CampaignResult(report, out_dir, len(pending), resumed, len(ex.errors), files)
