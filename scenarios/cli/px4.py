"""``hilnav sim px4 URL``: PX4 flies the simulated aircraft (part of the composition root).

The simulator side of PX4's simulator interface (:class:`hil.autopilot.px4.Px4Backend`) in
the one autopilot loop (:func:`hil.autopilot.fly_with_autopilot`): lockstep over TCP (PX4
SITL connects to ``tcpin:HOST:PORT``), paced at ``speed`` x real time over a serial port
(HITL). Every frame of the flight can be recorded to a ``.tlog`` (the same HIL_SENSOR /
HIL_GPS / truth frames as ``hilnav sim record``, plus the controls the aircraft flew as
HIL_ACTUATOR_CONTROLS from the simulator's autopilot component).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

from hil.autopilot import AutopilotFlown, fly_with_autopilot
from hil.autopilot.actuators import ActuatorMap
from hil.autopilot.px4 import Px4Backend
from hil.link import LinkUrl
from hil.pipeline import ProgressFn, SimSetup
from hil.tlog import TlogWriter
from scenarios.cli.autopilot_hints import px4_command

__all__ = ["fly_px4", "px4_failure", "px4_report"]


def fly_px4(
    setup: SimSetup, url: str, *, actuator_map: Path | None, record: Path | None,
    speed: float, stall_timeout_s: float, connect_timeout_s: float,
    progress: ProgressFn | None = None, stop: threading.Event | None = None,
    on_listening: Callable[[str], None] | None = None,
) -> AutopilotFlown:
    """Wait for PX4 at ``url`` and let it fly ``setup``; ValueError on bad input (URL,
    actuator map, a peer speaking another protocol). ``on_listening(where)`` is told where the
    link waits for PX4 (``tcpin`` port 0 binds a free port)."""
    parsed = LinkUrl.parse(url)
    if parsed.scheme not in ("tcpin", "serial"):
        raise ValueError(
            f"px4 URL {url}: PX4 SITL connects as a TCP client, so listen with "
            "tcpin:HOST:PORT (default tcpin:127.0.0.1:4560); HITL: serial:DEVICE:BAUD")
    amap = ActuatorMap.load(actuator_map) if actuator_map is not None else ActuatorMap.default()
    paced = speed if parsed.scheme == "serial" else None
    if record is not None:
        record.parent.mkdir(parents=True, exist_ok=True)
    with Px4Backend(url, actuator_map=amap) as backend:
        if on_listening is not None:
            where = backend.url
            if parsed.scheme == "tcpin":
                host, port = backend.local_address[:2]
                where = str(LinkUrl("tcpin", host, port))
            on_listening(where)
        if record is None:
            return fly_with_autopilot(
                setup, backend, speed=paced, stall_timeout_s=stall_timeout_s,
                connect_timeout_s=connect_timeout_s, progress=progress, stop=stop)
        with TlogWriter(record) as log:
            return fly_with_autopilot(
                setup, backend, on_frame=lambda t_us, frame: log.write(frame, t_us),
                speed=paced, stall_timeout_s=stall_timeout_s,
                connect_timeout_s=connect_timeout_s, progress=progress, stop=stop)


def px4_report(flown: AutopilotFlown, record: Path | None) -> str:
    """One line: what was flown, how fast, and the protocol's notable counts."""
    c = flown.counters
    return (
        f"PX4 flew {flown.sim_duration_s:.1f} s simulated in {flown.wall_s:.1f} s "
        f"({flown.realtime_factor:.2f}x real time): {flown.steps} steps, "
        f"{c.get('controls', 0)} HIL_ACTUATOR_CONTROLS ({c.get('disarmed_controls', 0)} "
        f"disarmed: trim held), {c.get('boot_steps', 0)} steps while PX4 booted, "
        f"{flown.clipped_controls} controls clipped or ignored, "
        f"{c.get('nonfinite_channels', 0)} non-finite channels, "
        f"{c.get('reconnects', 0)} reconnects"
        + (f" -> {record}" if record is not None else "")
    )


def px4_failure(flown: AutopilotFlown, url: str, connect_timeout_s: float) -> str | None:
    """Why the run failed (exit 1), or None."""
    if not flown.connected and not flown.stopped:
        return (f"PX4 did not connect to {url} within {connect_timeout_s:g} s (start it with "
                f"PX4_SIM_HOSTNAME pointing here: {px4_command()})")
    if flown.stalled is not None:
        return flown.stalled
    if flown.ended is not None:
        return str(flown.ended)
    if flown.problems:
        return "; ".join(flown.problems)
    return None
