"""A campaign's reports: ``campaign.json``, ``campaign.md`` and the error distributions plot."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.campaign.aggregate import run_metrics
from scenarios.summary import write_summary

# -- reports -----------------------------------------------------------------------------------


def _fmt(v: Any, spec: str = ".2f") -> str:
    return "n/a" if v is None else format(v, spec)


def point_label(point: Mapping[str, str]) -> str:
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
            f"| {g['scenario']} | {point_label(g['point'])} | {', '.join(g['bridge']) or 'n/a'} "
            f"| {', '.join(g['altitude']) or 'n/a'} | {g['runs']} "
            f"| {_fmt(g['pass_rate'], '.0%')} | {g['errored']} "
            f"| {triple(m['outage_horizontal_rmse_m'])} "
            f"| {triple(m['outage_horizontal_error_m_at_60s'])} "
            f"| {triple(m['outage_horizontal_max_m'])} "
            f"| {triple(m['gnss_on_horizontal_rmse_m'])} |")
    crit_rows = [(g, name, c) for g in report["groups"]
                 for name, c in (g.get("criteria") or {}).items()]
    if crit_rows:
        lines += ["", "## Each scenario's own criteria", "",
                  "Each criterion's value over the runs of a row: mean / p95 / worst, worst on "
                  "the failing side.", "",
                  "| scenario | grid point | criterion | metric | limit | passed "
                  "| mean / p95 / worst |", "|---|---|---|---|---|---|---|"]
        for g, name, c in crit_rows:
            lines.append(
                f"| {g['scenario']} | {point_label(g['point'])} | {name} | {c['metric']} "
                f"| {c['op']} {_fmt(c['limit'], 'g')} | {c['passed']}/{c['runs']} "
                f"| {_fmt(c['mean'], '.3g')} / {_fmt(c['p95'], '.3g')} "
                f"/ {_fmt(c['worst'], '.3g')} |")
    if report["failed"]:
        lines += ["", "## Runs that raised", "", "| run | scenario | seed | grid point | error |",
                  "|---|---|---|---|---|"]
        for f in report["failed"]:
            lines.append(f"| {f['id']} | {f['scenario']} | {f['seed']} "
                         f"| {point_label(f['point'])} | {f['error'].replace('|', '/')} |")
    if report["not_passed"]:
        lines += ["", "## Runs that failed their criteria", "",
                  "| run | scenario | seed | grid point | why |", "|---|---|---|---|---|"]
        for f in report["not_passed"]:
            lines.append(f"| {f['id']} | {f['scenario']} | {f['seed']} "
                         f"| {point_label(f['point'])} | {f['reason'].replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def plot_distributions(report: Mapping[str, Any], out_dir: Path, path: Path) -> None:
    """Box plots (with every value drawn) of the outage horizontal RMSE and the error 60 s into
    an outage, one box per grid point and one row per scenario."""
    from matplotlib.figure import Figure

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
    fig = Figure(figsize=(min(width, 24.0), 3.6 * rows))
    axes = fig.subplots(rows, 2, squeeze=False)
    for row, (spath, groups) in enumerate(sorted(by_scenario.items())):
        for col, (metric, label) in enumerate(panels):
            ax = axes[row][col]
            data, names = [], []
            for g in groups:
                key = (spath, json.dumps(sorted(g["point"].items())))
                data.append(values.get(key, {}).get(metric, []))
                names.append(point_label(g["point"]).replace(", ", "\n"))
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


def write_reports(report: dict[str, Any], out_dir: Path) -> list[Path]:
    """Write ``campaign.json``, ``campaign.md`` and ``distributions.png``; return their paths."""
    json_path = out_dir / "campaign.json"
    write_summary(report, json_path)  # same NaN -> null cleaning as summary.json
    md_path = out_dir / "campaign.md"
    md_path.write_text(markdown(report))
    png_path = out_dir / "distributions.png"
    plot_distributions(report, out_dir, png_path)
    return [json_path, md_path, png_path]
