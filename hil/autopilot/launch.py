"""hilnav starts the autopilot's own SITL binary: ArduPlane (``arduplane``) or PX4 (``px4``).

Given the path of a SITL binary the user built (hilnav ships none), :class:`LaunchPlan` picks
an instance number whose loopback ports are all free, says where the simulator link, the
telemetry link and (ArduPilot) the MAVLink parameter port of that instance are, and builds the
command line; :class:`AutopilotProcess` runs it in its own session and its own temporary working
folder, its output into a log file, and stops it by PID (SIGTERM to its process group, SIGKILL
after a grace period: the arduplane binary ignores SIGTERM); :func:`launched` is the context
manager that guarantees the stop whatever happens (exception, Ctrl-C, early end).

ArduPlane SITL (``libraries/AP_HAL_SITL/SITL_cmdline.cpp``, ``SITL_State.h``)
    ``arduplane --model JSON:127.0.0.1 --speedup 1 --home LAT,LON,ALT,HDG -I N --serial0 tcp:0
    [--defaults FILE[,FILE]]``. Instance N moves every port by 10 N: SERIAL0 listens on TCP
    5760 + 10 N (by default ``tcp:0:wait``, which blocks the boot until a client connects;
    ``tcp:0`` here, so that it boots at once: the telemetry link connects there), SERIAL1 /
    SERIAL2 on 5762 / 5763 + 10 N (SERIAL1: the MAVLink port of the denial's parameters),
    SERIAL5-8 on 5765-5768 + 10 N, RC input on UDP 5501 + 10 N, IRLock on UDP 9005 + 10 N; N
    is kept in a byte (0-255). SERIAL0 listens before anything else, the other serial ports
    only once its setup runs, which takes physics frames (ArduPlane V4.7.0-dev prints "bind
    port ... for SERIAL0" and then "No JSON sensor message received, resending servos" until
    the simulator answers): it is ready when SERIAL0 listens
    (:meth:`AutopilotProcess.wait_ready`), and the MAVLink link to SERIAL1 connects once the
    flight runs. Its JSON physics backend
    (``libraries/SITL/SIM_JSON.cpp``) binds nothing and sends its servo packets to UDP
    9002 + 10 N, where hilnav listens and answers. It writes ``eeprom.bin`` and its logs in its
    working folder. Without ``--defaults`` it boots with the firmware's own defaults (ArduPlane's
    SERVO1-4 functions are aileron, elevator, throttle, rudder: the default servo map).
PX4 SITL (``platforms/posix/src/px4/common/main.cpp``, ``ROMFS/px4fmu_common/init.d-posix``)
    ``PX4_SYS_AUTOSTART=1030 PX4_SIM_MODEL=gazebo-classic_plane px4 -i N -d
    -s etc/init.d-posix/rcS -w RUNDIR BUILD/etc`` where BUILD is the build folder of the binary
    (``BUILD/bin/px4``): the standard plane airframe, no simulator of its own
    (``px4-rc.simulator``: ``simulator_mavlink`` dials TCP 4560 + N on localhost, where hilnav
    listens), its ground-station MAVLink link on UDP 18570 + N (``px4-rc.mavlink``; it answers
    the first client that speaks: the telemetry link), the offboard, payload and gimbal links
    on UDP 14580 / 14280 / 13030 + N. RUNDIR holds its parameters and logs; ``/tmp/px4_lock-N``
    is its instance lock.

Bad input is :class:`LaunchError` (a ``ValueError``: exit 2): a binary that does not exist, is
not an executable file, or (PX4) has no ``etc`` folder beside its ``bin``; a binary that exits
before it connected is reported by the caller with :meth:`AutopilotProcess.last_lines`.
"""

from __future__ import annotations

import atexit
import contextlib
import fcntl
import os
import random
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Final

__all__ = [
    "STOP_GRACE_S",
    "AutopilotProcess",
    "Home",
    "LaunchError",
    "LaunchPlan",
    "ardupilot_binary_version",
    "launched",
    "plan_launch",
    "px4_build_version",
]

STOP_GRACE_S: Final = 5.0
"""Seconds between SIGTERM and SIGKILL when stopping the autopilot's process group."""

PX4_AIRFRAME: Final = "1030"
"""PX4's standard SITL plane (``1030_gazebo-classic_plane``), its simulator external."""
PX4_SIM_MODEL: Final = "gazebo-classic_plane"

# ArduPilot SITL: every port moves by 10 per instance
_AP_STEP: Final = 10
_AP_SERIAL_TCP: Final = {"serial0": 5760, "serial1": 5762, "serial2": 5763, "serial5": 5765,
                         "serial6": 5766, "serial7": 5767, "serial8": 5768}
_AP_JSON_UDP: Final = 9002
_AP_RCIN_UDP: Final = 5501
_AP_IRLOCK_UDP: Final = 9005
_AP_MAX_INSTANCE: Final = 256  # SITL keeps -I in a uint8_t: instance 880 runs as 112
# PX4 SITL: every port moves by 1 per instance
_PX4_SIM_TCP: Final = 4560
_PX4_UDP: Final = {"gcs": 18570, "offboard": 14580, "payload": 14280, "gimbal": 13030}
_PX4_MAX_INSTANCE: Final = 200
_PX4_LOCK: Final = "/tmp/px4_lock-{}"

_VERSION = re.compile(
    r"\b((?:Ardu[A-Za-z]+|PX4)\s+[vV]?\d+\.\d+\.\d+[\w.+\-]*(?:\s+\([0-9a-f]{6,}\))?)")
_VERSION_BYTES = re.compile(
    rb"(Ardu[A-Za-z]+ V\d+\.\d+\.\d+[\w.+\-]*(?: \([0-9a-f]{6,}\))?)\x00")
_TAIL_BYTES: Final = 16384


class LaunchError(ValueError):
    """The autopilot binary cannot be started, or exited before it connected (bad input)."""


@dataclass(frozen=True)
class Home:
    """ArduPilot's ``--home``: where it believes it starts (deg, deg, m MSL, deg)."""

    lat_deg: float
    lon_deg: float
    alt_msl_m: float
    heading_deg: float

    def arg(self) -> str:
        return (f"{self.lat_deg:.9g},{self.lon_deg:.9g},{self.alt_msl_m:.6g},"
                f"{self.heading_deg:.6g}")


@dataclass(frozen=True)
class LaunchPlan:
    """One SITL binary to start: its kind (``ardupilot`` / ``px4``), path, instance and what
    follows from them (ports, links, command line). Build it with :func:`plan_launch`.

    ``telemetry``: hilnav records the autopilot's estimate. ``defaults``: ArduPilot parameter
    files given as ``--defaults``.
    """

    kind: str
    binary: Path
    instance: int
    home: Home | None = None
    defaults: tuple[Path, ...] = ()
    telemetry: bool = True

    @property
    def ports(self) -> dict[str, int]:
        """Every loopback port of the instance, by name."""
        n = self.instance
        if self.kind == "ardupilot":
            tcp = {f"{k}_tcp": v + _AP_STEP * n for k, v in _AP_SERIAL_TCP.items()}
            return {"json_udp": _AP_JSON_UDP + _AP_STEP * n,
                    "rcin_udp": _AP_RCIN_UDP + _AP_STEP * n,
                    "irlock_udp": _AP_IRLOCK_UDP + _AP_STEP * n, **tcp}
        return {"simulator_tcp": _PX4_SIM_TCP + n,
                **{f"{k}_udp": v + n for k, v in _PX4_UDP.items()}}

    @property
    def link(self) -> str:
        """hilnav's side of the simulator link."""
        if self.kind == "ardupilot":
            return f"udpin:127.0.0.1:{self.ports['json_udp']}"
        return f"tcpin:127.0.0.1:{self.ports['simulator_tcp']}"

    @property
    def telemetry_url(self) -> str | None:
        """Where hilnav records the autopilot's estimate (None: not recorded)."""
        if not self.telemetry:
            return None
        if self.kind == "ardupilot":
            return f"tcp:127.0.0.1:{self.ports['serial0_tcp']}"
        return f"udpout:127.0.0.1:{self.ports['gcs_udp']}"

    @property
    def mavlink_url(self) -> str | None:
        """ArduPilot's MAVLink port for parameters (SERIAL1); None for PX4."""
        if self.kind == "ardupilot":
            return f"tcp:127.0.0.1:{self.ports['serial1_tcp']}"
        return None

    def argv(self, workdir: Path) -> list[str]:
        """The command line, run in ``workdir``."""
        if self.kind == "ardupilot":
            argv = [str(self.binary), "--model", "JSON:127.0.0.1", "--speedup", "1",
                    "-I", str(self.instance), "--serial0", "tcp:0"]
            if self.home is not None:
                argv += ["--home", self.home.arg()]
            if self.defaults:
                argv += ["--defaults", ",".join(str(p) for p in self.defaults)]
            return argv
        return [str(self.binary), "-i", str(self.instance), "-d",
                "-s", "etc/init.d-posix/rcS", "-w", str(workdir), str(px4_data_dir(self.binary))]

    def env(self) -> dict[str, str]:
        """The environment of the process: this one's, plus PX4's airframe selection."""
        env = dict(os.environ)
        if self.kind == "px4":
            env.update(PX4_SYS_AUTOSTART=PX4_AIRFRAME, PX4_SIM_MODEL=PX4_SIM_MODEL)
            for key in ("PX4_SIM_HOSTNAME", "PX4_SIM_HOST_ADDR", "PX4_SIMULATOR"):
                env.pop(key, None)  # the simulator is hilnav, on this machine
        return env

    def record(self) -> dict[str, Any]:
        """The plan as the summary records it."""
        return {"binary": str(self.binary), "kind": self.kind, "instance": self.instance,
                "ports": self.ports, "link": self.link, "telemetry": self.telemetry_url,
                "mavlink": self.mavlink_url,
                "home": None if self.home is None else self.home.arg(),
                "defaults": [str(p) for p in self.defaults]}


def px4_data_dir(binary: Path) -> Path:
    """``BUILD/etc`` of a PX4 SITL binary ``BUILD/bin/px4``."""
    return binary.parent.parent / "etc"


def px4_build_version(binary: Path) -> str | None:
    """``PX4 <git tag> (<git hash>)`` of the build folder of ``binary`` (from the header PX4's
    build writes, ``src/lib/version/build_git_version.h``), None without one."""
    header = binary.parent.parent / "src" / "lib" / "version" / "build_git_version.h"
    try:
        text = header.read_text(errors="replace")
    except OSError:
        return None
    fields = dict(re.findall(r'#define\s+(PX4_GIT_TAG_STR|PX4_GIT_VERSION_STR)\s+"([^"]*)"',
                             text))
    tag = fields.get("PX4_GIT_TAG_STR")
    if not tag:
        return None
    sha = fields.get("PX4_GIT_VERSION_STR", "")[:10]
    return f"PX4 {tag}" + (f" ({sha})" if sha else "")


def ardupilot_binary_version(binary: Path) -> str | None:
    """The firmware string built into an ArduPilot binary (``ArduPlane V4.7.0-dev
    (2598e9d4)``: the form with the git hash when present), None without one."""
    try:
        data = binary.read_bytes()
    except OSError:
        return None
    found = [m.group(1).decode("ascii") for m in _VERSION_BYTES.finditer(data)]
    if not found:
        return None
    return max(found, key=len)  # "ArduPlane V4.7.0-dev (2598e9d4)" over "ArduPlane V4.7.0-dev"


def check_binary(kind: str, binary: Path) -> Path:
    """``binary`` made absolute, if it is an executable file (and, for PX4, sits in a build
    folder with its ``etc``); LaunchError otherwise."""
    what = {"ardupilot": "ArduPilot SITL binary (arduplane)", "px4": "PX4 SITL binary (px4)"}
    if kind not in what:
        raise LaunchError(f"an autopilot binary needs autopilot kind px4 or ardupilot, not "
                          f"{kind!r}")
    path = Path(os.path.abspath(binary.expanduser()))
    if not path.exists():
        raise LaunchError(f"{what[kind]} {path}: no such file")
    if not path.is_file():
        raise LaunchError(f"{what[kind]} {path}: not a file")
    if not os.access(path, os.X_OK):
        raise LaunchError(f"{what[kind]} {path}: not executable (chmod +x, or give the built "
                          "binary)")
    if kind == "px4" and not (px4_data_dir(path) / "init.d-posix" / "rcS").is_file():
        raise LaunchError(f"{what[kind]} {path}: no {px4_data_dir(path)}/init.d-posix/rcS; give "
                          "the px4 of a SITL build folder (build/px4_sitl_default/bin/px4)")
    return path


def plan_launch(kind: str, binary: Path, *, home: Home | None = None,
                defaults: Sequence[Path] = (), telemetry: bool = True,
                instance: int | None = None, rng: random.Random | None = None) -> LaunchPlan:
    """The plan to start ``binary`` as autopilot ``kind``: the binary checked
    (:func:`check_binary`), an instance whose ports are all free (``instance`` given: that one,
    checked too). LaunchError on a bad binary or when no instance is free."""
    path = check_binary(kind, binary)
    for p in defaults:
        if not Path(p).is_file():
            raise LaunchError(f"ArduPilot defaults file {p}: no such file")
    plan = LaunchPlan(kind, path, 0, home=home, defaults=tuple(Path(p).resolve() for p in defaults),
                      telemetry=telemetry)
    if instance is not None:
        chosen = LaunchPlan(kind, path, instance, home, plan.defaults, telemetry)
        if not _instance_free(chosen):
            raise LaunchError(f"{kind} instance {instance}: a port of it is taken "
                              f"({_port_list(chosen)})")
        return chosen
    top = _AP_MAX_INSTANCE if kind == "ardupilot" else _PX4_MAX_INSTANCE
    rng = rng or random.Random()
    first = rng.randrange(1, top)
    for k in range(top - 1):
        n = 1 + (first - 1 + k) % (top - 1)
        candidate = LaunchPlan(kind, path, n, home, plan.defaults, telemetry)
        if _instance_free(candidate):
            return candidate
    raise LaunchError(f"no free {kind} SITL instance: every one has a port in use")


def _port_list(plan: LaunchPlan) -> str:
    return ", ".join(f"{k} {v}" for k, v in plan.ports.items())


def _instance_free(plan: LaunchPlan) -> bool:
    for name, port in plan.ports.items():
        kind = socket.SOCK_DGRAM if name.endswith("_udp") else socket.SOCK_STREAM
        if not _port_free(port, kind):
            return False
    return not (plan.kind == "px4" and _px4_locked(plan.instance))


def _port_free(port: int, kind: socket.SocketKind) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            return False
    return True


def _px4_locked(instance: int) -> bool:
    """Whether a PX4 server of ``instance`` runs (it holds a lock on its lock file)."""
    path = _PX4_LOCK.format(instance)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


@dataclass
class AutopilotProcess:
    """The started autopilot (:meth:`start`, :meth:`stop`), its output in ``log_path``."""

    plan: LaunchPlan
    log_path: Path
    grace_s: float = STOP_GRACE_S
    proc: subprocess.Popen[bytes] | None = None
    workdir: Path | None = None
    exit_code: int | None = None
    stopped_by: str | None = None
    """How it ended: ``exited`` (by itself), ``SIGTERM`` or ``SIGKILL`` (stopped by hilnav)."""
    _log: IO[bytes] | None = field(default=None, repr=False)
    _stopping: threading.Event = field(default_factory=threading.Event, repr=False)
    _watcher: threading.Thread | None = field(default=None, repr=False)

    def start(self) -> AutopilotProcess:
        """Start the binary in a new session and a new temporary working folder."""
        self.workdir = Path(tempfile.mkdtemp(prefix=f"hilnav-{self.plan.kind}-"))
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = self.log_path.open("wb")
        argv = self.plan.argv(self.workdir)
        self._log.write(("$ " + " ".join(argv) + "\n").encode())
        self._log.flush()
        try:
            self.proc = subprocess.Popen(
                argv, cwd=self.workdir, env=self.plan.env(), stdout=self._log,
                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
        except OSError as exc:
            self._cleanup()
            raise LaunchError(f"autopilot binary {self.plan.binary}: cannot start it: "
                              f"{exc.strerror or exc}") from None
        atexit.register(self.stop)  # an interpreter that ends without the stop still stops it
        return self

    @property
    def pid(self) -> int | None:
        return None if self.proc is None else self.proc.pid

    def poll(self) -> int | None:
        """Its exit code once it exited by itself, else None."""
        if self.proc is None:
            return None
        code = self.proc.poll()
        if code is not None and self.exit_code is None:
            self.exit_code = code
            self.stopped_by = self.stopped_by or "exited"
        return code

    def watch(self, on_exit: threading.Event) -> None:
        """Set ``on_exit`` when the process exits by itself (until :meth:`stop`)."""
        self._watcher = threading.Thread(target=_watch, args=(self, on_exit, self._stopping),
                                         name="autopilot-process", daemon=True)
        self._watcher.start()

    def stop(self) -> int | None:
        """Stop it by PID: SIGTERM to its process group, SIGKILL after ``grace_s``; returns its
        exit code (idempotent). Its working folder is removed."""
        self._stopping.set()
        atexit.unregister(self.stop)
        if self._watcher is not None:
            self._watcher.join(1.0)
        self.poll()
        proc = self.proc
        if proc is not None and proc.poll() is None:
            self._signal_group(signal.SIGTERM)
            self.stopped_by = "SIGTERM"
            try:
                proc.wait(self.grace_s)
            except subprocess.TimeoutExpired:
                self._signal_group(signal.SIGKILL)
                self.stopped_by = "SIGKILL"
                proc.wait(10.0)
        if proc is not None:
            self._signal_group(signal.SIGKILL)  # whatever it left behind in its group
            if self.exit_code is None:
                self.exit_code = proc.returncode
                self.stopped_by = self.stopped_by or "exited"
        self._cleanup()
        return self.exit_code

    def wait_ready(self, timeout_s: float, *, min_alive_s: float = 0.0) -> bool:
        """Until the binary is ready and has run ``min_alive_s``: True when ready, False after
        ``timeout_s``; LaunchError when it exits first (naming it and its last output).
        ArduPilot is ready when its SERIAL0 listens (its other ports open only once hilnav
        answers its physics frames); PX4 dials hilnav: nothing to wait for."""
        ports = [self.plan.ports["serial0_tcp"]] if self.plan.kind == "ardupilot" else []
        start = time.monotonic()
        deadline = start + timeout_s
        while True:
            if self.poll() is not None:
                raise LaunchError(f"autopilot binary {self.describe_exit()} (before it was "
                                  f"ready; is it {self.plan.kind}'s SITL? log {self.log_path})")
            panic = self._panic()
            if panic is not None:  # ArduPilot's SITL hangs in its core-dump helper after it
                raise LaunchError(f"autopilot binary {self.plan.binary} stopped before it was "
                                  f"ready: {panic} (log {self.log_path})")
            now = time.monotonic()
            if all(_tcp_listening(p) for p in ports) and now - start >= min_alive_s:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)

    def _panic(self) -> str | None:
        """ArduPilot's fatal-error line (``PANIC: ...``) in its output so far, else None."""
        if self.plan.kind != "ardupilot":
            return None
        for line in self.output().splitlines():
            if line.startswith("PANIC:"):
                return line.strip()
        return None

    def _signal_group(self, sig: signal.Signals) -> None:
        assert self.proc is not None
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.proc.pid, sig)  # its own session: the group id is its PID

    def _cleanup(self) -> None:
        if self._log is not None:
            self._log.close()
            self._log = None
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def output(self) -> str:
        """The end of its output so far (the command line hilnav wrote first excluded)."""
        try:
            with self.log_path.open("rb") as f:
                f.seek(0, os.SEEK_END)
                size = f.tell()
                f.seek(max(0, size - _TAIL_BYTES))
                text = f.read().decode("utf-8", "replace")
        except OSError:
            return ""
        lines = text.splitlines()
        if lines and lines[0].startswith("$ "):
            lines = lines[1:]
        return "\n".join(lines)

    def last_lines(self, n: int = 2) -> str:
        """Its last ``n`` non-empty output lines joined by `` | `` ("no output" if none)."""
        lines = [ln.strip() for ln in self.output().splitlines() if ln.strip()]
        return " | ".join(lines[-n:]) if lines else "no output"

    def version(self, texts: Sequence[str] = ()) -> str | None:
        """The version it printed (``ArduPlane V4.7.0-dev (2598e9d4)``), else the first one
        in ``texts`` (its STATUSTEXTs), else the one built into it: ArduPilot's firmware
        string in the binary (it prints none on its console), PX4's from its build folder
        (``BUILD/src/lib/version/build_git_version.h``); None when none is found."""
        for text in (self._head(), *texts):
            match = _VERSION.search(text)
            if match is not None:
                return match.group(1)
        if self.plan.kind == "px4":
            return px4_build_version(self.plan.binary)
        return ardupilot_binary_version(self.plan.binary)

    def _head(self) -> str:
        try:
            with self.log_path.open("rb") as f:
                return f.read(_TAIL_BYTES * 4).decode("utf-8", "replace")
        except OSError:
            return ""

    def record(self, texts: Sequence[str] = ()) -> dict[str, Any]:
        """What the summary says of the process: the plan, its PID, version, how it ended."""
        return {**self.plan.record(), "pid": self.pid, "version": self.version(texts),
                "exit_code": self.exit_code, "stopped_by": self.stopped_by,
                "log": str(self.log_path)}

    def describe_exit(self) -> str:
        """``BINARY exited with code C: LAST LINES`` (for a failure sentence)."""
        code = self.exit_code if self.exit_code is not None else self.poll()
        how = f"was killed by signal {-code}" if code is not None and code < 0 else \
            f"exited with code {code}"
        return f"{self.plan.binary} {how}: {self.last_lines()}"


@contextlib.contextmanager
def launched(plan: LaunchPlan, log_path: Path, *, grace_s: float = STOP_GRACE_S,
             on_exit: threading.Event | None = None) -> Iterator[AutopilotProcess]:
    """Run the plan's binary for the block; stopped by PID when the block ends, however it
    ends. ``on_exit``: set when the process exits by itself (e.g. to end a wait for it)."""
    process = AutopilotProcess(plan, log_path, grace_s=grace_s).start()
    if on_exit is not None:
        process.watch(on_exit)
    try:
        yield process
    finally:
        process.stop()


def _tcp_listening(port: int) -> bool:
    """Whether a socket of this machine listens on TCP ``port`` (read from the kernel's
    table, so that the check is no connection the autopilot would see)."""
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 3 and fields[3] == "0A" and \
                    int(fields[1].rsplit(":", 1)[1], 16) == port:
                return True
    if not Path("/proc/net/tcp").exists():  # no kernel table: try a connection
        with socket.socket() as s:
            s.settimeout(0.2)
            return s.connect_ex(("127.0.0.1", port)) == 0
    return False


def _watch(process: AutopilotProcess, on_exit: threading.Event, done: threading.Event) -> None:
    proc = process.proc
    assert proc is not None
    while not done.is_set():
        if proc.poll() is not None:
            on_exit.set()
            return
        done.wait(0.1)
