"""The commands of a live deployment: ``up`` (the whole chain on this machine), ``monitor``,
``router`` and ``check`` (the health check of containers)."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Annotated, Any, Literal

import typer

from fusion.choices import DEFAULT_AIRSPEED_MODE, DEFAULT_ALIGN_MODE, DEFAULT_THERMAL_MODE
from scenarios.cli.autopilot_hints import AutopilotBinaryOption
from scenarios.cli.errors import RunFailed, cli_errors, out_dir, out_file
from scenarios.cli.options import (
    AirspeedOption,
    AlignOption,
    AltitudeOption,
    BridgeOption,
    FoxgloveOption,
    ImuThermalOption,
    QuietOption,
    ThermalCalOption,
    ThermalOption,
    ThermalPartOption,
    ZenohKeyFileOption,
    ZenohLowLatencyOption,
    ZenohSecurity,
    zenoh_security_options,
)
from scenarios.cli.output import (
    console,
    err_console,
    print_autopilot,
    print_live,
    print_summary,
    progress_bar,
    say_warning,
    scripted_events,
)

__all__ = ["check", "monitor", "router", "up"]


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
    imu_thermal: ImuThermalOption = "off",
    thermal: ThermalOption = DEFAULT_THERMAL_MODE,
    thermal_cal: ThermalCalOption = None,
    thermal_part: ThermalPartOption = "bmi088",
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
    actuator_map: Annotated[Path | None, typer.Option(
        help="With --px4: actuator map YAML (default: the legacy HIL order 0 roll, 1 pitch, "
             "2 yaw, 3 throttle).", rich_help_panel="Autopilot in the loop")] = None,
    servo_map: Annotated[Path | None, typer.Option(
        help="With --ardupilot: servo map YAML (default ArduPlane: 1 aileron, 2 elevator, "
             "3 throttle, 4 rudder).", rich_help_panel="Autopilot in the loop")] = None,
    ardupilot_mavlink: Annotated[str | None, typer.Option(
        help="With --ardupilot: its MAVLink port (e.g. tcp:127.0.0.1:5762; 5760 is "
             "sim_vehicle's MAVProxy) for the SIM_GPS1_* parameters of the GNSS denial; "
             "without it ArduPilot's own GNSS is not denied.",
        rich_help_panel="Autopilot in the loop")] = None,
    connect_timeout: Annotated[float, typer.Option(
        help="Wait this long for the autopilot, s.",
        rich_help_panel="Autopilot in the loop")] = 300.0,
    stall_timeout: Annotated[float, typer.Option(
        help="End the run as stalled after this long without controls, s.",
        rich_help_panel="Autopilot in the loop")] = 10.0,
    autopilot_binary: AutopilotBinaryOption = None,
    quiet: QuietOption = False,
) -> None:
    """Run router + fusion + sim (+ monitor) on loopback; Ctrl-C stops everything. With --px4
    or --ardupilot the autopilot flies and both estimates are scored side by side."""
    out_dir(out)
    from hil.pipeline import SimSetup
    from scenarios.cli.children import sigterm_interrupts
    from scenarios.cli.up import UpOptions, run_up
    from scenarios.cli.up_options import DEFAULT_DURATION_S

    if px4 and ardupilot:
        raise ValueError("give --px4 or --ardupilot, not both")
    kind: Literal["none", "px4", "ardupilot"] = "px4" if px4 else \
        "ardupilot" if ardupilot else "none"
    if autopilot_link is not None and kind == "none":
        raise ValueError("--autopilot-link needs --px4 or --ardupilot")
    options = UpOptions(duration_s=duration, speed=speed, out=out, vehicle=vehicle, plan=plan,
                        seed=seed, gnss_off=tuple(gnss_off or ()), imu=imu, gnss=gnss,
                        bridge=bridge, altitude=altitude, airspeed=airspeed, align=align,
                        imu_thermal=imu_thermal, thermal=thermal, thermal_cal=thermal_cal,
                        thermal_part=thermal_part, gcs=gcs,
                        monitor=monitor,
                        lockstep=lockstep, foxglove_port=foxglove, zenoh_host=zenoh_host,
                        users_file=users_file, insecure=insecure, zenoh_key_file=zenoh_key_file,
                        autopilot=kind,
                        autopilot_link=autopilot_link,
                        autopilot_telemetry=None if autopilot_telemetry == "none"
                        else autopilot_telemetry,
                        actuator_map=actuator_map, servo_map=servo_map,
                        ardupilot_mavlink=ardupilot_mavlink,
                        connect_timeout_s=connect_timeout, stall_timeout_s=stall_timeout,
                        autopilot_binary=autopilot_binary)
    setup = SimSetup.build(plan=plan, seed=seed, gnss_off=list(gnss_off or ()), imu=imu,
                           gnss=gnss, imu_thermal=imu_thermal,
                           duration_s=duration or DEFAULT_DURATION_S)
    def log(text: str) -> None:
        console.print(text, highlight=False)

    launch: contextlib.AbstractContextManager[tuple[UpOptions, Any]] = \
        contextlib.nullcontext((options, None))
    if autopilot_binary is not None:  # the autopilot's libraries: only then
        from scenarios.cli.up_autopilot import record_process, started_autopilot

        launch = started_autopilot(options, log)
    with sigterm_interrupts(), launch as (options, process), progress_bar(
            setup.duration_s, "flying", quiet=quiet, events=scripted_events(setup)) as progress:
        summary = run_up(options, log=log, progress=progress, warn=say_warning)
    if process is not None and summary is not None:
        record_process(summary, process, out / "summary.json")
    if summary is not None:
        console.print("[bold]scorecard of the live run[/]")
        print_summary(summary)
        print_autopilot(summary)
        print_live(summary)
    elif duration is not None or kind != "none":
        raise RunFailed("the live run produced no scorecard (see the fusion output above)")
    failures = list((summary or {}).get("failures") or [])
    for failure in failures:
        err_console.print(f"[red]failure:[/] {failure}", highlight=False)
    if summary is not None and (summary.get("autopilot") or {}).get("stalled"):
        raise RunFailed(summary["autopilot"]["stalled"])
    if summary is not None and summary.get("autopilot") and \
            not summary["autopilot"].get("connected"):
        raise RunFailed(f"{summary['autopilot']['source']} did not connect within "
                        f"{connect_timeout:g} s")
    if failures:
        raise RunFailed("; ".join(failures))


@cli_errors
@zenoh_security_options
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
    *,
    zenoh_security: ZenohSecurity,
) -> None:
    """Show (and optionally record) what the fusion service publishes."""
    if record is not None:
        out_file(record, "--record")
    from hil.bus import validate_endpoint
    from hil.monitor import monitor_main

    validate_endpoint(connect)
    access = zenoh_security.access(connect)
    if peer:
        from hil.bus.security import check_peer_link

        check_peer_link([connect], access.security)
    code = monitor_main(connect=connect, vehicle=vehicle, record=record, duration_s=duration,
                        headless=headless, foxglove_port=foxglove, bus_access=access,
                        peer=peer, low_latency=zenoh_low_latency)
    if code:
        raise typer.Exit(code)


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


@cli_errors
@zenoh_security_options
def check(
    connect: Annotated[str, typer.Option(help="Zenoh router endpoint.")] = "tcp/127.0.0.1:7447",
    vehicle: Annotated[str, typer.Option(help="Vehicle whose fusion/alive token --alive asks for.")
                       ] = "sim1",
    alive: Annotated[bool, typer.Option(help="Require the fusion service's liveliness token.")
                     ] = False,
    key: Annotated[list[str] | None, typer.Option(
        "--key", help="A sample must arrive on this key expression (repeatable).")] = None,
    timeout: Annotated[float, typer.Option(help="Overall time budget, s.")] = 5.0,
    *,
    zenoh_security: ZenohSecurity,
) -> None:
    """Health check of a running deployment (container health checks): exit 0 healthy, 1 not.

    With the shared key (HILNAV_ZENOH_KEY / --zenoh-key-file), --alive also challenges the
    fusion (a token declared by anyone else fails) and only tagged samples count for --key.
    """
    from hil.bus import check_bus

    access = zenoh_security.access(connect)
    code = check_bus(connect, vehicle, alive=alive, keys=tuple(key or ()), timeout_s=timeout,
                     report=lambda line: err_console.print(line, highlight=False),
                     security=access.security, auth_key=access.auth_key)
    if code:
        raise typer.Exit(code)
