"""Fixtures of the hil tests: the loopback links the hil.link tests talk through."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from hil.link import LinkRole, MavlinkLink
from tests.hil.link_helpers import Peer


@pytest.fixture
def fusion_udp() -> Iterator[Peer]:
    """The fusion's UDP link on a free loopback port."""
    with MavlinkLink("udpin:127.0.0.1:0", LinkRole.fusion()) as link:
        yield Peer(link)


@pytest.fixture
def raw_udp() -> Iterator[socket.socket]:
    """A plain UDP socket on a free loopback port."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    yield sock
    sock.close()
