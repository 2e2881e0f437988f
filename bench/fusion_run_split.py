"""Benchmark: where the ``decode_filter`` phase of ``hilnav run`` goes, part by part.

``bench/run_end_to_end.py`` times the :class:`hil.pipeline.FusionRun` sink of a real ``hilnav
run`` as one phase (decode + filter + collector). This bench flies the same scenario once (the
300 s copy of ``turning-60s-outages`` of that bench by default: its filter, bridging and
altitude method, its seed), keeps every frame the sink received in memory, and then times, in
one process, on those frames (CPU time, ``process_time``; best of ``--rounds`` rounds):

- ``framing``: :class:`hil.codec.framing.FrameParser` alone;
- ``decode``: :meth:`hil.codec.Decoder.feed` (framing + unpack + SI samples + ``Decoded``);
- ``filter``: :meth:`fusion.filter.NavFilter.step` on the decoded samples (truth skipped);
- ``filter_collect``: :meth:`hil.tracks.Collector.feed` on them (filter + collector);
- ``fusion_run``: the run's own sink, a fresh :class:`FusionRun`, given the frames as
  :func:`hil.pipeline.fly` gives them (whole lockstep batches where the tree's sink takes
  them, else frame by frame).

``in_flight``: the same flight flown into that sink and into one that does nothing,
alternately: the fusion's marginal CPU inside a real lockstep flight (cache and garbage
collector effects of the simulator around it included, no clock read per frame).

Differences give the decoder's dispatch and sample objects (``decode - framing``), the
collector (``filter_collect - filter``) and ``sink_loop`` (``fusion_run - decode -
filter_collect``: what the sink costs beyond its parts run one after the other over the
whole recording: its own loop and the parts' code and data evicting each other). ``by_kind``
splits ``decode`` by message and ``filter`` by sample type, one clock read pair around each
call (the pair's own cost, measured, is subtracted). Every figure is also given per IMU sample
(the run's 200 Hz). The filter, bridge and collector are built exactly as
``scenarios.runner.run_scenario`` builds them.

    python bench/fusion_run_split.py --out bench/results/fusion_run_split.json

``--base REV`` (before / after of a change): the timings run in child processes, the code of
REV (``git archive`` into a temporary folder, first on ``PYTHONPATH``, this script with it)
and of this tree alternately, ``--rounds`` each, on the same recorded frames (and ``in_flight``
in each child); ``ab`` holds each tree's best per part. With ``--count-s S`` it also counts,
for both trees, the instructions of ``decode`` and ``fusion_run`` over the frames of the
first S simulated seconds (valgrind, as :mod:`bench.instruction_count` does: the loop's
process minus the same process without the loop, per IMU sample): a before / after that the
machine's load does not move. ``--count-parts`` counts other parts too (any of ``framing``,
``decode``, ``filter``, ``filter_collect``, ``fusion_run``); with ``filter`` and
``filter_collect`` the JSON also gives the collector's own instructions (their difference).
The count is a difference of two whole processes (~10^9 instructions of start-up each), so
it varies by several thousand instructions per IMU sample from one invocation to the next
over a few seconds of frames: compare effects larger than that.

    python bench/fusion_run_split.py --base 4be3151 --rounds 3 --count-s 20 \
        --out bench/results/fusion_run_split_ab.json
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import platform
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PARTS = ("framing", "decode", "filter", "filter_collect", "fusion_run")


def record(scenario_path: Path) -> dict[str, Any]:
    """Fly the scenario as ``hilnav run`` does and keep the frames its fusion sink receives."""
    from scenarios.runner import simulate
    from scenarios.schema import load_scenario

    scn = load_scenario(scenario_path)
    frames: list[tuple[int, bytes]] = []
    simulate(scn, lambda t, f: frames.append((t, f)))
    return {"scenario_path": str(scenario_path), "frames": frames}


def in_flight(scenario_path: Path, rounds: int) -> dict[str, Any]:
    """The fusion's marginal CPU inside a flight: the lockstep flight (``simulate``) into the
    run's :class:`FusionRun` and into a sink that does nothing, alternately, best of
    ``rounds``; no clock is read per frame."""
    from hil.pipeline import FusionRun, build_filter
    from scenarios.runner import simulate
    from scenarios.schema import load_scenario

    scn = load_scenario(scenario_path)
    config, bridge = _setup(str(scenario_path))
    cpu = time.process_time
    best: dict[str, float] = {}
    for _ in range(rounds):
        for name in ("flight_only", "flight_with_fusion"):
            sink: Any = (lambda t, f: None) if name == "flight_only" else FusionRun(
                config, bridge, nav=build_filter(config, bridge))
            t0 = cpu()
            simulate(scn, sink)
            dt = cpu() - t0
            best[name] = min(best.get(name, dt), dt)
    n_imu = round(scn.duration_s * scn.flight_config().rate_hz)
    return {"cpu_s": best, "imu_samples": n_imu,
            "fusion_marginal_us_per_imu_sample":
                (best["flight_with_fusion"] - best["flight_only"]) / n_imu * 1e6}


def _setup(scenario_path: str) -> tuple[Any, str]:
    from scenarios.runner import filter_config
    from scenarios.schema import load_scenario

    scn = load_scenario(Path(scenario_path))
    return filter_config(scn, scn.fusion.altitude), scn.fusion.bridge


def time_parts(rec: dict[str, Any], rounds: int) -> dict[str, Any]:
    """Every part of the module docstring on the recorded frames, best of ``rounds``."""
    from hil.codec import Decoder
    from hil.codec.counters import DecoderCounters
    from hil.codec.framing import FrameParser
    from hil.pipeline import FusionRun, build_filter
    from hil.tracks import Collector
    from sim.samples import ImuSample, Truth

    config, bridge = _setup(rec["scenario_path"])
    frames: list[tuple[int, bytes]] = rec["frames"]
    cpu = time.process_time

    batches = _lockstep_batches(frames)
    dec = Decoder()
    decoded = [[d.sample for d in dec.feed(f)] for _t, f in frames]
    flat = [s for ss in decoded for s in ss]
    n_imu = sum(isinstance(s, ImuSample) for s in flat)

    def framing() -> None:
        parser = FrameParser(DecoderCounters())
        feed = parser.feed
        for _t, f in frames:
            feed(f)

    def decode() -> None:
        feed = Decoder().feed
        for _t, f in frames:
            feed(f)

    def filt() -> None:
        step = build_filter(config, bridge).step
        for s in flat:
            if not isinstance(s, Truth):
                step(s)

    def filter_collect() -> None:
        Collector().feed(build_filter(config, bridge), flat)

    def fusion_run() -> None:
        run = FusionRun(config, bridge, nav=build_filter(config, bridge))
        batch_sink = getattr(run, "frames", None)
        if batch_sink is None:  # a tree without batches: fly() hands the frames one by one
            for t, f in frames:
                run(t, f)
            return
        for batch in batches:
            batch_sink(batch)

    fns = {"framing": framing, "decode": decode, "filter": filt,
           "filter_collect": filter_collect, "fusion_run": fusion_run}
    best: dict[str, float] = {}
    for _ in range(rounds):
        for name in PARTS:
            t0 = cpu()
            fns[name]()
            dt = cpu() - t0
            best[name] = min(best.get(name, dt), dt)
    return {"frames": len(frames), "imu_samples": n_imu, "samples": len(flat),
            "cpu_s": best, "us_per_imu_sample": {k: v / n_imu * 1e6 for k, v in best.items()},
            "derived_us_per_imu_sample": _derived(best, n_imu),
            "by_kind": _by_kind(frames, flat, config, bridge, n_imu)}


def _lockstep_batches(frames: list[tuple[int, bytes]]) -> list[list[tuple[int, bytes]]]:
    """The frames as :func:`hil.pipeline.fly` hands them to a batch sink: those of
    ``LOCKSTEP_BATCH`` steps at a time (a step's frames start with its HIL_SENSOR)."""
    from hil.pipeline import LOCKSTEP_BATCH

    out: list[list[tuple[int, bytes]]] = [[]]
    steps = 0
    for t, f in frames:
        if f[7] == 107 and f[8] == 0 and f[9] == 0:  # HIL_SENSOR: a new step
            if steps == LOCKSTEP_BATCH:
                out.append([])
                steps = 0
            steps += 1
        out[-1].append((t, f))
    return out


def _derived(best: dict[str, float], n_imu: int) -> dict[str, float]:
    us = {k: v / n_imu * 1e6 for k, v in best.items()}
    return {"framing": us["framing"],
            "decoder_dispatch_and_samples": us["decode"] - us["framing"],
            "filter": us["filter"],
            "collector": us["filter_collect"] - us["filter"],
            "sink_loop": us["fusion_run"] - us["decode"] - us["filter_collect"]}


def _by_kind(frames: list[tuple[int, bytes]], flat: list[Any], config: Any, bridge: str,
             n_imu: int) -> dict[str, Any]:
    """CPU us per IMU sample of ``decode`` by message id and of ``filter`` by sample type (one
    pass each; the clock pair's own cost subtracted per call)."""
    from hil.codec import Decoder
    from hil.pipeline import build_filter
    from sim.samples import Truth

    clock = time.process_time_ns
    pair = min(_pair_ns(clock) for _ in range(5))
    dec_ns: dict[str, int] = defaultdict(int)
    dec_n: dict[str, int] = defaultdict(int)
    feed = Decoder().feed
    for _t, f in frames:
        key = f"msg_{f[7] | (f[8] << 8) | (f[9] << 16)}" if f[0] == 0xFD else "other"
        t0 = clock()
        feed(f)
        dec_ns[key] += clock() - t0 - pair
        dec_n[key] += 1
    flt_ns: dict[str, int] = defaultdict(int)
    flt_n: dict[str, int] = defaultdict(int)
    step = build_filter(config, bridge).step
    for s in flat:
        if isinstance(s, Truth):
            continue
        key = type(s).__name__
        t0 = clock()
        step(s)
        flt_ns[key] += clock() - t0 - pair
        flt_n[key] += 1
    return {"timer": "process_time_ns (CPU) per call, minus the clock pair's own cost",
            "clock_pair_ns": pair,
            "decode_us_per_imu_sample": {k: v / n_imu / 1e3 for k, v in dec_ns.items()},
            "decode_us_per_call": {k: dec_ns[k] / dec_n[k] / 1e3 for k in dec_ns},
            "frames": dict(dec_n),
            "filter_us_per_imu_sample": {k: v / n_imu / 1e3 for k, v in flt_ns.items()},
            "filter_us_per_call": {k: flt_ns[k] / flt_n[k] / 1e3 for k in flt_ns},
            "samples": dict(flt_n)}


def _pair_ns(clock: Any) -> float:
    n = 100_000
    t0 = clock()
    for _ in range(n):
        clock()
        clock()
    return (clock() - t0) / n


def _child(rec_path: Path, rounds: int, out_path: Path) -> None:
    rec = pickle.loads(rec_path.read_bytes())
    result = time_parts(rec, rounds)
    result["in_flight"] = in_flight(Path(rec["scenario_path"]), rounds)
    out_path.write_text(json.dumps(result), encoding="utf-8")


COUNTED = ("decode", "fusion_run")
"""The parts counted by default (``--count-parts``: any of :data:`PARTS`)."""


def _count_child(part: str, rec_path: str, run: bool) -> None:
    """The valgrind-counted process: build ``part``'s objects; run its loop if ``run``."""
    from hil.codec import Decoder
    from hil.codec.counters import DecoderCounters
    from hil.codec.framing import FrameParser
    from hil.pipeline import FusionRun, build_filter
    from hil.tracks import Collector
    from sim.samples import Truth

    rec = pickle.loads(Path(rec_path).read_bytes())
    frames = rec["frames"]
    if part == "framing":
        parse = FrameParser(DecoderCounters()).feed
        if run:
            for _t, f in frames:
                parse(f)
        return
    if part == "decode":
        feed = Decoder().feed
        if run:
            for _t, f in frames:
                feed(f)
        return
    config, bridge = _setup(rec["scenario_path"])
    if part in ("filter", "filter_collect"):
        dec = Decoder()  # decoded in both processes: only the loop below differs
        flat = [d.sample for _t, f in frames for d in dec.feed(f)]
        nav = build_filter(config, bridge)
        if run and part == "filter":
            step = nav.step
            for s in flat:
                if not isinstance(s, Truth):
                    step(s)
        elif run:
            Collector().feed(nav, flat)
        return
    sink = FusionRun(config, bridge, nav=build_filter(config, bridge))
    batch_sink = getattr(sink, "frames", None)
    batches = _lockstep_batches(frames)
    if run and batch_sink is None:
        for t, f in frames:
            sink(t, f)
    elif run:
        for batch in batches:
            batch_sink(batch)


def count_ab(rec: dict[str, Any], trees: dict[str, Path], seconds: float,
             folder: Path, parts: tuple[str, ...] = COUNTED) -> dict[str, Any]:
    """Instructions per IMU sample of ``parts`` (default :data:`COUNTED`) over the first
    ``seconds`` of the recording, for each tree."""
    from instruction_count import _count

    t_end = rec["frames"][0][0] + round(seconds * 1e6)
    frames = [(t, f) for t, f in rec["frames"] if t < t_end]
    n_imu = sum(1 for _t, f in frames if f[7] == 107 and f[8] == 0 and f[9] == 0)
    path = folder / "count-frames.pickle"
    path.write_bytes(pickle.dumps({**rec, "frames": frames}))
    out: dict[str, Any] = {"seconds": seconds, "frames": len(frames), "hil_sensor_frames": n_imu,
                           "method": "valgrind cachegrind I refs, (with loop - without) / "
                                     "HIL_SENSOR frames", "instructions_per_imu_sample": {}}
    for key, tree in trees.items():
        script = tree / "bench" / Path(__file__).name
        out["instructions_per_imu_sample"][key] = {
            part: (_count(tree, part, str(path), True, script)
                   - _count(tree, part, str(path), False, script)) / n_imu
            for part in parts}
    if set(trees) == {"before", "after"}:
        per = out["instructions_per_imu_sample"]
        out["after_over_before"] = {p: per["after"][p] / per["before"][p] for p in parts}
    if {"filter", "filter_collect"} <= set(parts):
        out["collector_instructions_per_imu_sample"] = {
            key: per_part["filter_collect"] - per_part["filter"]
            for key, per_part in out["instructions_per_imu_sample"].items()}
    return out


def export(base: str, folder: Path) -> Path:
    """``git archive`` of ``base`` in ``folder/base``, with this script in its bench/."""
    tree = folder / "base"
    tree.mkdir()
    archive = subprocess.run(["git", "archive", base], cwd=ROOT, check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    (tree / "bench" / Path(__file__).name).write_bytes(Path(__file__).read_bytes())
    return tree


def time_ab(rec: dict[str, Any], tree: Path, rounds: int, folder: Path) -> dict[str, Any]:
    """The parts of the base ``tree`` and of this tree in alternating child processes (one
    round each)."""
    rec_path = folder / "frames.pickle"
    rec_path.write_bytes(pickle.dumps(rec))
    runs: dict[str, list[dict[str, Any]]] = {"before": [], "after": []}
    for k in range(rounds):
        for key, src in (("before", tree), ("after", ROOT)):
            out = folder / f"{key}-{k}.json"
            cmd = [sys.executable, str(src / "bench" / Path(__file__).name), "--child-time",
                   str(rec_path), "1", str(out)]
            subprocess.run(cmd, cwd=src, env={**os.environ, "PYTHONPATH": str(src)},
                           check=True)
            runs[key].append(json.loads(out.read_text(encoding="utf-8")))
    best = {key: {p: min(r["us_per_imu_sample"][p] for r in rs) for p in PARTS}
            for key, rs in runs.items()}
    kinds = {key: {k: min(r["by_kind"]["decode_us_per_call"][k] for r in rs)
                   for k in rs[0]["by_kind"]["decode_us_per_call"]} for key, rs in runs.items()}
    marginal = {key: min(r["in_flight"]["fusion_marginal_us_per_imu_sample"] for r in rs)
                for key, rs in runs.items()}
    return {"rounds": rounds, "us_per_imu_sample_best": best,
            "in_flight_marginal_us_per_imu_sample_best": marginal,
            "decode_us_per_call_best": kinds,
            "after_over_before": {p: best["after"][p] / best["before"][p] for p in PARTS},
            "rounds_us_per_imu_sample": {key: [r["us_per_imu_sample"] for r in rs]
                                         for key, rs in runs.items()}}


def main() -> None:
    if len(sys.argv) == 5 and sys.argv[1] == "--child-time":
        sys.path.insert(0, str(ROOT))
        _child(Path(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4]))
        return
    if len(sys.argv) == 5 and sys.argv[1] == "--child":  # instruction_count's child call
        sys.path.insert(0, str(ROOT))
        _count_child(sys.argv[2], sys.argv[3], sys.argv[4] == "run")
        return
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--base", help="git revision: time its parts alternately with this tree's")
    ap.add_argument("--count-s", type=float, default=0.0,
                    help="with --base: also count instructions over the first S simulated s")
    ap.add_argument("--count-parts", default=",".join(COUNTED),
                    help=f"with --count-s: comma-separated parts to count, of {', '.join(PARTS)}")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/fusion_run_split.json")
    args = ap.parse_args()
    count_parts = tuple(args.count_parts.split(","))
    if bad := [p for p in count_parts if p not in PARTS]:
        ap.error(f"unknown part(s) {', '.join(bad)}; valid: {', '.join(PARTS)}")
    sys.path.insert(0, str(ROOT / "bench"))
    from run_end_to_end import LIBRARY, scenario_copy

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hilnav-split-") as tmp:
        folder = Path(tmp)
        path = scenario_copy(LIBRARY / f"{args.scenario}.yaml", args.duration, folder)
        rec = record(path)
        result: dict[str, Any] = {"benchmark": "fusion_run_split",
                                  "python": platform.python_version(),
                                  "scenario": args.scenario, "sim_duration_s": args.duration,
                                  "timer": "CPU seconds (process_time), best of rounds",
                                  "load_average_1m_before": load_before}
        if args.base is None:
            result["split"] = time_parts(rec, args.rounds)
            result["in_flight"] = in_flight(path, args.rounds)
        else:
            tree = export(args.base, folder)
            result["ab"] = {"base": args.base,
                            **time_ab(rec, tree, args.rounds, folder)}
            if args.count_s > 0:
                result["ab"]["instructions"] = count_ab(
                    rec, {"before": tree, "after": ROOT}, args.count_s, folder, count_parts)
    result["load_average_1m_after"] = os.getloadavg()[0]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
