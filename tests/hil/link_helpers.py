"""Shared helpers of the hil.link tests: a link with what it received, receive loops with a
bound on how long a broken link may hang a test, and sample frames. The loopback fixtures
``fusion_udp`` and ``raw_udp`` are in ``tests/hil/conftest.py``."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hil.codec import Encoder, mavlink2
from hil.link import LinkCounters, MavlinkLink
from sim.samples import ImuSample

HB = mavlink2.MAVLINK_MSG_ID_HEARTBEAT
KEY = bytes(range(100, 132))
WAIT_LIMIT_S = 10.0  # a broken link fails the test after this long instead of hanging it


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
