"""``hilnav compare``: every bridging method on the *same* sensor data, per seed.

For each seed the scenario is flown once (JSBSim -> sensors -> faults -> MAVLink frames kept in
memory); every method then decodes and fuses exactly those frames, so the methods differ only in
how they bridge. The result is the papers' Table 1 (outage RMSE of latitude, longitude, height,
vN, vE, vD and horizontal error) and Table 2 (mean update time per sample and fit time) on our
data, written as ``compare.json`` (docs/architecture.md) and ``compare.md``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from fusion.bridging.registry import BRIDGE_METHODS, make_bridge
from hil.pipeline import Frame, fuse_frames
from scenarios.jsonable import plain_dict, write_json
from scenarios.runner import filter_config, score, simulate
from scenarios.schema import Scenario
from scenarios.summary import write_summary

RMSE_KEYS = ("lat_deg", "lon_deg", "h_m", "vn_mps", "ve_mps", "vd_mps")
AT_KEYS = ("10", "30", "60")


def parse_methods(text: str) -> list[str]:
    """``"none,gmdh"`` -> ``["none", "gmdh"]`` (ValueError lists the valid methods)."""
    methods = [m.strip() for m in text.split(",") if m.strip()]
    if not methods:
        raise ValueError(f"--methods is empty; valid methods: {', '.join(BRIDGE_METHODS)}")
    for m in methods:
        if m not in BRIDGE_METHODS:
            raise ValueError(f"unknown bridging method {m!r}; valid methods: "
                             f"{', '.join(BRIDGE_METHODS)}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"--methods lists a method twice: {text}")
    return methods


def compare(
    scenario: Scenario,
    methods: Sequence[str],
    seeds: Sequence[int],
    out_dir: Path,
    *,
    altitude: str | None = None,
    progress: Callable[[str], None] | None = None,
    flight_progress: Callable[[int, float], None] | None = None,
) -> dict[str, Any]:
    """Run the comparison and write ``compare.json``, ``compare.md`` and per-run summaries.
    ``progress(message)`` is told each seed's flight and each method's fusion;
    ``flight_progress(seed, simulated_s)`` how far a seed's flight is."""
    for m in methods:
        make_bridge(m)
    if not seeds:
        raise ValueError("need at least one seed")
    if scenario.autopilot.flies:
        raise ValueError(f"{scenario.name}: autopilot: {scenario.autopilot.kind} needs the "
                         "autopilot connected; fly it with `hilnav run`, not `compare`")
    altitude = altitude or scenario.fusion.altitude
    out_dir.mkdir(parents=True, exist_ok=True)
    runs: dict[str, list[dict[str, Any]]] = {m: [] for m in methods}
    for seed in seeds:
        scn = scenario.with_overrides(seed=seed)
        frames: list[Frame] = []
        if progress:
            progress(f"seed {seed}: flying {scn.duration_s:.0f} s")
        flown = simulate(scn, _appender(frames), progress=None if flight_progress is None
                         else functools.partial(flight_progress, seed))
        ended = [] if flown.ended is None else [f"the flight ended early: {flown.ended}"]
        config = filter_config(scn, altitude)
        for m in methods:
            if progress:
                progress(f"seed {seed}: fusing with {m}")
            fused = fuse_frames(frames, config, m)
            status = plain_dict(fused.nav.bridge_status)
            summary, _ = score(
                scn, fused, out_dir / f"seed{seed}" / m, bridge=m, altitude=altitude,
                sim_duration_s=flown.sim_duration_s, wall_s=fused.fuse_s,
                health_extra={"bridge_status": status}, reports=False, failures=ended)
            summary["update_us_per_sample"] = 1e6 * fused.fuse_s / max(fused.samples, 1)
            summary["fit_ms"] = status.get("fit_ms")
            write_summary(summary, out_dir / f"seed{seed}" / m / "summary.json")
            runs[m].append(summary)
    result = aggregate(scenario.name, runs, list(seeds))
    write_json(result, out_dir / "compare.json")
    (out_dir / "compare.md").write_text(markdown(result))
    _plot_drift(runs, out_dir / "drift_by_method.png")
    return result


def _appender(frames: list[Frame]) -> Callable[[int, bytes], None]:
    def sink(time_us: int, frame: bytes) -> None:
        frames.append((time_us, frame))

    return sink


def _rms(values: list[float]) -> float | None:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return math.sqrt(sum(v * v for v in vals) / len(vals)) if vals else None


def _mean(values: list[Any]) -> float | None:
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return sum(vals) / len(vals) if vals else None


def aggregate(scenario: str, runs: dict[str, list[dict[str, Any]]],
              seeds: list[int]) -> dict[str, Any]:
    """Pool the per-seed summaries into the ``compare.json`` layout.

    Outage RMSEs are pooled as the root mean square of the per-outage RMSEs over all outages of
    all seeds; errors at 10/30/60 s into an outage are means (with the worst case alongside).
    """
    methods: dict[str, Any] = {}
    for m, summaries in runs.items():
        outages = [o for s in summaries for o in s.get("outages", [])]
        rmse = {k: _rms([o["rmse"].get(k) for o in outages]) for k in RMSE_KEYS}
        rmse["horizontal_m"] = _rms([o.get("horizontal_rmse_m") for o in outages])
        at = {k: _mean([o["horizontal_error_m_at"].get(k) for o in outages]) for k in AT_KEYS}
        worst = {k: max((o["horizontal_error_m_at"].get(k) or 0.0 for o in outages),
                        default=None) for k in AT_KEYS}
        methods[m] = {
            "outage_rmse": rmse,
            "horizontal_error_m_at": at,
            "horizontal_error_m_at_worst": worst,
            "vertical_rmse_m": _rms([o.get("vertical_rmse_m") for o in outages]),
            "update_us_per_sample": _mean([s.get("update_us_per_sample") for s in summaries]),
            "fit_ms": _mean([s.get("fit_ms") for s in summaries]),
            "outages": len(outages),
            "per_outage_horizontal_rmse_m": [o.get("horizontal_rmse_m") for o in outages],
        }
    if "none" in methods:
        base = methods["none"]["per_outage_horizontal_rmse_m"]
        for row in methods.values():
            ratios = [a / b for a, b in zip(row["per_outage_horizontal_rmse_m"], base, strict=False)
                      if a is not None and b]
            b_rmse = methods["none"]["outage_rmse"]["horizontal_m"]
            row["ratio_to_none"] = {
                "horizontal_rmse": (row["outage_rmse"]["horizontal_m"] / b_rmse
                                    if b_rmse and row["outage_rmse"]["horizontal_m"] is not None
                                    else None),
                "worst_single_outage": max(ratios) if ratios else None,
                "at_60s": _ratio(row["horizontal_error_m_at"]["60"],
                                 methods["none"]["horizontal_error_m_at"]["60"]),
            }
    return {"scenario": scenario, "seeds": seeds, "methods": methods}


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b else None


def _f(v: Any, spec: str) -> str:
    return "n/a" if v is None else format(v, spec)


def markdown(result: dict[str, Any]) -> str:
    """The comparison as Markdown tables (Table 1 and Table 2 of the papers)."""
    lines = [
        f"# Bridging comparison: {result['scenario']}",
        "",
        f"Seeds: {', '.join(str(s) for s in result['seeds'])}. RMSE during GNSS outages "
        "(pooled over all outages of all seeds).",
        "",
        "| method | lat (deg) | lon (deg) | h (m) | vN (m/s) | vE (m/s) | vD (m/s) | horiz (m) "
        "| @10 s (m) | @30 s (m) | @60 s (m) | vs none |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for m, row in result["methods"].items():
        r, at = row["outage_rmse"], row["horizontal_error_m_at"]
        ratio = row.get("ratio_to_none", {}).get("horizontal_rmse")
        lines.append(
            f"| {m} | {_f(r['lat_deg'], '.2e')} | {_f(r['lon_deg'], '.2e')} "
            f"| {_f(r['h_m'], '.2f')} "
            f"| {_f(r['vn_mps'], '.3f')} | {_f(r['ve_mps'], '.3f')} | {_f(r['vd_mps'], '.3f')} "
            f"| {_f(r['horizontal_m'], '.2f')} | {_f(at['10'], '.1f')} | {_f(at['30'], '.1f')} "
            f"| {_f(at['60'], '.1f')} | {_f(ratio, '.2f')} |")
    lines += ["", "| method | update (us/sample) | fit (ms) |", "|---|---|---|"]
    for m, row in result["methods"].items():
        lines.append(f"| {m} | {_f(row['update_us_per_sample'], '.1f')} "
                     f"| {_f(row['fit_ms'], '.1f')} |")
    return "\n".join(lines) + "\n"


def _plot_drift(runs: dict[str, list[dict[str, Any]]], path: Path) -> None:
    """Horizontal error vs time into the outage, every outage faint and the mean bold."""
    from scenarios.report import drift_curves, plot_drift_compare

    curves = {m: [c for s in summaries for c in drift_curves(s)] for m, summaries in runs.items()}
    plot_drift_compare(curves, path, title="drift during GNSS outages by bridging method")
