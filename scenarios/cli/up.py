"""``hilnav up``: the whole live chain on this machine, without Docker (composition root).

An in-process Zenoh router (:mod:`hil.router`) plus three child processes on loopback with
free ports: ``hilnav fusion`` (MAVLink in on ``udpin:127.0.0.1:<free>``, writes the live
scorecard ``summary.json`` at exit), ``hilnav sim --live`` (waits for the fusion's heartbeat,
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

import atexit
import contextlib
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from fusion.choices import DEFAULT_AIRSPEED_MODE, DEFAULT_ALIGN_MODE
from hil.bus import validate_vehicle
from hil.bus.security import RouterSecurity, endpoint_host
from hil.codec import SIM_SYSTEM_ID
from hil.pipeline import SimSetup, build_filter, filter_config
from hil.router import zenoh_router
from sim.presets import gnss_preset

__all__ = ["Child", "UpOptions", "free_udp_port", "run_up", "stop_process"]

_STOP_TIMEOUT_S = 5.0
_FUSION_IDLE_EXIT_S = 3.0
_DEFAULT_DURATION_S = 3600.0


class UpOptions(BaseModel):
    """Options of :func:`run_up`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    duration_s: float | None = Field(default=None, gt=0.0)
    speed: float = Field(default=1.0, gt=0.0, le=1000.0)
    out: Path = Path("out/up")
    vehicle: str = "sim1"
    plan: str = "racetrack"
    seed: int = Field(default=1, ge=0)
    imu: str = "industrial-mems"
    """IMU preset: the simulated sensor and the filter's tuning."""
    gnss: str = "modern"
    """GNSS receiver preset: the simulated receiver and the filter's model of it."""
    bridge: str = "none"
    """The fusion's GNSS-outage bridging method."""
    altitude: str = "ekf"
    """The fusion's altitude method."""
    airspeed: str = DEFAULT_AIRSPEED_MODE
    """The fusion's air-data choice (on, off, synthetic)."""
    align: str = DEFAULT_ALIGN_MODE
    """The fusion's alignment (auto, static, in-flight)."""
    gnss_off: tuple[str, ...] = ()
    gcs: str | None = None
    monitor: bool = True
    lockstep: bool = False
    """Run the sim with ``--lockstep``: it never runs ahead of the fusion (no loss at any
    speed; the run goes as fast as the slower of the two)."""
    foxglove_port: int | None = Field(default=None, ge=0, le=65535)
    """The monitor also serves a Foxglove WebSocket on ``127.0.0.1:<port>`` (needs monitor)."""
    settle_s: float | None = Field(default=None, ge=0.0)
    """Scorecard settling time; None: 60 s, at most a quarter of the duration."""
    zenoh_host: str = "127.0.0.1"
    """Where the in-process router listens (beyond loopback only with ``users_file`` or
    ``insecure``)."""
    users_file: Path | None = None
    """usrpwd dictionary (``user:password`` lines) of outside clients, admitted read-only;
    turns on authentication and access control for the children too."""
    insecure: bool = False
    """Allow ``zenoh_host`` beyond loopback without authentication."""
    zenoh_key_file: Path | None = None
    """Shared payload key for every child (default: ``HILNAV_ZENOH_KEY``, inherited)."""
    autopilot: Literal["none", "px4", "ardupilot"] = "none"
    """An autopilot flies instead of hilnav's guidance (:mod:`scenarios.cli.up_autopilot`)."""
    autopilot_link: str | None = None
    """Where the simulator meets it (None: the backend's default)."""
    autopilot_telemetry: str | None = "udpin:127.0.0.1:14550"
    """Where it reports its estimate (None: not recorded)."""
    connect_timeout_s: float = Field(default=300.0, gt=0.0)
    stall_timeout_s: float = Field(default=10.0, gt=0.0)


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


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


def hilnav_argv(*args: str) -> list[str]:
    """Command line running ``hilnav ARGS`` with this interpreter."""
    return [sys.executable, "-m", "scenarios.cli", *args]


def stop_process(proc: subprocess.Popen[Any], timeout_s: float = _STOP_TIMEOUT_S) -> int | None:
    """Stop one child by PID: SIGTERM, wait, SIGKILL; returns its exit code."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            proc.wait(timeout_s)
    return proc.returncode


class Child:
    """A child process with its output in a log file."""

    def __init__(self, name: str, argv: list[str], log_path: Path) -> None:
        self.name = name
        self.log_path = log_path
        self._log: IO[bytes] = log_path.open("wb")
        self.proc: subprocess.Popen[bytes] = subprocess.Popen(
            argv, stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            start_new_session=True,  # Ctrl-C in the terminal reaches `up` only; up stops us
        )

    @property
    def pid(self) -> int:
        return self.proc.pid

    def stop(self) -> int | None:
        code = stop_process(self.proc)
        self._log.close()
        return code


@contextlib.contextmanager
def _children() -> Iterator[list[Child]]:
    children: list[Child] = []

    def stop_all() -> None:
        for child in reversed(children):
            child.stop()

    atexit.register(stop_all)
    previous = signal.getsignal(signal.SIGTERM)

    def on_term(_sig: int, _frame: Any) -> None:
        raise KeyboardInterrupt

    in_main = _is_main_thread()
    if in_main:
        signal.signal(signal.SIGTERM, on_term)
    try:
        yield children
    finally:
        stop_all()
        atexit.unregister(stop_all)
        if in_main:
            signal.signal(signal.SIGTERM, previous)


def _is_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def run_up(options: UpOptions, *, log: Callable[[str], None] = print,
           backend: Any = None) -> dict[str, Any] | None:
    """Run router, fusion, sim and monitor until the sim is done (or Ctrl-C). With
    ``options.autopilot`` the simulator side runs in this process with the autopilot at the
    controls (:func:`scenarios.cli.up_autopilot.fly_autopilot`; ``backend``: a backend already
    built, for tests).

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
                   imu=options.imu, gnss=options.gnss,
                   duration_s=options.duration_s or _DEFAULT_DURATION_S)
    build_filter(filter_config(options.imu, gnss_preset(options.gnss), options.altitude,
                               options.airspeed, options.align), options.bridge)
    if options.autopilot != "none" and options.lockstep:
        raise ValueError("--lockstep paces the simulator against the fusion; with --px4 / "
                         "--ardupilot the autopilot sets the pace (lockstep with it)")
    if options.autopilot != "none" and backend is None:
        from scenarios.cli.up_autopilot import up_backend

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
        children = stack.enter_context(_children())
        if backend is not None:
            from scenarios.cli.up_autopilot import fly_autopilot

            endpoint = _start_fusion_and_monitor(options, listen, security, zenoh_args, port,
                                                 children, log, idle_exit=True)
            return fly_autopilot(options, endpoint, port, children, log, summary_path,
                                 backend=backend)
        return _run_children(options, listen, security, zenoh_args, port, children, log,
                             summary_path)


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
                   "--vehicle", options.vehicle, "--out", str(out), "--imu", options.imu,
                   "--gnss", options.gnss, "--bridge", options.bridge,
                   "--altitude", options.altitude, "--airspeed", options.airspeed,
                   "--align", options.align]
    fusion_args += ["--settle", str(settle_s(options))]
    if idle_exit:
        fusion_args += ["--idle-exit", str(_FUSION_IDLE_EXIT_S)]
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


def settle_s(options: UpOptions) -> float:
    """The scorecard's settling time: ``settle_s``, else 60 s, at most a quarter of the
    duration."""
    if options.settle_s is not None:
        return options.settle_s
    return min(60.0, 0.25 * (options.duration_s or _DEFAULT_DURATION_S))


def _run_children(options: UpOptions, listen: str, security: RouterSecurity,
                  zenoh_args: dict[str, list[str]], port: int, children: list[Child],
                  log: Callable[[str], None], summary_path: Path) -> dict[str, Any] | None:
    out = options.out
    endpoint = _start_fusion_and_monitor(options, listen, security, zenoh_args, port, children,
                                         log, idle_exit=options.duration_s is not None)
    fusion = children[0]
    sim_args = ["sim", "--live", f"udpout:127.0.0.1:{port}", "--speed", str(options.speed),
                "--zenoh", endpoint, *zenoh_args["sim"], "--vehicle", options.vehicle,
                "--plan", options.plan,
                "--seed", str(options.seed), "--imu", options.imu, "--gnss", options.gnss,
                "--duration", str(options.duration_s or _DEFAULT_DURATION_S),
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
        sim_code = sim.proc.wait()
        log(f"sim finished (exit {sim_code})")
        try:
            fusion.proc.wait(timeout=_FUSION_IDLE_EXIT_S + 30.0)
        except subprocess.TimeoutExpired:
            log("fusion did not stop by itself; stopping it")
    except KeyboardInterrupt:
        log("stopping ...")
    for child in reversed(children):
        code = child.stop()
        log(f"{child.name:<13} pid {child.pid} stopped (exit {code})")
    if summary_path.is_file():
        loaded: dict[str, Any] = json.loads(summary_path.read_text())
        log(f"summary -> {summary_path}")
        return loaded
    return None


def wait_gone(pids: list[int], timeout_s: float = 5.0) -> bool:
    """Whether every PID is gone (or a zombie) within ``timeout_s`` (for tests)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.05)
    return not any(_alive(p) for p in pids)


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/stat").read_text().split()[2]
    except (FileNotFoundError, IndexError, ProcessLookupError):
        return False
    return status != "Z"
