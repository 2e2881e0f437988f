"""Benchmark: GNSS-outage bridging strategies against the plain filter.

Each run flies one plan for 600 s (Cessna 172, ``industrial-mems`` IMU, ``modern`` GNSS,
``ms5611`` baro, ``consumer`` magnetometer) with GNSS switched off for four 25 s outages (P0's
repeated 25-second outages) at 150, 230, 310 and 390 s and a 60 s outage at 470 s. The frames
go through the same in-memory MAVLink path as ``hilnav replay`` (SensorStreamer -> Decoder), the
filter is tuned from the IMU datasheet (:func:`hil.tuning.filter_config_for_imu`).

How the methods are run
-----------------------
An :class:`~fusion.bridging.interface.OutputCorrection` strategy (``gmdh``, ``rbf``, ``mlp``,
``bp-parallel``, and the P0-input variants) never changes the filter: it only shifts the
output during an outage. So each flight is filtered **once** with a recording strategy that
asks for the same virtual outages (INS copies) as the learned methods and returns nothing; the
recorded hook calls (every ``on_gnss`` with its virtual-outage pairs, every ``on_outage``, every
``on_gnss_restored``, in order) are then replayed into each strategy, and its corrections are
applied to the recorded estimates exactly as ``NavFilter._make_estimate`` does (a correction
holds from its bridge epoch until the next one or the end of the outage). The recorded run
*is* the ``none`` baseline. ``gmdh-pseudo`` changes the filter (its pseudo-fixes are fused), so
it is run through a second full filter pass — unless a replay of the recording shows that it
never sends a pseudo-fix (its fallback gate kept it off): until its first pseudo-fix its filter
*is* the recorded one, so then the recording is its run. ``--check-equivalence N`` runs a real
``NavFilter(bridge=make_bridge("gmdh"))`` on the first N flights and reports the largest
difference from the replay (it must be ~0: same code, same inputs).

Reported (held-out seeds 100-109 on manoeuvre, cruise and climb-descent by default; the
feature set and settings were chosen with ``--tune`` on seeds 1-5 of racetrack and survey):

- per 25 s outage: horizontal RMSE of each method and its ratio to ``none``; aggregated as the
  ratio of summed RMSEs, the mean and the worst single-outage ratio (targets: ``gmdh`` <= 0.3x
  overall, never > 1.2x in one outage);
- the 60 s outage: horizontal error 60 s in (target: ``gmdh`` <= 0.5x ``none``);
- cost: GMDH prediction (one ``on_outage`` call, all six networks, features included) against
  one filter step (one IMU sample with ``none``), target <= 0.3x; the refit of one component
  network and of all six on 60 s of 100 Hz data (6000 pairs, default features), target
  <= 100 ms; the in-loop fits (pairs used, wall time per component fit) of the replays;
- the bridging status at the start of each outage (state, fallback flags).

    python bench/bridging.py --out bench/results/bridging.json [--seeds 10] [--seed-base 100]
        [--plans manoeuvre,cruise,climb-descent] [--jobs 2] [--full-methods-seeds K]
        [--cache DIR] [--no-pseudo]
    python bench/bridging.py --tune --out bench/results/bridging_tuning.json
    python bench/bridging.py --tune-gate --out bench/results/bridging_gate_tuning.json

Every method runs on every flight (the replays are cheap: refits are bounded);
``--full-methods-seeds K`` limits the P0-input variants to the first K seeds. For a quick
check use ``--seeds 2 --no-pseudo`` (the reported numbers need the full 10 seeds x 3 plans).
``--cache DIR`` keeps the decoded flights (pickles) *and* the recordings, the latter keyed by a
hash of the filter code (``fusion/`` without the strategies, ``hil/tuning.py``,
``scenarios/collect.py`` and ``metrics.py``): a re-run with the same filter skips every
filter pass but ``gmdh-pseudo``'s; the flight is loaded only when a filter pass needs it.
``--tune-gate`` searches the fallback gate's settings (``BridgeConfig.gate_*``) on the tuning
seeds and plans.
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import multiprocessing as mp
import os
import pickle
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fusion.bridging.interface import NoBridge

IMU = "industrial-mems"
GNSS = "modern"
DURATION_S = 600.0
OUTAGES: tuple[tuple[float, float], ...] = (
    (150.0, 25.0), (230.0, 25.0), (310.0, 25.0), (390.0, 25.0), (470.0, 60.0),
)  # fmt: skip
HELD_OUT_PLANS = "manoeuvre,cruise,climb-descent"
TUNING_PLANS = "racetrack,survey"
TARGETS = {
    "rmse_25s_ratio": 0.3,
    "worst_25s_ratio": 1.2,
    "error_at_60s_ratio": 0.5,
    "predict_over_filter_step": 0.3,
    "refit_60s_100hz_ms": 100.0,
}

# Variants run by replay: name -> (method, BridgeConfig overrides)
FAST_VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "gmdh": ("gmdh", {}),
    "rbf": ("rbf", {}),
    "bp-parallel": ("bp-parallel", {}),
    "mlp": ("mlp", {}),
}
P0_VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "gmdh-p0-fix": ("gmdh", {"training": "fix", "features": ("own",)}),
    "gmdh-p0-virtual": ("gmdh", {"features": ("own",)}),
}
TUNING_FEATURES: tuple[tuple[str, ...], ...] = (
    ("own",), ("t",), ("t", "t2"), ("t", "own"), ("t", "sinpsi", "cospsi"),
    ("t", "t2", "sinpsi", "cospsi"), ("t", "dn", "de"), ("t", "t2", "dn", "de"),
    ("t", "dn", "de", "sinpsi", "cospsi"), ("t", "dvn", "dve"),
    ("t", "fn", "fe", "sinpsi", "cospsi"), ("t", "vn", "ve", "dn", "de"),
    ("t", "sinpsi0", "cospsi0", "dn", "de"), ("t", "bax", "bay", "bgz", "sinpsi", "cospsi"),
)  # fmt: skip
TUNING_SETTINGS: tuple[dict[str, Any], ...] = (
    {}, {"window_s": 150.0}, {"window_s": 600.0},
)
TUNING_GATES: tuple[dict[str, Any], ...] = (
    {"gate_margin": 1.0, "gate_min_wins": 0.01, "gate_min_outages": 1},  # ~ no gate
    {"gate_margin": 0.9, "gate_min_wins": 0.5},
    {"gate_margin": 0.8, "gate_min_wins": 0.75},
    {"gate_margin": 0.6, "gate_min_wins": 1.0},
    {"gate_margin": 0.8, "gate_min_wins": 0.75, "gate_outages": 10, "gate_min_outages": 5},
    {"gate_margin": 0.8, "gate_min_wins": 0.75, "gate_horizon_s": 30.0},
)
"""Gate settings searched with ``--tune-gate`` (tuning seeds and plans only)."""
TUNING_GATE_METHODS = ("gmdh", "rbf")


# ------------------------------------------------------------------------------ recording
@dataclass
class Recorded:
    """One flight filtered once with the recording strategy."""

    hooks: list[tuple[str, Any, Any]] = field(default_factory=list)
    est_t_us: list[int] = field(default_factory=list)
    err_pos: Any = None  # (N, 3) estimate - truth, NED m, at est_t_us
    fix_t_s: Any = None
    imu_samples: int = 0
    filter_cpu_s: float = 0.0


class HookRecorder(NoBridge):
    """Asks for virtual outages like the learned strategies, records every hook call, returns
    nothing (the filter runs as ``none``)."""

    name = "recorder"

    def __init__(self, virtual_outage_s: float, count: int, hooks: list[Any]) -> None:
        self.virtual_outage_s = virtual_outage_s
        self.virtual_outage_count = count
        self.hooks = hooks

    def on_gnss(self, epoch: Any, error: Any) -> None:
        self.hooks.append(("g", epoch, error))

    def on_outage(self, epoch: Any) -> None:
        self.hooks.append(("o", epoch, None))

    def on_gnss_restored(self, epoch: Any) -> None:
        self.hooks.append(("r", epoch, None))


def simulate(plan: str, seed: int, cache: Path | None) -> list[Any]:
    """Fly one plan and decode every frame: the samples and truth in arrival order."""
    path = None if cache is None else cache / f"{plan}_{seed}.pkl"
    if path is not None and path.is_file():
        items: list[Any] = pickle.loads(path.read_bytes())
        return items
    from hil.codec import Decoder
    from hil.pipeline import SimSetup, fly

    setup = SimSetup.build(
        plan=plan, imu=IMU, gnss=GNSS, duration_s=DURATION_S, seed=seed,
        gnss_off=[f"{s:g}:{d:g}" for s, d in OUTAGES])  # fmt: skip
    decoder = Decoder()
    items: list[Any] = []

    def sink(_t_us: int, frame: bytes) -> None:
        items.extend(d.sample for d in decoder.feed(frame))

    report = fly(setup, sink)
    if report.ended is not None:
        raise RuntimeError(f"{plan} seed {seed}: flight ended early ({report.ended})")
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(items))
    return items


def run_filter(items: list[Any], bridge: Any) -> tuple[Any, Any, list[float], float]:
    """Filter ``items``; returns (estimate errors, estimate times us, fix times s, cpu s)."""
    import numpy as np

    from fusion.filter import NavFilter
    from hil.pipeline import FusionRun
    from hil.tuning import filter_config_for_imu
    from scenarios import metrics

    config = filter_config_for_imu(IMU)
    run = FusionRun(config, nav=NavFilter(config, bridge=bridge))
    col = run.collector
    assert col is not None
    t0 = time.process_time()
    run.feed(items)
    cpu = time.process_time() - t0
    est, truth = col.estimate_track(), col.truth_track()
    err = metrics.errors(est, truth)
    return err, np.round(err.time_s * 1e6).astype(np.int64), [t * 1e-6 for t in
                                                              col.fix_times_us], cpu


def _code_hash() -> str:
    """Hash of the code a recording depends on (the filter and its tuning): a cached
    recording is reused only while that code is unchanged."""
    import hashlib

    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    strategies = {"bridging.py", "gmdh.py", "regressors.py"}  # replayed, not recorded
    for f in sorted([*(root / "fusion").rglob("*.py"), root / "hil" / "tuning.py",
                     root / "scenarios" / "collect.py", root / "scenarios" / "metrics.py"]):
        if f.parent.name != "fusion" or f.name not in strategies:
            h.update(f.read_bytes())
    return h.hexdigest()[:12]


def record(
    items_fn: Any, virtual_outage_s: float, count: int, cache: Path | None = None,
    key: str = "",
) -> Recorded:  # fmt: skip
    """Filter once with the recording strategy (cached under ``cache`` by flight and code)."""
    from sim.samples import ImuSample

    path = None
    if cache is not None:
        path = cache / f"rec_{key}_{virtual_outage_s:g}x{count}_{_code_hash()}.pkl"
        if path.is_file():
            cached: Recorded = pickle.loads(path.read_bytes())
            return cached
    rec = Recorded()
    items = items_fn()
    err, t_us, fixes, cpu = run_filter(items, HookRecorder(virtual_outage_s, count, rec.hooks))
    rec.err_pos = err.pos_ned_m
    rec.est_t_us = t_us.tolist()
    rec.fix_t_s = fixes
    rec.filter_cpu_s = cpu
    rec.imu_samples = sum(1 for i in items if isinstance(i, ImuSample))
    if path is not None:
        path.write_bytes(pickle.dumps(rec))
    return rec


# ------------------------------------------------------------------------------ replay
@dataclass
class Replayed:
    corr: Any  # (N, 3) position correction applied to each recorded estimate
    fit_s: list[float]
    fit_cpu_s: list[float]
    fit_pairs: list[int]
    predict_cpu_s: list[float]
    status_at_outage: list[dict[str, Any]]


def replay_hooks(bridge: Any, rec: Recorded) -> Replayed:
    """Feed the recorded hook calls to ``bridge``; the output correction at every estimate."""
    import numpy as np

    from fusion.bridging.interface import OutputCorrection

    events: list[tuple[int, tuple[float, float, float] | None]] = []
    fit_s: list[float] = []
    fit_cpu_s: list[float] = []
    fit_pairs: list[int] = []
    pred_s: list[float] = []
    statuses: list[dict[str, Any]] = []
    current: tuple[float, float, float] | None = None
    in_outage = False
    for kind, epoch, error in rec.hooks:
        if kind == "g":
            refits = bridge.status.refits
            c0 = time.process_time()
            t0 = time.perf_counter()
            bridge.on_gnss(epoch, error)
            dt = time.perf_counter() - t0
            dc = time.process_time() - c0
            st = bridge.status
            if st.refits > refits:
                fit_s.append(dt)
                fit_cpu_s.append(dc)
                fit_pairs.append(st.last_fit_samples)
        elif kind == "o":
            if not in_outage:
                st = bridge.status
                statuses.append({"time_s": epoch.time_us * 1e-6, "state": st.state,
                                 "fallback": list(st.fallback), "samples": st.samples,
                                 "horizon_s": st.horizon_s})
                in_outage = True
            c0 = time.process_time()
            action = bridge.on_outage(epoch)
            pred_s.append(time.process_time() - c0)
            if isinstance(action, OutputCorrection):
                current = action.pos_ned_m
                events.append((epoch.time_us, current))
        else:
            bridge.on_gnss_restored(epoch)
            in_outage = False
            if current is not None:
                # cleared after this epoch's estimate (the filter leaves the outage in
                # _fuse_gnss, after the estimate of the same IMU epoch when the fix comes
                # separately)
                events.append((epoch.time_us + 1, None))
            current = None
    corr = np.zeros((len(rec.est_t_us), 3))
    times = [e[0] for e in events]
    for i, t in enumerate(rec.est_t_us):
        j = bisect.bisect_right(times, t) - 1
        if j >= 0 and events[j][1] is not None:
            corr[i] = events[j][1]
    return Replayed(corr, fit_s, fit_cpu_s, fit_pairs, pred_s, statuses)


def pseudo_fixes_in_replay(bridge: Any, rec: Recorded) -> int:
    """Replay the recorded hooks into a pseudo-GNSS strategy up to its first pseudo-fix;
    returns 1 if it sends one (the recording no longer matches its filter from there), else 0.
    """
    from fusion.bridging.interface import PseudoGnss

    for kind, epoch, error in rec.hooks:
        if kind == "g":
            bridge.on_gnss(epoch, error)
        elif kind == "o":
            if isinstance(bridge.on_outage(epoch), PseudoGnss):
                return 1
        else:
            bridge.on_gnss_restored(epoch)
    return 0


# ------------------------------------------------------------------------------ scoring
def outage_scores(t_us: Any, pos_err: Any, fix_t_s: list[float]) -> list[dict[str, Any]]:
    """Per planned outage: horizontal RMSE, max, error at its end and at 25 / 60 s."""
    import numpy as np

    from scenarios import metrics

    t = np.asarray(t_us, dtype=float) * 1e-6
    end = float(t[-1])
    windows = metrics.outages_from_fix_times(np.asarray(fix_t_s), end_s=end)
    h = np.hypot(pos_err[:, 0], pos_err[:, 1])
    out = []
    for start, dur in OUTAGES:
        match = [w for w in windows if abs(w.start_s - start) < 1.0]
        if not match:
            out.append({"start_s": start, "duration_s": dur, "missing": True})
            continue
        w = match[0]
        m = w.mask(t)
        hh, tt = h[m], t[m] - w.start_s
        row: dict[str, Any] = {"start_s": start, "duration_s": dur,
               "window_s": [w.start_s, w.end_s],
               "h_rmse_m": metrics.rms(hh), "h_max_m": float(hh.max()),
               "h_end_m": float(hh[-1])}
        for at in (25, 60):
            if at <= dur:
                row[f"h_at_{at}s_m"] = float(np.interp(at, tt, hh))
        out.append(row)
    return out


def ratios(base: list[dict[str, Any]], meth: list[dict[str, Any]]) -> dict[str, Any]:
    r25 = [m["h_rmse_m"] / b["h_rmse_m"] for b, m in zip(base, meth, strict=True)
           if b["duration_s"] == 25 and "h_rmse_m" in b and "h_rmse_m" in m]
    r60 = [m["h_at_60s_m"] / b["h_at_60s_m"] for b, m in zip(base, meth, strict=True)
           if b["duration_s"] >= 60 and "h_at_60s_m" in b and "h_at_60s_m" in m]
    return {"rmse_25s_ratios": r25, "at_60s_ratios": r60}


# ------------------------------------------------------------------------------ one flight
def make(method: str, overrides: dict[str, Any]) -> Any:
    """``make_bridge(method)`` with some settings changed (the others: method defaults)."""
    from fusion.bridging.registry import make_bridge
    from fusion.config import BridgeConfig

    return make_bridge(method, BridgeConfig(**overrides))


def run_flight(task: dict[str, Any]) -> dict[str, Any]:
    """Simulate, record, replay every variant, run gmdh-pseudo; one result row."""
    from fusion.config import BridgeConfig

    plan, seed = task["plan"], task["seed"]
    t_start = time.perf_counter()
    cache = Path(task["cache"]) if task.get("cache") else None
    loaded: list[Any] = []

    def items_fn() -> list[Any]:  # the flight is loaded only when a filter pass needs it
        if not loaded:
            loaded.append(simulate(plan, seed, cache))
        return loaded[0]

    if task.get("check") or task.get("step_cost"):
        items_fn()
    sim_wall = time.perf_counter() - t_start
    cfg = BridgeConfig()
    rec = record(items_fn, cfg.virtual_outage_s, cfg.virtual_outage_count, cache,
                 f"{plan}_{seed}")  # fmt: skip
    base = outage_scores(rec.est_t_us, rec.err_pos, rec.fix_t_s)
    row: dict[str, Any] = {
        "plan": plan, "seed": seed, "sim_wall_s": sim_wall,
        "filter_cpu_s_recording": rec.filter_cpu_s, "imu_samples": rec.imu_samples,
        "methods": {"none": {"outages": base}},
    }
    variants: dict[str, tuple[str, dict[str, Any]]] = dict(task["variants"])
    for name, (method, overrides) in variants.items():
        bridge = make(method, overrides)
        t0 = time.process_time()
        rp = replay_hooks(bridge, rec)
        cpu = time.process_time() - t0
        scores = outage_scores(rec.est_t_us, rec.err_pos - rp.corr, rec.fix_t_s)
        row["methods"][name] = {
            "outages": scores, **ratios(base, scores), "replay_cpu_s": cpu,
            "fits": len(rp.fit_s),
            "fit_ms_median": 1e3 * statistics.median(rp.fit_s) if rp.fit_s else None,
            "fit_ms_max": 1e3 * max(rp.fit_s) if rp.fit_s else None,
            "fit_cpu_ms": [round(1e3 * x, 2) for x in rp.fit_cpu_s],
            "fit_pairs_max": max(rp.fit_pairs) if rp.fit_pairs else None,
            "predict_cpu_us_median": (1e6 * statistics.median(rp.predict_cpu_s)
                                      if rp.predict_cpu_s else None),
            "outages_active": [sum(1 for f in st["fallback"] if not f)
                               for st in rp.status_at_outage],
            "status_at_outage_start": rp.status_at_outage,
        }
    if task.get("pseudo"):
        # Until gmdh-pseudo sends its first pseudo-fix the filter is the recorded one (same
        # virtual outages, nothing fused): replay it first, and run the full filter pass only when
        # it would send one; otherwise its run *is* the recording, bit for bit.
        fixes_sent = pseudo_fixes_in_replay(make("gmdh-pseudo", {}), rec)
        if fixes_sent:
            err, t_us, fixes, cpu = run_filter(items_fn(), make("gmdh-pseudo", {}))
            scores = outage_scores(t_us, err.pos_ned_m, fixes)
        else:
            scores, cpu = base, 0.0
        row["methods"]["gmdh-pseudo"] = {"outages": scores, **ratios(base, scores),
                                         "filter_cpu_s": cpu,
                                         "pseudo_fixes_in_replay": fixes_sent,
                                         "full_filter_pass": bool(fixes_sent)}
    if task.get("check"):
        err, t_us, fixes, cpu = run_filter(items_fn(), make("gmdh", {}))
        ref = row["methods"]["gmdh"]["outages"]
        real = outage_scores(t_us, err.pos_ned_m, fixes)
        diffs = [abs(a["h_rmse_m"] - b["h_rmse_m"]) for a, b in zip(ref, real, strict=True)
                 if "h_rmse_m" in a and "h_rmse_m" in b]
        row["equivalence_check"] = {"max_abs_rmse_diff_m": max(diffs) if diffs else None,
                                    "filter_cpu_s_with_gmdh": cpu}
    if task.get("step_cost"):
        _err, _t, _f, cpu = run_filter(items_fn(), None)
        row["filter_cpu_s_none"] = cpu
    row["wall_s"] = time.perf_counter() - t_start
    return row


def _run_star(task: dict[str, Any]) -> dict[str, Any]:
    try:
        row = run_flight(task)
    except Exception as exc:  # a failed run is reported, not allowed to sink the others
        row = {"plan": task["plan"], "seed": task["seed"], "error": f"{type(exc).__name__}: {exc}"}
    g = row.get("methods", {}).get("gmdh", {})
    print(f"  {task['plan']:13s} seed {task['seed']:4d}: gmdh/none 25 s "
          f"{[round(r, 2) for r in g.get('rmse_25s_ratios', [])]}, 60 s "
          f"{[round(r, 2) for r in g.get('at_60s_ratios', [])]} ({row.get('wall_s', 0):.0f} s)",
          flush=True)
    return row


# ------------------------------------------------------------------------------ costs
def _synthetic_stream(n: int, seed: int = 0) -> list[tuple[Any, Any]]:
    """``n`` GNSS epochs at 100 Hz, each with one virtual-outage pair of a known drift law
    (a t^2 along the heading, a turning aircraft, 60 s outages)."""
    import numpy as np

    from fusion.bridging.interface import BridgeEpoch, InsError, VirtualOutage

    rng = np.random.default_rng(seed)
    lat0, lon0 = math.radians(47.0), math.radians(8.0)

    def epoch(t_us: int, el: float, yaw: float) -> BridgeEpoch:
        return BridgeEpoch(
            t_us, lat0 + 1e-7 * t_us * 1e-4, lon0, 1000.0,
            (50.0 * math.cos(yaw), 50.0 * math.sin(yaw), 0.0), (0.0, 0.0, yaw),
            (0.3, -0.2, -9.8), (0.0, 0.0, 0.01), el, (1e-3, -1e-3, 0.0), (1e-5, 0.0, 2e-5))

    out = []
    start = epoch(0, 0.0, 0.0)
    for i in range(n):
        el = (i % 6000) * 0.01
        yaw = 0.05 * el
        ep = epoch(i * 10_000, el, yaw)
        a = 0.01 * el * el
        noise = rng.normal(0.0, 0.3, 6)
        v = VirtualOutage(
            0, el, start, ep,
            (a * math.cos(yaw) + noise[0], a * math.sin(yaw) + noise[1], 0.1 * a + noise[2]),
            (0.02 * el + 0.1 * noise[3], 0.01 * el + 0.1 * noise[4], 0.002 * el + 0.1 * noise[5]),
        )  # fmt: skip
        out.append((ep, InsError((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), True, True, (v,))))
    return out


def cost_benchmarks(repeats: int = 5) -> dict[str, Any]:
    """GMDH refit on 60 s of 100 Hz pairs (one component, all six) and one prediction call."""
    from fusion.bridging.registry import make_bridge
    from fusion.config import BridgeConfig

    n = 6000
    stream = _synthetic_stream(n + 6)
    cfg = BridgeConfig(window_s=1e4, max_samples=n, min_samples=n, min_horizon_s=0.0,
                       warmup_s=0.0, refit_period_s=1e4)
    one: list[float] = []
    six: list[float] = []
    pred: list[float] = []
    pairs = 0
    for _ in range(repeats):
        bridge: Any = make_bridge("gmdh", cfg)
        for ep, er in stream[: n - 1]:
            bridge.on_gnss(ep, er)
        fits = []
        for ep, er in stream[n - 1 : n + 5]:  # one component fit per call in the first round
            t0 = time.process_time()
            bridge.on_gnss(ep, er)
            fits.append(time.process_time() - t0)
        pairs = bridge.status.last_fit_samples
        one.append(statistics.median(fits))
        six.append(sum(fits))
        ep = stream[n // 2][0]
        m = 2000
        t0 = time.process_time()
        for _ in range(m):
            bridge.on_outage(ep)
        pred.append((time.process_time() - t0) / m)
        active = 6 - sum(bridge.status.fallback)
    return {
        "pairs": n, "pairs_used_by_a_fit": pairs,
        "refit_one_component_ms": 1e3 * statistics.median(one),
        "refit_six_components_ms": 1e3 * statistics.median(six),
        "refit_note": ("one fit per component refit (the fallback gate judges it later on "
                       "held-out virtual outages, no validation refit); the components take "
                       "turns, one per refit tick"),
        "predict_call_us": 1e6 * statistics.median(pred),
        "predict_active_components": active,
    }


def _pool_map(tasks: list[dict[str, Any]], jobs: int) -> list[dict[str, Any]]:
    if jobs == 1:
        return [_run_star(t) for t in tasks]
    with mp.get_context("spawn").Pool(jobs) as pool:
        return list(pool.imap(_run_star, tasks))


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per method: summed-RMSE ratio and mean / worst ratio over the 25 s outages, and the
    ratio of the errors 60 s into the 60 s outages (sum and per flight)."""
    import numpy as np

    good = [r for r in rows if "error" not in r]
    names = sorted({m for r in good for m in r["methods"]} - {"none"})
    out: dict[str, Any] = {}
    for name in names:
        num25 = den25 = num60 = den60 = 0.0
        r25: list[float] = []
        r60: list[float] = []
        fit_ms: list[float] = []
        pred_us: list[float] = []
        by_plan: dict[str, list[float]] = {}
        gains: list[dict[str, Any]] = []
        flights = 0
        for r in good:
            if name not in r["methods"]:
                continue
            flights += 1
            rm = r["methods"][name]
            fit_ms.extend(rm.get("fit_cpu_ms", []))
            if rm.get("predict_cpu_us_median") is not None:
                pred_us.append(rm["predict_cpu_us_median"])
            base, meth = r["methods"]["none"]["outages"], r["methods"][name]["outages"]
            for b, m in zip(base, meth, strict=True):
                if "h_rmse_m" not in b or "h_rmse_m" not in m:
                    continue
                if b["duration_s"] == 25:
                    num25 += m["h_rmse_m"]
                    den25 += b["h_rmse_m"]
                    ratio = m["h_rmse_m"] / b["h_rmse_m"]
                    r25.append(ratio)
                    by_plan.setdefault(r["plan"], []).append(ratio)
                    if ratio < 0.9:
                        gains.append({"plan": r["plan"], "seed": r["seed"],
                                      "start_s": b["start_s"], "ratio": ratio})
                elif "h_at_60s_m" in b:
                    num60 += m["h_at_60s_m"]
                    den60 += b["h_at_60s_m"]
                    r60.append(m["h_at_60s_m"] / b["h_at_60s_m"])
        out[name] = {
            "flights": flights,
            "outages_25s": len(r25),
            "rmse_25s_ratio_of_sums": num25 / den25 if den25 else None,
            "rmse_25s_ratio_mean": statistics.mean(r25) if r25 else None,
            "rmse_25s_ratio_median": statistics.median(r25) if r25 else None,
            "rmse_25s_ratio_worst": max(r25) if r25 else None,
            "rmse_25s_ratio_p95": float(np.percentile(r25, 95)) if r25 else None,
            "rmse_25s_ratio_mean_by_plan": {k: statistics.mean(v) for k, v in by_plan.items()},
            "outages_25s_better_than_0_9x": gains,
            "outages_25s_changed": sum(1 for x in r25 if abs(x - 1.0) > 1e-9),
            "fit_cpu_ms_median": statistics.median(fit_ms) if fit_ms else None,
            "fit_cpu_ms_max": max(fit_ms) if fit_ms else None,
            "fits": len(fit_ms),
            "predict_call_cpu_us_median": statistics.median(pred_us) if pred_us else None,
            "rmse_25s_outages_worse_than_1_2x": sum(1 for x in r25 if x > 1.2),
            "none_rmse_25s_mean_m": den25 / len(r25) if r25 else None,
            "method_rmse_25s_mean_m": num25 / len(r25) if r25 else None,
            "error_at_60s_ratio_of_sums": num60 / den60 if den60 else None,
            "error_at_60s_ratio_worst": max(r60) if r60 else None,
            "error_at_60s_ratio_mean": statistics.mean(r60) if r60 else None,
            "none_error_at_60s_mean_m": den60 / len(r60) if r60 else None,
            "method_error_at_60s_mean_m": num60 / len(r60) if r60 else None,
        }
    return out


def _table(summary: dict[str, Any]) -> str:
    lines = [f"{'method':18s} {'flights':>7s} {'25s ratio':>9s} {'mean':>6s} {'p95':>6s} "
             f"{'worst':>6s} {'>1.2x':>5s} {'<0.9x':>5s} {'none m':>7s} {'meth m':>7s} "
             f"{'@60 ratio':>9s} {'none@60':>8s} {'fit ms':>7s} {'max':>7s}"]
    for name, s in summary.items():
        def f(v: Any, spec: str = ".2f") -> str:
            return "n/a" if v is None else format(v, spec)
        lines.append(
            f"{name:18s} {s['flights']:7d} {f(s['rmse_25s_ratio_of_sums']):>9s} "
            f"{f(s['rmse_25s_ratio_mean']):>6s} {f(s['rmse_25s_ratio_p95']):>6s} "
            f"{f(s['rmse_25s_ratio_worst']):>6s} "
            f"{s['rmse_25s_outages_worse_than_1_2x']:5d} "
            f"{len(s['outages_25s_better_than_0_9x']):5d} "
            f"{f(s['none_rmse_25s_mean_m'], '.1f'):>7s} "
            f"{f(s['method_rmse_25s_mean_m'], '.1f'):>7s} {f(s['error_at_60s_ratio_of_sums']):>9s} "
            f"{f(s['none_error_at_60s_mean_m'], '.1f'):>8s} {f(s['fit_cpu_ms_median'], '.1f'):>7s} "
            f"{f(s['fit_cpu_ms_max'], '.1f'):>7s}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--seed-base", type=int, default=100)
    ap.add_argument("--plans", default=HELD_OUT_PLANS)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--full-methods-seeds", type=int, default=None,
                    help="run the P0-input variants on the first K seeds only (default all)")
    ap.add_argument("--check-equivalence", type=int, default=1)
    ap.add_argument("--tune", action="store_true",
                    help="feature/setting search on the tuning seeds 1-5 of racetrack, survey")
    ap.add_argument("--tune-gate", action="store_true",
                    help="fallback-gate search on the tuning seeds 1-5 of racetrack, survey")
    ap.add_argument("--no-pseudo", action="store_true", help="skip gmdh-pseudo (quick checks)")
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=Path("bench/results/bridging.json"))
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.jobs < 1:
        ap.error("--seeds and --jobs must be >= 1")
    cache = None if args.cache is None else str(args.cache)
    if args.tune_gate:
        plans = [p for p in TUNING_PLANS.split(",")]
        seeds = list(range(1, 6))
        variants: dict[str, tuple[str, dict[str, Any]]] = {}
        for meth in TUNING_GATE_METHODS:
            for gate in TUNING_GATES:
                key = ",".join(f"{k.removeprefix('gate_')}={v:g}" for k, v in gate.items())
                variants[f"{meth}:{key}"] = (meth, dict(gate))
        tasks = [{"plan": p, "seed": s, "variants": variants, "cache": cache}
                 for p in plans for s in seeds]
    elif args.tune:
        plans = [p for p in TUNING_PLANS.split(",")]
        seeds = list(range(1, 6))
        variants = {}
        for fs in TUNING_FEATURES:
            variants["gmdh:" + ",".join(fs)] = ("gmdh", {"features": fs})
        for setting in TUNING_SETTINGS[1:]:
            key = ",".join(f"{k}={v}" for k, v in setting.items())
            variants["gmdh:default-features:" + key] = ("gmdh", dict(setting))
        tasks = [{"plan": p, "seed": s, "variants": variants, "cache": cache}
                 for p in plans for s in seeds]
    else:
        plans = [p.strip() for p in args.plans.split(",") if p.strip()]
        seeds = list(range(args.seed_base, args.seed_base + args.seeds))
        tasks = []
        for p in plans:
            for i, s in enumerate(seeds):
                variants = dict(FAST_VARIANTS)
                if args.full_methods_seeds is None or i < args.full_methods_seeds:
                    variants.update(P0_VARIANTS)
                tasks.append({"plan": p, "seed": s, "variants": variants, "cache": cache,
                              "pseudo": not args.no_pseudo,
                              "check": p == plans[0] and i < args.check_equivalence,
                              "step_cost": p == plans[0] and i == 0})
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    print(f"{len(tasks)} flights ({len(plans)} plans x {len(seeds)} seeds) on {args.jobs} "
          "process(es)", flush=True)
    costs = None if args.tune or args.tune_gate else cost_benchmarks()
    rows = _pool_map(tasks, args.jobs)
    wall = time.perf_counter() - t0
    summary = summarise(rows)

    import numpy as np

    from fusion.bridging.registry import DEFAULT_FEATURES
    from fusion.config import BridgeConfig

    good = [r for r in rows if "error" not in r]
    step = [r["filter_cpu_s_none"] / r["imu_samples"] for r in good if "filter_cpu_s_none" in r]
    virtual = [r["filter_cpu_s_recording"] / r["imu_samples"] for r in good]
    check = [r["equivalence_check"] for r in good if "equivalence_check" in r]
    if costs is not None and step:
        costs["filter_step_us_none"] = 1e6 * step[0]
        costs["filter_step_us_with_virtual_outages"] = 1e6 * statistics.mean(virtual)
        costs["predict_over_filter_step"] = costs["predict_call_us"] / costs["filter_step_us_none"]
        costs["predict_per_imu_sample_over_filter_step"] = (
            costs["predict_over_filter_step"] * BridgeConfig().rate_hz / 200.0)
        if check:
            costs["filter_step_us_gmdh_in_loop"] = 1e6 * check[0]["filter_cpu_s_with_gmdh"] / (
                good[0]["imu_samples"])
    result: dict[str, Any] = {
        "benchmark": "bridging",
        "mode": "tune-gate" if args.tune_gate else "tune" if args.tune else "held-out",
        "imu": IMU, "gnss": GNSS, "duration_s": DURATION_S, "plans": plans, "seeds": seeds,
        "seeds_note": ("tuning seeds" if args.tune else
                       "held-out seeds and plans (defaults chosen with --tune on seeds 1-5 of "
                       "racetrack, survey)"),
        "outages": [{"start_s": s, "duration_s": d} for s, d in OUTAGES],
        "bridge_config": BridgeConfig().model_dump(),
        "default_features": {k: list(v) for k, v in DEFAULT_FEATURES.items()},
        "targets": TARGETS,
        "costs": costs,
        "equivalence_check": check,
        "summary": summary,
        "machine": {
            "python": platform.python_version(), "numpy": np.__version__,
            "cpu_count": os.cpu_count(), "jobs": args.jobs,
            "load_average_at_start": list(load0), "load_average_at_end": list(os.getloadavg()),
        },
        "wall_s": wall,
        "runs": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from scenarios.jsonable import json_safe

    args.out.write_text(json.dumps(json_safe(result), indent=1) + "\n")
    for r in rows:
        if "error" in r:
            print(f"FAILED {r['plan']} seed {r['seed']}: {r['error']}", file=sys.stderr)
    print(_table(summary))
    if costs:
        print({k: v for k, v in costs.items() if not isinstance(v, str)})
    if check:
        print("equivalence (replay vs real filter):", check)
    print(f"wall {wall:.0f} s, load {load0} -> {os.getloadavg()} -> {args.out}")
    return 1 if len(good) < len(rows) else 0


if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
