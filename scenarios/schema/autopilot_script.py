"""The ``autopilot`` section's script (parameter file, mission, arm, mode) as the commander's
:class:`hil.autopilot.commander.Script`.

Mission positions are turned into absolute ones here, once: ``north_m`` / ``east_m`` from the
scenario's start (on the WGS-84 ellipsoid's local radii at the start), ``alt_m`` above the
start's altitude -> an altitude above mean sea level. A takeoff without a position is placed
:data:`TAKEOFF_AHEAD_M` ahead of the start on the start's heading: PX4's fixed-wing runway
take-off rolls and climbs out along the bearing from where it starts the roll to the takeoff
item (a takeoff item at the start itself gives that bearing from a metre of position noise:
any direction), and refuses a mission whose first item is farther than ``MIS_DIST_1WP``
(900 m by default); ArduPlane takes off on the heading it faces whatever the item's
position. A loiter without a position circles the previous item's position (the start for the
first), at the previous item's altitude when it has no ``alt_m``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Final

from fusion.earth import principal_radii
from hil.autopilot.aiding import aiding_off_params, aiding_params
from hil.autopilot.commander import Script, StepTimeouts
from hil.autopilot.mission import (
    MissionItem,
    loiter,
    return_to_launch,
    takeoff,
    waypoint,
)
from hil.autopilot.param_file import read_param_file
from scenarios.schema.sections import AutopilotSection, MissionItemSection

__all__ = ["TAKEOFF_AHEAD_M", "build_script", "mission_items"]

TAKEOFF_AHEAD_M: Final = 500.0
"""How far ahead of the start, on its heading, a takeoff item without a position is put (m):
far enough that the start's position noise turns the bearing by ~0.1 deg, within PX4's
``MIS_DIST_1WP`` (900 m)."""


def build_script(section: AutopilotSection, start: tuple[float, float, float],
                 params_path: Path | None, *, heading_deg: float = 0.0) -> Script:
    """The script of ``section`` for a flight starting at ``start`` (lat deg, lon deg, alt
    MSL m) facing ``heading_deg`` (true, deg); ``params_path`` is ``section.params`` resolved
    against the scenario's folder.

    Raises
    ------
    hil.autopilot.param_file.ParamFileError
        The parameter file cannot be read (one line, ``FILE:LINE: reason``).
    """
    params = tuple(read_param_file(params_path)) if params_path is not None else ()
    aiding = section.aiding == "hilnav" and section.kind in ("ardupilot", "px4")
    aiding_off = section.aiding == "disabled" and section.kind in ("ardupilot", "px4")
    if aiding:
        given = {p.name for p in params}
        params += tuple(p for p in aiding_params(section.kind) if p.name not in given)
    elif aiding_off:  # unaided whatever the file says: its line for the name gives way
        off = aiding_off_params(section.kind)
        names = {p.name for p in off}
        params = tuple(p for p in params if p.name not in names) + off
    t = section.timeouts
    return Script(
        params=params,
        params_file=str(params_path) if params_path is not None else None,
        mission=tuple(mission_items(section.mission or [], start, heading_deg=heading_deg)),
        arm=section.arm,
        mode=None if section.mode is None else section.mode.upper(),
        timeouts=StepTimeouts(heartbeat_s=t.heartbeat_s, params_s=t.params_s,
                              mission_s=t.mission_s, arm_s=t.arm_s, mode_s=t.mode_s),
        aiding=aiding,
        aiding_off=aiding_off,
    )


def mission_items(items: list[MissionItemSection], start: tuple[float, float, float], *,
                  heading_deg: float = 0.0) -> list[MissionItem]:
    """The mission items of the section at absolute positions for a start at ``start`` (lat
    deg, lon deg, alt MSL m) facing ``heading_deg`` (see the module docstring)."""
    lat0, lon0, alt0 = start
    r_n, r_e = (float(r) for r in principal_radii(math.radians(lat0)))

    def at(north_m: float, east_m: float) -> tuple[float, float]:
        return (lat0 + math.degrees(north_m / (r_n + alt0)),
                lon0 + math.degrees(east_m / ((r_e + alt0) * math.cos(math.radians(lat0)))))

    out: list[MissionItem] = []
    here = (lat0, lon0, alt0)
    counts: dict[str, int] = {}
    for item in items:
        counts[item.type] = counts.get(item.type, 0) + 1
        label = f"{item.type} {counts[item.type]}"
        if item.type == "rtl":
            out.append(return_to_launch(label=label))
            continue
        if item.lat_deg is not None and item.lon_deg is not None:
            lat, lon = item.lat_deg, item.lon_deg
        elif item.north_m is not None and item.east_m is not None:
            lat, lon = at(item.north_m, item.east_m)
        elif item.type == "takeoff":
            heading_rad = math.radians(heading_deg)
            lat, lon = at(TAKEOFF_AHEAD_M * math.cos(heading_rad),
                          TAKEOFF_AHEAD_M * math.sin(heading_rad))
        else:
            lat, lon = here[0], here[1]
        alt = alt0 + item.alt_m if item.alt_m is not None else here[2]
        if item.type == "takeoff":
            out.append(takeoff(lat, lon, alt, pitch_deg=item.pitch_deg, label=label))
        elif item.type == "waypoint":
            out.append(waypoint(lat, lon, alt, label=label))
        else:
            assert item.radius_m is not None
            out.append(loiter(lat, lon, alt, radius_m=item.radius_m, turns=item.turns,
                              time_s=item.time_s, label=label))
        here = (lat, lon, alt)
    return out
