"""``hilnav sim px4 URL`` as a real process on loopback with the PX4 protocol peer: the tlog it
records and its exit codes (0 flown, 1 stalled, 2 a peer speaking another protocol)."""

from __future__ import annotations

import re
import socket
import struct
import subprocess
import time
from collections import Counter
from pathlib import Path

from hil.codec import AUTOPILOT_COMPONENT_ID, mavlink2
from hil.tlog import read_tlog
from scenarios.cli.up import stop_process
from tests.helpers.processes import hilnav_process
from tests.helpers.px4_peer import Px4Peer

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"
_WAITING = re.compile(r"waiting for PX4 at tcpin:127\.0\.0\.1:(\d+)")


def _listening_port(proc: subprocess.Popen[bytes], log: Path, timeout_s: float = 60.0) -> int:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        found = _WAITING.search(log.read_text(errors="replace")) if log.exists() else None
        if found:
            return int(found.group(1))
        assert proc.poll() is None, log.read_text(errors="replace")
        time.sleep(0.05)
    raise AssertionError(f"no 'waiting for PX4' line in {log}")


def _sim_px4(tmp_path: Path, *args: str) -> tuple[subprocess.Popen[bytes], Path, int]:
    log = tmp_path / "sim.log"
    proc = hilnav_process("sim", "px4", "tcpin:127.0.0.1:0", "--rate", "50", "--seed", "5",
                          *args, log=log)
    return proc, log, _listening_port(proc, log)


def test_sim_px4_records_what_px4_flew_and_exits_0(tmp_path: Path) -> None:
    tlog = tmp_path / "px4.tlog"
    proc, log, port = _sim_px4(tmp_path, "--duration", "20", "--gnss-off", "8:6", "--record",
                               str(tlog), "--actuator-map", str(STANDARD_PLANE))
    try:
        with Px4Peer(f"tcp:127.0.0.1:{port}") as peer:
            rc = proc.wait(timeout=120)
    finally:
        stop_process(proc)
    text = log.read_text()
    assert rc == 0, text
    assert peer.errors == []
    assert "PX4 flew 20.0 s simulated" in text and "20 disarmed: trim held" in text
    kinds: Counter[str] = Counter()
    controls_from_autopilot = 0
    gps_times = []
    for _t, frame in read_tlog(tlog):
        msg = mavlink2.MAVLink(None).decode(bytearray(frame))
        kinds[msg.get_type()] += 1
        if msg.get_type() == "HIL_ACTUATOR_CONTROLS":
            controls_from_autopilot += msg.get_srcComponent() == AUTOPILOT_COMPONENT_ID
        if msg.get_type() == "HIL_GPS":
            gps_times.append(msg.time_usec)
    assert kinds["HIL_SENSOR"] == 1000 == peer.counters["sensors"]
    assert kinds["HIL_ACTUATOR_CONTROLS"] == controls_from_autopilot > 0
    assert gps_times and not [t for t in gps_times if 8e6 <= t < 14e6]


def test_sim_px4_exits_1_when_px4_goes_silent(tmp_path: Path) -> None:
    proc, log, port = _sim_px4(tmp_path, "--duration", "30", "--stall-timeout", "3")
    try:
        with Px4Peer(f"tcp:127.0.0.1:{port}", outputs="legacy", silent_after_s=2.0):
            rc = proc.wait(timeout=120)
    finally:
        stop_process(proc)
    text = log.read_text()
    assert rc == 1, text
    assert "failed: PX4 sent no controls for 3 s (simulated time 2.00 s)" in text


def test_sim_px4_exits_2_naming_the_protocol_it_expected(tmp_path: Path) -> None:
    proc, log, port = _sim_px4(tmp_path, "--duration", "30")
    packet = struct.pack("<HHI16H", 18458, 400, 1, *[1500] * 16)
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            sock.sendall(packet)  # the simulator answers the first packet by leaving
            rc = proc.wait(timeout=60)
    finally:
        stop_process(proc)
    text = log.read_text()
    assert rc == 2, text
    errors = [line for line in text.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "ArduPilot SITL 16-channel servo packet" in errors[0]
    assert "expected PX4's simulator interface" in errors[0] and "Traceback" not in text
