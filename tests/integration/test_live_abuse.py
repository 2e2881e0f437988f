"""A hostile sender on the live chain's MAVLink port, over real loopback sockets.

`tests/hil/test_service.py` floods a fusion that has already bound to the simulator with valid
frames from system 99, and `tests/integration/test_fuzz.py` feeds hostile values from the
simulator's own address through decoder + filter. This test covers what neither does: a sender
that speaks *before* the simulator (so it could be the first source the fusion sees), from the
system ids next to the simulator's (0 and 2) and from its components (sensor, truth), with
valid flight data 50 km away, forged truth, lockstep heartbeats and CRC-valid frames with
timestamps an hour ahead or behind, 0 and 2^64 - 1, for the whole flight.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from hil.codec import SENSOR_COMPONENT_ID, TRUTH_COMPONENT_ID, Encoder, mavlink2
from hil.link import LOCKSTEP_CUSTOM_MODE
from scenarios.cli.app import app
from scenarios.cli.up import wait_gone
from sim.samples import GnssFix, ImuSample
from tests.helpers.hostile import hostile_frame

_FUSION_PORT = re.compile(r"^fusion\s+pid (\d+): MAVLink in udpin:127\.0\.0\.1:(\d+)")
_PID = re.compile(r"^(fusion|monitor|sim)\s+pid (\d+):", re.M)
#: The neighbours of the simulator's address (system 1, components 200 sensor / 25 truth).
HOSTILE_SOURCES = ((2, SENSOR_COMPONENT_ID), (0, SENSOR_COMPONENT_ID), (2, TRUTH_COMPONENT_ID))


def _attack(port: int, stop: threading.Event, sent: list[int]) -> None:
    """Send until ``stop``: ~4,000 frames/s, a mix of plausible sensor data 50 km away,
    forged truth, lockstep heartbeats and CRC-valid frames with hostile values and times."""
    rng = np.random.default_rng(13)
    enc = Encoder(system_id=2)  # the simulator's components, the next system id
    packers = [mavlink2.MAVLink(None, srcSystem=s, srcComponent=c) for s, c in HOSTILE_SOURCES]
    fix = GnssFix(time_us=0, lat_rad=0.83, lon_rad=0.15, alt_msl_m=500.0,
                  v_ned_mps=np.zeros(3), eph_m=1.0, epv_m=1.0, speed_accuracy_mps=0.1)
    heartbeat = mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_GENERIC, mavlink2.MAV_AUTOPILOT_INVALID, 0, LOCKSTEP_CUSTOM_MODE,
        mavlink2.MAV_STATE_ACTIVE, 3)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        k = 0
        while not stop.is_set():
            mav = packers[k % len(packers)]
            t = 1_000_000 + 5000 * k
            kind = k % 10
            if kind < 4:
                frame = enc.sensors(imu=ImuSample(t, 0.005, np.array([0.0, 0.0, -9.8]),
                                                  np.zeros(3)))
            elif kind == 4:
                frame = enc.gnss(dataclasses.replace(fix, time_us=t))
            elif kind == 5:
                frame = heartbeat.pack(mav)
            elif kind == 6:  # forged truth 50 km away, at the simulator's truth component
                frame = mavlink2.MAVLink_hil_state_quaternion_message(
                    t, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 475_000_000, 86_000_000, 500_000,
                    0, 0, 0, 0, 0, 0, 0, 0).pack(packers[2])
            else:
                frame = hostile_frame(rng, t, mav)
            s.sendto(frame, ("127.0.0.1", port))
            sent[0] += 1
            k += 1
            if k % 40 == 0:
                time.sleep(0.01)


def test_a_hostile_sender_speaking_before_the_simulator_costs_the_live_run_nothing(
    tmp_path: Path,
) -> None:
    """GIVEN `hilnav up --lockstep` and a hostile sender that starts flooding the fusion's
    port as soon as `up` names it (before the simulator's first frame) WHEN the flight ends
    THEN the fusion bound to the simulator (system 1), its reply address never left the
    simulator (one peer learned), none of the hostile frames was fused or scored, no
    legitimate frame was lost, and the live scorecard equals `hilnav replay` of the sim's
    recording (accuracy unchanged: the same numbers)."""
    out = tmp_path / "up"
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "up", "--duration", "60", "--speed", "20",
         "--lockstep", "--no-monitor", "--out", str(out)],  # settle: 15 s (a quarter)
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"},
    )
    stop = threading.Event()
    sent = [0]
    attacker: threading.Thread | None = None
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            m = _FUSION_PORT.match(line)
            if m and attacker is None:
                attacker = threading.Thread(target=_attack, args=(int(m.group(2)), stop, sent),
                                            daemon=True)
                attacker.start()
        proc.wait(240)
    finally:
        stop.set()
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)
    if attacker is not None:
        attacker.join(5.0)
    text = "".join(lines)
    assert proc.returncode == 0, text
    pids = {name: int(pid) for name, pid in _PID.findall(text)}
    assert wait_gone(list(pids.values())), "a child outlived `hilnav up`"
    assert attacker is not None and sent[0] > 20_000, sent  # the attack ran the whole flight
    assert "sim finished (exit 0)" in text, text

    live = json.loads((out / "summary.json").read_text())
    mav = live["live"]["links"]["mavlink"]
    assert live["live"]["source_system"] == 1
    # every hostile frame that reached the socket was refused by its source; the kernel may
    # drop some datagrams of the flood, never the simulator's (lockstep: it waits for acks)
    assert mav["wrong_source"] >= sent[0] // 2, (mav, sent)
    assert mav["udp_peer_changes"] == 1, mav  # the simulator's address, learned once
    assert live["live"]["lost_frames"] == 0
    assert live["live"]["truth_from_other_components"] == 0
    assert live["sim_duration_s"] >= 59.0

    result = CliRunner().invoke(app, ["replay", str(out / "run.tlog"), "--out",
                                      str(tmp_path / "replay"), "--settle", "15"])
    assert result.exit_code == 0, result.output
    ref = json.loads((tmp_path / "replay" / "summary.json").read_text())
    assert ref["gnss_on"]["horizontal_rmse_m"] < 5.0  # a real flight was scored
    for key in ("gnss_on", "nees", "outages", "containment_3sigma"):
        assert live[key] == ref[key], key
    assert live["health"]["filter"] == ref["health"]["filter"]


def test_hostile_stamps_from_the_simulators_own_address_cannot_stop_the_lockstep(
    tmp_path: Path,
) -> None:
    """GIVEN `hilnav fusion` fed by `hilnav sim live URL --lockstep` WHEN a sender that forges
    the simulator's own address (system 1, component 200; no signing) slips in HIL_SENSOR
    frames stamped 2^64 - 1 us and an hour ahead, ten a second THEN the fusion keeps
    acknowledging the simulator's real time (a stamp of 2^64 - 1 us used to kill its reader
    thread: TIMESYNC carries int64 ns; an hour-ahead stamp would be the simulator's newest
    acknowledgement for good), the flight runs to its end and the scorecard is written."""
    from scenarios.cli.up import free_udp_port
    from tests.helpers.processes import finish_lockstep_chain, lockstep_chain

    port = free_udp_port()
    fusion, sim = lockstep_chain(tmp_path, port, speed="20", duration_s="40", seed="8",
                                 settle_s="10")
    stop = threading.Event()
    sent = [0]

    def spoof() -> None:
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=SENSOR_COMPONENT_ID)
        rec = tmp_path / "run.tlog"
        while not stop.is_set() and (not rec.exists() or rec.stat().st_size < 100_000):
            time.sleep(0.05)  # once the fusion bound to the simulator and lockstep runs
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            k = 0
            while not stop.is_set():
                t = 2**64 - 1 if k % 2 == 0 else 3_600_000_000 + 100_000 * k
                frame = mavlink2.MAVLink_hil_sensor_message(
                    t, 0.0, 0.0, -9.8, 0.0, 0.0, 0.0, 0.2, 0.0, 0.4, 1013.0, 0.0, 0.0, 20.0,
                    0x1FFF, 0).pack(mav)
                s.sendto(frame, ("127.0.0.1", port))
                sent[0] += 1
                k += 1
                time.sleep(0.1)

    spoofer = threading.Thread(target=spoof, daemon=True)
    spoofer.start()
    finish_lockstep_chain(tmp_path, fusion, sim, stop, spoofer)
    assert "Traceback" not in (tmp_path / "fusion.log").read_text()
    live = json.loads((tmp_path / "live" / "summary.json").read_text())
    assert sent[0] >= 10
    assert live["sim_duration_s"] >= 39.0
    assert live["live"]["lockstep_acks_withheld"] >= sent[0] // 2
    assert live["health"]["filter"]["time_quarantined"] >= sent[0] // 2
