"""Benchmark: GMDH refit and prediction cost, with the neural comparators'
fit cost.

Data: 60 s of 100 Hz samples (6000 rows) of smooth, noisy INS-like features (4, 6 and 8
columns) and a nonlinear target. Measures, for the regressor defaults and for P0's preset
(``GmdhRegressor.paper()``), the median wall time of ``fit``, of ``predict_one`` (single
sample, the filter's path), of a batch ``predict`` per sample, and of ``predict`` on one row;
and the refit on the bridging training window (``BridgeConfig.max_samples`` = 3000 pairs of
the 4 bridging features, the bridges' settings ``paper(split="tail", ridge=1e-6)``, and the
defaults on the same window). Targets: refit <= 50 ms;
single-sample predict <= 0.3 x a filter step (30-50 us), i.e. <= 9-15 us.

    python bench/gmdh_speed.py --out bench/results/gmdh_speed.json [--blas-threads 1]

``--blas-threads`` sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS before numpy loads: on a busy
2-core machine OpenBLAS's second thread can make small GEMMs 10-100x slower.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any


def _synthetic(n: int, n_features: int, seed: int) -> tuple[Any, Any]:
    import numpy as np

    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    cols = [
        np.sin(2 * np.pi * (0.01 + 0.013 * k) * t + k) + 0.05 * rng.normal(size=n)
        for k in range(n_features)
    ]
    X = np.column_stack(cols)
    y = X[:, 0] * X[:, 1] + 0.5 * X[:, 2] ** 2 - X[:, 3] + 0.01 * rng.normal(size=n)
    return X, y


def _median_s(fn: Any, repeats: int) -> tuple[float, float]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times)


def _median_cpu_s(fn: Any, repeats: int) -> float:
    """Median process CPU time (less disturbed than wall time by other jobs on the machine;
    with one BLAS thread it is the fit's own compute)."""
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return statistics.median(times)


def _time_gmdh(model: Any, X: Any, y: Any, args: argparse.Namespace) -> dict[str, Any]:
    model.fit(X, y)  # warm-up
    fit_med, fit_min = _median_s(lambda: model.fit(X, y), args.repeats)
    entry: dict[str, Any] = {
        "fit_ms_median": fit_med * 1e3,
        "fit_ms_min": fit_min * 1e3,
        "fit_cpu_ms_median": _median_cpu_s(lambda: model.fit(X, y), args.repeats) * 1e3,
        "n_layers": model.n_layers_,
        "neurons_in_pruned_network": int(sum(len(layer.pairs) for layer in model.network_)),
        "r2_train": model.score(X, y),
    }
    x = X[123].copy()
    n_single = 20000
    one_med, _ = _median_s(lambda: [model.predict_one(x) for _ in range(n_single)], 5)
    entry["predict_one_us"] = one_med / n_single * 1e6
    batch_med, _ = _median_s(lambda: model.predict(X), 20)
    entry["predict_batch_us_per_sample"] = batch_med / len(X) * 1e6
    n_row = 2000
    row_med, _ = _median_s(lambda: [model.predict(X[5:6]) for _ in range(n_row)], 3)
    entry["predict_one_row_via_predict_us"] = row_med / n_row * 1e6
    return entry


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=6000)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--blas-threads", type=int, default=None)
    ap.add_argument("--narx-nfev", type=int, default=10,
                    help="LM evaluations for the NarxMLP timing (35 hidden, P1)")
    ap.add_argument("--out", type=Path, default=Path("bench/results/gmdh_speed.json"))
    args = ap.parse_args()
    if args.blas_threads is not None:
        os.environ["OPENBLAS_NUM_THREADS"] = str(args.blas_threads)
        os.environ["OMP_NUM_THREADS"] = str(args.blas_threads)

    import numpy as np

    from fusion.gmdh import GmdhRegressor
    from fusion.regressors import BpNet, NarxMLP, RbfNet

    result: dict[str, Any] = {
        "benchmark": "gmdh_speed",
        "samples": args.samples,
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
        "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                    "numpy": np.__version__, "load_average_1min_at_start": os.getloadavg()[0]},
        "targets": {"fit_ms": 50.0, "predict_one_us": "<= 0.3 x filter step (9-15 us)"},
        "gmdh": {},
    }

    presets = {"default": GmdhRegressor, "paper": GmdhRegressor.paper}
    for preset, make in presets.items():
        result["gmdh"][preset] = {}
        for n_features in (4, 6, 8):
            X, y = _synthetic(args.samples, n_features, seed=n_features)
            result["gmdh"][preset][f"{n_features}_features"] = _time_gmdh(make(), X, y, args)
    X, y = _synthetic(3000, 4, seed=4)
    result["bridging_window_3000x4"] = {
        "bridge_settings_fit_ms_median": _median_s(
            lambda: GmdhRegressor.paper(split="tail", ridge=1e-6).fit(X, y), args.repeats
        )[0] * 1e3,
        "default_fit_ms_median": _median_s(lambda: GmdhRegressor().fit(X, y), args.repeats)[0]
        * 1e3,
        "bridge_settings_fit_cpu_ms_median": _median_cpu_s(
            lambda: GmdhRegressor.paper(split="tail", ridge=1e-6).fit(X, y), args.repeats
        ) * 1e3,
        "default_fit_cpu_ms_median": _median_cpu_s(lambda: GmdhRegressor().fit(X, y), args.repeats)
        * 1e3,
    }

    X, y = _synthetic(args.samples, 6, seed=6)
    others: dict[str, Any] = {}
    for name, model_other in [
        ("RbfNet()", RbfNet()),
        ("BpNet()", BpNet()),
        (f"NarxMLP(max_nfev={args.narx_nfev})", NarxMLP(max_nfev=args.narx_nfev)),
    ]:
        t0 = time.perf_counter()
        model_other.fit(X, y)
        fit_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        model_other.predict(X)
        pred_s = time.perf_counter() - t0
        others[name] = {
            "fit_ms": fit_s * 1e3,
            "predict_batch_us_per_sample": pred_s / len(X) * 1e6,
            "r2_train": model_other.score(X, y),
        }
        if isinstance(model_other, NarxMLP):
            others[name]["lm_evaluations"] = model_other.n_iter_
            others[name]["fit_ms_per_lm_evaluation"] = fit_s * 1e3 / model_other.n_iter_
    result["comparators_6_features"] = others

    result["machine"]["load_average_1min_at_end"] = os.getloadavg()[0]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
