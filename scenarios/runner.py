"""``hilnav run``: fly a scenario in lockstep, fuse it, score it, write the run folder.

One process, simulated time only: JSBSim -> sensor models -> fault injection (the scenario's
timeline) -> MAVLink 2 bytes (the same encoder the live path uses) -> ``run.tlog`` and, in
memory, the decoder -> NavFilter with the scenario's bridging and altitude methods. The same
scenario and seed give the same bytes and the same numbers on every machine.

The flight and the fusion are the pipeline's (:mod:`hil.pipeline`); this module turns a
:class:`~scenarios.schema.Scenario` into its :class:`~hil.pipeline.SimSetup` and filter, scores
the run with the one scorer (:func:`scenarios.summary.score_run`) and writes the run folder.
``hilnav compare`` flies once (:func:`simulate`) and fuses the *same* frames with several
methods.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fusion.config import FilterConfig
from hil.pipeline import Flown, FusionRun, SimSetup, build_filter, fly, tee
from hil.pipeline import filter_config as pipeline_filter_config
from hil.tlog import TlogWriter
from scenarios.jsonable import plain_dict
from scenarios.schema import Scenario
from scenarios.summary import RunInfo, Scored, score_run, write_summary
from sim.faults.events import event_type_name

ProgressFn = Callable[[float], None]

#: Event types whose effect on the navigation is scored as an event (time to detect etc.).
_SCORED_EVENT_KINDS = {
    "gnss_spoof_drift": "spoof",
    "gnss_spoof_hijack": "spoof",
    "gnss_jamming": "jamming",
    "baro_glitch": "glitch",
}


@dataclass(frozen=True)
class RunResult:
    summary: dict[str, Any]
    out_dir: Path
    files: list[Path]

    @property
    def passed(self) -> bool:
        return bool(self.summary.get("passed"))


def sim_setup(scenario: Scenario) -> SimSetup:
    """What the pipeline flies for ``scenario`` (its seed, sensors, plan and fault timeline)."""
    return SimSetup(
        flight=scenario.flight_config(),
        plan=scenario.flight_plan(),
        sensors=scenario.sensor_config(),
        duration_s=scenario.duration_s,
        seed=scenario.seed,
        faults=tuple(scenario.fault_events()),
    )


def filter_config(scenario: Scenario, altitude: str | None = None) -> FilterConfig:
    """The filter tuned from the scenario's IMU datasheet preset and its GNSS receiver's error
    model (position-bias states for a time-correlated receiver), with its altitude method
    its air-data choice (``fusion.airspeed``), its alignment (``fusion.align``), and the
    magnetic reference at the scenario's date (``date``)."""
    config = pipeline_filter_config(scenario.imu_preset, scenario.sensor_config().gnss,
                                    altitude or scenario.fusion.altitude,
                                    scenario.fusion.airspeed, scenario.fusion.align)
    mag = config.mag.model_copy(update={"decimal_year": scenario.decimal_year})
    return config.model_copy(update={"mag": mag})


def simulate(scenario: Scenario, sink: Callable[[int, bytes], None], *,
             progress: ProgressFn | None = None) -> Flown:
    """Fly ``scenario`` (its seed) and hand every frame to ``sink(time_us, frame)``."""
    return fly(sim_setup(scenario), sink, progress=progress)


def event_windows(scenario: Scenario, end_s: float) -> list[dict[str, Any]]:
    """The scenario's timeline as scored windows ``{type, kind, start_s, end_s}``."""
    rows = []
    for ev in scenario.fault_events():
        type_name = event_type_name(ev)
        start = float(ev.start_s)
        stop = end_s if ev.duration_s is None else min(end_s, start + float(ev.duration_s))
        rows.append({"type": type_name, "kind": _SCORED_EVENT_KINDS.get(type_name, "generic"),
                     "start_s": start, "end_s": stop})
    return rows


def score(
    scenario: Scenario,
    run: FusionRun,
    out_dir: Path,
    *,
    bridge: str,
    altitude: str,
    sim_duration_s: float,
    wall_s: float,
    health_extra: dict[str, Any] | None = None,
    reports: bool = True,
) -> tuple[dict[str, Any], list[Path]]:
    """Build ``summary.json`` (+ JUnit XML, plots and HTML when ``reports``) in ``out_dir``."""
    col = run.collector
    assert col is not None
    end_s = col.end_s()
    info = RunInfo(scenario=scenario.name, seed=scenario.seed, sim_duration_s=sim_duration_s,
                   wall_s=wall_s, bridge=bridge, altitude=altitude)
    scored: Scored = score_run(run, info, criteria=scenario.criteria(),
                               events=event_windows(scenario, end_s),
                               health_extra=health_extra, with_series=True)
    summary = scored.summary
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [out_dir / "summary.json"]
    write_summary(summary, files[0])
    if reports:
        from scenarios.html import write_html
        from scenarios.junit import write_junit
        from scenarios.report import write_plots

        junit = out_dir / "junit.xml"
        write_junit(summary, junit, suite_name=f"hilnav.{scenario.name}")
        plots = write_plots(scored.estimate, scored.truth, scored.errors, scored.outages,
                            out_dir, events=summary["events"])
        html = out_dir / "report.html"
        write_html(summary, plots, html)
        files += [junit, *plots, html]
    return summary, files


def run_scenario(
    scenario: Scenario,
    out_dir: Path,
    *,
    bridge: str | None = None,
    altitude: str | None = None,
    progress: ProgressFn | None = None,
    tlog: bool = True,
    reports: bool = True,
) -> RunResult:
    """Fly, fuse and score one scenario (seed and overrides already applied to ``scenario``)."""
    bridge = bridge or scenario.fusion.bridge
    altitude = altitude or scenario.fusion.altitude
    config = filter_config(scenario, altitude)
    nav = build_filter(config, bridge)  # bad names fail before anything flies
    out_dir.mkdir(parents=True, exist_ok=True)
    log_path = out_dir / "run.tlog"
    fusion = FusionRun(config, bridge, nav=nav)
    t0 = time.perf_counter()
    if tlog:
        with TlogWriter(log_path) as log:
            flown = simulate(scenario, tee(lambda t, f: log.write(f, t), fusion),
                             progress=progress)
    else:
        flown = simulate(scenario, fusion, progress=progress)
    wall = time.perf_counter() - t0
    extra: dict[str, Any] = {
        "faults": flown.fault_counters,
        "fault_log": [plain_dict(e) for e in flown.fault_log],
        "fusion_us_per_sample": fusion.fusion_us_per_sample,
    }
    if flown.ended is not None:
        extra["flight_ended"] = str(flown.ended)
    summary, files = score(
        scenario, fusion, out_dir, bridge=bridge, altitude=altitude,
        sim_duration_s=flown.sim_duration_s, wall_s=wall, health_extra=extra,
        reports=reports)
    if flown.ended is not None:
        # a crash is a failed run whatever the criteria say
        summary["passed"] = False
        write_summary(summary, files[0])
    if tlog:
        files.insert(1, log_path)
    return RunResult(summary, out_dir, files)
