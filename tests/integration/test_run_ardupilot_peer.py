"""``hilnav run`` with ``autopilot: ardupilot`` against the ArduPilot protocol peer
(tests/helpers/ardupilot_peer.py: SITL's JSON side flying from its own estimate, its own GPS
switched off through SIM_GPS1_* over its MAVLink port): the backend built by the scenario
(hil.autopilot.make_backend), both estimates on one scorecard."""

from __future__ import annotations

import math
import threading
from pathlib import Path

from scenarios.cli.up import free_udp_port
from scenarios.runner import run_scenario, sim_setup
from scenarios.schema import load_scenario
from tests.helpers.ardupilot_peer import ArduPilotPeer, PeerPlan, trimmed_controls


def test_run_scores_ardupilots_estimate_beside_hilnavs(tmp_path: Path) -> None:
    port, tport = free_udp_port(), free_udp_port()

    def scenario(mavlink_url: str | None) -> Path:
        path = tmp_path / "ardupilot.yaml"
        path.write_text(f"""
name: ardupilot-peer
duration_s: 200
sim_rate_hz: 100
seed: 3
start: {{lat_deg: 47.0, lon_deg: 8.0, alt_msl_m: 1000, heading_deg: 0, airspeed_mps: 50}}
autopilot:
  kind: ardupilot
  link: udpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  {f"mavlink: {mavlink_url}" if mavlink_url else ""}
  connect_timeout_s: 30
  stall_timeout_s: 20
events:
  - {{type: gnss_outage, at: 65, duration: 35}}
""")
        return path

    # the peer is trimmed as a tuned ArduPlane (the aircraft's trim at the start); its MAVLink
    # port is named in the scenario; the run waits for it, then it flies. It boots disarmed
    # for 8 s (neutral outputs) and has no GPS fix for 5 s (its position 0/0 until then)
    trim = trimmed_controls(sim_setup(load_scenario(scenario(None))))
    peer = ArduPilotPeer(telemetry_url=f"udpout:127.0.0.1:{tport}",
                         plan=PeerPlan(headings=((70.0, 90.0),)), home=(47.0, 8.0, 0.0),
                         trim=trim, mavlink=True, disarmed_s=8.0, fix_after_s=5.0)
    scn = load_scenario(scenario(peer.mavlink_url))
    starter = threading.Timer(0.5, lambda: peer.start(f"udp:127.0.0.1:{port}"))
    starter.start()
    try:
        result = run_scenario(scn, tmp_path / "out", reports=False)
    finally:
        starter.cancel()
        peer.stop()
    assert peer.error is None
    s = result.summary
    ap = s["autopilot"]
    assert ap["source"] == "ArduPilot" and ap["connected"] and ap["stalled"] is None
    assert ap["problem"] is None
    assert ap["health"]["autopilot_type"] == 3  # MAV_AUTOPILOT_ARDUPILOTMEGA
    assert ap["health"]["estimator"]["reports"] > 1000  # EKF_STATUS_REPORT
    assert ap["counters"]["params_sent"] == ap["counters"]["params_acked"] >= 3
    assert ap["counters"]["telemetry_position_reports"] > 1900
    (mine,) = s["outages"]
    (theirs,) = ap["outages"]
    assert (theirs["start_s"], theirs["end_s"]) == (mine["start_s"], mine["end_s"])
    assert math.isfinite(theirs["horizontal_rmse_m"])
    # the trim was held until it armed, and the scorecard says when that was
    assert peer.armed_at_s is not None
    assert peer.armed_at_s <= ap["trim_released_s"] < peer.armed_at_s + 1.0
    # its position before its first fix (0/0) is not its estimate: scored from its fix on
    assert 5.0 <= ap["estimate_from_s"] < 6.5
    assert ap["counters"]["telemetry_positions_before_fix"] >= 50
    assert ap["gnss_on"]["horizontal_rmse_m"] < 100.0  # not the 5,000 km to 0/0
    # its denial was acknowledged step by step: the outage is its outage too
    assert ap["outages_not_denied"] == []
    assert {d["status"] for d in ap["denial"]} == {"acknowledged"}
    assert "failures" not in s
    assert theirs["horizontal_max_m"] > ap["gnss_on"]["horizontal_rmse_m"]
