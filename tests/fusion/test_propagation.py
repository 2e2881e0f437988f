"""fusion.propagation (covariance time update, gap growth, bias decay) and
fusion.screening (which input samples are used)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth
from fusion.config import ImuTuning
from fusion.error_model import ErrorModel, ProcessNoise
from fusion.estimate import HealthCounters
from fusion.propagation import CovariancePropagator, decay_gnss_bias
from fusion.rotations import dcm_from_quat
from fusion.screening import SampleScreen
from fusion.state_layout import INS16, INS22
from fusion.strapdown import InsState, coast, increments, increments_scaled
from sim.samples import ImuSample

NOISE = ProcessNoise(1e-4, 1e-3, 1e-5, 600.0, 1e-3, 600.0, 5.0, 1000.0, 1e-3, 3600.0, 1e-3,
                     3600.0)  # fmt: skip
INS = InsState(0.7, 0.1, 500.0, (50.0, 10.0, -2.0), (1.0, 0.0, 0.0, 0.0))


def test_propagate_is_phi_p_phi_t_plus_q_with_the_mean_specific_force() -> None:
    # GIVEN 0.01 s accumulated, the INS having gained 0.05 m/s north
    model = ErrorModel(INS16, NOISE)
    cov = CovariancePropagator(model, 0.01, ImuTuning(), 1000.0)
    P0 = np.diag(np.linspace(1.0, 2.0, 16))
    v0 = (49.95, 10.0, -2.0)
    cov.restart(P0, v0)
    cov.acc_dt = 0.01
    k = cov.propagate(INS)
    # THEN the specific force is recovered from v' = f + g - (2 w_ie + w_en) x v
    lt = earth.local_terms(INS.lat_rad, INS.alt_msl_m)
    assert cov.f_n[0] == pytest.approx(5.0, rel=1e-3)
    assert cov.f_n[2] == pytest.approx(-lt.gravity_mps2, rel=1e-3)
    # AND P is the first-order transition applied to P0 plus the discrete process noise
    phi = model.first_order_transition(INS.lat_rad, INS.alt_msl_m, INS.v_ned_mps,
                                       dcm_from_quat(INS.q_nb), cov.f_n, 0.01)  # fmt: skip
    np.testing.assert_allclose(cov.P, phi @ P0 @ phi.T + model.process_noise(0.01), rtol=1e-13)
    # AND the interval restarts, and the baro-bias decay factor is returned
    assert cov.acc_dt == 0.0 and cov.v0 == INS.v_ned_mps
    assert k == math.exp(-0.01 / 1000.0)


def test_coast_propagates_in_sub_steps_and_adds_the_unknown_manoeuvre() -> None:
    imu = ImuTuning(gap_accel_sigma_mps2=2.0, gap_rate_sigma_rps=0.05)
    model = ErrorModel(INS22, NOISE)
    cov = CovariancePropagator(model, 0.01, imu, 1000.0)
    cov.restart(np.eye(22) * 1e-2, INS.v_ned_mps)
    P_before = cov.P.copy()
    decays = cov.coast(coast(INS, 2.5), INS.v_ned_mps, 2.5)
    # THEN 25 sub-steps of 0.1 s, each with its baro decay factor
    assert decays == [math.exp(-0.1 / 1000.0)] * 25
    grown = np.diag(cov.P) - np.diag(P_before)
    # AND position, velocity and attitude grew by at least the assumed manoeuvre
    assert np.all(grown[0:3] >= (0.5 * 2.0 * 2.5**2) ** 2)
    assert np.all(grown[3:6] >= (2.0 * 2.5) ** 2)
    assert np.all(grown[6:9] >= (0.05 * 2.5) ** 2)
    np.testing.assert_allclose(cov.P, cov.P.T, atol=1e-12)


def test_coast_moves_the_ins_at_constant_velocity() -> None:
    out = coast(INS, 2.0)
    lt = earth.local_terms(INS.lat_rad, INS.alt_msl_m)
    assert out.lat_rad == INS.lat_rad + 50.0 * 2.0 / lt.rho_n_m
    assert out.alt_msl_m == 504.0 and out.v_ned_mps is INS.v_ned_mps and out.q_nb is INS.q_nb


def test_gnss_bias_decays_with_its_correlation_times() -> None:
    b = decay_gnss_bias([1.0, -2.0, 3.0], 60.0, 120.0, 30.0)
    assert b == (math.exp(-0.5), -2.0 * math.exp(-0.5), 3.0 * math.exp(-2.0))


def test_increments_compensate_biases_and_scale_factors() -> None:
    fw = (1.0, 2.0, -9.0, 0.1, 0.2, 0.3)
    dth, dv = increments(fw, 0.01, (0.5, 0.0, 0.0), (0.0, 0.1, 0.0))
    assert dth == pytest.approx((0.001, 0.001, 0.003)) and dv == pytest.approx((0.005, 0.02, -0.09))
    dth, dv = increments_scaled(fw, 0.01, (0.0,) * 3, (0.0,) * 3, (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    assert dv[0] == pytest.approx(0.005) and dth[2] == pytest.approx(0.0015)
    assert increments_scaled(fw, 0.01, (0.5, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0,) * 3,
                             (0.0,) * 3) == increments(fw, 0.01, (0.5, 0.0, 0.0), (0.0, 0.1, 0.0))


# --------------------------------------------------------------------------- screening
def _imu(t_us: int, f: tuple[float, ...] = (0.0, 0.0, -9.8), dt: float = 0.01) -> ImuSample:
    return ImuSample(t_us, dt, np.array(f), np.zeros(3))


def test_imu_screen_holds_the_last_good_sample_and_flags_time_jumps() -> None:
    c = HealthCounters()
    screen = SampleScreen(ImuTuning(time_jump_s=1.0, max_dt_s=0.05), c)
    # the first sample is integrated over its own dt
    assert screen.imu(_imu(10_000)) == (10_000, 0.01, (0.0, 0.0, -9.8, 0.0, 0.0, 0.0), True, False)
    # a NaN sample is replaced by the last good one over its interval
    t, dt, fw, good, gap = screen.imu(_imu(20_000, (math.nan, 0.0, 0.0)))  # type: ignore[misc]
    assert (t, fw, good, gap) == (20_000, (0.0, 0.0, -9.8, 0.0, 0.0, 0.0), False, False)
    assert dt == pytest.approx(0.01)
    # duplicates, backwards and out-of-range samples
    assert screen.imu(_imu(20_000)) is None and screen.imu(_imu(15_000)) is None
    assert screen.imu(_imu(30_000, (1e4, 0.0, 0.0)))[3] is False  # type: ignore[index]
    # a forward step beyond time_jump_s is quarantined until confirmed by consecutive samples
    # at plausible intervals; then it is a gap, not integrated
    confirm = ImuTuning().time_base_confirm_samples
    for k in range(confirm - 1):
        assert screen.imu(_imu(2_030_000 + 10_000 * k)) is None
    step = screen.imu(_imu(2_030_000 + 10_000 * (confirm - 1)))
    assert step is not None and step[4] and step[1] == pytest.approx(2.0 + 0.01 * (confirm - 1))
    h = c.snapshot()
    assert (h.imu_ok, h.imu_nan, h.imu_out_of_range, h.duplicates, h.time_backwards,
            h.time_jump, h.time_quarantined) == (2, 1, 1, 1, 1, 1, confirm)  # fmt: skip


def test_one_bogus_stamp_never_moves_the_clock() -> None:
    # GIVEN a screen running at 100 Hz
    c = HealthCounters()
    screen = SampleScreen(ImuTuning(), c)
    t = 40_000_000
    assert screen.imu(_imu(t)) is not None
    for bogus in (t + 3_600_000_000, 2**64 - 1, -5, t - 30_000_000):
        # WHEN one sample an hour ahead, at 2^64-1, negative or 30 s back arrives
        assert screen.imu(_imu(bogus)) is None
        t += 10_000
        # THEN the next real sample is on the clock as if nothing had happened
        step = screen.imu(_imu(t))
        assert step is not None and step[0] == t and not step[4]
        assert step[1] == pytest.approx(0.01)
    # AND a stream of bogus stamps interleaved with the real one never confirms
    for k in range(20):
        assert screen.imu(_imu(t + 3_600_000_000 + 10_000 * k)) is None
        t += 10_000
        assert screen.imu(_imu(t)) is not None
    h = c.snapshot()
    assert h.time_quarantined == 3 + 20 and h.time_backwards == 1
    assert h.time_jump == 0 and not screen.rebase_pending


def test_a_consistent_step_back_or_a_long_gap_asks_for_a_rebase() -> None:
    confirm = ImuTuning().time_base_confirm_samples
    clock = 40_000_000
    for start in (clock - 30_000_000, clock + 20_000_000):  # 30 s back; a 20 s gap (> 10 s)
        screen = SampleScreen(ImuTuning(), HealthCounters())
        assert screen.imu(_imu(clock)) is not None
        for k in range(confirm - 1):
            assert screen.imu(_imu(start + 10_000 * k)) is None
            assert not screen.rebase_pending
        assert screen.imu(_imu(start + 10_000 * (confirm - 1))) is None
        assert screen.rebase_pending


def test_imu_screen_drops_until_a_good_sample_and_an_implausible_first_interval() -> None:
    c = HealthCounters()
    screen = SampleScreen(ImuTuning(max_dt_s=0.05), c)
    assert screen.imu(_imu(10_000, (math.nan, 0.0, 0.0))) is None  # nothing good to hold
    assert screen.last_imu_us == 10_000
    screen2 = SampleScreen(ImuTuning(max_dt_s=0.05), HealthCounters())
    assert screen2.imu(_imu(10_000, dt=0.2)) is None  # implausible first dt
    assert screen2.imu(_imu(20_000)) is not None


def test_aiding_order_screen_drops_repeats_backwards_and_far_future_stamps() -> None:
    c = HealthCounters()
    screen = SampleScreen(ImuTuning(max_sensor_lead_s=5.0), c)
    screen.last_imu_us = 1_000_000
    assert screen.order("gnss", 900_000) == 900_000
    assert screen.order("gnss", 900_000) is None and screen.order("gnss", 800_000) is None
    assert screen.order("baro", 800_000) == 800_000  # per sensor
    assert screen.order("mag", 7_000_000) is None  # 6 s ahead of the IMU
    assert screen.order("gnss", "soon") is None
    assert screen.order("baro", 2**64 - 1) is None and screen.order("baro", -1) is None
    h = c.snapshot()
    assert (h.duplicates, h.time_backwards, h.time_jump, h.gnss_invalid,
            h.baro_invalid) == (1, 1, 1, 1, 2)  # fmt: skip
