"""``hilnav up --px4 / --ardupilot``: the live chain with an autopilot at the controls
(composition root).

``up`` starts the Zenoh router, the fusion service and the monitor as for any live run
(:mod:`scenarios.cli.up`); the simulator side runs here, in ``up``'s own process:
:func:`hil.autopilot.fly_with_autopilot` with the autopilot's backend (lockstep for SITL, paced
at ``--speed`` for a HITL board on a serial link), every frame sent to the fusion service over
loopback UDP and recorded in ``run.tlog``, the autopilot's own estimate recorded from its
telemetry (:class:`hil.autopilot.telemetry.AutopilotTelemetry`). When the flight ends (its
duration, a stall, Ctrl-C) the fusion service writes its live scorecard and ``up`` adds the
``autopilot`` section, scored against the same truth and outages
(:func:`scenarios.autopilot_summary.autopilot_section`), and prints both side by side.
"""

from __future__ import annotations

import json
import subprocess
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.autopilot import (
    AutopilotBackend,
    AutopilotFlown,
    BackendSettings,
    close_backend,
    fly_with_autopilot,
    make_backend,
)
from hil.autopilot.telemetry import AutopilotTelemetry
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimSetup, SimStep
from hil.tlog import TlogWriter
from hil.tracks import truth_track
from scenarios.autopilot_summary import score_flown
from scenarios.cli.children import Child
from scenarios.cli.up_options import DEFAULT_DURATION_S, FUSION_IDLE_EXIT_S, UpOptions, settle_s
from scenarios.jsonable import write_json
from scenarios.metrics import Window
from sim.samples import Truth

__all__ = ["AUTOPILOT_SIDE_COMMANDS", "fly_autopilot", "up_backend"]

#: What the user runs on the autopilot's side (printed by ``up``; details in docs/autopilots.md).
AUTOPILOT_SIDE_COMMANDS = {
    "px4": "PX4 SITL (lockstep): in PX4-Autopilot, `make px4_sitl none_<airframe>` (it connects "
           "to TCP 4560 on PX4_SIM_HOSTNAME, default this machine); its estimate comes back on "
           "its ground-station link, UDP 14550",
    "ardupilot": "ArduPilot SITL: `sim_vehicle.py -v ArduPlane --model JSON:127.0.0.1 --out "
                 "udp:127.0.0.1:14550` (JSON servo packets to UDP 9002; its estimate to UDP "
                 "14550)",
}
_TRUTH_PERIOD_US = 20_000  # the truth kept for scoring the autopilot: 50 Hz


def _setup(options: UpOptions) -> SimSetup:
    return SimSetup.build(plan=options.plan, seed=options.seed, gnss_off=list(options.gnss_off),
                          imu=options.imu, gnss=options.gnss,
                          duration_s=options.duration_s or DEFAULT_DURATION_S)


def up_backend(options: UpOptions) -> AutopilotBackend:
    """The autopilot's backend for ``up`` (ValueError: a bad link, a missing backend)."""
    return make_backend(options.autopilot,
                        BackendSettings(link=options.autopilot_link, setup=_setup(options)))


def _paced(options: UpOptions) -> float | None:
    """Lockstep for SITL; a board on a serial link (HITL) runs on its own clock: paced."""
    link = options.autopilot_link or ""
    return options.speed if link.startswith("serial:") else None


def fly_autopilot(options: UpOptions, endpoint: str, port: int, children: list[Child],
                  log: Callable[[str], None], summary_path: Path, *,
                  backend: AutopilotBackend) -> dict[str, Any] | None:
    """Fly with the autopilot, feed the fusion service (``children[0]``), then write and return
    the live scorecard with its ``autopilot`` section (None: the fusion wrote none)."""
    fusion = children[0]
    out = options.out
    setup = _setup(options)
    telemetry = (AutopilotTelemetry(options.autopilot_telemetry)
                 if options.autopilot_telemetry is not None else None)
    truths: list[Truth] = []
    stop = threading.Event()
    flown: AutopilotFlown | None = None
    with MavlinkLink(f"udpout:127.0.0.1:{port}", LinkRole.simulator()) as link, \
            TlogWriter(out / "run.tlog") as tlog:

        def on_frame(time_us: int, frame: bytes) -> None:
            link.send(frame)
            tlog.write(frame, time_us)

        def on_step(step: SimStep) -> None:
            if not truths or step.truth.time_us - truths[-1].time_us >= _TRUTH_PERIOD_US:
                truths.append(step.truth)
                link.tick()  # heartbeats to the fusion service

        _wait_for_fusion(link, 30.0)
        name = options.autopilot if options.autopilot != "none" else backend.name
        where = options.autopilot_link or getattr(backend, "url", "its default link")
        log(f"simulator     in this process: waiting up to {options.connect_timeout_s:g} s "
            f"for {backend.name} on {where}"
            + (f"; its estimate from {options.autopilot_telemetry}"
               if telemetry is not None else "") + f"; recording {out / 'run.tlog'}")
        if name in AUTOPILOT_SIDE_COMMANDS:
            log(f"now start     {AUTOPILOT_SIDE_COMMANDS[name]}")
        log(f"subscribe:    hilnav monitor --connect {endpoint} --vehicle {options.vehicle}")
        if telemetry is not None:
            telemetry.start()
        try:
            flown = fly_with_autopilot(
                setup, backend, on_frame=on_frame, on_step=on_step, speed=_paced(options),
                connect_timeout_s=options.connect_timeout_s,
                stall_timeout_s=options.stall_timeout_s, stop=stop)
        except KeyboardInterrupt:
            log("stopping ...")
        finally:
            if telemetry is not None:
                telemetry.stop()
            close_backend(backend)
    if flown is not None:
        log(_flown_line(flown))
        try:
            fusion.proc.wait(timeout=FUSION_IDLE_EXIT_S + 30.0)
        except subprocess.TimeoutExpired:
            log("fusion did not stop by itself; stopping it")
    for child in reversed(children):
        code = child.stop()
        log(f"{child.name:<13} pid {child.pid} stopped (exit {code})")
    if not summary_path.is_file():
        return None
    summary: dict[str, Any] = json.loads(summary_path.read_text())
    if flown is not None:
        summary["autopilot"] = _section(options, summary, flown, telemetry, truths)
        if flown.stalled is not None or not flown.connected:
            summary["passed"] = False
        write_json(summary, summary_path)
    log(f"summary -> {summary_path}")
    return summary


def _wait_for_fusion(link: MavlinkLink, wait_s: float) -> None:
    """Until the fusion service's heartbeat is heard (its socket is bound), at most ``wait_s``."""
    deadline = threading.Event()
    timer = threading.Timer(wait_s, deadline.set)
    timer.start()
    try:
        while not deadline.is_set() and not link.peer_alive:
            link.recv(0.05)
    finally:
        timer.cancel()


def _flown_line(flown: AutopilotFlown) -> str:
    if not flown.connected:
        return f"{flown.autopilot} did not connect"
    return (f"{flown.autopilot} flew {flown.sim_duration_s:.1f} s in {flown.wall_s:.1f} s "
            f"({flown.realtime_factor:.2f}x real time), {flown.clipped_controls} controls "
            "clipped" + (f"; {flown.stalled}" if flown.stalled else ""))


def _section(options: UpOptions, summary: dict[str, Any], flown: AutopilotFlown,
             telemetry: AutopilotTelemetry | None, truths: list[Truth]) -> dict[str, Any]:
    """The autopilot's estimate scored with the truth flown here and the outages of the live
    scorecard (found by the fusion service from the gaps of the same sensor stream)."""
    outages = [Window(float(o["start_s"]), float(o["end_s"]))
               for o in summary.get("outages") or []]
    link = {"simulator": options.autopilot_link, "telemetry": options.autopilot_telemetry}
    return score_flown(flown, telemetry, truth_track(truths) if len(truths) >= 2 else None,
                       outages, link=link, settle_s=settle_s(options)).section
