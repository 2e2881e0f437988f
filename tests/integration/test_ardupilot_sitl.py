"""ArduPilot SITL's JSON physics interface over real loopback sockets: hilnav's
ArduPilotBackend against the ArduPilot-side protocol peer (tests.helpers.ardupilot_peer),
which flies the aircraft from its own estimate and takes its GPS denial as SIM_GPS1_*
parameters over its MAVLink port."""

from __future__ import annotations

import dataclasses
import math
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from hil.autopilot import AutopilotFlown, fly_with_autopilot
from hil.autopilot.ardupilot import ArduPilotBackend
from hil.autopilot.sitl_json import encode_servo_packet
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimSetup
from sim.faults import GnssSpoofHijack, ImuBiasStep, PitotBlockage
from tests.helpers.ardupilot_peer import ArduPilotPeer, PeerPlan, parse_sim_json, trimmed_controls

HIL_GPS_ID = int(mavlink2.MAVLINK_MSG_ID_HIL_GPS)
RATE_HZ = 100.0


def _setup(duration_s: float, gnss_off: tuple[str, ...] = ()) -> SimSetup:
    return SimSetup.build(duration_s=duration_s, rate_hz=RATE_HZ, seed=3, gnss_off=gnss_off)


def _msg_id(frame: bytes) -> int:
    return frame[7] | frame[8] << 8 | frame[9] << 16


@contextmanager
def _flying(setup: SimSetup, backend: ArduPilotBackend, **kw: float) -> Iterator[dict]:
    """fly_with_autopilot in a thread; the dict gets 'flown' when it returns."""
    out: dict[str, AutopilotFlown] = {}
    stop = threading.Event()
    thread = threading.Thread(
        target=lambda: out.update(flown=fly_with_autopilot(setup, backend, stop=stop, **kw)))
    thread.start()
    try:
        yield out
    finally:
        stop.set()
        thread.join(timeout=30)
        assert not thread.is_alive()


def test_the_peer_flies_a_turn_while_its_gps_is_switched_off_by_parameter() -> None:
    # GIVEN a 150 s flight with GNSS off from 40 s for 60 s, and an ArduPilot peer (32
    # outputs) that turns to 090 at 60 s, in the outage; its MAVLink port takes the SIM_GPS1
    # parameters and its estimate goes out as telemetry
    setup = _setup(150.0, ("40:60",))
    telemetry = MavlinkLink("udpin:127.0.0.1:0", LinkRole(
        system_id=250, component_id=190, mav_type=int(mavlink2.MAV_TYPE_GCS),
        autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID)))
    peer = ArduPilotPeer(
        telemetry_url=f"udpout:127.0.0.1:{telemetry.local_address[1]}",
        plan=PeerPlan(headings=((60.0, 90.0),)), home=(47.0, 8.0, 0.0),
        trim=trimmed_controls(setup), mavlink=True, channels=32)
    gnss_frames: list[int] = []
    telemetry_msgs: list = []
    with telemetry, ArduPilotBackend("udpin:127.0.0.1:0", setup=setup,
                                     mavlink_url=peer.mavlink_url) as backend:
        peer.start(f"udp:127.0.0.1:{backend.local_address[1]}")
        try:
            # WHEN the simulator flies in lockstep with it
            flown = fly_with_autopilot(
                setup, backend, stall_timeout_s=10.0,
                on_frame=lambda t, f: gnss_frames.append(t) if _msg_id(f) == HIL_GPS_ID else None,
                on_step=lambda step: telemetry_msgs.extend(telemetry.recv(0.0)))
            telemetry_msgs.extend(telemetry.recv(0.5))
        finally:
            peer.stop()
        counters = backend.counters()
    assert peer.error is None
    # THEN every step was one new servo packet of 32 outputs, answered once
    assert flown.stalled is None and flown.ended is None
    assert flown.steps == 150 * RATE_HZ == counters["steps_answered"]
    assert counters["packets_32"] == flown.steps + 1 and counters["packets_16"] == 0
    assert counters["repeated_frames"] == counters["bad_magic"] == counters["bad_size"] == 0
    # AND the peer's own GPS went off and on again through SIM_GPS1_ENABLE, on simulated time
    enable = [(t, v) for t, name, v in peer.param_log if name == "SIM_GPS1_ENABLE"]
    assert [v for _, v in enable] == [1.0, 0.0, 1.0]
    assert 40.0 <= enable[1][0] <= 40.2 and 100.0 <= enable[2][0] <= 100.2
    assert counters["params_sent"] == counters["params_acked"] == 3
    assert not [t for t in peer.fix_times if 40.2 < t < 100.0]
    assert [t for t in peer.fix_times if t > 100.2]
    # AND hilnav's own HIL_GPS had the same hole (the same denial for both)
    assert not [t for t in gnss_frames if 40e6 <= t < 100e6]
    # AND the aircraft answered its commands: altitude held, turned to 090 in the outage
    alts = [alt for _, _, _, alt in peer.truth_track]
    assert max(abs(a - 1000.0) for a in alts) < 30.0
    (_, n0, e0, _), (_, n1, e1, _) = peer.truth_track[-11], peer.truth_track[-1]
    assert math.degrees(math.atan2(e1 - e0, n1 - n0)) == pytest.approx(90.0, abs=5.0)
    # AND its estimate was its own: dead reckoning drifted off the truth in the outage
    err = {round(a[0]): math.hypot(a[1] - b[1], a[2] - b[2])
           for a, b in zip(peer.track, peer.truth_track, strict=True)}
    assert max(err[t] for t in range(70, 100)) > 1.0
    # AND its telemetry is stamped with its clock, which is the simulated time
    gpi = [m for m in telemetry_msgs if m.get_type() == "GLOBAL_POSITION_INT"]
    assert gpi and all(m.time_boot_ms % 10 == 0 for m in gpi)  # on the 100 Hz step grid
    assert max(m.time_boot_ms for m in gpi) == pytest.approx(150_000, abs=100)
    assert {m.get_type() for m in telemetry_msgs} >= {"ATTITUDE", "EKF_STATUS_REPORT"}


def _client(backend: ArduPilotBackend) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(5.0)
    sock.connect(backend.local_address)
    return sock


def _line(sock: socket.socket) -> dict[str, tuple[float, ...]]:
    parsed = parse_sim_json(sock.recv(65000).decode().strip())
    assert parsed is not None
    return parsed


def test_a_repeated_frame_count_does_not_step_and_a_smaller_one_is_a_restart() -> None:
    setup = _setup(5.0)
    with ArduPilotBackend("udpin:127.0.0.1:0") as backend, _client(backend) as sock, \
            _flying(setup, backend, stall_timeout_s=5.0):
        sock.send(encode_servo_packet(10, [1500, 1500, 1700, 1500]))
        first = _line(sock)
        sock.send(encode_servo_packet(10, [1500, 1500, 1700, 1500]))  # a resend
        assert _line(sock) == first  # answered again, not stepped
        sock.send(encode_servo_packet(11, [1500, 1500, 1700, 1500]))
        second = _line(sock)
        assert second["timestamp"][0] == pytest.approx(first["timestamp"][0] + 1 / RATE_HZ)
        with _client(backend) as restarted:  # a new ArduPilot process: a new source port
            restarted.send(encode_servo_packet(0, [1500, 1500, 1700, 1500]))
            third = _line(restarted)  # the answer follows the new sender
        assert third["timestamp"][0] == pytest.approx(second["timestamp"][0] + 1 / RATE_HZ)
        counters = backend.counters()
    assert counters["repeated_frames"] == 1 and counters["restarts"] == 1
    assert counters["steps_answered"] == 3
    assert any("restarted" in w for w in backend.warnings)


def test_a_physics_rate_unlike_ours_is_one_warning() -> None:
    setup = _setup(5.0)
    with ArduPilotBackend("udpin:127.0.0.1:0", setup=setup) as backend, \
            _client(backend) as sock, _flying(setup, backend, stall_timeout_s=5.0):
        for frame in range(3):
            sock.send(encode_servo_packet(frame, [1500, 1500, 1700, 1500], frame_rate_hz=400))
            _line(sock)
    assert backend.frame_rate_hz == 400
    assert backend.warnings == ["ArduPilot asks for 400 Hz physics (SIM_RATE_HZ); hilnav "
                                "steps at 100 Hz: set SIM_RATE_HZ 100"]


def test_a_silent_autopilot_stalls_the_run_where_it_stopped() -> None:
    setup = _setup(30.0)
    with ArduPilotBackend("udpin:127.0.0.1:0") as backend:
        peer = ArduPilotPeer(trim=trimmed_controls(setup), silent_after=120)
        peer.start(f"udp:127.0.0.1:{backend.local_address[1]}")
        try:
            flown = fly_with_autopilot(setup, backend, stall_timeout_s=0.5)
        finally:
            peer.stop()
    assert flown.steps == 120 and flown.stalled is not None
    assert "1.20 s" in flown.stalled and "ArduPilot" in flown.stalled


def test_bad_packets_are_counted_and_ignored_and_bad_pwm_clipped() -> None:
    setup = _setup(5.0)
    with ArduPilotBackend("udpin:127.0.0.1:0") as backend, _client(backend) as sock, \
            _flying(setup, backend, stall_timeout_s=5.0):
        sock.send(b"\x34\x12" + bytes(38))  # unknown magic
        sock.send(encode_servo_packet(1, [1500] * 16)[:-4])  # 16-output magic, 36 bytes
        sock.send(encode_servo_packet(1, [2600, 0, 1700, 1500]))  # aileron too high, elevator 0
        line = _line(sock)
        sock.send(encode_servo_packet(2, [1500, 1500, 1700, 1500], channels=32))
        assert _line(sock)["timestamp"][0] > line["timestamp"][0]
        counters = backend.counters()
    assert counters["bad_magic"] == 1 and counters["bad_size"] == 1
    assert counters["pwm_clipped"] == 1 and counters["pwm_undriven"] == 1
    assert counters["steps_answered"] == 2 and counters["packets"] == 2


def test_mavlink_on_the_json_port_gets_one_line_naming_what_was_expected() -> None:
    setup = _setup(5.0)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 0, 3).pack(
        mavlink2.MAVLink(None, srcSystem=1, srcComponent=1))
    with ArduPilotBackend("udpin:127.0.0.1:0") as backend, _client(backend) as sock:
        for _ in range(3):
            sock.send(bytes(heartbeat))
        flown = fly_with_autopilot(setup, backend, connect_timeout_s=0.5)
    assert not flown.connected and flown.steps == 0
    assert backend.counters()["wrong_protocol"] == 3
    assert len(backend.warnings) == 1
    line = backend.warnings[0]
    assert "MAVLink" in line and "expected ArduPilot SITL JSON servo packets" in line
    assert "18458" in line and "--model JSON" in line


@pytest.mark.parametrize("url", ["tcp:127.0.0.1:9002", "udpin:127.0.0.1", "udpout:1.2.3.4:9"])
def test_a_bad_url_is_one_clear_error(url: str) -> None:
    with pytest.raises(ValueError, match="expected udpin:HOST:PORT"):
        ArduPilotBackend(url)


def test_imu_and_pitot_faults_reach_ardupilot_through_the_json_line() -> None:
    # GIVEN an accelerometer bias step of +1 m/s^2 on x at 2 s and a pitot blocked at 3 s
    setup = dataclasses.replace(_setup(4.0), faults=(
        ImuBiasStep(start_s=2.0, sensor="accel", axis="x", value=1.0),
        PitotBlockage(start_s=3.0, mode="zero"),
    ))
    lines = []
    with ArduPilotBackend("udpin:127.0.0.1:0", setup=setup) as backend, \
            _client(backend) as sock, _flying(setup, backend, stall_timeout_s=5.0) as out:
        for frame in range(400):
            sock.send(encode_servo_packet(frame, [1460, 1400, 1870, 1500],
                                          frame_rate_hz=round(RATE_HZ)))
            lines.append(_line(sock))
    assert out["flown"].steps == 400
    # THEN ArduPilot's accelerometer carries the bias from 2 s on (IMU noise averages out)
    ax = [(line["timestamp"][0], line["accel_body"][0]) for line in lines]
    before = [a for t, a in ax if 1.0 < t <= 2.0]
    after = [a for t, a in ax if 2.0 < t <= 3.0]
    assert sum(after) / len(after) - sum(before) / len(before) == pytest.approx(1.0, abs=0.15)
    # AND its airspeed is the pitot's: flying before 3 s, nothing once the pitot is blocked
    speeds = [(line["timestamp"][0], line["airspeed"][0]) for line in lines]
    assert all(40.0 < v < 55.0 for t, v in speeds if 0.1 < t < 2.9)
    assert all(v == 0.0 for t, v in speeds if t > 3.1)
    # AND neither needed a parameter (nothing to send, so no MAVLink port was asked for)
    assert backend.param_sender is None and not backend.warnings


def test_a_hijack_spoof_moves_the_peers_gps_by_the_offset_in_metres() -> None:
    # GIVEN a spoofed GNSS position 300 m north and 200 m west from 10 s to 30 s, played to
    # ArduPilot as SIM_GPS1_GLTCH_X/Y in degrees
    setup = dataclasses.replace(_setup(40.0), faults=(
        GnssSpoofHijack(start_s=10.0, duration_s=20.0, offset_ned_m=(300.0, -200.0, 0.0)),))
    peer = ArduPilotPeer(home=(47.0, 8.0, 0.0), trim=trimmed_controls(setup), mavlink=True,
                         frame_rate_hz=round(RATE_HZ))
    with ArduPilotBackend("udpin:127.0.0.1:0", setup=setup,
                         mavlink_url=peer.mavlink_url) as backend:
        peer.start(f"udp:127.0.0.1:{backend.local_address[1]}")
        try:
            flown = fly_with_autopilot(setup, backend, stall_timeout_s=10.0)
        finally:
            peer.stop()
    assert peer.error is None and flown.steps == 40 * RATE_HZ
    # THEN the peer's GPS-based position is off by that offset in metres while spoofed (its
    # GPS lags 100 ms: ~5 m behind along the track north), and back afterwards
    off = {round(a[0]): (a[1] - b[1], a[2] - b[2])
           for a, b in zip(peer.track, peer.truth_track, strict=True)}
    for t in (15, 20, 25):
        assert off[t][0] == pytest.approx(300.0 - 5.0, abs=3.0)
        assert off[t][1] == pytest.approx(-200.0, abs=3.0)
    assert math.hypot(*off[35]) < 10.0
    # X, Y, Z at their defaults at 0 s; X and Y at 10 s and back at 30 s (Z stays 0)
    assert backend.counters()["params_acked"] == backend.counters()["params_sent"] == 7
