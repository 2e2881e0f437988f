"""Benchmark: the budget of issue #15's whole-pipeline ratio targets, and how much of it parts
that no optimisation inside hilnav's pipeline can remove already spend.

The issue's two ratio targets are a 300 s ``hilnav run`` within 3x of bare JSBSim's ``run()``
on the same flight and rate, and the simulator chain within 1.8x. It also sets absolute
targets for the parts: HIL_SENSOR encode and decode <= 5 us per frame each, and the filter
<= 30 us per IMU sample (<= 40 us with air-data states). This bench measures, in one
invocation, on the 300 s copy of ``turning-60s-outages`` that ``bench/run_end_to_end.py``
times (200 Hz; a copy whose outages repeat every 120 s):

- ``bare``: JSBSim's ``run()`` alone, controls frozen at trim, CPU s (best of ``--repeats``;
  :func:`run_end_to_end.time_jsbsim_bare`);
- ``bare_process``: a child process that imports only the simulator's flight adapter
  (``sim.flight``: numpy, JSBSim, and pydantic for the simulator's configurations), builds
  this scenario's flight (model load, initial conditions, trim; the flight configuration
  handed over pickled, so the child does not import the scenario schema, which pulls in the
  whole filter) and flies the bare loop; its whole CPU minus its loop's is ``floor_fixed_s``,
  the least a process that flies this scenario through hilnav's simulator pays before its
  first step (best of ``--repeats``);
- ``phases``: the phase-timed ``hilnav run`` child of :func:`run_end_to_end.time_phases`,
  best of ``--rounds`` per phase: what today's run spends on fixed costs (start-up, set-up,
  plots, exit), on JSBSim's ``run()`` inside the run, and on the per-step work (the simulator
  chain's Python, decode + filter + collector, the tlog);
- ``jsbsim_in_chain``: :func:`sim_throughput.time_jsbsim_in_chain` against
  :func:`sim_throughput.time_jsbsim_bare_timed` (the racetrack, 200 Hz, ``--chain-duration``
  s; best of ``--repeats``): how much slower JSBSim's own ``run()`` is when the chain's Python
  runs between its calls.

From them (``budget``, no further measurement):

- ``run_3x``: the budget (3 x bare), and against it
  ``components_at_their_own_targets`` (the chain at 1.8 x bare, one HIL_SENSOR decoded per step
  at 5 us, the filter at 30 us per IMU sample: what the run would cost if every part met its
  own target exactly and nothing else cost anything; with ``floor_fixed_s`` added too),
  ``fixed_now`` (start-up, set-up, scoring,
  exit; plots apart, the issue's parenthesis "sim + encode + decode + filter + scoring" does not
  name them) and ``left_for_per_step_work`` (the budget minus today's fixed costs and JSBSim's
  ``run()`` inside the run), with and without the plots, against the per-step work today;
- ``chain_1_8x``: the budget per step (1.8 x bare), JSBSim's ``run()`` inside the chain, and
  what is left per step for the guidance law, the truth, six sensor models and the encoder,
  against one HIL_SENSOR encode at its own 5 us target.

    python bench/speed_budget.py --out bench/results/speed_budget.json
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import platform
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from run_end_to_end import LIBRARY, scenario_copy, time_jsbsim_bare, time_phases
from sim_throughput import time_jsbsim_bare_timed, time_jsbsim_in_chain

from sim.flight import FlightConfig

ROOT = Path(__file__).resolve().parent.parent

#: The issue's absolute targets for the parts, us.
CODEC_US_PER_FRAME = 5.0
FILTER_US_PER_IMU_SAMPLE = 30.0
RUN_RATIO = 3.0
CHAIN_RATIO = 1.8

#: Phases of ``run_end_to_end``'s child that do not grow with the flight.
FIXED_PHASES = ("interpreter_start", "cli_import", "setup", "scoring", "other", "exit")
#: Phases that are per-step work besides JSBSim's ``run()`` (``phase_timers`` is the child's
#: own clock reads, not the run's).
PER_STEP_PHASES = ("sim_chain_python", "decode_filter", "tlog_write")


def bare_process_cpu_s(scenario_path: Path, folder: Path) -> tuple[float, float]:
    """The ``bare_process`` child (see the module doc): its whole CPU and its loop's CPU."""
    from scenarios.schema import load_scenario

    scn = load_scenario(scenario_path)
    flight = folder / "flight.pickle"  # the scenario's flight, for a child without the schema
    flight.write_bytes(pickle.dumps((scn.flight_config(), scn.flight_plan(), scn.duration_s)))
    code = ("import pickle, sys\n"
            "sys.path.insert(0, sys.argv[2])\n"
            "from run_end_to_end import time_bare_loop\n"
            "print(time_bare_loop(*pickle.loads(open(sys.argv[1], 'rb').read()))[0])\n")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-c", code, str(flight), str(ROOT / "bench")],
                          cwd=ROOT, check=True, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    whole = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return whole, float(proc.stdout.split()[-1])


def run_budget(bare_s: float, steps: int, floor_fixed_s: float,
               phases: dict[str, float]) -> dict[str, Any]:
    """The ``run_3x`` block of the module doc (seconds of CPU, and ratios to ``bare_s``)."""
    budget = RUN_RATIO * bare_s
    at_targets = {
        "sim_chain_at_1_8x_bare_s": CHAIN_RATIO * bare_s,
        "hil_sensor_decode_at_5us_s": CODEC_US_PER_FRAME * 1e-6 * steps,
        "filter_at_30us_s": FILTER_US_PER_IMU_SAMPLE * 1e-6 * steps,
    }
    at_targets_sum = sum(at_targets.values())
    fixed = sum(phases[p] for p in FIXED_PHASES)
    per_step_now = sum(phases[p] for p in PER_STEP_PHASES)
    jsbsim_inside = phases["jsbsim_run"]

    def left(with_plots: bool) -> dict[str, Any]:
        spent = fixed + jsbsim_inside + (phases["reports"] if with_plots else 0.0)
        rest = budget - spent
        return {"spent_before_per_step_work_s": spent, "left_s": rest,
                "left_us_per_step": rest / steps * 1e6,
                "per_step_work_now_us_per_step": per_step_now / steps * 1e6,
                "per_step_work_must_shrink_by": per_step_now / rest if rest > 0 else None}

    return {
        "budget_s": budget,
        "floor_fixed_s": floor_fixed_s,
        "floor_fixed_over_bare": floor_fixed_s / bare_s,
        "components_at_their_own_targets_s": at_targets,
        "components_at_their_own_targets_over_bare": at_targets_sum / bare_s,
        "components_at_targets_plus_floor_fixed_over_bare":
            (at_targets_sum + floor_fixed_s) / bare_s,
        "fixed_now_s": fixed,
        "reports_now_s": phases["reports"],
        "jsbsim_run_inside_run_s": jsbsim_inside,
        "with_plots": left(True),
        "without_plots": left(False),
    }


def chain_budget(bare_timed_s: float, in_chain_s: float, steps: int) -> dict[str, Any]:
    """The ``chain_1_8x`` block of the module doc (us per step)."""
    bare_us = bare_timed_s / steps * 1e6
    inside_us = in_chain_s / steps * 1e6
    budget_us = CHAIN_RATIO * bare_us
    return {"bare_us_per_step": bare_us, "budget_us_per_step": budget_us,
            "jsbsim_run_inside_chain_us_per_step": inside_us,
            "jsbsim_inside_over_bare": in_chain_s / bare_timed_s,
            "left_us_per_step": budget_us - inside_us,
            "hil_sensor_encode_at_its_target_us": CODEC_US_PER_FRAME}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds of the run")
    ap.add_argument("--chain-duration", type=float, default=120.0,
                    help="simulated seconds of the chain's JSBSim-inside timing")
    ap.add_argument("--repeats", type=int, default=3, help="best of this many (bare, chain)")
    ap.add_argument("--rounds", type=int, default=2, help="phase-timed runs (best per phase)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/speed_budget.json")
    args = ap.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="hilnav-budget-") as tmp:
        folder = Path(tmp)
        scenario = scenario_copy(LIBRARY / f"{args.scenario}.yaml", args.duration, folder)
        print("bare JSBSim ...", flush=True)
        bare_runs = [time_jsbsim_bare(scenario) for _ in range(args.repeats)]
        bare_s, steps = min(s for s, _ in bare_runs), bare_runs[0][1]
        print("bare process ...", flush=True)
        floor_fixed_s = min(whole - loop for whole, loop in (
            bare_process_cpu_s(scenario, folder) for _ in range(args.repeats)))
        rounds = []
        for i in range(args.rounds):
            print(f"phase-timed hilnav run {i + 1}/{args.rounds} ...", flush=True)
            rounds.append(time_phases(scenario, folder / f"run{i}")["cpu_s"])
    phases = {p: min(r[p] for r in rounds) for p in rounds[0]}
    print("JSBSim inside the chain ...", flush=True)
    cfg = FlightConfig(rate_hz=200.0)
    chain_steps = round(args.chain_duration * cfg.rate_hz)
    in_chain = min(time_jsbsim_in_chain(cfg, "racetrack", args.chain_duration)
                   for _ in range(args.repeats))
    bare_timed = min(time_jsbsim_bare_timed(cfg, "racetrack", args.chain_duration)
                     for _ in range(args.repeats))
    result = {
        "benchmark": "speed_budget",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "scenario": f"{args.scenario} ({args.duration:g} s copy, outages every 120 s)",
        "timer": "CPU seconds (process_time / getrusage of children); best of repeats/rounds",
        "load_average_before": list(load_before),
        "bare_s": bare_s,
        "steps": steps,
        "bare_us_per_step": bare_s / steps * 1e6,
        "phases_best_cpu_s": phases,
        "budget": {"run_3x": run_budget(bare_s, steps, floor_fixed_s, phases),
                   "chain_1_8x": chain_budget(bare_timed, in_chain, chain_steps)},
        "load_average_after": list(os.getloadavg()),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result["budget"], indent=2))


if __name__ == "__main__":
    main()
