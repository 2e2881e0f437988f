"""hil.link: framing robustness on a live link (garbage, truncated, corrupted, unknown-id and
MAVLink 1 frames, a stream cut anywhere, random noise) and floods over TCP and UDP.

No timing assertions: waiting loops only bound how long a broken link may hang the test.
"""

from __future__ import annotations

import socket
import threading
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.codec import SENSOR_COMPONENT_ID, Encoder, mavlink2
from hil.link import FrameParser, LinkCounters, LinkRole, MavlinkLink
from sim.samples import BaroSample
from tests.hil.link_helpers import (
    Peer,
    assert_books_balance,
    drain,
    imu,
    magic_free,
    pump,
    sensor_frames,
    times_us,
)


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
