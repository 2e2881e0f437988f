"""Benchmark: navigation-filter cost per IMU sample, alone and behind the MAVLink decoder.

The sample stream is generated once: ``--duration`` s (default 120) of the racetrack with the
``industrial-mems`` IMU at 200 Hz, ``modern`` GNSS at 5 Hz, ``ms5611`` baro and ``consumer``
magnetometer at 50 Hz, through the pipeline's simulator half (:class:`hil.pipeline.SimChain`).
It is kept twice: as the list of SI samples in emission
order (truth dropped) and as the list of encoded MAVLink frames (truth frames included, as on
the wire).

Timed (best of ``--repeats``, each on a fresh filter tuned by
:func:`hil.tuning.filter_config_for_imu`):

- ``filter``: ``NavFilter.step`` over the samples;
- ``decode+filter``: the pipeline's fusion half over the frames
  (:meth:`hil.pipeline.FusionRun.feed_frame` without collection: decode, every decoded
  sample except truth to ``NavFilter.step``; the path ``hilnav replay`` takes, minus file
  reading and collection).

Both with the covariance propagated at 100 Hz (``RatesConfig`` default) and at every IMU
sample. CPU time (``time.process_time``) and wall time (``time.perf_counter``) are reported as
µs per IMU sample and as the real-time factor (simulated seconds per CPU second). Target:
<= 50 µs per sample for the filter at 100 Hz covariance (>= 100x real time at 200 Hz) on one
core; <= 40 µs for the commands' filter with air-data states (``--gnss-bias on``,
``ins35+gnss+air``) and <= 30 µs for the plain ``ins16`` layout. Alignment (the first ~1 s)
is inside the timed span.

A pyinstrument profile of the filter alone (100 Hz covariance) gives the top functions by own
time. The 1-, 5- and 15-minute load averages are recorded: other jobs may share the machine.

    python bench/fusion_speed.py --out bench/results/fusion_speed.json \
        [--duration 120] [--repeats 3] [--seed 1] [--gnss-bias on|off] [--airspeed on|off]

(``--gnss-bias on``, the default, is the commands' filter for the ``modern`` receiver.)

Both streams hold the same sensor samples (the simulator's pitot at 50 Hz included:
HIL_SENSOR ``diff_pressure``). ``--airspeed off`` drops the pitot samples from the ``filter``
stream (the air-data states stay dormant there; the frames still carry them).
``--layout NAME`` overrides the error-state layout the IMU preset's tuning picks (e.g.
``ins16``, the plain 16-state layout; default: the commands' ``ins35+air``).

``--breakdown`` adds where the time of one IMU sample's worth of decode + filter goes (CPU
time per IMU sample over the whole stream): the framing (:class:`hil.codec.framing.
FrameParser`), the fast unpack (:mod:`hil.codec.fast_frames`), the rest of the decoder
(dispatch and the SI sample objects: ``Decoder.feed`` minus the two), the filter on the
decoded samples, and the filter's time split by module group from a pyinstrument profile
(the profile's shares times the measured filter time).

Bit identity: ``digest_filter_cov_100hz`` is a SHA-256 over every estimate of one filter pass
(each array field's bytes, every other field's ``repr``: exact for floats), the innovations of
every step and the final covariance's bytes; two trees agree on it only if their estimates are
bit for bit the same. ``--ab REV`` times the filter of git revision ``REV`` (a ``git archive``
of it in a temporary folder, first on ``PYTHONPATH`` of a child process) against this tree on
the same stream, alternating the two in child processes ``--rounds`` times (order swapped every
round) so that both see the same machine load, and records both digests:

    python bench/fusion_speed.py --ab REV [--rounds 6] [--layout ins16 | --gnss-bias on] \
        --out bench/results/fusion_speed_ab_....json

A ``git archive`` has no built extension: the base tree gets this tree's build of each compiled
module whose C source is byte-identical in both (listed in the JSON as
``base_compiled_modules_copied``); the others run their Python reference there.
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
from pathlib import Path
from typing import Any

IMU = "industrial-mems"
RATE_HZ = 200.0
TARGET_US = 50.0
"""CPU us per IMU sample (filter alone, covariance at 100 Hz) of any layout: >= 100x real time."""
TARGET_US_BY_LAYOUT = {"ins16": 30.0, "ins35+gnss+air": 40.0}
"""Tighter targets: the plain 16-state filter and the commands' filter with air-data states."""


def generate(duration_s: float, seed: int) -> tuple[list[Any], list[bytes], int]:
    """Fly the racetrack once; returns (samples, frames, number of IMU samples).

    Parameters
    ----------
    duration_s : float
        Simulated seconds.
    seed : int
        Scenario seed.
    """
    from hil.pipeline import SimChain, SimSetup
    from sim.samples import AirspeedSample, ImuSample

    setup = SimSetup.build(plan="racetrack", imu=IMU, gnss="modern", baro="ms5611",
                           mag="consumer", rate_hz=RATE_HZ, duration_s=duration_s, seed=seed)
    samples: list[Any] = []  # as emitted by the sensor suite
    frames: list[bytes] = []
    with SimChain(setup) as chain:
        for step in chain.steps():
            samples.extend(s for s in step.samples
                           if AIRSPEED["on"] or not isinstance(s, AirspeedSample))
            frames.extend(frame for _t, frame in step.frames)
    if chain.ended is not None:
        raise RuntimeError(f"flight ended early: {chain.ended}")
    n_imu = sum(isinstance(s, ImuSample) for s in samples)
    return samples, frames, n_imu


AIRSPEED = {"on": True}
"""Whether the ``filter`` stream keeps the simulator's pitot samples (``--airspeed``)."""

LAYOUT: dict[str, str | None] = {"name": None}
"""Error-state layout override (``--layout``); None: the tuning's choice."""

GNSS_BIAS = {"on": False}
"""Whether the filter carries the GNSS position-bias states (``--gnss-bias``)."""


def _helpers() -> Any:
    """``tests/helpers/filter_digest.py`` loaded from this tree by its path: an ``--ab`` child has
    the base tree first on ``PYTHONPATH``, and the base need not have the helper."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "_filter_digest", Path(__file__).resolve().parents[1] / "tests/helpers/filter_digest.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _config(cov_rate_hz: float | None) -> Any:
    return _helpers().tuned_config(IMU, cov_rate_hz=cov_rate_hz, layout=LAYOUT["name"],
                                   gnss_bias=GNSS_BIAS["on"])


def time_filter(samples: list[Any], cov_rate_hz: float | None) -> tuple[float, float, int]:
    """(cpu_s, wall_s, estimates) of one pass of a fresh NavFilter over ``samples``."""
    from fusion.filter import NavFilter

    nav = NavFilter(_config(cov_rate_hz))
    step = nav.step
    n_out = 0
    c0, w0 = time.process_time(), time.perf_counter()
    for s in samples:
        n_out += len(step(s))
    return time.process_time() - c0, time.perf_counter() - w0, n_out


def time_decode_filter(frames: list[bytes], cov_rate_hz: float | None) -> tuple[float, float, int]:
    """(cpu_s, wall_s, estimates) of the pipeline's fusion half (:class:`hil.pipeline.FusionRun`
    without collection: decode + a fresh NavFilter) over ``frames``."""
    from hil.pipeline import FusionRun

    feed = FusionRun(_config(cov_rate_hz), collect=False).feed_frame
    n_out = 0
    c0, w0 = time.process_time(), time.perf_counter()
    for f in frames:
        n_out += len(feed(f))
    return time.process_time() - c0, time.perf_counter() - w0, n_out


def digest_filter(samples: list[Any], cov_rate_hz: float | None) -> str:
    """SHA-256 of one filter pass (:func:`tests.helpers.filter_digest.filter_digest`)."""
    return str(_helpers().filter_digest(_config(cov_rate_hz), samples))


def _ab_child(stream_path: str) -> None:
    """The timed process of ``--ab``: one filter pass (covariance at 100 Hz) of the pickled
    stream with the code first on ``PYTHONPATH``; prints JSON (CPU us per IMU sample, digest)."""
    with open(stream_path, "rb") as fh:
        data = pickle.load(fh)
    LAYOUT["name"], GNSS_BIAS["on"] = data["layout"], data["gnss_bias"]
    samples, n_imu = data["samples"], data["imu_samples"]
    cpu = min(time_filter(samples, 100.0)[0] for _ in range(data["repeats"]))
    print(json.dumps({"cpu_us_per_imu_sample": 1e6 * cpu / n_imu,
                      "digest": digest_filter(samples, 100.0)}))


def ab_compare(base_rev: str, samples: list[Any], n_imu: int, rounds: int, repeats: int
               ) -> dict[str, Any]:
    """The filter of ``base_rev`` against this tree's, alternating child processes on the same
    stream (see the module docstring)."""
    root = Path(__file__).resolve().parent.parent
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        base.mkdir()
        archive = subprocess.run(["git", "archive", base_rev], cwd=root, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        compiled = _share_compiled(root, base)
        stream = Path(tmp) / "stream.pkl"
        with open(stream, "wb") as fh:
            pickle.dump({"samples": samples, "imu_samples": n_imu, "layout": LAYOUT["name"],
                         "gnss_bias": GNSS_BIAS["on"], "repeats": repeats}, fh)
        trees = {"base": base, "this": root}
        runs: dict[str, list[dict[str, Any]]] = {"base": [], "this": []}
        for r in range(rounds):
            for name in (("base", "this") if r % 2 == 0 else ("this", "base")):
                env = {**os.environ, "PYTHONPATH": str(trees[name]), "OPENBLAS_NUM_THREADS": "1",
                       "OMP_NUM_THREADS": "1"}
                out = subprocess.run([sys.executable, str(Path(__file__).resolve()),
                                      "--ab-child", str(stream)], cwd=trees[name], env=env,
                                     check=True, capture_output=True, text=True).stdout
                runs[name].append(json.loads(out.strip().splitlines()[-1]))
                print(f"round {r} {name:4s} {runs[name][-1]['cpu_us_per_imu_sample']:6.1f} us",
                      flush=True)
    best = {k: min(x["cpu_us_per_imu_sample"] for x in v) for k, v in runs.items()}
    digests = {k: sorted({x["digest"] for x in v}) for k, v in runs.items()}
    return {
        "base_rev": base_rev,
        "method": ("filter/cov_100hz, CPU us per IMU sample; child processes alternating base "
                   "and this tree on one pickled stream, order swapped every round; best of "
                   "each child's repeats, then best over the rounds"),
        "rounds": rounds,
        "cpu_us_per_imu_sample": best,
        "this_over_base": best["this"] / best["base"],
        "all_cpu_us_per_imu_sample": {k: [x["cpu_us_per_imu_sample"] for x in v]
                                      for k, v in runs.items()},
        "digests": digests,
        "bit_identical": digests["base"] == digests["this"] and len(digests["this"]) == 1,
        "base_compiled_modules_copied": compiled,
    }


def _share_compiled(root: Path, base: Path) -> list[str]:
    """A ``git archive`` holds no built extension: give the base tree this tree's build of every
    compiled module whose C source is byte-identical in both (e.g. ``fusion/_strapdown.c``), so
    that both sides run the kernels their sources define; a module the base lacks (or has in
    another version) stays absent there and the base runs its Python reference. Returns the
    copied files."""
    import shutil

    copied = []
    for src in sorted((base / "fusion").glob("_*.c")):
        ours = root / "fusion" / src.name
        if not ours.exists() or ours.read_bytes() != src.read_bytes():
            continue
        for built in sorted((root / "fusion").glob(src.stem + ".*.so")) + sorted(
                (root / "fusion").glob(src.stem + ".*.pyd")):
            shutil.copy2(built, base / "fusion" / built.name)
            copied.append(f"fusion/{built.name}")
    return copied


def profile_filter(samples: list[Any], top: int = 10) -> list[dict[str, Any]]:
    """Top ``top`` functions by own (self) time of one filter pass (pyinstrument; a function
    called from several places is summed)."""
    from pyinstrument import Profiler

    from fusion.filter import NavFilter

    nav = NavFilter(_config(100.0))
    prof = Profiler(interval=0.0005)
    prof.start()
    for s in samples:
        nav.step(s)
    session = prof.stop()
    root = session.root_frame()
    total = root.time if root is not None else 0.0
    own: dict[tuple[str, str, int], float] = {}

    def walk(frame: Any) -> None:
        if frame.is_synthetic:  # "[self]" leaves: already in the parent's total_self_time
            return
        key = (frame.function, frame.file_path_short or "", frame.line_no or 0)
        own[key] = own.get(key, 0.0) + frame.total_self_time
        for child in frame.children:
            walk(child)

    if root is not None:
        walk(root)
    ranked = sorted(own.items(), key=lambda kv: kv[1], reverse=True)
    return [
        {"function": fn, "file": f"{path}:{line}", "self_percent": 100.0 * t / total,
         "self_s": t}
        for (fn, path, line), t in ranked[:top]
    ] if total > 0 else []


# Module groups of the filter's time (first match of a path fragment wins; the rest is the
# filter's orchestration, numpy's Python wrappers and the interpreter). Inside the call tree of
# an aiding source (AIDING_GROUPS) everything but the covariance propagation (a flush before
# the update) counts to that source's update: its model, the Kalman step, the feedback.
FILTER_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("INS mechanisation (strapdown, Earth terms)", ("/fusion/strapdown.py", "/fusion/earth.py",
                                                     "/fusion/rotations.py")),
    ("covariance propagation", ("/fusion/propagation.py", "/fusion/error_model.py")),
    ("measurement updates outside an aiding source (Kalman step, feedback)",
     ("/fusion/kalman.py", "/fusion/feedback.py", "/fusion/airspeed_model.py",
      "/fusion/wind_model.py")),
    ("altitude channel", ("/fusion/altitude/", "/fusion/altitude_link.py")),
    ("IMU screening", ("/fusion/screening.py",)),
    ("estimate output", ("/fusion/estimate.py",)),
    ("alignment", ("/fusion/alignment.py",)),
    ("INS history, outage bookkeeping", ("/fusion/history.py", "/fusion/outage.py",
                                          "/fusion/bridging/")),
)
AIDING_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("GNSS update (model, Kalman step, feedback)", ("/fusion/aiding/gnss.py",
                                                    "/fusion/aiding/pseudo_gnss.py")),
    ("baro update", ("/fusion/aiding/baro.py",)),
    ("magnetometer update", ("/fusion/aiding/mag.py",)),
    ("air-data updates (TAS, sideslip, pitot monitor)", ("/fusion/aiding/airspeed.py",
                                                         "/fusion/aiding/pitot_monitor.py")),
    ("zero-motion detection and updates", ("/fusion/aiding/zero_motion.py",)),
)
OTHER_GROUP = "filter orchestration (fusion/filter.py) and the rest"
_PROPAGATION = FILTER_GROUPS[1]


def _cpu_s(fn: Any) -> float:
    c0 = time.process_time()
    fn()
    return time.process_time() - c0


def filter_shares(samples: list[Any]) -> dict[str, float]:
    """Share of each group (:data:`FILTER_GROUPS`, :data:`AIDING_GROUPS`) in the own (self)
    time of one filter pass (pyinstrument; covariance at 100 Hz)."""
    from pyinstrument import Profiler

    from fusion.filter import NavFilter

    nav = NavFilter(_config(100.0))
    prof = Profiler(interval=0.0002)
    prof.start()
    for s in samples:
        nav.step(s)
    root = prof.stop().root_frame()
    names = [n for n, _ in FILTER_GROUPS] + [n for n, _ in AIDING_GROUPS] + [OTHER_GROUP]
    own = dict.fromkeys(names, 0.0)

    def match(path: str, groups: tuple[tuple[str, tuple[str, ...]], ...]) -> str | None:
        return next((name for name, frags in groups if any(f in path for f in frags)), None)

    def walk(frame: Any, group: str, aiding: str | None) -> None:
        path = frame.file_path or ""
        if not frame.is_synthetic:
            aiding = match(path, AIDING_GROUPS) or aiding
            if any(f in path for f in _PROPAGATION[1]):
                group = _PROPAGATION[0]
            elif aiding is not None:
                group = aiding
            else:
                group = match(path, FILTER_GROUPS) or (OTHER_GROUP if "/fusion/" in path
                                                       else group)
            own[group] += frame.total_self_time
        for child in frame.children:
            walk(child, group, aiding)

    if root is not None:
        walk(root, OTHER_GROUP, None)
    total = sum(own.values())
    return {k: v / total for k, v in own.items()} if total > 0 else own


def breakdown(frames: list[bytes], n_imu: int, repeats: int) -> dict[str, Any]:
    """Where the CPU time of decode + filter goes, us per IMU sample (covariance at 100 Hz;
    each stage timed alone over the whole stream, best of ``repeats``)."""
    from hil.codec import Decoder
    from hil.codec.counters import DecoderCounters
    from hil.codec.fast_frames import unpack_fields
    from hil.codec.framing import FrameParser
    from sim.samples import Truth

    def framing() -> None:
        feed = FrameParser(DecoderCounters()).feed
        for f in frames:
            feed(f)

    def unpack() -> None:
        for f in frames:
            unpack_fields(f, f[7] | (f[8] << 8) | (f[9] << 16))

    def decode() -> None:
        feed = Decoder().feed
        for f in frames:
            feed(f)

    dec = Decoder()
    decoded = [d.sample for f in frames for d in dec.feed(f) if not isinstance(d.sample, Truth)]
    us = 1e6 / n_imu
    t_framing = min(_cpu_s(framing) for _ in range(repeats)) * us
    t_unpack = min(_cpu_s(unpack) for _ in range(repeats)) * us
    t_decode = min(_cpu_s(decode) for _ in range(repeats)) * us
    t_filter = min(time_filter(decoded, 100.0)[0] for _ in range(repeats)) * us
    t_both = min(time_decode_filter(frames, 100.0)[0] for _ in range(repeats)) * us
    shares = filter_shares(decoded)
    return {
        "method": ("CPU us per IMU sample, each stage timed alone over the whole stream, best "
                   "of repeats; the filter's groups are pyinstrument self-time shares times "
                   "the measured filter time"),
        "decoder": {
            "framing (FrameParser.feed)": t_framing,
            "fast unpack (fast_frames)": t_unpack,
            "dispatch + SI sample objects (Decoder.feed minus the two above)":
                t_decode - t_framing - t_unpack,
            "total (Decoder.feed)": t_decode,
        },
        "filter": {**{k: v * t_filter for k, v in shares.items()}, "total (NavFilter.step)":
                   t_filter},
        "decode+filter (FusionRun.feed_frame)": t_both,
        "decode+filter minus the two stages": t_both - t_decode - t_filter,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    ap.add_argument("--repeats", type=int, default=3, help="best of this many passes")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-profile", action="store_true", help="skip the pyinstrument profile")
    ap.add_argument("--out", type=Path, default=Path("bench/results/fusion_speed.json"))
    ap.add_argument("--gnss-bias", choices=("on", "off"), default="on",
                    help="on: the filter as the commands tune it for the modern receiver "
                         "(ins35+gnss+air, 43 states); off: the IMU datasheet layout "
                         "(ins35+air)")
    ap.add_argument("--airspeed", choices=("on", "off"), default="on",
                    help="on: the filter stream carries 20 Hz pitot samples (air data fused); "
                         "off: no air data (the air-data states stay dormant)")
    ap.add_argument("--layout", default=None,
                    help="error-state layout instead of the tuning's (e.g. ins16)")
    ap.add_argument("--breakdown", action="store_true",
                    help="also time each stage of decode + filter (see the module docstring)")
    ap.add_argument("--ab", metavar="REV", default=None,
                    help="time the filter of git revision REV against this tree, alternating "
                         "(see the module docstring); only that, with the digests")
    ap.add_argument("--rounds", type=int, default=6, help="--ab: alternations")
    if argv is None and len(sys.argv) == 3 and sys.argv[1] == "--ab-child":
        _ab_child(sys.argv[2])
        return 0
    args = ap.parse_args(argv)
    GNSS_BIAS["on"] = args.gnss_bias == "on"
    AIRSPEED["on"] = args.airspeed == "on"
    LAYOUT["name"] = args.layout
    if args.duration <= 5 or args.repeats < 1 or args.rounds < 1:
        ap.error("--duration must be > 5 s, --repeats and --rounds >= 1")

    import numpy as np

    load_start = os.getloadavg()
    t0 = time.perf_counter()
    samples, frames, n_imu = generate(args.duration, args.seed)
    gen_s = time.perf_counter() - t0
    print(f"generated {len(samples)} samples ({n_imu} IMU), {len(frames)} frames in "
          f"{gen_s:.1f} s", flush=True)
    sim_s = n_imu / RATE_HZ
    machine = {
        "python": platform.python_version(), "numpy": np.__version__,
        "platform": platform.platform(), "cpu_count": os.cpu_count(),
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
    }
    stream = {
        "plan": "racetrack", "seed": args.seed, "duration_s": args.duration,
        "imu_rate_hz": RATE_HZ, "gnss_rate_hz": 5.0, "baro_rate_hz": 50.0,
        "mag_rate_hz": 50.0, "imu_samples": n_imu, "samples": len(samples),
        "frames": len(frames), "generate_wall_s": gen_s,
    }
    if args.ab is not None:
        from fusion.filter import NavFilter

        layout = NavFilter(_config(100.0)).layout
        ab = ab_compare(args.ab, samples, n_imu, args.rounds, args.repeats)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({
            "benchmark": "fusion_speed_ab", "imu": IMU, "state_layout": layout.name,
            "error_states": layout.n, "airspeed_samples_in_filter_stream": AIRSPEED["on"],
            "stream": stream, "repeats": args.repeats, **ab,
            "machine": {**machine, "load_average_at_start": list(load_start),
                        "load_average_at_end": list(os.getloadavg())},
        }, indent=1) + "\n")
        b, t = ab["cpu_us_per_imu_sample"]["base"], ab["cpu_us_per_imu_sample"]["this"]
        print(f"{layout.name}: base {b:.1f} us, this {t:.1f} us per IMU sample "
              f"({t / b:.3f}x); bit-identical: {ab['bit_identical']}; load "
              f"{list(load_start)} -> {list(os.getloadavg())}; -> {args.out}")
        return 0

    cases: dict[str, Any] = {}
    for cov_name, cov in (("cov_100hz", 100.0), ("cov_every_sample", None)):
        for path_name, fn, data in (("filter", time_filter, samples),
                                    ("decode+filter", time_decode_filter, frames)):
            runs = [fn(data, cov) for _ in range(args.repeats)]
            cpu = min(r[0] for r in runs)
            wall = min(r[1] for r in runs)
            key = f"{path_name}/{cov_name}"
            cases[key] = {
                "covariance_rate_hz": cov,
                "cpu_us_per_imu_sample": 1e6 * cpu / n_imu,
                "wall_us_per_imu_sample": 1e6 * wall / n_imu,
                "realtime_factor_cpu": sim_s / cpu,
                "realtime_factor_wall": sim_s / wall,
                "all_cpu_s": [r[0] for r in runs],
                "all_wall_s": [r[1] for r in runs],
                "estimates": runs[0][2],
            }
            print(f"{key:32s} {cases[key]['cpu_us_per_imu_sample']:7.1f} us/sample CPU "
                  f"({cases[key]['wall_us_per_imu_sample']:.1f} wall), "
                  f"{cases[key]['realtime_factor_cpu']:.0f}x real time", flush=True)

    hot = [] if args.no_profile else profile_filter(samples)
    split = breakdown(frames, n_imu, args.repeats) if args.breakdown else None
    main_case = cases["filter/cov_100hz"]
    from fusion.filter import NavFilter

    layout = NavFilter(_config(100.0)).layout  # the cost grows with the error-state size
    target_us = TARGET_US_BY_LAYOUT.get(layout.name, TARGET_US)
    result: dict[str, Any] = {
        "benchmark": "fusion_speed",
        "imu": IMU,
        "state_layout": layout.name,
        "error_states": layout.n,
        "airspeed_samples_in_filter_stream": AIRSPEED["on"],
        "stream": stream,
        "digest_filter_cov_100hz": digest_filter(samples, 100.0),
        "method": ("best of repeats; fresh NavFilter per pass (alignment included); "
                   "us per IMU sample = time / IMU samples; realtime factor = simulated s / "
                   "CPU s"),
        "repeats": args.repeats,
        "target": {"cpu_us_per_imu_sample": target_us, "case": "filter/cov_100hz",
                   "realtime_factor": 1e6 / target_us / RATE_HZ},
        "meets_target": {
            "filter_cov_100hz_cpu": bool(main_case["cpu_us_per_imu_sample"] <= target_us),
            "filter_cov_100hz_wall": bool(main_case["wall_us_per_imu_sample"] <= target_us),
        },
        "cases": cases,
        "profile_top10_filter_cov_100hz": hot,
        "breakdown_cov_100hz": split,
        "machine": {**machine, "load_average_at_start": list(load_start),
                    "load_average_at_end": list(os.getloadavg())},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    if split is not None:
        print("\nper IMU sample, CPU us (cov 100 Hz):")
        for part in ("decoder", "filter"):
            for k, v in split[part].items():
                print(f"  {part:8s} {v:6.2f}  {k}")
        print(f"  decode+filter {split['decode+filter (FusionRun.feed_frame)']:6.2f}")
    print("\ntop functions (self time, filter alone, cov 100 Hz):")
    for h in hot:
        print(f"  {h['self_percent']:5.1f} %  {h['function']}  {h['file']}")
    print(f"load average {result['machine']['load_average_at_start']} -> "
          f"{result['machine']['load_average_at_end']}; -> {args.out}")
    return 0


if __name__ == "__main__":
    # One BLAS thread: the target is one core, and small GEMMs get slower with a second thread.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
