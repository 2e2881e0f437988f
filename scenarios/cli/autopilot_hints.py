"""What the user starts on the autopilot's side, printed by ``hilnav up --px4 / --ardupilot``
and ``hilnav sim px4 / ardupilot`` (the same commands as docs/autopilots.md).

PX4 has no make target that starts a plane without a simulator of its own: its SITL binary is
started from the PX4-Autopilot folder after ``make px4_sitl_default`` with the standard plane
airframe (1030), and its simulator MAVLink module dials TCP 4560 where hilnav plays the
simulator. ArduPilot's ``sim_vehicle.py`` takes its home as ``-l LAT,LON,ALT,HDG``: the start of
the flight at ground level (JSBSim's ground is 0 m MSL, the JSON origin hilnav sends).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["ARDUPILOT_MAVLINK", "AutopilotBinaryOption", "ardupilot_command", "px4_command",
           "with_autopilot_binary"]

AutopilotBinaryOption = Annotated[Path | None, typer.Option(
    help="The autopilot's SITL binary (ArduPilot: arduplane; PX4: build/px4_sitl_default/bin/"
         "px4): hilnav starts it on free loopback ports and stops it at the end.",
    rich_help_panel="Autopilot in the loop")]

ARDUPILOT_MAVLINK = "tcp:127.0.0.1:5762"
"""ArduPilot SITL's second MAVLink port (the first, 5760, is taken by sim_vehicle's MAVProxy):
where hilnav sets the ``SIM_*`` parameters of the GNSS denial."""


def px4_command() -> str:
    """PX4 SITL's plane, started to use hilnav as its simulator."""
    return ("in the PX4-Autopilot folder, after `make px4_sitl_default`: "
            "`PX4_SYS_AUTOSTART=1030 PX4_SIM_MODEL=plane ./build/px4_sitl_default/bin/px4 -d` "
            "(it dials TCP 4560 on PX4_SIM_HOSTNAME, default this machine, where hilnav plays "
            "the simulator; its estimate comes back on its ground-station link, UDP 14550)")


def ardupilot_command(start: Any, host: str = "127.0.0.1",
                      given_as: str = "--ardupilot-mavlink") -> str:
    """ArduPlane SITL with its home at ``start`` (a :class:`sim.flight_config.StartState`:
    ``lat_deg``, ``lon_deg``, ``heading_deg``) on the ground, talking to hilnav at ``host``;
    ``given_as``: where the user names ArduPilot's MAVLink port."""
    return (f"`sim_vehicle.py -v ArduPlane --model JSON:{host} "
            f"-l {start.lat_deg:g},{start.lon_deg:g},0,{start.heading_deg:g} "
            "--out udp:127.0.0.1:14550` (servo packets to UDP 9002, its estimate to UDP 14550; "
            f"hilnav sets its SIM_GPS1_* parameters over its MAVLink port {ARDUPILOT_MAVLINK}, "
            f"given as {given_as})")


def with_autopilot_binary(scn: Any, binary: Path) -> Any:
    """The scenario ``scn`` with ``autopilot.binary`` set to ``binary`` (``~`` expanded, made
    absolute from the working folder); ValueError for a scenario no autopilot flies."""
    if scn.autopilot.kind == "none":
        raise ValueError("--autopilot-binary needs a scenario flown by an autopilot "
                         "(autopilot: px4 or ardupilot)")
    path = os.path.abspath(binary.expanduser())
    return scn.model_copy(update={"autopilot": scn.autopilot.model_copy(
        update={"binary": path})})
