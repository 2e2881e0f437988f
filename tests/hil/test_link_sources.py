"""hil.link: who a link listens and replies to: source and message-id filtering, sequence
numbers, heartbeats and peer loss on an injected clock, UDP peer learning, locking onto the
first source, and signing on a live link.

No timing assertions: waiting loops only bound how long a broken link may hang the test.
"""

from __future__ import annotations

import select
import socket
import time

import pytest

from hil.codec import SENSOR_COMPONENT_ID, TRUTH_COMPONENT_ID, Encoder, mavlink2
from hil.link import LinkRole, MavlinkLink
from hil.link.endpoint import PEER_HOLD_HEARTBEATS
from hil.signing import Signer, Verdict
from tests.hil.link_helpers import (
    KEY,
    WAIT_LIMIT_S,
    FakeClock,
    Peer,
    assert_books_balance,
    drain,
    frame_from,
    imu,
    pump,
    sensor_frames,
    times_us,
)


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
