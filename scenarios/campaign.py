"""``hilnav campaign``: Monte Carlo sweeps over seeds and parameter grids, on Dask.

A campaign is the cartesian product *scenario files x grid points x seeds*. A grid point is one
choice per ``--vary`` key (``{"imu": "consumer-mems", "bridge": "gmdh"}``); the keys are
seed-independent scenario fields listed in :data:`VARY_KEYS`. Each run is a lockstep
:func:`~scenarios.runner.run_scenario` call: independent of every other run and deterministic
for its inputs, so the numbers do not depend on which worker (or machine) flew it.

Layout of the output folder::

    DIR/runs/<id>/summary.json     one per finished run (written last, atomically)
    DIR/runs/<id>/error.txt        a run that raised: the traceback (the run is retried on resume)
    DIR/runs/<id>/run.json         what the run was: scenario, seed, grid point
    DIR/campaign.json              aggregate statistics, the run list, failed runs
    DIR/campaign.md                the same as Markdown tables
    DIR/distributions.png          error distributions per grid point

``<id>`` is a hash of the scenario file's bytes, the seed and the grid point, so running the same
campaign again into the same folder skips every run that has a ``summary.json`` (counted as
*resumed*) and only flies the missing or failed ones. The id covers neither the hilnav code
nor a plan file the scenario refers to by path: after changing either, start a new folder.

Execution: a ``dask.distributed`` ``LocalCluster`` with one single-threaded worker process per
core by default, or an existing cluster (``scheduler="tcp://HOST:8786"``) whose workers have the
same hilnav installed. Scenarios are loaded and the grid applied on the client; workers receive
the resulting :class:`~scenarios.schema.Scenario` objects, fly them in a private temporary
folder and send the run's files back, so workers need neither the scenario files nor a shared
file system. A run that raises is recorded (``error.txt`` and ``campaign.json["failed"]``), never
silently dropped.

Aggregation reads the summaries back sorted by run id, so it is the same whatever the order in
which the runs completed. Per scenario x grid point (the bridging and altitude methods are part
of the grid point when varied, and are named in every group), every metric gets ``mean``,
``p95`` (linear interpolation between order statistics), ``worst`` (the maximum: every metric is
an error) and ``n``. Outage metrics are pooled over every outage of every run of the group
(``n`` counts outages); GNSS-on metrics have one value per run. Wall-clock timings are kept out
of the aggregate (they do depend on the machine).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import tempfile
import time
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from scenarios.schema import Scenario, ScenarioError, load_scenario
from scenarios.summary import write_summary

SCHEMA_VERSION = 1

#: Keys accepted by ``--vary``: key -> (where it goes in the scenario file, what it is). The
#: one table that knows the schema's layout; every key is seed-independent. ``bridge`` and
#: ``altitude`` go through :meth:`Scenario.with_overrides`, the others replace the value at
#: their path in the scenario's data, which the schema validates again (so a sensor preset
#: changes under any field overrides the file gives for that sensor, which stay applied).
VARY_KEYS: dict[str, tuple[tuple[str, ...], str]] = {
    "imu": (("sensors", "imu", "preset"), "IMU preset (sim.presets)"),
    "gnss": (("sensors", "gnss", "preset"), "GNSS receiver preset (sim.presets)"),
    "baro": (("sensors", "baro", "preset"), "barometer preset (sim.presets)"),
    "mag": (("sensors", "mag", "preset"), "magnetometer preset (sim.presets)"),
    "bridge": (("fusion", "bridge"), "GNSS-outage bridging method"),
    "altitude": (("fusion", "altitude"), "vertical channel method"),
    "aircraft": (("aircraft",), "JSBSim aircraft (hilnav list)"),
    "plan": (("plan",), "flight plan: packaged name or YAML path relative to the scenario"),
}
_WITH_OVERRIDES = ("bridge", "altitude")

#: Seconds into an outage at which the horizontal error is aggregated (summary.json keys).
ERROR_AT_S = ("10", "30", "60", "120")

#: Aggregated metrics, in report order: name -> what one value is (all in metres).
METRICS: dict[str, str] = {
    "outage_horizontal_rmse_m": "horizontal RMSE over each outage",
    "outage_horizontal_max_m": "largest horizontal error in each outage",
    **{f"outage_horizontal_error_m_at_{s}s": f"horizontal error {s} s into each outage"
       for s in ERROR_AT_S},
    "outage_cep95_m": "95 % circular error of each outage",
    "outage_vertical_rmse_m": "vertical RMSE over each outage",
    "gnss_on_horizontal_rmse_m": "horizontal RMSE with GNSS (per run)",
    "gnss_on_vertical_rmse_m": "vertical RMSE with GNSS (per run)",
}

Point = dict[str, str]


# -- planning ----------------------------------------------------------------------------------


def parse_vary(items: Iterable[str]) -> dict[str, list[str]]:
    """Parse ``--vary`` options: ``["imu=a,b", "bridge=none"]`` -> ``{"imu": ["a", "b"], ...}``.

    Parameters
    ----------
    items : ``KEY=VALUE[,VALUE...]`` strings; keys from :data:`VARY_KEYS`.

    Returns
    -------
    dict
        Key -> values, in the order given (the grid's order).

    Raises
    ------
    ValueError
        Not ``KEY=VALUES``, an unknown key (the message lists the valid ones), a key given
        twice, an empty or repeated value.
    """
    grid: dict[str, list[str]] = {}
    for item in items:
        key, sep, rest = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--vary {item!r} must be KEY=VALUE[,VALUE...], e.g. "
                             "imu=consumer-mems,industrial-mems")
        if key not in VARY_KEYS:
            raise ValueError(f"--vary: unknown key {key!r}; valid keys: {', '.join(VARY_KEYS)}")
        if key in grid:
            raise ValueError(f"--vary: key {key!r} given twice; list its values once, "
                             "comma-separated")
        values = [v.strip() for v in rest.split(",")]
        if not rest.strip() or any(not v for v in values):
            raise ValueError(f"--vary {item!r}: empty value")
        if len(set(values)) != len(values):
            raise ValueError(f"--vary {item!r}: a value is listed twice")
        grid[key] = values
    return grid


def grid_points(vary: Mapping[str, Sequence[str]]) -> list[Point]:
    """The cartesian product of ``vary`` (first key varies slowest); ``[{}]`` when empty."""
    keys = list(vary)
    return [dict(zip(keys, combo, strict=True))
            for combo in itertools.product(*(vary[k] for k in keys))]


def apply_point(scenario: Scenario, point: Mapping[str, str]) -> Scenario:
    """``scenario`` with the grid point's values applied and validated again by the schema.

    Raises
    ------
    ValueError
        An unknown key, or a value the schema rejects (:class:`ScenarioError`, one line).
    """
    unknown = sorted(set(point) - set(VARY_KEYS))
    if unknown:
        raise ValueError(f"unknown grid key(s) {', '.join(unknown)}; "
                         f"valid keys: {', '.join(VARY_KEYS)}")
    nested = {k: v for k, v in point.items() if k not in _WITH_OVERRIDES}
    if nested:
        data = scenario.model_dump(by_alias=True, exclude_unset=True)
        data.setdefault("duration_s", scenario.duration_s)
        data.setdefault("name", scenario.name)
        for key, value in nested.items():
            path = VARY_KEYS[key][0]
            node = data
            for part in path[:-1]:
                node[part] = dict(node.get(part) or {})
                node = node[part]
            node[path[-1]] = value
        try:
            scenario = Scenario.model_validate(data, context={"base_dir": scenario.source_dir})
        except ValidationError as error:
            raise ScenarioError(_one_line(error)) from None
    if "bridge" in point or "altitude" in point:
        scenario = scenario.with_overrides(bridge=point.get("bridge"),
                                           altitude=point.get("altitude"))
    return scenario


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run_id(scenario_sha256: str, seed: int, point: Mapping[str, str]) -> str:
    """Stable id of one run: hash of the scenario file's bytes, the seed and the grid point."""
    key = json.dumps({"scenario_sha256": scenario_sha256, "seed": int(seed),
                      "point": dict(sorted(point.items()))}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RunSpec:
    """One planned run: what it is (for the reports) and the scenario to fly (for the worker)."""

    id: str
    scenario_path: str
    scenario_name: str
    scenario_sha256: str
    seed: int
    point: Point
    scenario: Scenario = field(repr=False, compare=False)
    #: (scenario index, grid point index): the report order of the run's group
    order: tuple[int, int] = (0, 0)

    def describe(self) -> dict[str, Any]:
        return {"id": self.id, "scenario": self.scenario_name, "scenario_path": self.scenario_path,
                "seed": self.seed, "point": dict(self.point)}


def plan_runs(
    scenarios: Sequence[Path], seeds: Sequence[int], vary: Mapping[str, Sequence[str]]
) -> list[RunSpec]:
    """Load every scenario, apply every grid point and seed; sorted by run id.

    Raises
    ------
    ValueError
        No scenario, no seed, a scenario that does not load, a grid value the schema rejects,
        or the same scenario file content given twice.
    FileNotFoundError
        A scenario file that does not exist.
    """
    if not scenarios:
        raise ValueError("no scenario given")
    if not seeds:
        raise ValueError("need at least one seed")
    points = grid_points(vary)
    runs: dict[str, RunSpec] = {}
    seen: dict[str, Path] = {}
    for i_scn, path in enumerate(scenarios):
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"scenario file not found: {path}")
        sha = _sha256_file(path)
        if sha in seen:
            raise ValueError(f"{path} has the same content as {seen[sha]}; give it once")
        seen[sha] = path
        base = load_scenario(path)
        for i_pt, point in enumerate(points):
            try:
                varied = apply_point(base, point)
            except ValueError as exc:
                what = ", ".join(f"{k}={v}" for k, v in point.items())
                raise ValueError(f"{path.name} with {what}: {_one_line(exc)}") from None
            for seed in seeds:
                rid = run_id(sha, seed, point)
                runs[rid] = RunSpec(rid, str(path), base.name, sha, int(seed), dict(point),
                                    varied.with_overrides(seed=int(seed)), (i_scn, i_pt))
    return [runs[k] for k in sorted(runs)]


def _one_line(exc: BaseException) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):  # pydantic ValidationError: name the field
        try:
            first = errors()[0]
            loc = ".".join(str(p) for p in first["loc"])
            msg = str(first["msg"]).removeprefix("Value error, ")
            return f"{loc}: {msg}" if loc else msg
        except (IndexError, KeyError, TypeError):
            pass
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


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
            return RunOutcome(task.id, {}, f"{type(exc).__name__}: {_one_line(exc)}",
                              traceback.format_exc(), time.perf_counter() - t0,
                              time.process_time() - c0)
        files = {str(p.relative_to(out)): p.read_bytes()
                 for p in sorted(out.rglob("*")) if p.is_file()}
    return RunOutcome(task.id, files, worker_wall_s=time.perf_counter() - t0,
                      worker_cpu_s=time.process_time() - c0)


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
                             f"{_one_line(exc)}") from None
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
                outcome = RunOutcome(rid, {}, f"{type(lost).__name__}: {_one_line(lost)}",
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
    return ExecutionStats(n_workers, errors, run_s, cpu)


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
        "run_s": ex.run_s,  # first submission to last result
        "runs_per_minute": 60.0 * len(pending) / ex.run_s if ex.run_s > 0 else None,
        "worker_cpu_s": ex.worker_cpu_s,
    }
    files = write_reports(report, out_dir)
    return CampaignResult(report, out_dir, len(pending), resumed, len(ex.errors), files)


# -- aggregation -------------------------------------------------------------------------------


def _finite(values: Iterable[Any]) -> list[float]:
    out = []
    for v in values:
        if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v):
            out.append(float(v))
    return out


def stats(values: Sequence[float]) -> dict[str, float | int | None]:
    """``{mean, p95, worst, n}`` of ``values`` (None when empty); order-independent."""
    if not values:
        return {"mean": None, "p95": None, "worst": None, "n": 0}
    arr = np.sort(np.asarray(values, dtype=float))  # sorted: sums independent of input order
    return {"mean": math.fsum(arr.tolist()) / arr.size,
            "p95": float(np.percentile(arr, 95.0)),
            "worst": float(arr[-1]),
            "n": int(arr.size)}


def run_metrics(summary: Mapping[str, Any]) -> dict[str, list[float]]:
    """The values one run adds to each of :data:`METRICS` (outage metrics: one per outage)."""
    outages = summary.get("outages") or []
    on = summary.get("gnss_on") or {}
    values: dict[str, list[float]] = {
        "outage_horizontal_rmse_m": _finite(o.get("horizontal_rmse_m") for o in outages),
        "outage_horizontal_max_m": _finite(o.get("horizontal_max_m") for o in outages),
    }
    for s in ERROR_AT_S:
        values[f"outage_horizontal_error_m_at_{s}s"] = _finite(
            (o.get("horizontal_error_m_at") or {}).get(s) for o in outages)
    values["outage_cep95_m"] = _finite(o.get("cep95_m") for o in outages)
    values["outage_vertical_rmse_m"] = _finite(o.get("vertical_rmse_m") for o in outages)
    values["gnss_on_horizontal_rmse_m"] = _finite([on.get("horizontal_rmse_m")])
    values["gnss_on_vertical_rmse_m"] = _finite([on.get("vertical_rmse_m")])
    return values


def _not_passed_reason(summary: Mapping[str, Any]) -> str:
    ended = (summary.get("health") or {}).get("flight_ended")
    if ended:
        return str(ended)
    failed = [c for c in summary.get("criteria") or [] if not c.get("ok")]
    return "; ".join(f"{c.get('name')}: {c.get('value')} > {c.get('limit')}" for c in failed) \
        or "not passed"


def _group_key(spec: RunSpec) -> str:
    return json.dumps([spec.scenario_path, sorted(spec.point.items())])


def aggregate(specs: Sequence[RunSpec], out_dir: Path) -> dict[str, Any]:
    """Read every planned run's result from ``out_dir/runs`` and aggregate (sorted by run id).

    Returns
    -------
    dict
        ``campaign.json`` without the execution block: ``groups`` (per scenario x grid point:
        methods, run counts, pass rate and :func:`stats` of every metric), ``runs`` (id,
        scenario, seed, point, status), ``failed`` (runs that raised, with the message) and
        ``not_passed`` (runs that finished but failed their criteria or crashed).
    """
    ordered = sorted(specs, key=lambda s: s.id)
    groups: dict[str, dict[str, Any]] = {}
    runs, failed, not_passed = [], [], []
    for spec in ordered:
        run_dir = out_dir / "runs" / spec.id
        summary_path = run_dir / "summary.json"
        g = groups.setdefault(_group_key(spec), {
            "order": spec.order, "scenario": spec.scenario_name,
            "scenario_path": spec.scenario_path, "point": dict(spec.point),
            "bridge": [], "altitude": [],
            "runs": 0, "passed": 0, "errored": 0, "values": {m: [] for m in METRICS}})
        g["runs"] += 1
        row = spec.describe()
        if summary_path.is_file():
            summary = json.loads(summary_path.read_text())
            passed = bool(summary.get("passed"))
            row["status"] = "passed" if passed else "not_passed"
            g["passed"] += int(passed)
            for name in ("bridge", "altitude"):
                if summary.get(name) is not None and summary[name] not in g[name]:
                    g[name].append(summary[name])
            for m, vals in run_metrics(summary).items():
                g["values"][m].extend(vals)
            if not passed:
                not_passed.append({**spec.describe(), "reason": _not_passed_reason(summary)})
        else:
            error_path = run_dir / "error.txt"
            message = (error_path.read_text().splitlines() or ["error"])[0] \
                if error_path.is_file() else "no result (run did not finish)"
            row["status"] = "error"
            g["errored"] += 1
            failed.append({**spec.describe(), "error": message})
        runs.append(row)
    group_rows = []
    for g in groups.values():
        values = g.pop("values")
        g["bridge"] = sorted(g["bridge"])
        g["altitude"] = sorted(g["altitude"])
        g["pass_rate"] = g["passed"] / g["runs"] if g["runs"] else None
        g["metrics"] = {m: stats(values[m]) for m in METRICS}
        group_rows.append(g)
    group_rows.sort(key=lambda g: g["order"])
    for g in group_rows:
        del g["order"]
    return {"schema_version": SCHEMA_VERSION, "groups": group_rows, "runs": runs,
            "failed": failed, "not_passed": not_passed}


# -- reports -----------------------------------------------------------------------------------


def _fmt(v: Any, spec: str = ".2f") -> str:
    return "n/a" if v is None else format(v, spec)


def _point_label(point: Mapping[str, str]) -> str:
    return ", ".join(f"{k}={v}" for k, v in point.items()) or "(base)"


def markdown(report: Mapping[str, Any]) -> str:
    """``campaign.md``: one table row per scenario x grid point; failed runs listed."""
    ex = report.get("execution", {})
    lines = [
        "# Campaign",
        "",
        f"{len(report['runs'])} runs: seeds {', '.join(str(s) for s in report.get('seeds', []))}"
        f"; executed {ex.get('executed', 'n/a')}, resumed {ex.get('resumed', 'n/a')}, "
        f"errors {len(report['failed'])}, not passed {len(report['not_passed'])}.",
        "",
        "Outage metrics pooled over every outage of every run of a row: mean / p95 / worst (m).",
        "",
        "| scenario | grid point | bridge | altitude | runs | pass rate | errors "
        "| outage horiz RMSE | horiz @60 s | horiz max | GNSS-on horiz RMSE |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def triple(s: Mapping[str, Any]) -> str:
        return f"{_fmt(s['mean'], '.1f')} / {_fmt(s['p95'], '.1f')} / {_fmt(s['worst'], '.1f')}"

    for g in report["groups"]:
        m = g["metrics"]
        lines.append(
            f"| {g['scenario']} | {_point_label(g['point'])} | {', '.join(g['bridge']) or 'n/a'} "
            f"| {', '.join(g['altitude']) or 'n/a'} | {g['runs']} "
            f"| {_fmt(g['pass_rate'], '.0%')} | {g['errored']} "
            f"| {triple(m['outage_horizontal_rmse_m'])} "
            f"| {triple(m['outage_horizontal_error_m_at_60s'])} "
            f"| {triple(m['outage_horizontal_max_m'])} "
            f"| {triple(m['gnss_on_horizontal_rmse_m'])} |")
    if report["failed"]:
        lines += ["", "## Runs that raised", "", "| run | scenario | seed | grid point | error |",
                  "|---|---|---|---|---|"]
        for f in report["failed"]:
            lines.append(f"| {f['id']} | {f['scenario']} | {f['seed']} "
                         f"| {_point_label(f['point'])} | {f['error'].replace('|', '/')} |")
    if report["not_passed"]:
        lines += ["", "## Runs that failed their criteria", "",
                  "| run | scenario | seed | grid point | why |", "|---|---|---|---|---|"]
        for f in report["not_passed"]:
            lines.append(f"| {f['id']} | {f['scenario']} | {f['seed']} "
                         f"| {_point_label(f['point'])} | {f['reason'].replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def plot_distributions(report: Mapping[str, Any], out_dir: Path, path: Path) -> None:
    """Box plots (with every value drawn) of the outage horizontal RMSE and the error 60 s into
    an outage, one box per grid point and one row per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_scenario: dict[str, list[dict[str, Any]]] = {}
    for g in report["groups"]:
        by_scenario.setdefault(g["scenario_path"], []).append(g)
    # the raw values again, from the summaries (campaign.json only keeps the statistics)
    values: dict[tuple[str, str], dict[str, list[float]]] = {}
    for r in report["runs"]:
        if r["status"] == "error":
            continue
        summary = json.loads((out_dir / "runs" / r["id"] / "summary.json").read_text())
        key = (r["scenario_path"], json.dumps(sorted(r["point"].items())))
        acc = values.setdefault(key, {"outage_horizontal_rmse_m": [],
                                      "outage_horizontal_error_m_at_60s": []})
        m = run_metrics(summary)
        for name in acc:
            acc[name].extend(m[name])
    panels = (("outage_horizontal_rmse_m", "outage horizontal RMSE (m)"),
              ("outage_horizontal_error_m_at_60s", "horizontal error 60 s into outage (m)"))
    rows = max(1, len(by_scenario))
    width = max(8.0, 1.3 * max((len(v) for v in by_scenario.values()), default=1) * 2)
    fig, axes = plt.subplots(rows, 2, figsize=(min(width, 24.0), 3.6 * rows), squeeze=False)
    for row, (spath, groups) in enumerate(sorted(by_scenario.items())):
        for col, (metric, label) in enumerate(panels):
            ax = axes[row][col]
            data, names = [], []
            for g in groups:
                key = (spath, json.dumps(sorted(g["point"].items())))
                data.append(values.get(key, {}).get(metric, []))
                names.append(_point_label(g["point"]).replace(", ", "\n"))
            positions = list(range(1, len(data) + 1))
            ax.boxplot([d if d else [math.nan] for d in data], positions=positions,
                       whis=(5, 95), showfliers=False)
            for x, d in zip(positions, data, strict=True):
                if d:
                    ax.plot(np.full(len(d), x), d, "o", alpha=0.45, markersize=3, color="C1")
            if not any(data):
                ax.text(0.5, 0.5, "no values (no outage lasts that long)", ha="center",
                        va="center", transform=ax.transAxes, fontsize=8, color="0.4")
            ax.set_xticks(positions, names, fontsize=7)
            ax.set_ylabel(label, fontsize=8)
            ax.set_title(f"{groups[0]['scenario']}", fontsize=9)
            ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle("Error distributions per grid point (box: quartiles, whiskers: 5-95 %)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_reports(report: dict[str, Any], out_dir: Path) -> list[Path]:
    """Write ``campaign.json``, ``campaign.md`` and ``distributions.png``; return their paths."""
    json_path = out_dir / "campaign.json"
    write_summary(report, json_path)  # same NaN -> null cleaning as summary.json
    md_path = out_dir / "campaign.md"
    md_path.write_text(markdown(report))
    png_path = out_dir / "distributions.png"
    plot_distributions(report, out_dir, png_path)
    return [json_path, md_path, png_path]


# -- CLI entry (wired into typer by hil/cli.py) ----------------------------------------------


def campaign_main(
    scenarios: list[Path],
    seeds: int,
    seed_base: int,
    vary: list[str],
    out: Path,
    scheduler: str | None,
    workers: int | None,
    keep_tlogs: bool,
) -> int:
    """``hilnav campaign``: run the sweep with a progress bar and print where the results are.

    Returns
    -------
    int
        0 when every run finished and passed its criteria, 1 when a run raised, crashed or
        failed its criteria.

    Raises
    ------
    ValueError
        Bad input (one line: unknown ``--vary`` key or value, ``--seeds`` < 1, ...).
    FileNotFoundError
        A scenario file that does not exist.
    """
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    if seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {seeds}")
    if seed_base < 0:
        raise ValueError(f"--seed-base must be >= 0, got {seed_base}")
    grid = parse_vary(vary)
    seed_list = list(range(seed_base, seed_base + seeds))
    console = Console(stderr=True, soft_wrap=True)
    bar = Progress(TextColumn("[bold]campaign"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("runs"), TimeElapsedColumn(), TimeRemainingColumn(),
                   console=console, transient=False)
    task_id = None

    def progress(done: int, total: int, _rid: str) -> None:
        nonlocal task_id
        if task_id is None:
            task_id = bar.add_task("runs", total=total)
        bar.update(task_id, completed=done)

    with bar:
        result = run_campaign(scenarios, seed_list, grid, out, scheduler=scheduler,
                              workers=workers, keep_tlogs=keep_tlogs, progress=progress)
    rep = result.report
    console.print(
        f"{len(rep['runs'])} runs: {result.executed} executed, {result.resumed} resumed, "
        f"{len(rep['failed'])} raised, {len(rep['not_passed'])} did not pass -> "
        f"{out / 'campaign.json'}, {out / 'campaign.md'}, {out / 'distributions.png'}",
        highlight=False)
    for f in rep["failed"]:
        console.print(f"[red]run {f['id']}[/] ({f['scenario']}, seed {f['seed']}, "
                      f"{_point_label(f['point'])}): {f['error']}", highlight=False)
    return 0 if result.all_passed else 1
