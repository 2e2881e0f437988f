"""Benchmark: a million hostile frames through decoder + filter.

Per seed, a synthetic flight (tests/helpers/nav_synth.py: turns, climbs, speed changes;
sensor errors from the filter's own model; IMU 100 Hz, GNSS 5 Hz, baro 25 Hz, mag 10 Hz) is
encoded as the simulator sends it. Attack windows of ``--window`` s start every ``--period``
s: inside them every frame is byte-mutated (1-3 bytes) and one CRC-valid hostile frame
(tests/helpers/hostile.py: NaN / inf / 1e30 fields, stamps +-1 h, 2^64-1 or 0, GNSS at the
int32 limits, 327 m/s) follows each, all from the legitimate source address. The same flight is
also run clean. Counted: frames fed, exceptions (the run stops at the first), non-finite
estimates, and per attack window the *recovery time*: from the window's end until the filter
is GNSS-aided and within 2 m of the clean run's horizontal error from then on, up to the next
window (``recovered``: within ``--recover`` s; ``never_recovered``: not before the next window),
and the worst excess over the clean run in that span.

    python bench/fuzz.py [--seeds 1-40] [--duration 600] [--period 90] [--window 30]
        [--recover 30] [--jobs 2] [--out bench/results/fuzz.json]

With every frame of a window mutated, almost no legitimate IMU frame survives its CRC, and the
hostile frames' stamps alone can form a consistent run: the filter then takes a new time base
(``time_rebases``) and re-aligns when the real stream returns. That is the design (a
consistent time base is believed; only MAVLink 2 signing can tell an impostor on the
legitimate address from the real sender); the count is reported.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def run_one(job: tuple[int, float, float, float, float]) -> dict[str, Any]:
    """One seed: the attacked and the clean run of one flight."""
    import numpy as np

    from fusion.config import FilterConfig
    from fusion.filter import NavFilter
    from hil.codec import Decoder
    from tests.helpers.hostile import encode, horizontal_error_m, hostile_frame, mutate, sender
    from tests.helpers.nav_synth import Flight, SensorErrors, make_scenario

    seed, duration_s, period_s, window_s, recover_s = job
    n_turns = int(duration_s // 60)
    flight = Flight(
        duration_s=duration_s,
        turns=[(60.0 * k + 10.0, 60.0 * k + 25.0, 0.15 * (-1) ** k) for k in range(n_turns)],
        climbs=[(60.0 * k + 30.0, 60.0 * k + 40.0, 2.0 * (-1) ** k) for k in range(n_turns)],
        speed_wave_mps=3.0,
    )
    cfg = FilterConfig()
    sc = make_scenario(flight, np.random.default_rng(seed), SensorErrors.from_config(cfg),
                       mag_rate_hz=10.0)  # fmt: skip
    frames = encode(sc.samples)
    rng = np.random.default_rng(10_000 + seed)
    mav = sender()
    windows = [(t, t + window_s) for t in np.arange(period_s / 2, duration_s - recover_s
                                                    - window_s, period_s)]
    stream: list[bytes] = []
    mutated = hostile = 0
    for t_us, frame in frames:
        t = t_us * 1e-6
        if any(a <= t < b for a, b in windows):
            stream.append(mutate(rng, frame))
            stream.append(hostile_frame(rng, t_us, mav))
            mutated += 1
            hostile += 1
        else:
            stream.append(frame)

    def horizontal(e: Any) -> float:
        return horizontal_error_m(sc, e)

    def fly(data: list[bytes]) -> tuple[list[Any], str | None, float, Any]:
        nav, dec = NavFilter(cfg), Decoder()
        est: list[Any] = []
        t0 = time.process_time()
        try:
            for f in data:
                for d in dec.feed(f):
                    est.extend(nav.step(d.sample))
        except Exception as err:  # the bench counts them
            return est, f"{type(err).__name__}: {err}", time.process_time() - t0, nav
        return est, None, time.process_time() - t0, nav

    est, error, cpu_s, nav = fly(stream)
    clean, _, _, _ = fly([f for _, f in frames])
    non_finite = sum(
        1 for e in est
        if not (np.all(np.isfinite(e.v_ned_mps)) and np.all(np.isfinite(e.P_diag))
                and math.isfinite(e.lat_rad) and math.isfinite(e.lon_rad))
    )  # fmt: skip
    t_clean = np.array([e.time_us for e in clean], dtype=np.int64)
    err_clean = np.array([horizontal(c) for c in clean])

    def clean_error_near(time_us: int) -> float:
        """The clean run's error at its estimate nearest in time (the earlier one on a tie)."""
        k = int(np.searchsorted(t_clean, time_us))
        if k == len(t_clean) or (k > 0 and time_us - t_clean[k - 1] <= t_clean[k] - time_us):
            k -= 1
        return float(err_clean[k])
    recovery_s: list[float | None] = []
    worst_m: list[float] = []
    ends = [w[0] for w in windows[1:]] + [duration_s]
    for (_a, b), nxt in zip(windows, ends, strict=True):
        # from the window's end to the next window: the time after which the attacked run
        # stays GNSS-aided and within 2 m of the clean run's error (the clean estimate nearest
        # in time; the output grid may have moved), None if it never settles before the next
        # window; and its worst excess over the clean run in that span
        settled: float | None = 0.0
        worst = 0.0
        for e in est:
            t = e.time_us * 1e-6
            if not b <= t < nxt:
                continue
            excess = horizontal(e) - clean_error_near(e.time_us)
            worst = max(worst, excess)
            if e.mode != "gnss" or excess > 2.0:
                settled = None
            elif settled is None:
                settled = t - b
        recovery_s.append(settled)
        worst_m.append(worst)
    recovered = sum(1 for r in recovery_s if r is not None and r <= recover_s)
    return {
        "seed": seed, "frames": len(stream), "mutated": mutated, "hostile": hostile,
        "exception": error, "non_finite_estimates": non_finite, "estimates": len(est),
        "attack_windows": len(windows), "recovered": recovered, "recovery_s": recovery_s,
        "worst_excess_m": worst_m, "cpu_s": cpu_s,
        "frames_per_s_cpu": len(stream) / cpu_s if cpu_s > 0 else None,
        "health": {k: getattr(nav.health, k) for k in (
            "time_quarantined", "time_backwards", "time_rebases", "imu_nan", "imu_out_of_range",
            "gnss_invalid", "gnss_rejected", "gnss_resets", "gnss_resets_refused")},
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    import numpy as np

    from scenarios.jsonable import write_json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-40", help="comma-separated seeds or A-B ranges")
    ap.add_argument("--duration", type=float, default=600.0, help="simulated s per seed")
    ap.add_argument("--period", type=float, default=90.0, help="s between attack starts")
    ap.add_argument("--window", type=float, default=30.0, help="attack window, s")
    ap.add_argument("--recover", type=float, default=30.0,
                    help="s after a window at which recovery is judged")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "fuzz.json")
    args = ap.parse_args(argv)
    seeds: list[int] = []
    for part in (p.strip() for p in args.seeds.split(",") if p.strip()):
        lo, _, hi = part.partition("-")
        seeds += list(range(int(lo), int(hi or lo) + 1))
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    jobs = [(s, args.duration, args.period, args.window, args.recover) for s in seeds]
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(run_one, jobs))
    total = {
        "frames": sum(r["frames"] for r in rows),
        "mutated_frames": sum(r["mutated"] for r in rows),
        "hostile_frames": sum(r["hostile"] for r in rows),
        "exceptions": sum(r["exception"] is not None for r in rows),
        "non_finite_estimates": sum(r["non_finite_estimates"] for r in rows),
        "attack_windows": sum(r["attack_windows"] for r in rows),
        "recovered": sum(r["recovered"] for r in rows),
        "recovery_s_median": float(np.median([x for r in rows for x in r["recovery_s"]
                                              if x is not None])),
        "recovery_s_max": max((x for r in rows for x in r["recovery_s"] if x is not None),
                              default=None),
        "never_recovered": sum(x is None for r in rows for x in r["recovery_s"]),
        "worst_excess_m_median": float(np.median([x for r in rows for x in r["worst_excess_m"]])),
        "frames_per_s_cpu": sum(r["frames"] for r in rows) / sum(r["cpu_s"] for r in rows),
        "time_rebases": sum(r["health"]["time_rebases"] for r in rows),
    }
    write_json({
        "bench": "fuzz", "seeds": seeds, "duration_s": args.duration, "period_s": args.period,
        "window_s": args.window, "recover_s": args.recover, "total": total, "rows": rows,
        "wall_s": time.perf_counter() - t0, "load_average": [list(load0), list(os.getloadavg())],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
    }, args.out)
    for k, v in total.items():
        print(f"{k:24s} {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
