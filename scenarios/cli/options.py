"""Options that several ``hilnav`` commands share, each declared once.

Single options are :data:`typing.Annotated` aliases a command names in its signature. A group
of options that always travel together (the Zenoh security of a bus client, the flight and
sensors of the simulator) is an :func:`option_group`: its options are declared once, as the
signature of a template function, and a command takes the whole group as one parameter, a
frozen dataclass built from the values the user gave.

Only the names of the fusion's choices are imported here (no numpy, scipy or pydantic): every
command imports what it runs, so ``--help`` and the light commands stay fast.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from fusion.choices import (
    AIRSPEED_MODES,
    ALIGN_MODES,
    ALTITUDE_METHODS,
    BRIDGE_METHODS,
    THERMAL_MODES,
)

__all__ = [
    "IMU_THERMAL_HELP", "AirspeedOption", "AirspeedOverride", "AlignOption", "AlignOverride",
    "AltitudeOption", "BridgeOption", "FoxgloveOption", "GnssOption", "ImuOption",
    "ImuThermalOption", "QuietOption", "SettleOption",
    "SigningKeyFileOption", "ThermalCalOption", "ThermalOption", "ThermalOverride",
    "ThermalPartOption", "ZenohKeyFileOption",
    "ZenohLowLatencyOption", "ZenohSecurity",
    "option_group", "zenoh_security_options",
]

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
ThermalOption = Annotated[str, typer.Option(
    help=f"IMU thermal strategy: {', '.join(THERMAL_MODES)} (off: the datasheet's bias noise; "
         "blind: bias noise widened for the part's thermal drift; states: temperature-"
         "coefficient states; cal: a calibration file, --thermal-cal).")]
ThermalOverride = Annotated[str | None, typer.Option(
    help=f"Override the scenario's IMU thermal strategy: {', '.join(THERMAL_MODES)} (cal: the "
         "scenario's fusion.thermal_cal file).")]
ThermalPartOption = Annotated[str, typer.Option(
    help="The IMU part whose datasheet temperature coefficients and temperature sensor the "
         "thermal strategies assume (a thermal preset: bmi088, icm42688p, icm20948, "
         "adis1646x).")]
IMU_THERMAL_HELP = ("Thermal preset of the simulated IMU part (its temperature, warming up "
                    "from the start, moves its biases; the stream carries it); off = none.")
"""Help of the simulator's ``--imu-thermal`` (``hilnav sim`` puts it in its flight panel)."""
ImuThermalOption = Annotated[str, typer.Option(help=IMU_THERMAL_HELP)]
ThermalCalOption = Annotated[Path | None, typer.Option(
    help="IMU thermal calibration file (PX4 TC_G0_*/TC_A0_* or ArduPilot INS_TCAL1_* "
         "parameters); implies --thermal cal.")]
SettleOption = Annotated[
    float, typer.Option(help="Scorecard: seconds excluded after the start and each outage "
                             "(shortened, with a warning, when a log is too short for it).")]

QuietOption = Annotated[bool, typer.Option(
    help="No progress (a bar on a terminal, a line every 10 % of the flight otherwise).")]

SigningKeyFileOption = Annotated[Path | None, typer.Option(
    help="MAVLink 2 signing key file (default: env HILNAV_MAVLINK_KEY).")]
ZenohLowLatencyOption = Annotated[bool, typer.Option(
    help="Ask for Zenoh's low-latency transport (no transmit batching; QoS priorities off). A "
         "link uses it only when the other end asks too (fusion and a direct subscriber).")]
ZenohKeyFileOption = Annotated[Path | None, typer.Option(
    help="Shared key (32 bytes, hex or base64) that tags every Zenoh sample and checks "
         "received ones (default: env HILNAV_ZENOH_KEY).", rich_help_panel="Zenoh security")]
FoxgloveOption = Annotated[int | None, typer.Option(
    "--foxglove", metavar="PORT",
    help="Serve a Foxglove WebSocket on 127.0.0.1:PORT (Foxglove's usual port: 8765).")]

F = TypeVar("F", bound=Callable[..., Any])


def option_group(name: str, template: Callable[..., None], build: Callable[..., Any]
                 ) -> Callable[[F], F]:
    """A decorator that gives a command the options declared by ``template``'s signature.

    The decorated command declares one parameter ``name`` instead of the options; the user
    sees the options (same names, help and defaults as in ``template``), and the command is
    called with ``name=build(**their values)``.

    Parameters
    ----------
    name
        The command's parameter that receives the group.
    template
        A function whose (Typer-annotated) parameters are the options of the group.
    build
        Called with the options' values as keywords; its result is what the command gets.
    """
    group = list(inspect.signature(template, eval_str=True).parameters.values())
    group_names = [p.name for p in group]

    def decorate(command: F) -> F:
        own = inspect.signature(command, eval_str=True)
        if name not in own.parameters:
            raise TypeError(f"{command.__name__} has no parameter {name!r} for its options")
        kept = [p for p in own.parameters.values() if p.name != name]
        # keyword-only: Typer calls commands with keywords, and the order of defaults is free
        params = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in (*kept, *group)]

        @functools.wraps(command)
        def with_group(*args: Any, **kwargs: Any) -> Any:
            values = {n: kwargs.pop(n) for n in group_names}
            return command(*args, **{name: build(**values)}, **kwargs)

        signature = own.replace(parameters=params)
        with_group.__signature__ = signature  # type: ignore[attr-defined]
        with_group.__annotations__ = {
            **{p.name: p.annotation for p in params}, "return": own.return_annotation}
        return with_group  # type: ignore[return-value]

    return decorate


# How a bus client (fusion, sim, monitor, check) joins a secured Zenoh router; see
# docs/live.md, "Securing the Zenoh bus". Secrets never go on the command line: files or the
# environment.
def _zenoh_security_template(
    zenoh_user: Annotated[str | None, typer.Option(
        help="Zenoh usrpwd user (password from --zenoh-password-file or env "
             "HILNAV_ZENOH_PASSWORD).", rich_help_panel="Zenoh security")] = None,
    zenoh_password_file: Annotated[Path | None, typer.Option(
        help="File whose first line is the Zenoh usrpwd password.",
        rich_help_panel="Zenoh security")] = None,
    tls_ca: Annotated[Path | None, typer.Option(
        help="CA certificate (PEM) that signed the router's certificate (tls/ endpoints).",
        rich_help_panel="Zenoh security")] = None,
    tls_cert: Annotated[Path | None, typer.Option(
        help="This client's certificate (PEM) for mTLS; its common name is its access-control "
             "name.", rich_help_panel="Zenoh security")] = None,
    tls_key: Annotated[Path | None, typer.Option(
        help="Private key (PEM) of --tls-cert.", rich_help_panel="Zenoh security")] = None,
    zenoh_key_file: ZenohKeyFileOption = None,
) -> None:
    """The Zenoh security options of a bus client (template of :class:`ZenohSecurity`)."""


@dataclasses.dataclass(frozen=True)
class ZenohSecurity:
    """What a bus client was given to join a secured Zenoh router."""

    zenoh_user: str | None = None
    zenoh_password_file: Path | None = None
    tls_ca: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None
    zenoh_key_file: Path | None = None

    def given(self) -> list[str]:
        """The options the user gave, as spelled on the command line."""
        return [f"--{f.name.replace('_', '-')}" for f in dataclasses.fields(self)
                if getattr(self, f.name) is not None]

    def access(self, endpoint: str | None) -> Any:
        """The :class:`hil.bus.security.BusAccess` for ``endpoint`` (None: the command does
        not use Zenoh, and no option of the group may be given; ValueError on bad input)."""
        given = self.given()
        if endpoint is None and given:
            raise ValueError(f"{given[0]} is a Zenoh option: it needs --zenoh ENDPOINT")
        import hil.codec  # noqa: F401  # hil.signing and hil.codec import each other: codec first
        from hil.bus.auth import KEY_ENV
        from hil.bus.security import BusAccess, ClientSecurity
        from hil.signing import load_key

        security = ClientSecurity.from_options(
            user=self.zenoh_user, password_file=self.zenoh_password_file, tls_ca=self.tls_ca,
            tls_cert=self.tls_cert, tls_key=self.tls_key)
        if endpoint is not None:
            security.check_endpoints([endpoint])
        return BusAccess(security=security, auth_key=load_key(self.zenoh_key_file, env=KEY_ENV))


zenoh_security_options = option_group("zenoh_security", _zenoh_security_template, ZenohSecurity)
"""Gives a command the six Zenoh security options as one ``zenoh_security: ZenohSecurity``."""
