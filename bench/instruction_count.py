"""Benchmark: instructions per frame (decoder) and per IMU sample (filter, decode + filter),
counted by valgrind: a load-independent before/after measure for a shared machine.

    python bench/instruction_count.py --out bench/results/instruction_count.json \
        [--tree DIR] [--duration 20] [--frames 4000] [--only CASE,...] \
        [--layout NAME] [--gnss-bias on|off]

Each case runs twice under ``valgrind --tool=cachegrind --cache-sim=no``, once with its loop
and once without (same imports, same input built), and reports the difference divided by the
number of frames / IMU samples: the interpreter's start-up and the input cancel out. Cases:

- ``encode_hil_sensor_imu``, ``encode_hil_gps``: ``Encoder.sensors`` (IMU fields) /
  ``Encoder.gnss`` per frame over ``--frames`` samples (made in the set-up);
- ``decode_hil_sensor_imu``, ``decode_hil_sensor_all``, ``decode_hil_gps``: ``Decoder.feed``
  per frame over ``--frames`` frames of the same samples;
- ``filter``: ``NavFilter.step`` over a ``--duration`` s racetrack stream
  (:func:`bench.fusion_speed.generate`, covariance at 100 Hz, the tuning's layout, or
  ``--layout`` / ``--gnss-bias`` as in :mod:`bench.fusion_speed`);
- ``decode+filter``: :meth:`hil.pipeline.FusionRun.feed_frame` over the frames of that stream.

``--tree DIR`` counts the code of another checkout (e.g. ``git worktree`` or ``git archive`` of
a base commit) with this script: its ``DIR`` goes first on ``PYTHONPATH``. The stream is
generated once, in this process, with the code of ``--tree``, and handed to the counted runs.
Needs ``valgrind`` on the PATH. Slow: ~50x the plain run time.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
CASES = ("encode_hil_sensor_imu", "encode_hil_gps", "decode_hil_sensor_imu",
         "decode_hil_sensor_all", "decode_hil_gps", "filter", "decode+filter")
_PER_FRAME = ("encode_", "decode_hil")


def _encode_inputs(kind: str, n: int) -> tuple[str, list[tuple[Any, ...]], dict[str, Any]]:
    """The case's ``Encoder`` method, its positional arguments for each frame, its keywords."""
    import math

    import numpy as np

    from sim.samples import BaroSample, GnssFix, ImuSample, MagSample

    rng = np.random.default_rng(1)
    imu = [ImuSample(1000 + 5000 * i, 0.005, rng.normal(size=3), rng.normal(size=3))
           for i in range(n)]
    if kind.endswith("hil_sensor_imu"):
        return "sensors", [(s,) for s in imu], {}
    if kind.endswith("hil_sensor_all"):
        return "sensors", [(s, BaroSample(s.time_us, 95_000.0, 280.0),
                            MagSample(s.time_us, np.array([2e-5, 1e-6, 4e-5]))) for s in imu], {
            "diff_pressure_pa": 600.0}
    return "gnss", [(GnssFix(s.time_us, 0.8, 0.1, 500.0, np.array([50.0, -3.0, 0.5]), 1.5, 2.5,
                             math.nan, 3, 12),) for s in imu], {}


def _decode_frames(kind: str, n: int) -> list[bytes]:
    from hil.codec import Encoder

    method, args, kwargs = _encode_inputs(kind, n)
    encode = getattr(Encoder(), method)
    return [encode(*a, **kwargs) for a in args]


def child(case: str, data_path: str, run: bool) -> None:
    """The counted process: build the input, run the loop if ``run``."""
    with open(data_path, "rb") as fh:
        data = pickle.load(fh)
    if case.startswith("encode_"):
        from hil.codec import Encoder

        method, args, kwargs = _encode_inputs(case, data["frames"])
        encode = getattr(Encoder(), method)
        if run:
            for a in args:
                encode(*a, **kwargs)
        return
    if case.startswith("decode_hil"):
        from hil.codec import Decoder

        frames = _decode_frames(case, data["frames"])
        feed = Decoder().feed
        if run:
            for f in frames:
                feed(f)
        return
    sys.path.insert(0, str(HERE))
    import fusion_speed

    from fusion.filter import NavFilter
    from hil.pipeline import FusionRun

    fusion_speed.LAYOUT["name"] = data.get("layout")
    fusion_speed.GNSS_BIAS["on"] = data.get("gnss_bias", False)
    cfg = fusion_speed._config(100.0)
    if case == "filter":
        step = NavFilter(cfg).step
        if run:
            for s in data["samples"]:
                step(s)
    else:
        feed_frame = FusionRun(cfg, collect=False).feed_frame
        if run:
            for f in data["stream_frames"]:
                feed_frame(f)


def _describe(tree: Path) -> dict[str, Any]:
    """The counted tree without machine paths: this checkout or another one, and its commit
    (None for a tree that is not a git work tree, e.g. a ``git archive``)."""
    git = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True, check=False)
    commit = git.stdout.strip() if git.returncode == 0 else None
    same = tree == HERE.parent.resolve()
    return {"tree": "." if same else "another checkout", "tree_commit": commit}


def _count(tree: Path, case: str, data_path: str, run: bool,
           script: Path | None = None) -> int:
    """Instructions of ``script --child CASE DATA run|setup`` under valgrind, with ``tree``
    first on ``PYTHONPATH`` (``script``: this bench, or another with the same child call)."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    cmd = ["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
           sys.executable, str(script or Path(__file__).resolve()), "--child", case, data_path,
           "run" if run else "setup"]
    out = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=True)
    m = re.search(r"I\s+refs:\s+([\d,]+)", out.stderr)
    if m is None:
        raise RuntimeError(f"no instruction count in valgrind's output:\n{out.stderr[-2000:]}")
    return int(m.group(1).replace(",", ""))


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[3], sys.argv[4] == "run")
        return 0
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tree", type=Path, default=HERE.parent, help="checkout whose code is counted")
    ap.add_argument("--duration", type=float, default=20.0, help="racetrack stream, s")
    ap.add_argument("--frames", type=int, default=4000, help="frames per decode case")
    ap.add_argument("--only", default=None, help="comma-separated cases (default: all)")
    ap.add_argument("--out", type=Path, default=Path("bench/results/instruction_count.json"))
    ap.add_argument("--layout", default=None, help="filter cases: error-state layout (e.g. ins16)")
    ap.add_argument("--gnss-bias", choices=("on", "off"), default="off",
                    help="filter cases: the filter as tuned for the modern receiver (as in "
                         "bench/fusion_speed.py)")
    args = ap.parse_args()
    cases = CASES if args.only is None else tuple(args.only.split(","))
    if bad := [c for c in cases if c not in CASES]:
        ap.error(f"unknown case(s) {', '.join(bad)}; valid: {', '.join(CASES)}")
    if shutil.which("valgrind") is None:
        print("valgrind not found on the PATH", file=sys.stderr)
        return 2
    tree = args.tree.resolve()
    sys.path[:0] = [str(tree), str(HERE)]  # generate with the counted tree's code
    import fusion_speed

    samples, frames, n_imu = fusion_speed.generate(args.duration, 1)
    result: dict[str, Any] = {
        "benchmark": "instruction_count", **_describe(tree), "duration_s": args.duration,
        "imu_samples": n_imu, "frames_per_decode_case": args.frames,
        "filter_layout": args.layout, "filter_gnss_bias": args.gnss_bias,
        "method": "valgrind cachegrind I refs, (with loop - without loop) / count", "cases": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        data_path = str(Path(tmp) / "stream.pkl")
        with open(data_path, "wb") as fh:
            pickle.dump({"samples": samples, "stream_frames": frames, "frames": args.frames,
                         "layout": args.layout, "gnss_bias": args.gnss_bias == "on"}, fh)
        for case in cases:
            per = args.frames if case.startswith(_PER_FRAME) else n_imu
            diff = (_count(tree, case, data_path, True)
                    - _count(tree, case, data_path, False))
            unit = "frame" if case.startswith(_PER_FRAME) else "imu_sample"
            result["cases"][case] = {f"instructions_per_{unit}": diff / per}
            print(f"{case:24s} {diff / per:10.0f} instructions per {unit}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
