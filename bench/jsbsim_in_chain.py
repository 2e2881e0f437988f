"""Benchmark: why JSBSim's ``run()`` costs more inside the sim chain than in a bare loop.

Every case flies the same aircraft, start and rate (c172x, racetrack, 200 Hz by default) and
reads the CPU clock (``process_time``) around each ``run()`` call only, so the figure is
JSBSim's own time per step under each condition (best of ``--repeats``, the cases run in
turn, round after round, so a change of load hits them alike). The hypotheses, one case each:

- ``bare``: the controls frozen at the trim, nothing between the calls (the reference);
- ``bare_same_flight``: the controls the guidance law wrote at each step of a guided flight,
  replayed (four property writes before each call): the chain's flight conditions (turns,
  climbs, throttle changes) and its property writes, without its Python. The flight is checked
  to be the guided one (its last state bit-identical);
- ``bare_touch_<N>MB``: the bare loop with a numpy pass over N MB between the calls (evicts
  the CPU caches by N MB of reads and nothing else);
- ``adapter``: :meth:`sim.flight.Flight.step` (guidance, property reads, checks, truth);
- ``chain``: :class:`hil.pipeline.SimChain` stepped one step at a time (sensor models and the
  encoder between the calls); ``chain_gc_off``: the same with the garbage collector off;
- ``chain_batch_<K>``: the chain stepped in batches of K steps (``steps(batch=K)``: JSBSim
  and the guidance law K steps in a row, then the sensors and the encoder).

    python bench/jsbsim_in_chain.py --out bench/results/jsbsim_in_chain.json
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hil.pipeline import LOCKSTEP_BATCH, SimChain, SimSetup
from sim import presets
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # bench.sim_throughput
    sys.path.insert(0, str(ROOT))

from bench.sim_throughput import TimedRun  # noqa: E402

TOUCH_MB = (0.5, 1.0, 2.0, 4.0, 16.0)


def _controls(flight: Flight) -> tuple[float, ...]:
    nodes = [flight._n_ail, flight._n_ele, flight._n_rud, *flight._n_thr]
    return tuple(node.get_double_value() for node in nodes)


def guided_controls(cfg: FlightConfig, plan: str, n: int) -> tuple[list[tuple[float, ...]],
                                                                    list[float]]:
    """The controls JSBSim flew with at each of ``n`` guided steps, and the last state."""
    with Flight(cfg, load_plan(plan)) as flight:
        out = []
        for _ in range(n):
            flight.step()
            out.append(_controls(flight))  # written before this step's run(), held since
        return out, flight._sample()


def bare(cfg: FlightConfig, plan: str, n: int,
         between: Callable[[], object] | None = None,
         replay: list[tuple[float, ...]] | None = None,
         expect_last: list[float] | None = None) -> float:
    """JSBSim's run() alone, with ``between`` called after each call or the controls of
    ``replay`` written before each call; CPU us per call."""
    with Flight(cfg, load_plan(plan)) as flight:
        fdm = flight._fdm  # the bench measures the library underneath the adapter
        nodes = [flight._n_ail, flight._n_ele, flight._n_rud, *flight._n_thr]
        setters = [node.set_double_value for node in nodes]
        cpu = 0.0
        for k in range(n):
            if replay is not None:
                for set_value, value in zip(setters, replay[k], strict=True):
                    set_value(value)
            t0 = time.process_time()
            fdm.run()
            cpu += time.process_time() - t0
            if between is not None:
                between()
        if expect_last is not None and flight._sample() != expect_last:
            raise AssertionError("the replayed controls did not fly the guided flight")
        return cpu / n * 1e6


def adapter(cfg: FlightConfig, plan: str, n: int) -> float:
    with Flight(cfg, load_plan(plan)) as flight:
        timed = TimedRun(flight._fdm)
        flight._fdm = timed
        for _ in range(n):
            flight.step()
        return timed.cpu_s / n * 1e6


def chain(cfg: FlightConfig, plan: str, n: int, *, batch: int = 1, gc_off: bool = False
          ) -> float:
    setup = SimSetup(flight=cfg, plan=load_plan(plan), sensors=presets.suite_config(),
                     duration_s=n / cfg.rate_hz, seed=1)
    with SimChain(setup) as sim:
        assert sim.flight is not None
        timed = TimedRun(sim.flight._fdm)
        sim.flight._fdm = timed
        if gc_off:
            gc.disable()
        try:
            steps = sum(1 for _ in sim.steps(batch=batch))
        finally:
            gc.enable()
        return timed.cpu_s / steps * 1e6


def _touching(cfg: FlightConfig, plan: str, n: int, buffer: np.ndarray) -> Callable[[], float]:
    return lambda: bare(cfg, plan, n, between=buffer.sum)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=60.0, help="simulated seconds per case")
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--plan", default="racetrack")
    ap.add_argument("--repeats", type=int, default=3, help="rounds; best of them per case")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/jsbsim_in_chain.json")
    args = ap.parse_args()
    cfg = FlightConfig(rate_hz=args.rate)
    n = round(args.duration * args.rate)
    plan = args.plan
    replay, last = guided_controls(cfg, plan, n)
    buffers = {mb: np.ones(round(mb * 2**20 / 8)) for mb in TOUCH_MB}
    cases: dict[str, Callable[[], float]] = {
        "bare": lambda: bare(cfg, plan, n),
        "bare_same_flight": lambda: bare(cfg, plan, n, replay=replay, expect_last=last),
        **{f"bare_touch_{mb:g}MB": _touching(cfg, plan, n, buffers[mb]) for mb in TOUCH_MB},
        "adapter": lambda: adapter(cfg, plan, n),
        "chain": lambda: chain(cfg, plan, n),
        "chain_gc_off": lambda: chain(cfg, plan, n, gc_off=True),
        "chain_batch_20": lambda: chain(cfg, plan, n, batch=20),
        f"chain_batch_{LOCKSTEP_BATCH}": lambda: chain(cfg, plan, n, batch=LOCKSTEP_BATCH),
    }
    load_before = os.getloadavg()[0]
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(args.repeats):
        for name, case in cases.items():
            best[name] = min(best[name], case())
    result = {
        "benchmark": "jsbsim_in_chain",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "plan": plan,
        "rate_hz": args.rate,
        "steps_per_case": n,
        "timer": f"process_time around each run() call, best of {args.repeats} rounds",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "jsbsim_run_us_per_step": best,
        "over_bare": {k: v / best["bare"] for k, v in best.items()},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
