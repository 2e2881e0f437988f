"""The shadow vehicle seen by real ground-station software over real UDP sockets on loopback:
MAVSDK (its C++ core through the ``mavsdk`` wheel), MAVProxy (the ``mavproxy.py`` program, run
non-interactively, and its fence module's SYS_STATUS logic), QGroundControl's initial connection
sequence played with pymavlink (QGC itself cannot run here), and pymavlink's log tools on the
recorded shadow tlog."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from hil.tlog import iter_messages
from scenarios.cli.up import free_udp_port, stop_process
from tests.helpers.processes import hilnav_process

SHADOW_SYS = 7
BIN = Path(sys.executable).parent


def _start_chain(tmp_path: Path, gcs_url: str, *, speed: str, duration: str,
                 gnss_off: str) -> tuple[Any, Any]:
    port = free_udp_port()
    fusion = hilnav_process(
        "fusion", "--mavlink", f"udpin:127.0.0.1:{port}", "--gcs", gcs_url, "--shadow-sysid",
        str(SHADOW_SYS), "--gcs-tlog", str(tmp_path / "shadow.tlog"), "--idle-exit", "3",
        log=tmp_path / "fusion.log")
    sim = hilnav_process(
        "sim", "live", f"udpout:127.0.0.1:{port}", "--speed", speed, "--duration", duration,
        "--seed", "3", "--gnss-off", gnss_off, "--wait-peer", "30", log=tmp_path / "sim.log")
    return fusion, sim


def test_mavsdk_sees_a_complete_vehicle(tmp_path: Path) -> None:
    """GIVEN a live run (GNSS off 40-60 s sim time) shown to MAVSDK 4.1 WHEN MAVSDK watches THEN
    it discovers the vehicle with all health ok, a 3-D fix with satellites, home, in air and
    turning rates; during the outage the fix is lost, ``is_global_position_ok`` (MAVSDK reads
    the SYS_STATUS GPS bits) goes false and STATUSTEXTs arrive; the mode names reach MAVSDK
    through its MavlinkDirect plugin (AVAILABLE_MODES / CURRENT_MODE).

    Two MAVSDK 4.1 limits, asserted as they are (docs/ground-stations.md, "Which client shows
    what"): ``Telemetry.flight_mode`` is a fixed enum of PX4 / ArduPilot modes, and MAVSDK decodes a
    non-ArduPilot ``custom_mode`` as PX4's (``to_flight_mode_from_custom_mode``): 101-105 have PX4
    main mode 0, so it says UNKNOWN rather than a wrong name. ``Telemetry.battery`` takes
    SYS_STATUS ``voltage_battery`` times 1e-3 without testing the spec's UINT16_MAX = "not
    sent" (``TelemetryImpl::process_sys_status``): the spec-correct "unknown" reads 65.535 V,
    ``remaining_percent`` -1."""
    mavsdk = pytest.importorskip("mavsdk")
    from mavsdk.plugins.mavlink_direct import MavlinkDirect, MavlinkMessage
    from mavsdk.plugins.telemetry import Telemetry

    gcs_port = free_udp_port()
    sdk = mavsdk.Mavsdk(mavsdk.Configuration.create_with_component_type(
        mavsdk.ComponentType.GROUND_STATION))
    assert sdk.add_any_connection(f"udpin://127.0.0.1:{gcs_port}") == (
        mavsdk.ConnectionResult.SUCCESS)
    fusion, sim = _start_chain(tmp_path, f"udpout:127.0.0.1:{gcs_port}", speed="4",
                               duration="90", gnss_off="40:20")
    texts: list[str] = []
    lock = threading.Lock()
    seen: list[dict[str, Any]] = []
    names: dict[int, str] = {}
    current: list[int] = []
    try:
        system = sdk.first_autopilot(30.0)
        assert system is not None, (tmp_path / "fusion.log").read_text()
        tel = Telemetry(system)
        direct = MavlinkDirect(system)

        def on_text(st: Any, _ud: Any) -> None:
            with lock:
                texts.append(st.text)

        def on_available(m: Any, _ud: Any) -> None:
            f = json.loads(m.fields_json)
            with lock:
                names[int(f["custom_mode"])] = f["mode_name"]

        def on_current(m: Any, _ud: Any) -> None:
            with lock:
                current.append(int(json.loads(m.fields_json)["custom_mode"]))

        tel.subscribe_status_text(on_text)
        direct.subscribe_message("AVAILABLE_MODES", on_available)
        direct.subscribe_message("CURRENT_MODE", on_current)
        # what a MAVSDK application does to learn the names: REQUEST_MESSAGE(435), all modes
        direct.send_message(MavlinkMessage("COMMAND_LONG", 0, 0, SHADOW_SYS, 1, json.dumps({
            "target_system": SHADOW_SYS, "target_component": 1,
            "command": int(mavlink2.MAV_CMD_REQUEST_MESSAGE), "confirmation": 0,
            "param1": 435, "param2": 0, "param3": 0, "param4": 0, "param5": 0, "param6": 0,
            "param7": 0})))
        deadline = time.monotonic() + 40.0
        while sim.poll() is None and time.monotonic() < deadline:
            h = tel.health()
            gps = tel.gps_info()
            w = tel.attitude_angular_velocity_body()
            battery = tel.battery()
            with lock:
                mode_name = names.get(current[-1]) if current else None
            seen.append({
                "all_ok": tel.health_all_ok(), "global_ok": h.is_global_position_ok,
                "home_ok": h.is_home_position_ok, "fix": int(gps.fix_type),
                "sats": gps.num_satellites, "in_air": tel.in_air(),
                "mode": tel.flight_mode().name, "mode_name": mode_name,
                "rate_rps": math.sqrt(w.roll_rad_s ** 2 + w.pitch_rad_s ** 2
                                      + w.yaw_rad_s ** 2),
                "voltage_v": battery.voltage_v, "remaining": battery.remaining_percent,
            })
            time.sleep(0.25)
        assert sim.wait(30) == 0, (tmp_path / "sim.log").read_text()
        assert fusion.wait(30) == 0, (tmp_path / "fusion.log").read_text()
    finally:
        for p in (sim, fusion):
            stop_process(p)
        sdk.destroy()
    (tmp_path / "mavsdk_seen.txt").write_text("\n".join(map(str, seen)) + "\n" + str(texts))
    ok = [s for s in seen if s["all_ok"] and s["fix"] >= 3]
    assert len(ok) > 10, seen[-5:]
    assert all(s["sats"] > 0 and s["home_ok"] and s["in_air"] for s in ok)
    # the outage: the fix is lost (GPS_RAW_INT NO_FIX, 0 satellites) after a 3-D fix, MAVSDK's
    # global position health goes false with the SYS_STATUS GPS bit, and comes back
    after = seen[seen.index(ok[0]):]
    lost = [i for i, s in enumerate(after) if s["fix"] == 1 and s["sats"] == 0]
    assert lost, seen
    assert any(not s["global_ok"] for s in after[lost[0]:]), seen
    assert any(s["global_ok"] and s["fix"] >= 3 for s in after[lost[-1]:]), seen
    assert any("GNSS lost" in t for t in texts) and any("GNSS regained" in t for t in texts), texts
    assert any("Nav aligned" in t for t in texts), texts
    assert not any("rejected" in t for t in texts), texts
    assert max(s["rate_rps"] for s in ok) > 0.02  # racetrack turns: ~0.1 rad/s yaw rate
    # the mode: named through MavlinkDirect, UNKNOWN in Telemetry (see the docstring)
    assert names == {101: "ALIGNING", 102: "GNSS", 103: "BRIDGING", 104: "DEAD-RECKONING",
                     105: "FREE-INERTIAL"}
    shown = [s["mode_name"] for s in seen if s["mode_name"] is not None]
    assert "GNSS" in shown and "DEAD-RECKONING" in shown[shown.index("GNSS"):], shown
    assert {s["mode"] for s in seen} == {"UNKNOWN"}
    # the battery: SYS_STATUS says "not sent" (65535 mV, -1 %); MAVSDK 4.1 shows 65.535 V
    read = {(s["voltage_v"], s["remaining"]) for s in seen if not math.isnan(s["voltage_v"])}
    assert read == {(float(np.float32(65.535)), -1.0)}, read

    # pymavlink's log tools read the shadow tlog
    log = str(tmp_path / "shadow.tlog")
    summ = subprocess.run([sys.executable, str(BIN / "mavsummarize.py"), log],
                          capture_output=True, text=True, timeout=60)
    assert summ.returncode == 0, summ.stderr
    (tmp_path / "mavsummarize.txt").write_text(summ.stdout)
    gpx = subprocess.run([sys.executable, str(BIN / "mavtogpx.py"), log],
                         capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert gpx.returncode == 0, gpx.stderr
    # one track point per position frame sent with a fix (mavtogpx pairs GLOBAL_POSITION_INT
    # with the last GPS_RAW_INT's fix type); how many were sent depends on the machine's load
    fix_type, with_fix = 0, 0
    for _t, m in iter_messages(log):
        if m.get_type() == "GPS_RAW_INT":
            fix_type = int(m.fix_type)
        if m.get_type() in ("GPS_RAW_INT", "GLOBAL_POSITION_INT") and fix_type >= 2:
            with_fix += 1
    assert with_fix > 20
    assert (tmp_path / "shadow.tlog.gpx").read_text().count("<trkpt") == with_fix
    ft = subprocess.run([sys.executable, str(BIN / "mavflighttime.py"), log],
                        capture_output=True, text=True, timeout=60)
    assert ft.returncode == 0, ft.stderr
    (tmp_path / "mavflighttime.txt").write_text(ft.stdout)
    assert "Flight time" in ft.stdout, ft.stdout


def _gcs_role() -> LinkRole:
    return LinkRole(system_id=255, component_id=190, mav_type=mavlink2.MAV_TYPE_GCS,
                    autopilot=mavlink2.MAV_AUTOPILOT_INVALID)


def test_mavproxy_fence_logic_and_home_polling(tmp_path: Path) -> None:
    """GIVEN a live run WHEN a ground station polls GET_HOME_POSITION as MAVProxy does and
    feeds every SYS_STATUS to MAVProxy's own fence module logic THEN home is answered, no
    "fence breach" is said, the mode names come from AVAILABLE_MODES, and CURRENT_MODE and
    the HEARTBEAT's custom mode agree."""
    fence_mod = pytest.importorskip("MAVProxy.modules.mavproxy_fence")
    said: list[str] = []

    class _Fence:  # MAVProxy's handle_sys_status, run unbound on a minimal module state
        present, enabled, healthy = False, False, True
        console = type("C", (), {"set_status": staticmethod(lambda *a, **k: None)})()

        def say(self, text: str) -> None:
            said.append(text)

    fence = _Fence()
    acks: dict[int, int] = {}
    got: dict[str, Any] = {"modes": {}, "current": [], "custom": [], "home": 0,
                           "gps_health": [], "battery": []}
    gps = int(mavlink2.MAV_SYS_STATUS_SENSOR_GPS)
    with MavlinkLink("udpin:127.0.0.1:0", _gcs_role()) as gcs:
        fusion, sim = _start_chain(tmp_path, f"udpout:127.0.0.1:{gcs.local_address[1]}",
                                   speed="4", duration="40", gnss_off="20:10")
        try:
            next_poll = 0.0
            deadline = time.monotonic() + 40.0
            while sim.poll() is None and time.monotonic() < deadline:
                for m in gcs.recv(0.05):
                    t = m.get_type()
                    if t == "SYS_STATUS":
                        fence_mod.FenceModule.handle_sys_status(fence, m)
                        got["gps_health"].append(bool(m.onboard_control_sensors_health & gps))
                        got["battery"].append((m.voltage_battery, m.current_battery,
                                               m.battery_remaining))
                    elif t == "COMMAND_ACK":
                        acks[int(m.command)] = int(m.result)
                    elif t == "HOME_POSITION":
                        got["home"] += 1
                    elif t == "AVAILABLE_MODES":
                        got["modes"][int(m.custom_mode)] = m.mode_name
                    elif t == "CURRENT_MODE":
                        got["current"].append(int(m.custom_mode))
                    elif t == "HEARTBEAT" and m.get_srcSystem() == SHADOW_SYS:
                        got["custom"].append(int(m.custom_mode))
                now = time.monotonic()
                if now >= next_poll and got["custom"]:
                    for cmd, p1 in ((mavlink2.MAV_CMD_GET_HOME_POSITION, 0),
                                    (mavlink2.MAV_CMD_REQUEST_MESSAGE, 435)):
                        gcs.send_message(mavlink2.MAVLink_command_long_message(
                            SHADOW_SYS, 1, cmd, 0, p1, 0, 0, 0, 0, 0, 0))
                    next_poll = now + 2.0
            assert sim.wait(30) == 0, (tmp_path / "sim.log").read_text()
        finally:
            for p in (sim, fusion):
                stop_process(p)
    assert "fence breach" not in said, said
    # the GNSS health bit: set, cleared in the outage (20-30 s sim = 5-7.5 s wall), set again
    h = got["gps_health"]
    assert True in h and False in h[h.index(True):], h
    assert True in h[h.index(False, h.index(True)):], h
    assert set(got["battery"]) == {(65535, -1, -1)}
    assert acks.get(int(mavlink2.MAV_CMD_GET_HOME_POSITION)) == mavlink2.MAV_RESULT_ACCEPTED
    assert got["home"] > 0
    assert got["modes"] == {101: "ALIGNING", 102: "GNSS", 103: "BRIDGING",
                            104: "DEAD-RECKONING", 105: "FREE-INERTIAL"}
    assert {102}.issubset(set(got["current"])) and {102}.issubset(set(got["custom"]))
    assert set(got["current"]) - {101} <= set(got["modes"])


def test_mavproxy_program_shows_the_vehicle_its_mode_and_warnings(tmp_path: Path) -> None:
    """GIVEN ``mavproxy.py`` 1.8.75 run non-interactively on the shadow vehicle's UDP stream
    (GNSS off 20-30 s sim time) WHEN the run ends THEN MAVProxy detected the vehicle, said no
    "fence breach", showed the STATUSTEXT warnings (the filter's and the scenario's, relayed
    from the simulator) and a GPS lock, fetched the parameters without an FTP timeout, stopped
    polling GET_HOME_POSITION once a HOME_POSITION came (the shadow tlog holds every answer),
    and showed the mode as the custom-mode number: MAVProxy names ``custom_mode`` only from
    ArduPilot's and PX4's tables and does not read AVAILABLE_MODES (modules/mavproxy_link.py,
    pymavlink ``mode_string_v10``)."""
    mavproxy = BIN / "mavproxy.py"
    if not mavproxy.exists():
        pytest.skip("MAVProxy is not installed (test extra)")
    gcs_port = free_udp_port()
    mp_log = tmp_path / "mavproxy.log"
    mp = subprocess.Popen(
        [sys.executable, str(mavproxy), f"--master=udpin:127.0.0.1:{gcs_port}",
         "--non-interactive", "--nowait", "--state-basedir", str(tmp_path)],
        stdout=mp_log.open("wb"), stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        start_new_session=True, cwd=tmp_path)
    fusion, sim = _start_chain(tmp_path, f"udpout:127.0.0.1:{gcs_port}", speed="4",
                               duration="40", gnss_off="20:10")
    try:
        assert sim.wait(120) == 0, (tmp_path / "sim.log").read_text()
        assert fusion.wait(30) == 0, (tmp_path / "fusion.log").read_text()
        time.sleep(1.0)  # MAVProxy prints what it has received
    finally:
        for p in (sim, fusion, mp):
            stop_process(p)
    out = mp_log.read_text(errors="replace")
    assert f"online system {SHADOW_SYS}" in out, out
    assert "fence breach" not in out, out
    assert "AP: GNSS lost" in out and "AP: GNSS regained" in out, out
    # alignment is said; a fault-free flight's single gate rejections (the gate's false-alarm
    # rate) are no warnings
    assert "AP: Nav aligned" in out, out
    assert "rejected" not in out, out
    # the scenario's own events, relayed from the simulator
    assert "AP: SIM: GNSS off for 10 s" in out and "AP: SIM: GNSS on" in out, out
    assert "GPS lock" in out, out
    # parameters: its FTP download is refused at once (no timeout), the list then arrives
    assert "FTP: request timed out" not in out and "Received 1 parameters" in out, out
    shown = {int(n) for n in re.findall(r"Mode Mode\((\d+)\)", out)}
    assert 102 in shown and shown <= {101, 102, 103, 104, 105}, out
    # the vehicle's side: every GET_HOME_POSITION MAVProxy sent was answered (acks are in the
    # shadow tlog), and once a HOME_POSITION had gone out at most one more was in flight
    get_home = int(mavlink2.MAV_CMD_GET_HOME_POSITION)
    sent: list[tuple[str, int]] = []
    boot_ms: list[int] = []
    for _t, m in iter_messages(tmp_path / "shadow.tlog"):
        if m.get_type() == "GLOBAL_POSITION_INT":
            boot_ms.append(int(m.time_boot_ms))
        if m.get_type() == "HOME_POSITION":
            sent.append(("home", 0))
        elif m.get_type() == "COMMAND_ACK" and int(m.command) == get_home:
            sent.append(("ack", int(m.result)))
    acks = [r for kind, r in sent if kind == "ack"]
    assert acks, sent  # MAVProxy asked at least once
    assert set(acks) <= {int(mavlink2.MAV_RESULT_ACCEPTED),
                         int(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED)}, acks
    first_home = [kind for kind, _r in sent].index("home")
    assert sum(kind == "ack" for kind, _r in sent[first_home:]) <= 1, sent
    # time_boot_ms is simulated time: it ends near the 40 s flown, never beyond (at --speed 4
    # the wall clock since the fusion started stays well below)
    assert boot_ms == sorted(boot_ms) and 30_000 <= boot_ms[-1] <= 40_000, boot_ms[-5:]


def _exchange(gcs: MavlinkLink, send: Any, done: Any, timeout_s: float = 20.0) -> list[Any]:
    """Send ``send`` once (never a retry) and collect the shadow vehicle's frames until
    ``done(frames)``. ``timeout_s`` only bounds a failing test: the property is that the one
    request is answered, not how fast (that depends on the machine's load)."""
    gcs.send_message(send)
    got: list[Any] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got += [m for m in gcs.recv(0.05) if m.get_srcSystem() == SHADOW_SYS]
        if done(got):
            return got
    raise AssertionError(f"no answer to {send.get_type()} within {timeout_s} s: "
                         f"{sorted({m.get_type() for m in got})}")


def _acked(command: int) -> Any:
    return lambda got: any(m.get_type() == "COMMAND_ACK" and int(m.command) == command
                           for m in got)


def _ack_of(got: list[Any], command: int) -> Any:
    return next(m for m in got if m.get_type() == "COMMAND_ACK" and int(m.command) == command)


def test_qgc_initial_connection_sequence_is_answered(tmp_path: Path) -> None:
    """GIVEN a live run WHEN a ground station plays QGroundControl's initial connection sequence
    over UDP (src/Vehicle/InitialConnectStateMachine: AUTOPILOT_VERSION, PROTOCOL_VERSION,
    standard modes, component metadata, parameters, mission; then the home position), sending
    each request once, THEN every step gets its final answer, so QGC completes its connection
    without waiting out a timeout and retrying: the requested messages, or an immediate
    MAV_RESULT_UNSUPPORTED for what the vehicle does not have (PROTOCOL_VERSION: not in
    pymavlink's dialects; component metadata: none), one complete parameter list, an empty
    mission; no geofence / rally capability claimed, so QGC skips those two steps; and the
    mode name QGC derives (custom_mode -> AVAILABLE_MODES name) is the navigation mode."""
    req = int(mavlink2.MAV_CMD_REQUEST_MESSAGE)

    def request_message(msg_id: int, param2: float = 0.0) -> Any:
        return mavlink2.MAVLink_command_long_message(
            SHADOW_SYS, 1, req, 0, msg_id, param2, 0, 0, 0, 0, 0)

    with MavlinkLink("udpin:127.0.0.1:0", _gcs_role()) as gcs:
        fusion, sim = _start_chain(tmp_path, f"udpout:127.0.0.1:{gcs.local_address[1]}",
                                   speed="4", duration="60", gnss_off="100:10")
        try:
            deadline = time.monotonic() + 30.0
            heartbeat = None
            while heartbeat is None and time.monotonic() < deadline:
                heartbeat = next((m for m in gcs.recv(0.1) if m.get_type() == "HEARTBEAT"
                                  and m.get_srcSystem() == SHADOW_SYS), None)
            assert heartbeat is not None, (tmp_path / "fusion.log").read_text()
            assert heartbeat.autopilot == mavlink2.MAV_AUTOPILOT_GENERIC  # QGC: generic plugin

            # 1. AUTOPILOT_VERSION: capabilities decide QGC's later steps
            got = _exchange(gcs, request_message(148),
                            lambda g: any(m.get_type() == "AUTOPILOT_VERSION" for m in g))
            assert _ack_of(got, req).result == mavlink2.MAV_RESULT_ACCEPTED
            caps = next(m for m in got if m.get_type() == "AUTOPILOT_VERSION").capabilities
            assert caps & mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            assert not caps & (mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                               | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY)
            # 2. PROTOCOL_VERSION (QGC 4.x; also the older MAV_CMD_REQUEST_PROTOCOL_VERSION)
            got = _exchange(gcs, request_message(300), _acked(req))
            assert _ack_of(got, req).result == mavlink2.MAV_RESULT_UNSUPPORTED
            old = int(mavlink2.MAV_CMD_REQUEST_PROTOCOL_VERSION)
            got = _exchange(gcs, mavlink2.MAVLink_command_long_message(
                SHADOW_SYS, 1, old, 0, 1, 0, 0, 0, 0, 0, 0), _acked(old))
            assert _ack_of(got, old).result == mavlink2.MAV_RESULT_UNSUPPORTED
            # 3. standard modes: all at once (param2 = 0), done at mode_index == number_modes
            got = _exchange(gcs, request_message(435), lambda g: any(
                m.get_type() == "AVAILABLE_MODES" and m.mode_index == m.number_modes
                for m in g))
            assert _ack_of(got, req).result == mavlink2.MAV_RESULT_ACCEPTED
            names = {int(m.custom_mode): m.mode_name for m in got
                     if m.get_type() == "AVAILABLE_MODES"}
            assert names == {101: "ALIGNING", 102: "GNSS", 103: "BRIDGING",
                             104: "DEAD-RECKONING", 105: "FREE-INERTIAL"}
            # 4. component metadata, then the older component information: none
            for msg_id in (397, 395):
                got = _exchange(gcs, request_message(msg_id), _acked(req))
                assert _ack_of(got, req).result == mavlink2.MAV_RESULT_UNSUPPORTED
            # 5. parameters: one complete list (QGC asks every component)
            got = _exchange(gcs, mavlink2.MAVLink_param_request_list_message(SHADOW_SYS, 0),
                            lambda g: (vals := [m for m in g if m.get_type() == "PARAM_VALUE"])
                            != [] and len({m.param_index for m in vals}) == vals[0].param_count)
            vals = [m for m in got if m.get_type() == "PARAM_VALUE"]
            assert {m.param_index for m in vals} == set(range(vals[0].param_count))
            # 6. mission: zero items; QGC acknowledges the empty list
            got = _exchange(gcs, mavlink2.MAVLink_mission_request_list_message(
                SHADOW_SYS, 1, 0), lambda g: any(m.get_type() == "MISSION_COUNT" for m in g))
            count = next(m for m in got if m.get_type() == "MISSION_COUNT")
            assert (count.count, count.mission_type) == (0, 0)
            assert (count.target_system, count.target_component) == (255, 190)
            gcs.send_message(mavlink2.MAVLink_mission_ack_message(SHADOW_SYS, 1, 0, 0))
            # a command the vehicle does not implement is refused at once, not ignored
            interval = int(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL)
            got = _exchange(gcs, mavlink2.MAVLink_command_long_message(
                SHADOW_SYS, 1, interval, 0, 33, 100000, 0, 0, 0, 0, 0), _acked(interval))
            assert _ack_of(got, interval).result == mavlink2.MAV_RESULT_UNSUPPORTED
            # then the home position (QGC asks until it has one: refused while aligning)
            home = None
            results = []
            while home is None and time.monotonic() < deadline + 30.0:
                got = _exchange(gcs, request_message(242), _acked(req))
                results.append(int(_ack_of(got, req).result))
                got += [m for m in gcs.recv(0.2) if m.get_srcSystem() == SHADOW_SYS]
                home = next((m for m in got if m.get_type() == "HOME_POSITION"), None)
            assert home is not None, results
            assert set(results) <= {int(mavlink2.MAV_RESULT_ACCEPTED),
                                    int(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED)}
            assert results[-1] == mavlink2.MAV_RESULT_ACCEPTED and home.latitude != 0
            # the flight mode QGC shows: FirmwarePlugin::flightMode's custom_mode -> name
            shown = set()
            end = time.monotonic() + 3.0
            while time.monotonic() < end:
                shown |= {names.get(int(m.custom_mode), f"Custom:0x{int(m.custom_mode):x}")
                          for m in gcs.recv(0.1) if m.get_type() == "HEARTBEAT"
                          and m.get_srcSystem() == SHADOW_SYS}
            assert shown == {"GNSS"}, shown
            assert sim.wait(60) == 0, (tmp_path / "sim.log").read_text()
        finally:
            for p in (sim, fusion):
                stop_process(p)
