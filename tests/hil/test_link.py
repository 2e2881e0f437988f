"""hil.link: MAVLink links over real loopback sockets and a pty serial pair.

Round trips (UDP, TCP, serial), framing robustness (garbage, truncated, corrupted, unknown-id
and MAVLink 1 frames), floods, source filtering, heartbeats and peer loss on an injected clock,
TCP reconnects, UDP peer learning, signing on a live link, non-blocking sends.

No timing assertions: waiting loops only bound how long a broken link may hang the test.
"""

from __future__ import annotations

import os
import select
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.codec import (
    AUTOPILOT_COMPONENT_ID,
    SENSOR_COMPONENT_ID,
    TRUTH_COMPONENT_ID,
    Decoder,
    Encoder,
    mavlink2,
)
from hil.link import (
    FC_SENSOR_MSG_IDS,
    HIL_MSG_IDS,
    FrameParser,
    LinkCounters,
    LinkRole,
    LinkUrl,
    MavlinkLink,
)
from hil.link.endpoint import PEER_HOLD_HEARTBEATS
from hil.signing import Signer, Verdict
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Truth

HB = mavlink2.MAVLINK_MSG_ID_HEARTBEAT
KEY = bytes(range(100, 132))
WAIT_LIMIT_S = 10.0  # a broken link fails the test after this long instead of hanging it


# --- helpers -------------------------------------------------------------------------------
class FakeClock:
    """Injectable monotonic clock."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@dataclass
class Peer:
    """A link and everything it has received so far."""

    link: MavlinkLink
    msgs: list[Any] = field(default_factory=list)

    def data(self) -> list[Any]:
        """Received messages other than heartbeats."""
        return [m for m in self.msgs if m.get_msgId() != HB]

    def heartbeats(self) -> list[Any]:
        return [m for m in self.msgs if m.get_msgId() == HB]


def pump(until: Callable[[], bool], *peers: Peer) -> None:
    """Run every link's recv() until ``until()`` holds (fail after WAIT_LIMIT_S)."""
    deadline = time.monotonic() + WAIT_LIMIT_S
    while not until():
        if time.monotonic() > deadline:
            raise AssertionError("link did not reach the expected state")
        for p in peers:
            p.msgs += p.link.recv(0.005)


def drain(*peers: Peer, quiet_s: float = 0.1) -> None:
    """Receive until nothing has arrived on any link for ``quiet_s``."""
    idle_since = time.monotonic()
    while time.monotonic() - idle_since < quiet_s:
        for p in peers:
            got = p.link.recv(0.005)
            if got:
                p.msgs += got
                idle_since = time.monotonic()


def assert_books_balance(c: dict[str, int]) -> None:
    """Every CRC-valid frame is accepted or dropped for exactly one reason."""
    after_crc = sum(c[r] for r in LinkCounters.DROP_REASONS) - (
        c["bad_crc"] + c["unknown_msg_id"] + c["truncated"]
    )
    assert c["received"] == c["accepted"] + after_crc


def imu(time_us: int) -> ImuSample:
    # Values chosen so that no payload byte is 0xFD / 0xFE (see magic_free()).
    return ImuSample(
        time_us=time_us,
        dt_s=0.004,
        specific_force_b_mps2=np.array([0.5, -0.25, -9.75]),
        angular_rate_b_rps=np.array([0.01, 0.02, -0.03]),
        temperature_k=300.0,
    )


def sensor_frames(n: int, start_us: int = 4000, encoder: Encoder | None = None) -> list[bytes]:
    enc = encoder or Encoder()
    return [enc.sensors(imu=imu(start_us + 4000 * k)) for k in range(n)]


def times_us(msgs: list[Any]) -> list[int]:
    return [int(m.time_usec) for m in msgs]


def magic_free(frame: bytes) -> bool:
    return not any(b in (0xFD, 0xFE) for b in frame[1:])


def frame_from(system_id: int, component_id: int, msg: Any, seq: int = 0) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    mav.seq = seq
    return bytes(msg.pack(mav))


@pytest.fixture
def fusion_udp() -> Iterator[Peer]:
    with MavlinkLink("udpin:127.0.0.1:0", LinkRole.fusion()) as link:
        yield Peer(link)


@pytest.fixture
def raw_udp() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    yield sock
    sock.close()


# --- URLs and roles ------------------------------------------------------------------------
def test_url_parsing() -> None:
    assert LinkUrl.parse("udpin:0.0.0.0:14550") == LinkUrl("udpin", "0.0.0.0", 14550)
    assert LinkUrl.parse("tcp:[::1]:5760") == LinkUrl("tcp", "::1", 5760)
    assert str(LinkUrl.parse("tcp:[::1]:5760")) == "tcp:[::1]:5760"
    assert LinkUrl.parse("serial:/dev/ttyACM0:921600") == LinkUrl("serial", "/dev/ttyACM0", 921600)
    for bad, match in [
        ("udp:1.2.3.4:5", "scheme must be one of"),
        ("tcp:localhost", "expected tcp:HOST:PORT"),
        ("udpout:1.2.3.4:0", r"port must be in \[1, 65535\]"),
        ("tcpin:1.2.3.4:70000", "port must be in"),
        ("serial:/dev/ttyS0:0", "baud rate must be > 0"),
    ]:
        with pytest.raises(ValueError, match=match):
            LinkUrl.parse(bad)


def test_role_presets_and_validation() -> None:
    sim, fusion = LinkRole.simulator(), LinkRole.fusion()
    assert (sim.system_id, sim.component_id) == (1, SENSOR_COMPONENT_ID)
    assert sim.autopilot == mavlink2.MAV_AUTOPILOT_INVALID
    assert fusion.mav_type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
    assert fusion.accepts_source(1, SENSOR_COMPONENT_ID)
    assert fusion.accepts_source(1, TRUTH_COMPONENT_ID)
    assert fusion.accepts_source(1, AUTOPILOT_COMPONENT_ID)  # HIL_ACTUATOR_CONTROLS, RAW_RPM
    assert not fusion.accepts_source(1, 2)
    assert not fusion.accepts_source(1, fusion.component_id)  # own echo
    assert fusion.accept_msg_ids == HIL_MSG_IDS
    assert fusion.accepts_msg_id(HB) and not fusion.accepts_msg_id(30)
    shadow = LinkRole.shadow_vehicle(system_id=42, gcs_system_id=255)
    assert (shadow.component_id, shadow.mav_type) == (1, mavlink2.MAV_TYPE_FIXED_WING)
    assert shadow.accepts_source(255, 190) and not shadow.accepts_source(254, 190)
    assert LinkRole.companion().accept_msg_ids == FC_SENSOR_MSG_IDS
    assert fusion.peer_timeout_s == 5.0
    with pytest.raises(ValueError, match="accept_sources"):
        LinkRole(
            system_id=1, component_id=1, mav_type=0, autopilot=8, accept_sources=frozenset({(0, 1)})
        )
    with pytest.raises(ValueError, match="not in hilnav's dialect"):
        LinkRole(
            system_id=1, component_id=1, mav_type=0, autopilot=8, accept_msg_ids=frozenset({99999})
        )
    with pytest.raises(ValueError, match="extra"):
        LinkRole(system_id=1, component_id=1, mav_type=0, autopilot=8, colour="red")  # type: ignore[call-arg]


def test_bad_link_arguments() -> None:
    with pytest.raises(ValueError, match="cannot open serial device"):
        MavlinkLink("serial:/dev/does-not-exist:57600", LinkRole.fusion())
    with pytest.raises(ValueError, match="cannot resolve"):
        MavlinkLink("udpout:no-such-host.invalid:14550", LinkRole.fusion())
    with MavlinkLink("udpin:127.0.0.1:0", LinkRole.fusion()) as link:
        with pytest.raises(ValueError, match="cannot open UDP socket"):
            MavlinkLink(f"udpin:127.0.0.1:{link.local_address[1]}", LinkRole.fusion())
        with pytest.raises(ValueError, match="header says"):
            link.send(sensor_frames(1)[0][:-1])
        with pytest.raises(ValueError, match="timeout"):
            link.recv(-1.0)


# --- round trips ---------------------------------------------------------------------------
def test_udp_round_trip_and_peer_learning(fusion_udp: Peer) -> None:
    """GIVEN a simulator link sending HIL_SENSOR, HIL_GPS and HIL_STATE_QUATERNION over UDP,
    THEN the fusion link accepts every frame unchanged and in order, and its heartbeats reach
    the simulator at the address it learned."""
    enc, frames = Encoder(), []
    for k in range(30):
        t = 4000 * (k + 1)
        frames.append(
            enc.sensors(
                imu=imu(t),
                baro=BaroSample(t, 95000.0, 290.0),
                mag=MagSample(t, np.array([2e-5, 1e-6, 4e-5])),
            )
        )
        if k % 5 == 0:
            fix = GnssFix(t, 0.9, 0.4, 120.0, np.array([20.0, 1.0, -0.5]), 1.5, 3.0, 0.2, 3, 12)
            frames.append(enc.gnss(fix))
        if k % 2 == 0:
            truth = Truth(
                t, 0.9, 0.4, 120.0, np.array([20.0, 1.0, -0.5]), np.array([1.0, 0, 0, 0]),
                np.zeros(3), np.array([0, 0, -9.8]), 95000.0, 290.0, 20.0, 19.0,
            )  # fmt: skip
            frames.append(enc.truth(truth))
    port = fusion_udp.link.local_address[1]
    with MavlinkLink(f"udpout:127.0.0.1:{port}", LinkRole.simulator()) as sim_link:
        sim = Peer(sim_link)
        assert all(sim.link.send(f) for f in frames)
        pump(lambda: len(fusion_udp.data()) == len(frames), fusion_udp)
        assert [bytes(m.get_msgbuf()) for m in fusion_udp.data()] == frames
        # the codec decodes what the link accepted exactly as it decodes the raw bytes
        via_link = [d for m in fusion_udp.data() for d in Decoder().decode_message(m)]
        direct = Decoder().feed(b"".join(frames))
        assert [d.sample.time_us for d in via_link] == [d.sample.time_us for d in direct]
        pump(lambda: len(sim.heartbeats()) >= 1, fusion_udp, sim)
        hb = sim.heartbeats()[0]
        assert (hb.get_srcSystem(), hb.get_srcComponent()) == (1, 191)
        assert (hb.type, hb.autopilot, hb.mavlink_version) == (
            mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
            mavlink2.MAV_AUTOPILOT_INVALID,
            3,
        )
        c = fusion_udp.link.counters()
        assert c["dropped"] == 0 and c["lost_seq"] == 0 and c["udp_peer_changes"] == 1
        assert c["accepted"] == len(fusion_udp.msgs)
        assert_books_balance(c)


def test_tcp_round_trip_both_directions() -> None:
    with MavlinkLink("tcpin:127.0.0.1:0", LinkRole.simulator()) as server_link:
        port = server_link.local_address[1]
        with MavlinkLink(f"tcp:127.0.0.1:{port}", LinkRole.fusion()) as client_link:
            server, client = Peer(server_link), Peer(client_link)
            pump(lambda: server.link.counters()["connects"] == 1, server, client)
            frames = sensor_frames(200)
            assert all(server.link.send(f) for f in frames)
            pump(lambda: len(client.data()) == len(frames), server, client)
            assert times_us(client.data()) == [4000 * (k + 1) for k in range(200)]
            # heartbeats flow both ways
            pump(lambda: bool(server.heartbeats() and client.heartbeats()), server, client)
            assert client.link.peer_alive and server.link.peer_alive
            for p in (server, client):
                assert p.link.counters()["dropped"] == 0
                assert_books_balance(p.link.counters())


def test_tcp_client_reconnects_after_server_restart() -> None:
    """GIVEN a TCP client link connected to a server, WHEN the server goes away and a new one
    listens on the same port, THEN the client reconnects on its own and the stream resumes."""
    server = Peer(MavlinkLink("tcpin:127.0.0.1:0", LinkRole.simulator()))
    port = server.link.local_address[1]
    client = Peer(
        MavlinkLink(
            f"tcp:127.0.0.1:{port}",
            LinkRole.fusion(),
            reconnect_min_s=0.01,
            reconnect_max_s=0.05,
        )
    )
    try:
        enc = Encoder()
        pump(lambda: server.link.counters()["connects"] == 1, server, client)
        assert all(server.link.send(f) for f in sensor_frames(5, encoder=enc))
        pump(lambda: len(client.data()) == 5, server, client)

        server.link.close()
        pump(lambda: client.link.counters()["disconnects"] == 1, client)
        assert not client.link.send(sensor_frames(1)[0])  # nowhere to send: counted, no block
        assert client.link.counters()["tx_no_peer"] >= 1

        server = Peer(MavlinkLink(f"tcpin:127.0.0.1:{port}", LinkRole.simulator()))
        pump(
            lambda: (
                client.link.counters()["connects"] == 2 and server.link.counters()["connects"] == 1
            ),
            server,
            client,
        )
        assert all(server.link.send(f) for f in sensor_frames(5, 24000, encoder=enc))
        pump(lambda: len(client.data()) == 10, server, client)
        assert times_us(client.data()) == [4000 * (k + 1) for k in range(10)]
        assert client.link.counters()["dropped"] == 0
    finally:
        client.link.close()
        server.link.close()


def test_serial_over_a_pty_pair() -> None:
    """A pty pair stands in for a serial cable: frames written at one end are accepted by the
    link at the other, the link's heartbeats and frames come out, garbage is counted, and a
    vanished device is detected without the link failing."""
    master, slave = os.openpty()
    try:
        device = os.ttyname(slave)
        with MavlinkLink(f"serial:{device}:921600", LinkRole.fusion()) as link:
            peer = Peer(link)
            frames = sensor_frames(50)
            os.write(master, b"\x00\x11noise" + b"".join(frames[:25]))
            os.write(master, b"".join(frames[25:]))
            pump(lambda: len(peer.data()) == 50, peer)
            assert times_us(peer.data()) == [4000 * (k + 1) for k in range(50)]
            assert link.counters()["garbage_bytes"] == 7

            out = Encoder(system_id=1, sensor_component_id=191, truth_component_id=192)
            assert link.send(out.sensors(imu=imu(777)))
            parsed: list[bytes] = []
            parser = FrameParser(LinkCounters())
            deadline = time.monotonic() + WAIT_LIMIT_S
            while len(parsed) < 2 and time.monotonic() < deadline:  # heartbeat + our frame
                if select.select([master], [], [], 0.05)[0]:
                    parsed += parser.feed(os.read(master, 4096))
            msgs = [mavlink2.MAVLink(None).decode(bytearray(f)) for f in parsed]
            assert sorted(m.get_type() for m in msgs) == ["HEARTBEAT", "HIL_SENSOR"]
            assert all((m.get_srcSystem(), m.get_srcComponent()) == (1, 191) for m in msgs)

            os.close(master)  # the device disappears
            master = -1
            pump(lambda: link.counters()["disconnects"] == 1, peer)
            assert link.recv(0.01) == []  # still running
    finally:
        if master >= 0:
            os.close(master)
        os.close(slave)


# --- bad input -----------------------------------------------------------------------------
def corrupted(frame: bytes) -> bytes:
    bad = bytearray(frame)
    bad[12] ^= 0x40  # a payload bit: the CRC no longer matches
    return bytes(bad)


def unknown_id(frame: bytes) -> bytes:
    bad = bytearray(frame)
    bad[7:10] = (0x0C, 0x0B, 0x0A)  # message id 0x0A0B0C is in no dialect
    assert 0x0A0B0C not in mavlink2.mavlink_map
    return bytes(bad)


def mavlink1(msg: Any) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=SENSOR_COMPONENT_ID)
    return bytes(msg.pack(mav, force_mavlink1=True))


def test_stream_survives_garbage_truncated_corrupted_unknown_and_mavlink1() -> None:
    """Over TCP: every good frame is accepted in order, each bad one is counted once."""
    # Frames without 0xFD / 0xFE after their start byte make the expected counts exact.
    good = [f for f in sensor_frames(20) if magic_free(f)][:7]
    noise = b"\x00\x01garbage\x7f"
    v1 = mavlink1(mavlink2.MAVLink_attitude_message(1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert magic_free(v1)
    stream = b"".join(
        [
            good[0],
            noise,
            good[1][:15],  # truncated: the next frame follows right away
            good[2],
            corrupted(good[3]),
            unknown_id(good[4]),
            good[5],
            v1,
            good[6],
        ]
    )
    with MavlinkLink("tcpin:127.0.0.1:0", LinkRole.fusion()) as link:
        peer = Peer(link)
        with socket.create_connection(link.local_address) as raw:
            for i in range(0, len(stream), 7):  # arrive in small pieces
                raw.sendall(stream[i : i + 7])
            pump(lambda: len(peer.data()) == 4, peer)
        c = link.counters()
    assert times_us(peer.data()) == times_us(
        [mavlink2.MAVLink(None).decode(bytearray(good[i])) for i in (0, 2, 5, 6)]
    )
    assert (c["bad_crc"], c["unknown_msg_id"], c["mavlink1"], c["truncated"]) == (2, 1, 1, 0)
    assert c["garbage_bytes"] == len(noise) + 15 + len(good[3])
    assert (c["received"], c["accepted"]) == (5, 4)
    # the sender's frames between good[0] and good[6] that did not arrive intact
    assert c["lost_seq"] == good[6][4] - good[0][4] + 1 - 4
    assert_books_balance(c)


def test_first_bytes_of_each_connection_are_kept_to_name_a_wrong_protocol() -> None:
    with MavlinkLink("tcpin:127.0.0.1:0", LinkRole.simulator()) as link:
        peer = Peer(link)
        with socket.create_connection(link.local_address) as raw:
            raw.sendall(b"GET / HTTP/1.1\r\n" + b"x" * 100)
            pump(lambda: link.counters()["bytes_received"] >= 116, peer)
        assert link.first_bytes == b"GET / HTTP/1.1\r\n"[:16]
        with socket.create_connection(link.local_address) as raw:  # a new connection
            raw.sendall(b"\x1a\x48")
            pump(lambda: link.counters()["connects"] == 2
                 and link.counters()["bytes_received"] >= 118, peer)
        assert link.first_bytes == b"\x1a\x48"


def test_udp_truncated_datagram_does_not_spoil_the_next(
    fusion_udp: Peer, raw_udp: socket.socket
) -> None:
    good = sensor_frames(5)
    address = fusion_udp.link.local_address
    raw_udp.sendto(good[0] + good[1][:20], address)  # cut short at the end
    raw_udp.sendto(good[2], address)
    raw_udp.sendto(b"\x13\x37" * 30, address)
    raw_udp.sendto(good[3] + good[4], address)
    pump(lambda: len(fusion_udp.data()) == 4, fusion_udp)
    c = fusion_udp.link.counters()
    assert times_us(fusion_udp.data()) == [4000, 12000, 16000, 20000]
    assert (c["truncated"], c["garbage_bytes"], c["bad_crc"]) == (1, 20 + 60, 0)
    assert_books_balance(c)


@settings(max_examples=40, deadline=None)
@given(
    noise=st.lists(
        st.binary(max_size=40).map(lambda b: bytes(x for x in b if x not in (0xFD, 0xFE))),
        min_size=6,
        max_size=6,
    ),
    cuts=st.lists(st.integers(min_value=1, max_value=90), min_size=1, max_size=40),
)
def test_parser_recovers_every_frame_however_the_stream_is_cut(
    noise: list[bytes], cuts: list[int]
) -> None:
    enc = Encoder()
    frames = [
        enc.sensors(imu=imu(1000 * k), baro=BaroSample(1000 * k, 90000.0 + k, 280.0))
        for k in range(1, 7)
    ]  # frames themselves may contain 0xFD / 0xFE bytes
    stream = b"".join(n + f for n, f in zip(noise, frames, strict=True))
    counters = LinkCounters()
    parser = FrameParser(counters)
    out, i, k = [], 0, 0
    while i < len(stream):
        step = cuts[k % len(cuts)]
        out += parser.feed(stream[i : i + step])
        i, k = i + step, k + 1
    assert out == frames
    assert counters.garbage_bytes == sum(map(len, noise))
    assert counters.bad_crc == counters.unknown_msg_id == 0


def test_parser_resynchronises_in_random_noise() -> None:
    """Noise of every byte value (false start markers included) between good frames: every
    good frame is still found, in order (seeded, so the outcome is reproducible)."""
    rng = np.random.default_rng(20240611)
    frames = sensor_frames(400)
    chunks = [
        rng.integers(0, 256, int(rng.integers(0, 120)), dtype=np.uint8).tobytes() for _ in frames
    ]
    stream = b"".join(n + f for n, f in zip(chunks, frames, strict=True))
    counters = LinkCounters()
    parser = FrameParser(counters)
    out = [f for i in range(0, len(stream), 512) for f in parser.feed(stream[i : i + 512])]
    assert out == frames
    assert counters.garbage_bytes == sum(map(len, chunks))


def test_flood_at_ten_times_the_nominal_rate_over_tcp() -> None:
    """2500 HIL_SENSOR frames (10x a 250 Hz IMU for one second) with noise between them, sent
    as fast as the socket takes them: all accepted, in order; the noise is counted."""
    rng = np.random.default_rng(7)
    frames = sensor_frames(2500)
    noise = [
        rng.integers(0, 256, int(rng.integers(0, 30)), dtype=np.uint8).tobytes() for _ in frames
    ]
    stream = b"".join(n + f for n, f in zip(noise, frames, strict=True))
    with MavlinkLink("tcpin:127.0.0.1:0", LinkRole.fusion()) as link:
        peer = Peer(link)
        raw = socket.create_connection(link.local_address)
        sender = threading.Thread(target=raw.sendall, args=(stream,))
        sender.start()
        try:
            pump(lambda: len(peer.data()) == len(frames), peer)
        finally:
            sender.join()
            raw.close()
        c = link.counters()
    assert times_us(peer.data()) == [4000 * (k + 1) for k in range(2500)]
    assert c["garbage_bytes"] == sum(map(len, noise))
    assert c["lost_seq"] == 0
    assert_books_balance(c)


def test_flood_over_udp_never_reorders_or_duplicates(fusion_udp: Peer) -> None:
    """The same flood as datagrams with garbage datagrams between them. The kernel may drop
    datagrams when its buffer overflows; whatever reaches the link is accepted in order, and
    the link still answers afterwards."""
    frames = sensor_frames(2500)
    address = fusion_udp.link.local_address

    def flood() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for k, f in enumerate(frames):
                s.sendto(f, address)
                if k % 3 == 0:
                    s.sendto(b"\x00garbage\xfd\x01", address)

    sender = threading.Thread(target=flood)
    sender.start()
    while sender.is_alive():
        fusion_udp.msgs += fusion_udp.link.recv(0.01)
    sender.join()
    drain(fusion_udp)
    got = times_us(fusion_udp.data())
    c = fusion_udp.link.counters()
    assert got == sorted(set(got)) and set(got) <= {4000 * (k + 1) for k in range(2500)}
    assert len(got) == c["accepted"] > 0
    assert_books_balance(c)
    # still alive: a new sender is heard
    with MavlinkLink(f"udpout:127.0.0.1:{address[1]}", LinkRole.simulator()) as sim:
        sim.send(sensor_frames(1, 10_000_004)[0])
        pump(lambda: 10_000_004 in times_us(fusion_udp.data()), fusion_udp)


# --- filtering, sequence numbers -----------------------------------------------------------
def test_source_and_message_id_filtering(fusion_udp: Peer, raw_udp: socket.socket) -> None:
    attitude = mavlink2.MAVLink_attitude_message(1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    heartbeat = mavlink2.MAVLink_heartbeat_message(0, 8, 0, 0, 4, 3)
    good = sensor_frames(1)[0]  # from (1, 200)
    other_system = Encoder(system_id=2).sensors(imu=imu(8000))
    sends = [
        other_system,  # wrong system
        frame_from(1, 191, heartbeat),  # our own ids: an echo
        frame_from(1, SENSOR_COMPONENT_ID, attitude),  # accepted source, unwanted message
        frame_from(1, TRUTH_COMPONENT_ID, heartbeat),  # heartbeats are always accepted
        good,
    ]
    for f in sends:
        raw_udp.sendto(f, fusion_udp.link.local_address)
    pump(lambda: len(fusion_udp.msgs) == 2, fusion_udp)
    drain(fusion_udp)
    c = fusion_udp.link.counters()
    assert [m.get_type() for m in fusion_udp.msgs] == ["HEARTBEAT", "HIL_SENSOR"]
    assert (c["wrong_source"], c["wrong_msg_id"], c["accepted"]) == (2, 1, 2)
    assert fusion_udp.link.peers() == {(1, TRUTH_COMPONENT_ID): True}
    assert_books_balance(c)


def test_lost_and_out_of_order_sequence_numbers(fusion_udp: Peer, raw_udp: socket.socket) -> None:
    frames = sensor_frames(12)  # seq 0..11 from (1, 200)
    order = [0, 1, 2, 5, 6, 11, 10]  # 3, 4 and 7..9 lost; 10 arrives late
    for i in order:
        raw_udp.sendto(frames[i], fusion_udp.link.local_address)
    pump(lambda: len(fusion_udp.data()) == len(order), fusion_udp)
    c = fusion_udp.link.counters()
    assert times_us(fusion_udp.data()) == [4000 * (i + 1) for i in order]  # all delivered
    assert (c["lost_seq"], c["seq_out_of_order"]) == (2 + 4, 1)


def test_a_burst_of_more_than_128_lost_frames_is_counted_as_lost(
    fusion_udp: Peer, raw_udp: socket.socket
) -> None:
    frames = sensor_frames(300)  # seq 0..255, 0..43 from (1, 200)
    order = [0, 1, 2, 200, 201, 202]  # 197 lost in one burst, then the stream goes on
    for i in order:
        raw_udp.sendto(frames[i], fusion_udp.link.local_address)
    pump(lambda: len(fusion_udp.data()) == len(order), fusion_udp)
    c = fusion_udp.link.counters()
    assert (c["lost_seq"], c["seq_out_of_order"]) == (197, 0)


def test_link_numbers_heartbeats_and_encoder_frames_in_one_sequence(fusion_udp: Peer) -> None:
    """The simulator's heartbeats and its encoder's HIL_SENSOR come from the same component:
    the receiver sees one gap-free sequence."""
    clock = FakeClock()
    url = f"udpout:127.0.0.1:{fusion_udp.link.local_address[1]}"
    with MavlinkLink(url, LinkRole.simulator(), clock=clock) as sim:
        enc = Encoder()
        for k in range(10):
            sim.send(enc.sensors(imu=imu(4000 * (k + 1))))
            clock.t += 0.5  # a heartbeat every second frame
            sim.tick()
        pump(lambda: len(fusion_udp.msgs) == 10 + sim.counters()["heartbeats_sent"], fusion_udp)
    seqs = [m.get_seq() for m in fusion_udp.msgs]
    assert len(fusion_udp.heartbeats()) >= 5
    assert seqs == list(range(len(seqs)))
    assert fusion_udp.link.counters()["lost_seq"] == 0


# --- heartbeats and peers ------------------------------------------------------------------
def test_heartbeats_and_peer_loss_on_an_injected_clock() -> None:
    """GIVEN a simulator heartbeating at 1 Hz on a fake clock, WHEN it falls silent, THEN the
    fusion declares it lost only after five missed heartbeats, and alive again when it is
    back; no test time is spent sleeping."""
    clock = FakeClock()
    with (
        MavlinkLink("udpin:127.0.0.1:0", LinkRole.fusion(), clock=clock) as fusion_link,
        MavlinkLink(
            f"udpout:127.0.0.1:{fusion_link.local_address[1]}", LinkRole.simulator(), clock=clock
        ) as sim,
    ):
        fusion_udp = Peer(fusion_link)
        for _ in range(3):  # repeated ticks at the same time send one heartbeat
            sim.tick()
        assert sim.counters()["heartbeats_sent"] == 1
        pump(lambda: len(fusion_udp.heartbeats()) == 1, fusion_udp)
        hb = fusion_udp.heartbeats()[0]
        assert (hb.get_srcSystem(), hb.get_srcComponent()) == (1, SENSOR_COMPONENT_ID)
        assert (hb.type, hb.autopilot) == (
            mavlink2.MAV_TYPE_GENERIC,
            mavlink2.MAV_AUTOPILOT_INVALID,
        )
        assert fusion_udp.link.peer_alive

        clock.t = 3.0
        sim.tick()  # one heartbeat for the missed schedule, not a burst of three
        assert sim.counters()["heartbeats_sent"] == 2
        pump(lambda: len(fusion_udp.heartbeats()) == 2, fusion_udp)
        clock.t = 7.9  # 4.9 s of silence
        fusion_udp.link.tick()
        assert fusion_udp.link.peer_alive
        clock.t = 8.1  # more than 5 heartbeat periods
        fusion_udp.link.tick()
        assert not fusion_udp.link.peer_alive
        assert fusion_udp.link.counters()["peer_losses"] == 1
        assert fusion_udp.link.peers() == {(1, SENSOR_COMPONENT_ID): False}

        sim.tick()  # it is back
        pump(lambda: fusion_udp.link.peer_alive, fusion_udp)
        assert fusion_udp.link.counters()["peer_losses"] == 1


def test_heartbeat_state_and_shadow_vehicle_identity() -> None:
    gcs_role = LinkRole(system_id=255, component_id=190, mav_type=6, autopilot=8)
    with (
        MavlinkLink("udpin:127.0.0.1:0", gcs_role) as gcs_link,
        MavlinkLink(
            f"udpout:127.0.0.1:{gcs_link.local_address[1]}",
            LinkRole.shadow_vehicle(system_id=42),
        ) as shadow,
    ):
        gcs = Peer(gcs_link)
        shadow.set_heartbeat_state(base_mode=mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, custom_mode=7)
        shadow.tick()
        pump(lambda: len(gcs.heartbeats()) == 1, gcs)
        hb = gcs.heartbeats()[0]
        assert (hb.get_srcSystem(), hb.get_srcComponent()) == (42, 1)
        assert (hb.type, hb.autopilot) == (
            mavlink2.MAV_TYPE_FIXED_WING,
            mavlink2.MAV_AUTOPILOT_GENERIC,
        )
        assert (hb.base_mode, hb.custom_mode, hb.system_status) == (
            mavlink2.MAV_MODE_FLAG_SAFETY_ARMED,
            7,
            mavlink2.MAV_STATE_ACTIVE,
        )
        with pytest.raises(ValueError, match="uint8"):
            shadow.set_heartbeat_state(base_mode=256)


def test_udp_peer_learning_follows_a_sender_that_comes_back(fusion_udp: Peer) -> None:
    """A simulator restarts and sends from a new port: the fusion's replies follow it."""
    address = fusion_udp.link.local_address

    def restart_and_talk(generation: int) -> None:
        with MavlinkLink(f"udpout:127.0.0.1:{address[1]}", LinkRole.simulator()) as sim_link:
            sim = Peer(sim_link)
            sim.link.send(sensor_frames(1, 4000 * (generation + 1))[0])
            pump(lambda: len(fusion_udp.data()) == generation + 1, fusion_udp)
            fusion_udp.link.send_message(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
            pump(lambda: len(sim.heartbeats()) >= 1, sim)  # the reply found it

    restart_and_talk(0)
    # the old port falls silent for more than the hold (a restart takes seconds); a new
    # address cannot take the replies from a peer that is still talking (next test)
    quiet_until = time.monotonic() + PEER_HOLD_HEARTBEATS * LinkRole.fusion().heartbeat_period_s
    pump(lambda: time.monotonic() > quiet_until + 0.2, fusion_udp)  # read on, as a service does
    restart_and_talk(1)
    assert fusion_udp.link.counters()["udp_peer_changes"] == 2


def test_a_second_address_of_the_same_source_cannot_take_the_replies_of_a_talking_peer(
    fusion_udp: Peer, raw_udp: socket.socket,
) -> None:
    """GIVEN the fusion replying to the simulator WHEN another socket sends valid frames with
    the simulator's own source address (unsigned: they are accepted) while the simulator keeps
    talking THEN the replies stay with the simulator; once it has been silent for the hold
    the other address takes over (what a restarted simulator needs)."""
    address = fusion_udp.link.local_address
    with MavlinkLink(f"udpout:127.0.0.1:{address[1]}", LinkRole.simulator()) as sim_link:
        sim = Peer(sim_link)
        sim.link.send(sensor_frames(1)[0])
        pump(lambda: len(fusion_udp.data()) == 1, fusion_udp)
        for k in range(5):
            raw_udp.sendto(Encoder().sensors(imu=imu(2 + k)), address)  # forged source 1:200
            sim.link.send(sensor_frames(1, 5000 * (k + 2))[0])
            pump(lambda k=k: len(fusion_udp.data()) == 3 + 2 * k, fusion_udp)
        assert fusion_udp.link.counters()["udp_peer_changes"] == 1
        fusion_udp.link.send_message(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
        pump(lambda: len(sim.heartbeats()) >= 1, sim)


def test_garbage_cannot_redirect_udp_replies(fusion_udp: Peer, raw_udp: socket.socket) -> None:
    address = fusion_udp.link.local_address
    with MavlinkLink(f"udpout:127.0.0.1:{address[1]}", LinkRole.simulator()) as sim_link:
        sim = Peer(sim_link)
        sim.link.send(sensor_frames(1)[0])
        pump(lambda: len(fusion_udp.data()) == 1, fusion_udp)
        raw_udp.sendto(b"\xfd\x00garbage", address)  # from another port, nothing accepted
        raw_udp.sendto(Encoder(system_id=9).sensors(imu=imu(1)), address)  # wrong source
        pump(lambda: fusion_udp.link.counters()["wrong_source"] == 1, fusion_udp)
        assert fusion_udp.link.counters()["udp_peer_changes"] == 1
        fusion_udp.link.send_message(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
        pump(lambda: len(sim.heartbeats()) >= 1, sim)


# --- signing on a live link ----------------------------------------------------------------
def test_signed_link_rejects_attacks_without_blocking_the_stream(
    raw_udp: socket.socket,
) -> None:
    """GIVEN simulator and fusion sharing a key, WHEN an attacker injects unsigned,
    wrong-key, replayed and forged far-future frames before and between the legitimate
    ones, THEN every legitimate frame is accepted in order and each attack is counted."""
    with MavlinkLink("udpin:127.0.0.1:0", LinkRole.fusion(), signer=Signer(KEY)) as link:
        fusion = Peer(link)
        address = link.local_address
        legit_tx = Signer(KEY)
        legit = [legit_tx.sign(f) for f in sensor_frames(20)]
        # Without the key an attacker can send unsigned frames, frames signed with another
        # key (here also an hour ahead), replay captured frames, or move a captured frame's
        # timestamp a year ahead (leaving its now invalid signature).
        unsigned = Encoder().sensors(imu=imu(999_000))
        wrong_key = Signer(bytes(32), wall_clock=lambda: time.time() + 3600.0).sign(
            Encoder().sensors(imu=imu(998_000))
        )
        year = 365 * 24 * 3600 * 100_000
        ts = int.from_bytes(legit[0][-12:-6], "little")
        forged_future = legit[0][:-12] + (ts + year).to_bytes(6, "little") + legit[0][-6:]
        for attack in (forged_future, unsigned, wrong_key):  # before the stream starts
            raw_udp.sendto(attack, address)
        for k, f in enumerate(legit):
            raw_udp.sendto(f, address)
            if k == 5:
                raw_udp.sendto(forged_future, address)  # in the middle of it
                raw_udp.sendto(legit[2], address)  # a replay
        pump(lambda: len(fusion.data()) == 20, fusion)
        drain(fusion)
        c = link.counters()
        assert times_us(fusion.data()) == [4000 * (k + 1) for k in range(20)]
        assert (c["bad_signature"], c["unsigned"], c["replayed"]) == (3, 1, 1)
        assert c["accepted"] == 20
        assert_books_balance(c)

        # what the link sends is signed, and the key holder verifies it
        link.send_message(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
        raw_udp.settimeout(WAIT_LIMIT_S)
        reply, _ = raw_udp.recvfrom(1024)
        assert reply[2] & 0x01
        assert Signer(KEY).verify(reply) is Verdict.OK


def test_signed_links_talk_to_each_other_over_tcp() -> None:
    with MavlinkLink("tcpin:127.0.0.1:0", LinkRole.simulator(), signer=Signer(KEY)) as s_link:
        url = f"tcp:127.0.0.1:{s_link.local_address[1]}"
        with MavlinkLink(url, LinkRole.fusion(), signer=Signer(KEY)) as f_link:
            server, fusion = Peer(s_link), Peer(f_link)
            pump(lambda: s_link.counters()["connects"] == 1, server, fusion)
            assert all(s_link.send(f) for f in sensor_frames(10))
            pump(lambda: len(fusion.data()) == 10 and bool(server.heartbeats()), server, fusion)
            assert all(m.get_msgbuf()[2] & 0x01 for m in fusion.msgs + server.msgs)
            assert f_link.counters()["dropped"] == s_link.counters()["dropped"] == 0


# --- sending never blocks ------------------------------------------------------------------
def test_send_without_a_peer_is_counted_not_blocking(fusion_udp: Peer) -> None:
    frame = Encoder(system_id=1, sensor_component_id=191, truth_component_id=192).sensors(
        imu=imu(1)
    )
    assert not fusion_udp.link.send(frame)  # udpin has learned no peer yet
    assert fusion_udp.link.counters()["tx_no_peer"] == 1
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    port = listener.getsockname()[1]
    listener.close()  # nothing listens there
    with MavlinkLink(
        f"tcp:127.0.0.1:{port}", LinkRole.simulator(), reconnect_min_s=0.01, reconnect_max_s=0.02
    ) as client:
        pump(lambda: client.counters()["connect_failures"] >= 2, Peer(client))
        assert not client.send(sensor_frames(1)[0])
        assert client.counters()["tx_no_peer"] >= 1


def test_full_transmit_buffer_drops_whole_frames_without_blocking() -> None:
    """A TCP peer that never reads: the kernel buffers fill, then the link's buffer; further
    frames are dropped whole and counted, and send() keeps returning at once."""
    listener = socket.socket()
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    try:
        with MavlinkLink(
            f"tcp:127.0.0.1:{listener.getsockname()[1]}",
            LinkRole.simulator(),
            tx_buffer_bytes=4096,
        ) as link:
            pump(lambda: link.counters()["connects"] == 1, Peer(link))
            conn, _ = listener.accept()
            frames = sensor_frames(200)
            accepted_sends = 0
            for k in range(1_000_000):
                if not link.send(frames[k % 200]):
                    break
                accepted_sends += 1
            assert link.counters()["tx_buffer_full"] == 1
            conn.setblocking(False)
            received = bytearray()
            deadline = time.monotonic() + WAIT_LIMIT_S
            while len(received) < link.counters()["bytes_sent"]:  # read it all
                assert time.monotonic() < deadline, "queued frames were not delivered"
                try:
                    received += conn.recv(1 << 20)
                except BlockingIOError:
                    link.recv(0.001)  # lets the link flush its own buffer
            counters = LinkCounters()
            parsed = FrameParser(counters).feed(bytes(received), final=True)
            assert len(parsed) == link.counters()["sent"] >= accepted_sends
            assert counters.garbage_bytes == counters.truncated == 0
            conn.close()
    finally:
        listener.close()


def test_fileno_becomes_readable_when_data_arrives(
    fusion_udp: Peer, raw_udp: socket.socket
) -> None:
    assert select.select([fusion_udp.link], [], [], 0)[0] == []
    raw_udp.sendto(sensor_frames(1)[0], fusion_udp.link.local_address)
    assert select.select([fusion_udp.link], [], [], WAIT_LIMIT_S)[0] == [fusion_udp.link]
    assert len(fusion_udp.link.recv(0)) == 1


def test_a_locked_link_ignores_a_second_sender_and_keeps_its_reply_address() -> None:
    """GIVEN the fusion's input link (locks onto the first sensor source) WHEN system 1 sends
    sensors and then system 99 sends sensors and heartbeats from another socket THEN only
    system 1's frames come through, system 99's are counted as wrong_source, and replies still
    go to system 1's address (it receives our heartbeat; the attacker receives nothing after
    the lock)."""
    from hil.service import input_role

    legit = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    hostile = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    legit.bind(("127.0.0.1", 0))
    hostile.bind(("127.0.0.1", 0))
    try:
        with MavlinkLink("udpin:127.0.0.1:0", input_role()) as link:
            peer = Peer(link)
            addr = link.local_address
            for f in sensor_frames(5):
                legit.sendto(f, addr)
            pump(lambda: len(peer.data()) == 5, peer)
            assert link.locked_system == 1
            hostile_enc = Encoder(system_id=99)
            heartbeat = mavlink2.MAVLink_heartbeat_message(0, 8, 0, 0, 4, 3)
            for k in range(50):
                hostile.sendto(hostile_enc.sensors(imu=imu(100_000 + 4000 * k)), addr)
                hostile.sendto(frame_from(99, 1, heartbeat, seq=k), addr)
            for f in sensor_frames(5, start_us=24_000):
                legit.sendto(f, addr)
            pump(lambda: len(peer.data()) == 10, peer)
            drain(peer)
            c = link.counters()
            assert len(peer.data()) == 10 and c["wrong_source"] == 100
            assert c["udp_peer_changes"] == 1
            link.send_message(mavlink2.MAVLink_heartbeat_message(0, 8, 0, 0, 4, 3))
            assert select.select([legit], [], [], 2.0)[0] == [legit]
            assert select.select([hostile], [], [], 0.3)[0] == []
    finally:
        legit.close()
        hostile.close()


def test_source_option_binds_before_any_frame() -> None:
    from hil.service import input_role, parse_source

    assert parse_source("7") == (7, None) and parse_source("7:200") == (7, 200)
    for bad in ("x", "0", "7:300", "1:2:3"):
        with pytest.raises(ValueError, match="--source"):
            parse_source(bad)
    role = input_role((7, None))
    assert not role.lock_to_first_source
    assert role.accepts_source(7, 200) and not role.accepts_source(8, 200)


def _random_message(cls: Any, rng: np.random.Generator) -> Any:
    """A pymavlink message of ``cls`` with random values of every field's type."""
    ints = {"uint8_t": (0, 255), "int8_t": (-128, 127), "uint16_t": (0, 65535),
            "int16_t": (-32768, 32767), "uint32_t": (0, 2**32 - 1),
            "int32_t": (-(2**31), 2**31 - 1), "uint64_t": (0, 2**63 - 1),
            "int64_t": (-(2**62), 2**62)}
    values = []
    for name, kind in zip(cls.fieldnames, cls.fieldtypes, strict=True):
        n = cls.lengths[cls.ordered_fieldnames.index(name)]  # lengths: in wire order
        if kind in ints:
            lo, hi = ints[kind]
            vals: list[Any] = [int(rng.integers(lo, hi, endpoint=True)) for _ in range(n)]
        else:  # float, double: the filter reads them exactly
            vals = [float(np.float32(x)) if kind == "float" else float(x)
                    for x in rng.normal(0.0, 1e3, n)]
        values.append(vals if n > 1 else vals[0])
    return cls(*values)


def test_fast_messages_equal_pymavlink_in_fields_header_and_samples(
    raw_udp: socket.socket,
) -> None:
    """GIVEN the fusion's input link (``fast_msg_ids``) WHEN random frames of every fast
    message arrive, unsigned and signed, THEN each unsigned one comes back as a light record
    whose fields, header methods and decoded samples equal pymavlink's decode of the same
    frame, and each signed one as a pymavlink message."""
    from hil.link.fast_messages import FAST_MSG_IDS
    from hil.service import input_role

    rng = np.random.default_rng(15)
    ids = sorted(FAST_MSG_IDS)
    frames, signed = [], Signer(b"k" * 32, link_id=0)
    for k in range(60):
        msg = _random_message(mavlink2.mavlink_map[ids[k % len(ids)]], rng)
        frame = frame_from(1, SENSOR_COMPONENT_ID, msg, seq=k)
        frames.append(signed.sign(frame, seq=k) if k % 10 == 9 else frame)
    with MavlinkLink("udpin:127.0.0.1:0", input_role(), fast_msg_ids=FAST_MSG_IDS) as link:
        peer = Peer(link)
        for f in frames:
            raw_udp.sendto(f, link.local_address)
        pump(lambda: len(peer.data()) == len(frames), peer)
    ref = mavlink2.MAVLink(None, 0, 0)
    fast_decoder, ref_decoder = Decoder(), Decoder()
    for k, (got, frame) in enumerate(zip(peer.data(), frames, strict=True)):
        want = ref.decode(bytearray(frame))
        assert isinstance(got, mavlink2.MAVLink_message) == (k % 10 == 9)
        assert [getattr(got, n) for n in want.fieldnames] == [
            getattr(want, n) for n in want.fieldnames]
        for method in ("get_msgId", "get_type", "get_srcSystem", "get_srcComponent", "get_seq",
                       "get_msgbuf", "get_signed"):
            assert getattr(got, method)() == getattr(want, method)(), method
        samples = [d.sample for d in fast_decoder.decode_message(got)]
        assert repr(samples) == repr([d.sample for d in ref_decoder.decode_message(want)])
    assert fast_decoder.counters.as_dict() == ref_decoder.counters.as_dict()
