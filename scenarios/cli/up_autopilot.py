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

import contextlib
import json
import math
import subprocess
import threading
from collections.abc import Callable, Iterator
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
from hil.autopilot.ardupilot import json_origin
from hil.autopilot.launch import AutopilotProcess, Home, plan_launch
from hil.autopilot.telemetry import AutopilotTelemetry
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimSetup, SimStep
from hil.tlog import TlogWriter
from hil.tracks import truth_track
from scenarios.autopilot_summary import score_flown
from scenarios.cli.autopilot_hints import ARDUPILOT_MAVLINK, ardupilot_command, px4_command
from scenarios.cli.children import Child
from scenarios.cli.up_options import (
    DEFAULT_DURATION_S,
    UpOptions,
    fusion_idle_exit_s,
    settle_s,
)
from scenarios.jsonable import write_json
from scenarios.metrics import Window
from sim.samples import Truth

__all__ = ["autopilot_side_command", "fly_autopilot", "record_process", "started_autopilot",
           "up_backend"]

_TRUTH_PERIOD_US = 20_000  # the truth kept for scoring the autopilot: 50 Hz
_COVERAGE_SLACK_S = 5.0  # the scorecard may start after the flight (the filter's alignment)


def _setup(options: UpOptions) -> SimSetup:
    return SimSetup.build(plan=options.plan, seed=options.seed, gnss_off=list(options.gnss_off),
                          imu=options.imu, gnss=options.gnss, imu_thermal=options.imu_thermal,
                          duration_s=options.duration_s or DEFAULT_DURATION_S)


def up_backend(options: UpOptions) -> AutopilotBackend:
    """The autopilot's backend for ``up`` (ValueError: a bad link or map, a missing
    backend)."""
    return make_backend(options.autopilot, BackendSettings(
        link=options.autopilot_link, setup=_setup(options), actuator_map=options.actuator_map,
        servo_map=options.servo_map, mavlink=options.ardupilot_mavlink))


def autopilot_side_command(options: UpOptions) -> str | None:
    """What the user starts on the autopilot's side (details in docs/autopilots.md); None
    when ``up`` started it."""
    if options.autopilot_binary is not None:
        return None
    if options.autopilot == "px4":
        return f"PX4 SITL (lockstep): {px4_command()}"
    if options.autopilot == "ardupilot":
        return f"ArduPilot SITL: {ardupilot_command(_setup(options).flight.start)}"
    return None


def denial_warning(options: UpOptions) -> str | None:
    """The warning when the scenario denies GNSS but ArduPilot's own GNSS cannot be (its
    simulated GPS is reached only through its MAVLink port)."""
    if options.autopilot == "ardupilot" and options.gnss_off and \
            options.ardupilot_mavlink is None:
        return ("ArduPilot's GNSS is NOT denied: its GPS is its own simulation, switched off "
                "through its MAVLink port; give --ardupilot-mavlink "
                f"{ARDUPILOT_MAVLINK} (only hilnav's fusion loses GNSS now)")
    return None


def _paced(options: UpOptions) -> float | None:
    """Lockstep for SITL; a board on a serial link (HITL) runs on its own clock: paced."""
    link = options.autopilot_link or ""
    return options.speed if link.startswith("serial:") else None


def fly_autopilot(options: UpOptions, endpoint: str, port: int, children: list[Child],
                  log: Callable[[str], None], summary_path: Path, *,
                  backend: AutopilotBackend,
                  progress: Callable[[float, str | None], None] | None = None,
                  warn: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """Fly with the autopilot, feed the fusion service (``children[0]``), then write and return
    the live scorecard with its ``autopilot`` section (None: the fusion wrote none).
    ``progress(simulated_s, None)`` is told how far the flight is; ``warn`` gets the
    warnings (default: ``log``)."""
    warn = warn or log
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
        where = options.autopilot_link or getattr(backend, "url", "its default link")
        log(f"simulator     in this process: waiting up to {options.connect_timeout_s:g} s "
            f"for {backend.name} on {where}"
            + (f"; its estimate from {options.autopilot_telemetry}"
               if telemetry is not None else "") + f"; recording {out / 'run.tlog'}")
        side = autopilot_side_command(options)
        if side is not None:
            log(f"now start     {side}")
            log("              (or give --autopilot-binary PATH: up starts the SITL binary)")
        denial = denial_warning(options)
        if denial is not None:
            warn(denial)
        log(f"subscribe:    hilnav monitor --connect {endpoint} --vehicle {options.vehicle}")
        if telemetry is not None:
            telemetry.start()
        try:
            flown = fly_with_autopilot(
                setup, backend, on_frame=on_frame, on_step=on_step, speed=_paced(options),
                connect_timeout_s=options.connect_timeout_s,
                stall_timeout_s=options.stall_timeout_s, stop=stop,
                progress=None if progress is None else lambda t_s: progress(t_s, None))
        except KeyboardInterrupt:
            log("stopping ...")
        finally:
            if telemetry is not None:
                telemetry.stop()
            close_backend(backend)
    if flown is not None:
        log(_flown_line(flown))
        try:
            fusion.proc.wait(timeout=fusion_idle_exit_s(options) + 30.0)
        except subprocess.TimeoutExpired:
            log("fusion did not stop by itself; stopping it")
    for child in reversed(children):
        code = child.stop()
        log(f"{child.name:<13} pid {child.pid} stopped (exit {code})")
    if not summary_path.is_file():
        return None
    summary: dict[str, Any] = json.loads(summary_path.read_text())
    if flown is not None:
        scored_s = float(summary.get("sim_duration_s") or 0.0)
        if scored_s < flown.sim_duration_s - _COVERAGE_SLACK_S:
            warn(f"the live scorecard covers {scored_s:.1f} s of the {flown.sim_duration_s:.1f} s "
                 f"flown: the fusion service stopped early (see {fusion.log_path})")
        summary["autopilot"] = _section(options, summary, flown, telemetry, truths)
        if flown.problems:
            summary["failures"] = [*summary.get("failures", []), *flown.problems]
        if flown.stalled is not None or not flown.connected or flown.problems:
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


@contextlib.contextmanager
def started_autopilot(options: UpOptions, log: Callable[[str], None]
                      ) -> Iterator[tuple[UpOptions, AutopilotProcess | None]]:
    """With ``options.autopilot_binary``: start it on a free instance (its output in
    ``<out>/autopilot.log``), wait until it is ready and yield the options pointed at its
    ports with the process; it is stopped by PID when the block ends, however it ends.
    Without a binary: the options as they are, and None. ValueError (exit 2): a bad binary,
    ports given by hand as well, or a binary that exits before it is ready."""
    if options.autopilot_binary is None:
        yield options, None
        return
    for given, name in ((options.autopilot_link, "--autopilot-link"),
                        (options.ardupilot_mavlink, "--ardupilot-mavlink")):
        if given is not None:
            raise ValueError(f"{name}: hilnav chooses the ports of the binary it starts; drop "
                             f"{name} or --autopilot-binary")
    setup = _setup(options)
    home = None
    if options.autopilot == "ardupilot":
        origin = json_origin(setup)
        home = Home(math.degrees(origin.lat_rad), math.degrees(origin.lon_rad),
                    origin.alt_msl_m, setup.flight.start.heading_deg)
    plan = plan_launch(options.autopilot, options.autopilot_binary, home=home,
                       telemetry=options.autopilot_telemetry is not None)
    options.out.mkdir(parents=True, exist_ok=True)
    process = AutopilotProcess(plan, options.out / "autopilot.log").start()
    try:
        log(f"autopilot     pid {process.pid}: {plan.binary} (instance {plan.instance}, "
            f"simulator {plan.link}" + (f", MAVLink {plan.mavlink_url}" if plan.mavlink_url
                                        else "") + f"); log {process.log_path}")
        # a binary that exits at once (not an autopilot, a bad option) is seen here
        if not process.wait_ready(options.connect_timeout_s, min_alive_s=1.0):
            raise ValueError(f"{plan.binary} (instance {plan.instance}) did not get ready "
                             f"within {options.connect_timeout_s:g} s; its last output: "
                             f"{process.last_lines()}")
        yield options.model_copy(update={
            "autopilot_link": plan.link, "autopilot_telemetry": plan.telemetry_url,
            "ardupilot_mavlink": plan.mavlink_url}), process
    finally:
        code = process.stop()
        log(f"autopilot     pid {process.pid} stopped ({process.stopped_by}, exit {code})")


def record_process(summary: dict[str, Any], process: AutopilotProcess,
                   summary_path: Path) -> None:
    """Add the started binary (:meth:`AutopilotProcess.record`) to the scorecard's
    ``autopilot`` section and rewrite ``summary_path``."""
    section = summary.get("autopilot")
    if not isinstance(section, dict):
        return
    texts = [str(t.get("text")) for t in (section.get("health") or {}).get("statustext") or []]
    section["process"] = process.record(texts)
    write_json(summary, summary_path)
