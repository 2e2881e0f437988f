"""Benchmark: bare JSBSim vs the flight adapter vs the simulator chain (JSBSim + guidance +
sensor models + MAVLink encode), same flight, same rate, one process run. Writes JSON.

Targets: the sim chain within 1.8x of bare JSBSim on the same flight and rate.
"bare JSBSim" is JSBSim's own ``run()`` with the controls frozen at trim; "adapter" is
:class:`sim.flight.Flight` (JSBSim + guidance law + property reads + checks + SI truth);
"chain" is :class:`hil.pipeline.SimChain` (adapter + sensor suite + vehicle-state reports +
sensor streamer), stepped one step at a time (``sim_chain``) and in the batches a lockstep
flight uses (``sim_chain_batched``, :data:`hil.pipeline.LOCKSTEP_BATCH` steps: JSBSim and the
guidance law for the whole batch, then the sensors and the encoder). Times are CPU seconds of
this process (best of ``--repeats``).

``breakdown_us_per_step`` says where a chain step's microseconds go: each part is timed alone,
in a loop, on the states of a flight of the same plan (JSBSim's ``run()``, the property reads,
the checks, the guidance input and law, the truth object, the sensor suite, the vehicle-state
reporter, the streamer's encode); ``rest`` is the chain minus their sum (the pipeline's loop,
``SimStep``, control writes, and what the isolated loops do not see). A pointer, not an exact
account: parts timed alone run with warmer caches than in the chain.
``jsbsim_run_inside_chain`` times JSBSim's ``run()`` alone while the chain runs (the clock
read around each call), against the bare loop timed the same way
(``jsbsim_run_bare_timed_alike``): how much slower the same library call is when the Python
of the chain runs between its calls.

    python bench/sim_throughput.py --duration 300 --out bench/results/sim_throughput.json
    python bench/sim_throughput.py --duration 300 --wind 8,-4,0 --wind-shear 0.142857 \
        --out /tmp/sim_throughput_wind_shear.json   # a wind profile written at every step

``--base REV --ab-rounds N`` is the before/after of a change on a loaded machine: child processes
of this script time bare JSBSim, the chain step by step and the chain in batches (``--ratio-only``,
best of ``--repeats`` each), alternately with the code of a ``git archive`` of REV and of this
tree first on ``PYTHONPATH``, N rounds; each child's ratios come from one process, and the JSON
keeps every round and the best of each side (``ab``).

    python bench/sim_throughput.py --duration 120 --repeats 2 --base REV --ab-rounds 3 \
        --out /tmp/sim_throughput_ab.json

``--wind`` / ``--wind-shear`` fly in a steady wind / a power-law wind profile (the profile is
written to JSBSim at every step: its cost shows as the difference to a run without it).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.pipeline import LOCKSTEP_BATCH, SimChain, SimSetup
from sim import presets
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan
from sim.sensors import SensorSuite
from sim.vehicle_state import VehicleStateReporter


def time_jsbsim_bare(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """JSBSim's own ``run()`` with the controls frozen at trim (no guidance, no truth)."""
    with Flight(cfg, load_plan(plan_name)) as flight:
        fdm = flight._fdm  # the bench measures the library underneath the adapter
        n = round(duration_s * cfg.rate_hz)
        t0 = time.process_time()
        for _ in range(n):
            fdm.run()
        return time.process_time() - t0


def time_jsbsim(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """The flight adapter: JSBSim + guidance law + SI truth."""
    plan = load_plan(plan_name)
    with Flight(cfg, plan) as flight:
        n = round(duration_s * cfg.rate_hz)
        t0 = time.process_time()
        for _ in range(n):
            flight.step()
        return time.process_time() - t0


def time_chain(cfg: FlightConfig, plan_name: str, duration_s: float, batch: int = 1
               ) -> tuple[float, int]:
    """The simulator half of the pipeline (:class:`hil.pipeline.SimChain`): JSBSim + guidance
    + sensor models + MAVLink encode, stepped in batches of ``batch`` steps."""
    setup = SimSetup(flight=cfg, plan=load_plan(plan_name), sensors=presets.suite_config(),
                     duration_s=duration_s, seed=1)
    frames = 0
    with SimChain(setup) as chain:
        t0 = time.process_time()
        for step in chain.steps(batch=batch):
            frames += len(step.frames)
        return time.process_time() - t0, frames


def _best(fn: Callable[[], float], repeats: int) -> float:
    return min(fn() for _ in range(repeats))


def _loop_us(fn: Callable[[], object], n: int) -> float:
    t0 = time.process_time()
    for _ in range(n):
        fn()
    return (time.process_time() - t0) / n * 1e6


class TimedRun:
    """JSBSim's FGFDMExec with its ``run()`` timed (CPU seconds summed in ``cpu_s``)."""

    def __init__(self, fdm: Any) -> None:
        self._fdm = fdm
        self.cpu_s = 0.0

    def run(self) -> Any:
        t0 = time.process_time()
        result = self._fdm.run()
        self.cpu_s += time.process_time() - t0
        return result

    def __getattr__(self, name: str) -> Any:
        return getattr(self._fdm, name)


def time_jsbsim_in_chain(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """CPU seconds of JSBSim's ``run()`` alone while it runs inside the sim chain (every other
    part of the chain running in between), the clock read around each call only."""
    setup = SimSetup(flight=cfg, plan=load_plan(plan_name), sensors=presets.suite_config(),
                     duration_s=duration_s, seed=1)
    with SimChain(setup) as chain:
        assert chain.flight is not None
        timed = TimedRun(chain.flight._fdm)
        chain.flight._fdm = timed  # the bench measures the library underneath the adapter
        for _ in chain.steps():
            pass
        return timed.cpu_s


def time_jsbsim_bare_timed(cfg: FlightConfig, plan_name: str, duration_s: float) -> float:
    """The bare loop with the clock read around each ``run()`` as in
    :func:`time_jsbsim_in_chain`: its reference (the clock reads cost a few us per call)."""
    with Flight(cfg, load_plan(plan_name)) as flight:
        timed = TimedRun(flight._fdm)
        for _ in range(round(duration_s * cfg.rate_hz)):
            timed.run()
        return timed.cpu_s


def breakdown(cfg: FlightConfig, plan_name: str, duration_s: float) -> dict[str, float]:
    """Microseconds per step of each part of a chain step, each timed alone (see the module
    docstring). The garbage collector is off meanwhile: the recorded flight (thousands of
    truth and sample objects held at once) would otherwise make its passes cost whichever part
    is being timed (the chain itself holds none of them; its collections stay in ``rest``)."""
    gc.disable()
    try:
        return _breakdown(cfg, plan_name, duration_s)
    finally:
        gc.enable()


def _breakdown(cfg: FlightConfig, plan_name: str, duration_s: float) -> dict[str, float]:
    setup = SimSetup(flight=cfg, plan=load_plan(plan_name), sensors=presets.suite_config(),
                     duration_s=duration_s, seed=1)
    out: dict[str, float] = {}
    with SimChain(setup) as chain:
        flight, streamer = chain.flight, chain.streamer
        assert flight is not None and streamer is not None
        n = round(duration_s * cfg.rate_hz)
        truths = [flight.step() for _ in range(n)]
        # the adapter's parts, on the flight's last state
        law = flight.guidance
        g_in = flight._guidance_input(flight.time_s)
        out["jsbsim_run"] = _loop_us(flight._fdm.run, n)
        out["property_reads"] = _loop_us(flight._sample, n)
        out["checks"] = _loop_us(flight._check, n)
        out["guidance_input"] = _loop_us(lambda: flight._guidance_input(1.0), n)
        out["guidance_law"] = _loop_us(lambda: law.update(g_in), n)
        out["truth_object"] = _loop_us(flight._read_truth, n)
        # the chain's parts, on the recorded truth
        suite = SensorSuite(setup.sensors, setup.seed, cfg.rate_hz)
        t0 = time.process_time()
        samples = [suite.step(tr) for tr in truths]
        out["sensor_models"] = (time.process_time() - t0) / n * 1e6
        reporter = VehicleStateReporter(setup.vehicle_state)
        t0 = time.process_time()
        reports = [reporter.step(tr.time_us, flight.vehicle_state) for tr in truths]
        out["vehicle_state"] = (time.process_time() - t0) / n * 1e6
        steps = [(tr, [*s, *r] if r else s) for tr, s, r in zip(truths, samples, reports,
                                                                   strict=True)]
        t0 = time.process_time()
        for tr, s in steps:
            streamer.frames(tr, s)
        out["encode_streamer"] = (time.process_time() - t0) / n * 1e6
    return out


def ratio_only(cfg: FlightConfig, plan_name: str, duration_s: float, repeats: int
               ) -> dict[str, float]:
    """Bare JSBSim, the chain step by step and in batches, CPU s (best of ``repeats``), with the
    ratios to bare: what ``--base`` compares."""
    bare = _best(lambda: time_jsbsim_bare(cfg, plan_name, duration_s), repeats)
    chain = _best(lambda: time_chain(cfg, plan_name, duration_s)[0], repeats)
    batched = _best(lambda: time_chain(cfg, plan_name, duration_s, LOCKSTEP_BATCH)[0], repeats)
    return {"jsbsim_bare_cpu_s": bare, "sim_chain_cpu_s": chain, "sim_chain_batched_cpu_s": batched,
            "chain_over_bare_ratio": chain / bare, "chain_batched_over_bare_ratio": batched / bare}


def ab_rounds(args: argparse.Namespace) -> dict[str, Any]:
    """``--ratio-only`` children of a git archive of ``args.base`` and of this tree, in turn."""
    script = Path(__file__).resolve()
    root = script.parent.parent
    child_args = ["--ratio-only", "--duration", str(args.duration), "--rate", str(args.rate),
                  "--plan", args.plan, "--wind", args.wind, "--wind-shear",
                  str(args.wind_shear), "--repeats", str(args.repeats)]
    rounds: dict[str, list[dict[str, float]]] = {"base": [], "this_tree": []}
    with tempfile.TemporaryDirectory(prefix="hilnav-simab-") as tmp:
        archive = subprocess.run(["git", "archive", args.base], cwd=root, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        for _ in range(args.ab_rounds):
            for side, tree in (("base", Path(tmp)), ("this_tree", root)):
                out = Path(tmp) / "child.json"
                subprocess.run([sys.executable, str(script), *child_args, "--out", str(out)],
                               env={**os.environ, "PYTHONPATH": str(tree)}, cwd=tree, check=True)
                rounds[side].append(json.loads(out.read_text()))
    keys = ("jsbsim_bare_cpu_s", "sim_chain_cpu_s", "sim_chain_batched_cpu_s",
            "chain_over_bare_ratio", "chain_batched_over_bare_ratio")
    best = {side: {key: min(r[key] for r in runs) for key in keys}
            for side, runs in rounds.items()}
    return {"base": args.base, "rounds": rounds, "best": best,
            "chain_cpu_this_over_base": best["this_tree"]["sim_chain_cpu_s"]
            / best["base"]["sim_chain_cpu_s"],
            "chain_batched_cpu_this_over_base": best["this_tree"]["sim_chain_batched_cpu_s"]
            / best["base"]["sim_chain_batched_cpu_s"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--plan", default="racetrack")
    ap.add_argument("--wind", default="0,0,0", help="steady wind N,E,D, m/s")
    ap.add_argument("--wind-shear", type=float, default=0.0, help="power-law shear exponent")
    ap.add_argument("--repeats", type=int, default=3, help="best of this many runs")
    ap.add_argument("--out", type=Path, default=Path("bench/results/sim_throughput.json"))
    ap.add_argument("--base", help="git revision: alternate its chain with this tree's (A/B)")
    ap.add_argument("--ab-rounds", type=int, default=3, help="rounds of the A/B")
    ap.add_argument("--ratio-only", action="store_true",
                    help="only bare JSBSim and the chain (what one round of the A/B runs)")
    args = ap.parse_args()
    wn, we, wd = (float(v) for v in args.wind.split(","))
    cfg = FlightConfig(rate_hz=args.rate, wind_ned_mps=(wn, we, wd),
                       wind_shear_exponent=args.wind_shear)
    load_before = os.getloadavg()[0]
    if args.ratio_only or args.base:
        part = ({"ab": ab_rounds(args)} if args.base
                else ratio_only(cfg, args.plan, args.duration, args.repeats))
        summary = {"benchmark": "sim_throughput", "python": platform.python_version(),
                   "machine": platform.machine(), "plan": args.plan, "rate_hz": args.rate,
                   "sim_duration_s": args.duration,
                   "timer": f"process_time (CPU seconds), best of {args.repeats} per child",
                   "load_average_1m_before": load_before, **part,
                   "load_average_1m_after": os.getloadavg()[0]}
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(summary, indent=2) + "\n")
        if not args.ratio_only:
            print(json.dumps(summary, indent=2))
        return
    bare = _best(lambda: time_jsbsim_bare(cfg, args.plan, args.duration), args.repeats)
    adapter = _best(lambda: time_jsbsim(cfg, args.plan, args.duration), args.repeats)
    chain_runs = [time_chain(cfg, args.plan, args.duration) for _ in range(args.repeats)]
    chain = min(c for c, _ in chain_runs)
    frames = chain_runs[0][1]
    batched = _best(lambda: time_chain(cfg, args.plan, args.duration, LOCKSTEP_BATCH)[0],
                    args.repeats)
    steps = round(args.duration * args.rate)
    parts = breakdown(cfg, args.plan, min(args.duration, 60.0))
    chain_us = chain / steps * 1e6
    parts["rest"] = chain_us - sum(parts.values())
    in_chain = _best(lambda: time_jsbsim_in_chain(cfg, args.plan, args.duration), args.repeats)
    bare_timed = _best(lambda: time_jsbsim_bare_timed(cfg, args.plan, args.duration),
                       args.repeats)

    def entry(cpu: float) -> dict[str, float]:
        return {"cpu_s": cpu, "us_per_step": cpu / steps * 1e6,
                "realtime_factor": args.duration / cpu}

    result = {
        "benchmark": "sim_throughput",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "rate_hz": args.rate,
        "plan": args.plan,
        "wind_ned_mps": [wn, we, wd],
        "wind_shear_exponent": args.wind_shear,
        "sim_duration_s": args.duration,
        "timer": f"process_time (CPU seconds of this process), best of {args.repeats}",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "jsbsim_bare_run": entry(bare),
        "adapter": entry(adapter),
        "sim_chain": {**entry(chain), "frames": frames},
        "sim_chain_batched": {**entry(batched), "batch": LOCKSTEP_BATCH,
                              "note": "steps(batch=LOCKSTEP_BATCH), as hilnav run flies"},
        "adapter_over_bare_ratio": adapter / bare,
        "chain_over_bare_ratio": chain / bare,
        "chain_over_adapter_ratio": chain / adapter,
        "chain_batched_over_bare_ratio": batched / bare,
        "breakdown_us_per_step": parts,
        "jsbsim_run_inside_chain": {
            **entry(in_chain),
            "note": "JSBSim's run() timed inside the chain (the other parts between its calls)",
        },
        "jsbsim_run_bare_timed_alike": entry(bare_timed),
        "jsbsim_inside_chain_over_bare_timed_alike_ratio": in_chain / bare_timed,
        "targets": {"chain_over_bare_ratio_max": 1.8},
    }
    result["meets_targets"] = min(chain, batched) / bare <= 1.8
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
