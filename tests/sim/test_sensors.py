"""Sensor error models (sim.imu, sim.gnss, sim.baro, sim.mag), presets and the suite."""

from __future__ import annotations

import math
from functools import cache

import allantools
import numpy as np
import pytest
from numpy.typing import NDArray
from pydantic import ValidationError

import physconst as pc
from physconst.geomag import magnetic_field_ned_t
from sim import atmosphere as atm
from sim._sensor_common import meridian_prime_radii_m
from sim.baro import BaroModel
from sim.gnss import GnssConfig, GnssModel
from sim.imu import (
    GM_ALLAN_PEAK_RATIO,
    GM_ALLAN_PEAK_TAU_RATIO,
    AccelConfig,
    GyroConfig,
    ImuConfig,
    ImuModel,
    ImuParams,
)
from sim.mag import MagModel
from sim.presets import (
    available_baro_presets,
    available_gnss_presets,
    available_imu_presets,
    available_mag_presets,
    baro_preset,
    gnss_preset,
    imu_preset,
    mag_preset,
    suite_config,
)
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Truth
from sim.sensors import SensorSuite

G = 9.80665
OMEGA_IE = 7.292115e-5
LAT = math.radians(47.0)
LON = math.radians(8.0)
EARTH_RATE_B = np.array([OMEGA_IE * math.cos(LAT), 0.0, -OMEGA_IE * math.sin(LAT)])
LEVEL_NORTH = np.array([1.0, 0.0, 0.0, 0.0])


def stationary_truth(k: int, rate_hz: float = 200.0, alt_m: float = 500.0) -> Truth:
    """Vehicle at rest, level, heading north at 47°N 8°E."""
    return Truth(
        time_us=round(k * 1e6 / rate_hz),
        lat_rad=LAT,
        lon_rad=LON,
        alt_msl_m=alt_m,
        v_ned_mps=np.zeros(3),
        q_nb=LEVEL_NORTH,
        omega_b_rps=EARTH_RATE_B,
        specific_force_b_mps2=np.array([0.0, 0.0, -G]),
        static_pressure_pa=95000.0,
        temperature_k=285.0,
        airspeed_mps=0.0,
        indicated_airspeed_mps=0.0,
    )


def ideal_imu(**gyro_accel: float) -> ImuConfig:
    """An error-free IMU (optional overrides: ``gyro_<field>`` / ``accel_<field>``)."""
    gyro: dict[str, float] = dict(
        range_dps=500.0,
        angle_random_walk_deg_per_rth=0.0,
        bias_instability_deg_per_h=0.0,
        bias_correlation_time_s=100.0,
    )
    accel: dict[str, float] = dict(
        range_g=8.0,
        velocity_random_walk_mps_per_rth=0.0,
        bias_instability_ug=0.0,
        bias_correlation_time_s=100.0,
    )
    for key, value in gyro_accel.items():
        sensor, field = key.split("_", 1)
        (gyro if sensor == "gyro" else accel)[field] = value
    return ImuConfig(gyro=GyroConfig(**gyro), accel=AccelConfig(**accel))  # type: ignore[arg-type]


# --------------------------------------------------------------------------- presets, validation


def test_every_preset_exists_and_lists_are_sorted() -> None:
    assert available_imu_presets() == ["consumer-mems", "industrial-mems", "paper-p2", "tactical"]
    assert available_gnss_presets() == ["modern", "paper-p2"]
    for name in available_imu_presets():
        assert isinstance(imu_preset(name), ImuConfig)
    for name in available_gnss_presets():
        assert isinstance(gnss_preset(name), GnssConfig)
    for name in available_baro_presets():
        baro_preset(name)
    for name in available_mag_presets():
        mag_preset(name)


@pytest.mark.parametrize(
    ("lookup", "names"),
    [
        (imu_preset, available_imu_presets()),
        (gnss_preset, available_gnss_presets()),
        (baro_preset, available_baro_presets()),
        (mag_preset, available_mag_presets()),
    ],
)
def test_unknown_preset_names_valid_choices(lookup: object, names: list[str]) -> None:
    with pytest.raises(ValueError) as err:
        lookup("navigation-grade")  # type: ignore[operator]
    message = str(err.value)
    assert "\n" not in message and "navigation-grade" in message
    for name in names:
        assert name in message


def test_paper_presets_carry_the_paper_figures() -> None:
    p2 = imu_preset("paper-p2").gyro
    assert (p2.bias_instability_deg_per_h, p2.bias_correlation_time_s) == (0.1, 100.0)
    assert p2.bias_instability_spec == "gm_sigma"
    params = ImuParams.from_config(imu_preset("paper-p2"))
    assert params.gm_sigma[3] == pytest.approx(math.radians(0.1) / 3600.0)
    g = gnss_preset("paper-p2")
    assert (g.horizontal_gm_sigma_m, g.horizontal_gm_tau_s) == (20.0, 10.0)
    assert (g.velocity_gm_sigma_mps, g.velocity_gm_tau_s) == (0.1, 5.0)
    # Datasheet floor -> Gauss-Markov sigma via the GM Allan peak ratio.
    ind = ImuParams.from_config(imu_preset("industrial-mems"))
    assert ind.gm_sigma[3] * GM_ALLAN_PEAK_RATIO == pytest.approx(math.radians(2.0) / 3600.0)


def test_negative_noise_parameter_names_the_field() -> None:
    cfg = imu_preset("tactical")
    with pytest.raises(ValidationError) as err:
        cfg.model_copy(update={"gyro": {"angle_random_walk_deg_per_rth": -0.1}})
    assert err.value.errors()[0]["loc"] == ("gyro", "angle_random_walk_deg_per_rth")
    assert "gyro.angle_random_walk_deg_per_rth" in str(err.value)
    with pytest.raises(ValidationError, match="noise_pa"):
        baro_preset("ms5611").model_copy(update={"noise_pa": -1.0})
    with pytest.raises(ValidationError, match="horizontal_white_sigma_m"):
        gnss_preset("modern").model_copy(update={"horizontal_white_sigma_m": math.nan})


def test_validated_override_changes_only_that_field() -> None:
    cfg = imu_preset("tactical")
    new = cfg.model_copy(update={"gyro": {"angle_random_walk_deg_per_rth": 0.3}})
    assert new.gyro.angle_random_walk_deg_per_rth == 0.3
    assert new.gyro.bias_instability_deg_per_h == cfg.gyro.bias_instability_deg_per_h
    assert new.accel == cfg.accel
    assert cfg.gyro.angle_random_walk_deg_per_rth == 0.125  # original untouched


def test_missing_unknown_and_frozen_fields_are_rejected() -> None:
    fields = gnss_preset("modern").model_dump()
    del fields["vertical_gm_sigma_m"]
    with pytest.raises(ValidationError) as err:
        GnssConfig(**fields)
    assert err.value.errors()[0]["loc"] == ("vertical_gm_sigma_m",)
    assert err.value.errors()[0]["type"] == "missing"
    with pytest.raises(ValidationError, match=r"extra_forbidden|Extra inputs"):
        gnss_preset("modern").model_copy(update={"horizontal_sigma": 1.0})
    with pytest.raises(ValidationError):
        gnss_preset("modern").rate_hz = 10.0


# --------------------------------------------------------------------------- IMU: Allan deviation

ALLAN_RATE_HZ = 50.0
ALLAN_BIN_S = 0.1


@cache
def stationary_imu_record(name: str) -> tuple[NDArray[np.float64], ImuParams]:
    """Hours of stationary output, averaged into 0.1 s bins, shape (n, 6) [f, ω]."""
    model = ImuModel(imu_preset(name), np.random.default_rng(2024), ALLAN_RATE_HZ)
    tau_c = float(np.max(model.params.gm_tau_s))
    duration_s = int(max(6 * 3600, 40 * GM_ALLAN_PEAK_TAU_RATIO * tau_c))
    per_bin = round(ALLAN_BIN_S * ALLAN_RATE_HZ)
    chunk_s = 1800
    n = int(chunk_s * ALLAN_RATE_HZ)
    f = np.tile([0.0, 0.0, -G], (n, 1))
    w = np.tile(EARTH_RATE_B, (n, 1))
    bins = []
    for _ in range(duration_s // chunk_s):
        fm, wm = model.measure_block(f, w)
        y = np.concatenate((fm, wm), axis=1)
        bins.append(y.reshape(-1, per_bin, 6).mean(axis=1))
    return np.concatenate(bins), model.params


def triad_adev(y: NDArray[np.float64], axes: slice, taus: list[float]) -> NDArray[np.float64]:
    """Overlapping Allan deviation (allantools), RMS over the three axes of a triad."""
    adevs = []
    for j in range(axes.start, axes.stop):
        _, adev, _, _ = allantools.oadev(
            y[:, j], rate=1.0 / ALLAN_BIN_S, data_type="freq", taus=np.array(taus)
        )
        adevs.append(adev)
    return np.asarray(np.sqrt(np.mean(np.square(adevs), axis=0)))


@pytest.mark.parametrize("name", ["consumer-mems", "industrial-mems", "tactical", "paper-p2"])
@pytest.mark.parametrize(("triad", "axes"), [("accel", slice(0, 3)), ("gyro", slice(3, 6))])
def test_allan_deviation_matches_preset(name: str, triad: str, axes: slice) -> None:
    y, p = stationary_imu_record(name)
    j = axes.start
    tau_peak = round(GM_ALLAN_PEAK_TAU_RATIO * p.gm_tau_s[j] / ALLAN_BIN_S) * ALLAN_BIN_S
    adev_short, adev_peak = triad_adev(y, axes, [ALLAN_BIN_S, tau_peak])

    # Random walk coefficient from the short-tau (white-dominated) end. A well-dithered
    # quantiser adds white noise LSB²·dt/12, which the measured N must include.
    n_expected = math.sqrt(p.white_density[j] ** 2 + p.resolution[j] ** 2 / ALLAN_RATE_HZ / 12.0)
    n_measured = adev_short * math.sqrt(ALLAN_BIN_S)
    assert n_measured == pytest.approx(n_expected, rel=0.15), (triad, n_measured / n_expected)

    # Bias-instability floor: the datasheet floor B (or 0.6174·sigma for a paper's GM
    # sigma), read at the Gauss-Markov peak 1.893·tau. White noise and rate random walk add
    # on top there; the presets keep that below a few per cent, the tolerance is 30 %.
    floor_expected = p.allan_floor[j]
    assert adev_peak == pytest.approx(floor_expected, rel=0.30), (triad, adev_peak / floor_expected)


# --------------------------------------------------------------------------- IMU: other errors


def test_step_and_block_paths_share_one_stream() -> None:
    cfg = imu_preset("consumer-mems")
    a = ImuModel(cfg, np.random.default_rng(5), 200.0)
    b = ImuModel(cfg, np.random.default_rng(5), 200.0)
    n = 2500  # spans block boundaries
    rng = np.random.default_rng(0)
    f = rng.normal(0.0, 5.0, (n, 3))
    w = rng.normal(0.0, 1.0, (n, 3))
    fb, wb = b.measure_block(f, w)
    for k in range(n):
        fa, wa = a.measure(f[k], w[k])
        np.testing.assert_allclose(fa, fb[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(wa, wb[k], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.current_bias(), b.current_bias())


def test_scale_factor_and_misalignment_apply_the_drawn_matrix() -> None:
    cfg = ideal_imu(gyro_scale_factor_ppm=3000.0, gyro_misalignment_mrad=5.0)
    model = ImuModel(cfg, np.random.default_rng(3), 100.0)
    t = model.transfer
    assert np.all(t[0:3, 0:3] == np.eye(3))  # accelerometer is ideal
    assert np.any(np.abs(np.diag(t)[3:] - 1.0) > 1e-4)
    assert np.any(np.abs(t[3:6, 3:6] - np.diag(np.diag(t)[3:])) > 1e-4)
    w = np.array([0.5, -0.2, 0.1])
    _, w_meas = model.measure(np.zeros(3), w)
    np.testing.assert_allclose(w_meas, t[3:6, 3:6] @ w, rtol=0, atol=1e-15)


def test_turn_on_bias_statistics() -> None:
    cfg = ideal_imu(accel_turn_on_bias_mg=2.0, gyro_turn_on_bias_deg_per_h=100.0)
    draws = np.array(
        [ImuModel(cfg, np.random.default_rng(s), 100.0).turn_on_bias for s in range(600)]
    )
    np.testing.assert_allclose(draws[:, :3].std(axis=0), 2e-3 * G, rtol=0.15)
    np.testing.assert_allclose(draws[:, 3:].std(axis=0), math.radians(100.0) / 3600.0, rtol=0.15)


def test_saturation_and_quantisation() -> None:
    cfg = ideal_imu(gyro_resolution_dps=0.01, accel_resolution_mg=1.0, gyro_range_dps=300.0)
    model = ImuModel(cfg, np.random.default_rng(0), 100.0)
    f = np.array([[0.0, 0.0, -G], [100.0, -100.0, 3.3]])
    w = np.array([[0.1, -0.2, 0.3], [math.radians(400.0), math.radians(-1000.0), 0.0]])
    fm, wm = model.measure_block(f, w)
    lsb_g, lsb_a = math.radians(0.01), 1e-3 * G
    # Quantised outputs are integer multiples of the LSB ...
    np.testing.assert_allclose(wm / lsb_g, np.round(wm / lsb_g), atol=1e-9)
    np.testing.assert_allclose(fm / lsb_a, np.round(fm / lsb_a), atol=1e-9)
    # ... within half an LSB of the input ...
    assert np.all(np.abs(wm[0] - w[0]) <= lsb_g / 2 + 1e-15)
    # ... and clip at the range (±8 g accelerometer, ±300 °/s gyro).
    assert fm[1, 0] == pytest.approx(round(8 * G / lsb_a) * lsb_a)
    assert fm[1, 1] == pytest.approx(-round(8 * G / lsb_a) * lsb_a)
    assert wm[1, 0] == pytest.approx(round(math.radians(300.0) / lsb_g) * lsb_g)
    assert wm[1, 1] == pytest.approx(-round(math.radians(300.0) / lsb_g) * lsb_g)
    # The per-sample path quantises and clips the same way.
    fs, ws = model.measure(f[1], w[1])
    assert abs(ws[0]) <= math.radians(300.0) + lsb_g and abs(fs[1]) <= 8 * G + lsb_a


# --------------------------------------------------------------------------- GNSS


def gnss_errors_m(
    config: GnssConfig, n_receivers: int, n_fixes: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], GnssFix]:
    """Position errors (N, E, D) in metres and velocity errors of many independent receivers."""
    truth = stationary_truth(0)
    r_m, r_n = meridian_prime_radii_m(LAT)
    pos, vel = [], []
    fix = None
    for seed in range(n_receivers):
        model = GnssModel(config, np.random.default_rng(seed))
        for k in range(n_fixes):
            fix = model.measure(stationary_truth(k * 40))
            pos.append(
                [
                    (fix.lat_rad - truth.lat_rad) * (r_m + truth.alt_msl_m),
                    (fix.lon_rad - truth.lon_rad) * (r_n + truth.alt_msl_m) * math.cos(LAT),
                    truth.alt_msl_m - fix.alt_msl_m,
                ]
            )
            vel.append(fix.v_ned_mps)
    assert fix is not None
    return np.array(pos), np.array(vel), fix


@pytest.mark.parametrize("name", ["modern", "paper-p2"])
def test_gnss_reported_accuracy_matches_actual_errors(name: str) -> None:
    config = gnss_preset(name)
    # Receivers start from the stationary distribution, so an ensemble of short runs samples
    # the error statistics without waiting many correlation times.
    pos, vel, fix = gnss_errors_m(config, n_receivers=300, n_fixes=20)
    assert np.abs(pos.mean(axis=0)).max() < 0.25 * fix.eph_m
    for axis in (0, 1):
        assert pos[:, axis].std() == pytest.approx(fix.eph_m, rel=0.20)
        assert vel[:, axis].std() == pytest.approx(fix.speed_accuracy_mps, rel=0.20)
    assert pos[:, 2].std() == pytest.approx(fix.epv_m, rel=0.20)


def test_gnss_error_correlation_time() -> None:
    config = gnss_preset("paper-p2")  # 20 m, tau = 10 s, no white part
    model = GnssModel(config, np.random.default_rng(11))
    errs = np.array(
        [model.advance_errors(round(k * 2e5)).pos_ned_m for k in range(15000)]
    )  # 3000 s at 5 Hz
    lag = 50  # 10 s
    for axis in range(3):
        e = errs[:, axis]
        rho = np.corrcoef(e[:-lag], e[lag:])[0, 1]
        assert rho == pytest.approx(math.exp(-1.0), abs=0.1)
        assert e.std() == pytest.approx(20.0, rel=0.2)


def test_gnss_dishonest_receiver_reports_scaled_accuracy() -> None:
    config = gnss_preset("modern").model_copy(update={"accuracy_report_scale": 2.0})
    fix = GnssModel(config, np.random.default_rng(0)).measure(stationary_truth(0))
    honest = GnssModel(gnss_preset("modern"), np.random.default_rng(0)).measure(stationary_truth(0))
    assert fix.eph_m == pytest.approx(2.0 * honest.eph_m)
    assert honest.eph_m == pytest.approx(math.hypot(1.4, 0.5))


def test_gnss_latency_rate_and_time_of_validity_in_suite() -> None:
    suite = SensorSuite(suite_config(gnss="modern"), seed=3, sim_rate_hz=200.0)
    emitted: list[tuple[int, GnssFix]] = []
    for k in range(2001):  # 10 s
        t = stationary_truth(k)
        emitted += [(t.time_us, s) for s in suite.step(t) if isinstance(s, GnssFix)]
    validity = [fix.time_us for _, fix in emitted]
    assert all(t_out - fix.time_us == 100_000 for t_out, fix in emitted)
    assert validity[:3] == [0, 200_000, 400_000]
    assert len(emitted) == 50  # fixes valid at 0 .. 9.8 s, emitted up to 9.9 s
    assert suite.pending_gnss() == 1  # the fix valid at 10.0 s is still in the receiver


# --------------------------------------------------------------------------- barometer


def baro_series(
    config_update: dict[str, float], alts: NDArray[np.float64], rate_hz: float = 50.0
) -> NDArray[np.float64]:
    model = BaroModel(
        baro_preset("ms5611").model_copy(update=config_update), np.random.default_rng(1)
    )
    return np.array(
        [model.measure(round(k * 1e6 / rate_hz), float(h)).pressure_pa for k, h in enumerate(alts)]
    )


@pytest.mark.parametrize(
    ("alt_m", "p_table_pa"), [(0.0, 101325.0), (1000.0, 89876.0), (5000.0, 54048.0)]
)
def test_ideal_baro_reads_the_standard_atmosphere(alt_m: float, p_table_pa: float) -> None:
    sample = BaroModel(baro_preset("ideal"), np.random.default_rng(0)).measure(0, alt_m)
    assert sample.pressure_pa == pytest.approx(p_table_pa, abs=1.0)
    t_isa = atm.isa_temperature_k(atm.geopotential_from_geometric(alt_m))
    assert sample.temperature_k == pytest.approx(t_isa)


def test_baro_in_nonstandard_atmosphere_inverts_with_p4() -> None:
    cfg = baro_preset("ideal").model_copy(
        update={"sea_level_temperature_offset_k": 12.0, "sea_level_pressure_offset_hpa": -9.0}
    )
    model = BaroModel(cfg, np.random.default_rng(0))
    for k, alt in enumerate([0.0, 800.0, 2500.0, 6000.0]):
        s = model.measure(k * 20_000, alt)
        h_gp = atm.altitude_from_pressure(s.pressure_pa, 12.0, -900.0)
        assert atm.geometric_from_geopotential(h_gp) == pytest.approx(alt, abs=1e-6)
        # Pressure altitude (altimeter set to standard) differs by P4's scale and bias.
        hp = atm.pressure_altitude_m(s.pressure_pa)
        s_, b = atm.nonstandard_scale_bias(12.0, -900.0)
        assert hp == pytest.approx((h_gp - b) / (1 + s_), abs=1e-6)
    # Air temperature of the hydrostatic P4 atmosphere: T_isa(Hp)·(1 + dT/T0); at sea level
    # T0 + dT − L·b (P4's bias shifts the whole profile by b; −0.49 K here).
    s_, b = atm.nonstandard_scale_bias(12.0, -900.0)
    t_sea = model.measure(100_000, 0.0).temperature_k
    assert t_sea == pytest.approx(pc.ISA_T0_K + 12.0 - pc.ISA_L0_KPM * b, abs=1e-9)
    warm = BaroModel(
        baro_preset("ideal").model_copy(update={"sea_level_temperature_offset_k": 12.0}),
        np.random.default_rng(0),
    )
    assert warm.measure(0, 0.0).temperature_k == pytest.approx(pc.ISA_T0_K + 12.0, abs=1e-9)


@pytest.mark.parametrize("alt_m", [0.0, 3000.0])
def test_weather_front_drift_rate(alt_m: float) -> None:
    drift_hpa_per_h = 2.0
    t_s = np.arange(0.0, 3600.0, 0.5)
    p = baro_series(
        {"pressure_drift_hpa_per_h": drift_hpa_per_h, "bias_gm_sigma_pa": 0.0},
        np.full(t_s.size, alt_m),
        rate_hz=2.0,
    )
    slope_pa_per_h = np.polyfit(t_s / 3600.0, p, 1)[0]
    # Aloft a sea-level pressure change shows up scaled by the density ratio.
    h_gp = atm.geopotential_from_geometric(alt_m)
    ratio = atm.density_from_altitude(h_gp) / atm.density_from_altitude(0.0)
    assert slope_pa_per_h == pytest.approx(100.0 * drift_hpa_per_h * ratio, rel=0.02)


def test_baro_noise_and_quantisation() -> None:
    p = baro_series({"bias_gm_sigma_pa": 0.0}, np.full(20000, 250.0))
    np.testing.assert_array_equal(p, np.round(p))  # 1 Pa output LSB
    # White 1.2 Pa plus the 1 Pa quantiser's LSB²/12.
    assert p.std() == pytest.approx(math.sqrt(1.2**2 + 1.0 / 12.0), rel=0.05)
    p_true = atm.pressure_from_altitude(atm.geopotential_from_geometric(250.0))
    assert p.mean() == pytest.approx(p_true, abs=0.1)


def test_baro_lag_time_constant() -> None:
    cfg = baro_preset("ideal").model_copy(update={"lag_time_constant_s": 0.5})
    model = BaroModel(cfg, np.random.default_rng(0))
    rate = 100.0
    p0 = model.measure(0, 0.0).pressure_pa
    p_new = atm.pressure_from_altitude(atm.geopotential_from_geometric(100.0))
    readings = [model.measure(round(k * 1e6 / rate), 100.0).pressure_pa for k in range(1, 51)]
    fraction_after_tau = (readings[49] - p0) / (p_new - p0)  # 0.5 s after the step
    assert fraction_after_tau == pytest.approx(1.0 - math.exp(-1.0), abs=1e-9)


# --------------------------------------------------------------------------- magnetometer


def test_field_is_the_world_magnetic_model_at_the_simulated_date() -> None:
    model = MagModel(mag_preset("ideal"), np.random.default_rng(0), LAT, LON, 500.0, 2026.5)
    ref = magnetic_field_ned_t(LAT, LON, 500.0, 2026.5)
    np.testing.assert_array_equal(model.field_ned_tesla, ref.ned_t)
    b = model.field_ned_tesla
    # the real declination near Zurich (about +3.5 deg east), not the former dipole's -13.7
    assert 3.0 < math.degrees(math.atan2(b[1], b[0])) < 4.5


def _declination_deg(field_b: np.ndarray) -> float:
    return math.degrees(math.atan2(field_b[1], field_b[0]))


@pytest.mark.parametrize(
    ("lat_deg", "lon_deg"),
    [(47.0, 8.0), (-33.9, 151.2), (64.1, -21.9), (-54.8, -68.3), (1.3, 103.8), (71.0, -156.8)],
)
def test_declination_follows_the_model_along_a_flight(lat_deg: float, lon_deg: float) -> None:
    # GIVEN an ideal magnetometer flown level, nose north, 100 km east-north-east and 2 km up
    lat0, lon0 = math.radians(lat_deg), math.radians(lon_deg)
    model = MagModel(mag_preset("ideal"), np.random.default_rng(0), lat0, lon0, 100.0)
    worst = 0.0
    for k in range(0, 1001, 5):
        s = k / 1000.0
        lat = lat0 + s * 40_000.0 / 6.371e6
        lon = lon0 + s * 92_000.0 / (6.371e6 * math.cos(lat0))
        alt = 100.0 + 2000.0 * s
        # WHEN it reports where it is every 100 m
        model.move_to(lat, lon, alt)
        got = _declination_deg(model.measure(k, LEVEL_NORTH).field_b_tesla)
        ref = math.degrees(magnetic_field_ned_t(lat, lon, alt, 2026.0).declination_rad)
        worst = max(worst, abs(got - ref))
    # THEN its declination is the model's at the vehicle within 0.5 deg (the field is
    # re-evaluated every 500 m: ~0.01 deg away from the poles)
    assert worst < 0.5
    if abs(lat_deg) < 65.0:
        assert worst < 0.05


def test_suite_magnetometer_takes_the_configured_date() -> None:
    truth = stationary_truth(0)
    decl = {}
    for year in (2016.5, 2026.5):
        suite = SensorSuite(suite_config(mag="ideal").model_copy(update={"decimal_year": year}),
                            seed=1, sim_rate_hz=200.0)
        mags = [s for k in range(20) for s in suite.step(stationary_truth(k))
                if isinstance(s, MagSample)]
        f = magnetic_field_ned_t(truth.lat_rad, truth.lon_rad, truth.alt_msl_m, year)
        # level, nose north: body axes are NED
        np.testing.assert_allclose(mags[0].field_b_tesla, f.ned_t, rtol=0, atol=1e-15)
        decl[year] = math.degrees(f.declination_rad)
    assert decl[2026.5] - decl[2016.5] > 0.8  # secular variation reaches the simulator


def test_mag_rotates_field_into_body_axes() -> None:
    model = MagModel(mag_preset("ideal"), np.random.default_rng(0), LAT, LON, 500.0)
    bn, be, bd = model.field_ned_tesla
    np.testing.assert_allclose(model.measure(0, LEVEL_NORTH).field_b_tesla, [bn, be, bd])
    yaw_east = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
    np.testing.assert_allclose(model.measure(1, yaw_east).field_b_tesla, [be, -bn, bd], atol=1e-18)
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        m = model.measure(2, q).field_b_tesla
        assert np.linalg.norm(m) == pytest.approx(np.linalg.norm(model.field_ned_tesla))


def test_mag_noise_hard_iron_and_override() -> None:
    cfg = mag_preset("consumer").model_copy(update={"field_ned_ut": (20.0, 1.0, 44.0)})
    model = MagModel(cfg, np.random.default_rng(9), LAT, LON, 500.0)
    m = np.array([model.measure(k, LEVEL_NORTH).field_b_tesla for k in range(5000)]) * 1e6
    np.testing.assert_allclose(m.mean(axis=0), np.array([21.0, 0.4, 44.8]), atol=0.02)
    np.testing.assert_allclose(m.std(axis=0), math.sqrt(0.2**2 + 0.15**2 / 12), rtol=0.06)


# --------------------------------------------------------------------------- suite


def run_suite(
    seed: int, steps: int = 1200, gnss: str = "modern"
) -> list[ImuSample | GnssFix | BaroSample | MagSample]:
    suite = SensorSuite(suite_config(gnss=gnss), seed=seed, sim_rate_hz=200.0)
    out = []
    for k in range(steps):
        out += suite.step(stationary_truth(k))
    return out


def stream_arrays(
    samples: list[ImuSample | GnssFix | BaroSample | MagSample | AirspeedSample],
) -> list[NDArray[np.float64]]:
    arrays = []
    for s in samples:
        if isinstance(s, ImuSample):
            arrays.append(
                np.concatenate(([s.time_us], s.specific_force_b_mps2, s.angular_rate_b_rps))
            )
        elif isinstance(s, GnssFix):
            arrays.append(
                np.concatenate(([s.time_us, s.lat_rad, s.lon_rad, s.alt_msl_m], s.v_ned_mps))
            )
        elif isinstance(s, BaroSample):
            arrays.append(np.array([s.time_us, s.pressure_pa, s.temperature_k]))
        elif isinstance(s, AirspeedSample):
            arrays.append(np.array([s.time_us, s.diff_pressure_pa, s.temperature_k]))
        else:
            arrays.append(np.concatenate(([s.time_us], s.field_b_tesla)))
    return arrays


def test_same_seed_gives_bit_identical_streams() -> None:
    a, b = stream_arrays(run_suite(7)), stream_arrays(run_suite(7))
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    c = stream_arrays(run_suite(8))
    assert any(not np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_one_sensors_config_does_not_change_another_sensors_noise() -> None:
    imu_a = [s for s in run_suite(7, gnss="modern") if isinstance(s, ImuSample)]
    imu_b = [s for s in run_suite(7, gnss="paper-p2") if isinstance(s, ImuSample)]
    for x, y in zip(imu_a, imu_b, strict=True):
        np.testing.assert_array_equal(x.angular_rate_b_rps, y.angular_rate_b_rps)


def test_suite_rates_and_time_order() -> None:
    suite = SensorSuite(suite_config(gnss="paper-p2"), seed=1, sim_rate_hz=200.0)
    counts = {ImuSample: 0, GnssFix: 0, BaroSample: 0, MagSample: 0, AirspeedSample: 0}
    for k in range(2000):  # 10 s
        t = stationary_truth(k)
        out = suite.step(t)
        times = [s.time_us for s in out]
        assert times == sorted(times) and all(x <= t.time_us for x in times)
        for s in out:
            counts[type(s)] += 1
    assert counts == {
        ImuSample: 2000, GnssFix: 50, BaroSample: 500, MagSample: 500, AirspeedSample: 500
    }


def test_imu_decimation_averages_truth_over_interval() -> None:
    config = suite_config(baro="ideal", mag="ideal", imu_rate_hz=50.0).model_copy(
        update={"imu": ideal_imu().model_dump()}
    )
    suite = SensorSuite(config, seed=0, sim_rate_hz=200.0)
    samples = []
    for k in range(13):
        # Linear ramp: the trapezoidal interval average is exact.
        t = stationary_truth(k)
        t = Truth(
            **{
                **{f: getattr(t, f) for f in t.__slots__},
                "omega_b_rps": np.array([0.01 * k, -0.02 * k, 0.0]),
                "specific_force_b_mps2": np.array([0.1 * k, 0.0, -G]),
            }
        )
        samples += [s for s in suite.step(t) if isinstance(s, ImuSample)]
    assert [s.time_us for s in samples] == [0, 20_000, 40_000, 60_000]
    assert all(s.dt_s == pytest.approx(0.02) for s in samples)
    # Interval ending at step 8 covers steps 4..8: mean of k = 6.
    np.testing.assert_allclose(samples[2].angular_rate_b_rps, [0.06, -0.12, 0.0], atol=1e-15)
    np.testing.assert_allclose(samples[2].specific_force_b_mps2, [0.6, 0.0, -G], atol=1e-14)


@pytest.mark.parametrize(
    ("kwargs", "sim_rate", "match"),
    [
        ({"imu_rate_hz": 150.0}, 200.0, "divide"),
        ({"baro_rate_hz": 400.0}, 200.0, "baro_rate_hz"),
        ({"imu_rate_hz": 400.0}, 200.0, "divide"),
    ],
)
def test_suite_rejects_bad_rates(kwargs: dict[str, float], sim_rate: float, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SensorSuite(suite_config(**kwargs), seed=0, sim_rate_hz=sim_rate)  # type: ignore[arg-type]


def test_suite_rejects_negative_seed() -> None:
    with pytest.raises(ValueError, match="seed"):
        SensorSuite(suite_config(), seed=-1, sim_rate_hz=200.0)
