"""``hilnav up --px4``: the fusion service (child process) beside the simulator side in ``up``,
PX4 (the protocol peer, tests/helpers/px4_peer.py) at the controls over loopback TCP, its
estimate recorded from its telemetry; the live scorecard gets the side-by-side section and every
child is stopped by PID."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios.cli.up import free_udp_port, stop_process, wait_gone
from tests.helpers.processes import free_tcp_port
from tests.helpers.px4_peer import PeerPlan, Px4Peer

_PID = re.compile(r"^(fusion|monitor)\s+pid (\d+):", re.M)


def test_up_px4_waits_for_px4_and_writes_the_side_by_side_scorecard(tmp_path: Path) -> None:
    port, tport = free_tcp_port(), free_udp_port()
    out = tmp_path / "up"
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "up", "--px4",
         "--autopilot-link", f"tcpin:127.0.0.1:{port}",
         "--autopilot-telemetry", f"udpin:127.0.0.1:{tport}", "--duration", "90",
         "--gnss-off", "40:20", "--no-monitor", "--connect-timeout", "60", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"})
    peer = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}",
                   PeerPlan(turns=((45.0, 90.0),)), outputs="legacy")
    try:
        with peer:
            text, _ = proc.communicate(timeout=600)
    finally:
        stop_process(proc)
    assert proc.returncode == 0, text
    assert peer.errors == []
    # where it waits and what to run on the autopilot's side are printed
    assert f"for PX4 on tcpin:127.0.0.1:{port}" in text
    assert "PX4_SYS_AUTOSTART=1030 PX4_SIM_MODEL=plane ./build/px4_sitl_default/bin/px4" in text
    # and how far the flight is (a line every 10 % when the output is not a terminal)
    assert "flying: 90/90 s simulated (100 %)" in text or "flying: 81/90 s" in text
    pids = [int(pid) for _, pid in _PID.findall(text)]
    assert pids and wait_gone(pids), "a child outlived `hilnav up`"
    s = json.loads((out / "summary.json").read_text())
    ap = s["autopilot"]
    assert ap["source"] == "PX4" and ap["connected"] and ap["stalled"] is None
    assert ap["problem"] is None
    assert ap["counters"]["telemetry_position_reports"] == len(peer.estimates) > 800
    # hilnav's live scorecard and the autopilot's, over the same outage
    (mine,) = s["outages"]
    (theirs,) = ap["outages"]
    assert (theirs["start_s"], theirs["end_s"]) == (mine["start_s"], mine["end_s"])
    assert "hilnav vs PX4" in text
    assert (out / "run.tlog").stat().st_size > 0


@pytest.mark.parametrize(("args", "needle"), [
    (["--px4", "--ardupilot"], "give --px4 or --ardupilot, not both"),
    (["--autopilot-link", "tcpin:127.0.0.1:4560"], "--autopilot-link needs --px4 or --ardupilot"),
    (["--px4", "--lockstep"], "the autopilot sets the pace"),
    (["--px4", "--autopilot-link", "tcpin:no-such-host.invalid:4560"], "no-such-host"),
    (["--ardupilot", "--autopilot-link", "tcpin:127.0.0.1:9002"], "udp"),
])
def test_bad_autopilot_options_are_one_line_and_start_nothing(
        tmp_path: Path, args: list[str], needle: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "up", *args, "--duration", "10", "--out",
         str(tmp_path / "up")], capture_output=True, text=True, timeout=120, check=False,
        env={**os.environ, "COLUMNS": "200"})
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "pid" not in proc.stdout  # nothing was started
