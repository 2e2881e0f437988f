"""``hilnav run``: fly a scenario in lockstep, fuse it, score it, write the run folder.

One process, simulated time only: JSBSim -> sensor models -> fault injection (the scenario's
timeline) -> MAVLink 2 bytes (the same encoder the live path uses) -> ``run.tlog`` and, in
memory, the decoder -> NavFilter with the scenario's bridging and altitude methods. The same
scenario and seed give the same bytes and the same numbers on every machine.

The pieces are split so ``hilnav compare`` can fly once and fuse the *same* frames with several
methods: :func:`simulate` produces frames, :func:`fuse` runs one filter over frames,
:func:`score` turns the collected tracks into ``summary.json`` and the reports.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fusion.bridging.registry import make_bridge
from fusion.config import FilterConfig
from fusion.filter import NavFilter
from hil.codec import Decoder
from hil.streamer import LockstepReport, SensorStreamer, run_lockstep
from hil.tlog import TlogWriter
from hil.tuning import filter_config_for_imu, filter_gnss_config, gnss_state_layout
from scenarios import metrics
from scenarios.collect import Collector
from scenarios.jsonable import plain_dict
from scenarios.schema import Scenario
from scenarios.summary import RunInfo, build_summary, write_summary
from sim.faults import FaultInjector
from sim.flight import Flight
from sim.sensors import SensorSuite

Frame = tuple[int, bytes]
ProgressFn = Callable[[float], None]

#: Event types whose effect on the navigation is scored as an event (time to detect etc.).
_SCORED_EVENT_KINDS = {
    "gnss_spoof_drift": "spoof",
    "gnss_spoof_hijack": "spoof",
    "gnss_jamming": "jamming",
    "baro_glitch": "glitch",
}


@dataclass(frozen=True)
class Simulated:
    """What the simulator produced for one seed."""

    report: LockstepReport
    fault_log: list[Any]
    fault_counters: dict[str, int]


@dataclass
class Fused:
    """One filter run over a frame stream."""

    collector: Collector
    nav: NavFilter
    decoder: Decoder
    wall_s: float
    samples: int
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RunResult:
    summary: dict[str, Any]
    out_dir: Path
    files: list[Path]

    @property
    def passed(self) -> bool:
        return bool(self.summary.get("passed"))


def filter_config(scenario: Scenario, altitude: str | None = None) -> FilterConfig:
    """The filter tuned from the scenario's IMU datasheet preset and its GNSS receiver's error
    model (position-bias states for a time-correlated receiver), with its altitude method."""
    config = filter_config_for_imu(scenario.imu_preset)
    method = altitude or scenario.fusion.altitude
    return config.model_copy(update={
        "altitude": config.altitude.model_copy(update={"method": method}),
        "gnss": filter_gnss_config(scenario.sensor_config().gnss, config.gnss),
        "state_layout": gnss_state_layout(scenario.sensor_config().gnss, config.state_layout),
    })


def simulate(
    scenario: Scenario,
    sink: Callable[[int, bytes], None],
    *,
    progress: ProgressFn | None = None,
) -> Simulated:
    """Fly ``scenario`` (its seed) and hand every frame to ``sink(time_us, frame)``."""
    flight_cfg = scenario.flight_config()
    suite = SensorSuite(scenario.sensor_config(), scenario.seed, flight_cfg.rate_hz)
    with Flight(flight_cfg, scenario.flight_plan()) as flight:
        faults = FaultInjector(scenario.fault_events(), seed=scenario.seed, t0_us=flight.time_us)
        streamer = SensorStreamer(faults=faults)
        report = run_lockstep(flight, suite, streamer, scenario.duration_s, sink, progress=progress)
    return Simulated(report, list(faults.log), dict(faults.counters))


def fuse(
    frames: Iterable[Frame],
    config: FilterConfig,
    bridge: str,
) -> Fused:
    """Decode ``frames`` and run one NavFilter with bridging method ``bridge`` over them."""
    nav = NavFilter(config, bridge=make_bridge(bridge, config.bridge))
    decoder = Decoder()
    col = Collector()
    n = 0
    t0 = time.perf_counter()
    for _t, frame in frames:
        decoded = decoder.feed(frame)
        n += len(decoded)
        col.feed(nav, (d.sample for d in decoded))
    wall = time.perf_counter() - t0
    return Fused(col, nav, decoder, wall, n)


class _StreamingFuser:
    """A frame sink that writes the .tlog and fuses as the simulator flies (one pass)."""

    def __init__(self, log: TlogWriter | None, config: FilterConfig, bridge: str) -> None:
        self.log = log
        self.nav = NavFilter(config, bridge=make_bridge(bridge, config.bridge))
        self.decoder = Decoder()
        self.col = Collector()
        self.samples = 0
        self.fuse_s = 0.0

    def __call__(self, time_us: int, frame: bytes) -> None:
        if self.log is not None:
            self.log.write(frame, time_us)
        t0 = time.perf_counter()
        decoded = self.decoder.feed(frame)
        self.samples += len(decoded)
        self.col.feed(self.nav, (d.sample for d in decoded))
        self.fuse_s += time.perf_counter() - t0


def event_windows(scenario: Scenario, end_s: float) -> list[dict[str, Any]]:
    """The scenario's timeline as scored windows ``{type, kind, start_s, end_s}``."""
    rows = []
    for ev in scenario.fault_events():
        type_name = _type_name(ev)
        start = float(ev.start_s)
        stop = end_s if ev.duration_s is None else min(end_s, start + float(ev.duration_s))
        rows.append({"type": type_name, "kind": _SCORED_EVENT_KINDS.get(type_name, "generic"),
                     "start_s": start, "end_s": stop})
    return rows


def _type_name(event: object) -> str:
    from sim.faults import EVENT_TYPES

    for name, cls in EVENT_TYPES.items():
        if type(event) is cls:
            return name
    return type(event).__name__


def score(
    scenario: Scenario,
    fused: Fused | _StreamingFuser,
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
    col = fused.collector if isinstance(fused, Fused) else fused.col
    nav = fused.nav
    estimate = col.estimate_track()
    truth = col.truth_track()
    end_s = min(float(estimate.time_s[-1]), float(truth.time_s[-1]))
    outages = metrics.outages_from_fix_times(
        np.asarray(col.fix_times_us, dtype=float) * 1e-6, end_s=end_s)
    info = RunInfo(scenario=scenario.name, seed=scenario.seed, sim_duration_s=sim_duration_s,
                   wall_s=wall_s, bridge=bridge, altitude=altitude)
    health: dict[str, Any] = {"filter": plain_dict(nav.health),
                              "decoder": plain_dict(fused.decoder.counters)}
    health.update(health_extra or {})
    summary, err = build_summary(
        info, estimate, truth, outages, criteria=scenario.criteria(), health=health,
        events=event_windows(scenario, end_s), series=col.series())
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [out_dir / "summary.json"]
    write_summary(summary, files[0])
    if reports:
        from scenarios.html import write_html
        from scenarios.junit import write_junit
        from scenarios.report import write_plots

        junit = out_dir / "junit.xml"
        write_junit(summary, junit, suite_name=f"hilnav.{scenario.name}")
        plots = write_plots(estimate, truth, err, outages, out_dir, events=summary["events"])
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
    make_bridge(bridge)  # bad names fail before anything flies
    out_dir.mkdir(parents=True, exist_ok=True)
    log_path = out_dir / "run.tlog"
    t0 = time.perf_counter()
    if tlog:
        with TlogWriter(log_path) as log:
            sink = _StreamingFuser(log, config, bridge)
            sim = simulate(scenario, sink, progress=progress)
    else:
        sink = _StreamingFuser(None, config, bridge)
        sim = simulate(scenario, sink, progress=progress)
    wall = time.perf_counter() - t0
    extra: dict[str, Any] = {
        "faults": sim.fault_counters,
        "fault_log": [plain_dict(e) for e in sim.fault_log],
        "fusion_us_per_sample": 1e6 * sink.fuse_s / max(sink.samples, 1),
    }
    if sim.report.ended is not None:
        extra["flight_ended"] = str(sim.report.ended)
    summary, files = score(
        scenario, sink, out_dir, bridge=bridge, altitude=altitude,
        sim_duration_s=sim.report.sim_duration_s, wall_s=wall, health_extra=extra,
        reports=reports)
    if sim.report.ended is not None:
        # a crash is a failed run whatever the criteria say
        summary["passed"] = False
        write_summary(summary, files[0])
    if tlog:
        files.insert(1, log_path)
    return RunResult(summary, out_dir, files)
