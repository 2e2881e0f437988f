"""hil.codec: SI <-> MAVLink round trips of the simulator's messages (HIL_SENSOR with air
data, HIL_GPS, HIL_STATE_QUATERNION) within the wire quantisation, components and sequence
numbers."""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.codec import (
    SENSOR_COMPONENT_ID,
    TRUTH_COMPONENT_ID,
    Decoder,
    Encoder,
    HilSensorField,
    mavlink2,
)
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Truth
from tests.hil.codec_helpers import (
    DEGE7_PER_RAD,
    FAST,
    G0,
    angle_diff,
    assert_f32_close,
    assert_int_close,
    int_tol,
    one,
    parse_raw,
)


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


def test_float32_pressure_matches_struct_rounding() -> None:
    # The codec's pressure loss is exactly IEEE float32 rounding of the hPa value.
    p = 101_325.123
    (b,) = one(Decoder(), Encoder().sensors(None, BaroSample(0, p, 288.15)))
    assert b.pressure_pa == pytest.approx(
        struct.unpack("<f", struct.pack("<f", p / 100.0))[0] * 100.0, rel=1e-15
    )


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
