"""Fake autopilot SITL binaries for the launcher's tests: small executable Python scripts
written into a test's folder that take the command line, environment and working folder
hilnav gives the real ``arduplane`` / ``px4`` and run the protocol peers
(:mod:`tests.helpers.ardupilot_peer`, :mod:`tests.helpers.px4_peer`) on the ports that
command line implies, so the launch contract itself is exercised; plus fakes that misbehave
(exit at once, ignore SIGTERM, never connect).

The ArduPlane fake exits (code 4, "PANIC: fake crash") after ``FAKE_SITL_EXIT_AFTER_S`` wall
seconds when that is set, and takes its servo trims from ``FAKE_SITL_TRIM`` (roll, pitch, yaw,
throttle). Each fake writes ``fake.json`` into the folder named by ``FAKE_SITL_REPORT`` (when
set): its argv, its working folder, the environment keys that matter and its PID, for the test
to check.
"""

from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

_PRELUDE = f"""#!{sys.executable}
import json, os, signal, sys, time
sys.path.insert(0, {str(REPO)!r})

def report(**extra):
    folder = os.environ.get("FAKE_SITL_REPORT")
    if folder:
        data = {{"argv": sys.argv, "cwd": os.getcwd(), "pid": os.getpid(),
                 "env": {{k: v for k, v in os.environ.items() if k.startswith("PX4_")}},
                 **extra}}
        with open(os.path.join(folder, "fake.json"), "w") as f:
            json.dump(data, f)

def option(name, default=None):
    return sys.argv[sys.argv.index(name) + 1] if name in sys.argv else default

def serial_relay(tcp_port):
    # a TCP server on tcp_port (as SITL's serial port) relaying MAVLink frames both ways to a
    # peer's udpout link; returns that link's URL
    import socket, threading
    from hil.codec import mavlink2
    server = socket.create_server(("127.0.0.1", tcp_port))
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    state = {{"client": None, "peer": None}}

    def from_peer():
        while True:
            data, address = udp.recvfrom(65536)
            state["peer"] = address
            client = state["client"]
            if client is not None:
                try:
                    client.sendall(data)
                except OSError:
                    state["client"] = None

    def from_client(conn):
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        while True:
            try:
                data = conn.recv(65536)
            except OSError:
                return
            if not data:
                return
            for msg in parser.parse_buffer(data) or []:
                if state["peer"] is not None and msg.get_type() != "BAD_DATA":
                    udp.sendto(bytes(msg.get_msgbuf()), state["peer"])

    def accept():
        while True:
            conn, _ = server.accept()
            state["client"] = conn
            threading.Thread(target=from_client, args=(conn,), daemon=True).start()

    threading.Thread(target=from_peer, daemon=True).start()
    threading.Thread(target=accept, daemon=True).start()
    return "udpout:127.0.0.1:%d" % udp.getsockname()[1]
"""

ARDUPLANE = _PRELUDE + """
from tests.helpers.ardupilot_peer import ArduPilotPeer, PeerPlan

model = option("--model")
if model is None or not model.startswith("JSON:"):
    print("You must specify a vehicle model.", flush=True)
    sys.exit(1)
n = int(option("-I", "0"))
lat, lon, alt, hdg = (float(x) for x in option("--home", "0,0,0,0").split(","))
open("eeprom.bin", "wb").close()  # as ArduPilot: its storage in the working folder
trim = [float(x) for x in os.environ.get("FAKE_SITL_TRIM", "0,0,0,0.6").split(",")]
print("ArduPlane V4.7.0-dev (f4k3f4k3)", flush=True)
print("JSON control interface set to 127.0.0.1:%d" % (9002 + 10 * n), flush=True)
serial0 = option("--serial0", "tcp:0:wait")
report(instance=n, home=[lat, lon, alt, hdg], serial0=serial0)
# SERIAL0 (TCP 5760 + 10 N) carries the peer's telemetry link (a udpout link) both ways
telemetry = serial_relay(5760 + 10 * n)
peer = ArduPilotPeer(telemetry_url=telemetry,
                     plan=PeerPlan(headings=((10.0, hdg + 20.0),)), home=(lat, lon, alt),
                     trim=trim, mavlink=True, disarmed_s=2.0, fix_after_s=1.0,
                     mavlink_listen="tcpin:127.0.0.1:%d" % (5762 + 10 * n))
print("SERIAL0 on TCP port %d" % (5760 + 10 * n), flush=True)
peer.start("udp:127.0.0.1:%d" % (9002 + 10 * n))
exit_after_s = float(os.environ.get("FAKE_SITL_EXIT_AFTER_S", "inf"))
started = time.monotonic()
while True:
    time.sleep(0.2)
    if time.monotonic() - started > exit_after_s:
        print("PANIC: fake crash", flush=True)
        os._exit(4)
    if peer.error is not None:
        print("peer error: %r" % (peer.error,), flush=True)
        sys.exit(3)
"""

PX4 = _PRELUDE + """
from tests.helpers.px4_peer import PeerPlan, Px4Peer

n = int(option("-i", "0"))
workdir = option("-w")
data = sys.argv[-1]
if "-d" not in sys.argv or option("-s") != "etc/init.d-posix/rcS" or workdir is None:
    print("Usage: px4 [-h|-d] [-s <startup_file>] ...", flush=True)
    sys.exit(1)
if not os.path.isfile(os.path.join(data, "init.d-posix", "rcS")):
    print("ERROR [px4] no startup script in " + data, flush=True)
    sys.exit(1)
os.symlink(data, os.path.join(workdir, "etc"))  # as px4: the data folder linked into rootfs
print("INFO  [px4] instance: %d" % n, flush=True)
print("INFO  [init] PX4_SIM_HOSTNAME: localhost", flush=True)
report(instance=n)
peer = Px4Peer("tcp:127.0.0.1:%d" % (4560 + n), "udpin:127.0.0.1:%d" % (18570 + n),
               PeerPlan(turns=((10.0, 20.0),)))
peer.start()
while True:
    time.sleep(0.2)
    if peer.errors:
        print("peer error: %s" % peer.errors[0], flush=True)
        sys.exit(3)
"""

EXITS_AT_ONCE = _PRELUDE + """
print("starting", flush=True)
print("fake: unrecognized option '--model'", file=sys.stderr, flush=True)
sys.exit(3)
"""

NEVER_CONNECTS = _PRELUDE + """
report()
print("Waiting for connection ....", flush=True)
while True:
    time.sleep(0.2)
"""

PANICS = _PRELUDE + """
# ArduPilot's SITL on a fatal error: it prints PANIC, then hangs in its core-dump helper
print("PANIC: Failed to load defaults from nowhere.parm", flush=True)
print("Running: sh dumpstack.sh 1 >dumpstack.out 2>&1", flush=True)
while True:
    time.sleep(0.2)
"""

IGNORES_SIGTERM = _PRELUDE + """
signal.signal(signal.SIGTERM, signal.SIG_IGN)
report()
print("ignoring SIGTERM", flush=True)
while True:
    time.sleep(0.2)
"""

IGNORES_SIGTERM_LISTENING = _PRELUDE + """
import socket
signal.signal(signal.SIGTERM, signal.SIG_IGN)  # as the real arduplane
n = int(option("-I", "0"))
ports = [socket.create_server(("127.0.0.1", 5760 + 10 * n + k)) for k in (0, 2)]
report(instance=n)
print("SERIAL0 on TCP port %d" % (5760 + 10 * n), flush=True)
while True:  # ready (its MAVLink ports listen) but never sends a servo packet
    time.sleep(0.2)
"""


def write_fake(folder: Path, name: str, script: str) -> Path:
    """``script`` as an executable file ``folder/name``."""
    path = folder / name
    path.write_text(script)
    path.chmod(0o755)
    return path


def px4_build(folder: Path, script: str = PX4) -> Path:
    """A fake PX4 SITL build folder: ``folder/build/bin/px4`` and ``build/etc/init.d-posix/rcS``."""
    build = folder / "build"
    (build / "bin").mkdir(parents=True)
    (build / "etc" / "init.d-posix").mkdir(parents=True)
    (build / "etc" / "init.d-posix" / "rcS").write_text("#!/bin/sh\n")
    return write_fake(build / "bin", "px4", script)
