"""Benchmark: ``hilnav run`` end to end against bare JSBSim on the same flight and rate, and
the run's peak memory.

In one invocation it times

- ``jsbsim_bare``: JSBSim's own ``run()`` with the controls frozen at trim, for the scenario's
  aircraft, start, rate and duration (CPU seconds of this process);
- ``hilnav_run``: ``hilnav run SCENARIO --quiet`` as a child process on a copy of the scenario
  whose ``duration_s`` (and GNSS outages) are set by ``--duration``: the whole process
  (start-up, simulation, encode, decode, filter, scoring, plots, report) as the child's CPU
  seconds (``getrusage(RUSAGE_CHILDREN)``), its wall time, and its peak resident set size
  (``ru_maxrss``), plus the ``wall_s`` the run reports for itself in ``summary.json``.

The ratio ``hilnav_run cpu / jsbsim_bare cpu`` is the end-to-end speed figure (target <= 3);
the peak RSS of a 3600 s run is the memory figure (target < 500 MB). The load average is
recorded before and after.

``phases`` (unless ``--skip-phases``): where each CPU second of the run goes, from a second
child that runs the same ``hilnav run`` command in-process (``app([...])``) with CPU timers
(``process_time``) around its parts: ``interpreter_start`` (CPU before the first line of the
child), ``cli_import`` (``scenarios.cli.app``), ``setup`` (the command up to the flight: the
imports of the runner, pipeline and report modules, scenario load, filter build; the child
imports the runner and the pipeline first, to time their parts, inside the command's
``settled_heap`` as the command itself does), ``flight``
split into ``jsbsim_run`` (JSBSim's ``run()`` alone, the clock read around each call),
``decode_filter`` (the :class:`hil.pipeline.FusionRun` sink: decode + filter + collector, per
frame or per batch), ``tlog_write`` and ``sim_chain_python`` (the rest of the flight: adapter,
guidance, sensor models, encode, the pipeline's loop), ``scoring`` (``score`` minus its
reports), ``reports`` (JUnit, plots, HTML, and the import of their modules: matplotlib) and
``exit`` (the child's CPU after the command returned: interpreter teardown);
``setup_split_cpu_s`` and ``reports_split_cpu_s`` split those two phases (imports / the command
up to the flight; each plot, and matplotlib's layout pass and savefig over all plots). The
per-call timers (JSBSim's ``run()``, the sink, the tlog write: two clock reads each, 1-2 us per
call on this VM, ~0.7 s of a 300 s run) are measured in the child (``timer_us_per_call``) and
taken out of the phases they would inflate; what they cost is its own phase, ``phase_timers``,
so this child's total is that much above the plain run's. ``gc`` is the CPU of the garbage
collector's passes during the command, by generation (spread over the phases above, not a phase
of its own).

    python bench/run_end_to_end.py --duration 300 --out bench/results/run_end_to_end.json
    python bench/run_end_to_end.py --duration 3600 --skip-bare \\
        --out bench/results/run_end_to_end_1h.json

``--base REV`` adds ``ab``: the whole ``hilnav run`` child of revision REV (``git archive``
into a temporary folder, first on ``PYTHONPATH``) and of this tree, alternately,
``--ab-rounds`` times each, so a before / after ratio holds on a loaded machine; unless
``--skip-phases``, the phase-timed child of each tree too, alternately (``phases_cpu_s``,
per phase the best of the rounds in ``phases_best_cpu_s`` and their difference), and
``same_bytes_as_base``: per round, whether the two trees wrote ``run.tlog`` and the PNGs with
the same bytes.

    python bench/run_end_to_end.py --duration 300 --base REV --ab-rounds 3 \\
        --out /tmp/run_end_to_end_ab.json

The scenario (default ``turning-60s-outages``, 200 Hz) keeps its seed, sensors and plan; its
outage events are replaced by one 60 s outage every 120 s from 120 s on, so a long run has
outages throughout.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "scenarios" / "library"


def scenario_copy(source: Path, duration_s: float, folder: Path) -> Path:
    """The scenario YAML with ``duration_s`` and one 60 s GNSS outage every 120 s."""
    import yaml

    doc: dict[str, Any] = yaml.safe_load(source.read_text(encoding="utf-8"))
    doc["duration_s"] = duration_s
    starts = range(120, int(duration_s) - 60, 120)
    doc["events"] = [{"type": "gnss_outage", "at": s, "duration": 60} for s in starts]
    path = folder / f"{doc['name']}-{int(duration_s)}s.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def time_jsbsim_bare(scenario_path: Path) -> tuple[float, int]:
    """CPU seconds of JSBSim's ``run()`` alone (controls frozen at trim) over the scenario's
    duration at its rate, and the number of steps."""
    from scenarios.schema import load_scenario

    scn = load_scenario(scenario_path)
    return time_bare_loop(scn.flight_config(), scn.flight_plan(), scn.duration_s)


def time_bare_loop(cfg: Any, plan: Any, duration_s: float) -> tuple[float, int]:
    """:func:`time_jsbsim_bare` from the flight's configuration and plan (it imports only
    ``sim.flight``, not the scenario schema); CPU seconds and steps."""
    from sim.flight import Flight

    n = round(duration_s * cfg.rate_hz)
    with Flight(cfg, plan) as flight:
        fdm = flight._fdm  # the bench measures the library underneath the adapter
        t0 = time.process_time()
        for _ in range(n):
            fdm.run()
        return time.process_time() - t0, n


def time_hilnav_run(scenario_path: Path, out: Path, tree: Path = ROOT) -> dict[str, Any]:
    """Run ``hilnav run --quiet`` as a child (the code of ``tree``, first on ``PYTHONPATH``);
    its CPU, wall time, peak RSS and summary."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = [sys.executable, "-m", "scenarios.cli", "run", str(scenario_path), "--out", str(out),
           "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):  # 1: criteria failed, still a complete run
        sys.exit(f"hilnav run failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {
        "command": "python -m scenarios.cli run SCENARIO --out DIR --quiet",
        "exit_code": proc.returncode,
        "cpu_s": cpu,
        "wall_s": wall,
        "peak_rss_mb": after.ru_maxrss / 1024.0,  # Linux: kilobytes
        "summary_wall_s": summary["wall_s"],
        "summary_realtime_factor": summary["realtime_factor"],
        "sim_duration_s": summary["sim_duration_s"],
    }


def _timer_cost(rounds: int = 3, calls: int = 20_000) -> tuple[float, float]:
    """CPU seconds that one call timed the way the phases are timed adds: ``(inside, whole)``,
    the part the timer books to the timed phase and the whole cost of the timing (the rest
    lands in the enclosing phase); best of ``rounds``."""
    cpu = time.process_time
    acc = {"x": 0.0}
    count = {"x": 0}

    def noop() -> None:
        return None

    def wrapper() -> None:
        t0 = cpu()
        try:
            return noop()
        finally:
            acc["x"] += cpu() - t0
            count["x"] += 1

    inside, whole = [], []
    for _ in range(rounds):
        acc["x"] = 0.0
        t0 = cpu()
        for _ in range(calls):
            wrapper()
        wrapped = cpu() - t0
        t0 = cpu()
        for _ in range(calls):
            noop()
        plain = cpu() - t0
        inside.append(acc["x"] / calls)
        whole.append((wrapped - plain) / calls)
    return min(inside), min(whole)


def _child_phases(scenario_path: Path, out: Path, phases_json: Path) -> None:
    """The phase-timed ``hilnav run`` (see the module docstring); runs in the child."""
    cpu = time.process_time
    t_start = cpu()
    gc_n, gc_s, gc_t0 = [0, 0, 0], [0.0, 0.0, 0.0], [0.0]

    def gc_clock(phase: str, info: dict[str, int]) -> None:  # CPU of the collections
        if phase == "start":
            gc_t0[0] = cpu()
        else:
            gc_n[info["generation"]] += 1
            gc_s[info["generation"]] += cpu() - gc_t0[0]

    gc.callbacks.append(gc_clock)
    import scenarios.cli.app as cli_app

    t_cli = cpu()
    heap: Any = contextlib.nullcontext  # an older tree
    with contextlib.suppress(ImportError):
        from scenarios.cli import quick_exit

        heap = quick_exit.settled_heap
    with heap():  # as the run command imports them: no collections, frozen
        import hil.pipeline
        import scenarios.runner
    t_imports = cpu()

    acc: dict[str, float] = {"jsbsim_run": 0.0, "decode_filter": 0.0, "tlog_write": 0.0,
                             "flight": 0.0, "score_total": 0.0, "reports": 0.0}
    report_parts = ("plot_ground_track", "plot_errors", "plot_horizontal_vertical",
                    "plot_drift", "figure_tight_layout", "figure_savefig")
    acc.update(dict.fromkeys(report_parts, 0.0))
    calls: dict[str, int] = dict.fromkeys(acc, 0)
    marks: dict[str, float] = {}

    def timed(key: str, fn: Any) -> Any:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            t0 = cpu()
            try:
                return fn(*args, **kwargs)
            finally:
                acc[key] += cpu() - t0
                calls[key] += 1
        return wrapper

    class TimedFdm:  # JSBSim's FGFDMExec with run() timed
        def __init__(self, fdm: Any) -> None:
            self._fdm = fdm

        def run(self) -> Any:
            t0 = cpu()
            try:
                return self._fdm.run()
            finally:
                acc["jsbsim_run"] += cpu() - t0
                calls["jsbsim_run"] += 1

        def __getattr__(self, name: str) -> Any:
            return getattr(self._fdm, name)

    chain_enter = hil.pipeline.SimChain.__enter__

    def enter(self: Any) -> Any:
        chain = chain_enter(self)
        assert chain.flight is not None
        chain.flight._fdm = TimedFdm(chain.flight._fdm)
        return chain

    simulate = scenarios.runner.simulate

    def timed_simulate(*args: Any, **kwargs: Any) -> Any:
        marks.setdefault("flight_start", cpu())
        return timed("flight", simulate)(*args, **kwargs)

    hil.pipeline.SimChain.__enter__ = enter  # type: ignore[method-assign]
    hil.pipeline.FusionRun.__call__ = timed(  # type: ignore[method-assign]
        "decode_filter", hil.pipeline.FusionRun.__call__)
    if hasattr(hil.pipeline.FusionRun, "frames"):  # the sink of whole lockstep batches
        hil.pipeline.FusionRun.frames = timed(  # type: ignore[method-assign]
            "decode_filter", hil.pipeline.FusionRun.frames)
    scenarios.runner.TlogWriter.write = timed(  # type: ignore[method-assign]
        "tlog_write", scenarios.runner.TlogWriter.write)
    scenarios.runner.simulate = timed_simulate
    score = scenarios.runner.score

    def timed_score(*args: Any, **kwargs: Any) -> Any:
        t0 = cpu()
        # the report modules (matplotlib) are imported by score() itself in a plain run
        import scenarios.html
        import scenarios.junit
        import scenarios.report

        for module, name in ((scenarios.report, "write_plots"), (scenarios.html, "write_html"),
                             (scenarios.junit, "write_junit")):
            setattr(module, name, timed("reports", getattr(module, name)))
        # the reports, split (a handful of calls: no timer correction): each plot, and inside
        # them matplotlib's layout pass and the draw + PNG encoding of savefig
        from matplotlib.figure import Figure

        for name in ("plot_ground_track", "plot_errors", "plot_horizontal_vertical",
                     "plot_drift"):
            setattr(scenarios.report, name, timed(name, getattr(scenarios.report, name)))
        for name in ("tight_layout", "savefig"):
            setattr(Figure, name, timed(f"figure_{name}", getattr(Figure, name)))
        acc["reports"] += cpu() - t0
        return score(*args, **kwargs)

    scenarios.runner.score = timed("score_total", timed_score)
    code = 0
    entry = getattr(cli_app, "main", None) or cli_app.app  # main: the console entry point
    try:
        entry(["run", str(scenario_path), "--out", str(out), "--quiet"])
    except SystemExit as exc:
        code = int(exc.code or 0)
    t_end = cpu()
    gc.callbacks.remove(gc_clock)
    # the per-call timers (two clock reads each, ~1-2 us on this VM) are not the run's work:
    # what each books to its own phase and what it adds around it are measured and taken out
    inside, whole = _timer_cost()
    per_call = ("jsbsim_run", "decode_filter", "tlog_write")
    n_calls = sum(calls[k] for k in per_call)
    flight_start = marks.get("flight_start", t_end)
    split = {
        "interpreter_start": t_start,
        "cli_import": t_cli - t_start,
        "setup": flight_start - t_cli,
        "jsbsim_run": acc["jsbsim_run"] - calls["jsbsim_run"] * inside,
        "sim_chain_python": acc["flight"] - acc["jsbsim_run"] - acc["decode_filter"]
        - acc["tlog_write"] - n_calls * (whole - inside),
        "decode_filter": acc["decode_filter"] - calls["decode_filter"] * inside,
        "tlog_write": acc["tlog_write"] - calls["tlog_write"] * inside,
        "phase_timers": n_calls * whole,
        "scoring": acc["score_total"] - acc["reports"],
        "reports": acc["reports"],
    }
    split["other"] = t_end - sum(split.values())
    doc = {"exit_code": code, "cpu_s": split,
           "timer_us_per_call": {"inside": inside * 1e6, "whole": whole * 1e6},
           "timed_calls": {k: calls[k] for k in per_call},
           # setup, split: the runner's and pipeline's imports (numpy, scipy, pydantic,
           # pymavlink, JSBSim's module, ours), then the command up to the flight (scenario
           # load, the plots' module, filter build, run folder)
           "setup_split_cpu_s": {"runner_pipeline_imports": t_imports - t_cli,
                                 "command_to_flight": flight_start - t_imports},
           # inside ``reports``: each plot (its figure, layout, draw and PNG), and over all
           # plots matplotlib's tight-layout pass and savefig (draw + PNG encoding)
           "reports_split_cpu_s": {k: acc[k] for k in report_parts},
           "gc": {"collections_by_generation": gc_n, "cpu_s_by_generation": gc_s,
                  "cpu_s": sum(gc_s)}}
    # the child's own bookkeeping (calibration, this file) is neither the run nor its exit
    doc["cpu_s_at_return"] = cpu()
    phases_json.write_text(json.dumps(doc), encoding="utf-8")


def time_phases(scenario_path: Path, out: Path, tree: Path = ROOT) -> dict[str, Any]:
    """Run the phase-timed child on the code of ``tree``; its split (CPU s) with ``exit`` = its
    whole CPU minus the CPU at the command's return."""
    phases_json = out.parent / f"{out.name}-phases.json"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child-phases", str(scenario_path),
           str(out), str(phases_json), str(tree)]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0 or not phases_json.is_file():
        sys.exit(f"phase-timed run failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    child = json.loads(phases_json.read_text(encoding="utf-8"))
    if child["exit_code"] not in (0, 1):
        sys.exit(f"phase-timed hilnav run exited {child['exit_code']}:\n{proc.stderr[-2000:]}")
    total = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    split: dict[str, float] = child["cpu_s"]
    split["exit"] = total - child["cpu_s_at_return"]
    return {"command": "python bench/run_end_to_end.py --child-phases SCENARIO DIR JSON TREE",
            "cpu_s_total": total, "cpu_s": split,
            "share": {k: v / total for k, v in split.items()},
            "timer_us_per_call": child["timer_us_per_call"], "timed_calls": child["timed_calls"],
            "gc": child["gc"], "setup_split_cpu_s": child.get("setup_split_cpu_s"),
            "reports_split_cpu_s": child.get("reports_split_cpu_s")}


#: Files of a run folder that the same seed writes with the same bytes in any tree (summary.json
#: and junit.xml hold the run's wall time).
SAME_BYTES_FILES = ("run.tlog", "ground_track.png", "errors.png", "horizontal_vertical.png",
                    "drift.png")


def same_bytes(a: Path, b: Path) -> dict[str, bool]:
    """Per file of :data:`SAME_BYTES_FILES` in run folder ``a``: the same bytes in ``b``."""
    return {name: (a / name).read_bytes() == (b / name).read_bytes()
            for name in SAME_BYTES_FILES if (a / name).is_file()}


def time_ab(scenario_path: Path, base: str, rounds: int, folder: Path,
            phases: bool = True) -> dict[str, Any]:
    """``hilnav run`` of git revision ``base`` (exported with ``git archive``) and of this tree,
    alternately, ``rounds`` times each; CPU seconds of each child and the ratio of the bests;
    with ``phases``, also the phase-timed child of each tree, alternately, and per phase the
    best (lowest) of the rounds."""
    tree = folder / "base"
    tree.mkdir()
    archive = subprocess.run(["git", "archive", base], cwd=ROOT, check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    cpu: dict[str, list[float]] = {"before": [], "after": []}
    split: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    gc_cpu: dict[str, list[float]] = {"before": [], "after": []}
    setup_split: dict[str, list[Any]] = {"before": [], "after": []}
    reports_split: dict[str, list[Any]] = {"before": [], "after": []}
    for k in range(rounds):
        for key, src in (("before", tree), ("after", ROOT)):
            run = time_hilnav_run(scenario_path, folder / f"ab-{key}-{k}", src)
            cpu[key].append(run["cpu_s"])
            if phases:
                timed_run = time_phases(scenario_path, folder / f"abp-{key}-{k}", src)
                split[key].append(timed_run["cpu_s"])
                gc_cpu[key].append(timed_run["gc"]["cpu_s"])
                setup_split[key].append(timed_run["setup_split_cpu_s"])
                reports_split[key].append(timed_run["reports_split_cpu_s"])
    result: dict[str, Any] = {"base": base, "rounds": rounds, "cpu_s": cpu,
                              "after_over_before_best": min(cpu["after"]) / min(cpu["before"]),
                              "same_bytes_as_base": [same_bytes(folder / f"ab-before-{k}",
                                                                folder / f"ab-after-{k}")
                                                     for k in range(rounds)]}
    if phases:
        best = {key: {p: min(r[p] for r in rows) for p in rows[0]}
                for key, rows in split.items()}
        result["phases_cpu_s"] = split
        result["phases_gc_cpu_s"] = gc_cpu
        result["phases_setup_split_cpu_s"] = setup_split
        result["phases_reports_split_cpu_s"] = reports_split
        result["phases_best_cpu_s"] = best
        result["phases_best_after_minus_before"] = {
            p: best["after"][p] - best["before"][p] for p in best["after"]
            if p in best["before"]}
    return result


def main() -> None:
    if len(sys.argv) == 6 and sys.argv[1] == "--child-phases":
        sys.path.insert(0, sys.argv[5])  # the tree whose code runs (this one, or --base's)
        _child_phases(Path(sys.argv[2]), Path(sys.argv[3]), Path(sys.argv[4]))
        return
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds")
    ap.add_argument("--skip-bare", action="store_true", help="only the hilnav run (memory)")
    ap.add_argument("--skip-phases", action="store_true",
                    help="no phase-timed second run (the split of the CPU seconds)")
    ap.add_argument("--base", help="git revision: also time its hilnav run alternately with "
                                   "this tree's (--ab-rounds each)")
    ap.add_argument("--ab-rounds", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/run_end_to_end.json")
    args = ap.parse_args()
    from scenarios.schema import load_scenario

    if args.duration < 60:
        sys.exit("--duration must be >= 60 s")
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hilnav-bench-") as tmp:
        folder = Path(tmp)
        scn_path = scenario_copy(LIBRARY / f"{args.scenario}.yaml", args.duration, folder)
        rate_hz = load_scenario(scn_path).flight_config().rate_hz
        bare_cpu, steps = (None, 0) if args.skip_bare else time_jsbsim_bare(scn_path)
        run = time_hilnav_run(scn_path, folder / "run")
        phases = None if args.skip_phases else time_phases(scn_path, folder / "phases")
        ab = None if args.base is None else time_ab(scn_path, args.base, args.ab_rounds, folder,
                                                    phases=not args.skip_phases)
    result: dict[str, Any] = {
        "benchmark": "run_end_to_end",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "scenario": args.scenario,
        "sim_duration_s": args.duration,
        "timer": "CPU seconds (process_time here, getrusage for the child)",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "hilnav_run": run,
        "rate_hz": rate_hz,
        "hilnav_run_us_per_step": run["cpu_s"] / (args.duration * rate_hz) * 1e6,
    }
    if bare_cpu is not None:
        result["jsbsim_bare"] = {"cpu_s": bare_cpu, "steps": steps,
                                 "us_per_step": bare_cpu / steps * 1e6,
                                 "realtime_factor": args.duration / bare_cpu}
        result["run_over_bare_cpu_ratio"] = run["cpu_s"] / bare_cpu
        result["run_inside_over_bare_ratio"] = run["summary_wall_s"] / bare_cpu
    if ab is not None:
        result["ab"] = ab
    if phases is not None:
        result["phases"] = phases
        if bare_cpu is not None:
            result["phases"]["over_bare"] = {k: v / bare_cpu for k, v in phases["cpu_s"].items()}
    result["targets"] = {"run_over_bare_cpu_ratio_max": 3.0, "peak_rss_mb_max_1h": 500.0}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
