"""hil.codec: SI <-> MAVLink round trips within the wire quantisation, stream robustness,
and decoding of the messages a real flight controller sends."""

from __future__ import annotations

import itertools
import math
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from hil.codec import (
    DEFAULT_FIRST_IMU_DT_S,
    SENSOR_COMPONENT_ID,
    TRUTH_COMPONENT_ID,
    Decoded,
    Decoder,
    Encoder,
    HilSensorField,
    RawImuScale,
    mavlink2,
)
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Truth

G0 = 9.80665
DEGE7_PER_RAD = 1e7 * 180.0 / math.pi
FAST = settings(max_examples=60, deadline=None)


# --- wire quantisation: the tolerance of every round trip ----------------------------------
def f32_tol(si_value: float, si_per_wire: float, offset: float = 0.0) -> float:
    """Largest SI error of a float32 wire field: half a float32 ulp of the wire value, in SI,
    plus a few float64 ulps for the unit conversion arithmetic."""
    wire = (si_value - offset) / si_per_wire
    half_ulp = float(np.spacing(np.float32(abs(wire)))) / 2.0
    return half_ulp * si_per_wire + 4.0 * float(np.spacing(abs(si_value) + abs(offset)))


def int_tol(si_per_count: float, si_value: float = 0.0) -> float:
    """Largest SI error of an integer wire field: half a count, plus float64 slack."""
    return 0.5 * si_per_count + 4.0 * float(np.spacing(abs(si_value) + 1.0))


def assert_f32_close(
    got: ArrayLike, want: ArrayLike, si_per_wire: float, offset: float = 0.0
) -> None:
    for g, w in zip(np.atleast_1d(got), np.atleast_1d(want), strict=True):
        assert abs(g - w) <= f32_tol(float(w), si_per_wire, offset), (g, w)


def assert_int_close(got: ArrayLike, want: ArrayLike, si_per_count: float) -> None:
    for g, w in zip(np.atleast_1d(got), np.atleast_1d(want), strict=True):
        assert abs(g - w) <= int_tol(si_per_count, float(w)), (g, w)


def angle_diff(a: float, b: float) -> float:
    return (a - b + math.pi) % (2 * math.pi) - math.pi


# --- strategies ----------------------------------------------------------------------------
def floats(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def vec3(lo: float, hi: float) -> st.SearchStrategy[np.ndarray]:
    return st.tuples(floats(lo, hi), floats(lo, hi), floats(lo, hi)).map(
        lambda t: np.array(t, dtype=np.float64)
    )


times = st.integers(0, 2**63)
imus = st.builds(
    ImuSample,
    time_us=st.just(0),
    dt_s=st.just(0.004),
    specific_force_b_mps2=vec3(-200.0, 200.0),
    angular_rate_b_rps=vec3(-30.0, 30.0),
)
baros = st.builds(
    BaroSample,
    time_us=st.just(0),
    pressure_pa=floats(1.0, 120_000.0),
    temperature_k=floats(180.0, 340.0),
)
mags = st.builds(MagSample, time_us=st.just(0), field_b_tesla=vec3(-1e-4, 1e-4))
fixes = st.builds(
    GnssFix,
    time_us=times,
    lat_rad=floats(-math.pi / 2, math.pi / 2),
    lon_rad=floats(-math.pi, math.pi),
    alt_msl_m=floats(-1000.0, 30_000.0),
    v_ned_mps=vec3(-300.0, 300.0),
    eph_m=st.one_of(floats(0.0, 600.0), st.just(math.nan)),
    epv_m=st.one_of(floats(0.0, 600.0), st.just(math.inf)),
    speed_accuracy_mps=floats(0.0, 10.0),
    fix_type=st.integers(0, 6),
    satellites_visible=st.integers(0, 255),
    sensor_id=st.integers(0, 255),
)


def _quat(t: tuple[float, float, float, float]) -> np.ndarray:
    q = np.array(t, dtype=np.float64)
    n = np.linalg.norm(q)
    return q / n if n > 1e-3 else np.array([1.0, 0.0, 0.0, 0.0])


truths = st.builds(
    Truth,
    time_us=times,
    lat_rad=floats(-math.pi / 2, math.pi / 2),
    lon_rad=floats(-math.pi, math.pi),
    alt_msl_m=floats(-1000.0, 30_000.0),
    v_ned_mps=vec3(-320.0, 320.0),
    q_nb=st.tuples(*(floats(-1.0, 1.0) for _ in range(4))).map(_quat),
    omega_b_rps=vec3(-10.0, 10.0),
    specific_force_b_mps2=vec3(-300.0, 300.0),
    static_pressure_pa=floats(1.0, 120_000.0),
    temperature_k=floats(180.0, 340.0),
    airspeed_mps=floats(0.0, 600.0),
    indicated_airspeed_mps=floats(0.0, 600.0),
)


def one(decoder: Decoder, frame: bytes) -> list[Any]:
    return [d.sample for d in decoder.feed(frame)]


def parse_raw(frame: bytes) -> Any:
    mav = mavlink2.MAVLink(None)
    msgs = mav.parse_buffer(frame)
    assert msgs is not None and len(msgs) == 1
    return msgs[0]


# --- HIL_SENSOR ----------------------------------------------------------------------------
@FAST
@given(
    imu=st.one_of(st.none(), imus),
    baro=st.one_of(st.none(), baros),
    mag=st.one_of(st.none(), mags),
    diff=st.one_of(st.none(), floats(-5000.0, 5000.0)),
    t=times,
    sensor_id=st.integers(0, 255),
)
def test_hil_sensor_round_trip_within_float32_quantisation(
    imu: ImuSample | None,
    baro: BaroSample | None,
    mag: MagSample | None,
    diff: float | None,
    t: int,
    sensor_id: int,
) -> None:
    imu = (
        None
        if imu is None
        else ImuSample(
            t, 0.004, imu.specific_force_b_mps2, imu.angular_rate_b_rps, sensor_id=sensor_id
        )
    )
    baro = None if baro is None else BaroSample(t, baro.pressure_pa, baro.temperature_k, sensor_id)
    mag = None if mag is None else MagSample(t, mag.field_b_tesla, sensor_id)
    if imu is None and baro is None and mag is None and diff is None:
        with pytest.raises(ValueError, match="at least one"):
            Encoder().sensors(None)
        return
    frame = Encoder().sensors(imu, baro, mag, time_us=t, diff_pressure_pa=diff)

    # fields_updated has exactly the bits of what was given.
    raw = parse_raw(frame)
    want_bits = (
        (HilSensorField.IMU if imu else 0)
        | (HilSensorField.MAG if mag else 0)
        | (HilSensorField.BARO if baro else 0)
        | (HilSensorField.DIFF_PRESSURE if diff is not None else 0)
    )
    assert raw.fields_updated == want_bits
    # With only a differential pressure there is no sample to take an id from: id 0.
    assert raw.time_usec == t
    assert raw.id == (sensor_id if (imu or baro or mag) else 0)
    if diff is not None:
        assert_f32_close(raw.diff_pressure * 100.0, diff, 100.0)

    got = one(Decoder(imu_dt_s=0.01), frame)
    kinds = [type(s) for s in got]
    given = ((ImuSample, imu), (MagSample, mag), (BaroSample, baro))
    want = [k for k, s in given if s] + ([AirspeedSample] if diff is not None else [])
    assert kinds == want
    for s in got:
        assert s.time_us == t and s.sensor_id == raw.id
        if isinstance(s, ImuSample):
            assert imu is not None
            assert_f32_close(s.specific_force_b_mps2, imu.specific_force_b_mps2, 1.0)
            assert_f32_close(s.angular_rate_b_rps, imu.angular_rate_b_rps, 1.0)
            assert s.dt_s == 0.01  # first sample of the source: the configured imu_dt_s
            if baro is None:  # the IMU's own temperature is not on the wire
                assert math.isnan(s.temperature_k)
            else:
                assert s.temperature_k == pytest.approx(baro.temperature_k, abs=1e-4)
        elif isinstance(s, MagSample):
            assert mag is not None
            assert_f32_close(s.field_b_tesla, mag.field_b_tesla, 1e-4)
        elif isinstance(s, AirspeedSample):
            assert diff is not None
            assert_f32_close(s.diff_pressure_pa, diff, 100.0)
        else:
            assert baro is not None
            assert_f32_close(s.pressure_pa, baro.pressure_pa, 100.0)
            assert_f32_close(s.temperature_k, baro.temperature_k, 1.0, offset=273.15)


def test_pressure_quantisation_at_sea_level_is_millipascal() -> None:
    # Documented in hil.codec: float32 hPa costs <= 6.1e-3 Pa near 1013 hPa.
    errors = []
    for p in np.linspace(101_000.0, 103_000.0, 2001):
        frame = Encoder().sensors(None, BaroSample(0, float(p), 288.15))
        (b,) = one(Decoder(), frame)
        errors.append(abs(b.pressure_pa - p))
    assert max(errors) <= 2.0**-13 * 100.0 / 2.0 + 1e-9
    assert max(errors) > 0.0  # the quantisation is real, not a no-op


def test_hil_sensor_frame_time_and_id_must_agree() -> None:
    enc = Encoder()
    imu = ImuSample(1000, 0.004, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"baro.time_us"):
        enc.sensors(imu, BaroSample(2000, 1e5, 288.0))
    with pytest.raises(ValueError, match=r"mag.sensor_id"):
        enc.sensors(imu, mag=MagSample(1000, np.zeros(3), sensor_id=1))
    # An explicit time_us overrides the samples' own times.
    (s, b) = one(Decoder(), enc.sensors(imu, BaroSample(2000, 1e5, 288.0), time_us=1500))
    assert s.time_us == b.time_us == 1500


@pytest.mark.parametrize(
    ("sample", "match"),
    [
        (ImuSample(0, 0.004, np.array([np.nan, 0, 0]), np.zeros(3)), "imu.specific_force_b_mps2"),
        (ImuSample(0, 0.004, np.zeros(3), np.zeros(2)), "imu.angular_rate_b_rps"),
        (ImuSample(-1, 0.004, np.zeros(3), np.zeros(3)), "imu.time_us"),
        (BaroSample(0, -5.0, 288.0), "baro.pressure_pa"),
        (BaroSample(0, 1e5, math.inf), "baro.temperature_k"),
        (MagSample(0, np.array([0, math.inf, 0])), "mag.field_b_tesla"),
    ],
)
def test_sensors_bad_input_names_the_field(sample: Any, match: str) -> None:
    enc = Encoder()
    with pytest.raises(ValueError, match=match):
        if isinstance(sample, ImuSample):
            enc.sensors(sample)
        elif isinstance(sample, BaroSample):
            enc.sensors(None, baro=sample)
        else:
            enc.sensors(None, mag=sample)


def test_float32_overflow_is_clipped_and_counted() -> None:
    enc = Encoder()
    imu = ImuSample(0, 0.004, np.array([1e39, 0.0, -1e40]), np.zeros(3))
    raw = parse_raw(enc.sensors(imu))
    assert raw.xacc == pytest.approx(float(np.finfo(np.float32).max))
    assert raw.zacc == pytest.approx(-float(np.finfo(np.float32).max))
    assert enc.saturations == {"HIL_SENSOR.xacc": 1, "HIL_SENSOR.zacc": 1}


# --- HIL_GPS -------------------------------------------------------------------------------
@FAST
@given(fix=fixes)
def test_hil_gps_round_trip_within_integer_quantisation(fix: GnssFix) -> None:
    enc = Encoder()
    frame = enc.gnss(fix)
    assert not enc.saturations  # the strategy stays inside every wire range
    (got,) = one(Decoder(), frame)
    assert isinstance(got, GnssFix)
    assert got.time_us == fix.time_us
    assert abs(got.lat_rad - fix.lat_rad) <= int_tol(1 / DEGE7_PER_RAD, fix.lat_rad)
    assert abs(angle_diff(got.lon_rad, fix.lon_rad)) <= int_tol(1 / DEGE7_PER_RAD, fix.lon_rad)
    assert abs(got.alt_msl_m - fix.alt_msl_m) <= int_tol(1e-3, fix.alt_msl_m)
    assert_int_close(got.v_ned_mps, fix.v_ned_mps, 1e-2)
    for got_acc, want_acc in ((got.eph_m, fix.eph_m), (got.epv_m, fix.epv_m)):
        if math.isfinite(want_acc):
            assert abs(got_acc - want_acc) <= int_tol(1e-2, want_acc)
        else:
            assert math.isnan(got_acc)  # unknown stays unknown
    assert math.isnan(got.speed_accuracy_mps)  # HIL_GPS has no such field
    assert (got.fix_type, got.satellites_visible, got.sensor_id) == (
        fix.fix_type,
        fix.satellites_visible,
        fix.sensor_id,
    )
    raw = parse_raw(frame)
    speed = math.hypot(fix.v_ned_mps[0], fix.v_ned_mps[1])
    assert abs(raw.vel / 100.0 - speed) <= int_tol(1e-2, speed)
    if raw.vel > 0:
        course = math.degrees(math.atan2(fix.v_ned_mps[1], fix.v_ned_mps[0])) % 360.0
        assert abs(((raw.cog / 100.0 - course) + 180.0) % 360.0 - 180.0) <= 0.005 + 1e-9
    assert raw.yaw == 0


def test_hil_gps_eph_is_centimetres_of_accuracy_px4_convention() -> None:
    fix = GnssFix(
        5, 0.5, 0.1, 100.0, np.zeros(3), eph_m=1.23, epv_m=math.nan, speed_accuracy_mps=0.2
    )
    raw = parse_raw(Encoder().gnss(fix))
    assert raw.eph == 123
    assert raw.epv == 65535  # UINT16_MAX: unknown
    assert raw.cog == 65535  # zero ground speed: course unknown


def test_hil_gps_saturates_and_counts() -> None:
    enc = Encoder()
    fix = GnssFix(0, 0.5, 0.1, 100.0, np.array([400.0, -500.0, 1.0]), 1000.0, 2.0, 0.2)
    raw = parse_raw(enc.gnss(fix))
    assert (raw.vn, raw.ve, raw.vd) == (32767, -32768, 100)
    assert raw.eph == 65534  # largest known accuracy; 65535 would mean "unknown"
    assert enc.saturations == {"HIL_GPS.vn": 1, "HIL_GPS.ve": 1, "HIL_GPS.eph": 1}


def test_hil_gps_bad_input() -> None:
    enc = Encoder()
    base = GnssFix(0, 0.5, 0.1, 100.0, np.zeros(3), 1.0, 2.0, 0.2)
    with pytest.raises(ValueError, match=r"fix\.lat_rad"):
        enc.gnss(GnssFix(0, 1.6, 0.1, 100.0, np.zeros(3), 1.0, 2.0, 0.2))
    with pytest.raises(ValueError, match=r"fix\.eph_m"):
        enc.gnss(GnssFix(0, 0.5, 0.1, 100.0, np.zeros(3), -1.0, 2.0, 0.2))
    with pytest.raises(ValueError, match=r"fix\.fix_type"):
        enc.gnss(GnssFix(0, 0.5, 0.1, 100.0, np.zeros(3), 1.0, 2.0, 0.2, fix_type=300))
    with pytest.raises(ValueError, match=r"fix\.alt_msl_m"):
        enc.gnss(GnssFix(0, 0.5, 0.1, math.nan, np.zeros(3), 1.0, 2.0, 0.2))
    assert enc.gnss(base)  # the valid one still encodes


# --- HIL_STATE_QUATERNION ------------------------------------------------------------------
@FAST
@given(truth=truths)
def test_hil_state_quaternion_round_trip(truth: Truth) -> None:
    enc = Encoder(system_id=7)
    frame = enc.truth(truth)
    assert not enc.saturations
    (item,) = Decoder().feed(frame)
    assert (item.system_id, item.component_id, item.msg_id) == (7, TRUTH_COMPONENT_ID, 115)
    got = item.sample
    assert isinstance(got, Truth)
    assert got.time_us == truth.time_us
    assert abs(got.lat_rad - truth.lat_rad) <= int_tol(1 / DEGE7_PER_RAD, truth.lat_rad)
    assert abs(angle_diff(got.lon_rad, truth.lon_rad)) <= int_tol(1 / DEGE7_PER_RAD, truth.lon_rad)
    assert abs(got.alt_msl_m - truth.alt_msl_m) <= int_tol(1e-3, truth.alt_msl_m)
    assert_int_close(got.v_ned_mps, truth.v_ned_mps, 1e-2)
    assert_f32_close(got.q_nb, truth.q_nb, 1.0)
    assert_f32_close(got.omega_b_rps, truth.omega_b_rps, 1.0)
    assert_int_close(got.specific_force_b_mps2, truth.specific_force_b_mps2, G0 * 1e-3)
    assert abs(got.airspeed_mps - truth.airspeed_mps) <= int_tol(1e-2, truth.airspeed_mps)
    assert abs(got.indicated_airspeed_mps - truth.indicated_airspeed_mps) <= int_tol(1e-2, 600.0)
    assert math.isnan(got.static_pressure_pa) and math.isnan(got.temperature_k)


def test_truth_clips_int16_velocity_and_negative_airspeed() -> None:
    enc = Encoder()
    truth = Truth(
        0,
        0.5,
        0.1,
        100.0,
        np.array([350.0, 0.0, -400.0]),
        np.array([1.0, 0, 0, 0]),
        np.zeros(3),
        np.array([0.0, 0.0, -400.0]),
        1e5,
        288.0,
        -1.0,
        10.0,
    )
    (got,) = one(Decoder(), enc.truth(truth))
    assert got.v_ned_mps.tolist() == [327.67, 0.0, -327.68]
    assert got.airspeed_mps == 0.0
    assert got.specific_force_b_mps2[2] == pytest.approx(-32768 * G0 * 1e-3)
    assert enc.saturations == {
        "HIL_STATE_QUATERNION.vx": 1,
        "HIL_STATE_QUATERNION.vz": 1,
        "HIL_STATE_QUATERNION.zacc": 1,
        "HIL_STATE_QUATERNION.true_airspeed": 1,
    }


def test_components_and_sequence_numbers() -> None:
    enc = Encoder(system_id=3)
    imu = ImuSample(0, 0.004, np.zeros(3), np.zeros(3))
    truth = Truth(
        0,
        0.5,
        0.1,
        1.0,
        np.zeros(3),
        np.array([1.0, 0, 0, 0]),
        np.zeros(3),
        np.zeros(3),
        1e5,
        288.0,
        0.0,
        0.0,
    )
    frames = [
        enc.sensors(imu),
        enc.truth(truth),
        enc.gnss(GnssFix(0, 0.5, 0.1, 1.0, np.zeros(3), 1, 1, 1)),
        enc.truth(truth),
    ]
    raws = [parse_raw(f) for f in frames]
    assert [(m.get_srcSystem(), m.get_srcComponent(), m.get_seq()) for m in raws] == [
        (3, SENSOR_COMPONENT_ID, 0),
        (3, TRUTH_COMPONENT_ID, 0),
        (3, SENSOR_COMPONENT_ID, 1),
        (3, TRUTH_COMPONENT_ID, 1),
    ]
    assert all(f[0] == 0xFD for f in frames)  # MAVLink 2
    with pytest.raises(ValueError, match="truth_component_id"):
        Encoder(sensor_component_id=5, truth_component_id=5)
    with pytest.raises(ValueError, match="system_id"):
        Encoder(system_id=0)


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


# --- messages from a real flight controller ------------------------------------------------
def _fc_frames() -> dict[str, bytes]:
    fc = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    msgs = {
        "HIGHRES_IMU": mavlink2.MAVLink_highres_imu_message(
            2_000_000,
            0.5,
            -0.25,
            -9.75,
            0.125,
            -0.0625,
            0.03125,
            0.2,
            0.01,
            0.4,
            1001.5,
            0.0,
            110.0,
            31.5,
            0x1FFF,
            0,
        ),
        "SCALED_IMU": mavlink2.MAVLink_scaled_imu_message(
            1500, 100, -50, -1000, 10, -20, 30, 200, 10, 400, 3150
        ),
        "SCALED_IMU2": mavlink2.MAVLink_scaled_imu2_message(1500, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 0),
        "SCALED_IMU3": mavlink2.MAVLink_scaled_imu3_message(
            1500, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 100
        ),
        "RAW_IMU": mavlink2.MAVLink_raw_imu_message(
            2_000_000, 100, -50, -1000, 10, -20, 30, 200, 10, 400, 0, 0
        ),
        "GPS_RAW_INT": mavlink2.MAVLink_gps_raw_int_message(
            3_000_000,
            3,
            473_977_420,
            85_455_940,
            488_120,
            90,
            150,
            1000,
            9000,
            14,
            0,
            1200,
            2400,
            300,
            0,
            0,
        ),
        "SCALED_PRESSURE": mavlink2.MAVLink_scaled_pressure_message(1500, 1001.5, 0.25, 2150),
        "SCALED_PRESSURE3": mavlink2.MAVLink_scaled_pressure3_message(1500, 1000.0, 0.0, -500),
        "ATTITUDE": mavlink2.MAVLink_attitude_message(1500, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0),
    }
    out = {}
    for name, m in msgs.items():
        out[name] = m.pack(fc)
        fc.seq += 1
    return out


def test_flight_controller_messages_decode_to_si() -> None:
    frames = _fc_frames()
    dec = Decoder(raw_imu_scale=RawImuScale.milli_units())

    imu, mag, baro, airspeed = one(dec, frames["HIGHRES_IMU"])
    assert isinstance(airspeed, AirspeedSample)
    assert airspeed.diff_pressure_pa == 0.0  # bit 10 set with 0 hPa: a finite reading passes
    assert airspeed.temperature_k == pytest.approx(304.65)
    assert imu.specific_force_b_mps2.tolist() == [0.5, -0.25, -9.75]
    assert imu.angular_rate_b_rps.tolist() == [0.125, -0.0625, 0.03125]
    assert imu.temperature_k == pytest.approx(304.65)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])
    assert baro.pressure_pa == pytest.approx(100_150.0)

    imu, mag = one(dec, frames["SCALED_IMU"])
    assert imu.time_us == 1_500_000 and imu.sensor_id == 0
    assert imu.specific_force_b_mps2 == pytest.approx(np.array([0.1, -0.05, -1.0]) * G0)
    assert imu.angular_rate_b_rps == pytest.approx([0.01, -0.02, 0.03])
    assert imu.temperature_k == pytest.approx(304.65)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])

    (imu2,) = one(dec, frames["SCALED_IMU2"])  # all-zero field: no magnetometer
    assert imu2.sensor_id == 1 and math.isnan(imu2.temperature_k)  # 0 cdegC: not provided
    (imu3,) = one(dec, frames["SCALED_IMU3"])
    assert imu3.sensor_id == 2 and imu3.temperature_k == pytest.approx(274.15)

    imu, mag = one(dec, frames["RAW_IMU"])
    assert imu.specific_force_b_mps2 == pytest.approx(np.array([0.1, -0.05, -1.0]) * G0)
    assert mag.field_b_tesla == pytest.approx([2e-5, 1e-6, 4e-5])

    (fix,) = one(dec, frames["GPS_RAW_INT"])
    assert math.degrees(fix.lat_rad) == pytest.approx(47.397742, abs=1e-9)
    assert math.degrees(fix.lon_rad) == pytest.approx(8.545594, abs=1e-9)
    assert fix.alt_msl_m == pytest.approx(488.12)
    assert fix.v_ned_mps[:2] == pytest.approx([0.0, 10.0], abs=1e-12)  # 10 m/s due east
    assert math.isnan(fix.v_ned_mps[2])  # GPS_RAW_INT has no vertical velocity
    assert (fix.eph_m, fix.epv_m, fix.speed_accuracy_mps) == pytest.approx((1.2, 2.4, 0.3))
    assert fix.satellites_visible == 14

    (b,) = one(dec, frames["SCALED_PRESSURE"])
    assert (b.time_us, b.pressure_pa, b.temperature_k) == pytest.approx(
        (1_500_000, 100_150.0, 294.65)
    )
    (b3,) = one(dec, frames["SCALED_PRESSURE3"])
    assert b3.sensor_id == 2 and b3.temperature_k == pytest.approx(268.15)

    assert one(dec, frames["ATTITUDE"]) == []
    assert dec.counters.ignored_msgs == 1
    assert dec.counters.samples == 13  # HIGHRES_IMU: IMU, mag, baro, airspeed


def test_raw_imu_needs_an_explicit_scale() -> None:
    frame = _fc_frames()["RAW_IMU"]
    dec = Decoder()
    assert dec.feed(frame) == []
    assert dec.counters.unscaled_raw_imu == 1
    scaled = Decoder(raw_imu_scale=RawImuScale(accel_mps2_per_lsb=0.01, gyro_rps_per_lsb=0.001))
    (imu,) = one(scaled, frame)  # no magnetometer scale: no MagSample
    assert imu.specific_force_b_mps2 == pytest.approx([1.0, -0.5, -10.0])
    with pytest.raises(ValueError, match="accel_mps2_per_lsb"):
        RawImuScale(accel_mps2_per_lsb=-1.0, gyro_rps_per_lsb=0.001)
    with pytest.raises(ValueError, match="extra"):
        RawImuScale(accel_mps2_per_lsb=1.0, gyro_rps_per_lsb=0.001, typo=1.0)  # type: ignore[call-arg]


def test_gps_raw_int_unknowns_are_nan() -> None:
    fc = mavlink2.MAVLink(None, 1, 1)
    frame = mavlink2.MAVLink_gps_raw_int_message(
        1, 3, 0, 0, 0, 65535, 65535, 65535, 65535, 255
    ).pack(fc)
    (fix,) = one(Decoder(), frame)
    assert np.isnan(fix.v_ned_mps).all()
    assert math.isnan(fix.eph_m) and math.isnan(fix.epv_m) and math.isnan(fix.speed_accuracy_mps)


def test_decode_message_accepts_pymavlink_objects() -> None:
    frame = Encoder().gnss(GnssFix(9, 0.5, 0.1, 1.0, np.zeros(3), 1.0, 2.0, 0.1))
    msg = parse_raw(frame)
    dec = Decoder()
    (item,) = dec.decode_message(msg)
    assert item.msg_id == mavlink2.MAVLINK_MSG_ID_HIL_GPS and item.sample.time_us == 9
    assert dec.decode_message(mavlink2.MAVLink_bad_data(b"\x01", "Bad prefix")) == []
    assert dec.counters.garbage_bytes == 1


def test_float32_pressure_matches_struct_rounding() -> None:
    # The codec's pressure loss is exactly IEEE float32 rounding of the hPa value.
    p = 101_325.123
    (b,) = one(Decoder(), Encoder().sensors(None, BaroSample(0, p, 288.15)))
    assert b.pressure_pa == pytest.approx(
        struct.unpack("<f", struct.pack("<f", p / 100.0))[0] * 100.0, rel=1e-15
    )


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
        # THEN every one of the 2,000 good frames is decoded (pymavlink 2.4.50's byte parser,
        # which the decoder used before, lost 1-3 of them here; the issue measured 146)
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


# ------------------------------------------------------------------------- air data (pitot)
def test_airspeed_sample_round_trips_in_hil_sensor_with_the_baro_temperature() -> None:
    t = 5_000_000
    imu = ImuSample(t, 0.005, np.array([0.1, 0.0, -9.8]), np.array([0.0, 0.01, 0.0]))
    baro = BaroSample(t, 89_875.0, 283.15)
    airspeed = AirspeedSample(t, 1_391.37, 290.0)  # its own temperature is not on the wire
    frame = Encoder().sensors(imu, baro, airspeed=airspeed)
    raw = parse_raw(frame)
    assert raw.fields_updated == HilSensorField.IMU | HilSensorField.BARO | (
        HilSensorField.DIFF_PRESSURE
    )
    assert_f32_close(raw.diff_pressure, 13.9137, 1.0)  # hPa, as PX4 reads it
    got = one(Decoder(), frame)
    (a,) = [s for s in got if isinstance(s, AirspeedSample)]
    assert a.time_us == t and a.sensor_id == 0
    assert_f32_close(a.diff_pressure_pa, airspeed.diff_pressure_pa, 100.0)
    assert a.temperature_k == pytest.approx(baro.temperature_k, abs=1e-4)
    with pytest.raises(ValueError, match="not both"):
        Encoder().sensors(imu, airspeed=airspeed, diff_pressure_pa=1.0)
    with pytest.raises(ValueError, match="time_us"):
        Encoder().sensors(imu, airspeed=AirspeedSample(t + 1, 1.0, 290.0))


def _hil_sensor_with_diff_hpa(diff_hpa: float, t: int = 1_000_000) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=200)
    msg = mavlink2.MAVLink_hil_sensor_message(
        t, 0, 0, -9.8, 0, 0, 0, 0, 0, 0, 900.0, diff_hpa, 0, 15.0,
        HilSensorField.IMU | HilSensorField.BARO | HilSensorField.DIFF_PRESSURE, 0,
    )  # fmt: skip
    return bytes(msg.pack(mav))


def test_non_finite_diff_pressure_is_counted_and_finite_negative_passes() -> None:
    dec = Decoder()
    for i, bad in enumerate((math.nan, math.inf, -math.inf)):
        got = one(dec, _hil_sensor_with_diff_hpa(bad, t=1_000_000 + 10_000 * i))
        assert [type(s) for s in got] == [ImuSample, BaroSample]  # the rest of it is kept
    assert dec.counters.bad_diff_pressure == 3
    # slightly negative: sensor noise at zero flow, passed through (the filter judges physics)
    got = one(dec, _hil_sensor_with_diff_hpa(-0.02, t=2_000_000))
    (a,) = [s for s in got if isinstance(s, AirspeedSample)]
    assert a.diff_pressure_pa == pytest.approx(-2.0, rel=1e-6)
    assert dec.counters.bad_diff_pressure == 3
