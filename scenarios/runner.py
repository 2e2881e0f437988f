"""``hilnav run``: fly a scenario in lockstep, fuse it, score it, write the run folder.

One process, simulated time only: JSBSim -> sensor models -> fault injection (the scenario's
timeline) -> MAVLink 2 bytes (the same encoder the live path uses) -> ``run.tlog`` and, in
memory, the decoder -> NavFilter with the scenario's bridging and altitude methods. The same
scenario and seed give the same bytes and the same numbers on every machine.

With ``autopilot: px4 | ardupilot`` the autopilot flies instead of hilnav's guidance: the one
autopilot loop (:func:`hil.autopilot.fly_with_autopilot`) runs the same sensor chain in lockstep
with the autopilot, every frame goes to the same fusion and ``run.tlog``, the autopilot's own
estimate is recorded from its telemetry (:class:`hil.autopilot.telemetry.AutopilotTelemetry`)
and scored beside hilnav's (``summary.json``'s ``autopilot`` section,
:mod:`scenarios.autopilot_summary`). A stalled autopilot fails the run and says so.

With ``aiding: hilnav`` and ``unaided_baseline`` the scenario is flown twice
(:func:`scenarios.unaided_baseline.run_with_unaided_baseline`): first unaided, then aided;
the :class:`~scenarios.unaided_baseline.UnaidedBaseline` given to both runs is recorded by the
first one's scoring and scored into the second one's card (:func:`score`'s ``baseline``).

A flight that ends early (ground impact, stall of the aircraft, an autopilot that stopped
sending controls) is scored as far as it flew: events that had not begun are listed in
``events_not_reached``, events it cut short are scored up to its end and carry
``"clipped": true`` with their ``planned_end_s``. Whatever fails a run besides its criteria
(the early end, a stalled autopilot, a denial step the autopilot did not acknowledge) is one
sentence in ``failures`` (present only when there is one) and ``passed`` is false.

With ``autopilot.binary`` hilnav starts the autopilot's SITL binary itself
(:meth:`AutopilotRun.start`, :mod:`hil.autopilot.launch`): on free loopback ports, its output
in ``autopilot.log`` of the run folder, the scenario's simulator link, telemetry and ArduPilot
MAVLink port pointed at it, stopped by PID when the flight ends, however it ends. The
summary's ``autopilot.process`` records the binary, its version, instance, ports and how it
ended.

The flight and the fusion are the pipeline's (:mod:`hil.pipeline`); this module turns a
:class:`~scenarios.schema.Scenario` into its :class:`~hil.pipeline.SimSetup` and filter, scores
the run with the one scorer (:func:`scenarios.summary.score_run`) and writes the run folder.
``hilnav compare`` flies once (:func:`simulate`) and fuses the *same* frames with several
methods.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fusion.config import FilterConfig
from hil.pipeline import Flown, FrameSink, FusionRun, SimSetup, SimStep, build_filter, fly, tee
from hil.pipeline import filter_config as pipeline_filter_config
from hil.thermal_cal import part_thermal_tuning, thermal_tuning
from hil.tlog import TlogWriter
from scenarios.jsonable import plain_dict
from scenarios.schema import Scenario
from scenarios.summary import RunInfo, Scored, score_run, write_summary
from sim.faults.events import event_type_name

if TYPE_CHECKING:  # the autopilot's modules (its link, its telemetry) load when one flies
    from hil.autopilot import AutopilotBackend, AutopilotFlown
    from hil.autopilot.aiding import CompanionAiding
    from hil.autopilot.commander import Commander
    from hil.autopilot.launch import AutopilotProcess
    from hil.autopilot.telemetry import AutopilotTelemetry
    from scenarios.autopilot_summary import ScoredAutopilot
    from scenarios.unaided_baseline import UnaidedBaseline, UnaidedFlight

ProgressFn = Callable[[float], None]

SETTLE_S = 60.0
"""Seconds after the start and after each outage / event left out of the GNSS-on figures
(hilnav's and the autopilot's alike)."""

#: Event types whose effect on the navigation is scored as an event (time to detect etc.).
_SCORED_EVENT_KINDS = {
    "gnss_spoof_drift": "spoof",
    "gnss_spoof_hijack": "spoof",
    "gnss_jamming": "jamming",
    "baro_glitch": "glitch",
}


class AutopilotAbsent(RuntimeError):
    """The autopilot never connected, or stalled (or failed a scripted step) before there was
    anything to score."""


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
    fusion = scenario.fusion
    cal = None
    if fusion.thermal_cal is not None:
        cal = Path(fusion.thermal_cal)
        base = scenario.source_dir
        if not cal.is_absolute() and base is not None:
            cal = base / cal
    sensors = scenario.sensor_config()
    part = None if sensors.imu_thermal is None else sensors.imu_thermal.part
    part_tuning = None if part is None else part_thermal_tuning(part)
    config = pipeline_filter_config(scenario.imu_preset, sensors.gnss,
                                    altitude or fusion.altitude, fusion.airspeed, fusion.align,
                                    thermal_tuning(fusion.thermal, cal, part_tuning))
    mag = config.mag.model_copy(update={"decimal_year": scenario.decimal_year})
    return config.model_copy(update={"mag": mag})


def simulate(scenario: Scenario, sink: Callable[[int, bytes], None], *,
             progress: ProgressFn | None = None) -> Flown:
    """Fly ``scenario`` (its seed) and hand every frame to ``sink(time_us, frame)``."""
    return fly(sim_setup(scenario), sink, progress=progress)


def event_windows(scenario: Scenario, end_s: float, *,
                  ended_early: bool = False) -> list[dict[str, Any]]:
    """The scenario's timeline as scored windows ``{type, kind, start_s, end_s}``, cut at
    ``end_s`` (the end of the scored data).

    ``ended_early``: the flight ended before the scenario did; an event that had not begun by
    ``end_s`` is then ``{type, kind, start_s, planned_end_s, not_reached: True}`` (nothing to
    score), one it cut short carries ``clipped: True`` and its ``planned_end_s``.
    """
    rows = []
    for ev in scenario.fault_events():
        type_name = event_type_name(ev)
        start = float(ev.start_s)
        planned = (float(scenario.duration_s) if ev.duration_s is None
                   else start + float(ev.duration_s))
        row: dict[str, Any] = {"type": type_name,
                               "kind": _SCORED_EVENT_KINDS.get(type_name, "generic"),
                               "start_s": start, "end_s": min(end_s, planned)}
        if ended_early and start >= end_s:
            row = {**row, "end_s": None, "planned_end_s": planned, "not_reached": True}
        elif ended_early and planned > end_s:
            row.update(clipped=True, planned_end_s=planned)
        rows.append(row)
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
    autopilot: AutopilotRun | None = None,
    failures: list[str] | None = None,
    baseline: UnaidedBaseline | None = None,
    ended_early: bool | None = None,
) -> tuple[dict[str, Any], list[Path]]:
    """Build ``summary.json`` (+ JUnit XML, plots and HTML when ``reports``) in ``out_dir``;
    with ``autopilot``, its estimate scored beside hilnav's (the ``autopilot`` section).
    ``failures``: sentences on why the run failed besides its criteria; given, the flight
    ended early (its events are cut as :func:`event_windows` says) and the run failed.
    ``baseline``: the unaided baseline of a run aided by hilnav (:func:`_with_baseline`).
    ``ended_early``: the flight stopped before the scenario's end (default: ``failures``
    given), so events it never reached are listed, not scored."""
    col = run.collector
    assert col is not None
    end_s = col.end_s()
    info = RunInfo(scenario=scenario.name, seed=scenario.seed, sim_duration_s=sim_duration_s,
                   wall_s=wall_s, bridge=bridge, altitude=altitude,
                   setup=scenario.setup_record())
    failures = list(failures or [])
    cut = bool(failures) if ended_early is None else ended_early
    timeline = event_windows(scenario, end_s, ended_early=cut)
    events = [e for e in timeline if not e.get("not_reached")]
    scored: Scored = score_run(run, info, criteria=scenario.criteria(), events=events,
                               health_extra=health_extra, with_series=True, settle_s=SETTLE_S)
    summary = scored.summary
    _mark_cut_events(summary, timeline)
    side: ScoredAutopilot | None = None
    if autopilot is not None:
        side = autopilot.score(scored, events)
        _mark_cut_events(side.section, timeline)
        summary["autopilot"] = side.section
        failures += autopilot.failures()
    if failures:
        summary["failures"] = failures
        summary["passed"] = False
    unaided = _with_baseline(baseline, scenario, summary, scored, side)
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
        if side is not None and side.track is not None and side.errors is not None:
            from scenarios.report import plot_side_by_side

            path = out_dir / "autopilot_side_by_side.png"
            plot_side_by_side(scored.truth, scored.estimate, scored.errors, side.track,
                              side.errors, scored.outages, path,
                              autopilot=str(side.section["source"]), unaided=unaided)
            plots.append(path)
        html = out_dir / "report.html"
        write_html(summary, plots, html)
        files += [junit, *plots, html]
    return summary, files


def _with_baseline(baseline: UnaidedBaseline | None, scenario: Scenario,
                   summary: dict[str, Any], scored: Scored,
                   side: ScoredAutopilot | None) -> UnaidedFlight | None:
    """The unaided baseline's part in scoring a run: the baseline run (``aiding: disabled``)
    records itself into it; the aided run gets ``autopilot.unaided`` and
    ``autopilot.aided_vs_unaided`` (and fails when there is nothing to compare). Returns the
    unaided flight to draw beside the aided one (None: none, or this is the baseline)."""
    if baseline is None or side is None:
        return None
    if scenario.autopilot.aiding == "disabled":
        baseline.record(summary, scored.truth, side)
        return None
    failure = baseline.add_to(summary)
    if failure is not None:
        summary["failures"] = [*summary.get("failures", []), failure]
        summary["passed"] = False
    return baseline.flight


def _mark_cut_events(summary: dict[str, Any], timeline: list[dict[str, Any]]) -> None:
    """Mark the scored events a flight cut short, and list those it never reached (only a
    flight that ended early has either: a complete run's summary is left as it is)."""
    rows = summary.get("events")
    if rows is None:
        return
    scored = [e for e in timeline if not e.get("not_reached")]
    for row, event in zip(rows, scored, strict=True):
        if event.get("clipped"):
            row.update(clipped=True, planned_end_s=event["planned_end_s"])
    missed = [{k: e[k] for k in ("type", "kind", "start_s", "planned_end_s")}
              for e in timeline if e.get("not_reached")]
    if missed:
        summary["events_not_reached"] = missed


def run_scenario(
    scenario: Scenario,
    out_dir: Path,
    *,
    bridge: str | None = None,
    altitude: str | None = None,
    progress: ProgressFn | None = None,
    tlog: bool = True,
    reports: bool = True,
    backend: AutopilotBackend | None = None,
    baseline: UnaidedBaseline | None = None,
) -> RunResult:
    """Fly, fuse and score one scenario (seed and overrides already applied to ``scenario``).

    With ``autopilot: px4 | ardupilot`` (or a ``backend`` given, e.g. by a test) the autopilot
    flies (:class:`AutopilotRun`); :class:`AutopilotAbsent` when it never connects, or stalls
    before hilnav has an estimate to score. ``baseline``: see :func:`score`.
    """
    bridge = bridge or scenario.fusion.bridge
    altitude = altitude or scenario.fusion.altitude
    config = filter_config(scenario, altitude)
    nav = build_filter(config, bridge)  # bad names fail before anything flies
    out_dir.mkdir(parents=True, exist_ok=True)
    log_path = out_dir / "run.tlog"
    fusion = FusionRun(config, bridge, nav=nav)
    flies = backend is not None or scenario.autopilot.flies
    ap_run = AutopilotRun.start(scenario, backend, out_dir=out_dir) if flies else None
    if ap_run is not None and ap_run.aiding is not None:
        fusion.on_estimate = ap_run.aiding.offer  # hilnav navigates the autopilot
    t0 = time.perf_counter()

    def fly_into(sink: FrameSink) -> Flown:
        if ap_run is not None:
            return ap_run.fly(sink, progress)
        return simulate(scenario, sink, progress=progress)

    try:
        if tlog:
            with TlogWriter(log_path) as log:
                flown = fly_into(tee(lambda t, f: log.write(f, t), fusion))
        else:
            flown = fly_into(fusion)
    finally:
        if ap_run is not None:
            ap_run.close()  # a started autopilot binary never outlives the flight
    wall = time.perf_counter() - t0
    extra: dict[str, Any] = {
        "faults": flown.fault_counters,
        "fault_log": [plain_dict(e) for e in flown.fault_log],
        "fusion_us_per_sample": fusion.fusion_us_per_sample,
    }
    early: list[str] = []
    if flown.ended is not None:
        extra["flight_ended"] = str(flown.ended)
        # a crash is a failed run whatever the criteria say
        early.append(f"the flight ended early: {flown.ended}")
    ended_early = bool(early)
    if ap_run is not None:
        ap_run.check_scorable(fusion)
        early += ap_run.early_end()
        # a failed scripted step stops the flight too; its sentence comes with the failures
        ended_early = bool(early) or ap_run.script_failed()
    summary, files = score(
        scenario, fusion, out_dir, bridge=bridge, altitude=altitude,
        sim_duration_s=flown.sim_duration_s, wall_s=wall, health_extra=extra,
        reports=reports, autopilot=ap_run, failures=early, baseline=baseline,
        ended_early=ended_early)
    if tlog:
        files.insert(1, log_path)
    return RunResult(summary, out_dir, files)


class AutopilotRun:
    """An autopilot at the controls of one run: its backend, its telemetry recorder and what
    the flight with it produced (:meth:`open`, :meth:`fly`, :meth:`score`)."""

    def __init__(self, scenario: Scenario, backend: AutopilotBackend,
                 telemetry: AutopilotTelemetry | None,
                 commander: Commander | None = None,
                 aiding: CompanionAiding | None = None) -> None:
        self.scenario = scenario
        self.backend = backend
        self.telemetry = telemetry
        self.commander = commander
        self.aiding = aiding
        """hilnav's estimate sent to the autopilot (``aiding: hilnav``): give it the fusion's
        estimates (:attr:`hil.pipeline.FusionRun.on_estimate`)."""
        self.flown: AutopilotFlown | None = None
        self.process: AutopilotProcess | None = None
        """The SITL binary hilnav started (``autopilot.binary``, :meth:`start`), else None."""
        self.exited = threading.Event()
        """Set when the started binary exits by itself (the flight then stops)."""

    @classmethod
    def start(cls, scenario: Scenario, backend: AutopilotBackend | None = None, *,
              out_dir: Path | None = None) -> AutopilotRun:
        """:meth:`open`, after starting the scenario's ``autopilot.binary`` (if it names one
        and no ``backend`` is given) on a free instance and waiting until it is ready
        (:mod:`hil.autopilot.launch`; its output to ``out_dir / autopilot.log``); the run's
        scenario then has its link, telemetry and MAVLink port pointed at the binary's.
        :meth:`close` stops it. ValueError: a bad setting, URL or binary (LaunchError: it
        exited before it was ready); AutopilotAbsent: not ready within ``connect_timeout_s``."""
        ap = scenario.autopilot
        if ap.binary is None or backend is not None:
            return cls.open(scenario, backend)
        from hil.autopilot.ardupilot import json_origin
        from hil.autopilot.launch import AutopilotProcess, Home, plan_launch

        binary = scenario.autopilot_path(ap.binary)
        assert binary is not None
        home = None
        if ap.kind == "ardupilot":  # PX4 takes its home from the simulated GPS
            origin = json_origin(sim_setup(scenario))
            home = Home(math.degrees(origin.lat_rad), math.degrees(origin.lon_rad),
                        origin.alt_msl_m, scenario.start_state().heading_deg)
        # the scenario's ArduPilot parameter file (when the section names one) is also its
        # --defaults: in force from boot (e.g. ARSPD_SKIP_CAL, read once at boot)
        params = getattr(ap, "params", None)
        defaults = [scenario.autopilot_path(params)] if ap.kind == "ardupilot" and params else []
        launch = plan_launch(ap.kind, binary, home=home, telemetry=ap.telemetry is not None,
                             defaults=[p for p in defaults if p is not None])
        process = AutopilotProcess(launch, (out_dir or Path.cwd()) / "autopilot.log").start()
        try:
            exited = threading.Event()
            process.watch(exited)
            if not process.wait_ready(ap.connect_timeout_s):
                raise AutopilotAbsent(
                    f"{ap.kind} SITL {launch.binary} (instance {launch.instance}) did not get "
                    f"ready within {ap.connect_timeout_s:g} s (its MAVLink port "
                    f"{launch.ports.get('serial0_tcp')} never listened); its last output: "
                    f"{process.last_lines()} (log {process.log_path})")
            pointed = ap.model_copy(update={"link": launch.link,
                                            "telemetry": launch.telemetry_url,
                                            "mavlink": launch.mavlink_url})
            run = cls.open(scenario.model_copy(update={"autopilot": pointed}))
        except BaseException:
            process.stop()
            raise
        run.process, run.exited = process, exited
        return run

    def close(self) -> None:
        """Stop the started binary, if any, by PID (idempotent)."""
        if self.process is not None:
            self.process.stop()

    @classmethod
    def open(cls, scenario: Scenario, backend: AutopilotBackend | None = None) -> AutopilotRun:
        """Build the scenario's backend (:func:`hil.autopilot.make_backend`, unless one is
        given) and start recording its telemetry. ValueError: a bad setting or URL."""
        from hil.autopilot import BackendSettings, close_backend, make_backend
        from hil.autopilot.telemetry import AutopilotTelemetry

        ap = scenario.autopilot
        if backend is None:
            backend = make_backend(ap.kind, BackendSettings(
                link=ap.link, actuator_map=scenario.autopilot_path(ap.actuator_map),
                servo_map=scenario.autopilot_path(ap.servo_map), mavlink=ap.mavlink,
                setup=sim_setup(scenario)))
        telemetry = None
        if ap.telemetry is not None:
            try:
                telemetry = AutopilotTelemetry(ap.telemetry, rate_hz=ap.telemetry_rate_hz)
            except ValueError as exc:
                close_backend(backend)
                raise ValueError(f"autopilot telemetry {ap.telemetry}: {exc}") from None
            watch_armed = getattr(backend, "watch_armed", None)
            if callable(watch_armed):  # a backend that cannot see the armed flag itself
                recorder = telemetry
                watch_armed(lambda: recorder.armed)
            _hold_until_flying(backend, telemetry, ap.kind)
        commander = aiding = None
        if ap.scripted and telemetry is not None:
            from hil.autopilot.aiding import CompanionAiding
            from hil.autopilot.commander import Commander

            start = scenario.start_state()
            script = scenario.autopilot_script()
            commander = Commander(ap.kind, script,
                                  (start.lat_deg, start.lon_deg, start.alt_msl_m))
            telemetry.attach(commander)
            if script.aiding:
                aiding = CompanionAiding(ap.kind)
                telemetry.attach(aiding)
        return cls(scenario, backend, telemetry, commander, aiding)

    def fly(self, sink: FrameSink, progress: ProgressFn | None = None) -> Flown:
        """Fly the scenario with the autopilot at the controls, every frame into ``sink``."""
        from hil.autopilot import close_backend, fly_with_autopilot

        ap = self.scenario.autopilot
        if self.telemetry is not None:
            self.telemetry.start()
        setup = sim_setup(self.scenario)
        stop = self.exited  # set when the started binary exits, or when the script fails
        commander = self.commander
        on_step = None
        if commander is not None:
            def on_step(step: SimStep) -> None:
                commander.poll(step.truth.time_us * 1e-6)
                if commander.failure is not None:
                    stop.set()  # the script cannot go on: score what flew, fail the run
        try:
            flown = fly_with_autopilot(
                setup, self.backend, on_frame=sink, speed=ap.speed,
                connect_timeout_s=ap.connect_timeout_s, stall_timeout_s=ap.stall_timeout_s,
                progress=progress, on_step=on_step, stop=stop)
            if commander is not None and flown.connected:
                commander.end(commander.time_s)  # the last step's simulated time
        finally:
            if self.telemetry is not None:
                self.telemetry.stop()
            close_backend(self.backend)
            self.close()
        self.flown = flown
        if not flown.connected and self.process is not None:
            self._never_connected()
        if not flown.connected:
            raise AutopilotAbsent(
                f"{flown.autopilot} did not connect within {ap.connect_timeout_s:g} s "
                f"(link {ap.link or 'the backend default'})")
        return Flown(flown.sim_duration_s, flown.wall_s, flown.frames, flown.ended,
                     flown.fault_log, flown.fault_counters)

    def _never_connected(self) -> None:
        """The started binary did not connect: LaunchError (bad input) when it exited first,
        else AutopilotAbsent naming it and its last output."""
        from hil.autopilot.launch import LaunchError

        ap = self.scenario.autopilot
        process = self.process
        assert process is not None and self.flown is not None
        if process.stopped_by == "exited":
            raise LaunchError(f"autopilot binary {process.describe_exit()} (before it "
                              f"connected; is it {ap.kind}'s SITL? log {process.log_path})")
        raise AutopilotAbsent(
            f"{self.flown.autopilot} ({process.plan.binary}, instance {process.plan.instance}) "
            f"did not connect within {ap.connect_timeout_s:g} s on {process.plan.link}; its "
            f"last output: {process.last_lines()} (log {process.log_path})")

    def early_end(self) -> list[str]:
        """Why the flight with the autopilot ended before the scenario did (its stall, a stop
        asked for, the started binary's exit), as sentences; empty when it flew to the end."""
        flown = self.flown
        if flown is None or not flown.connected:
            return ["the autopilot never flew"]
        if self.process is not None and self.process.stopped_by == "exited":
            return [f"the autopilot process ended at {flown.sim_duration_s:.2f} s: "
                    f"{self.process.describe_exit()}"]
        if flown.stalled is not None:
            return [flown.stalled]
        if self.commander is not None and self.commander.failure is not None:
            return []  # the script's failure says why (:meth:`failures`)
        if flown.stopped:
            return [f"the run was stopped at {flown.sim_duration_s:.2f} s"]
        return []

    def script_failed(self) -> bool:
        """Whether a scripted step failed (which stops the flight where it was)."""
        return self.commander is not None and self.commander.failure is not None

    def failures(self) -> list[str]:
        """What the backend could not do for the scenario (:attr:`AutopilotFlown.problems`:
        a denial step the autopilot did not acknowledge; a scripted step it did not confirm)."""
        out = [] if self.flown is None else list(self.flown.problems)
        if self.commander is not None and self.commander.failure is not None:
            out.append(self.commander.failure)
        return out

    def check_scorable(self, fusion: FusionRun) -> None:
        """AutopilotAbsent when a stall or a failed scripted step left hilnav nothing to
        score."""
        col = fusion.collector
        try:
            if col is not None:
                col.end_s()
        except ValueError as exc:
            why = self.flown.stalled if self.flown is not None else None
            if why is None and self.commander is not None:
                why = self.commander.failure
            if why is None:
                raise
            raise AutopilotAbsent(f"{why}; nothing to score: {exc}") from None

    def score(self, hilnav: Scored, events: list[dict[str, Any]]) -> ScoredAutopilot:
        """The autopilot's estimate scored with hilnav's truth, outages, events and settling."""
        from scenarios.autopilot_summary import score_flown

        assert self.flown is not None
        ap = self.scenario.autopilot
        scored = score_flown(self.flown, self.telemetry, hilnav.truth, hilnav.outages,
                             link={"simulator": ap.link, "telemetry": ap.telemetry},
                             settle_s=SETTLE_S, events=events)
        hold = getattr(self.backend, "trim_hold", None)
        commander = self.commander
        scored.section["armed_s"] = (commander.armed_s if commander is not None
                                     else getattr(hold, "armed_s", None))
        scored.section["mode_reached_s"] = (None if commander is None
                                            else commander.mode_reached_s)
        scored.section["script"] = None if commander is None else commander.report()
        scored.section["aiding"] = _aiding_record(self.scenario, self.aiding)
        if self.process is not None:  # the binary hilnav started: which, how it ended
            texts = [] if self.telemetry is None else [
                str(t["text"]) for t in self.telemetry.health()["statustext"]]
            scored.section["process"] = self.process.record(texts)
        return scored


def _hold_until_flying(backend: AutopilotBackend, telemetry: AutopilotTelemetry,
                       kind: str) -> None:
    """The backend's trim hold lasts until the autopilot's HEARTBEAT on its telemetry says
    it is in a flying mode, besides armed (:mod:`hil.autopilot.arming`)."""
    from hil.autopilot.modes import is_flying_mode

    hold = getattr(backend, "trim_hold", None)
    if hold is None or kind not in ("px4", "ardupilot"):
        return

    def flying() -> bool | None:
        mode = telemetry.custom_mode
        return None if mode is None else is_flying_mode(kind, mode)

    hold.flying = flying


def _aiding_record(scenario: Scenario, aiding: CompanionAiding | None) -> dict[str, Any] | None:
    """The ``autopilot.aiding`` record: what hilnav sent (``aiding: hilnav``), or which of the
    autopilot's parameters were set off (``aiding: disabled``); None without either."""
    if aiding is not None:
        return {"source": "hilnav", "frames_sent": aiding.sent,
                "message": "GPS_INPUT" if aiding.autopilot == "ardupilot" else "ODOMETRY"}
    kind = scenario.autopilot.kind
    if scenario.autopilot.aiding != "disabled" or kind not in ("ardupilot", "px4"):
        return None
    from hil.autopilot.aiding import aiding_off_params

    return {"source": None, "frames_sent": 0, "message": None,
            "parameters_off": [p.name for p in aiding_off_params(kind)]}
