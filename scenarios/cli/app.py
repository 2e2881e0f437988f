"""The ``hilnav`` command line: a thin typed layer over the pipeline, the scorer and the services.

Exit codes follow ARCHITECTURE.md: 0 success / pass, 1 run failed (criteria failed, aircraft
crashed), 2 bad input (one line on stderr naming what is wrong, never a traceback).
"""

from __future__ import annotations

import contextlib
import functools
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any, Literal, ParamSpec, TypeVar

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from scenarios.cli.quick_exit import (
    QUICK_EXIT_COMMANDS,
    command_of,
    freeze_for_exit,
    settled_heap,
)

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

# the names of the fusion's choices, without the filter behind them (numpy, scipy, pydantic:
# each command imports what it runs, so --help and the light commands stay fast)
from fusion.choices import (  # noqa: E402
    AIRSPEED_MODES,
    ALIGN_MODES,
    ALTITUDE_METHODS,
    BRIDGE_METHODS,
    DEFAULT_AIRSPEED_MODE,
    DEFAULT_ALIGN_MODE,
)

# Options of every command that runs the filter: defined once so that replay, demo, fusion
# and up build the filter from the same choices (run / compare / campaign take them from the
# scenario file, with --bridge / --altitude / --airspeed / --align overrides).
ImuOption = Annotated[str, typer.Option(help="IMU datasheet preset the filter is tuned for.")]
GnssOption = Annotated[
    str, typer.Option(help="GNSS receiver preset the filter models (its correlated error).")]
BridgeOption = Annotated[str, typer.Option(
    help=f"GNSS-outage bridging method: {', '.join(BRIDGE_METHODS)}.")]
AltitudeOption = Annotated[str, typer.Option(
    help=f"Altitude method: {', '.join(ALTITUDE_METHODS)}.")]
AirspeedOption = Annotated[str, typer.Option(
    help="Air data: on (fused when the stream carries a pitot), off (not fused), synthetic "
         "(on, plus synthetic airspeed for a fixed-wing without a pitot).")]
AirspeedOverride = Annotated[str | None, typer.Option(
    help=f"Override the scenario's air-data choice: {', '.join(AIRSPEED_MODES)}.")]
AlignOption = Annotated[str, typer.Option(
    help="Alignment (experts): auto (at rest: levelling + magnetometer; moving: GNSS track, or "
         "the magnetometer when slower than 5 m/s), static, in-flight.")]
AlignOverride = Annotated[str | None, typer.Option(
    help=f"Override the scenario's alignment: {', '.join(ALIGN_MODES)}.")]
SettleOption = Annotated[
    float, typer.Option(help="Scorecard: seconds excluded after the start and each outage "
                             "(shortened, with a warning, when a log is too short for it).")]

# How a bus client (fusion, sim, monitor, check) joins a secured Zenoh router; see the README's
# "Securing the Zenoh bus". Secrets never go on the command line: files or the environment.
ZenohUserOption = Annotated[str | None, typer.Option(
    help="Zenoh usrpwd user (password from --zenoh-password-file or env HILNAV_ZENOH_PASSWORD).",
    rich_help_panel="Zenoh security")]
ZenohPasswordFileOption = Annotated[Path | None, typer.Option(
    help="File whose first line is the Zenoh usrpwd password.", rich_help_panel="Zenoh security")]
TlsCaOption = Annotated[Path | None, typer.Option(
    help="CA certificate (PEM) that signed the router's certificate (tls/ endpoints).",
    rich_help_panel="Zenoh security")]
TlsCertOption = Annotated[Path | None, typer.Option(
    help="This client's certificate (PEM) for mTLS; its common name is its access-control name.",
    rich_help_panel="Zenoh security")]
TlsKeyOption = Annotated[Path | None, typer.Option(
    help="Private key (PEM) of --tls-cert.", rich_help_panel="Zenoh security")]
ZenohKeyFileOption = Annotated[Path | None, typer.Option(
    help="Shared key (32 bytes, hex or base64) that tags every Zenoh sample and checks "
         "received ones (default: env HILNAV_ZENOH_KEY).", rich_help_panel="Zenoh security")]
ZenohLowLatencyOption = Annotated[bool, typer.Option(
    help="Ask for Zenoh's low-latency transport (no transmit batching; QoS priorities off). A "
         "link uses it only when the other end asks too (fusion and a direct subscriber).")]


class RunFailed(Exception):
    """The run happened but did not succeed (exit code 1)."""


def _bad_input_message(exc: ValueError) -> str:
    """One line for a bad value: pydantic's first validation error as ``where: what``."""
    pydantic = sys.modules.get("pydantic")  # not imported: exc cannot be a ValidationError
    if pydantic is None or not isinstance(exc, pydantic.ValidationError):
        return str(exc)
    e = exc.errors()[0]
    loc = ".".join(str(p) for p in e["loc"]) or exc.title
    return f"{loc}: {e['msg']}"


def cli_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn bad input into a one-line message and exit code 2; failed runs into exit 1."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except ValueError as exc:  # pydantic's ValidationError included
            err_console.print(f"[red]error:[/] {_bad_input_message(exc)}", highlight=False)
            raise typer.Exit(2) from None
        except FileNotFoundError as exc:
            err_console.print(f"[red]error:[/] {exc}", highlight=False)
            raise typer.Exit(2) from None
        except OSError as exc:  # a path the user named cannot be written or read
            where = f": {exc.filename}" if exc.filename else ""
            err_console.print(f"[red]error:[/] {exc.strerror or exc}{where}", highlight=False)
            raise typer.Exit(2) from None
        except RunFailed as exc:
            err_console.print(f"[red]failed:[/] {exc}", highlight=False)
            raise typer.Exit(1) from None

    return wrapper


def _out_dir(path: Path, option: str = "--out") -> Path:
    """``path`` can be (or become) a folder: not a file, no file on the way to it."""
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"lies under the file {p}"
                raise ValueError(f"{option} {path} {what}; give a folder")
            break
    return path


def _out_file(path: Path, option: str) -> Path:
    """``path`` can be (or become) a file: not a folder, no file on the way to it."""
    if path.is_dir():
        raise ValueError(f"{option} {path} is a folder; give a file name")
    _out_dir(path.parent, f"{option}'s folder")
    return path


def _choice(name: str, value: str, valid: tuple[str, ...] | list[str]) -> str:
    if value not in valid:
        raise ValueError(f"unknown {name} {value!r}; valid choices: {', '.join(valid)}")
    return value


@contextlib.contextmanager
def _progress(total_s: float, label: str) -> Iterator[Callable[[float], None]]:
    """A transient bar on stderr over ``total_s`` simulated seconds (hidden when stderr is not
    a terminal); yields the ``progress(t_s)`` callback the runners take."""
    bar = Progress(
        TextColumn(f"[bold]{label}"),
        BarColumn(),
        TextColumn("{task.completed:>7.0f}/{task.total:.0f} s"),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    )
    with bar:
        task = bar.add_task(label, total=total_s)
        yield lambda t: bar.update(task, completed=t)


# --------------------------------------------------------------------------------------- sim
@app.command()
@cli_errors
def sim(
    record: Annotated[
        Path | None, typer.Option(help="MAVLink log (.tlog) to write (required without --live).")
    ] = None,
    plan: Annotated[str, typer.Option(help="Flight plan name or YAML path.")] = "racetrack",
    aircraft: Annotated[str, typer.Option(help="JSBSim aircraft from the jsbsim wheel.")] = "c172x",
    duration: Annotated[float, typer.Option(help="Simulated seconds.")] = 600.0,
    seed: Annotated[int, typer.Option(help="Scenario seed (sensor noise, turbulence).")] = 1,
    rate: Annotated[float, typer.Option(help="Simulation and IMU rate, Hz (50-400).")] = 200.0,
    imu: Annotated[str, typer.Option(help="IMU preset.")] = "industrial-mems",
    gnss: Annotated[str, typer.Option(help="GNSS preset.")] = "modern",
    baro: Annotated[str, typer.Option(help="Barometer preset.")] = "ms5611",
    mag: Annotated[str, typer.Option(help="Magnetometer preset.")] = "consumer",
    pitot: Annotated[
        str, typer.Option(help="Pitot (airspeed) preset; none = an aircraft without one.")
    ] = "ms4525do",
    lat: Annotated[float, typer.Option(help="Start latitude, deg.")] = 47.0,
    lon: Annotated[float, typer.Option(help="Start longitude, deg.")] = 8.0,
    alt: Annotated[float, typer.Option(help="Start altitude MSL, m.")] = 1000.0,
    heading: Annotated[float, typer.Option(help="Start heading, deg true.")] = 0.0,
    airspeed: Annotated[float, typer.Option(help="Start true airspeed, m/s.")] = 50.0,
    wind: Annotated[str, typer.Option(help="Wind N,E,D in m/s (direction it blows to).")] = "0,0,0",
    wind_shear: Annotated[
        float,
        typer.Option(help="Power-law shear exponent of the horizontal wind (1/7 = neutral "
                     "boundary layer; 0 = the same wind at every height)."),
    ] = 0.0,
    wind_ref_agl: Annotated[
        float | None,
        typer.Option(help="Height above ground at which --wind holds, m (default: start "
                     "altitude)."),
    ] = None,
    turbulence: Annotated[float, typer.Option(help="Turbulence severity 0..1.")] = 0.0,
    gnss_off: Annotated[
        list[str] | None,
        typer.Option("--gnss-off", help="GNSS outage START:DURATION s (repeatable)."),
    ] = None,
    truth_rate: Annotated[float, typer.Option(help="Truth message rate, Hz.")] = 50.0,
    live: Annotated[
        str | None,
        typer.Option(help="Send the frames live to this MAVLink URL, e.g. udpout:HOST:14560."),
    ] = None,
    speed: Annotated[
        float, typer.Option(help="With --live: simulated seconds per wall second (1 = hardware).")
    ] = 1.0,
    zenoh: Annotated[
        str | None, typer.Option(help="With --live: publish truth and sensors via this router.")
    ] = None,
    vehicle: Annotated[str, typer.Option(help="Zenoh vehicle name.")] = "sim1",
    wait_peer: Annotated[
        float, typer.Option(help="With --live: wait up to S s for the receiver's heartbeat.")
    ] = 0.0,
    lockstep: Annotated[
        bool,
        typer.Option(help="With --live: never run ahead of the fusion service's "
                     "acknowledgements by more than --lockstep-window (no loss at any speed)."),
    ] = False,
    lockstep_window: Annotated[
        float, typer.Option(help="With --lockstep: simulated seconds allowed ahead of the ack.")
    ] = 0.25,
    signing_key_file: Annotated[
        Path | None,
        typer.Option(help="MAVLink 2 signing key file (default: env HILNAV_MAVLINK_KEY)."),
    ] = None,
    zenoh_user: ZenohUserOption = None,
    zenoh_password_file: ZenohPasswordFileOption = None,
    tls_ca: TlsCaOption = None,
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    zenoh_key_file: ZenohKeyFileOption = None,
    px4: Annotated[str | None, typer.Option(
        help="PX4 flies the aircraft: wait for PX4 SITL here (tcpin:127.0.0.1:4560, the port "
             "PX4 dials; tcpin:0.0.0.0:4560 for a PX4 on another machine; lockstep) or talk to "
             "a HITL board (serial:/dev/ttyACM0:921600; paced at --speed).",
        rich_help_panel="Autopilot in the loop")] = None,
    actuator_map: Annotated[Path | None, typer.Option(
        help="With --px4: actuator map YAML (default: the legacy HIL order 0 roll, 1 pitch, "
             "2 yaw, 3 throttle).", rich_help_panel="Autopilot in the loop")] = None,
    ardupilot: Annotated[str | None, typer.Option(
        help="ArduPilot SITL flies the aircraft: serve its JSON physics interface here "
             "(udpin:127.0.0.1:9002; udpin:0.0.0.0:9002 for a SITL on another machine).",
        rich_help_panel="Autopilot in the loop")] = None,
    servo_map: Annotated[Path | None, typer.Option(
        help="With --ardupilot: servo map YAML (default ArduPlane: 1 aileron, 2 elevator, "
             "3 throttle, 4 rudder, 1000-2000 us).", rich_help_panel="Autopilot in the loop")
    ] = None,
    ardupilot_mavlink: Annotated[str | None, typer.Option(
        help="With --ardupilot: ArduPilot's MAVLink port (e.g. tcp:127.0.0.1:5760) for the "
             "SIM_GPS1_* parameters of the GNSS denial.", rich_help_panel="Autopilot in the loop")
    ] = None,
    stall_timeout: Annotated[float, typer.Option(
        help="With an autopilot: wall seconds without its controls before the run ends as "
             "stalled.", rich_help_panel="Autopilot in the loop")] = 10.0,
    connect_timeout: Annotated[float, typer.Option(
        help="With an autopilot: wall seconds to wait for it to connect.",
        rich_help_panel="Autopilot in the loop")] = 60.0,
) -> None:
    """Fly a plan and record it (lockstep, as fast as possible), stream it live (--live), or let
    an autopilot fly it (--px4, --ardupilot)."""
    if record is not None:
        _out_file(record, "--record")
    from hil.pipeline import SimSetup, record_flight

    request = SimSetup.build(
        plan=plan, aircraft=aircraft, duration_s=duration, seed=seed, rate_hz=rate,
        imu=imu, gnss=gnss, baro=baro, mag=mag, pitot=pitot, lat_deg=lat, lon_deg=lon,
        alt_msl_m=alt, heading_deg=heading, airspeed_mps=airspeed, wind=wind, turbulence=turbulence,
        wind_shear_exponent=wind_shear, wind_ref_agl_m=wind_ref_agl,
        gnss_off=gnss_off or [], truth_rate_hz=truth_rate,
    )
    if lockstep and live is None:
        raise ValueError("--lockstep paces against a fusion service: it needs --live URL")
    if px4 is None and actuator_map is not None:
        raise ValueError("--actuator-map maps PX4's controls: it needs --px4 URL")
    if ardupilot is None and (servo_map is not None or ardupilot_mavlink is not None):
        raise ValueError("--servo-map and --ardupilot-mavlink need --ardupilot URL")
    if px4 is not None and ardupilot is not None:
        raise ValueError("--px4 and --ardupilot are two autopilots: give one")
    if px4 is not None:
        if live is not None:
            raise ValueError("--px4 and --live are two ways to fly: give one")
        _sim_px4(request, px4, actuator_map=actuator_map, record=record, speed=speed,
                 stall_timeout=stall_timeout, connect_timeout=connect_timeout)
        return
    if ardupilot is not None:
        if live is not None:
            raise ValueError("--ardupilot and --live are two ways to fly: give one")
        _sim_ardupilot(request, ardupilot, servo_map=servo_map, mavlink_url=ardupilot_mavlink,
                       record=record, stall_timeout=stall_timeout,
                       connect_timeout=connect_timeout)
        return
    if live is not None:
        access = _bus_access(zenoh, zenoh_user, zenoh_password_file, tls_ca, tls_cert,
                             tls_key, zenoh_key_file)
        _sim_live(request, live, speed=speed, record=record, zenoh=zenoh, vehicle=vehicle,
                  wait_peer=wait_peer, signing_key_file=signing_key_file, lockstep=lockstep,
                  lockstep_window=lockstep_window, bus_access=access)
        return
    if record is None:
        raise ValueError("--record is required (or stream live with --live URL)")
    with _progress(duration, "flying") as progress:
        report = record_flight(request, record, progress=progress)
    console.print(
        f"recorded {report.frames} frames, {report.sim_duration_s:.1f} s simulated in "
        f"{report.wall_s:.1f} s ({report.realtime_factor:.0f}x real time) -> {record}"
    )
    if report.ended is not None:
        raise RunFailed(f"{report.ended}; the log up to that point is kept in {record}")




def _sim_px4(request: Any, url: str, *, actuator_map: Path | None, record: Path | None,
             speed: float, stall_timeout: float, connect_timeout: float) -> None:
    from hil.live_sim import stop_on_signals
    from scenarios.cli.px4 import fly_px4, px4_failure, px4_report

    def listening(where: str) -> None:
        err_console.print(f"sim: waiting for PX4 at {where}", highlight=False, markup=False)

    with stop_on_signals() as stop, _progress(request.duration_s, "PX4 flying") as progress:
        flown = fly_px4(request, url, actuator_map=actuator_map, record=record, speed=speed,
                        stall_timeout_s=stall_timeout, connect_timeout_s=connect_timeout,
                        progress=progress, stop=stop, on_listening=listening)
    console.print(px4_report(flown, record), highlight=False)
    failure = px4_failure(flown, url, connect_timeout)
    if failure is not None:
        raise RunFailed(failure)


def _sim_ardupilot(request: Any, url: str, *, servo_map: Path | None, mavlink_url: str | None,
                   record: Path | None, stall_timeout: float, connect_timeout: float) -> None:
    from scenarios.cli.ardupilot import flown_sentence, fly_ardupilot

    def say(line: str) -> None:
        err_console.print(line, highlight=False, markup=False)

    with _progress(request.duration_s, "flying") as progress:
        flown = fly_ardupilot(request, url, servo_map_path=servo_map, mavlink_url=mavlink_url,
                              record=record, connect_timeout_s=connect_timeout,
                              stall_timeout_s=stall_timeout, progress=progress,
                              on_waiting=say, warn=lambda w: say(f"warning: {w}"))
    if not flown.connected:
        raise RunFailed(f"no ArduPilot servo packet within {connect_timeout:g} s on {url}")
    console.print(flown_sentence(flown, record), highlight=False, markup=False)
    if flown.stalled is not None:
        raise RunFailed(flown.stalled)
    if flown.ended is not None:
        raise RunFailed(str(flown.ended))


def _signing_key(path: Path | None) -> bytes | None:
    from hil.signing import load_key

    return load_key(path)


def _bus_access(endpoint: str | None, user: str | None, password_file: Path | None,
                tls_ca: Path | None, tls_cert: Path | None, tls_key: Path | None,
                key_file: Path | None) -> Any:
    """The :class:`hil.bus.BusAccess` of the Zenoh security options for ``endpoint`` (None:
    the command does not use Zenoh, and the options must not be given; exit 2 on bad input)."""
    given = [o for o, v in (("--zenoh-user", user), ("--zenoh-password-file", password_file),
                            ("--tls-ca", tls_ca), ("--tls-cert", tls_cert),
                            ("--tls-key", tls_key), ("--zenoh-key-file", key_file))
             if v is not None]
    if endpoint is None and given:
        raise ValueError(f"{given[0]} is a Zenoh option: it needs --zenoh ENDPOINT")
    import hil.codec  # noqa: F401  # hil.signing and hil.codec import each other: codec first
    from hil.bus.auth import KEY_ENV
    from hil.bus.security import BusAccess, ClientSecurity
    from hil.signing import load_key

    security = ClientSecurity.from_options(user=user, password_file=password_file,
                                           tls_ca=tls_ca, tls_cert=tls_cert, tls_key=tls_key)
    if endpoint is not None:
        security.check_endpoints([endpoint])
    return BusAccess(security=security, auth_key=load_key(key_file, env=KEY_ENV))


def _sim_live(request: Any, url: str, *, speed: float, record: Path | None, zenoh: str | None,
              vehicle: str, wait_peer: float, signing_key_file: Path | None,
              lockstep: bool = False, lockstep_window: float = 0.25,
              bus_access: Any = None) -> None:
    from hil.live_sim import live_sim, stop_on_signals

    if zenoh is not None:
        from hil.bus import validate_endpoint, validate_vehicle

        validate_endpoint(zenoh)
        validate_vehicle(vehicle)
    key = _signing_key(signing_key_file)
    err_console.print(f"sim: streaming to {url} at {speed:g}x real time"
                      + (" (lockstep)" if lockstep else ""), highlight=False)
    with stop_on_signals() as stop, _progress(request.duration_s, "flying") as progress:
        report = live_sim(request, url, speed=speed, record=record, zenoh=zenoh,
                          vehicle=vehicle, signing_key=key, bus_access=bus_access,
                          wait_peer_s=wait_peer,
                          lockstep=lockstep, lockstep_window_s=lockstep_window,
                          progress=progress, stop=stop)
    console.print(
        f"sent {report.sent}/{report.frames} frames, {report.sim_duration_s:.1f} s simulated in "
        f"{report.wall_s:.1f} s ({report.realtime_factor:.2f}x real time, target {speed:g}x)"
        + (f" -> {record}" if record is not None else "")
        + ("" if report.peer_seen or wait_peer == 0 else "; no receiver heartbeat seen")
        + (f"; waited {report.lockstep_wait_s:.1f} s for the fusion" if lockstep else "")
    )
    if report.stalled:
        raise RunFailed("lockstep: the fusion service stopped acknowledging (is it running "
                        f"and listening at {url}?)")
    if report.ended is not None:
        raise RunFailed(str(report.ended))


# ------------------------------------------------------------------------------------ fusion
@app.command()
@cli_errors
def fusion(
    mavlink: Annotated[
        str, typer.Option(help="Sensor input MAVLink URL, e.g. udpin:0.0.0.0:14560.")
    ] = "udpin:0.0.0.0:14560",
    source: Annotated[str | None, typer.Option(
        help="Take sensors only from SYSID[:COMPID] (default: lock onto the first sensor "
             "source; other senders are counted and ignored).")] = None,
    zenoh: Annotated[str | None, typer.Option(help="Zenoh router endpoint to publish on.")] = None,
    zenoh_listen: Annotated[str | None, typer.Option(
        help="Peer-to-peer: also serve Zenoh subscribers that connect here directly (hilnav "
             "monitor --peer), without the router's hop; loopback only, no login/TLS.")] = None,
    zenoh_low_latency: ZenohLowLatencyOption = False,
    vehicle: Annotated[str, typer.Option(help="Zenoh vehicle name.")] = "sim1",
    imu: ImuOption = "industrial-mems",
    gnss: GnssOption = "modern",
    bridge: BridgeOption = "none",
    altitude: AltitudeOption = "ekf",
    airspeed: AirspeedOption = DEFAULT_AIRSPEED_MODE,
    align: AlignOption = DEFAULT_ALIGN_MODE,
    gcs: Annotated[
        str | None,
        typer.Option(help="Shadow vehicle for ground stations, e.g. udpout:127.0.0.1:14550."),
    ] = None,
    shadow_sysid: Annotated[int, typer.Option(help="Shadow vehicle's MAVLink system id.")] = 1,
    gcs_tlog: Annotated[
        Path | None,
        typer.Option(help="Record the shadow vehicle's stream to this .tlog (needs --gcs)."),
    ] = None,
    companion: Annotated[
        str | None, typer.Option(help="Flight controller link for GPS_INPUT / ODOMETRY.")
    ] = None,
    companion_kind: Annotated[
        str, typer.Option(help="gps_input (ArduPilot) or odometry (PX4).")
    ] = "gps_input",
    companion_sysid: Annotated[int, typer.Option(help="Flight controller's system id.")] = 1,
    duration: Annotated[
        float | None, typer.Option(help="Stop after S wall-clock seconds.")
    ] = None,
    idle_exit: Annotated[
        float | None, typer.Option(help="Stop after S s without input (once input started).")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Write summary.json (live scorecard) here at exit.")
    ] = None,
    settle: SettleOption = 60.0,
    signing_key_file: Annotated[
        Path | None,
        typer.Option(help="MAVLink 2 signing key file (default: env HILNAV_MAVLINK_KEY)."),
    ] = None,
    zenoh_user: ZenohUserOption = None,
    zenoh_password_file: ZenohPasswordFileOption = None,
    tls_ca: TlsCaOption = None,
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    zenoh_key_file: ZenohKeyFileOption = None,
) -> None:
    """Live fusion service: MAVLink sensors in; shadow vehicle, companion and Zenoh out."""
    if out is not None:
        _out_dir(out)
    if gcs_tlog is not None and gcs is None:
        raise ValueError("--gcs-tlog needs --gcs")
    from hil.pipeline import build_filter, filter_config
    from hil.service import FusionOptions, parse_source
    from scenarios.cli.live import serve_fusion
    from sim.presets import gnss_preset

    access = _bus_access(zenoh or zenoh_listen, zenoh_user, zenoh_password_file, tls_ca,
                         tls_cert, tls_key, zenoh_key_file)
    if zenoh is not None or zenoh_listen is not None:
        from hil.bus import validate_endpoint, validate_vehicle

        for endpoint in (zenoh, zenoh_listen):
            if endpoint is not None:
                validate_endpoint(endpoint)
        validate_vehicle(vehicle)
    if zenoh_listen is not None:
        from hil.bus.security import check_peer_link

        check_peer_link([zenoh_listen], access.security)
    options = FusionOptions(
        mavlink=mavlink, source=source, zenoh=zenoh, zenoh_listen=zenoh_listen,
        zenoh_low_latency=zenoh_low_latency, vehicle=vehicle, imu=imu, gnss=gnss,
        bridge=bridge,
        altitude=altitude, airspeed=airspeed, align=align, gcs=gcs, gcs_tlog=gcs_tlog,
        shadow_system_id=shadow_sysid, companion=companion,
        companion_kind=companion_kind,  # type: ignore[arg-type]  # pydantic checks the literal
        companion_system_id=companion_sysid, duration_s=duration, idle_exit_s=idle_exit, out=out,
        settle_s=settle,
    )
    # a bad preset, method or source -> exit 2 before any socket opens
    if source is not None:
        parse_source(source)
    build_filter(filter_config(imu, gnss_preset(gnss), altitude, airspeed, align), bridge)
    key = _signing_key(signing_key_file)

    def ready(service: Any) -> None:
        where = ", ".join(f"{n}={link.url}" for n, link in service._links.items())
        err_console.print(f"fusion: listening ({where})", highlight=False)

    summary = serve_fusion(options, signing_key=key, bus_access=access, on_ready=ready)
    if summary is not None:
        _print_summary(summary)
        _warn_input(summary)
        live = summary.get("live", {})
        console.print(f"live: lost frames {live.get('lost_frames')}, "
                      f"realtime factor {_fmt(summary.get('realtime_factor'))}")
        if out is not None:
            console.print(f"summary -> {out / 'summary.json'}")


# ----------------------------------------------------------------------------------- monitor
FoxgloveOption = Annotated[int | None, typer.Option(
    "--foxglove", metavar="PORT",
    help="Serve a Foxglove WebSocket on 127.0.0.1:PORT (Foxglove's usual port: 8765).")]


@app.command()
@cli_errors
def monitor(
    connect: Annotated[str, typer.Option(help="Zenoh router endpoint.")] = "tcp/127.0.0.1:7447",
    peer: Annotated[bool, typer.Option(
        help="--connect is a fusion's --zenoh-listen endpoint: subscribe to it directly as a "
             "Zenoh peer (one hop less than through the router; loopback only).")] = False,
    zenoh_low_latency: ZenohLowLatencyOption = False,
    vehicle: Annotated[str, typer.Option(help="Vehicle name.")] = "sim1",
    record: Annotated[Path | None, typer.Option(help="Record everything to this .mcap.")] = None,
    duration: Annotated[float | None, typer.Option(help="Stop after S wall seconds.")] = None,
    headless: Annotated[bool, typer.Option(help="One text line per second.")] = False,
    foxglove: FoxgloveOption = None,
    zenoh_user: ZenohUserOption = None,
    zenoh_password_file: ZenohPasswordFileOption = None,
    tls_ca: TlsCaOption = None,
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    zenoh_key_file: ZenohKeyFileOption = None,
) -> None:
    """Show (and optionally record) what the fusion service publishes."""
    if record is not None:
        _out_file(record, "--record")
    from hil.bus import validate_endpoint
    from hil.monitor import monitor_main

    validate_endpoint(connect)
    access = _bus_access(connect, zenoh_user, zenoh_password_file, tls_ca, tls_cert, tls_key,
                         zenoh_key_file)
    if peer:
        from hil.bus.security import check_peer_link

        check_peer_link([connect], access.security)
    code = monitor_main(connect=connect, vehicle=vehicle, record=record, duration_s=duration,
                        headless=headless, foxglove_port=foxglove, bus_access=access,
                        peer=peer, low_latency=zenoh_low_latency)
    if code:
        raise typer.Exit(code)


# ------------------------------------------------------------------------------------ router
@app.command()
@cli_errors
def router(
    listen: Annotated[str, typer.Option(
        help="Endpoint(s) to listen on; beyond loopback only with --users-file or --mtls "
             "(or --insecure).")] = "tcp/127.0.0.1:7447",
    duration: Annotated[float | None, typer.Option(help="Stop after S wall seconds.")] = None,
    users_file: Annotated[Path | None, typer.Option(
        help="usrpwd dictionary (one user:password per line): clients must log in.",
        rich_help_panel="Zenoh security")] = None,
    tls_cert: Annotated[Path | None, typer.Option(
        help="The router's certificate (PEM) for tls/ endpoints.",
        rich_help_panel="Zenoh security")] = None,
    tls_key: Annotated[Path | None, typer.Option(
        help="Private key (PEM) of --tls-cert.", rich_help_panel="Zenoh security")] = None,
    tls_ca: Annotated[Path | None, typer.Option(
        help="With --mtls: the CA (PEM) that must have signed every client's certificate.",
        rich_help_panel="Zenoh security")] = None,
    mtls: Annotated[bool, typer.Option(
        help="Clients must present a certificate signed by --tls-ca.",
        rich_help_panel="Zenoh security")] = False,
    acl: Annotated[bool, typer.Option(
        help="Access control: default deny; everyone authenticated reads hilnav/**; only the "
             "--acl-fusion names publish fusion/**, only the --acl-sim names sim/sensors/scenario.",
        rich_help_panel="Zenoh security")] = False,
    acl_fusion: Annotated[list[str] | None, typer.Option(
        help="User name or certificate common name of the fusion role (repeatable; default "
             "fusion).", rich_help_panel="Zenoh security")] = None,
    acl_sim: Annotated[list[str] | None, typer.Option(
        help="User name or certificate common name of the sim role (repeatable; default sim).",
        rich_help_panel="Zenoh security")] = None,
    insecure: Annotated[bool, typer.Option(
        help="Allow listening beyond loopback without client authentication.",
        rich_help_panel="Zenoh security")] = False,
) -> None:
    """Run a Zenoh router in this process."""
    from hil.bus.security import RouterSecurity
    from hil.router import router_main

    security = RouterSecurity(
        users_file=users_file, tls_cert=tls_cert, tls_key=tls_key, tls_ca=tls_ca, mtls=mtls,
        acl=acl, fusion=tuple(acl_fusion or ("fusion",)), sim=tuple(acl_sim or ("sim",)),
        insecure=insecure)
    code = router_main(listen=listen, duration_s=duration, security=security)
    if code:
        raise typer.Exit(code)


# ------------------------------------------------------------------------------------- check
@app.command()
@cli_errors
def check(
    connect: Annotated[str, typer.Option(help="Zenoh router endpoint.")] = "tcp/127.0.0.1:7447",
    vehicle: Annotated[str, typer.Option(help="Vehicle whose fusion/alive token --alive asks for.")
                       ] = "sim1",
    alive: Annotated[bool, typer.Option(help="Require the fusion service's liveliness token.")
                     ] = False,
    key: Annotated[list[str] | None, typer.Option(
        "--key", help="A sample must arrive on this key expression (repeatable).")] = None,
    timeout: Annotated[float, typer.Option(help="Overall time budget, s.")] = 5.0,
    zenoh_user: ZenohUserOption = None,
    zenoh_password_file: ZenohPasswordFileOption = None,
    tls_ca: TlsCaOption = None,
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    zenoh_key_file: ZenohKeyFileOption = None,
) -> None:
    """Health check of a running deployment (container health checks): exit 0 healthy, 1 not.

    With the shared key (HILNAV_ZENOH_KEY / --zenoh-key-file), --alive also challenges the
    fusion (a token declared by anyone else fails) and only tagged samples count for --key.
    """
    from hil.bus import check_bus

    access = _bus_access(connect, zenoh_user, zenoh_password_file, tls_ca, tls_cert, tls_key,
                         zenoh_key_file)
    code = check_bus(connect, vehicle, alive=alive, keys=tuple(key or ()), timeout_s=timeout,
                     report=lambda line: err_console.print(line, highlight=False),
                     security=access.security, auth_key=access.auth_key)
    if code:
        raise typer.Exit(code)


# ---------------------------------------------------------------------------------------- up
@app.command()
@cli_errors
def up(
    duration: Annotated[
        float | None, typer.Option(help="Simulated seconds (None: fly an hour or until Ctrl-C).")
    ] = None,
    speed: Annotated[float, typer.Option(help="Simulated seconds per wall second.")] = 1.0,
    out: Annotated[Path, typer.Option(help="Folder for summary.json and the recording.")] = Path(
        "out/up"
    ),
    vehicle: Annotated[str, typer.Option(help="Zenoh vehicle name.")] = "sim1",
    plan: Annotated[str, typer.Option(help="Flight plan name or YAML path.")] = "racetrack",
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 1,
    gnss_off: Annotated[
        list[str] | None,
        typer.Option("--gnss-off", help="GNSS outage START:DURATION s (repeatable)."),
    ] = None,
    imu: Annotated[str, typer.Option(help="IMU preset (sensor and filter tuning).")] = (
        "industrial-mems"),
    gnss: Annotated[str, typer.Option(help="GNSS preset (sensor and filter model).")] = "modern",
    bridge: BridgeOption = "none",
    altitude: AltitudeOption = "ekf",
    airspeed: AirspeedOption = DEFAULT_AIRSPEED_MODE,
    align: AlignOption = DEFAULT_ALIGN_MODE,
    gcs: Annotated[
        str | None, typer.Option(help="Also show the shadow vehicle to this ground station URL.")
    ] = None,
    monitor: Annotated[bool, typer.Option(help="Start the headless monitor too.")] = True,
    lockstep: Annotated[bool, typer.Option(
        help="The sim never runs ahead of the fusion's acknowledgements (no loss at any speed)."
    )] = False,
    foxglove: FoxgloveOption = None,
    zenoh_host: Annotated[str, typer.Option(
        help="Where the in-process Zenoh router listens; beyond loopback only with "
             "--users-file (or --insecure).", rich_help_panel="Zenoh security")] = "127.0.0.1",
    users_file: Annotated[Path | None, typer.Option(
        help="Outside clients (user:password lines), admitted read-only; turns on usrpwd and "
             "access control (up's own processes get random passwords).",
        rich_help_panel="Zenoh security")] = None,
    insecure: Annotated[bool, typer.Option(
        help="Allow --zenoh-host beyond loopback without authentication.",
        rich_help_panel="Zenoh security")] = False,
    zenoh_key_file: ZenohKeyFileOption = None,
    px4: Annotated[bool, typer.Option(
        "--px4", help="PX4 flies: wait for PX4 SITL (tcpin:127.0.0.1:4560) or a HITL board "
                      "(--autopilot-link serial:DEV:BAUD).",
        rich_help_panel="Autopilot in the loop")] = False,
    ardupilot: Annotated[bool, typer.Option(
        "--ardupilot", help="ArduPilot flies: wait for ArduPilot SITL's JSON backend "
                            "(udpin:127.0.0.1:9002).",
        rich_help_panel="Autopilot in the loop")] = False,
    autopilot_link: Annotated[str | None, typer.Option(
        help="With --px4 / --ardupilot: where the simulator meets the autopilot (default: "
             "the one above).", rich_help_panel="Autopilot in the loop")] = None,
    autopilot_telemetry: Annotated[str, typer.Option(
        help="Where the autopilot reports its estimate ('none': not recorded).",
        rich_help_panel="Autopilot in the loop")] = "udpin:127.0.0.1:14550",
    connect_timeout: Annotated[float, typer.Option(
        help="Wait this long for the autopilot, s.",
        rich_help_panel="Autopilot in the loop")] = 300.0,
    stall_timeout: Annotated[float, typer.Option(
        help="End the run as stalled after this long without controls, s.",
        rich_help_panel="Autopilot in the loop")] = 10.0,
) -> None:
    """Run router + fusion + sim (+ monitor) on loopback; Ctrl-C stops everything. With --px4
    or --ardupilot the autopilot flies and both estimates are scored side by side."""
    _out_dir(out)
    from scenarios.cli.up import UpOptions, run_up

    if px4 and ardupilot:
        raise ValueError("give --px4 or --ardupilot, not both")
    kind: Literal["none", "px4", "ardupilot"] = "px4" if px4 else \
        "ardupilot" if ardupilot else "none"
    if autopilot_link is not None and kind == "none":
        raise ValueError("--autopilot-link needs --px4 or --ardupilot")
    options = UpOptions(duration_s=duration, speed=speed, out=out, vehicle=vehicle, plan=plan,
                        seed=seed, gnss_off=tuple(gnss_off or ()), imu=imu, gnss=gnss,
                        bridge=bridge, altitude=altitude, airspeed=airspeed, align=align,
                        gcs=gcs,
                        monitor=monitor,
                        lockstep=lockstep, foxglove_port=foxglove, zenoh_host=zenoh_host,
                        users_file=users_file, insecure=insecure, zenoh_key_file=zenoh_key_file,
                        autopilot=kind,
                        autopilot_link=autopilot_link,
                        autopilot_telemetry=None if autopilot_telemetry == "none"
                        else autopilot_telemetry,
                        connect_timeout_s=connect_timeout, stall_timeout_s=stall_timeout)
    summary = run_up(options, log=lambda text: console.print(text, highlight=False))
    if summary is not None:
        console.print("[bold]scorecard of the live run[/]")
        _print_summary(summary)
        _print_autopilot(summary)
        live = summary.get("live", {})
        console.print(f"live: lost frames {live.get('lost_frames')}, "
                      f"realtime factor {_fmt(summary.get('realtime_factor'))}")
    elif duration is not None or kind != "none":
        raise RunFailed("the live run produced no scorecard (see the fusion output above)")
    if summary is not None and (summary.get("autopilot") or {}).get("stalled"):
        raise RunFailed(summary["autopilot"]["stalled"])
    if summary is not None and summary.get("autopilot") and \
            not summary["autopilot"].get("connected"):
        raise RunFailed(f"{summary['autopilot']['source']} did not connect within "
                        f"{connect_timeout:g} s")


# ------------------------------------------------------------------------------------ replay
@app.command()
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
    gnss_off: Annotated[
        list[str] | None,
        typer.Option("--gnss-off", help="Cut GNSS START:DURATION s, from the log's first "
                                        "sample (repeatable)."),
    ] = None,
) -> None:
    """Run the navigation filter on a recorded log and score it against the log's truth
    (.tlog) or the autopilot's estimate (.ulg)."""
    _out_dir(out)
    with settled_heap():
        from hil.pipeline import filter_config
        from hil.streamer import GnssWindow
        from scenarios.replay import replay as run_replay
        from sim.presets import gnss_preset

    _choice("bridging method", bridge, BRIDGE_METHODS)
    _choice("altitude method", altitude, ALTITUDE_METHODS)
    _choice("airspeed mode", airspeed, AIRSPEED_MODES)
    _choice("alignment", align, ALIGN_MODES)
    windows = list(gnss_off or [])
    for w in windows:  # a malformed window -> exit 2 before the log is read
        GnssWindow.parse(w)
    if not settle >= 0.0:
        raise ValueError(f"--settle must be >= 0 s (got {settle:g})")
    result = run_replay(log, out,
                        config=filter_config(imu, gnss_preset(gnss), altitude, airspeed, align),
                        bridge=bridge, altitude=altitude, settle_s=settle, gnss_off=windows)
    console.print(f"scored against: {result.summary['reference']['source']}")
    _print_summary(result.summary)
    _warn_input(result.summary)
    console.print(f"summary -> {result.summary_path}")


def _warn_input(s: dict[str, Any]) -> None:
    """Say on stderr when the log was damaged or cut (the scorecard has it in ``input``), when
    the settling time was shortened to fit the log (``settling``) and what the reference
    lacks (``reference``)."""
    for section in ("settling", "reference", "alignment"):
        warning = s.get(section, {}).get("warning")
        if warning:
            err_console.print(f"[yellow]warning:[/] {warning}", highlight=False)
    inp = s.get("input", {})
    if inp.get("corrupt"):
        err_console.print("[yellow]warning:[/] the ULog is damaged: pyulog skipped a corrupt "
                          "stretch; scored what was readable", highlight=False)
    if inp.get("logger_dropouts"):
        err_console.print(f"[yellow]warning:[/] the vehicle's logger dropped data "
                          f"{inp['logger_dropouts']} times ({inp['logger_dropout_ms']} ms in "
                          "all): samples are missing there", highlight=False)
    if inp.get("truncated") or inp.get("bad_frames") or inp.get("skipped_bytes"):
        err_console.print(
            f"[yellow]warning:[/] the log is damaged: {inp.get('bad_frames', 0)} bad frames, "
            f"{inp.get('skipped_bytes', 0)} bytes skipped"
            + (", the last record is truncated" if inp.get("truncated") else "")
            + f"; scored over {s.get('sim_duration_s', 0):.0f} s", highlight=False)


def _fmt(v: Any, spec: str = ".2f") -> str:
    return "n/a" if v is None or (isinstance(v, float) and v != v) else format(v, spec)


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


def _say_waiting_for_autopilot(scn: Any) -> None:
    ap = scn.autopilot
    err_console.print(
        f"waiting up to {ap.connect_timeout_s:g} s for {ap.kind} on "
        f"{ap.link or 'its default link'}; its estimate is recorded from "
        f"{ap.telemetry or 'nowhere (telemetry: null)'}", highlight=False)


def _print_autopilot(s: dict[str, Any]) -> None:
    """The side-by-side lines of a run with an autopilot in the loop (nothing without one)."""
    from scenarios.html import side_by_side_rows

    ap = s.get("autopilot")
    if not ap:
        return
    console.print(f"[bold]hilnav vs {ap['source']}[/] (same truth, same GNSS denial)",
                  highlight=False)
    for name, mine, theirs in side_by_side_rows(s):
        if mine is None and theirs is None:
            continue
        console.print(f"  {name}: hilnav {_fmt(mine)} | {ap['source']} {_fmt(theirs)}",
                      highlight=False)
    if ap.get("problem"):
        err_console.print(f"[yellow]warning:[/] {ap['source']}'s estimate not scored: "
                          f"{ap['problem']}", highlight=False)
    for t in (ap.get("health") or {}).get("failsafes") or []:
        console.print(f"  {ap['source']} at {t['time_s']:.1f} s: {t['text']}", highlight=False)


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
    gnss: Annotated[str, typer.Option(help="GNSS preset (sensor and filter model).")] = "modern",
    airspeed: AirspeedOption = DEFAULT_AIRSPEED_MODE,
    align: AlignOption = DEFAULT_ALIGN_MODE,
) -> None:
    """The main job: fly a racetrack, record it, run the filter with a GNSS outage, score it."""
    _out_dir(out)
    with settled_heap():
        from hil.pipeline import SimSetup, filter_config, record_flight
        from scenarios.replay import replay as run_replay
        from sim.presets import gnss_preset

    out.mkdir(parents=True, exist_ok=True)
    log = out / "run.tlog"
    config = filter_config(imu, gnss_preset(gnss), airspeed=airspeed, align=align)
    request = SimSetup.build(plan=plan, imu=imu, gnss=gnss, duration_s=duration, seed=seed,
                               gnss_off=[outage])
    with _progress(duration, "flying") as progress:
        report = record_flight(request, log, progress=progress)
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


# --------------------------------------------------------------------------- scenarios
def _load_scenario(path: Path, **overrides: Any) -> Any:
    from scenarios.schema import load_scenario

    scn = load_scenario(path)
    given = {k: v for k, v in overrides.items() if v is not None}
    return scn.with_overrides(**given) if given else scn


@app.command()
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
    quiet: Annotated[bool, typer.Option(help="No progress bar.")] = False,
) -> None:
    """Fly a scenario in lockstep, fuse it, score it: exit 0 pass, 1 fail, 2 bad input."""
    _out_dir(out)
    with settled_heap():
        from scenarios.runner import AutopilotAbsent, run_scenario

        scn = _load_scenario(scenario, seed=seed, bridge=bridge, altitude=altitude,
                             airspeed=airspeed, align=align)
        # the plots' module (matplotlib) too, once the scenario is valid: loaded here, its
        # import runs no collection and the collections while the plots are drawn skip it
        import scenarios.report  # noqa: F401
    if scn.autopilot.flies:
        _say_waiting_for_autopilot(scn)
    try:
        if quiet:
            result = run_scenario(scn, out)
        else:
            with _progress(scn.duration_s, scn.name) as progress:
                result = run_scenario(scn, out, progress=progress)
    except AutopilotAbsent as exc:
        raise RunFailed(str(exc)) from None
    s = result.summary
    _print_summary(s)
    _print_autopilot(s)
    for c in s.get("criteria", []):
        mark = "[green]pass[/]" if c["ok"] else "[red]FAIL[/]"
        console.print(f"  {mark} {c['name']}: {_fmt(c['value'], '.3g')} (limit {c['limit']:.3g})",
                      highlight=False)
    if "flight_ended" in s.get("health", {}):
        raise RunFailed(f"the flight ended early: {s['health']['flight_ended']}; see {out}")
    console.print(f"summary -> {out / 'summary.json'}; report -> {out / 'report.html'}")
    if (s.get("autopilot") or {}).get("stalled"):
        raise RunFailed(f"{s['autopilot']['stalled']}; see {out}")
    if not result.passed:
        failed = [c["name"] for c in s.get("criteria", []) if not c["ok"]]
        raise RunFailed(f"{scn.name}: criteria failed: {', '.join(failed)}")


@app.command()
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
) -> None:
    """Every bridging method on the same sensor data per seed (the papers' Tables 1 and 2)."""
    _out_dir(out)
    with settled_heap():
        from scenarios.compare import compare as run_compare
        from scenarios.compare import markdown, parse_methods

    names = parse_methods(methods)
    scn = _load_scenario(scenario, altitude=altitude, airspeed=airspeed, align=align)
    result = run_compare(scn, names, list(range(seed_base, seed_base + seeds)), out,
                         progress=lambda msg: err_console.print(msg, highlight=False))
    console.print(markdown(result), highlight=False)
    console.print(f"compare -> {out / 'compare.json'}")


@app.command()
@cli_errors
def schema(
    out: Annotated[Path | None, typer.Option(help="Write to this file instead of stdout.")] = None,
) -> None:
    """Print the JSON Schema of scenario files (for editor completion)."""
    if out is not None:
        _out_file(out, "--out")
    from scenarios.schema import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:
        out.write_text(text)
        console.print(f"schema -> {out}")


@app.command()
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
) -> None:
    """Monte Carlo sweep over seeds and parameter grids on Dask; exit 1 if any run failed."""
    _out_dir(out)
    from rich.progress import MofNCompleteColumn, TimeElapsedColumn

    from scenarios.campaign import parse_vary, run_campaign
    from scenarios.campaign.report import point_label

    if seed_base < 0:
        raise ValueError(f"--seed-base must be >= 0, got {seed_base}")
    grid = parse_vary(vary or [])
    if airspeed is not None:  # one air-data choice for every run: a one-value grid axis
        _choice("airspeed mode", airspeed, AIRSPEED_MODES)
        if "airspeed" in grid:
            raise ValueError("give --airspeed or --vary airspeed=..., not both")
        grid["airspeed"] = [airspeed]
    if align is not None:  # one alignment for every run: a one-value grid axis
        _choice("alignment", align, ALIGN_MODES)
        if "align" in grid:
            raise ValueError("give --align or --vary align=..., not both")
        grid["align"] = [align]
    seed_list = list(range(seed_base, seed_base + seeds))
    bar = Progress(TextColumn("[bold]campaign"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("runs"), TimeElapsedColumn(), TimeRemainingColumn(),
                   console=err_console, transient=False)
    task_id = None

    def progress(done: int, total: int, _rid: str) -> None:
        nonlocal task_id
        if task_id is None:
            task_id = bar.add_task("runs", total=total)
        bar.update(task_id, completed=done)

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


def main(argv: list[str] | None = None) -> None:
    """The ``hilnav`` console entry: run the command (typer exits with its code), then, for an
    offline command with every file closed, skip the interpreter's final teardown collections
    (:mod:`scenarios.cli.quick_exit`)."""
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        app(args)
    finally:
        if command_of(args) in QUICK_EXIT_COMMANDS:
            freeze_for_exit()


if __name__ == "__main__":
    main()
