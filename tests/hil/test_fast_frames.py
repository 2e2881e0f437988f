"""The codec's fast path (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION, HIL_ACTUATOR_CONTROLS,
RAW_RPM) is bit-exact against pymavlink (the reference).

- Encoding: every field of the five messages, any value the wire can carry (NaN and
  infinities in the float fields included), any header: the same bytes as pymavlink's
  ``pack``.
- Decoding: the same field values as pymavlink's ``decode`` for truncated, full-length and
  over-long payloads.
- The decoder: ``Decoder.feed`` (fast path) gives the same samples and counters as
  ``Decoder.parse`` (pymavlink for every frame) followed by the decoder's dispatch, on clean,
  signed, byte-mutated and cut streams.
"""

from __future__ import annotations

import dataclasses
import math
import random
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.codec import Decoder, Encoder
from hil.codec.fast_frames import (
    HIL_ACTUATOR_CONTROLS,
    HIL_GPS,
    HIL_SENSOR,
    HIL_STATE_QUATERNION,
    RAW_RPM,
    FastLayout,
    pack_frame,
    unpack_fields,
)
from hil.codec.wire import frame_crc, mavlink2
from sim.samples import (
    ActuatorSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    RpmSample,
    Truth,
)

f32 = st.floats(width=32, allow_nan=True, allow_infinity=True)
u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
i16 = st.integers(-0x8000, 0x7FFF)
i32 = st.integers(-0x8000_0000, 0x7FFF_FFFF)
u32 = st.integers(0, 0xFFFF_FFFF)
u64 = st.integers(0, 0xFFFF_FFFF_FFFF_FFFF)
# Zero-heavy values too, so that payload truncation (trailing zero bytes) is exercised.
sparse_f32 = st.one_of(st.just(0.0), f32)


def sparse(s: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    return st.one_of(st.just(0), s)


# Field values in pymavlink's constructor order (MAVLink_<msg>_message.fieldnames).
FIELDS: dict[str, tuple[FastLayout, Any, st.SearchStrategy[tuple[Any, ...]]]] = {
    "HIL_SENSOR": (HIL_SENSOR, mavlink2.MAVLink_hil_sensor_message,
                   st.tuples(sparse(u64), *([sparse_f32] * 13), sparse(u32), u8)),
    "HIL_GPS": (HIL_GPS, mavlink2.MAVLink_hil_gps_message,
                st.tuples(sparse(u64), u8, i32, i32, i32, u16, u16, u16, i16, i16, i16, u16, u8,
                          sparse(u8), sparse(u16))),
    "HIL_STATE_QUATERNION": (HIL_STATE_QUATERNION, mavlink2.MAVLink_hil_state_quaternion_message,
                             st.tuples(sparse(u64), st.lists(sparse_f32, min_size=4, max_size=4),
                                       sparse_f32, sparse_f32, sparse_f32, i32, i32, i32, i16,
                                       i16, i16, u16, u16, i16, i16, sparse(i16))),
    "HIL_ACTUATOR_CONTROLS": (HIL_ACTUATOR_CONTROLS,
                              mavlink2.MAVLink_hil_actuator_controls_message,
                              st.tuples(sparse(u64), st.lists(sparse_f32, min_size=16,
                                                              max_size=16), sparse(u8),
                                        sparse(u64))),
    "RAW_RPM": (RAW_RPM, mavlink2.MAVLink_raw_rpm_message, st.tuples(u8, sparse_f32)),
}
header = st.tuples(u8, u8, u8)  # seq, system, component


def _bits(values: Any) -> Any:
    """Values with floats as their bit patterns (NaN compares equal to itself)."""
    if isinstance(values, list | tuple):
        return tuple(_bits(v) for v in values)
    return struct.pack("<d", values) if isinstance(values, float) else values


def _pymavlink_frame(cls: Any, values: tuple[Any, ...], hdr: tuple[int, int, int]) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=hdr[1], srcComponent=hdr[2])
    mav.seq = hdr[0]
    frame: bytes = cls(*values).pack(mav)
    return frame


@pytest.mark.parametrize("name", sorted(FIELDS))
@settings(max_examples=300, deadline=None)
@given(data=st.data(), hdr=header)
def test_frames_are_pymavlinks_bytes_and_fields(name: str, data: st.DataObject,
                                                hdr: tuple[int, int, int]) -> None:
    """Encode: the same bytes as pymavlink's pack; decode: the same values as its decode."""
    layout, cls, strategy = FIELDS[name]
    values = data.draw(strategy)
    ref = _pymavlink_frame(cls, values, hdr)
    assert pack_frame(layout, layout.payload(*values), *hdr) == ref
    fields = unpack_fields(ref, layout.msg_id)
    assert fields is not None
    msg = mavlink2.MAVLink(None).decode(bytearray(ref))
    assert tuple(fields._fields) == tuple(cls.fieldnames)
    assert _bits(fields) == _bits(tuple(getattr(msg, n) for n in cls.fieldnames))


def test_an_over_long_payload_is_read_as_pymavlink_reads_it() -> None:
    """A sender with a newer dialect may append extension fields: both ignore the extra bytes."""
    values = (123, *[float(i) for i in range(1, 14)], 0x1FFF, 7)
    frame = _pymavlink_frame(mavlink2.MAVLink_hil_sensor_message, values, (1, 2, 3))
    body = frame[10:-2] + b"\x55\x66"  # two extra payload bytes, CRC redone
    longer = bytearray(frame[:10]) + body
    longer[1] = len(body)
    longer += frame_crc(longer, len(body), HIL_SENSOR.crc_extra_byte[0]).to_bytes(2, "little")
    msg = mavlink2.MAVLink(None).decode(bytearray(longer))
    fields = unpack_fields(bytes(longer), HIL_SENSOR.msg_id)
    assert fields is not None
    assert _bits(fields) == _bits(tuple(getattr(msg, n) for n in fields._fields))


def test_other_messages_are_left_to_pymavlink() -> None:
    assert unpack_fields(b"\xfd" + bytes(20), int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)) is None
    with pytest.raises(ValueError, match="string fields"):
        FastLayout(mavlink2.MAVLink_statustext_message)


# -- the decoder: fast path == pymavlink path --

def _sample_key(sample: Any) -> tuple[Any, ...]:
    out = []
    for f in dataclasses.fields(sample):
        v = getattr(sample, f.name)
        # vectors: their values, and that they are float64 arrays of the same shape
        out.append(repr((type(v).__name__, v.dtype.str, v.shape, v.tolist()))
                   if isinstance(v, np.ndarray) else repr(v))
    return (type(sample).__name__, *out)


def _decode_both(stream: list[bytes], key: bytes | None = None) -> None:
    fast, ref = Decoder(), Decoder()
    if key is not None:  # a link with signing: both take pymavlink's signature check
        for d in (fast, ref):
            d.mav.signing.secret_key = key
    got = [(d.system_id, d.component_id, d.msg_id, _sample_key(d.sample))
           for chunk in stream for d in fast.feed(chunk)]
    want = [(d.system_id, d.component_id, d.msg_id, _sample_key(d.sample))
            for chunk in stream for m in ref.parse(chunk) for d in ref._decode(m)]
    assert got == want
    assert fast.counters == ref.counters


def _flight_frames(rng: random.Random, n: int) -> list[bytes]:
    enc = Encoder(system_id=rng.randint(1, 255))
    frames = []
    for i in range(n):
        t = 10_000 + 5_000 * i
        imu = ImuSample(t, 0.005, np.array([rng.gauss(0, 3), rng.gauss(0, 3), -9.8]),
                        np.array([rng.gauss(0, 0.1) for _ in range(3)]))
        baro = BaroSample(t, 95_000.0 + rng.gauss(0, 50), 280.0) if i % 4 == 0 else None
        mag = MagSample(t, np.array([2e-5, 1e-6, 4e-5])) if i % 2 == 0 else None
        frames.append(enc.sensors(imu, baro, mag,
                                  diff_pressure_pa=600.0 + i if i % 5 == 0 else None))
        if i % 4 == 0:
            frames.append(enc.actuators(ActuatorSample(t, (rng.uniform(-1, 1), 0.1, 0.0, 0.7))))
            frames.append(enc.rpm(RpmSample(t, 2400.0 + i)))
        if i % 4 == 2:
            q = np.array([rng.uniform(-1, 1) for _ in range(4)])
            frames.append(enc.truth(Truth(
                t, math.radians(47.0), math.radians(8.0 + 1e-6 * i), 1000.0 + rng.gauss(0, 5),
                np.array([50.0, rng.gauss(0, 3), 0.5]), q / np.linalg.norm(q),
                np.array([0.01, -0.02, 0.1]), np.array([0.3, 0.1, -9.7]), 90_000.0, 280.0,
                50.0 + i * 0.01, 48.0)))
        if i % 40 == 0:
            frames.append(enc.gnss(GnssFix(
                t - 2_000, math.radians(47.0 + 1e-5 * i), math.radians(8.0), 500.0 + 0.1 * i,
                np.array([50.0, -3.0, 0.5]), 1.5, math.nan if i % 80 else 2.5, math.nan, 3,
                12)))
    return frames


def _damaged(rng: random.Random, frames: list[bytes], p_garbage: float) -> list[bytes]:
    """Each frame: one byte changed (p 0.1), cut short (0.05), garbage before it
    (``p_garbage``), or intact."""
    out = []
    for f in frames:
        b = bytearray(f)
        r = rng.random()
        if r < 0.1:
            b[rng.randrange(len(b))] = rng.randrange(256)
        elif r < 0.15:
            b = b[: rng.randrange(1, len(b))]
        elif r < 0.15 + p_garbage:
            b = bytearray(rng.randbytes(rng.randrange(1, 40))) + b
        out.append(bytes(b))
    return out


def test_decoder_fast_path_equals_pymavlink_on_a_clean_stream() -> None:
    frames = _flight_frames(random.Random(1), 400)
    _decode_both(frames)
    _decode_both([b"".join(frames)])  # one chunk


def test_decoder_fast_path_equals_pymavlink_on_signed_frames() -> None:
    """Signed frames (and a configured key) take pymavlink's path; the result is the same."""
    frames = _flight_frames(random.Random(2), 100)
    key = bytes(range(32))
    mav = mavlink2.MAVLink(None)
    mav.signing.secret_key = key
    mav.signing.sign_outgoing = True
    mav.signing.link_id = 1
    mav.signing.timestamp = 1_000_000
    signed = []
    plain = mavlink2.MAVLink(None)
    for f in frames:
        m = plain.decode(bytearray(f))
        mav.srcSystem, mav.srcComponent, mav.seq = f[5], f[6], f[4]
        signed.append(m.pack(mav, force_mavlink1=False))
    _decode_both(signed)  # no key: signed frames accepted, as pymavlink does
    _decode_both(signed + frames, key=key)  # key: unsigned frames refused, counted alike


@pytest.mark.parametrize("name", sorted(FIELDS))
@settings(max_examples=150, deadline=None)
@given(data=st.data(), hdr=header,
       change=st.one_of(st.none(), st.tuples(st.integers(0, 300), u8)))
def test_decoder_on_single_frames_equals_pymavlink(name: str, data: st.DataObject,
                                                   hdr: tuple[int, int, int],
                                                   change: tuple[int, int] | None) -> None:
    """One frame per ``feed`` (the framing's whole-frame shortcut, then the fast unpack):
    random field values and header, optionally one byte of the first frame changed (its CRC,
    length, flags or id then no longer hold, or they do by chance): the same samples and
    counters as pymavlink's path."""
    _layout, cls, strategy = FIELDS[name]
    frames = [_pymavlink_frame(cls, data.draw(strategy), hdr) for _ in range(3)]
    if change is not None:
        pos, byte = change
        b = bytearray(frames[0])
        b[pos % len(b)] = byte
        frames[0] = bytes(b)
    _decode_both(frames)


@pytest.mark.parametrize("seed", [6, 7])
def test_decoder_fast_path_equals_pymavlink_frame_by_frame_when_damaged(seed: int) -> None:
    """Damaged frames fed one per call (as datagrams arrive): cut ones leave bytes in the
    parser, so the next call takes the scan, not the whole-frame shortcut; same result."""
    rng = random.Random(seed)
    _decode_both(_damaged(rng, _flight_frames(rng, 300), p_garbage=0.0))


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_decoder_fast_path_equals_pymavlink_on_damaged_streams(seed: int) -> None:
    """Byte mutations, cuts and garbage: the same samples survive, the same drops are counted."""
    rng = random.Random(seed)
    stream = b"".join(_damaged(rng, _flight_frames(rng, 300), p_garbage=0.05))
    cuts = sorted(rng.sample(range(1, len(stream)), 50))
    chunks = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    _decode_both(chunks)


# -- the encoder: plain float64 inputs (its guarded fast checks) == the checked path --

# Finite values of every size, the float32 and int16 edges, NaN and infinities.
f64 = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                st.sampled_from([3.4028234663852886e38, 3.5e38, -3.5e38, 327.67, 327.675,
                                 -327.68, -327.685, 0.0, -0.0, 655.34, 655.345]))


def _outcome(encode: Any) -> tuple[Any, ...]:
    """(bytes, saturations) of one encode, or its error message."""
    enc = Encoder()
    try:
        return encode(enc), dict(enc.saturations)
    except ValueError as err:
        return ("ValueError", str(err))


@settings(max_examples=300, deadline=None)
@given(t=st.one_of(u64, st.integers(-5, -1)), sid=st.integers(-1, 256),
       f=st.lists(f64, min_size=3, max_size=3), w=st.lists(f64, min_size=3, max_size=3))
def test_encoder_sensors_plain_arrays_equal_the_checked_path(
        t: int, sid: int, f: list[float], w: list[float]) -> None:
    """An IMU frame from float64 arrays (the guarded fast checks) has the bytes, the
    saturation counts and the errors of the same values given as lists (the checked path)."""
    fast = _outcome(lambda e: e.sensors(ImuSample(t, 0.005, np.array(f), np.array(w), 288.0,
                                                  sid)))
    checked = _outcome(lambda e: e.sensors(ImuSample(t, 0.005, list(f), list(w), 288.0,  # type: ignore[arg-type]
                                                     sid)))
    assert _bits(fast) == _bits(checked)


@settings(max_examples=300, deadline=None)
@given(lat=f64, lon=f64, alt=f64, v=st.lists(f64, min_size=3, max_size=3), eph=f64, epv=f64,
       ids=st.tuples(st.integers(-1, 256), st.integers(-1, 256), st.integers(-1, 256)))
def test_encoder_gnss_plain_floats_equal_the_checked_path(
        lat: float, lon: float, alt: float, v: list[float], eph: float, epv: float,
        ids: tuple[int, int, int]) -> None:
    """A HIL_GPS frame from plain floats and a float64 array (the guarded fast checks) has
    the bytes, saturation counts and errors of the same values as numpy scalars and a list
    (the checked path)."""
    fix_type, sats, sid = ids
    fast = _outcome(lambda e: e.gnss(GnssFix(7, lat, lon, alt, np.array(v), eph, epv,
                                             math.nan, fix_type, sats, sid)))
    n = np.float64
    checked = _outcome(lambda e: e.gnss(GnssFix(
        7, n(lat), n(lon), n(alt), list(v), n(eph), n(epv),  # type: ignore[arg-type]
        math.nan, fix_type, sats, sid)))
    assert _bits(fast) == _bits(checked)
