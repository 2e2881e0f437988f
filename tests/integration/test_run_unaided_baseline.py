"""``hilnav run`` with an unaided baseline: the autopilot flies the scenario's seed unaided
(``aiding: disabled``) and then aided by hilnav, each flight meeting a fresh protocol peer
(tests/helpers/px4_peer.py, ardupilot_peer.py, answering as autopilot_commands.py), and one
summary.json, report.html and side-by-side plot score hilnav, the aided and the unaided
autopilot together."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from hil.autopilot.modes import ARDUPLANE_MODES, PX4_MODES
from scenarios.cli.up import free_udp_port, stop_process
from scenarios.runner import sim_setup
from scenarios.schema import Scenario, load_scenario
from scenarios.unaided_baseline import run_with_unaided_baseline
from tests.helpers.ardupilot_peer import ArduPilotPeer, trimmed_controls
from tests.helpers.autopilot_commands import CommandSide
from tests.helpers.processes import free_tcp_port
from tests.helpers.px4_peer import PeerPlan as Px4Plan
from tests.helpers.px4_peer import Px4Peer

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"
# short flights: the outage starts once hilnav's filter and the peers navigate
DURATION_S = 42.0
OUTAGE = "{type: gnss_outage, at: 10, duration: 30}"


def _scenario(tmp_path: Path, autopilot: str) -> Path:
    path = tmp_path / "aided.yaml"
    path.write_text(f"""
name: aided
duration_s: {DURATION_S}
sim_rate_hz: 50
seed: 4
sensors:
  imu: {{preset: industrial-mems, rate_hz: 50}}
start: {{lat_deg: 47.0, lon_deg: 8.0, alt_msl_m: 1000, heading_deg: 0, airspeed_mps: 50}}
events:
  - {OUTAGE}
autopilot:
{autopilot}
  connect_timeout_s: 30
  stall_timeout_s: 20
  aiding: hilnav
  unaided_baseline: true
  arm: true
""")
    return path


def _px4_yaml(port: int, tport: int) -> str:
    return f"""  kind: px4
  link: tcpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  actuator_map: {STANDARD_PLANE}
  mode: HOLD"""


def _px4_side() -> CommandSide:
    return CommandSide("px4", {"EKF2_EV_CTRL": 15.0}, int_params={"EKF2_EV_CTRL"},
                       custom_mode=PX4_MODES["MANUAL"], valid_modes=PX4_MODES.values())


def _card(summary: dict[str, Any]) -> dict[str, Any]:
    (row,) = summary["autopilot"]["aided_vs_unaided"]["outages"]
    return dict(row)


def _same_figures(row: dict[str, Any] | None, outage: dict[str, Any]) -> None:
    assert row is not None
    assert row["horizontal_rmse_m"] == outage["horizontal_rmse_m"]
    assert row["horizontal_max_m"] == outage["horizontal_max_m"]
    assert row["horizontal_error_m_at"]["30"] == outage["horizontal_error_m_at"].get("30")


def test_px4_aided_and_unaided_on_one_card(tmp_path: Path) -> None:
    port, tport = free_tcp_port(), free_udp_port()
    scn = load_scenario(_scenario(tmp_path, _px4_yaml(port, tport)))
    sides: dict[str, CommandSide] = {}
    peers: dict[str, Px4Peer] = {}

    @contextmanager
    def each_flight(role: str, flight: Scenario) -> Iterator[None]:
        assert flight.autopilot.aiding == ("disabled" if role == "unaided" else "hilnav")
        sides[role] = _px4_side()
        peers[role] = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}",
                              Px4Plan(turns=()), commands=sides[role])
        with peers[role]:
            yield None

    out = tmp_path / "out"
    result = run_with_unaided_baseline(scn, out, tlog=False, each_run=each_flight)
    assert all(p.errors == [] for p in peers.values())
    summary = json.loads((out / "summary.json").read_text())
    assert summary == json.loads(json.dumps(result.summary).replace("NaN", "null"))
    assert "failures" not in summary, summary.get("failures")
    # unaided: its external vision set off and nothing sent; aided: set on and fused
    assert sides["unaided"].params["EKF2_EV_CTRL"] == 0.0
    assert peers["unaided"].counters.get("ev_fixes", 0) == 0
    assert sides["aided"].params["EKF2_EV_CTRL"] == 5.0
    assert peers["aided"].counters["ev_fixes"] > 500
    base = json.loads((out / "unaided" / "summary.json").read_text())
    assert base["autopilot"]["aiding"] == {"source": None, "frames_sent": 0, "message": None,
                                           "parameters_off": ["EKF2_EV_CTRL"]}
    ap = summary["autopilot"]
    assert ap["aiding"]["message"] == "ODOMETRY"
    unaided = ap["unaided"]
    assert unaided["run"]["folder"] == str(out / "unaided") and unaided["run"]["seed"] == 4
    assert unaided["outages"] == base["autopilot"]["outages"]
    # the rows are the three estimates' own outage figures; the ratios their RMSEs'
    row = _card(summary)
    (mine,), (aided,), (alone,) = summary["outages"], ap["outages"], base["autopilot"]["outages"]
    _same_figures(row["hilnav"], mine)
    _same_figures(row["aided"], aided)
    _same_figures(row["unaided"], alone)
    _same_figures(row["hilnav_unaided_flight"], base["outages"][0])
    assert row["aided_over_hilnav"] == pytest.approx(
        aided["horizontal_rmse_m"] / mine["horizontal_rmse_m"])
    assert row["aided_over_unaided"] == pytest.approx(
        aided["horizontal_rmse_m"] / alone["horizontal_rmse_m"])
    # the peer unaided dead-reckons on airspeed and heading; aided it is held on hilnav's
    # ODOMETRY
    assert row["aided"]["horizontal_rmse_m"] < row["unaided"]["horizontal_rmse_m"], row
    assert row["meets"]["aided_over_unaided"] is (row["aided_over_unaided"] <= 0.5)
    assert row["meets"]["aided_over_hilnav"] is (row["aided_over_hilnav"] <= 1.5)
    report = (out / "report.html").read_text()
    assert "Aided by hilnav and unaided" in report and "PX4 aided by hilnav" in report
    assert (out / "autopilot_side_by_side.png").stat().st_size > 0
    assert (out / "unaided" / "report.html").exists()


def test_cli_flies_arduplane_unaided_then_aided_and_prints_the_card(tmp_path: Path) -> None:
    port, tport, mport = free_udp_port(), free_udp_port(), free_tcp_port()
    path = _scenario(tmp_path, f"""  kind: ardupilot
  link: udpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  mavlink: tcp:127.0.0.1:{mport}
  mode: CRUISE""")
    # the flag, not the key, asks for the baseline here
    path.write_text(path.read_text().replace("  unaided_baseline: true\n", ""))
    trim = trimmed_controls(sim_setup(load_scenario(path)))
    out = tmp_path / "out"
    sides: list[CommandSide] = []
    peers: list[ArduPilotPeer] = []

    def fresh_peer() -> ArduPilotPeer:
        # a second GPS of type MAVLink in its stored parameters, as an aided flight leaves it
        sides.append(CommandSide("ardupilot", {"GPS2_TYPE": 14.0, "GPS_AUTO_SWITCH": 1.0},
                                 valid_modes=ARDUPLANE_MODES.values()))
        peers.append(ArduPilotPeer(telemetry_url=f"udpout:127.0.0.1:{tport}",
                                   home=(47.0, 8.0, 0.0), frame_rate_hz=50, mavlink=True,
                                   commands=sides[-1], trim=trim,
                                   mavlink_listen=f"tcpin:127.0.0.1:{mport}"))
        return peers[-1].start(f"udp:127.0.0.1:{port}")

    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "run", str(path), "--out", str(out),
         "--unaided-baseline", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True, env={**os.environ, "COLUMNS": "300"})
    try:
        # a person restarts the SITL between the flights: a fresh peer for each
        first = fresh_peer()
        deadline = time.monotonic() + 300
        while not (out / "unaided" / "summary.json").exists() and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.2)
        first.stop()
        second = fresh_peer()
        try:
            stdout, stderr = proc.communicate(timeout=300)
        finally:
            second.stop()
    finally:
        stop_process(proc)
    assert proc.returncode == 0, stdout + stderr
    assert "Traceback" not in stderr
    assert all(p.error is None for p in peers)
    # unaided: its second GPS set off and never used; aided: on, and used in the outage
    assert sides[0].params["GPS2_TYPE"] == 0.0 and peers[0].counters["gps_input_fixes"] == 0
    assert sides[1].params["GPS2_TYPE"] == 14.0 and peers[1].counters["gps_input_fixes"] > 100
    assert "flight 1 of 2: ardupilot unaided (aiding: disabled, the same seed)" in stderr
    assert "flight 2 of 2: ardupilot aided by hilnav" in stderr
    assert "start ardupilot afresh" in stderr
    summary = json.loads((out / "summary.json").read_text())
    ap = summary["autopilot"]
    assert ap["unaided"]["aiding"]["parameters_off"] == ["GPS2_TYPE"]
    # both flights were denied GNSS through the peer's SIM_GPS1_* parameters
    assert ap["outages_not_denied"] == [] and ap["unaided"]["outages_not_denied"] == []
    row = _card(summary)
    _same_figures(row["aided"], ap["outages"][0])
    _same_figures(row["unaided"], ap["unaided"]["outages"][0])
    assert row["aided_over_unaided"] == pytest.approx(
        ap["outages"][0]["horizontal_rmse_m"] / ap["unaided"]["outages"][0]["horizontal_rmse_m"])
    # the printout: the rows of the three estimates and the ratios against their targets
    assert "hilnav vs ArduPilot aided by hilnav vs ArduPilot unaided" in stdout
    rmse = (f"outage 1 (10-40 s): horizontal RMSE (m): hilnav "
            f"{row['hilnav']['horizontal_rmse_m']:.2f} | aided "
            f"{row['aided']['horizontal_rmse_m']:.2f} | unaided "
            f"{row['unaided']['horizontal_rmse_m']:.2f}")
    assert rmse in stdout
    verdict = "met" if row["meets"]["aided_over_unaided"] else "MISSED"
    assert (f"aided / unaided horizontal RMSE: {row['aided_over_unaided']:.2f} (target <= 0.50) "
            f"{verdict}") in stdout


def test_unaided_baseline_needs_aiding_by_hilnav(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("""
name: bad
duration_s: 30
autopilot: {kind: px4, unaided_baseline: true}
""")
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "run", str(path), "--out",
         str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "unaided_baseline compares the autopilot aided by hilnav with it unaided: set " \
           "aiding to hilnav" in proc.stderr
    assert "Traceback" not in proc.stderr
    path.write_text(path.read_text().replace("unaided_baseline: true", "arm: true"))
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "run", str(path), "--out",
         str(tmp_path / "out"), "--unaided-baseline"], capture_output=True, text=True,
        timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "needs autopilot.aiding: hilnav" in proc.stderr
