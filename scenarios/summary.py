"""Build ``summary.json`` (the CLI output contract of ARCHITECTURE.md) from collected tracks."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenarios import metrics
from scenarios.metrics import Errors, Track, Window

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Criterion:
    """A pass criterion: ``value <= limit`` (``value`` looked up by a dotted path)."""

    name: str
    path: str
    limit: float

    def evaluate(self, summary: dict[str, Any]) -> dict[str, Any]:
        value = _lookup(summary, self.path)
        ok = value is not None and math.isfinite(value) and value <= self.limit
        return {"name": self.name, "limit": self.limit, "value": value, "ok": bool(ok)}


def _lookup(tree: Any, path: str) -> float | None:
    node = tree
    for part in path.split("."):
        if isinstance(node, list):
            found = [v for v in (_lookup(item, part) for item in node) if v is not None]
            return max(found) if found else None  # worst case over a list (e.g. all outages)
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return float(node) if isinstance(node, int | float) else None


@dataclass(frozen=True)
class RunInfo:
    scenario: str
    seed: int | None
    sim_duration_s: float
    wall_s: float
    bridge: str
    altitude: str


def build_summary(
    info: RunInfo,
    estimate: Track,
    truth: Track,
    outages: list[Window],
    *,
    settle_s: float = 60.0,
    criteria: tuple[Criterion, ...] = (),
    health: dict[str, Any] | None = None,
) -> tuple[dict[str, Any], Errors]:
    """Score an estimate against truth; returns the summary dict and the error series."""
    err = metrics.errors(estimate, truth)
    outage_rows = []
    for w in outages:
        om = metrics.outage_metrics(err, w)
        if om is not None:
            outage_rows.append(om.as_dict())
    on = metrics.gnss_on_mask(err.time_s, outages, settle_s=settle_s)
    summary: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "scenario": info.scenario,
        "seed": info.seed,
        "sim_duration_s": info.sim_duration_s,
        "wall_s": info.wall_s,
        "realtime_factor": info.sim_duration_s / info.wall_s if info.wall_s > 0 else None,
        "bridge": info.bridge,
        "altitude": info.altitude,
        "outages": outage_rows,
        "gnss_on": metrics.gnss_on_metrics(err, on),
        "nees": metrics.consistency(err, on),
        "health": health or {},
    }
    results = [c.evaluate(summary) for c in criteria]
    summary["criteria"] = results
    summary["passed"] = all(r["ok"] for r in results)
    return summary, err


def _clean(obj: Any) -> Any:
    """JSON has no NaN/Inf: write them as null."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, float | np.floating):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_summary(summary: dict[str, Any], path: Path) -> None:
    path.write_text(json.dumps(_clean(summary), indent=2) + "\n")
