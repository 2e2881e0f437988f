"""The ``hilnav`` command line: a thin typed layer over the library's entry points.

Exit codes follow ARCHITECTURE.md: 0 success / pass, 1 run failed (criteria failed, aircraft
crashed), 2 bad input (one line on stderr naming what is wrong, never a traceback).
"""

from __future__ import annotations

import functools
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ParamSpec, TypeVar

import pydantic
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

app = typer.Typer(
    name="hilnav",
    help="Hardware-in-the-loop navigation: fly JSBSim, stream MAVLink sensors, fuse, score.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
err_console = Console(stderr=True, soft_wrap=True)
console = Console(soft_wrap=True)

P = ParamSpec("P")
R = TypeVar("R")

BRIDGE_METHODS = ("none",)
ALTITUDE_METHODS = ("ekf",)


class RunFailed(Exception):
    """The run happened but did not succeed (exit code 1)."""


def _first_validation_error(exc: pydantic.ValidationError) -> str:
    e = exc.errors()[0]
    loc = ".".join(str(p) for p in e["loc"]) or exc.title
    return f"{loc}: {e['msg']}"


def cli_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn bad input into a one-line message and exit code 2; failed runs into exit 1."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except pydantic.ValidationError as exc:
            err_console.print(f"[red]error:[/] {_first_validation_error(exc)}", highlight=False)
            raise typer.Exit(2) from None
        except (ValueError, FileNotFoundError) as exc:
            err_console.print(f"[red]error:[/] {exc}", highlight=False)
            raise typer.Exit(2) from None
        except RunFailed as exc:
            err_console.print(f"[red]failed:[/] {exc}", highlight=False)
            raise typer.Exit(1) from None

    return wrapper


def _choice(name: str, value: str, valid: tuple[str, ...] | list[str]) -> str:
    if value not in valid:
        raise ValueError(f"unknown {name} {value!r}; valid choices: {', '.join(valid)}")
    return value


def _progress(total_s: float, label: str) -> Progress:
    return Progress(
        TextColumn(f"[bold]{label}"),
        BarColumn(),
        TextColumn("{task.completed:>7.0f}/{task.total:.0f} s"),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    )


# --------------------------------------------------------------------------------------- sim
@app.command()
@cli_errors
def sim(
    record: Annotated[Path, typer.Option(help="MAVLink log (.tlog) to write.")],
    plan: Annotated[str, typer.Option(help="Flight plan name or YAML path.")] = "racetrack",
    aircraft: Annotated[str, typer.Option(help="JSBSim aircraft from the jsbsim wheel.")] = "c172x",
    duration: Annotated[float, typer.Option(help="Simulated seconds.")] = 600.0,
    seed: Annotated[int, typer.Option(help="Scenario seed (sensor noise, turbulence).")] = 1,
    rate: Annotated[float, typer.Option(help="Simulation and IMU rate, Hz (50-400).")] = 200.0,
    imu: Annotated[str, typer.Option(help="IMU preset.")] = "industrial-mems",
    gnss: Annotated[str, typer.Option(help="GNSS preset.")] = "modern",
    baro: Annotated[str, typer.Option(help="Barometer preset.")] = "ms5611",
    mag: Annotated[str, typer.Option(help="Magnetometer preset.")] = "consumer",
    lat: Annotated[float, typer.Option(help="Start latitude, deg.")] = 47.0,
    lon: Annotated[float, typer.Option(help="Start longitude, deg.")] = 8.0,
    alt: Annotated[float, typer.Option(help="Start altitude MSL, m.")] = 1000.0,
    heading: Annotated[float, typer.Option(help="Start heading, deg true.")] = 0.0,
    airspeed: Annotated[float, typer.Option(help="Start true airspeed, m/s.")] = 50.0,
    wind: Annotated[str, typer.Option(help="Wind N,E,D in m/s (direction it blows to).")] = "0,0,0",
    turbulence: Annotated[float, typer.Option(help="Turbulence severity 0..1.")] = 0.0,
    gnss_off: Annotated[
        list[str] | None,
        typer.Option("--gnss-off", help="GNSS outage START:DURATION s (repeatable)."),
    ] = None,
    truth_rate: Annotated[float, typer.Option(help="Truth message rate, Hz.")] = 50.0,
) -> None:
    """Fly a plan in lockstep (as fast as possible) and record sensors + truth as a .tlog."""
    from hil.recording import SimRequest, record_flight

    request = SimRequest.build(
        plan=plan, aircraft=aircraft, duration_s=duration, seed=seed, rate_hz=rate,
        imu=imu, gnss=gnss, baro=baro, mag=mag, lat_deg=lat, lon_deg=lon, alt_msl_m=alt,
        heading_deg=heading, airspeed_mps=airspeed, wind=wind, turbulence=turbulence,
        gnss_off=gnss_off or [], truth_rate_hz=truth_rate,
    )
    with _progress(duration, "flying") as bar:
        task = bar.add_task("fly", total=duration)
        report = record_flight(request, record, progress=lambda t: bar.update(task, completed=t))
    console.print(
        f"recorded {report.frames} frames, {report.sim_duration_s:.1f} s simulated in "
        f"{report.wall_s:.1f} s ({report.realtime_factor:.0f}x real time) -> {record}"
    )
    if report.ended is not None:
        raise RunFailed(f"{report.ended}; the log up to that point is kept in {record}")


# ------------------------------------------------------------------------------------ replay
@app.command()
@cli_errors
def replay(
    log: Annotated[Path, typer.Argument(help="MAVLink log (.tlog) with HIL_SENSOR/HIL_GPS.")],
    out: Annotated[Path, typer.Option(help="Output folder for summary.json and plots.")],
    bridge: Annotated[str, typer.Option(help="Outage bridging method.")] = "none",
    altitude: Annotated[str, typer.Option(help="Altitude method.")] = "ekf",
    settle: Annotated[float, typer.Option(help="Seconds excluded after start/outages.")] = 60.0,
    imu: Annotated[
        str, typer.Option(help="IMU datasheet preset the filter is tuned for.")
    ] = "industrial-mems",
) -> None:
    """Run the navigation filter on a recorded log and score it against the logged truth."""
    from hil.tuning import filter_config_for_imu
    from scenarios.replay import replay as run_replay

    _choice("bridging method", bridge, BRIDGE_METHODS)
    _choice("altitude method", altitude, ALTITUDE_METHODS)
    result = run_replay(log, out, config=filter_config_for_imu(imu), bridge=bridge,
                        altitude=altitude, settle_s=settle)
    _print_summary(result.summary)
    console.print(f"summary -> {result.summary_path}")


def _fmt(v: Any, spec: str = ".2f") -> str:
    return "n/a" if v is None else format(v, spec)


def _print_summary(s: dict[str, Any]) -> None:
    on = s.get("gnss_on", {})
    console.print(
        f"GNSS on: horizontal RMSE {_fmt(on.get('horizontal_rmse_m'))} m, vertical "
        f"{_fmt(on.get('vertical_rmse_m'))} m, roll/pitch/yaw "
        f"{_fmt(on.get('roll_rmse_deg'), '.3f')}/{_fmt(on.get('pitch_rmse_deg'), '.3f')}/"
        f"{_fmt(on.get('yaw_rmse_deg'), '.3f')} deg"
    )
    for o in s.get("outages", []):
        at = o["horizontal_error_m_at"]
        console.print(
            f"outage {o['start_s']:.0f}-{o['end_s']:.0f} s: horizontal RMSE "
            f"{_fmt(o['horizontal_rmse_m'])} m, max {_fmt(o['horizontal_max_m'])} m, at 10/30/60 s "
            f"{_fmt(at.get('10'), '.1f')}/{_fmt(at.get('30'), '.1f')}/{_fmt(at.get('60'), '.1f')} m"
        )
    nees = s.get("nees", {})
    if nees:
        console.print(f"NEES (9 dof, GNSS on): {_fmt(nees.get('nees_mean'))}")


# -------------------------------------------------------------------------------------- demo
@app.command()
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
) -> None:
    """The main job: fly a racetrack, record it, run the filter with a GNSS outage, score it."""
    from hil.recording import SimRequest, record_flight
    from hil.tuning import filter_config_for_imu
    from scenarios.replay import replay as run_replay

    out.mkdir(parents=True, exist_ok=True)
    log = out / "run.tlog"
    config = filter_config_for_imu(imu)
    request = SimRequest.build(plan=plan, imu=imu, duration_s=duration, seed=seed,
                               gnss_off=[outage])
    with _progress(duration, "flying") as bar:
        task = bar.add_task("fly", total=duration)
        report = record_flight(request, log, progress=lambda t: bar.update(task, completed=t))
    console.print(
        f"flew {report.sim_duration_s:.0f} s in {report.wall_s:.1f} s "
        f"({report.realtime_factor:.0f}x real time) -> {log}"
    )
    if report.ended is not None:
        raise RunFailed(str(report.ended))
    result = run_replay(log, out, config=config)
    _print_summary(result.summary)
    console.print(f"summary -> {result.summary_path}; plots in {out}")


# ------------------------------------------------------------------------------------ presets
@app.command("list")
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
        "gnss": presets.available_gnss_presets(),
        "baro": presets.available_baro_presets(),
        "mag": presets.available_mag_presets(),
        "bridge": list(BRIDGE_METHODS),
        "altitude": list(ALTITUDE_METHODS),
    }
    if as_json:
        sys.stdout.write(json.dumps(choices, indent=2) + "\n")
        return
    for k, v in choices.items():
        console.print(f"[bold]{k}[/]: {', '.join(v)}", highlight=False)
