"""PX4 in the loop over real loopback TCP: hilnav's simulator side (hil.autopilot.px4) against
the PX4 protocol peer (tests/helpers/px4_peer.py), which flies the JSBSim aircraft from its own
estimate through the actuator map."""

from __future__ import annotations

import math
import socket
import struct
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from hil.autopilot import AutopilotFlown, fly_with_autopilot
from hil.autopilot.actuators import ActuatorMap
from hil.autopilot.px4 import Px4Backend, WrongProtocol
from hil.codec import mavlink2
from hil.pipeline import SimSetup, SimStep
from tests.helpers.px4_peer import PeerPlan, Px4Peer

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"
RATE_HZ = 50.0


def _yaw_deg(step: SimStep) -> float:
    w, x, y, z = (float(v) for v in step.truth.q_nb)
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def _fly_with_peer(setup: SimSetup, *, amap: ActuatorMap | None = None,
                   stall_timeout_s: float = 20.0, **peer_options: Any
                   ) -> tuple[AutopilotFlown, Px4Peer]:
    """Fly ``setup`` with a Px4Backend on a free loopback port and a peer dialling it."""
    with Px4Backend("tcpin:127.0.0.1:0", actuator_map=amap) as backend:
        with Px4Peer(f"tcp:127.0.0.1:{backend.local_address[1]}", **peer_options) as peer:
            flown = fly_with_autopilot(setup, backend, stall_timeout_s=stall_timeout_s)
    assert peer.errors == []
    return flown, peer


def _telemetry_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.0)
    return sock


def _drain_telemetry(sock: socket.socket) -> list[object]:
    mav = mavlink2.MAVLink(None)
    out: list[object] = []
    while True:
        try:
            data = sock.recv(65536)
        except BlockingIOError:
            return out
        out.extend(m for m in mav.parse_buffer(data) or [] if m.get_type() != "BAD_DATA")


def test_px4_flies_a_turn_through_a_gnss_outage_in_lockstep() -> None:
    # GIVEN 150 s with GNSS off from 50 s to 110 s, and a 90 deg turn ordered at 60 s
    setup = SimSetup.build(duration_s=150.0, rate_hz=RATE_HZ, seed=5, gnss_off=["50:60"])
    amap = ActuatorMap.load(STANDARD_PLANE)
    altitudes: list[float] = []
    yaws: dict[int, float] = {}

    def on_step(step: SimStep) -> None:
        altitudes.append(step.truth.alt_msl_m)
        if step.truth.time_us % 1_000_000 == 0:
            yaws[step.truth.time_us // 1_000_000] = _yaw_deg(step)

    tel = _telemetry_socket()
    with tel, Px4Backend("tcpin:127.0.0.1:0", actuator_map=amap) as backend:
        port = backend.local_address[1]
        peer = Px4Peer(f"tcp:127.0.0.1:{port}", f"udpout:127.0.0.1:{tel.getsockname()[1]}",
                       PeerPlan(turns=((60.0, 90.0),)))
        with peer:
            # WHEN the peer flies it
            flown = fly_with_autopilot(setup, backend, on_step=on_step, stall_timeout_s=20.0)
        telemetry = _drain_telemetry(tel)
    assert peer.errors == []
    assert flown.connected and flown.stalled is None and flown.ended is None
    assert flown.sim_duration_s == pytest.approx(150.0)
    c = flown.counters
    # THEN lockstep: each step after PX4's boot flew exactly one controls message; PX4 boots on
    # our sensors (boot_sensors=30, then controls sent disarmed: the trim held)
    assert c["boot_steps"] == peer.boot_sensors + 1
    # (the loop asks for controls once more after the last step, then finds the end)
    assert flown.steps + 1 == c["boot_steps"] + c["controls"]
    assert flown.steps == peer.counters["sensors"] and c["controls"] == peer.counters["controls"]
    assert c["lockstep_controls"] == c["controls"] and c["disarmed_controls"] == 20
    # the trim hold ended with PX4's first armed controls, 50 steps (boot + disarmed) in
    assert flown.trim_released_s is not None
    assert flown.trim_released_s == pytest.approx((peer.boot_sensors + 20) / RATE_HZ, abs=0.05)
    assert c["reconnects"] == 0 and c["link_garbage_bytes"] == 0
    # the outage reached the autopilot: no HIL_GPS valid in [50, 110) s
    assert peer.gps_times and not [t for t in peer.gps_times if 50e6 <= t < 110e6]
    # the aircraft answered the autopilot: altitude held, the turn flown during the outage
    assert max(altitudes) - min(altitudes) < 30.0
    assert abs(yaws[50] - yaws[2]) < 10.0
    turned = (yaws[145] - yaws[50] + 180.0) % 360.0 - 180.0
    assert 75.0 < turned < 105.0
    # its estimate went out as telemetry stamped with the simulator's time (time_boot_ms)
    kinds = {m.get_type() for m in telemetry}  # type: ignore[attr-defined]
    assert {"GLOBAL_POSITION_INT", "ATTITUDE", "ESTIMATOR_STATUS", "HEARTBEAT"} <= kinds
    times = [m.time_boot_ms for m in telemetry  # type: ignore[attr-defined]
             if m.get_type() == "GLOBAL_POSITION_INT"]  # type: ignore[attr-defined]
    assert times == sorted(times) and 0 < times[0] and times[-1] <= 150_000


def test_lockstep_never_runs_ahead_of_a_silent_px4_and_reports_the_stall() -> None:
    setup = SimSetup.build(duration_s=30.0, rate_hz=RATE_HZ, seed=5)
    # (the stall timeout also bounds PX4's boot: 30 steps paced at real time, ~0.6 s)
    flown, peer = _fly_with_peer(setup, stall_timeout_s=3.0, outputs="legacy",
                                 silent_after_s=3.0)
    # the peer answered every HIL_SENSOR before 3 s; the step of 3.00 s got no answer
    assert flown.stalled is not None and "PX4 sent no controls for 3 s" in flown.stalled
    assert "simulated time 3.00 s" in flown.stalled
    assert flown.steps == peer.counters["sensors"] == 150  # never a step ahead
    assert peer.controls_at[-1] == 2_980_000


def test_nan_and_out_of_range_controls_are_clipped_and_counted() -> None:
    setup = SimSetup.build(duration_s=8.0, rate_hz=RATE_HZ, seed=5)
    flown, peer = _fly_with_peer(setup, amap=ActuatorMap.load(STANDARD_PLANE), nan_every=10,
                                 out_of_range_every=7)
    assert flown.stalled is None
    flown_msgs = flown.counters["controls"]  # the messages the simulator flew, in order
    bad = [kind for n, kind in peer.bad_at if n <= flown_msgs]
    assert bad.count("nan") > 5 and bad.count("out_of_range") > 5
    assert flown.counters["nonfinite_channels"] == bad.count("nan")
    assert flown.clipped_controls == len(bad)  # the flight ignored / clipped each one


def test_a_restarted_px4_reconnects_and_boots_again() -> None:
    setup = SimSetup.build(duration_s=10.0, rate_hz=RATE_HZ, seed=5)
    flown, peer = _fly_with_peer(setup, outputs="legacy", restart_at_s=4.0)
    assert flown.stalled is None and flown.ended is None
    c = flown.counters
    assert peer.counters["connections"] == 2 and c["reconnects"] == 1
    assert flown.steps == 500 and c["boot_steps"] >= 2 * peer.boot_sensors
    assert peer.sensor_times[-1] == 10_000_000  # the new PX4 was fed to the end


def test_paced_flight_flies_the_newest_controls() -> None:
    # HITL-style: simulated time at 10x the wall clock, the newest controls each step
    setup = SimSetup.build(duration_s=5.0, rate_hz=RATE_HZ, seed=5)
    with Px4Backend("tcpin:127.0.0.1:0") as backend:
        with Px4Peer(f"tcp:127.0.0.1:{backend.local_address[1]}", outputs="legacy") as peer:
            flown = fly_with_autopilot(setup, backend, speed=10.0, stall_timeout_s=20.0)
            # the peer's thread reads the last frame on its own time: let it before it stops
            deadline = time.monotonic() + 10.0
            while peer.counters["sensors"] < flown.steps and time.monotonic() < deadline:
                time.sleep(0.01)
    assert peer.errors == [] and flown.stalled is None and flown.ended is None
    assert flown.steps == 250 == peer.counters["sensors"]
    # paced: a step does not wait for controls, so some steps fly the previous ones
    assert 0 < flown.counters["controls"] <= peer.counters["controls"]


def _serve_wrong_protocol(port: int, payload: bytes, stop: threading.Event) -> None:
    while not stop.is_set():
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=1.0)
        except OSError:
            stop.wait(0.01)
            continue
        with sock:
            while not stop.is_set():
                try:
                    sock.sendall(payload)
                except OSError:
                    return
                stop.wait(0.005)
        return


@pytest.mark.parametrize(("payload", "named"), [
    (struct.pack("<HHI16H", 18458, 400, 1, *[1500] * 16),
     "ArduPilot SITL 16-channel servo packet (magic 18458)"),
    (b"GET / HTTP/1.1\r\nHost: x\r\n\r\n", "bytes without a MAVLink frame (first bytes 47 45 54"),
])
def test_a_peer_with_the_wrong_protocol_gets_one_line_naming_what_was_expected(
        payload: bytes, named: str) -> None:
    setup = SimSetup.build(duration_s=5.0, rate_hz=RATE_HZ, seed=5)
    stop = threading.Event()
    with Px4Backend("tcpin:127.0.0.1:0") as backend:
        thread = threading.Thread(target=_serve_wrong_protocol,
                                  args=(backend.local_address[1], payload, stop), daemon=True)
        thread.start()
        try:
            with pytest.raises(WrongProtocol) as info:
                fly_with_autopilot(setup, backend, connect_timeout_s=20.0)
        finally:
            stop.set()
            thread.join(timeout=5)
    line = str(info.value)
    assert "\n" not in line and named in line
    assert "expected PX4's simulator interface" in line
