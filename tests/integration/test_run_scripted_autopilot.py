"""``hilnav run`` scripting the autopilot (parameters, mission, arm, mode) over its telemetry
link, against the ArduPilot and PX4 protocol peers (tests/helpers/ardupilot_peer.py,
px4_peer.py, answering as tests/helpers/autopilot_commands.py): the script completes while the
simulator keeps stepping, the trim is held until the autopilot is armed and in a flying mode,
the times reach summary.json, and a step the autopilot does not confirm fails the run with a
sentence naming it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
import yaml

from hil.autopilot.modes import ARDUPLANE_MODES, PX4_MODES
from hil.autopilot.param_file import read_param_file
from scenarios.cli.up import free_udp_port, stop_process
from scenarios.runner import AutopilotAbsent, run_scenario, sim_setup
from scenarios.schema import LIBRARY_DIR, load_scenario
from tests.helpers.ardupilot_peer import ArduPilotPeer, trimmed_controls
from tests.helpers.autopilot_commands import CommandSide
from tests.helpers.processes import free_tcp_port
from tests.helpers.px4_peer import PeerPlan as Px4Plan
from tests.helpers.px4_peer import Px4Peer

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"
MISSION = """
  mission:
    - {type: waypoint, north_m: 3000, east_m: 0, alt_m: 0}
    - {type: loiter, radius_m: 400, turns: 1}
    - {type: rtl}
"""


def _scenario(tmp_path: Path, autopilot: str, duration_s: float = 40.0) -> Path:
    path = tmp_path / "scripted.yaml"
    path.write_text(f"""
name: scripted
duration_s: {duration_s}
sim_rate_hz: 50
seed: 4
sensors:
  imu: {{preset: industrial-mems, rate_hz: 50}}
start: {{lat_deg: 47.0, lon_deg: 8.0, alt_msl_m: 1000, heading_deg: 0, airspeed_mps: 50}}
autopilot:
{autopilot}""")
    return path


def _arduplane_run(tmp_path: Path, side: CommandSide, script: str,
                   duration_s: float = 40.0) -> tuple[dict[str, Any], ArduPilotPeer]:
    port, tport = free_udp_port(), free_udp_port()
    (tmp_path / "c172.parm").write_text("ARSPD_SKIP_CAL 1\nTRIM_ARSPD_CM 5000\n")
    path = _scenario(tmp_path, f"""  kind: ardupilot
  link: udpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  connect_timeout_s: 30
  stall_timeout_s: 20
{script}""", duration_s)
    scn = load_scenario(path)
    peer = ArduPilotPeer(telemetry_url=f"udpout:127.0.0.1:{tport}", home=(47.0, 8.0, 0.0),
                         trim=trimmed_controls(sim_setup(scn)), frame_rate_hz=50,
                         commands=side)
    return _fly(scn, peer, port, tmp_path / "out"), peer


def _fly(scn: Any, peer: ArduPilotPeer, port: int, out: Path) -> dict[str, Any]:
    """Fly ``scn`` against ``peer`` (started on the simulator's UDP ``port`` once hilnav
    listens, stopped at the end); the run's summary."""
    starter = threading.Timer(0.3, lambda: peer.start(f"udp:127.0.0.1:{port}"))
    starter.start()
    try:
        result = run_scenario(scn, out, reports=False, tlog=False)
    finally:
        starter.cancel()
        peer.stop()
    assert peer.error is None
    return result.summary


def _arduplane_side(**kwargs: Any) -> CommandSide:
    return CommandSide("ardupilot", {"ARSPD_SKIP_CAL": 0.0, "TRIM_ARSPD_CM": 2200.0},
                       valid_modes=ARDUPLANE_MODES.values(), **kwargs)


def test_arduplane_is_scripted_and_the_trim_held_until_it_flies(tmp_path: Path) -> None:
    side = _arduplane_side(prearm_ok_s=4.0)
    summary, peer = _arduplane_run(tmp_path, side, """  params: c172.parm
  arm: true
  mode: AUTO
""" + MISSION)
    assert "failures" not in summary, summary.get("failures")
    ap = summary["autopilot"]
    script = ap["script"]
    assert [s["status"] for s in script["steps"]] == ["done"] * 5
    assert script["params_confirmed"] == 2 and side.params["TRIM_ARSPD_CM"] == 5000.0
    # home slot + 3 items, uploaded with MISSION_REQUEST_INT
    assert side.mission_accepted and len(side.mission) == 4
    # refused while its pre-arm checks failed, armed once they passed, then AUTO
    assert side.arm_attempts >= 2 and side.armed_at_s is not None and side.armed_at_s >= 4.0
    assert ap["armed_s"] is not None and ap["armed_s"] >= side.armed_at_s
    assert ap["mode_reached_s"] >= ap["armed_s"]
    assert side.custom_mode == ARDUPLANE_MODES["AUTO"]
    # armed in MANUAL is still neutral surfaces: the hold lasted until AUTO was reported
    assert ap["trim_released_s"] >= side.mode_log[0][0]
    assert ap["trim_released_s"] < ap["mode_reached_s"] + 1.0
    assert ap["counters"]["disarmed_controls"] > 0
    assert peer.counters["frames"] > 1500  # the simulator stepped while the script waited


def test_arduplane_that_never_arms_fails_the_run_quoting_its_prearm_reason(
        tmp_path: Path) -> None:
    side = _arduplane_side(prearm_ok_s=1e9, prearm_reason="Airspeed 1 not healthy")
    # an outage the flight never reaches: scored as not reached, not a crash of the scoring
    summary, _ = _arduplane_run(tmp_path, side, """  arm: true
  mode: CRUISE
  timeouts: {arm_s: 6}
events:
  - {type: gnss_outage, at: 200, duration: 60}
""", duration_s=300.0)
    assert summary["passed"] is False
    assert [e["type"] for e in summary["events_not_reached"]] == ["gnss_outage"]
    (failure,) = summary["failures"]
    assert failure.startswith("ArduPilot did not arm within 6 s")
    assert "'PreArm: Airspeed 1 not healthy'" in failure
    # the run stopped there (6 s of simulated time and at least 2 wall seconds) and what
    # flew was scored
    assert 6.0 < summary["sim_duration_s"] < 300.0
    assert summary["autopilot"]["connected"] and summary["autopilot"]["stalled"] is None
    assert summary["autopilot"]["script"]["steps"][3]["status"] == "failed"
    assert summary["autopilot"]["trim_released_s"] is None


def test_arduplane_rejecting_a_parameter_fails_the_run_naming_it(tmp_path: Path) -> None:
    side = _arduplane_side(reject_params={"TRIM_ARSPD_CM"})
    with pytest.raises(AutopilotAbsent) as err:  # exit 1, at once: nothing flew to score
        _arduplane_run(tmp_path, side, "  params: c172.parm\n  arm: true\n")
    failure = str(err.value)
    assert "nothing to score" in failure
    assert f"rejected parameter TRIM_ARSPD_CM = 5000 ({tmp_path / 'c172.parm'}:2)" in failure
    assert "Param write denied" in failure
    assert not side.armed  # nothing after the failed step was commanded


def _px4_run(tmp_path: Path, side: CommandSide, script: str,
             reports: bool = False) -> tuple[dict[str, Any], Px4Peer]:
    port, tport = free_tcp_port(), free_udp_port()
    (tmp_path / "c172.params").write_text("1\t1\tFW_AIRSPD_TRIM\t45\t9\n1\t1\tNAV_DLL_ACT\t0\t6\n")
    path = _scenario(tmp_path, f"""  kind: px4
  link: tcpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  actuator_map: {STANDARD_PLANE}
  connect_timeout_s: 30
  stall_timeout_s: 20
{script}""")
    scn = load_scenario(path)
    peer = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}",
                   Px4Plan(turns=()), commands=side)
    with peer:
        result = run_scenario(scn, tmp_path / "out", reports=reports, tlog=False)
    assert peer.errors == []
    return result.summary, peer


def test_px4_is_scripted_with_its_integer_parameters_and_hold(tmp_path: Path) -> None:
    side = CommandSide("px4", {"FW_AIRSPD_TRIM": 15.0, "NAV_DLL_ACT": 2.0},
                       int_params={"NAV_DLL_ACT"}, custom_mode=PX4_MODES["MANUAL"],
                       valid_modes=PX4_MODES.values(), prearm_ok_s=8.0, legacy_requests=True)
    summary, _ = _px4_run(tmp_path, side, """  params: c172.params
  arm: true
  mode: HOLD
""" + MISSION, reports=True)
    assert "failures" not in summary, summary.get("failures")
    ap = summary["autopilot"]
    assert [s["status"] for s in ap["script"]["steps"]] == ["done"] * 5
    assert side.params == {"FW_AIRSPD_TRIM": 45.0, "NAV_DLL_ACT": 0.0}
    assert len(side.mission) == 3 and ap["script"]["counters"]["mission_legacy_requests"] == 3
    assert side.custom_mode == PX4_MODES["HOLD"]
    assert ap["armed_s"] >= 8.0 and ap["mode_reached_s"] >= ap["armed_s"]
    assert ap["trim_released_s"] >= ap["armed_s"]
    report = (tmp_path / "out" / "report.html").read_text()
    assert "Scripted: armed at " in report
    assert '<td class="l">mission</td><td class="l">done</td>' in report


def test_px4_that_never_reaches_the_mode_fails_the_run(tmp_path: Path) -> None:
    side = CommandSide("px4", {}, custom_mode=PX4_MODES["MANUAL"], never_reach_mode=True)
    summary, _ = _px4_run(tmp_path, side, "  arm: true\n  mode: MISSION\n"
                          "  timeouts: {mode_s: 4}\n")
    (failure,) = summary["failures"]
    # the mode step's timeout, or (on a machine slow enough that the wall-clock minimum of the
    # earlier steps ate the flight) the flight's end: either sentence names the mode it reports
    assert failure.startswith(("PX4 did not reach the mode within 4 s (it reports MANUAL)",
                               "the flight ended at 40.0 s while PX4 was still not in the "
                               "scripted mode (it reports MANUAL)"))
    # armed in MANUAL (zero outputs): the trim was never released
    assert summary["autopilot"]["trim_released_s"] is None


def test_arduplane_aided_by_hilnav_navigates_on_hilnavs_estimate_in_the_outage(
        tmp_path: Path) -> None:
    side = _arduplane_side()
    side.params.update({"GPS2_TYPE": 0.0, "GPS_AUTO_SWITCH": 0.0})
    port, tport = free_udp_port(), free_udp_port()
    peer = ArduPilotPeer(telemetry_url=f"udpout:127.0.0.1:{tport}", home=(47.0, 8.0, 0.0),
                         frame_rate_hz=50, mavlink=True, commands=side)
    path = _scenario(tmp_path, f"""  kind: ardupilot
  link: udpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  mavlink: {peer.mavlink_url}
  connect_timeout_s: 30
  stall_timeout_s: 20
  aiding: hilnav
  arm: true
  mode: CRUISE
events:
  - {{type: gnss_outage, at: 70, duration: 30}}
""", duration_s=110.0)
    scn = load_scenario(path)
    peer.trim = list(trimmed_controls(sim_setup(scn)))
    summary = _fly(scn, peer, port, tmp_path / "out")
    assert "failures" not in summary, summary.get("failures")
    ap = summary["autopilot"]
    # the parameters for it were set by the script's parameter step
    assert (side.params["GPS2_TYPE"], side.params["GPS_AUTO_SWITCH"]) == (14.0, 1.0)
    assert ap["script"]["params_confirmed"] == 2
    assert ap["aiding"]["message"] == "GPS_INPUT" and ap["aiding"]["frames_sent"] > 300
    # its own GPS was off for 30 s: it navigated on hilnav's GPS_INPUT at 5 Hz meanwhile
    assert 100 <= peer.counters["gps_input_fixes"] <= 160
    (mine,) = summary["outages"]
    (theirs,) = ap["outages"]
    assert theirs["horizontal_rmse_m"] <= 1.5 * mine["horizontal_rmse_m"] + 3.0


def test_hilnav_run_exits_1_with_the_sentence_when_px4_refuses_to_arm(tmp_path: Path) -> None:
    port, tport = free_tcp_port(), free_udp_port()
    path = _scenario(tmp_path, f"""  kind: px4
  link: tcpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  actuator_map: {STANDARD_PLANE}
  arm: true
  mode: MISSION
  timeouts: {{arm_s: 5}}
""", duration_s=300.0)
    side = CommandSide("px4", {}, custom_mode=PX4_MODES["MANUAL"], prearm_ok_s=1e9)
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "run", str(path), "--out",
         str(tmp_path / "out"), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True, env={**os.environ, "COLUMNS": "300"})
    try:
        with Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}", Px4Plan(turns=()),
                     commands=side):
            out, err = proc.communicate(timeout=300)
    finally:
        stop_process(proc)
    assert proc.returncode == 1, out + err
    sentence = ("PX4 did not arm within 5 s: last COMMAND_ACK MAV_RESULT_TEMPORARILY_REJECTED "
                "after ")
    assert sentence in err and ("its last message: 'Preflight Fail: Airspeed too high - check "
                                "airspeed calibration'") in err
    assert "Traceback" not in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["passed"] is False and summary["failures"][0].startswith(sentence)


def test_the_library_arduplane_mission_script_runs_against_the_peer(tmp_path: Path) -> None:
    library = LIBRARY_DIR / "autopilot"
    data = yaml.safe_load((library / "arduplane-mission-gnss-outage.yaml").read_text())
    params = read_param_file(library / "arduplane-c172x.parm")
    port, tport = free_udp_port(), free_udp_port()
    side = CommandSide("ardupilot", {p.name: 0.0 for p in params},
                       valid_modes=ARDUPLANE_MODES.values(), prearm_ok_s=3.0)
    peer = ArduPilotPeer(telemetry_url=f"udpout:127.0.0.1:{tport}", home=(47.0, 8.0, 0.0),
                         frame_rate_hz=200, mavlink=True, commands=side)
    # the library's script as it stands; only its ports, length and timeline are the test's
    data["autopilot"].update(link=f"udpin:127.0.0.1:{port}", telemetry=f"udpin:127.0.0.1:{tport}",
                             mavlink=peer.mavlink_url, params=str(library / "arduplane-c172x.parm"))
    data.update(duration_s=30, events=[], criteria=[])
    path = tmp_path / "library.yaml"
    path.write_text(yaml.safe_dump(data))
    scn = load_scenario(path)
    peer.trim = list(trimmed_controls(sim_setup(scn)))
    summary = _fly(scn, peer, port, tmp_path / "out")
    assert "failures" not in summary, summary.get("failures")
    script = summary["autopilot"]["script"]
    assert [s["status"] for s in script["steps"]] == ["done"] * 5
    # the autopilot stores float32: each value is read back to float32 precision
    assert side.params == pytest.approx({p.name: p.value for p in params}, rel=1e-6)
    assert len(side.mission) == 8 and side.custom_mode == ARDUPLANE_MODES["AUTO"]  # home + 7


def test_px4_aided_by_hilnav_takes_its_odometry_as_external_vision(tmp_path: Path) -> None:
    side = CommandSide("px4", {"EKF2_EV_CTRL": 0.0}, int_params={"EKF2_EV_CTRL"},
                       custom_mode=PX4_MODES["MANUAL"], valid_modes=PX4_MODES.values())
    port, tport = free_tcp_port(), free_udp_port()
    path = _scenario(tmp_path, f"""  kind: px4
  link: tcpin:127.0.0.1:{port}
  telemetry: udpin:127.0.0.1:{tport}
  actuator_map: {STANDARD_PLANE}
  connect_timeout_s: 30
  stall_timeout_s: 20
  aiding: hilnav
  arm: true
  mode: HOLD
events:
  - {{type: gnss_outage, at: 70, duration: 30}}
""", duration_s=110.0)
    peer = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tport}", Px4Plan(turns=()),
                   commands=side)
    with peer:
        summary = run_scenario(load_scenario(path), tmp_path / "out", reports=False,
                               tlog=False).summary
    assert peer.errors == []
    assert "failures" not in summary, summary.get("failures")
    ap = summary["autopilot"]
    assert side.params["EKF2_EV_CTRL"] == 5.0  # set by the script, an INT32 sent byte-wise
    assert ap["aiding"]["message"] == "ODOMETRY" and ap["aiding"]["frames_sent"] > 2000
    # through the 30 s outage it positioned itself on hilnav's ODOMETRY at ~30 Hz
    assert 600 <= peer.counters["ev_fixes"] <= 1000
    # aided, its error through the outage stays at its (simple) estimator's GNSS-on level;
    # unaided, the peer's dead reckoning grows to ~30 m RMSE over these 30 s
    (theirs,) = ap["outages"]
    assert theirs["horizontal_rmse_m"] <= ap["gnss_on"]["horizontal_rmse_m"], (
        theirs, ap["gnss_on"])
