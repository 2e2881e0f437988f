"""fusion.aiding: measurement models (H against finite differences, ISA) and their controls."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth
from fusion.aiding import baro, gnss, mag
from fusion.config import BaroTuning, GnssTuning, MagTuning
from fusion.rotations import euler_to_quat, quat_multiply, quat_to_dcm, rotvec_to_quat
from fusion.state_layout import INS16, INS16_GNSS
from fusion.strapdown import InsState
from physconst.isa import isa_pressure_pa, pressure_altitude_m
from sim.samples import GnssFix
from tests.helpers.nav_synth import FIELD_N_T

LAY = INS16
TRUE = InsState.from_arrays(
    math.radians(47.3), math.radians(8.5), 650.0, [35.0, -12.0, 2.5],
    euler_to_quat([0.3, -0.1, 2.2]),
)  # fmt: skip
LEVER = (0.4, -0.2, -0.3)
OMEGA = (0.05, -0.08, 0.2)


def perturb(state: InsState, dx: np.ndarray) -> InsState:
    """Estimated state = true state + error dx (the error-state convention)."""
    t = earth.local_terms(state.lat_rad, state.alt_msl_m)
    return InsState.from_arrays(
        state.lat_rad + dx[0] / t.rho_n_m,
        state.lon_rad + dx[1] / (t.rho_e_m * t.cos_lat),
        state.alt_msl_m - dx[2],
        np.add(state.v_ned_mps, dx[3:6]),
        quat_multiply(rotvec_to_quat(dx[6:9]), state.q_nb),
    )


def numerical_h(zfun, eps: np.ndarray) -> np.ndarray:
    cols = []
    for j in range(LAY.n):
        dx = np.zeros(LAY.n)
        dx[j] = eps[j]
        cols.append((zfun(dx) - zfun(-dx)) / (2.0 * eps[j]))
    return np.array(cols).T


EPS = np.array([1.0] * 3 + [0.01] * 3 + [1e-4] * 3 + [1e-3] * 3 + [1e-5] * 3 + [0.1])


def test_gnss_position_h_matches_finite_differences() -> None:
    # a fix exactly at the true antenna position
    arm_n = quat_to_dcm(TRUE.q_nb) @ LEVER
    t = earth.local_terms(TRUE.lat_rad, TRUE.alt_msl_m)
    fix = (
        TRUE.lat_rad + arm_n[0] / t.rho_n_m,
        TRUE.lon_rad + arm_n[1] / (t.rho_e_m * t.cos_lat),
        TRUE.alt_msl_m - arm_n[2],
    )

    def z(dx: np.ndarray) -> np.ndarray:
        obs = gnss.position_model(LAY, perturb(TRUE, dx), *fix, 2.0, 3.0, LEVER)
        assert obs is not None
        return obs.z

    obs = gnss.position_model(LAY, TRUE, *fix, 2.0, 3.0, LEVER)
    assert obs is not None
    np.testing.assert_allclose(obs.z, 0.0, atol=1e-6)
    np.testing.assert_allclose(obs.H, numerical_h(z, EPS), atol=1e-6)
    np.testing.assert_allclose(obs.R, np.diag([4.0, 4.0, 9.0]))
    # the latency term: the fix saw the position d seconds ago, dr(t - d) = dr - dv d
    delayed = gnss.position_model(LAY, TRUE, *fix, 2.0, 3.0, LEVER, delay_s=0.2)
    assert delayed is not None
    np.testing.assert_allclose(delayed.H[:, LAY.vel], -0.2 * np.eye(3))


def test_gnss_position_h_with_bias_states_matches_finite_differences() -> None:
    # GIVEN a fix carrying a receiver bias b (no white noise), the filter's bias estimate
    # b^ = b + db, and the layout with the GNSS bias block
    lay = INS16_GNSS
    g = lay.gnss
    assert g is not None
    b_true = np.array([1.2, -0.7, 2.1])
    arm_n = quat_to_dcm(TRUE.q_nb) @ LEVER
    t = earth.local_terms(TRUE.lat_rad, TRUE.alt_msl_m)
    d = arm_n + b_true
    fix = (
        TRUE.lat_rad + d[0] / t.rho_n_m,
        TRUE.lon_rad + d[1] / (t.rho_e_m * t.cos_lat),
        TRUE.alt_msl_m - d[2],
    )

    def z(dx: np.ndarray) -> np.ndarray:
        b_hat = b_true + dx[g]
        obs = gnss.position_model(
            lay, perturb(TRUE, dx), *fix, 0.5, 0.8, LEVER, bias_ned_m=tuple(b_hat)
        )
        assert obs is not None
        return obs.z

    eps = np.concatenate([EPS, [0.5, 0.5, 0.5]])
    cols = []
    for j in range(lay.n):
        dx = np.zeros(lay.n)
        dx[j] = eps[j]
        cols.append((z(dx) - z(-dx)) / (2.0 * eps[j]))
    h_num = np.array(cols).T
    # WHEN the model is evaluated at the true state and the true bias
    obs = gnss.position_model(lay, TRUE, *fix, 0.5, 0.8, LEVER, bias_ned_m=tuple(b_true))
    assert obs is not None
    # THEN z is zero, H matches the finite differences, with H = I on the bias block
    np.testing.assert_allclose(obs.z, 0.0, atol=1e-6)
    np.testing.assert_allclose(obs.H, h_num, atol=1e-6)
    np.testing.assert_array_equal(obs.H[:, g], np.eye(3))
    np.testing.assert_allclose(obs.R, np.diag([0.25, 0.25, 0.64]))
    # AND without a bias estimate (a bridging pseudo-fix) the bias block of H stays zero
    plain = gnss.position_model(lay, TRUE, *fix, 0.5, 0.8, LEVER)
    assert plain is not None
    np.testing.assert_array_equal(plain.H[:, g], 0.0)
    np.testing.assert_allclose(plain.z, -b_true, atol=1e-6)
    # AND a bias estimate for a layout without the block is an error, not a silent no-op
    with pytest.raises(ValueError, match="no GNSS"):
        gnss.position_model(INS16, TRUE, *fix, 0.5, 0.8, LEVER, bias_ned_m=(0.0, 0.0, 0.0))


def test_white_position_sigmas_take_the_bias_out_of_the_reported_accuracy() -> None:
    cfg = GnssTuning(bias_sigma_h_m=1.4, bias_sigma_v_m=2.4)
    # the modern receiver's eph = hypot(1.4, 0.5), epv = hypot(2.4, 0.8): the white parts remain
    h, v = gnss.white_position_sigmas(math.hypot(1.4, 0.5), math.hypot(2.4, 0.8), cfg, INS16_GNSS)
    assert (h, v) == (pytest.approx(0.5), pytest.approx(0.8))
    # a receiver reporting less than the bias sigma: the floor
    assert gnss.white_position_sigmas(1.0, 2.0, cfg, INS16_GNSS) == (0.5, 0.5)
    # without bias states the reported sigmas are used as they are
    assert gnss.white_position_sigmas(1.5, 2.5, cfg, INS16) == (1.5, 2.5)


def test_gnss_velocity_h_matches_finite_differences() -> None:
    def z(dx: np.ndarray) -> np.ndarray:
        # the model sees the bias-corrected rate omega^ = omega - dbg
        omega_hat = tuple(np.subtract(OMEGA, dx[LAY.bg]))
        obs = gnss.velocity_model(LAY, perturb(TRUE, dx), omega_hat, np.zeros(3), 0.2, LEVER)
        assert obs is not None
        return obs.z

    obs = gnss.velocity_model(LAY, TRUE, OMEGA, np.zeros(3), 0.2, LEVER)
    assert obs is not None
    h_num = numerical_h(z, EPS)
    # d omega_in / d position is neglected in the model (~1e-9 per metre)
    h_num[:, LAY.pos] = 0.0
    np.testing.assert_allclose(obs.H, h_num, atol=1e-7)
    # lever-arm velocity: omega × l rotated, minus the n-frame rate × lever arm
    c = quat_to_dcm(TRUE.q_nb)
    w_in = earth.earth_rate_n(TRUE.lat_rad) + earth.transport_rate_n(
        TRUE.lat_rad, TRUE.alt_msl_m, TRUE.v_ned_mps
    )
    expected = np.array(TRUE.v_ned_mps) + c @ np.cross(OMEGA, LEVER) - np.cross(w_in, c @ LEVER)
    np.testing.assert_allclose(obs.z, expected, atol=1e-12)


def test_gnss_models_reject_garbage() -> None:
    assert gnss.position_model(LAY, TRUE, math.nan, 0.1, 0.0, 1.0, 1.0) is None
    assert gnss.position_model(LAY, TRUE, 0.8, 0.1, 0.0, 0.0, 1.0) is None
    assert gnss.velocity_model(LAY, TRUE, OMEGA, np.array([1.0, math.inf, 0.0]), 0.1) is None


def test_isa_pressure_height() -> None:
    assert pressure_altitude_m(101325.0) == pytest.approx(0.0, abs=1e-9)
    # standard-atmosphere tables
    assert pressure_altitude_m(89874.6) == pytest.approx(1000.0, abs=0.1)
    assert pressure_altitude_m(22632.06) == pytest.approx(11000.0, abs=0.5)
    assert pressure_altitude_m(5474.89) == pytest.approx(20000.0, abs=1.0)
    for h in (-300.0, 0.0, 1234.5, 10999.0, 11001.0, 18000.0):
        assert pressure_altitude_m(isa_pressure_pa(h)) == pytest.approx(h, abs=1e-6)
    assert math.isnan(pressure_altitude_m(0.0))
    assert math.isnan(pressure_altitude_m(math.nan))


def test_baro_h_matches_finite_differences() -> None:
    bias, h_baro = 12.0, TRUE.alt_msl_m + 12.0

    def z(dx: np.ndarray) -> np.ndarray:
        obs = baro.height_model(LAY, perturb(TRUE, dx).alt_msl_m, bias + dx[LAY.BARO], h_baro, 0.5)
        assert obs is not None
        return obs.z

    obs = baro.height_model(LAY, TRUE.alt_msl_m, bias, h_baro, 0.5)
    assert obs is not None
    np.testing.assert_allclose(obs.z, 0.0, atol=1e-9)
    np.testing.assert_allclose(obs.H, numerical_h(z, EPS), atol=1e-9)
    assert obs.R[0, 0] == pytest.approx(0.25)
    assert baro.height_model(LAY, TRUE.alt_msl_m, bias, math.nan, 0.5) is None


def test_baro_h_with_the_scale_factor_matches_finite_differences() -> None:
    # GIVEN the layout with the baro scale factor, 4 % of scale and 150 m above the reference
    from fusion.state_layout import INS35

    lay = INS35
    bias, scale, h_ref = 12.0, 0.04, TRUE.alt_msl_m - 150.0
    h_baro = TRUE.alt_msl_m + bias + scale * 150.0

    def z(dx: np.ndarray) -> np.ndarray:
        est = perturb(TRUE, dx[:16])
        obs = baro.height_model(lay, est.alt_msl_m, bias + dx[lay.BARO], h_baro, 0.5,
                                scale + dx[lay.BS], h_ref)  # fmt: skip
        assert obs is not None
        return obs.z

    obs = baro.height_model(lay, TRUE.alt_msl_m, bias, h_baro, 0.5, scale, h_ref)
    assert obs is not None
    np.testing.assert_allclose(obs.z, 0.0, atol=1e-9)
    eps = np.r_[EPS, [1e-3] * (lay.n - EPS.size)]
    cols = []
    for j in range(lay.n):
        dx = np.zeros(lay.n)
        dx[j] = eps[j]
        cols.append((z(dx) - z(-dx)) / (2.0 * eps[j]))
    # THEN H is the model's derivative: -(1 + s) on pos D, 1 on the bias, h - h_ref on the scale
    np.testing.assert_allclose(obs.H, np.array(cols).T, atol=1e-9)
    assert obs.H[0, lay.POS + 2] == pytest.approx(-(1.0 + scale))
    assert obs.H[0, lay.BS] == pytest.approx(150.0)


def test_mag_heading_h_matches_finite_differences() -> None:
    field_b = quat_to_dcm(TRUE.q_nb).T @ FIELD_N_T

    def z(dx: np.ndarray) -> np.ndarray:
        c_hat = quat_to_dcm(perturb(TRUE, dx).q_nb)
        obs = mag.heading_model(LAY, c_hat, field_b, FIELD_N_T, 0.05)
        assert obs is not None
        return obs.z

    obs = mag.heading_model(LAY, quat_to_dcm(TRUE.q_nb), field_b, FIELD_N_T, 0.05)
    assert obs is not None
    np.testing.assert_allclose(obs.z, 0.0, atol=1e-12)
    np.testing.assert_allclose(obs.H, numerical_h(z, EPS), atol=1e-6)
    # a pure yaw error shows up one to one
    c_hat = quat_to_dcm(quat_multiply(rotvec_to_quat([0.0, 0.0, 0.1]), TRUE.q_nb))
    yawed = mag.heading_model(LAY, c_hat, field_b, FIELD_N_T, 0.05)
    assert yawed is not None and yawed.z[0] == pytest.approx(0.1, abs=1e-12)
    # no usable horizontal field
    assert (
        mag.heading_model(LAY, np.eye(3), np.array([0.0, 0.0, 4e-5]), FIELD_N_T, 0.05, 1e-6) is None
    )


def make_fix(t_us: int, **kw: object) -> GnssFix:
    base = dict(
        time_us=t_us, lat_rad=0.8, lon_rad=0.1, alt_msl_m=500.0, v_ned_mps=np.zeros(3),
        eph_m=1.5, epv_m=2.5, speed_accuracy_mps=0.2, fix_type=3,
    )  # fmt: skip
    base.update(kw)
    return GnssFix(**base)  # type: ignore[arg-type]


def test_fix_quality_and_sigmas() -> None:
    cfg = GnssTuning(max_eph_m=10.0, pos_noise_floor_m=2.0)
    assert gnss.fix_quality(make_fix(0), cfg) is None
    assert gnss.fix_quality(make_fix(0, fix_type=2), cfg) == "no_fix"
    assert gnss.fix_quality(make_fix(0, lat_rad=math.nan), cfg) == "invalid"
    assert gnss.fix_quality(make_fix(0, v_ned_mps=np.array([0.0, math.inf, 0.0])), cfg) == "invalid"
    assert gnss.fix_quality(make_fix(0, eph_m=12.0), cfg) == "inaccurate"
    assert gnss.fix_sigmas(make_fix(0), cfg) == (2.0, 2.5, 0.2)


def test_gnss_control_outage_reacquisition_and_reset() -> None:
    cfg = GnssTuning(outage_timeout_s=1.0, reacquire_fixes=3, reset_after_rejected_s=5.0)
    ctl = gnss.GnssControl(cfg)
    ctl.start(0)
    # GIVEN fixes every 0.2 s, all fused
    for k in range(1, 6):
        t = k * 200_000
        assert ctl.on_good_fix(t, t)
        assert not ctl.on_result("pos", t, True)
    assert ctl.is_active(1_000_000)
    # WHEN they stop for 3 s
    assert not ctl.is_active(2_100_000)
    assert ctl.time_since_fused_s(3_000_000) == pytest.approx(2.0)
    # THEN the first two returning fixes are held back, the third is fused
    assert not ctl.on_good_fix(4_000_000, 4_000_000)
    assert not ctl.on_good_fix(4_200_000, 4_200_000)
    assert ctl.on_good_fix(4_400_000, 4_400_000)
    # and if the INS drifted so far that the gate rejects it, reset at once
    assert ctl.on_result("pos", 4_400_000, False)
    ctl.on_reset("pos", 4_400_000)
    assert ctl.is_active(4_400_000)
    # a bad fix in between restarts the count
    ctl2 = gnss.GnssControl(cfg)
    ctl2.start(0)
    assert not ctl2.on_good_fix(3_000_000, 3_000_000)
    ctl2.on_bad_fix()
    assert not ctl2.on_good_fix(3_200_000, 3_200_000)
    assert not ctl2.on_good_fix(3_400_000, 3_400_000)
    assert ctl2.on_good_fix(3_600_000, 3_600_000)


def test_gnss_control_glitch_rejections_reset_only_after_the_timeout() -> None:
    ctl = gnss.GnssControl(GnssTuning(reset_after_rejected_s=5.0))
    ctl.start(0)
    t = 0
    resets = []
    for _ in range(40):  # 8 s of rejected good-quality fixes at 5 Hz
        t += 200_000
        ctl.on_good_fix(t, t)
        resets.append(ctl.on_result("pos", t, False))
    first = resets.index(True)
    assert (first + 1) * 0.2 == pytest.approx(5.2, abs=0.21)


def test_baro_control_batches_and_bias_init() -> None:
    ctl = baro.BaroControl(BaroTuning(fuse_rate_hz=10.0))
    out = [ctl.add_sample(t, 100.0 + t * 1e-6) for t in range(20_000, 1_000_001, 20_000)]
    batches = [b for b in out if b is not None]
    assert batches[0] == (20_000, pytest.approx(100.02), 1)
    # later batches: 5 samples of 20 ms, mean time in the middle
    t_mean, h_mean, n = batches[1]
    assert n == 5 and t_mean == 80_000 and h_mean == pytest.approx(100.08)
    assert ctl.need_bias_init(80_000)
    ctl.on_bias_init()
    assert not ctl.need_bias_init(100_000)
    assert ctl.is_active(1_000_000) and not ctl.is_active(3_000_000)


def test_mag_control_rate_limit_and_learning() -> None:
    ctl = mag.MagControl(MagTuning(fuse_rate_hz=5.0, reference="learned"))
    assert [ctl.due(t) for t in range(0, 1_000_000, 50_000)].count(True) == 5
    assert ctl.reference_n is None
    ctl.learn(FIELD_N_T, yaw_sigma_rad=0.2)  # heading not good enough yet
    assert ctl.reference_n is None
    for _ in range(mag.LEARN_SAMPLES):
        ctl.learn(FIELD_N_T, yaw_sigma_rad=0.01)
    assert ctl.learned
    np.testing.assert_allclose(ctl.reference_n, FIELD_N_T)


def test_mag_control_wmm_reference_is_located_and_never_learned() -> None:
    from physconst.geomag import magnetic_field_ned_t

    ctl = mag.MagControl(MagTuning(decimal_year=2020.5))
    assert ctl.follows_model and ctl.reference_n is None  # nowhere yet
    lat, lon = math.radians(-33.9), math.radians(151.2)
    ctl.locate(lat, lon, 50.0)
    want = magnetic_field_ned_t(lat, lon, 50.0, 2020.5).ned_t
    np.testing.assert_allclose(ctl.reference_n, want, rtol=1e-12)
    ctl.locate(lat + 200.0 / 6.371e6, lon, 50.0)  # 200 m on: the same evaluation
    np.testing.assert_allclose(ctl.reference_n, want, rtol=1e-12)
    ctl.locate(lat + 2000.0 / 6.371e6, lon, 50.0)  # 2 km on: re-evaluated
    assert not np.allclose(ctl.reference_n, want, rtol=1e-9, atol=0.0)
    for _ in range(mag.LEARN_SAMPLES):
        ctl.learn(FIELD_N_T, yaw_sigma_rad=0.01)
    assert not ctl.learned
    # a configured field overrides the model
    fixed = mag.MagControl(MagTuning(reference_field_n_tesla=(2e-5, 0.0, 4e-5)))
    fixed.locate(lat, lon, 50.0)
    assert not fixed.follows_model
    np.testing.assert_allclose(fixed.reference_n, (2e-5, 0.0, 4e-5))


def test_hard_iron_calibration_recovers_the_offset_and_the_earth_field() -> None:
    from fusion.rotations import euler_to_dcm

    rng = np.random.default_rng(3)
    offset = np.array([1.0e-6, -0.6e-6, 0.8e-6])
    cal = mag.HardIronCalibrator(math.radians(150.0), 5e-6)
    # one straight leg: no heading spread, no solution however many samples
    for _ in range(200):
        c_nb = euler_to_dcm(np.array([0.0, 0.02, 0.3]))
        cal.add(c_nb, c_nb.T @ FIELD_N_T + offset + rng.normal(0, 0.2e-6, 3), 0.3)
    assert not cal.solved
    # a racetrack: headings all round, banked turns
    for k in range(1500):
        yaw = 2 * math.pi * k / 300
        roll = math.radians(25.0) * math.sin(2 * math.pi * k / 150)
        c_nb = euler_to_dcm(np.array([roll, 0.03, yaw]))
        cal.add(c_nb, c_nb.T @ FIELD_N_T + offset + rng.normal(0, 0.2e-6, 3), yaw)
    assert cal.solved
    assert cal.offset_b is not None and cal.field_n is not None
    np.testing.assert_allclose(cal.offset_b, offset, atol=0.1e-6)
    np.testing.assert_allclose(cal.field_n, FIELD_N_T, atol=0.1e-6)


def test_mag_heading_is_fused_loosely_until_the_hard_iron_is_calibrated() -> None:
    cfg = MagTuning()
    ctl = mag.MagControl(cfg)
    assert ctl.heading_noise_rad() == cfg.uncalibrated_heading_noise_rad
    off = mag.MagControl(MagTuning(hard_iron_calibration=False))
    assert off.heading_noise_rad() == cfg.heading_noise_rad
    assert off.corrected(FIELD_N_T) is FIELD_N_T
