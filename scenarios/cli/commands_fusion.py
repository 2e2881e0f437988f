"""``hilnav fusion``: the live fusion service (MAVLink sensors in; shadow vehicle, companion
and Zenoh out; the live scorecard at exit, :mod:`scenarios.cli.live`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from fusion.choices import DEFAULT_AIRSPEED_MODE, DEFAULT_ALIGN_MODE, DEFAULT_THERMAL_MODE
from scenarios.cli.errors import cli_errors, out_dir
from scenarios.cli.options import (
    AirspeedOption,
    AlignOption,
    AltitudeOption,
    BridgeOption,
    GnssOption,
    ImuOption,
    SettleOption,
    SigningKeyFileOption,
    ThermalCalOption,
    ThermalOption,
    ThermalPartOption,
    ZenohLowLatencyOption,
    ZenohSecurity,
    zenoh_security_options,
)
from scenarios.cli.output import console, err_console, print_live, print_summary, warn_input

__all__ = ["fusion"]


@cli_errors
@zenoh_security_options
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
    thermal: ThermalOption = DEFAULT_THERMAL_MODE,
    thermal_cal: ThermalCalOption = None,
    thermal_part: ThermalPartOption = "bmi088",
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
    signing_key_file: SigningKeyFileOption = None,
    *,
    zenoh_security: ZenohSecurity,
) -> None:
    """Live fusion service: MAVLink sensors in; shadow vehicle, companion and Zenoh out."""
    if out is not None:
        out_dir(out)
    if gcs_tlog is not None and gcs is None:
        raise ValueError("--gcs-tlog needs --gcs")
    from hil.pipeline import build_filter, filter_config
    from hil.service import FusionOptions, parse_source
    from scenarios.cli.live import serve_fusion
    from sim.presets import gnss_preset

    access = zenoh_security.access(zenoh or zenoh_listen)
    if zenoh is not None or zenoh_listen is not None:
        from hil.bus import validate_endpoint, validate_vehicle

        for endpoint in (zenoh, zenoh_listen):
            if endpoint is not None:
                validate_endpoint(endpoint)
        validate_vehicle(vehicle)
    if zenoh_listen is not None:
        from hil.bus.security import check_peer_link

        check_peer_link([zenoh_listen], access.security)
    from hil.thermal_cal import command_thermal_tuning

    therm = command_thermal_tuning(thermal, thermal_cal, thermal_part)
    options = FusionOptions(
        mavlink=mavlink, source=source, zenoh=zenoh, zenoh_listen=zenoh_listen,
        zenoh_low_latency=zenoh_low_latency, vehicle=vehicle, imu=imu, gnss=gnss,
        bridge=bridge,
        altitude=altitude, airspeed=airspeed, align=align, gcs=gcs, gcs_tlog=gcs_tlog,
        shadow_system_id=shadow_sysid, companion=companion,
        companion_kind=companion_kind,  # type: ignore[arg-type]  # pydantic checks the literal
        companion_system_id=companion_sysid, duration_s=duration, idle_exit_s=idle_exit, out=out,
        settle_s=settle, thermal=therm,
    )
    # a bad preset, method or source -> exit 2 before any socket opens
    if source is not None:
        parse_source(source)
    build_filter(filter_config(imu, gnss_preset(gnss), altitude, airspeed, align, therm), bridge)
    from hil.signing import load_key

    key = load_key(signing_key_file)

    def ready(service: Any) -> None:
        where = ", ".join(f"{n}={link.url}" for n, link in service._links.items())
        err_console.print(f"fusion: listening ({where})", highlight=False)

    summary = serve_fusion(options, signing_key=key, bus_access=access, on_ready=ready)
    if summary is not None:
        print_summary(summary)
        warn_input(summary)
        print_live(summary)
        if out is not None:
            console.print(f"summary -> {out / 'summary.json'}")
