"""The offline commands: ``run``, ``replay``, ``demo``, ``compare``, ``campaign``, ``schema``
and ``list``.

Each one flies or reads what it is given, scores it and exits with the exit codes of
:mod:`scenarios.cli.errors`; none of them holds a network session, so all of them may skip the
interpreter's final collections (:mod:`scenarios.cli.quick_exit`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from fusion.choices import (
    AIRSPEED_MODES,
    ALIGN_MODES,
    ALTITUDE_METHODS,
    BRIDGE_METHODS,
    DEFAULT_AIRSPEED_MODE,
    DEFAULT_ALIGN_MODE,
    DEFAULT_THERMAL_MODE,
)
from scenarios.cli.autopilot_hints import AutopilotBinaryOption, with_autopilot_binary
from scenarios.cli.children import sigterm_interrupts
from scenarios.cli.errors import RunFailed, check_choice, cli_errors, out_dir, out_file
from scenarios.cli.options import (
    AirspeedOption,
    AirspeedOverride,
    AlignOption,
    AlignOverride,
    AltitudeOption,
    BridgeOption,
    GnssOption,
    ImuOption,
    QuietOption,
    SettleOption,
    ThermalCalOption,
    ThermalOption,
    ThermalOverride,
    ThermalPartOption,
)
from scenarios.cli.output import (
    console,
    err_console,
    fmt,
    print_autopilot,
    print_summary,
    progress_bar,
    say_waiting_for_autopilot,
    scripted_events,
    warn_input,
)
from scenarios.cli.quick_exit import settled_heap

__all__ = ["campaign", "compare", "demo", "list_choices", "replay", "run", "schema"]


@cli_errors
def replay(
    log: Annotated[Path, typer.Argument(
        help="Flight log: a MAVLink .tlog (HIL_SENSOR/HIL_GPS, truth as HIL_STATE_QUATERNION) "
             "or a PX4 ULog .ulg (scored against the autopilot's own estimate).")],
    out: Annotated[Path, typer.Option(help="Output folder for summary.json and plots.")],
    bridge: BridgeOption = "none",
    altitude: AltitudeOption = "ekf",
    airspeed: AirspeedOption = DEFAULT_AIRSPEED_MODE,
    align: AlignOption = DEFAULT_ALIGN_MODE,
    settle: SettleOption = 60.0,
    imu: ImuOption = "industrial-mems",
    gnss: GnssOption = "modern",
    thermal: ThermalOption = DEFAULT_THERMAL_MODE,
    thermal_cal: ThermalCalOption = None,
    thermal_part: ThermalPartOption = "bmi088",
    gnss_off: Annotated[
        list[str] | None,
        typer.Option("--gnss-off", help="Cut GNSS START:DURATION s, from the log's first "
                                        "sample (repeatable)."),
    ] = None,
) -> None:
    """Run the navigation filter on a recorded log and score it against the log's truth
    (.tlog) or the autopilot's estimate (.ulg)."""
    out_dir(out)
    with settled_heap():
        from hil.pipeline import filter_config
        from hil.streamer import GnssWindow
        from hil.thermal_cal import command_thermal_tuning
        from scenarios.replay import replay as run_replay
        from sim.presets import gnss_preset

    check_choice("bridging method", bridge, BRIDGE_METHODS)
    check_choice("altitude method", altitude, ALTITUDE_METHODS)
    check_choice("airspeed mode", airspeed, AIRSPEED_MODES)
    check_choice("alignment", align, ALIGN_MODES)
    windows = list(gnss_off or [])
    for w in windows:  # a malformed window -> exit 2 before the log is read
        GnssWindow.parse(w)
    if not settle >= 0.0:
        raise ValueError(f"--settle must be >= 0 s (got {settle:g})")
    therm = command_thermal_tuning(thermal, thermal_cal, thermal_part)
    result = run_replay(log, out,
                        config=filter_config(imu, gnss_preset(gnss), altitude, airspeed, align,
                                             therm),
                        bridge=bridge, altitude=altitude, settle_s=settle, gnss_off=windows)
    console.print(f"scored against: {result.summary['reference']['source']}")
    print_summary(result.summary)
    warn_input(result.summary)
    console.print(f"summary -> {result.summary_path}")


@cli_errors
def demo(
    out: Annotated[Path, typer.Option(help="Output folder.")] = Path("out/demo"),
    duration: Annotated[float, typer.Option(help="Simulated seconds.")] = 600.0,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 1,
    outage: Annotated[str, typer.Option(help="GNSS outage START:DURATION s.")] = "300:60",
    plan: Annotated[str, typer.Option(help="Flight plan name or YAML path.")] = "racetrack",
    imu: Annotated[str, typer.Option(help="IMU preset (sensor and filter tuning).")] = (
        "industrial-mems"
    ),
    gnss: Annotated[str, typer.Option(help="GNSS preset (sensor and filter model).")] = "modern",
    airspeed: AirspeedOption = DEFAULT_AIRSPEED_MODE,
    align: AlignOption = DEFAULT_ALIGN_MODE,
    quiet: QuietOption = False,
) -> None:
    """The main job: fly a racetrack with a GNSS outage, record, fuse, score, report.html."""
    out_dir(out)
    with settled_heap():
        from hil.pipeline import SimSetup, filter_config, record_flight
        from scenarios.replay import replay as run_replay
        from sim.presets import gnss_preset

    out.mkdir(parents=True, exist_ok=True)
    log = out / "run.tlog"
    config = filter_config(imu, gnss_preset(gnss), airspeed=airspeed, align=align)
    request = SimSetup.build(plan=plan, imu=imu, gnss=gnss, duration_s=duration, seed=seed,
                               gnss_off=[outage])
    with progress_bar(duration, "flying", quiet=quiet,
                      events=scripted_events(request)) as progress:
        report = record_flight(request, log, progress=progress)
    console.print(
        f"flew {report.sim_duration_s:.0f} s in {report.wall_s:.1f} s "
        f"({report.realtime_factor:.0f}x real time) -> {log}"
    )
    if report.ended is not None:
        raise RunFailed(str(report.ended))
    result = run_replay(log, out, config=config, setup=_demo_setup(request, plan, imu, gnss))
    from scenarios.html import write_html

    html = out / "report.html"
    write_html(result.summary, result.plots, html)
    print_summary(result.summary)
    console.print(f"summary -> {result.summary_path}; report -> {html}; plots in {out}")


def _demo_setup(request: Any, plan: str, imu: str, gnss: str) -> dict[str, Any]:
    """What ``demo`` flew, in the words of a scenario's ``setup`` (see
    :meth:`scenarios.schema.Scenario.setup_record`)."""
    import inspect

    from hil.pipeline import SimSetup

    defaults = {name: p.default for name, p in
                inspect.signature(SimSetup.build).parameters.items()}
    flight = request.flight
    return {
        "description": "hilnav demo",
        "aircraft": flight.aircraft,
        "plan": plan,
        "sensors": {"imu": imu, "gnss": gnss, "baro": defaults["baro"], "mag": defaults["mag"],
                    "pitot": defaults["pitot"]},
        "wind_ned_mps": list(flight.wind_ned_mps),
        "wind_shear_exponent": flight.wind_shear_exponent,
        "turbulence": flight.turbulence,
    }


@cli_errors
def list_choices(
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
) -> None:
    """List aircraft, flight plans and sensor presets."""
    from sim import presets
    from sim.flight import available_aircraft
    from sim.plans import available_plans

    choices = {
        "aircraft": available_aircraft(),
        "plans": available_plans(),
        "imu": presets.available_imu_presets(),
        "imu_thermal": presets.available_imu_thermal_presets(),
        "gnss": presets.available_gnss_presets(),
        "baro": presets.available_baro_presets(),
        "mag": presets.available_mag_presets(),
        "pitot": presets.available_pitot_presets(),
        "bridge": list(BRIDGE_METHODS),
        "altitude": list(ALTITUDE_METHODS),
        "align": list(ALIGN_MODES),
    }
    if as_json:
        sys.stdout.write(json.dumps(choices, indent=2) + "\n")
        return
    for k, v in choices.items():
        console.print(f"[bold]{k}[/]: {', '.join(v)}", highlight=False)


def _load_scenario(path: Path, **overrides: Any) -> Any:
    from scenarios.schema import load_scenario

    scn = load_scenario(path)
    given = {k: v for k, v in overrides.items() if v is not None}
    return scn.with_overrides(**given) if given else scn


@cli_errors
def run(
    scenario: Annotated[Path, typer.Argument(help="Scenario YAML (see `hilnav schema`).")],
    out: Annotated[Path, typer.Option(help="Run folder: summary.json, junit.xml, plots, "
                                           "report.html, run.tlog.")],
    seed: Annotated[int | None, typer.Option(help="Override the scenario's seed.")] = None,
    bridge: Annotated[str | None, typer.Option(help="Override the bridging method.")] = None,
    altitude: Annotated[str | None, typer.Option(help="Override the altitude method.")] = None,
    airspeed: AirspeedOverride = None,
    align: AlignOverride = None,
    unaided_baseline: Annotated[bool, typer.Option(
        "--unaided-baseline", help="With autopilot.aiding: hilnav: first fly the same seed "
        "with the autopilot unaided (into OUT/unaided), then aided, and score both on one card "
        "(as the scenario's autopilot.unaided_baseline).")] = False,
    thermal: ThermalOverride = None,
    autopilot_binary: AutopilotBinaryOption = None,
    quiet: QuietOption = False,
) -> None:
    """Fly a scenario in lockstep, fuse it, score it: exit 0 pass, 1 fail, 2 bad input."""
    out_dir(out)
    with settled_heap():
        from scenarios.runner import AutopilotAbsent, run_scenario, sim_setup

        scn = _load_scenario(scenario, seed=seed, bridge=bridge, altitude=altitude,
                             airspeed=airspeed, align=align, thermal=thermal)
        if autopilot_binary is not None:
            scn = with_autopilot_binary(scn, autopilot_binary)
        # the plots' module (matplotlib) too, once the scenario is valid: loaded here, its
        # import runs no collection and the collections while the plots are drawn skip it
        import scenarios.report  # noqa: F401
    twice = unaided_baseline or scn.autopilot.unaided_baseline
    if twice and scn.autopilot.aiding != "hilnav":
        raise ValueError(f"--unaided-baseline compares the autopilot aided by hilnav with it "
                         f"unaided: {scenario} needs autopilot.aiding: hilnav")
    if scn.autopilot.flies and not twice:
        say_waiting_for_autopilot(scn, out)
    try:
        if twice:
            from scenarios.unaided_baseline import run_with_unaided_baseline

            with sigterm_interrupts():
                result = run_with_unaided_baseline(scn, out, each_run=_each_flight(out, quiet))
        else:
            with sigterm_interrupts(), progress_bar(
                    scn.duration_s, scn.name, quiet=quiet,
                    events=scripted_events(sim_setup(scn))) as progress:
                result = run_scenario(scn, out, progress=progress)
    except AutopilotAbsent as exc:
        raise RunFailed(str(exc)) from None
    s = result.summary
    print_summary(s)
    print_autopilot(s)
    for c in s.get("criteria", []):
        mark = "[green]pass[/]" if c["ok"] else "[red]FAIL[/]"
        console.print(f"  {mark} {c['name']}: {fmt(c['value'], '.3g')} (limit {c['limit']:.3g})",
                      highlight=False)
    failures = list(s.get("failures") or [])
    for failure in failures:
        err_console.print(f"[red]failure:[/] {failure}", highlight=False)
    if "flight_ended" in s.get("health", {}) and not failures:
        raise RunFailed(f"the flight ended early: {s['health']['flight_ended']}; see {out}")
    console.print(f"summary -> {out / 'summary.json'}; report -> {out / 'report.html'}")
    stalled = (s.get("autopilot") or {}).get("stalled")
    if stalled and stalled not in failures:
        failures.insert(0, stalled)
    failed = [c["name"] for c in s.get("criteria", []) if not c["ok"]]
    if failed:
        failures.append(f"criteria failed: {', '.join(failed)}")
    if failures or not result.passed:
        raise RunFailed(f"{scn.name}: " + ("; ".join(failures) or "did not pass")
                        + f"; see {out}")


def _each_flight(out: Path, quiet: bool) -> Any:
    """The two flights of a run with its unaided baseline, each announced, waited for and
    shown with its own progress bar (:data:`scenarios.unaided_baseline.RunHook`)."""
    from contextlib import contextmanager

    from scenarios.runner import sim_setup
    from scenarios.unaided_baseline import UNAIDED_DIR

    @contextmanager
    def each_flight(role: str, scn: Any) -> Any:
        ap = scn.autopilot
        if role == "unaided":
            err_console.print(f"flight 1 of 2: {ap.kind} unaided (aiding: disabled, the same "
                              f"seed) -> {out / UNAIDED_DIR}", highlight=False)
        else:
            again = "" if getattr(ap, "binary", None) else (
                f"; start {ap.kind} afresh for it (the first flight's instance has flown)")
            err_console.print(f"flight 2 of 2: {ap.kind} aided by hilnav -> {out}{again}",
                              highlight=False)
        say_waiting_for_autopilot(scn, out)
        with progress_bar(scn.duration_s, f"{scn.name} ({role})", quiet=quiet,
                          events=scripted_events(sim_setup(scn))) as progress:
            yield progress

    return each_flight


@cli_errors
def compare(
    scenario: Annotated[Path, typer.Argument(help="Scenario YAML.")],
    out: Annotated[Path, typer.Option(help="Folder for compare.json, compare.md, runs.")],
    methods: Annotated[str, typer.Option(help="Comma-separated bridging methods.")] = (
        "none,gmdh,gmdh-pseudo,mlp,rbf,bp-parallel"),
    seeds: Annotated[int, typer.Option(min=1, help="Number of seeds.")] = 3,
    seed_base: Annotated[int, typer.Option(help="First seed (seeds S, S+1, ...).")] = 100,
    altitude: Annotated[str | None, typer.Option(help="Override the altitude method.")] = None,
    airspeed: AirspeedOverride = None,
    align: AlignOverride = None,
    quiet: QuietOption = False,
) -> None:
    """Every bridging method on the same sensor data per seed (the papers' Tables 1 and 2)."""
    out_dir(out)
    with settled_heap():
        from scenarios.compare import compare as run_compare
        from scenarios.compare import markdown, parse_methods

    names = parse_methods(methods)
    scn = _load_scenario(scenario, altitude=altitude, airspeed=airspeed, align=align)
    seed_list = list(range(seed_base, seed_base + seeds))
    with settled_heap():
        from scenarios.runner import sim_setup

        events = scripted_events(sim_setup(scn))
    # one bar over every seed's flight; the real-time factor counts each flight on its own
    with progress_bar(scn.duration_s * len(seed_list), "flying", quiet=quiet,
                      events=events) as progress:

        flying: list[int] = []

        def flight_progress(seed: int, t_s: float) -> None:
            if not flying or flying[-1] != seed:
                flying.append(seed)
                progress.restart_clock()
            progress((len(flying) - 1) * scn.duration_s + t_s, event_time_s=t_s)

        result = run_compare(scn, names, seed_list, out,
                             progress=None if quiet else
                             lambda msg: err_console.print(msg, highlight=False),
                             flight_progress=flight_progress)
    console.print(markdown(result), highlight=False)
    console.print(f"compare -> {out / 'compare.json'}")


@cli_errors
def schema(
    out: Annotated[Path | None, typer.Option(help="Write to this file instead of stdout.")] = None,
) -> None:
    """Print the JSON Schema of scenario files (for editor completion)."""
    if out is not None:
        out_file(out, "--out")
    from scenarios.schema import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:
        out.write_text(text)
        console.print(f"schema -> {out}")


@cli_errors
def campaign(
    scenarios: Annotated[list[Path], typer.Argument(help="Scenario YAML files.")],
    out: Annotated[Path, typer.Option(help="Campaign folder (resumable).")],
    seeds: Annotated[int, typer.Option(min=1, help="Seeds per scenario and grid point.")] = 10,
    seed_base: Annotated[int, typer.Option(help="First seed.")] = 100,
    vary: Annotated[list[str] | None, typer.Option(
        help="Grid axis KEY=V1,V2 (imu, gnss, baro, mag, pitot, bridge, altitude, airspeed,"
             " align, aircraft, plan); repeatable.")
    ] = None,
    airspeed: AirspeedOverride = None,
    align: AlignOverride = None,
    scheduler: Annotated[str | None, typer.Option(
        help="Dask scheduler address (tcp://HOST:8786); default: a local cluster.")] = None,
    workers: Annotated[int | None, typer.Option(help="Local cluster workers (default: cores).")
                       ] = None,
    keep_tlogs: Annotated[bool, typer.Option(help="Keep each run's run.tlog.")] = False,
    quiet: QuietOption = False,
) -> None:
    """Monte Carlo sweep over seeds and parameter grids on Dask; exit 1 if any run failed."""
    out_dir(out)
    from rich.progress import MofNCompleteColumn, TimeElapsedColumn

    from scenarios.campaign import parse_vary, run_campaign
    from scenarios.campaign.report import point_label

    if seed_base < 0:
        raise ValueError(f"--seed-base must be >= 0, got {seed_base}")
    grid = parse_vary(vary or [])
    if airspeed is not None:  # one air-data choice for every run: a one-value grid axis
        check_choice("airspeed mode", airspeed, AIRSPEED_MODES)
        if "airspeed" in grid:
            raise ValueError("give --airspeed or --vary airspeed=..., not both")
        grid["airspeed"] = [airspeed]
    if align is not None:  # one alignment for every run: a one-value grid axis
        check_choice("alignment", align, ALIGN_MODES)
        if "align" in grid:
            raise ValueError("give --align or --vary align=..., not both")
        grid["align"] = [align]
    seed_list = list(range(seed_base, seed_base + seeds))
    bar = Progress(TextColumn("[bold]campaign"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("runs"), TimeElapsedColumn(), TimeRemainingColumn(),
                   console=err_console, transient=False,
                   disable=quiet or not err_console.is_terminal)
    task_id = None
    next_tenth = 1

    def progress(done: int, total: int, _rid: str) -> None:
        nonlocal task_id, next_tenth
        if task_id is None:
            task_id = bar.add_task("runs", total=total)
        bar.update(task_id, completed=done)
        if quiet or err_console.is_terminal or total <= 0 or done * 10 < next_tenth * total:
            return
        while done * 10 >= next_tenth * total:  # a plain line every 10 % of the runs (CI logs)
            next_tenth += 1
        err_console.print(f"campaign: {done}/{total} runs ({100 * done / total:.0f} %)",
                          highlight=False)

    with bar:
        result = run_campaign(scenarios, seed_list, grid, out, scheduler=scheduler,
                              workers=workers, keep_tlogs=keep_tlogs, progress=progress)
    rep = result.report
    err_console.print(
        f"{len(rep['runs'])} runs: {result.executed} executed, {result.resumed} resumed, "
        f"{len(rep['failed'])} raised, {len(rep['not_passed'])} did not pass -> "
        f"{out / 'campaign.json'}, {out / 'campaign.md'}, {out / 'distributions.png'}",
        highlight=False)
    for f in rep["failed"]:
        err_console.print(f"[red]run {f['id']}[/] ({f['scenario']}, seed {f['seed']}, "
                          f"{point_label(f['point'])}): {f['error']}", highlight=False)
    if not result.all_passed:
        raise RunFailed(f"some runs failed their criteria or errored; see {out / 'campaign.md'}")


