"""ArduPilot in the loop (hil.autopilot.ardupilot) against the ArduPilot protocol peer
(tests/helpers/ardupilot_peer.py) over real loopback sockets: the trim hold while it boots
disarmed, a denial its MAVLink port never acknowledges, and its physics-rate warning."""

from __future__ import annotations

import math
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from hil.autopilot import fly_with_autopilot
from hil.autopilot.ardupilot import RATE_SETTLED_PACKETS, ArduPilotBackend
from hil.autopilot.sitl_json import encode_servo_packet
from hil.pipeline import SimSetup, SimStep
from tests.helpers.ardupilot_peer import ArduPilotPeer

RATE_HZ = 100.0


def _setup(duration_s: float, gnss_off: tuple[str, ...] = ()) -> SimSetup:
    return SimSetup.build(duration_s=duration_s, rate_hz=RATE_HZ, seed=3, gnss_off=gnss_off)


def _roll_deg(step: SimStep) -> float:
    w, x, y, z = (float(v) for v in step.truth.q_nb)
    return math.degrees(math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))


def test_the_trim_is_held_while_ardupilot_boots_disarmed() -> None:
    # GIVEN an ArduPilot that boots disarmed for 15 s (neutral surfaces, throttle at minimum,
    # no armed flag in its HEARTBEATs), then arms and flies
    setup = _setup(20.0)
    peer = ArduPilotPeer(home=(47.0, 8.0, 0.0), mavlink=True, disarmed_s=15.0)
    rolls: list[tuple[float, float]] = []
    with ArduPilotBackend("udpin:127.0.0.1:0", setup=setup,
                          mavlink_url=peer.mavlink_url) as backend:
        peer.start(f"udp:127.0.0.1:{backend.local_address[1]}")
        try:
            # WHEN the simulator flies with it
            flown = fly_with_autopilot(
                setup, backend, stall_timeout_s=10.0,
                on_step=lambda s: rolls.append((s.truth.time_us * 1e-6, _roll_deg(s))))
        finally:
            peer.stop()
    assert peer.error is None and flown.stalled is None and flown.ended is None
    # THEN the aircraft flew its trim while ArduPilot was disarmed: wings level
    assert max(abs(r) for t, r in rolls if t < 15.0) < 5.0
    # AND the hold ended when ArduPilot armed, and the flight says when
    assert peer.armed_at_s is not None
    assert flown.trim_released_s is not None
    assert peer.armed_at_s <= flown.trim_released_s < peer.armed_at_s + 1.0
    assert flown.counters["disarmed_controls"] > 0


@contextmanager
def _silent_mavlink_port() -> Iterator[str]:
    """A TCP port that accepts and reads, and never answers (someone else's program)."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.1)
        conns = []
        while not stop.is_set():
            try:
                conn, _ = server.accept()
                conn.settimeout(0.1)
                conns.append(conn)
            except TimeoutError:
                pass
            for c in conns:
                try:
                    c.recv(4096)
                except (TimeoutError, OSError):
                    pass
        for c in conns:
            c.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp:127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(5.0)
        server.close()


def test_a_denial_that_is_never_acknowledged_is_a_problem_naming_parameter_and_port() -> None:
    # GIVEN a GNSS outage from 5 s for 5 s and a MAVLink port that never answers
    setup = _setup(15.0, ("5:5",))
    peer = ArduPilotPeer(home=(47.0, 8.0, 0.0))
    with _silent_mavlink_port() as url, ArduPilotBackend(
            "udpin:127.0.0.1:0", setup=setup, mavlink_url=url,
            hold_trim_disarmed=False) as backend:
        peer.start(f"udp:127.0.0.1:{backend.local_address[1]}")
        try:
            # WHEN the simulator flies with it
            flown = fly_with_autopilot(setup, backend, stall_timeout_s=10.0)
        finally:
            peer.stop()
    # THEN the flight names what did not reach ArduPilot, and where it was sent
    assert flown.problems
    off = [p for p in flown.problems if "SIM_GPS1_ENABLE = 0" in p]
    assert len(off) == 1 and url in off[0] and "did not acknowledge" in off[0]
    # AND no step of the denial counts as taken
    assert flown.denial is not None and flown.denial
    assert not [d for d in flown.denial if d.took]


def test_a_physics_rate_that_changes_while_booting_is_one_warning_once_settled() -> None:
    # GIVEN an ArduPilot that asks for 1200 Hz while it boots, then settles at 201 Hz
    setup = _setup(5.0)
    warnings: list[str] = []
    rates = [1200] * 5 + [201] * (RATE_SETTLED_PACKETS + 20)
    with ArduPilotBackend("udpin:127.0.0.1:0", setup=setup, warn=warnings.append) as backend:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.settimeout(5.0)
        sock.connect(backend.local_address)
        out: dict[str, object] = {}
        thread = threading.Thread(target=lambda: out.update(
            flown=fly_with_autopilot(setup, backend, stall_timeout_s=5.0)))
        thread.start()
        try:
            for frame, rate in enumerate(rates):
                sock.send(encode_servo_packet(frame, [1500, 1500, 1500, 1500],
                                              frame_rate_hz=rate))
                sock.recv(65000)
            # THEN while it flies, one warning, naming the rate it settled at
            assert warnings == ["ArduPilot asks for 201 Hz physics (SIM_RATE_HZ); hilnav "
                                "steps at 100 Hz: set SIM_RATE_HZ 100"]
        finally:
            sock.close()
            thread.join(30.0)
    # AND no other one at the end
    assert len(warnings) == 1
