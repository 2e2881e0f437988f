"""Build ``summary.json`` (the output contract in docs/architecture.md) from collected tracks."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, NonNegativeFloat, PositiveFloat

from hil.build_info import build_info
from hil.pipeline import FusionRun
from hil.tracks import HealthSeries, Track
from scenarios import event_metrics, metrics
from scenarios.event_metrics import EventWindow
from scenarios.jsonable import plain_dict, write_json
from scenarios.metrics import Errors, Window

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Criterion:
    """A pass criterion: ``value <= limit`` (or ``>=`` with ``op=">="``), ``value`` looked up
    by a dotted path (e.g. ``"outages.horizontal_error_m_at.60"``).

    Through a list (all outages, all events) the worst value counts: the largest for ``<=``,
    the smallest for ``>=``. Items without the value are skipped (an outage too short for
    ``.120``), unless ``none_fails``: then one missing value fails the criterion (an event
    never detected has ``detect_s: null``). No value at all always fails.
    """

    name: str
    path: str
    limit: float
    op: Literal["<=", ">="] = "<="
    none_fails: bool = False

    def __post_init__(self) -> None:
        if self.op not in ("<=", ">="):
            raise ValueError(f"criterion {self.name!r}: op must be '<=' or '>='")

    def evaluate(self, summary: dict[str, Any]) -> dict[str, Any]:
        values = _lookup_all(summary, self.path)
        found = [v for v in values if v is not None]
        value: float | None
        if not found or (self.none_fails and len(found) < len(values)):
            value, ok = None, False
        else:
            value = _worst(found, self.op)
            ok = math.isfinite(value) and (
                value <= self.limit if self.op == "<=" else value >= self.limit)
        return {"name": self.name, "limit": self.limit, "value": value, "ok": bool(ok),
                "op": self.op, "path": self.path}


def _worst(values: list[float], op: str) -> float:
    return max(values) if op == "<=" else min(values)


def _lookup_all(tree: Any, path: str) -> list[float | None]:
    """Values at a dotted path; a list along the way fans out (one entry per item)."""
    node = tree
    parts = path.split(".")
    for i, part in enumerate(parts):
        if isinstance(node, list):
            rest = ".".join(parts[i:])
            return [v for item in node for v in _lookup_all(item, rest)]
        if not isinstance(node, dict) or part not in node:
            return [None]
        node = node[part]
    if isinstance(node, list):
        return [float(v) if isinstance(v, int | float) else None for v in node]
    return [float(node) if isinstance(node, int | float) else None]


def _lookup(tree: Any, path: str) -> float | None:
    """Worst (largest) value at a dotted path, ``None`` if there is none."""
    found = [v for v in _lookup_all(tree, path) if v is not None]
    return max(found) if found else None


class ScoringConfig(BaseModel):
    """How events and re-convergence are scored (defaults suit a 1-2 m GNSS receiver)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    reconverge_k: PositiveFloat = 3.0
    """Re-converged = horizontal error below ``reconverge_k`` x the GNSS-on horizontal RMSE."""
    reconverge_threshold_m: PositiveFloat | None = None
    """A fixed threshold instead (m)."""
    reconverge_hold_s: NonNegativeFloat = 10.0
    """The error must stay below the threshold this long."""
    bad_fix_m: PositiveFloat | None = None
    """A fix this far from truth must not be fused (m). Default: ``bad_fix_k`` x the RMS
    horizontal error of the fixes outside events, at least ``bad_fix_min_m``."""
    bad_fix_k: PositiveFloat = 5.0
    bad_fix_min_m: PositiveFloat = 10.0
    outage_merge_s: NonNegativeFloat = 3.0
    """GNSS fix gaps less than this apart form one outage (s); gaps inside one scripted
    outage or jamming event always do."""


MIN_SCORED_FRACTION = 0.5
"""A fitted settling time leaves at least this fraction of the GNSS-on time to score."""


@dataclass(frozen=True)
class Settling:
    """The settling time a scorecard used, and why it differs from the one asked for.

    Attributes
    ----------
    requested_s : the ``--settle`` asked for, s.
    applied_s : the one used, s (see :func:`fit_settling`).
    span_s : seconds during which both the navigation estimate and the reference exist.
    scored_s : seconds the GNSS-on figures cover with ``applied_s`` (after the start and
        after each outage).
    warning : None, or a one-line explanation (the CLI prints it on stderr).
    """

    requested_s: float
    applied_s: float
    span_s: float
    scored_s: float
    warning: str | None

    def as_dict(self) -> dict[str, Any]:
        return {"requested_s": self.requested_s, "applied_s": self.applied_s,
                "span_s": self.span_s, "scored_s": self.scored_s, "warning": self.warning}


def _on_seconds(time_s: np.ndarray, outages: list[Window], settle_s: float) -> float:
    if time_s.size < 2:
        return 0.0
    dt = np.diff(time_s, append=time_s[-1])
    return float(np.sum(dt[metrics.gnss_on_mask(time_s, outages, settle_s=settle_s)]))


def fit_settling(requested_s: float, time_s: np.ndarray, outages: list[Window]) -> Settling:
    """Fit ``requested_s`` of settling to a log: never GNSS-on figures that are silently empty.

    ``time_s`` are the scored times (estimate and reference both present), ``outages`` the
    GNSS outages. The request is applied when it leaves at least ``MIN_SCORED_FRACTION`` of
    the GNSS-on time (after the start and after each outage); otherwise the longest settling
    that does (found by bisection, to 1 ms) is applied, with a warning. No GNSS-on time at all
    (the outages cover the log) gives a warning that nothing can be scored with GNSS on.
    """
    span = float(time_s[-1] - time_s[0]) if time_s.size else 0.0
    full = _on_seconds(time_s, outages, 0.0)
    if full <= 0.0:
        return Settling(requested_s, 0.0, span, 0.0,
                        f"no GNSS-on time to score: the estimate overlaps the reference for "
                        f"{span:.1f} s, all of it in GNSS outages")
    needed = MIN_SCORED_FRACTION * full
    scored = _on_seconds(time_s, outages, requested_s)
    if scored >= needed:
        return Settling(requested_s, requested_s, span, scored, None)
    lo, hi = 0.0, requested_s
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _on_seconds(time_s, outages, mid) >= needed else (lo, mid)
    lo = math.floor(lo * 1e3) / 1e3  # down: never below the fraction to score
    scored = _on_seconds(time_s, outages, lo)
    return Settling(requested_s, lo, span, scored,
                    f"--settle {requested_s:g} s is longer than the log allows: the estimate "
                    f"overlaps the reference for {span:.1f} s ({full:.1f} s with GNSS); "
                    f"settled {lo:.1f} s after the start and each outage and scored "
                    f"{scored:.1f} s with GNSS on")


@dataclass(frozen=True)
class RunInfo:
    scenario: str
    seed: int | None
    sim_duration_s: float
    wall_s: float
    bridge: str
    altitude: str
    setup: Mapping[str, Any] | None = None
    """What was flown (aircraft, plan, sensor presets, air), when the caller knows it."""


def build_summary(
    info: RunInfo,
    estimate: Track,
    truth: Track,
    outages: list[Window],
    *,
    settle_s: float = 60.0,
    criteria: Sequence[Criterion] = (),
    health: dict[str, Any] | None = None,
    events: Sequence[EventWindow | Mapping[str, Any]] = (),
    series: HealthSeries | None = None,
    scoring: ScoringConfig | None = None,
) -> tuple[dict[str, Any], Errors]:
    """Score an estimate against truth; returns the summary dict and the error series.

    Parameters
    ----------
    info : RunInfo
    estimate, truth : Track
    outages : list of Window
        GNSS outages (from the fix gaps).
    settle_s : float
        Seconds after the start, after each outage and after each spoof / glitch / jamming
        event that the GNSS-on figures (and ``nees``) leave out.
    criteria : sequence of Criterion
    health : dict, optional
        Final counters, written as ``health``.
    events : sequence of EventWindow or mapping
        Scenario events (``{type, start_s, end_s[, kind, sensor]}``), scored into ``events``.
    series : HealthSeries, optional
        The filter's mode / test ratios / counters per estimate (``Collector.series()``):
        needed for ``detect_s`` and the re-accept check.
    scoring : ScoringConfig, optional

    Returns
    -------
    summary : dict
        The ``summary.json`` contract (docs/architecture.md) plus ``containment_3sigma``,
        ``events``, ``detect_s_by_sensor`` (the events' ``detect_s`` per sensor), ``scoring``
        and (with ``series``) ``rejections_outside_events``; each outage also has
        ``cep50_m``, ``cep95_m``, ``containment_3sigma``, ``reconverge_s``, vertical error
        figures, ``nees_mean`` and its ``drift`` curve.
    err : Errors
    """
    cfg = scoring if scoring is not None else ScoringConfig()
    windows = [_event(e) for e in events]
    err = metrics.errors(estimate, truth)
    on = metrics.gnss_on_mask(err.time_s, outages, settle_s=settle_s)
    end_data = float(err.time_s[-1]) if err.time_s.size else 0.0
    for ev in windows:
        # spoofing, glitches and jamming corrupt the GNSS-on figures (the reference of
        # re-convergence) as outages do; generic events (a slower or degraded receiver, an IMU
        # or baro fault) are part of what "GNSS on" means in that scenario
        if ev.kind != "generic":
            on &= ~((err.time_s >= ev.start_s)
                    & (err.time_s < min(ev.end_s, end_data) + settle_s))
    gnss_on = metrics.gnss_on_metrics(err, on)
    if cfg.reconverge_threshold_m is not None:
        threshold = cfg.reconverge_threshold_m
    else:
        threshold = cfg.reconverge_k * gnss_on["horizontal_rmse_m"]
    starts = sorted([w.start_s for w in outages] + [e.start_s for e in windows])

    def next_start(after: float) -> float:
        later = [s for s in starts if s > after]
        return later[0] if later else math.inf

    outage_rows = []
    for w in outages:
        om = metrics.outage_metrics(err, w)
        if om is not None:
            om.reconverge_s = metrics.reconverge_time(
                err, w.end_s, threshold_m=threshold, hold_s=cfg.reconverge_hold_s,
                until_s=next_start(w.end_s))
            row = om.as_dict()
            parts = w.gaps if isinstance(w, metrics.Outage) and w.gaps else (w,)
            row["gaps"] = [[g.start_s, g.end_s] for g in parts]
            outage_rows.append(row)
    fix_err = None
    bad_fix_m = cfg.bad_fix_m
    if series is not None and series.fixes is not None and series.fixes.time_s.size:
        fix_err = event_metrics.fix_errors(series.fixes, truth)
        if bad_fix_m is None:
            bad_fix_m = _bad_fix_threshold(series.fixes.time_s, fix_err, windows, cfg)
    event_rows = [
        event_metrics.event_metrics(
            err, ev, health=series, fix_err_m=fix_err, bad_fix_m=bad_fix_m,
            reconverge_threshold_m=threshold, hold_s=cfg.reconverge_hold_s,
            until_s=next_start(ev.end_s)).as_dict()
        for ev in windows
    ]
    summary: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "scenario": info.scenario,
        "seed": info.seed,
        "sim_duration_s": info.sim_duration_s,
        "wall_s": info.wall_s,
        "realtime_factor": info.sim_duration_s / info.wall_s if info.wall_s > 0 else None,
        "bridge": info.bridge,
        "altitude": info.altitude,
        **({"setup": dict(info.setup)} if info.setup is not None else {}),
        "outages": outage_rows,
        "gnss_on": gnss_on,
        "nees": metrics.consistency(err, on),
        "containment_3sigma": metrics.containment_3sigma(
            err, err.time_s >= err.time_s[0] + settle_s if err.time_s.size else None),
        "events": event_rows,
        "detect_s_by_sensor": event_metrics.detect_s_by_sensor(event_rows),
        "scoring": {"reconverge_threshold_m": threshold,
                    "reconverge_hold_s": cfg.reconverge_hold_s, "bad_fix_m": bad_fix_m},
        "health": health or {},
    }
    if series is not None:
        quiet = [(w.start_s, w.end_s + settle_s) for w in outages]
        quiet += [(e.start_s, min(e.end_s, end_data) + settle_s) for e in windows]
        summary["rejections_outside_events"] = event_metrics.rejections_outside(
            series, quiet, after_s=float(series.time_s[0]) + settle_s if series.time_s.size
            else 0.0)
    results = [c.evaluate(summary) for c in criteria]
    summary["criteria"] = results
    summary["passed"] = all(r["ok"] for r in results)
    return summary, err


@dataclass(frozen=True)
class Scored:
    """A scored run: the summary and what it was computed from (for plots and reports)."""

    summary: dict[str, Any]
    errors: Errors
    estimate: Track
    truth: Track
    outages: list[Window]


def score_run(
    run: FusionRun,
    info: RunInfo,
    *,
    settle_s: float = 60.0,
    criteria: Sequence[Criterion] = (),
    events: Sequence[EventWindow | Mapping[str, Any]] = (),
    health_extra: Mapping[str, Any] | None = None,
    with_series: bool = False,
    fit_settle: bool = False,
    scoring: ScoringConfig | None = None,
) -> Scored:
    """Score what a :class:`hil.pipeline.FusionRun` collected: the one scorer of ``run``,
    ``replay``, ``compare``, ``campaign``, the live scorecard and the benches.

    GNSS outages are the gaps of more than 1 s between received 3-D fixes (up to the end of
    the shorter of the estimate and truth tracks), merged into one outage where they fall
    inside one scripted outage or jamming event or are less than
    ``scoring.outage_merge_s`` apart (each outage row lists its ``gaps``); ``health`` holds
    the filter's and the decoder's final counters plus ``health_extra``; ``with_series``
    adds the per-estimate mode / test-ratio / counter series that event scoring needs.
    ``fit_settle`` fits ``settle_s`` to a short log (:func:`fit_settling`) and writes
    ``settling`` into the summary.

    Raises
    ------
    ValueError
        The run collected nothing (no collector), no navigation estimate or no truth.
    """
    col = run.collector
    if col is None:
        raise ValueError("the run kept no tracks to score (collect=False)")
    estimate = col.estimate_track()
    truth = col.truth_track()
    end_s = col.end_s()
    cfg = scoring if scoring is not None else ScoringConfig()
    denied = [metrics.Window(float(e.start_s), float(e.end_s)) for e in map(_event, events)
              if e.type in metrics.GNSS_DENIAL_EVENTS]
    gaps = metrics.outages_from_fix_times(
        np.asarray(col.fix_times_us, dtype=float) * 1e-6, end_s=end_s)
    outages: list[metrics.Window] = list(
        metrics.merge_gaps(gaps, denied=denied, merge_s=cfg.outage_merge_s))
    health: dict[str, Any] = {"filter": plain_dict(run.nav.health),
                              "decoder": plain_dict(run.decoder.counters),
                              "air_data": plain_dict(run.nav.air_data)}
    thermal = run.nav.thermal_status
    if thermal is not None:  # a thermal strategy ran (--thermal, --bridge gmdh-thermal)
        health["thermal"] = plain_dict(thermal)
    health.update(health_extra or {})
    fitted = None
    if fit_settle:
        t = estimate.time_s
        fitted = fit_settling(settle_s, t[(t >= truth.time_s[0]) & (t <= truth.time_s[-1])],
                              outages)
        settle_s = fitted.applied_s
    summary, err = build_summary(
        info, estimate, truth, outages, settle_s=settle_s, criteria=criteria, health=health,
        events=events, series=col.series() if with_series else None, scoring=cfg)
    if fitted is not None:
        summary["settling"] = fitted.as_dict()
    summary["build"] = build_info()
    return Scored(summary, err, estimate, truth, outages)


def _event(e: EventWindow | Mapping[str, Any]) -> EventWindow:
    return e if isinstance(e, EventWindow) else EventWindow.from_mapping(e)


def _bad_fix_threshold(
    fix_time_s: np.ndarray, fix_err_m: np.ndarray, events: list[EventWindow],
    cfg: ScoringConfig,
) -> float:
    """``bad_fix_k`` x RMS of the fix errors outside events, at least ``bad_fix_min_m``."""
    clean = np.isfinite(fix_err_m)
    for ev in events:
        clean &= ~((fix_time_s >= ev.start_s) & (fix_time_s <= ev.end_s))
    base = metrics.rms(fix_err_m[clean]) if np.any(clean) else 0.0
    return max(cfg.bad_fix_min_m, cfg.bad_fix_k * base)


def write_summary(summary: dict[str, Any], path: Path) -> None:
    """Write ``summary.json`` (NaN and infinity as ``null``)."""
    write_json(summary, path)
