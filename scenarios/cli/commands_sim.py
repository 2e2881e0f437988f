"""``hilnav sim``: fly a plan with synthetic sensors, in one of four modes.

* ``sim record FILE``: lockstep, as fast as possible, every frame into a MAVLink log;
* ``sim live URL``: stream the frames to a fusion service at ``--speed`` x real time;
* ``sim px4 URL``: PX4 (SITL or a HITL board) flies the aircraft (:mod:`scenarios.cli.px4`);
* ``sim ardupilot URL``: ArduPilot SITL flies it (:mod:`scenarios.cli.ardupilot`).

The flight and its sensors are the same options in every mode, declared once
(:data:`flight_options`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated, Any, Literal

import typer

from scenarios.cli.errors import RunFailed, bad_input, cli_errors, out_file
from scenarios.cli.options import (
    IMU_THERMAL_HELP,
    SigningKeyFileOption,
    ZenohSecurity,
    option_group,
    zenoh_security_options,
)
from scenarios.cli.output import (
    FLYING,
    console,
    err_console,
    progress_bar,
    say_warning,
    scripted_events,
    speed_sentence,
)

__all__ = ["MODES", "FlightOptions", "flight_options", "sim_app"]

MODES = ("record", "live", "px4", "ardupilot")
"""The subcommands of ``hilnav sim``."""

_FLIGHT = "Flight and sensors"
_AUTOPILOT = "Autopilot in the loop"


def _flight_template(
    plan: Annotated[str, typer.Option(
        help="Flight plan name or YAML path.", rich_help_panel=_FLIGHT)] = "racetrack",
    aircraft: Annotated[str, typer.Option(
        help="JSBSim aircraft from the jsbsim wheel.", rich_help_panel=_FLIGHT)] = "c172x",
    duration: Annotated[float, typer.Option(
        help="Simulated seconds.", rich_help_panel=_FLIGHT)] = 600.0,
    seed: Annotated[int, typer.Option(
        help="Scenario seed (sensor noise, turbulence).", rich_help_panel=_FLIGHT)] = 1,
    rate: Annotated[float, typer.Option(
        help="Simulation and IMU rate, Hz (50-400).", rich_help_panel=_FLIGHT)] = 200.0,
    imu: Annotated[str, typer.Option(
        help="IMU preset.", rich_help_panel=_FLIGHT)] = "industrial-mems",
    gnss: Annotated[str, typer.Option(help="GNSS preset.", rich_help_panel=_FLIGHT)] = "modern",
    baro: Annotated[str, typer.Option(
        help="Barometer preset.", rich_help_panel=_FLIGHT)] = "ms5611",
    mag: Annotated[str, typer.Option(
        help="Magnetometer preset.", rich_help_panel=_FLIGHT)] = "consumer",
    pitot: Annotated[str, typer.Option(
        help="Pitot (airspeed) preset; none = an aircraft without one.",
        rich_help_panel=_FLIGHT)] = "ms4525do",
    imu_thermal: Annotated[str, typer.Option(
        help=IMU_THERMAL_HELP, rich_help_panel=_FLIGHT)] = "off",
    lat: Annotated[float, typer.Option(
        help="Start latitude, deg.", rich_help_panel=_FLIGHT)] = 47.0,
    lon: Annotated[float, typer.Option(
        help="Start longitude, deg.", rich_help_panel=_FLIGHT)] = 8.0,
    alt: Annotated[float, typer.Option(
        help="Start altitude MSL, m.", rich_help_panel=_FLIGHT)] = 1000.0,
    heading: Annotated[float, typer.Option(
        help="Start heading, deg true.", rich_help_panel=_FLIGHT)] = 0.0,
    airspeed: Annotated[float, typer.Option(
        help="Start true airspeed, m/s.", rich_help_panel=_FLIGHT)] = 50.0,
    start: Annotated[str, typer.Option(
        help="air: trimmed in the air at --alt and --airspeed; ground: at rest on a runway at "
             "--alt (its elevation), engine idling, for an autopilot that takes off "
             "(px4, ardupilot).", rich_help_panel=_FLIGHT)] = "air",
    wind: Annotated[str, typer.Option(
        help="Wind N,E,D in m/s (direction it blows to).", rich_help_panel=_FLIGHT)] = "0,0,0",
    wind_shear: Annotated[float, typer.Option(
        help="Power-law shear exponent of the horizontal wind (1/7 = neutral boundary layer; "
             "0 = the same wind at every height).", rich_help_panel=_FLIGHT)] = 0.0,
    wind_ref_agl: Annotated[float | None, typer.Option(
        help="Height above ground at which --wind holds, m (default: start altitude).",
        rich_help_panel=_FLIGHT)] = None,
    turbulence: Annotated[float, typer.Option(
        help="Turbulence severity 0..1.", rich_help_panel=_FLIGHT)] = 0.0,
    gnss_off: Annotated[list[str] | None, typer.Option(
        "--gnss-off", help="GNSS outage START:DURATION s (repeatable).",
        rich_help_panel=_FLIGHT)] = None,
    truth_rate: Annotated[float, typer.Option(
        help="Truth message rate, Hz.", rich_help_panel=_FLIGHT)] = 50.0,
) -> None:
    """The flight and sensor options of every ``hilnav sim`` mode (template of
    :class:`FlightOptions`)."""


@dataclasses.dataclass(frozen=True)
class FlightOptions:
    """The flight and its sensors as the user gave them on the command line."""

    plan: str = "racetrack"
    aircraft: str = "c172x"
    duration: float = 600.0
    seed: int = 1
    rate: float = 200.0
    imu: str = "industrial-mems"
    gnss: str = "modern"
    baro: str = "ms5611"
    mag: str = "consumer"
    pitot: str = "ms4525do"
    imu_thermal: str = "off"
    lat: float = 47.0
    lon: float = 8.0
    alt: float = 1000.0
    heading: float = 0.0
    airspeed: float = 50.0
    start: str = "air"
    wind: str = "0,0,0"
    wind_shear: float = 0.0
    wind_ref_agl: float | None = None
    turbulence: float = 0.0
    gnss_off: list[str] | None = None
    truth_rate: float = 50.0

    def start_kind(self) -> Literal["air", "ground"]:
        """``--start`` checked (ValueError names the valid kinds)."""
        if self.start == "air":
            return "air"
        if self.start == "ground":
            return "ground"
        raise ValueError(f"--start must be air or ground (got {self.start!r})")

    def setup(self) -> Any:
        """The validated :class:`hil.pipeline.SimSetup` (ValueError on bad input)."""
        from hil.pipeline import SimSetup

        return SimSetup.build(
            plan=self.plan, aircraft=self.aircraft, duration_s=self.duration, seed=self.seed,
            rate_hz=self.rate, imu=self.imu, gnss=self.gnss, baro=self.baro, mag=self.mag,
            pitot=self.pitot, imu_thermal=self.imu_thermal, lat_deg=self.lat,
            lon_deg=self.lon, alt_msl_m=self.alt,
            heading_deg=self.heading, airspeed_mps=self.airspeed,
            start_kind=self.start_kind(), wind=self.wind,
            turbulence=self.turbulence, wind_shear_exponent=self.wind_shear,
            wind_ref_agl_m=self.wind_ref_agl, gnss_off=self.gnss_off or [],
            truth_rate_hz=self.truth_rate,
        )


def _guided_setup(flight: FlightOptions) -> Any:
    """The setup of a flight hilnav's guidance law flies: an in-air start only."""
    if flight.start_kind() == "ground":
        raise bad_input("--start ground needs an autopilot to take off (hilnav sim px4 or "
                        "sim ardupilot); hilnav's guidance law flies from an in-air start")
    return flight.setup()


flight_options = option_group("flight", _flight_template, FlightOptions)
"""Gives a ``sim`` mode the flight and sensor options as one ``flight: FlightOptions``."""

RecordAlsoOption = Annotated[Path | None, typer.Option(
    "--record", help="Also write every frame to this MAVLink log (.tlog).")]
StallTimeoutOption = Annotated[float, typer.Option(
    help="Wall seconds without the autopilot's controls before the run ends as stalled.",
    rich_help_panel=_AUTOPILOT)]
ConnectTimeoutOption = Annotated[float, typer.Option(
    help="Wall seconds to wait for the autopilot to connect.", rich_help_panel=_AUTOPILOT)]

sim_app = typer.Typer(
    name="sim",
    help="Fly a plan and record it (lockstep, as fast as possible), stream it live, or let an "
         "autopilot fly it (PX4, ArduPilot).",
    no_args_is_help=False,
    invoke_without_command=True,
    pretty_exceptions_enable=False,
)


@sim_app.callback()
def sim(ctx: typer.Context) -> None:
    """Fly a plan and record it (lockstep, as fast as possible), stream it live, or let an
    autopilot fly it (PX4, ArduPilot)."""
    if ctx.invoked_subcommand is None:
        raise bad_input("hilnav sim needs a mode: record FILE, live URL, px4 URL or "
                        "ardupilot URL (see hilnav sim --help)")


def _checked_record(record: Path | None) -> Path | None:
    return None if record is None else out_file(record, "--record")


@sim_app.command()
@cli_errors
@flight_options
def record(
    file: Annotated[Path, typer.Argument(help="MAVLink log (.tlog) to write.")],
    *,
    flight: FlightOptions,
) -> None:
    """Fly in lockstep, as fast as possible, and record every frame to FILE."""
    out_file(file, "--record")
    from hil.pipeline import record_flight

    request = _guided_setup(flight)
    with progress_bar(request.duration_s, "flying",
                      events=scripted_events(request)) as progress:
        report = record_flight(request, file, progress=progress)
    console.print(
        f"recorded {report.frames} frames, {report.sim_duration_s:.1f} s simulated in "
        f"{report.wall_s:.1f} s ({report.realtime_factor:.0f}x real time) -> {file}"
    )
    if report.ended is not None:
        raise RunFailed(f"{report.ended}; the log up to that point is kept in {file}")


@sim_app.command()
@cli_errors
@flight_options
@zenoh_security_options
def live(
    url: Annotated[str, typer.Argument(
        help="MAVLink URL to send the frames to, e.g. udpout:HOST:14560.")],
    record: RecordAlsoOption = None,
    speed: Annotated[float, typer.Option(
        help="Simulated seconds per wall second (1 = hardware).")] = 1.0,
    zenoh: Annotated[str | None, typer.Option(
        help="Publish truth and sensors via this router.")] = None,
    vehicle: Annotated[str, typer.Option(help="Zenoh vehicle name.")] = "sim1",
    wait_peer: Annotated[float, typer.Option(
        help="Wait up to S s for the receiver's heartbeat.")] = 0.0,
    lockstep: Annotated[bool, typer.Option(
        help="Never run ahead of the fusion service's acknowledgements by more than "
             "--lockstep-window (no loss at any speed).")] = False,
    lockstep_window: Annotated[float, typer.Option(
        help="With --lockstep: simulated seconds allowed ahead of the ack.")] = 0.25,
    signing_key_file: SigningKeyFileOption = None,
    *,
    flight: FlightOptions,
    zenoh_security: ZenohSecurity,
) -> None:
    """Stream the frames live to a MAVLink URL (a fusion service) at --speed x real time."""
    record = _checked_record(record)
    request = _guided_setup(flight)
    access = zenoh_security.access(zenoh)
    from hil.live_sim import live_sim, stop_on_signals
    from hil.signing import load_key

    if zenoh is not None:
        from hil.bus import validate_endpoint, validate_vehicle

        validate_endpoint(zenoh)
        validate_vehicle(vehicle)
    key = load_key(signing_key_file)
    err_console.print(f"sim: streaming to {url} at {speed:g}x real time"
                      + (" (lockstep)" if lockstep else ""), highlight=False)
    with stop_on_signals() as stop, progress_bar(
            request.duration_s, FLYING, events=scripted_events(request)) as progress:
        report = live_sim(request, url, speed=speed, record=record, zenoh=zenoh,
                          vehicle=vehicle, signing_key=key, bus_access=access,
                          wait_peer_s=wait_peer,
                          lockstep=lockstep, lockstep_window_s=lockstep_window,
                          progress=progress, stop=stop)
    speed_said, missed = speed_sentence(report.realtime_factor, speed)
    console.print(
        f"sent {report.sent}/{report.frames} frames, {report.sim_duration_s:.1f} s simulated in "
        f"{report.wall_s:.1f} s ({speed_said})"
        + (f" -> {record}" if record is not None else "")
        + ("" if report.peer_seen or wait_peer == 0 else "; no receiver heartbeat seen")
        + (f"; waited {report.lockstep_wait_s:.1f} s for the fusion" if lockstep else "")
    )
    if missed and report.ended is None and not report.stalled:
        say_warning(speed_said)
    if report.stalled:
        raise RunFailed("lockstep: the fusion service stopped acknowledging (is it running "
                        f"and listening at {url}?)")
    if report.ended is not None:
        raise RunFailed(str(report.ended))


@sim_app.command()
@cli_errors
@flight_options
def px4(
    url: Annotated[str, typer.Argument(
        help="Wait for PX4 SITL here (tcpin:127.0.0.1:4560, the port PX4 dials; "
             "tcpin:0.0.0.0:4560 for a PX4 on another machine; lockstep) or talk to a HITL "
             "board (serial:/dev/ttyACM0:921600; paced at --speed).")],
    actuator_map: Annotated[Path | None, typer.Option(
        help="Actuator map YAML (default: the legacy HIL order 0 roll, 1 pitch, 2 yaw, "
             "3 throttle).", rich_help_panel=_AUTOPILOT)] = None,
    record: RecordAlsoOption = None,
    speed: Annotated[float, typer.Option(
        help="With a HITL board: simulated seconds per wall second (1 = hardware).")] = 1.0,
    stall_timeout: StallTimeoutOption = 10.0,
    connect_timeout: ConnectTimeoutOption = 60.0,
    *,
    flight: FlightOptions,
) -> None:
    """PX4 flies the aircraft: SITL in lockstep over TCP, or a HITL board over a serial port."""
    record = _checked_record(record)
    request = flight.setup()
    from hil.live_sim import stop_on_signals
    from scenarios.cli.px4 import fly_px4, px4_failure, px4_report

    def listening(where: str) -> None:
        err_console.print(f"sim: waiting for PX4 at {where}", highlight=False, markup=False)

    with stop_on_signals() as stop, progress_bar(
            request.duration_s, "PX4 flying", events=scripted_events(request)) as progress:
        flown = fly_px4(request, url, actuator_map=actuator_map, record=record, speed=speed,
                        stall_timeout_s=stall_timeout, connect_timeout_s=connect_timeout,
                        progress=progress, stop=stop, on_listening=listening)
    console.print(px4_report(flown, record), highlight=False)
    failure = px4_failure(flown, url, connect_timeout)
    if failure is not None:
        raise RunFailed(failure)


@sim_app.command()
@cli_errors
@flight_options
def ardupilot(
    url: Annotated[str, typer.Argument(
        help="Serve ArduPilot SITL's JSON physics interface here (udpin:127.0.0.1:9002; "
             "udpin:0.0.0.0:9002 for a SITL on another machine).")],
    servo_map: Annotated[Path | None, typer.Option(
        help="Servo map YAML (default ArduPlane: 1 aileron, 2 elevator, 3 throttle, 4 rudder, "
             "1000-2000 us).", rich_help_panel=_AUTOPILOT)] = None,
    ardupilot_mavlink: Annotated[str | None, typer.Option(
        help="ArduPilot's MAVLink port (e.g. tcp:127.0.0.1:5762; 5760 is sim_vehicle's "
             "MAVProxy) for the SIM_GPS1_* parameters of the GNSS denial.",
        rich_help_panel=_AUTOPILOT)] = None,
    record: RecordAlsoOption = None,
    stall_timeout: StallTimeoutOption = 10.0,
    connect_timeout: ConnectTimeoutOption = 60.0,
    *,
    flight: FlightOptions,
) -> None:
    """ArduPilot SITL flies the aircraft through its JSON physics interface, in lockstep."""
    record = _checked_record(record)
    request = flight.setup()
    from scenarios.cli.ardupilot import flown_sentence, fly_ardupilot

    def say(line: str) -> None:
        err_console.print(line, highlight=False, markup=False)

    with progress_bar(request.duration_s, "flying",
                      events=scripted_events(request)) as progress:
        flown = fly_ardupilot(request, url, servo_map_path=servo_map,
                              mavlink_url=ardupilot_mavlink, record=record,
                              connect_timeout_s=connect_timeout, stall_timeout_s=stall_timeout,
                              progress=progress, on_waiting=say,
                              warn=lambda w: say(f"warning: {w}"))
    if not flown.connected:
        raise RunFailed(f"no ArduPilot servo packet within {connect_timeout:g} s on {url}")
    console.print(flown_sentence(flown, record), highlight=False, markup=False)
    for problem in flown.problems:
        err_console.print(f"[red]failure:[/] {problem}", highlight=False)
    if flown.stalled is not None:
        raise RunFailed(flown.stalled)
    if flown.ended is not None:
        raise RunFailed(str(flown.ended))
    if flown.problems:
        raise RunFailed("; ".join(flown.problems))
