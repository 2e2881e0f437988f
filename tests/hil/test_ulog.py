"""PX4 ULog reading (hil.ulog): units, frames, times and the EKF2 reference, on PX4's own
sample logs (``../shared/logs/px4/``, public pyulog test data, read-only) and crafted ones."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog

from hil.ulog import UlogLog, _reproject, read_ulog
from physconst.geomag import magnetic_field_ned_t
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample
from tests.helpers.ulog_bytes import filter_ulog

LOGS = Path(__file__).resolve().parents[2].parent / "shared" / "logs" / "px4"
EVENTS = LOGS / "sample_px4_events.ulg"  # SITL, 31 s, v1.14 field names (latitude_deg)
SMALL = LOGS / "sample_log_small.ulg"  # CubeOrange, older field names (lat degE7)

pytestmark = pytest.mark.skipif(not EVENTS.is_file(), reason=f"sample logs not found in {LOGS}")


@pytest.fixture(scope="module")
def events() -> UlogLog:
    return read_ulog(EVENTS)


def test_every_row_becomes_one_sample_in_time_order(events: UlogLog) -> None:
    raw = ULog(str(EVENTS))
    rows = {d.name: len(d.data["timestamp"]) for d in raw.data_list if d.multi_id == 0}
    assert events.count(ImuSample) == rows["sensor_combined"]
    assert events.count(GnssFix) == rows["vehicle_gps_position"]
    assert events.count(BaroSample) == rows["vehicle_air_data"]
    assert events.count(MagSample) == rows["vehicle_magnetometer"]
    t = [s.time_us for s in events.samples]
    assert t == sorted(t)
    # rebased to the log start (the raw stamps of this SITL log are Unix-like, ~1.7e15 us)
    assert 0 <= t[0] < 1_000_000 and t[-1] * 1e-6 == pytest.approx(events.duration_s, abs=0.1)
    assert events.ignored_topics > 0


def test_si_units_and_body_frd(events: UlogLog) -> None:
    """At rest on the ground: specific force ~ -g along body down, rates ~ 0, the field of
    the WMM at the PX4 SITL home (Zurich) in tesla, pressure of ~488 m in Pa."""
    imu = [s for s in events.samples if isinstance(s, ImuSample)][:500]
    f = np.mean([s.specific_force_b_mps2 for s in imu], axis=0)
    assert f[2] == pytest.approx(-9.8, abs=0.1) and np.hypot(f[0], f[1]) < 0.2
    assert np.abs(np.mean([s.angular_rate_b_rps for s in imu], axis=0)).max() < 0.01
    assert imu[0].dt_s == pytest.approx(0.004)  # gyro_integral_dt 4000 us
    fix = next(s for s in events.samples if isinstance(s, GnssFix) and s.fix_type >= 3)
    assert math.degrees(fix.lat_rad) == pytest.approx(47.3977, abs=1e-3)
    assert math.degrees(fix.lon_rad) == pytest.approx(8.5456, abs=1e-3)
    assert fix.alt_msl_m == pytest.approx(488.0, abs=5.0)
    mag = np.mean([s.field_b_tesla for s in events.samples if isinstance(s, MagSample)][:50],
                  axis=0)
    wmm = magnetic_field_ned_t(fix.lat_rad, fix.lon_rad, fix.alt_msl_m, 2024.2)
    # SITL simulates its own field model: strength and dip agree with the WMM within a few %
    assert np.linalg.norm(mag) == pytest.approx(wmm.intensity_t, rel=0.1)
    dip = math.atan2(mag[2], math.hypot(mag[0], mag[1]))
    assert dip == pytest.approx(wmm.inclination_rad, abs=math.radians(3.0))
    baro = next(s for s in events.samples if isinstance(s, BaroSample))
    assert baro.pressure_pa == pytest.approx(95600.0, rel=0.01)
    assert baro.temperature_k > 200.0
    assert events.first_fix_utc_us is not None
    assert events.first_fix_utc_us * 1e-6 == pytest.approx(1710773359.5, abs=60.0)  # 2024-03


def test_reference_is_the_ekf2_estimate(events: UlogLog) -> None:
    ref = events.reference
    assert events.reference_position == "vehicle_global_position"
    assert events.reference_velocity
    fixes = [s for s in events.samples if isinstance(s, GnssFix) and s.fix_type >= 3]
    # the reference starts where EKF2 has a global position and agrees with GNSS (SITL)
    assert ref[0].time_us >= 9_000_000
    r_m = 6.371e6
    north = (ref[-1].lat_rad - fixes[-1].lat_rad) * r_m
    assert abs(north) < 5.0 and abs(ref[-1].alt_msl_m - fixes[-1].alt_msl_m) < 5.0
    for r in ref[::50]:
        assert np.linalg.norm(r.q_nb) == pytest.approx(1.0, abs=1e-6)
        assert np.all(np.isfinite(r.v_ned_mps))
        assert math.isnan(r.airspeed_mps)  # what EKF2 does not give stays NaN


def test_old_field_names_degE7_and_attitude_only_reference() -> None:
    """A CubeOrange log of an older PX4: lat/lon in degE7, alt in mm; EKF2 never had a global
    position, so the reference is attitude only."""
    log = read_ulog(SMALL)
    fix = next(s for s in log.samples if isinstance(s, GnssFix))
    assert math.degrees(fix.lat_rad) == pytest.approx(63.4170622, abs=1e-7)
    assert fix.alt_msl_m == pytest.approx(66.814, abs=1e-3)
    assert log.reference_position is None and log.reference_height is None
    assert log.reference and all(math.isnan(r.lat_rad) for r in log.reference)
    assert (log.dropouts, log.dropout_ms) == (1, 30)  # the logger lost 30 ms, and says so


def test_reproject_is_px4s_azimuthal_equidistant_projection() -> None:
    """Due north: the arc is the latitude change; due east: the great circle leaves the
    parallel towards the equator by ``y^2 tan(lat) / (2 R)`` (second order)."""
    r_m = 6371000.0
    lat0, lon0 = math.radians(47.0), math.radians(8.0)
    lat, lon = _reproject(np.full(2, lat0), np.full(2, lon0), np.array([100.0, 0.0]),
                          np.array([0.0, -50.0]))
    assert (lat[0] - lat0) * r_m == pytest.approx(100.0, rel=1e-9)
    assert lon[0] == lon0
    assert (lon[1] - lon0) * r_m * math.cos(lat0) == pytest.approx(-50.0, rel=1e-6)
    assert (lat[1] - lat0) * r_m == pytest.approx(-(50.0**2) * math.tan(lat0) / (2 * r_m),
                                                  rel=1e-3)


def test_not_a_ulog_names_the_cause(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"x" * 200)
    with pytest.raises(ValueError, match="not a readable PX4 ULog"):
        read_ulog(bad)


def test_a_cut_log_reads_what_it_holds(tmp_path: Path) -> None:
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(EVENTS.read_bytes()[:300_000])
    log = read_ulog(cut)
    assert 0 < log.count(ImuSample) < 7783


def test_a_dropped_topic_is_absent(tmp_path: Path) -> None:
    log = read_ulog(filter_ulog(EVENTS, tmp_path / "x.ulg", drop_topics={"vehicle_magnetometer"}))
    assert log.count(MagSample) == 0 and log.count(ImuSample) == 7783


def test_imu_samples_carry_the_logged_imu_temperature() -> None:
    """The CubeOrange log's heated IMU: sensor_accel's ~1 Hz temperature, held until the next
    one, on every IMU sample after the first; NaN before it (never a made-up value)."""
    log = read_ulog(SMALL)
    raw = ULog(str(SMALL))
    accel = next(d for d in raw.data_list if d.name == "sensor_accel" and d.multi_id == 0)
    logged_c = np.asarray(accel.data["temperature"], dtype=float)
    imu = [s for s in log.samples if isinstance(s, ImuSample)]
    temps_c = np.array([s.temperature_k for s in imu]) - 273.15
    known = temps_c[np.isfinite(temps_c)]
    assert 0 < len(known) < len(temps_c)
    assert not np.any(np.isfinite(temps_c[:np.argmax(np.isfinite(temps_c))]))
    assert set(np.round(known, 4)) <= set(np.round(logged_c, 4))
    assert 35.0 < known.mean() < 45.0  # held near 40 C by the board's heater
