"""hil.codec.Decoder on a byte stream: unknown ids, bad CRCs, garbage, any split of the
stream, signed frames, damaged and MAVLink 1 frames, and the IMU interval it infers."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.codec import (
    DEFAULT_FIRST_IMU_DT_S,
    TRUTH_COMPONENT_ID,
    Decoded,
    Decoder,
    Encoder,
    HilSensorField,
    mavlink2,
)
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Truth
from tests.hil.codec_helpers import FAST, one, parse_raw


# --- stream robustness ---------------------------------------------------------------------
def _frames() -> tuple[list[bytes], int]:
    """A mixed stream: 20 IMU frames, baro/mag every 5th, a GNSS fix and truth every 10th."""
    enc = Encoder()
    parts = []
    n_samples = 0
    for k in range(20):
        t = 1_000_000 + 4000 * k
        imu = ImuSample(t, 0.004, np.array([0.1 * k, -0.2, -9.8]), np.array([0.01, 0.0, -0.02 * k]))
        if k % 5 == 0:
            parts.append(
                enc.sensors(
                    imu,
                    BaroSample(t, 95_000.0 + k, 280.0),
                    MagSample(t, np.array([2e-5, 1e-6, 4e-5])),
                )
            )
            n_samples += 3
        else:
            parts.append(enc.sensors(imu))
            n_samples += 1
        if k % 10 == 0:
            parts.append(
                enc.gnss(GnssFix(t, 0.8, 0.1, 500.0, np.array([50.0, 1.0, -0.5]), 1.5, 2.5, 0.1))
            )
            parts.append(
                enc.truth(
                    Truth(
                        t,
                        0.8,
                        0.1,
                        500.0,
                        np.array([50.0, 1.0, -0.5]),
                        np.array([1.0, 0, 0, 0]),
                        np.zeros(3),
                        np.array([0, 0, -9.8]),
                        9.5e4,
                        280.0,
                        50.0,
                        48.0,
                    )
                )
            )
            n_samples += 2
    return parts, n_samples


def _stream() -> tuple[bytes, int]:
    parts, n_samples = _frames()
    return b"".join(parts), n_samples


def _key(items: list[Decoded]) -> list[str]:
    return [repr(d) for d in items]


def test_scenario_statustext_comes_from_the_truth_component_and_gives_no_sample() -> None:
    enc = Encoder(system_id=3)
    frame = enc.statustext(int(mavlink2.MAV_SEVERITY_NOTICE), "SIM: GNSS off for 20 s " + "x" * 40)
    m = parse_raw(frame)
    assert (m.get_srcSystem(), m.get_srcComponent()) == (3, TRUTH_COMPONENT_ID)
    assert m.severity == mavlink2.MAV_SEVERITY_NOTICE
    assert m.text == ("SIM: GNSS off for 20 s " + "x" * 40)[:50]  # the message's 50 chars
    dec = Decoder()
    assert dec.feed(frame) == [] and dec.counters.ignored_msgs == 1  # no sample from it
    with pytest.raises(ValueError, match="severity"):
        enc.statustext(8, "x")


def test_unknown_message_id_is_counted_and_dropped() -> None:
    frames, n = _frames()
    # A well-formed MAVLink 2 frame with an id no dialect defines (pymavlink cannot CRC it).
    payload = b"\x01\x02\x03\x04"
    unknown = (
        bytes([0xFD, len(payload), 0, 0, 9, 1, 1])
        + (60_123).to_bytes(3, "little")
        + payload
        + b"\x00\x00"
    )
    assert 60_123 not in mavlink2.mavlink_map
    half = len(frames) // 2
    dec = Decoder()
    items = dec.feed(b"".join([*frames[:half], unknown, *frames[half:]]))
    assert len(items) == n
    assert dec.counters.unknown_msg_id == 1
    assert dec.counters.bad_crc == 0 and dec.counters.garbage_bytes == 0


def test_bad_crc_is_counted_and_dropped() -> None:
    enc = Encoder()
    imu = ImuSample(0, 0.004, np.zeros(3), np.zeros(3))
    good1, bad, good2 = (
        enc.sensors(imu),
        bytearray(enc.sensors(ImuSample(4000, 0.004, np.ones(3), np.zeros(3)))),
        enc.sensors(ImuSample(8000, 0.004, np.zeros(3), np.zeros(3))),
    )
    bad[12] ^= 0x40  # corrupt one payload bit
    dec = Decoder()
    items = dec.feed(good1 + bytes(bad) + good2)
    assert [d.sample.time_us for d in items] == [0, 8000]
    assert dec.counters.bad_crc == 1
    assert dec.counters.frames_ok == 2
    # The dropped frame leaves a gap in the IMU time series, visible in dt.
    after_gap = items[1].sample
    assert isinstance(after_gap, ImuSample) and after_gap.dt_s == pytest.approx(0.008)


def test_garbage_between_frames_is_counted() -> None:
    stream, n = _stream()
    dec = Decoder()
    items = dec.feed(b"\x00\x11\x22" + stream + b"\x42" * 5)
    assert len(items) == n
    assert dec.counters.garbage_bytes == 8


@FAST
@given(cuts=st.lists(st.integers(0, 10_000), max_size=30))
def test_stream_split_at_any_byte_boundary_gives_same_samples(cuts: list[int]) -> None:
    stream, n = _stream()
    stream = b"\x07garbage" + stream
    whole = Decoder(imu_dt_s=0.004)
    expected = whole.feed(stream)
    assert len(expected) == n
    pieces = sorted({c % (len(stream) + 1) for c in cuts} | {0, len(stream)})
    split = Decoder(imu_dt_s=0.004)
    got: list[Decoded] = []
    for a, b in itertools.pairwise(pieces):
        got.extend(split.feed(stream[a:b]))
    assert _key(got) == _key(expected)
    assert split.counters == whole.counters


@FAST
@given(cuts=st.lists(st.integers(0, 10_000), max_size=30))
def test_feed_all_is_feed_of_each_chunk_in_turn(cuts: list[int]) -> None:
    """GIVEN a stream with garbage, a damaged frame, an unknown id and a MAVLink 1 frame
    (pymavlink's path) cut anywhere WHEN the pieces go through one ``feed_all`` call and
    through one ``feed`` per piece THEN the same samples, in the same order, and the same
    counters (the lockstep sink decodes its batches with ``feed_all``)."""
    frames, _n = _frames()
    bad = bytearray(frames[3])
    bad[12] ^= 0x40
    unknown = bytes([0xFD, 4, 0, 0, 9, 1, 1]) + (60_123).to_bytes(3, "little") + bytes(6)
    v1 = mavlink2.MAVLink_scaled_pressure_message(1200, 1002.5, 0.0, 2100).pack(
        mavlink2.MAVLink(None, srcSystem=1, srcComponent=1), force_mavlink1=True)
    stream = b"".join([b"\x07garbage", *frames[:3], bytes(bad), unknown, v1, *frames[3:]])
    pieces = sorted({c % (len(stream) + 1) for c in cuts} | {0, len(stream)})
    chunks = [stream[a:b] for a, b in itertools.pairwise(pieces)]
    one_by_one = Decoder(imu_dt_s=0.004)
    expected = [d for c in chunks for d in one_by_one.feed(c)]
    batched = Decoder(imu_dt_s=0.004)
    got = batched.feed_all(iter(chunks))
    assert _key(got) == _key(expected) and len(got) > 30
    assert batched.counters == one_by_one.counters
    assert batched.counters.bad_crc == 1 and batched.counters.unknown_msg_id == 1


def test_signed_frames_decode_and_bad_signatures_are_rejected() -> None:
    sender = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    sender.signing.secret_key = b"k" * 32
    sender.signing.sign_outgoing = True
    sender.signing.timestamp = 1
    frame = mavlink2.MAVLink_scaled_pressure_message(10, 1000.0, 0.0, 2000).pack(sender)
    assert frame[2] & 0x01 and len(frame) == 10 + frame[1] + 2 + 13
    (b,) = one(Decoder(), frame)  # no key configured: signature not checked
    assert b.pressure_pa == pytest.approx(100_000.0)
    strict = Decoder()
    strict.mav.signing.secret_key = b"x" * 32
    assert strict.feed(frame) == []
    assert strict.counters.bad_signature == 1


def _imu_frames(n: int) -> list[bytes]:
    enc = Encoder()
    out = []
    for k in range(n):
        t = 1_000_000 + 5_000 * k
        imu = ImuSample(t, 0.005, np.array([0.1, -0.2, -9.8]), np.array([0.01, 0.0, -0.02]))
        out.append(enc.sensors(imu, time_us=t))
    return out


def test_damage_costs_the_decoder_only_the_damaged_frame() -> None:
    # GIVEN 2,000 good HIL_SENSOR frames after one damaged one (cut in half, or its length byte
    # hit), fed as a tlog replay feeds them (one record per call) and as one byte stream
    frames = _imu_frames(2001)
    hit = bytearray(frames[0])
    hit[1] = 255
    cut = [frames[0][: len(frames[0]) // 2], *frames[1:]]
    for chunks in (cut, [b"".join(cut)], [bytes(hit), *frames[1:]]):
        dec = Decoder()
        got = [d for c in chunks for d in dec.feed(c)]
        # THEN every one of the 2,000 good frames is decoded
        assert len(got) == 2000
        assert dec.counters.frames_ok == 2000
        assert dec.counters.garbage_bytes + dec.counters.bad_crc >= 1


def test_decoder_keeps_mavlink1_frames_of_a_mixed_link() -> None:
    # GIVEN a MAVLink 1 SCALED_PRESSURE between two MAVLink 2 ones
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    msg = mavlink2.MAVLink_scaled_pressure_message(1200, 1002.5, 0.0, 2100)
    stream = msg.pack(mav) + msg.pack(mav, force_mavlink1=True) + msg.pack(mav)
    dec = Decoder()
    got = dec.feed(stream)
    # THEN all three are decoded
    assert len(got) == 3 and all(isinstance(d.sample, BaroSample) for d in got)


# --- IMU interval inference ----------------------------------------------------------------
def test_imu_dt_inferred_per_source_with_duplicates_and_resets() -> None:
    enc = Encoder()
    enc2 = Encoder(sensor_component_id=201, truth_component_id=26)

    def frame(e: Encoder, t: int, sensor_id: int = 0) -> bytes:
        return e.sensors(ImuSample(t, 0.0, np.zeros(3), np.zeros(3), sensor_id=sensor_id))

    dec = Decoder()
    stream = [
        frame(enc, 1000),
        frame(enc2, 500),
        frame(enc, 5000),
        frame(enc, 1000, sensor_id=1),
        frame(enc, 9000),
        frame(enc, 9000),
        frame(enc2, 2500),
        frame(enc, 3000),
        frame(enc, 7000),
    ]
    dts = [d.sample.dt_s for f in stream for d in dec.feed(f) if isinstance(d.sample, ImuSample)]
    assert dts == pytest.approx([DEFAULT_FIRST_IMU_DT_S, 0.0, 0.004, 0.0, 0.004, 0.002, 0.0, 0.004])
    assert dec.counters.imu_duplicates == 1
    assert dec.counters.imu_time_resets == 1
    with pytest.raises(ValueError, match="imu_dt_s"):
        Decoder(imu_dt_s=-1.0)


def test_partial_fields_and_sim_reset_bit() -> None:
    mav = mavlink2.MAVLink(None, 1, 200)
    accel_only = mavlink2.MAVLink_hil_sensor_message(
        100,
        1,
        2,
        3,
        4,
        5,
        6,
        0.1,
        0.2,
        0.3,
        1000.0,
        0,
        0,
        20.0,
        HilSensorField.ACCEL | HilSensorField.XMAG | HilSensorField.ABS_PRESSURE,
        0,
    ).pack(mav)
    dec = Decoder()
    (baro,) = one(dec, accel_only)  # only the complete baro group survives
    assert isinstance(baro, BaroSample) and math.isnan(baro.temperature_k)
    assert dec.counters.incomplete_fields == 2
    # Temperature seen once is remembered for later frames of that source (PX4 behaviour).
    with_temp = mavlink2.MAVLink_hil_sensor_message(
        200,
        1,
        2,
        3,
        4,
        5,
        6,
        0,
        0,
        0,
        1000.0,
        0,
        0,
        20.0,
        HilSensorField.IMU | HilSensorField.BARO,
        0,
    ).pack(mav)
    reset = mavlink2.MAVLink_hil_sensor_message(
        100, 1, 2, 3, 4, 5, 6, 0, 0, 0, 0, 0, 0, 0, HilSensorField.IMU | HilSensorField.SIM_RESET, 0
    ).pack(mav)
    imu1, _ = one(dec, with_temp)
    (imu2,) = one(dec, reset)
    assert imu1.temperature_k == pytest.approx(293.15)
    assert imu2.temperature_k == pytest.approx(293.15)
    assert imu2.dt_s == DEFAULT_FIRST_IMU_DT_S  # the reset bit restarts the interval
    assert dec.counters.sim_resets == 1 and dec.counters.imu_time_resets == 0
