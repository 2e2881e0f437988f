"""hil.link.fast_messages: the light records of the fusion's input link equal pymavlink's
messages in fields, header methods and decoded samples."""

from __future__ import annotations

import socket
from typing import Any

import numpy as np

from hil.codec import SENSOR_COMPONENT_ID, Decoder, mavlink2
from hil.link import MavlinkLink
from hil.signing import Signer
from tests.hil.link_helpers import Peer, frame_from, pump


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
