"""Benchmark: building and encoding a ``fusion/estimate`` payload, base revision vs this tree,
in one process (issue 15, live latency).

The estimate is built in the filter's thread right after the filter step, 25 times a second:
on the live path the code runs cold (caches taken by the other threads and processes between
two estimates), where it costs several times its hot-loop time. So each variant is timed
alternately on the same 200 real estimates (a 40 s racetrack flight through the filter) both
back to back (hot) and with a 20 ms pause before each call (cold, as live at 25 Hz).
``hil/bus/payloads.py`` of the base is loaded from git next to the working tree's; both must
give the same bytes (checked).

    python bench/payload_ab.py --base 42eb08f --out bench/results/payload_ab.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hot_path_ab import base_module

from hil.bus import payloads as new_payloads
from hil.pipeline import FusionRun, SimSetup, filter_config, fly
from sim.presets import gnss_preset


def estimates(n: int) -> list[Any]:
    """The last ``n`` aligned estimates of a 40 s racetrack flight through the filter."""
    frames: list[bytes] = []
    fly(SimSetup.build(plan="racetrack", duration_s=40.0, seed=1),
        lambda _t, f: frames.append(f))
    run = FusionRun(filter_config("industrial-mems", gnss_preset("modern"), "ekf", "on",
                                  "auto"), "none", collect=False)
    out = [e for f in frames for e in run.feed_frame(f) if e.mode != "initializing"]
    return out[-n:]


def time_us(fn: Callable[[Any], Any], items: list[Any], pause_s: float) -> list[float]:
    out = []
    for item in items:
        if pause_s:
            time.sleep(pause_s)
        t0 = time.perf_counter_ns()
        fn(item)
        out.append((time.perf_counter_ns() - t0) / 1000)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", default="42eb08f", help="git revision of the base")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("bench/results/payload_ab.json"))
    args = ap.parse_args()
    base = base_module(args.base, "hil/bus/payloads.py", "payloads_base")
    ests = estimates(200)
    fns = {"base": lambda e: base.encode(base.estimate_payload(e)),
           "new": lambda e: new_payloads.encode(new_payloads.estimate_payload(e))}
    identical = all(fns["base"](e) == fns["new"](e) for e in ests)
    result: dict[str, Any] = {"benchmark": "payload_ab", "base": args.base,
                              "python": platform.python_version(), "load_start":
                              [round(x, 2) for x in os.getloadavg()],
                              "identical_bytes": identical, "estimates": len(ests)}
    for mode, pause_s in (("hot", 0.0), ("cold_20ms_pause", 0.02)):
        samples: dict[str, list[float]] = {"base": [], "new": []}
        for r in range(args.rounds):
            for name in ("base", "new") if r % 2 == 0 else ("new", "base"):
                samples[name] += time_us(fns[name], ests, pause_s)
        result[mode] = {name: {"median_us": round(float(np.median(v)), 2),
                               "p90_us": round(float(np.percentile(v, 90)), 2)}
                        for name, v in samples.items()}
        result[mode]["new_over_base_median"] = round(
            result[mode]["new"]["median_us"] / result[mode]["base"]["median_us"], 3)
    result["load_end"] = [round(x, 2) for x in os.getloadavg()]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=1))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
