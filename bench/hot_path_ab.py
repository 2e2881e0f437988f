"""Benchmark: the simulator's hot-path parts before and after a change, in one process.

On a shared machine whole-chain timings move by +-20 % between runs, more than most single
optimisations; this bench loads the *base* version of each changed module from git
(``git show BASE:path``) next to the working tree's and times the two alternately, part by
part, on the same inputs (CPU time, best of ``--rounds`` rounds of ``--n`` calls each), so the
ratio after / before holds even when the machine is loaded.

Parts: the guidance law (``Guidance.update``), the adapter's guidance input and truth object
(``Flight._guidance_input``, ``Flight._read_truth``), the IMU model (``measure_list``; and
``_refill``, one block of noise), the sensor suite's step (base suite with the base IMU model),
and the encoder (HIL_SENSOR with IMU fields / with every field, HIL_GPS, HIL_STATE_QUATERNION).

    python bench/hot_path_ab.py --base 0e06048 --out bench/results/hot_path_ab.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hil.codec import encoder as new_encoder
from sim import guidance as new_guidance
from sim import imu as new_imu
from sim import presets
from sim import sensors as new_sensors
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Truth

ROOT = Path(__file__).resolve().parent.parent


def base_module(rev: str, path: str, name: str, patch: dict[str, Any] | None = None
                ) -> types.ModuleType:
    """The module at ``path`` as of git revision ``rev``, loaded as ``name`` (its own imports
    resolve to the working tree); ``patch`` replaces globals before its body runs."""
    source = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    module = types.ModuleType(name)
    module.__file__ = f"{rev}:{path}"
    sys.modules[name] = module  # dataclasses look their module up by name
    exec(compile(source, module.__file__, "exec"), module.__dict__)
    for key, value in (patch or {}).items():
        setattr(module, key, value)
    return module


def ab(before: Callable[[], object], after: Callable[[], object], n: int, rounds: int
       ) -> dict[str, float]:
    """Best CPU us per call of each, measured alternately."""
    best = {"before_us": math.inf, "after_us": math.inf}
    for _ in range(rounds):
        for key, fn in (("before_us", before), ("after_us", after)):
            t0 = time.process_time()
            for _ in range(n):
                fn()
            best[key] = min(best[key], (time.process_time() - t0) / n * 1e6)
    best["after_over_before"] = best["after_us"] / best["before_us"]
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="git revision of the 'before' modules")
    ap.add_argument("--n", type=int, default=20000, help="calls per round")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/hot_path_ab.json")
    args = ap.parse_args()
    n, rounds = args.n, args.rounds
    old_guidance = base_module(args.base, "sim/guidance.py", "_base_guidance")
    old_imu = base_module(args.base, "sim/imu.py", "_base_imu")
    old_sensors = base_module(args.base, "sim/sensors.py", "_base_sensors",
                              {"ImuModel": old_imu.ImuModel})
    old_encoder = base_module(args.base, "hil/codec/encoder.py", "_base_encoder")
    old_flight = base_module(args.base, "sim/flight.py", "_base_flight")
    load_before = os.getloadavg()[0]
    cases: dict[str, dict[str, float]] = {}

    cfg = FlightConfig()
    plan = load_plan("racetrack")
    with Flight(cfg, plan) as flight, old_flight.Flight(cfg, plan) as base_flight:
        truths = [flight.step() for _ in range(2000)]
        for _ in range(2000):
            base_flight.step()
        cases["guidance_input"] = ab(lambda: base_flight._guidance_input(1.0),
                                     lambda: flight._guidance_input(1.0), n, rounds)
        cases["truth_object"] = ab(base_flight._read_truth, flight._read_truth, n, rounds)
        g_in = flight._guidance_input(1.0)
        law = flight.guidance
        args_law = (law.plan, 0.0, cfg.start.alt_msl_m, cfg.start.airspeed_mps, law._trim,
                    law.gains)
        old_law = old_guidance.Guidance(*args_law)
        new_law = new_guidance.Guidance(*args_law)
        cases["guidance_law"] = ab(lambda: old_law.update(g_in), lambda: new_law.update(g_in),
                                   n, rounds)

    imu_cfg = presets.suite_config().imu
    u = [0.1, 0.2, -9.8, 0.01, 0.02, 0.03]
    imu_old = old_imu.ImuModel(imu_cfg, np.random.default_rng(1), 200.0)
    imu_new = new_imu.ImuModel(imu_cfg, np.random.default_rng(1), 200.0)
    cases["imu_measure"] = ab(lambda: imu_old.measure_list(u), lambda: imu_new.measure_list(u),
                              n, rounds)
    # the noise block of BLOCK_STEPS samples (Gauss-Markov filter, random walks), per call
    block_old = old_imu.ImuModel(imu_cfg, np.random.default_rng(2), 200.0)
    block_new = new_imu.ImuModel(imu_cfg, np.random.default_rng(2), 200.0)
    cases["imu_noise_block"] = ab(block_old._refill, block_new._refill, max(n // 200, 5), rounds)
    assert block_old._err.tobytes() == block_new._err.tobytes()

    suite_cfg = presets.suite_config()

    def suite_loop(module: types.ModuleType) -> Callable[[], object]:
        suite = module.SensorSuite(suite_cfg, 1, 200.0)
        items: Iterator[Truth] = iter(())

        def step() -> object:
            nonlocal items, suite
            truth = next(items, None)
            if truth is None:  # a fresh suite for each pass over the recorded flight
                suite = module.SensorSuite(suite_cfg, 1, 200.0)
                items = iter(truths)
                truth = next(items)
            return suite.step(truth)
        return step

    cases["sensor_suite_step"] = ab(suite_loop(old_sensors), suite_loop(new_sensors), n, rounds)

    rng = np.random.default_rng(1)
    imu = ImuSample(1000, 0.005, rng.normal(size=3), rng.normal(size=3))
    baro = BaroSample(1000, 95_000.0, 280.0)
    mag = MagSample(1000, np.array([2e-5, 1e-6, 4e-5]))
    fix = GnssFix(1000, math.radians(47.0), math.radians(8.0), 500.0,
                  np.array([50.0, -3.0, 0.5]), 1.5, 2.5, math.nan, 3, 12)
    truth = truths[-1]
    e_old, e_new = old_encoder.Encoder(), new_encoder.Encoder()
    cases["encode_hil_sensor_imu"] = ab(lambda: e_old.sensors(imu), lambda: e_new.sensors(imu),
                                        n, rounds)
    cases["encode_hil_sensor_all"] = ab(
        lambda: e_old.sensors(imu, baro, mag, diff_pressure_pa=600.0),
        lambda: e_new.sensors(imu, baro, mag, diff_pressure_pa=600.0), n, rounds)
    cases["encode_hil_gps"] = ab(lambda: e_old.gnss(fix), lambda: e_new.gnss(fix), n, rounds)
    cases["encode_truth"] = ab(lambda: e_old.truth(truth), lambda: e_new.truth(truth), n,
                               rounds)
    # same payloads, same values: what the change must keep (headers and CRCs differ by the
    # sequence numbers the two encoders have reached)
    assert e_old.gnss(fix)[10:-2] == e_new.gnss(fix)[10:-2]
    assert e_old.truth(truth)[10:-2] == e_new.truth(truth)[10:-2]
    assert imu_old.measure_list(u) == imu_new.measure_list(u)

    result = {
        "benchmark": "hot_path_ab",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "base": args.base,
        "timer": f"process_time, best of {rounds} alternating rounds of {n} calls",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "cases": cases,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
