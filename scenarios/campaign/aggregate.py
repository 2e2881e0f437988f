"""Aggregating a campaign: per scenario x grid point statistics of every run's scorecard."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.campaign.plan import ERROR_AT_S, METRICS, SCHEMA_VERSION, RunSpec

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


def _add_criteria(into: dict[str, dict[str, Any]], summary: Mapping[str, Any]) -> None:
    """Collect one run's criterion results (value and verdict) by criterion name."""
    for c in summary.get("criteria") or []:
        row = into.setdefault(str(c.get("name")), {
            "metric": c.get("path"), "op": c.get("op", "<="), "limit": c.get("limit"),
            "values": [], "passed": 0, "runs": 0})
        row["runs"] += 1
        row["passed"] += int(bool(c.get("ok")))
        row["values"].extend(_finite([c.get("value")]))


def criterion_stats(row: Mapping[str, Any]) -> dict[str, Any]:
    """A scenario's criterion over a group's runs: its metric, limit, pass count and the
    ``{mean, p95, worst, n}`` of its values, where worst and p95 are on the failing side
    (the smallest values for a ``>=`` criterion)."""
    values = list(row["values"])
    low_is_bad = row["op"] in (">=", ">")
    st = stats([-v for v in values] if low_is_bad else values)
    if low_is_bad:
        st = {"mean": None if st["mean"] is None else -st["mean"],
              "p95": None if st["p95"] is None else -st["p95"],
              "worst": None if st["worst"] is None else -st["worst"], "n": st["n"]}
    return {"metric": row["metric"], "op": row["op"], "limit": row["limit"],
            "passed": row["passed"], "runs": row["runs"], **st}


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
        methods, run counts, pass rate, :func:`stats` of every metric and, per criterion of
        the scenario, :func:`criterion_stats`), ``runs`` (id,
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
            "runs": 0, "passed": 0, "errored": 0, "values": {m: [] for m in METRICS},
            "criteria": {}})
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
            _add_criteria(g["criteria"], summary)
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
        g["criteria"] = {name: criterion_stats(row) for name, row in g["criteria"].items()}
        group_rows.append(g)
    group_rows.sort(key=lambda g: g["order"])
    for g in group_rows:
        del g["order"]
    return {"schema_version": SCHEMA_VERSION, "groups": group_rows, "runs": runs,
            "failed": failed, "not_passed": not_passed}
