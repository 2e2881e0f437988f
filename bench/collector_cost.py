"""What the live scorecard's collector costs per sample and per flight-hour of memory (#13).

One racetrack flight is flown and fused once; its estimates are recorded per input sample.
Then the collector alone is timed over the same samples with a stand-in filter that hands back
the recorded estimates (the filter's own cost is the same in every variant):

* ``objects``: what the collector did before compaction: append every estimate, truth
  sample and fix object to lists (measured with a minimal re-implementation of that loop);
* ``compact``: :class:`hil.tracks.Collector` (objects compacted into column chunks every
  ``CHUNK_ROWS``), chunks in memory (``hilnav run`` / ``replay``);
* ``spill``: the same, chunks spilled to an anonymous file (the live service's ``--out``).

The filter's own time per input sample (one pass) is reported beside them. For each:
microseconds per input sample (best of ``--repeat``), the longest single
``feed`` call (the compaction pause, ms), and bytes held per estimate (tracemalloc, objects
and columns in memory, with the truth samples and fixes the collector holds; the spill
file's bytes are on disk and reported apart as ``column_bytes_per_estimate``).

    python bench/collector_cost.py [--duration 300] [--repeat 5] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

from fusion.config import FilterConfig
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from hil.codec import Decoder
from hil.pipeline import SimSetup, filter_config, fly
from hil.tracks import CHUNK_ROWS, Collector
from sim.presets import gnss_preset
from sim.samples import GnssFix, Sample, Truth

ROOT = Path(__file__).resolve().parent.parent
CONFIG: FilterConfig = filter_config("industrial-mems", gnss_preset("modern"))


class _Recorded:
    """Stands in for the filter: returns the estimates the real one returned, in order, and
    its clock after each step."""

    def __init__(self, per_sample: list[list[NavEstimate]], clock_us: list[int],
                 config: FilterConfig) -> None:
        self._per_sample = per_sample
        self._clock_us = clock_us
        self.config = config
        self.time_us = 0
        self._k = 0

    def step(self, _sample: object) -> list[NavEstimate]:
        out = self._per_sample[self._k]
        self.time_us = self._clock_us[self._k]
        self._k += 1
        return out


class _ObjectLists:
    """The collector's loop before compaction (objects in lists)."""

    def __init__(self) -> None:
        self.estimates: list[NavEstimate] = []
        self.truths: list[Truth] = []
        self.fix_times_us: list[int] = []
        self.fixes: list[GnssFix] = []
        self.last_time_us = 0

    def feed(self, nav: Any, items: list[Sample | Truth]) -> None:
        for item in items:
            self.last_time_us = max(self.last_time_us, item.time_us)
            if isinstance(item, Truth):
                self.truths.append(item)
                continue
            if isinstance(item, GnssFix) and item.fix_type >= 3:
                self.fix_times_us.append(item.time_us)
                self.fixes.append(item)
            self.estimates.extend(nav.step(item))


def _flight(duration_s: float
            ) -> tuple[list[Sample | Truth], list[list[NavEstimate]], float]:
    frames: list[bytes] = []
    fly(SimSetup.build(duration_s=duration_s, seed=21, gnss_off=["120:60"]),
        lambda _t, f: frames.append(f))
    dec = Decoder()
    samples = [d.sample for f in frames for d in dec.feed(f)]
    nav = NavFilter(CONFIG)
    t0 = time.perf_counter()
    per_sample = [[] if isinstance(s, Truth) else nav.step(s) for s in samples]
    filter_s = time.perf_counter() - t0
    return samples, per_sample, filter_s


def _clocks(samples: list[Sample | Truth]) -> list[int]:
    """The filter's clock after each non-truth sample (a second pass, not timed)."""
    nav = NavFilter(CONFIG)
    out = []
    for s in samples:
        if not isinstance(s, Truth):
            nav.step(s)
            out.append(nav.time_us)
    return out


def _run(kind: str, samples: list[Sample | Truth], per_sample: list[list[NavEstimate]],
         clock_us: list[int], batch: int, spill_dir: Path) -> tuple[float, float, Any]:
    nav = _Recorded([p for s, p in zip(samples, per_sample, strict=True)
                     if not isinstance(s, Truth)], clock_us, CONFIG)
    col: Any = (_ObjectLists() if kind == "objects"
                else Collector(spill_dir=spill_dir if kind == "spill" else None))
    longest = 0.0
    t0 = time.perf_counter()
    for k in range(0, len(samples), batch):
        t1 = time.perf_counter()
        col.feed(nav, samples[k:k + batch])
        longest = max(longest, time.perf_counter() - t1)
    return time.perf_counter() - t0, longest, col


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0, help="simulated s")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--batch", type=int, default=20, help="samples per feed call")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "collector_cost.json")
    args = ap.parse_args(argv)
    samples, per_sample, filter_s = _flight(args.duration)
    clock_us = _clocks(samples)
    n_est = sum(len(p) for p in per_sample)
    # the objects stay alive in `per_sample` while timing; memory is measured apart below
    rows: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for kind in ("objects", "compact", "spill"):
            best, longest = float("inf"), 0.0
            for _ in range(args.repeat):
                wall, worst, col = _run(kind, samples, per_sample, clock_us, args.batch,
                                        Path(tmp))
                best = min(best, wall)
                longest = max(longest, worst)
                if kind != "objects":
                    col.close()
            rows[kind] = {"us_per_sample": 1e6 * best / len(samples),
                          "longest_feed_ms": 1e3 * longest}
        # memory: a fresh copy of the flight's samples and estimates is made while tracing,
        # fed, then dropped: what stays allocated is what the collector holds
        for kind in ("objects", "compact", "spill"):
            tracemalloc.start()
            before = tracemalloc.get_traced_memory()[0]
            s_copy, p_copy = copy.deepcopy((samples, per_sample))
            _, _, col = _run(kind, s_copy, p_copy, clock_us, args.batch, Path(tmp))
            del s_copy, p_copy
            held = tracemalloc.get_traced_memory()[0] - before
            tracemalloc.stop()
            rows[kind]["bytes_held_per_estimate"] = held / n_est
            if kind != "objects":
                rows[kind]["column_bytes_per_estimate"] = col.compact_nbytes / n_est
                col.close()
            del col
    result = {
        "duration_s": args.duration, "samples": len(samples), "estimates": n_est,
        "batch": args.batch, "chunk_rows": CHUNK_ROWS, "repeat": args.repeat,
        "filter_us_per_sample": 1e6 * filter_s / len(samples),
        "load_avg": os.getloadavg(), "kinds": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
