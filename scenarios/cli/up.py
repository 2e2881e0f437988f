"""``hilnav up``: the whole live chain on this machine, without Docker (composition root).

An in-process Zenoh router (:mod:`hil.router`) plus three child processes on loopback with
free ports: ``hilnav fusion`` (MAVLink in on ``udpin:127.0.0.1:<free>``, writes the live
scorecard ``summary.json`` at exit), ``hilnav sim live`` (waits for the fusion's heartbeat,
then streams at ``--speed``; also records ``run.tlog``) and, optionally, ``hilnav monitor
--headless`` (records ``live.mcap``). Each child's output goes to ``<out>/<name>.log``.

Children are started in their own sessions and stopped by PID only (terminate, wait, kill):
on a normal end, on Ctrl-C / SIGTERM, and from an ``atexit`` hook, so no orphan survives
``up``. With a duration the run ends by itself: the sim finishes, the fusion exits after its
input went idle and writes the scorecard, the monitor is stopped.

Zenoh security: the router listens on loopback unless ``zenoh_host`` says otherwise, and then
only with ``users_file`` (or ``insecure``). With a users file ``up`` turns on usrpwd and access
control, makes a random password for each of its own children (``fusion``, ``sim``,
``monitor``, in a private temporary folder removed at exit) and admits the file's users as
read-only clients. ``HILNAV_ZENOH_KEY`` (or ``zenoh_key_file``) makes every child tag and check
its samples.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.bus import validate_vehicle
from hil.bus.security import RouterSecurity, endpoint_host
from hil.codec import SIM_SYSTEM_ID
from hil.pipeline import SimSetup, build_filter, filter_config
from hil.router import zenoh_router
from hil.thermal_cal import command_thermal_tuning
from scenarios.cli.children import (
    Child,
    free_udp_port,
    hilnav_argv,
    running_children,
    stop_process,
    wait_gone,
)
from scenarios.cli.output import FLYING
from scenarios.cli.up_options import (
    DEFAULT_DURATION_S,
    UpOptions,
    fusion_idle_exit_s,
    settle_s,
)
from sim.presets import gnss_preset

# the children's helpers are part of up's interface (tests and benches stop processes by PID)
__all__ = ["Child", "Progress", "SimLogRelay", "UpOptions", "filter_args", "free_udp_port",
           "run_up", "stop_process", "wait_gone"]

_CHILD_USERS = ("fusion", "sim", "monitor")


def _bus_security(options: UpOptions, folder: Path) -> tuple[RouterSecurity, dict[str, list[str]]]:
    """The router's security and each child's Zenoh options (login, key file)."""
    key_args = [] if options.zenoh_key_file is None else [
        "--zenoh-key-file", str(options.zenoh_key_file)]
    if options.users_file is None:
        return RouterSecurity(insecure=options.insecure), dict.fromkeys(_CHILD_USERS, key_args)
    try:
        outside = [line.strip() for line in options.users_file.read_text().splitlines()
                   if line.strip()]
    except OSError as exc:
        raise ValueError(f"--users-file {options.users_file}: {exc.strerror}") from None
    for line in outside:
        name = line.split(":", 1)[0]
        if ":" not in line or name in _CHILD_USERS:
            raise ValueError(f"--users-file line {line.split(':', 1)[0]!r}: expected user:password"
                             f" with a user other than {', '.join(_CHILD_USERS)} (up's own)")
    args: dict[str, list[str]] = {}
    lines = []
    for name in _CHILD_USERS:
        password = secrets.token_urlsafe(24)
        pw_file = folder / f"{name}.pw"
        pw_file.write_text(password + "\n")
        lines.append(f"{name}:{password}")
        args[name] = ["--zenoh-user", name, "--zenoh-password-file", str(pw_file), *key_args]
    users = folder / "users.txt"
    users.write_text("\n".join(lines + outside) + "\n")
    security = RouterSecurity(users_file=users, acl=True, fusion=("fusion",), sim=("sim",),
                              insecure=options.insecure)
    return security, args


def run_up(options: UpOptions, *, log: Callable[[str], None] = print,
           backend: Any = None, progress: Progress | None = None,
           warn: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """Run router, fusion, sim and monitor until the sim is done (or Ctrl-C). With
    ``options.autopilot`` the simulator side runs in this process with the autopilot at the
    controls (:func:`scenarios.cli.up_autopilot.fly_autopilot`; ``backend``: a backend already
    built, for tests). ``progress(simulated_s, info)`` is told how far the flight is (``info``:
    the sim child's own real-time factor and scripted event, None when up flies itself);
    ``warn`` gets the warnings (default: ``log``).

    Returns
    -------
    dict or None
        The fusion's live scorecard (``<out>/summary.json``), None if it wrote none.
    """
    validate_vehicle(options.vehicle)
    if options.foxglove_port is not None and not options.monitor:
        raise ValueError("--foxglove needs the monitor (drop --no-monitor)")
    # validate the flight and the filter here: a typo must fail before anything starts
    SimSetup.build(plan=options.plan, seed=options.seed, gnss_off=list(options.gnss_off),
                   imu=options.imu, gnss=options.gnss, imu_thermal=options.imu_thermal,
                   duration_s=options.duration_s or DEFAULT_DURATION_S)
    therm = command_thermal_tuning(options.thermal, options.thermal_cal, options.thermal_part)
    build_filter(filter_config(options.imu, gnss_preset(options.gnss), options.altitude,
                               options.airspeed, options.align, therm), options.bridge)
    if options.autopilot != "none" and options.lockstep:
        raise ValueError("--lockstep paces the simulator against the fusion; with --px4 / "
                         "--ardupilot the autopilot sets the pace (lockstep with it)")
    if options.autopilot != "none" and backend is None:
        from scenarios.cli.up_autopilot import up_backend  # the autopilot's libraries: only then

        backend = up_backend(options)  # a bad link or map fails before anything starts
    out = options.out
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary_path.unlink(missing_ok=True)
    port = free_udp_port()
    with tempfile.TemporaryDirectory(prefix="hilnav-up-") as private, \
            contextlib.ExitStack() as stack:
        os.chmod(private, 0o700)  # the children's passwords live here until up exits
        security, zenoh_args = _bus_security(options, Path(private))
        listen = stack.enter_context(zenoh_router(host=options.zenoh_host, security=security))
        children = stack.enter_context(running_children())
        if backend is not None:
            from scenarios.cli.up_autopilot import fly_autopilot

            endpoint = _start_fusion_and_monitor(options, listen, security, zenoh_args, port,
                                                 children, log, idle_exit=True)
            return fly_autopilot(options, endpoint, port, children, log, summary_path,
                                 backend=backend, progress=progress, warn=warn or log)
        return _run_children(options, listen, security, zenoh_args, port, children, log,
                             summary_path, SimLogRelay(progress, log, warn or log))


def filter_args(options: UpOptions) -> list[str]:
    """The fusion child's filter choices (``hilnav fusion`` options) from ``up``'s."""
    args = ["--imu", options.imu, "--gnss", options.gnss, "--bridge", options.bridge,
            "--altitude", options.altitude, "--airspeed", options.airspeed,
            "--align", options.align, "--thermal", options.thermal,
            "--thermal-part", options.thermal_part]
    if options.thermal_cal is not None:
        # the child's working folder is up's: an absolute path reads the same file either way
        args += ["--thermal-cal", str(options.thermal_cal.resolve())]
    return args


def _start_fusion_and_monitor(options: UpOptions, listen: str, security: RouterSecurity,
                              zenoh_args: dict[str, list[str]], port: int,
                              children: list[Child], log: Callable[[str], None], *,
                              idle_exit: bool) -> str:
    """Start the fusion service (``children[0]``, MAVLink in on ``udpin:127.0.0.1:PORT``) and
    the monitor; returns the Zenoh endpoint the children use."""
    out = options.out
    host = endpoint_host(listen)
    # the children are on this machine: an every-interface router is reached on loopback
    endpoint = listen.replace(f"/{host}:", "/127.0.0.1:") if host in ("0.0.0.0", "::") \
        else listen
    log(f"zenoh router  {listen} (in process"
        + ("; usrpwd + access control" if security.users_file is not None else "") + ")")
    # bound to the simulator's system from the first frame: a sender that speaks first
    # can neither become the fusion's source nor its reply address
    fusion_args = ["fusion", "--mavlink", f"udpin:127.0.0.1:{port}",
                   "--source", str(SIM_SYSTEM_ID), "--zenoh", endpoint,
                   *zenoh_args["fusion"],
                   "--vehicle", options.vehicle, "--out", str(out), *filter_args(options)]
    fusion_args += ["--settle", str(settle_s(options))]
    if idle_exit:
        fusion_args += ["--idle-exit", str(fusion_idle_exit_s(options))]
    if options.gcs is not None:
        fusion_args += ["--gcs", options.gcs, "--gcs-tlog", str(out / "shadow.tlog")]
    fusion = Child("fusion", hilnav_argv(*fusion_args), out / "fusion.log")
    children.append(fusion)
    log(f"fusion        pid {fusion.pid}: MAVLink in udpin:127.0.0.1:{port}"
        + (f", shadow vehicle -> {options.gcs}" if options.gcs else "")
        + f"; log {fusion.log_path}")
    if options.monitor:
        mon_args = ["monitor", "--connect", endpoint, "--vehicle", options.vehicle,
                    "--headless", "--record", str(out / "live.mcap"),
                    *zenoh_args["monitor"]]
        if options.foxglove_port is not None:
            mon_args += ["--foxglove", str(options.foxglove_port)]
        mon = Child("monitor", hilnav_argv(*mon_args), out / "monitor.log")
        children.append(mon)
        log(f"monitor       pid {mon.pid}: recording {out / 'live.mcap'}; log {mon.log_path}")
        if options.foxglove_port is not None:
            log(f"foxglove      open connection -> Foxglove WebSocket "
                f"ws://127.0.0.1:{options.foxglove_port}")
    return endpoint


def _run_children(options: UpOptions, listen: str, security: RouterSecurity,
                  zenoh_args: dict[str, list[str]], port: int, children: list[Child],
                  log: Callable[[str], None], summary_path: Path,
                  relay: SimLogRelay) -> dict[str, Any] | None:
    out = options.out
    endpoint = _start_fusion_and_monitor(options, listen, security, zenoh_args, port, children,
                                         log, idle_exit=options.duration_s is not None)
    fusion = children[0]
    sim_args = ["sim", "live", f"udpout:127.0.0.1:{port}", "--speed", str(options.speed),
                "--zenoh", endpoint, *zenoh_args["sim"], "--vehicle", options.vehicle,
                "--plan", options.plan,
                "--seed", str(options.seed), "--imu", options.imu, "--gnss", options.gnss,
                "--imu-thermal", options.imu_thermal,
                "--duration", str(options.duration_s or DEFAULT_DURATION_S),
                "--record", str(out / "run.tlog"), "--wait-peer", "30"]
    for w in options.gnss_off:
        sim_args += ["--gnss-off", w]
    if options.lockstep:
        sim_args.append("--lockstep")
    sim = Child("sim", hilnav_argv(*sim_args), out / "sim.log")
    children.append(sim)
    log(f"sim           pid {sim.pid}: -> udpout:127.0.0.1:{port} at {options.speed:g}x"
        + (" (lockstep)" if options.lockstep else "") + ", "
        f"recording {out / 'run.tlog'}; log {sim.log_path}")
    log(f"subscribe:    hilnav monitor --connect {endpoint} --vehicle {options.vehicle}"
        + (" --zenoh-user USER (password: HILNAV_ZENOH_PASSWORD)"
           if security.users_file is not None else ""))
    try:
        while True:  # the sim child's progress and result lines, as they come
            try:
                sim_code = sim.proc.wait(timeout=0.5)
                break
            except subprocess.TimeoutExpired:
                relay.poll(sim.log_path)
        relay.poll(sim.log_path)
        log(f"sim finished (exit {sim_code})")
        try:
            fusion.proc.wait(timeout=fusion_idle_exit_s(options) + 30.0)
        except subprocess.TimeoutExpired:
            log("fusion did not stop by itself; stopping it")
    except KeyboardInterrupt:
        log("stopping ...")
    for child in reversed(children):
        code = child.stop()
        log(f"{child.name:<13} pid {child.pid} stopped (exit {code})")
    relay.poll(sim.log_path)
    if summary_path.is_file():
        loaded: dict[str, Any] = json.loads(summary_path.read_text())
        log(f"summary -> {summary_path}")
        return loaded
    return None


Progress = Callable[[float, "str | None"], None]
"""``progress(simulated_s, info)``: how far the flight of ``up`` is."""

# what output.progress_line prints for the sim child's flight (``hilnav sim live``)
_SIM_PROGRESS = re.compile(
    rf"^{FLYING}: ([0-9.]+)/[0-9.]+ s simulated \([0-9]+ %\)(?:, (.*))?$")


class SimLogRelay:
    """Reads the lines the sim child adds to its log: its progress lines (a line every 10 % of
    the flight, as ``hilnav sim live`` prints them when its output is a file) go to
    ``progress``, its warnings to ``warn``, its result line to ``log``."""

    def __init__(self, progress: Progress | None, log: Callable[[str], None],
                 warn: Callable[[str], None]) -> None:
        self.progress = progress
        self.log = log
        self.warn = warn
        self._offset = 0
        self._partial = b""

    def poll(self, path: Path) -> None:
        """Pass on the complete lines written to ``path`` since the last call."""
        try:
            with path.open("rb") as f:
                f.seek(self._offset)
                data = f.read()
        except OSError:
            return
        self._offset += len(data)
        *lines, self._partial = (self._partial + data).split(b"\n")
        for raw in lines:
            self._line(raw.decode("utf-8", "replace").strip())

    def _line(self, line: str) -> None:
        match = _SIM_PROGRESS.match(line)
        if match is not None:
            if self.progress is not None:
                self.progress(float(match.group(1)), match.group(2) or "")
        elif line.startswith("warning: "):
            self.warn(line.removeprefix("warning: "))
        elif line.startswith("sent "):
            self.log(f"sim           {line}")
