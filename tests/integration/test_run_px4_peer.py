"""``hilnav run`` with ``autopilot: px4`` against the PX4 protocol peer (tests/helpers/px4_peer.py,
PX4's side of the simulator interface flying from its own estimate): the real CLI in a child
process, real loopback TCP for the simulator link and UDP for the peer's telemetry; both
estimates on one scorecard, and a stall failing the run."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

from scenarios.cli.up import free_udp_port, stop_process
from tests.helpers.processes import free_tcp_port
from tests.helpers.px4_peer import PeerPlan, Px4Peer

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"


def _scenario(tmp_path: Path, port: int, tport: int, *, stall_timeout_s: float) -> Path:
    path = tmp_path / "px4.yaml"
    path.write_text(f"""
name: px4-peer
duration_s: 200
sim_rate_hz: 50
seed: 5
sensors:
  imu: {{preset: industrial-mems, rate_hz: 50}}
autopilot:
  kind: px4
  link: tcpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  actuator_map: {STANDARD_PLANE}
  connect_timeout_s: 60
  stall_timeout_s: {stall_timeout_s}
events:
  - {{type: gnss_outage, at: 65, duration: 35}}
""")
    return path


def _run_with_peer(tmp_path: Path, **peer_faults: float) -> tuple[subprocess.CompletedProcess[str],
                                                                   Px4Peer]:
    port, tport = free_tcp_port(), free_udp_port()
    # the stall timeout also bounds PX4's boot (paced at real time): 3 s leaves it room
    scn = _scenario(tmp_path, port, tport, stall_timeout_s=3.0 if peer_faults else 20.0)
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "run", str(scn), "--out", str(tmp_path / "out"),
         "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, env={**os.environ, "COLUMNS": "200"})
    peer = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}",
                   PeerPlan(turns=((70.0, 90.0),)), **peer_faults)  # type: ignore[arg-type]
    try:
        with peer:
            out, err = proc.communicate(timeout=900)
    finally:
        stop_process(proc)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err), peer


def test_run_scores_px4s_estimate_beside_hilnavs_through_the_outage(tmp_path: Path) -> None:
    done, peer = _run_with_peer(tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert peer.errors == []
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    ap = s["autopilot"]
    assert ap["source"] == "PX4" and ap["connected"] and ap["stalled"] is None
    assert ap["problem"] is None and ap["nees"] is None
    assert ap["health"]["autopilot_type"] == 12 and ap["health"]["armed_ever"]
    # every telemetry report the peer sent was recorded and scored on the simulated time axis
    assert ap["counters"]["telemetry_position_reports"] == len(peer.estimates) > 1900
    assert ap["samples"] >= len(peer.estimates) - 2
    # the same outage (from the gaps of the one sensor stream) scored for both estimators
    (mine,) = s["outages"]
    (theirs,) = ap["outages"]
    assert (theirs["start_s"], theirs["end_s"]) == (mine["start_s"], mine["end_s"])
    assert 64.0 < mine["start_s"] < 65.5 and 99.5 < mine["end_s"] < 101.0
    # the peer takes its position from GNSS while it has fixes and dead-reckons without: its
    # error grows through the outage beyond its aided error
    assert math.isfinite(ap["gnss_on"]["horizontal_rmse_m"])
    assert theirs["horizontal_max_m"] > ap["gnss_on"]["horizontal_rmse_m"]
    assert "hilnav vs PX4" in done.stdout
    assert "Both estimates on one scorecard" in (tmp_path / "out" / "report.html").read_text()


def test_a_px4_that_stops_sending_controls_fails_the_run(tmp_path: Path) -> None:
    done, peer = _run_with_peer(tmp_path, silent_after_s=70.0)
    assert done.returncode == 1, done.stdout + done.stderr
    assert peer.errors == []
    # one clear line (after the line saying where it waited)
    (failed,) = [line for line in done.stderr.splitlines() if line.startswith("failed:")]
    assert "PX4 sent no controls for 3 s (simulated time 70.00 s)" in failed
    assert "Traceback" not in done.stderr
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["autopilot"]["stalled"].startswith("PX4 sent no controls") and not s["passed"]
    assert s["sim_duration_s"] < 70.1
