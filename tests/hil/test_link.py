"""hil.link: URLs and roles, round trips over real loopback sockets (UDP, TCP, serial over a
pty pair), TCP reconnects, and sends that never block.

No timing assertions: waiting loops only bound how long a broken link may hang the test.
"""

from __future__ import annotations

import os
import select
import socket
import time

import numpy as np
import pytest

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
from sim.samples import BaroSample, GnssFix, MagSample, Truth
from tests.hil.link_helpers import (
    HB,
    WAIT_LIMIT_S,
    Peer,
    assert_books_balance,
    imu,
    pump,
    sensor_frames,
    times_us,
)


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
