"""fusion.aiding.airspeed / pitot_monitor and the filter's air data: wind states, TAS and
sideslip fusion, dead reckoning, pitot faults, synthetic airspeed."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import chi2

from fusion import earth
from fusion.aiding.airspeed import sideslip_model, tas_model
from fusion.config import AirspeedTuning, FilterConfig
from fusion.estimate import AidSource, NavEstimate
from fusion.filter import NavFilter
from fusion.rotations import euler_to_quat, quat_multiply, rotvec_to_quat
from fusion.state_layout import layout_for
from tests.helpers.nav_synth import (
    Flight,
    Prepared,
    Scenario,
    SensorErrors,
    airspeed_samples,
    make_scenario,
    merge,
    prepare,
    run_nees,
)

WIND = (6.0, -4.0)
# these synthetic flights have *white* TAS noise and no turbulence: the matched setting is 5 Hz
# batches with a 1 m/s floor and (nearly) no gusts (the defaults, 1 Hz and 1.5 m/s gusts, are for
# JSBSim's turbulence: AirspeedTuning.fuse_rate_hz, gust_sigma_mps). The turbulence estimate is
# off: it would take the white TAS noise these flights inject for gusts (on a real pitot the
# batch average leaves little white noise; tests/fusion/test_turbulence.py checks the estimate)
WHITE_NOISE_AIR = AirspeedTuning(fuse_rate_hz=5.0, tas_noise_floor_mps=1.0, gust_sigma_mps=0.05,
                                 adaptive_turbulence=False)
CFG = FilterConfig(state_layout="ins16+air", airspeed=WHITE_NOISE_AIR)
ERRORS = SensorErrors.from_config(CFG)
# the filter's TAS model: 1 m/s floor per 5 Hz batch = 2 m/s white at 20 Hz (4 per batch)
TAS_NOISE_MPS = 2.0
OUTAGE = (100.0, 400.0)


@pytest.fixture(scope="module")
def long_flight() -> Prepared:
    """400 s at 30 m/s through a 7.2 m/s wind: turns every minute, a climb and a descent,
    a slow airspeed wave."""
    turns = [(20.0, 35.0, 0.2), (60.0, 75.0, -0.2), (130.0, 145.0, 0.2), (190.0, 205.0, 0.2),
             (250.0, 265.0, -0.2), (310.0, 325.0, 0.2), (360.0, 375.0, -0.2)]  # fmt: skip
    return prepare(Flight(duration_s=OUTAGE[1], speed_mps=30.0, wind_ne_mps=WIND, turns=turns,
                          climbs=[(80.0, 95.0, 3.0), (220.0, 235.0, -3.0)],
                          speed_wave_mps=2.0))  # fmt: skip


def run(nav: NavFilter, samples: list[object]) -> list[NavEstimate]:
    out: list[NavEstimate] = []
    for s in samples:
        out.extend(nav.step(s))
    return out


def horizontal_error_m(sc: Scenario, est: NavEstimate) -> float:
    kin = sc.traj(np.array([est.time_us * 1e-6]))
    d = earth.ned_offset_m(est.lat_rad, est.lon_rad, est.alt_msl_m, *kin.lla[0])
    return math.hypot(d[0], d[1])


def at(est: list[NavEstimate], t_s: float) -> NavEstimate:
    return min(est, key=lambda e: abs(e.time_us * 1e-6 - t_s))


def air_config(**kw: object) -> FilterConfig:
    return CFG.model_copy(update={"airspeed": WHITE_NOISE_AIR.model_copy(update=kw)})


# --------------------------------------------------------------------------- models
def test_tas_and_sideslip_jacobians_match_finite_differences() -> None:
    # GIVEN an operating point with wind, a climb and a non-zero sideslip
    lay = layout_for("ins16+gnss+air")
    v = (25.0, 8.0, -2.0)
    wind = (4.0, -3.0)
    k = 0.02
    q = tuple(euler_to_quat(np.array([0.2, 0.05, 0.4])))

    def h_tas(dx: np.ndarray) -> float:
        # the estimate is truth + error: v^ = v + dv, w^ = w + dw + dg, k^ = k + dk (the
        # model sees the wind at the aircraft: mean wind plus gust)
        vv = tuple(np.add(v, dx[lay.vel]))
        ww = (wind[0] + dx[lay.WIND] + dx[lay.GUST], wind[1] + dx[lay.WIND + 1] + dx[lay.GUST + 1])
        obs = tas_model(lay, vv, ww, k + dx[lay.ASPD_SCALE], 0.0, 1.0)  # type: ignore[arg-type]
        assert obs is not None
        return float(obs.z[0])

    def h_beta(dx: np.ndarray) -> float:
        vv = tuple(np.add(v, dx[lay.vel]))
        ww = (wind[0] + dx[lay.WIND] + dx[lay.GUST], wind[1] + dx[lay.WIND + 1] + dx[lay.GUST + 1])
        # C^_nb = (I + [phi×]) C_nb: q^ = q(phi) ⊗ q
        qq = tuple(quat_multiply(rotvec_to_quat(dx[lay.att]), np.array(q)))
        obs = sideslip_model(lay, vv, qq, ww, 0.3)  # type: ignore[arg-type]
        assert obs is not None
        return float(obs.z[0])

    for h, obs in (
        (h_tas, tas_model(lay, v, wind, k, 0.0, 1.0)),
        (h_beta, sideslip_model(lay, v, q, wind, 0.3)),  # type: ignore[arg-type]
    ):
        assert obs is not None
        # WHEN each error state is perturbed (central differences, step 1e-5)
        eps = 1e-5
        num = np.zeros(lay.n)
        for i in range(lay.n):
            d = np.zeros(lay.n)
            d[i] = eps
            num[i] = (h(d) - h(-d)) / (2 * eps)
        # THEN the analytic Jacobian matches: truncation ~eps^2 |h''| ~ 1e-10 of the entries
        # (which are O(1) for TAS, O(1/V) for beta), far inside 1e-7
        np.testing.assert_allclose(obs.H[0], num, atol=1e-7)


# --------------------------------------------------------------------------- dormant block
def test_without_air_data_the_air_layout_navigates_as_the_layout_without_it(
    long_flight: Prepared,
) -> None:
    # GIVEN a stream without air data (60 s)
    sc = make_scenario(long_flight, np.random.default_rng(3), ERRORS)
    samples = [s for s in sc.samples if s.time_us <= 60_000_000]  # type: ignore[attr-defined]
    # WHEN the same filter runs with and without the air-data block
    plain = run(NavFilter(FilterConfig(state_layout="ins16")), samples)
    nav = NavFilter(CFG)
    air = run(nav, samples)
    # THEN the block stayed dormant (zero rows, no wind) and the navigation is the same to
    # rounding (the same arithmetic on a larger, zero-padded matrix)
    assert len(plain) == len(air)
    a, b = plain[-1], air[-1]
    assert nav.wind_ne_mps is None and b.air_data is not None and b.air_data.state == "waiting"
    assert np.all(nav.covariance[nav.layout.air, :] == 0.0)
    assert a.lat_rad == pytest.approx(b.lat_rad, abs=1e-12)
    assert a.lon_rad == pytest.approx(b.lon_rad, abs=1e-12)
    np.testing.assert_allclose(b.v_ned_mps, a.v_ned_mps, atol=1e-9)
    np.testing.assert_allclose(b.P_diag[:16], a.P_diag, rtol=1e-9, atol=1e-15)
    assert a.mode == b.mode == "gnss"


# --------------------------------------------------------------------------- wind, outage
def test_wind_converges_to_the_true_wind_while_gnss_is_good(long_flight: Prepared) -> None:
    # GIVEN 100 s with GNSS and a pitot in a steady 7.2 m/s wind, with turns
    rng = np.random.default_rng(11)
    sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
    air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS)
    samples = merge(sc.samples, air)
    nav = NavFilter(CFG)
    est = run(nav, [s for s in samples if s.time_us <= 99_000_000])  # type: ignore[attr-defined]
    last = est[-1]
    assert last.air_data is not None and last.air_data.state == "fusing"
    w = np.array(last.air_data.wind_ne_mps)
    sd = np.sqrt(last.P_diag[nav.layout.air][:2])
    # THEN the wind is within 4 of the filter's sigmas of the truth, and the sigma is small:
    # after three turns the TAS (1 m/s per batch, ~500 batches) and GNSS velocity (0.15 m/s)
    # pin the wind far below the TAS noise; 0.5 m/s is half of one batch's sigma
    assert np.all(np.abs(w - WIND) < 4.0 * sd), (w, sd)
    assert np.all(sd < 0.5), sd
    assert nav.health.airspeed_fused > 400 and nav.health.wind_resets == 1
    assert nav.health.sideslip_fused > 400


def test_the_wind_waits_for_the_heading_and_is_not_left_wrong_by_its_alignment(
    long_flight: Prepared,
) -> None:
    # GIVEN the first 60 s of a flight without a magnetometer: the heading aligns from the
    # GNSS velocity (sigma ~15 deg at 2 s) and is known only after the first turn (20-35 s);
    # on seed 2 it is 10-15 deg off in the first seconds
    rng = np.random.default_rng(2)
    sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
    air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS)
    nav = NavFilter(CFG)
    samples = [s for s in merge(sc.samples, air) if s.time_us <= 60_000_000]  # type: ignore[attr-defined]
    est = run(nav, samples)
    lay, max_sd = nav.layout, math.radians(CFG.airspeed.wind_start_max_heading_sigma_deg)
    started = next(e for e in est if e.air_data is not None and e.air_data.state == "fusing")
    # THEN the wind starts only once the heading's sigma is within the bound (a wind computed
    # from a heading still aligning carries its error without the correlation)
    waiting = [e for e in est if e.air_data is not None and e.air_data.state == "waiting"]
    assert waiting and waiting[-1].time_us < started.time_us
    assert math.sqrt(float(started.P_diag[lay.ATT + 2])) <= max_sd * 1.01
    assert max(math.sqrt(float(e.P_diag[lay.ATT + 2])) for e in waiting) > max_sd
    # AND after the turn the wind is right within 3 of its sigmas (started at once, at 2 s,
    # it is 1.7 m/s off with a sigma of 0.35 m/s here: the sideslip and airspeed updates take
    # the heading's error for information)
    last = est[-1]
    assert last.air_data is not None
    w = np.array(last.air_data.wind_ne_mps)
    sd = np.sqrt(last.P_diag[lay.air][:2])
    assert np.all(np.abs(w - WIND) < 3.0 * sd), (w - WIND, sd)
    assert nav.health.wind_resets == 1


@pytest.mark.slow
def test_air_data_holds_a_300_s_outage_far_better_than_free_inertial(
    long_flight: Prepared,
) -> None:
    # GIVEN GNSS lost for 300 s (after 100 s of GNSS) in a 7.2 m/s wind, a pitot at 20 Hz
    ratios = []
    nav_e, nav_p = [], []
    evals = np.arange(110.0, OUTAGE[1] - 1.0, 10.0)
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
        air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS)
        with_air = dataclasses.replace(sc, samples=merge(sc.samples, air))
        # WHEN the same stream is fused with air data and with air data off
        nav = NavFilter(CFG)
        e, p = run_nees(nav, with_air, evals)
        nav_e.append(e[:, :9])
        nav_p.append(p[:, :9, :9])
        est_on = nav.estimate()
        off = NavFilter(air_config(enabled=False))
        est_off = run(off, with_air.samples)
        assert est_on is not None
        assert est_on.mode == "dead-reckoning" and est_off[-1].mode == "free-inertial"
        assert off.health.airspeed_ignored == len(air)
        assert nav.health.airspeed_blockages == 0  # a healthy pitot is never dropped
        ratios.append(horizontal_error_m(sc, est_on) / horizontal_error_m(sc, est_off[-1]))
    # THEN the horizontal error after 300 s is at most half of free-inertial's (mean over the
    # seeds; none above 0.6). Free-inertial error grows as t^2..t^3 (tilt and accelerometer
    # bias errors integrated twice): 300-450 m here, for a mid-range MEMS whose biases the
    # filter had learned. With air data the velocity is held to |v - w| = TAS and its
    # direction to the heading, so the error grows only linearly, with the wind error at the
    # outage start (sigma ~0.3 m/s -> ~90 m in 300 s) and the heading error (no magnetometer
    # on this stream: V dpsi = 30 m/s x 0.3 deg = 0.16 m/s -> ~50 m): ~100-150 m, a third of
    # free inertial; half leaves a margin for the seeds' spread
    assert np.mean(ratios) <= 0.5 and max(ratios) <= 0.6, ratios
    # AND the position / velocity / attitude NEES over the outage stays in the chi-square 95 %
    # band of the 9 navigation states averaged over the seeds (the truth is the filter's model
    # family: IMU errors from its model, TAS noise at its floor, a constant wind it models as a
    # random walk, which can only make it conservative; measured ANEES 9.5 in [4.9, 14.4])
    err = np.array(nav_e)
    cov = np.array(nav_p)
    nees = np.einsum("sei,seij,sej->se", err, np.linalg.inv(cov), err).mean(axis=0)
    n_seeds = err.shape[0]
    lo, hi = chi2.ppf([0.025, 0.975], 9 * n_seeds) / n_seeds
    assert lo < nees.mean() < hi, (nees.mean(), lo, hi)


# --------------------------------------------------------------------------- bad input
def test_bad_diff_pressure_is_counted_and_never_fused(long_flight: Prepared) -> None:
    # GIVEN a pitot stream with NaN, negative, absurd and unreadable readings mixed in
    rng = np.random.default_rng(5)
    sc = make_scenario(long_flight, rng, ERRORS)
    air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS)
    air = [a for a in air if a.time_us <= 40_000_000]
    base = [s for s in sc.samples if s.time_us <= 40_000_000]  # type: ignore[attr-defined]
    bad = []
    for i, value in enumerate([math.nan, -50.0, 1e7, math.inf, "junk"]):
        t = 20_000_000 + 1_000 * (i + 1)  # between two good samples
        bad.append(dataclasses.replace(air[0], time_us=t, diff_pressure_pa=value))
    clean = NavFilter(CFG)
    est_clean = run(clean, merge(base, air))
    nav = NavFilter(CFG)
    est = run(nav, merge(base, sorted([*air, *bad], key=lambda s: s.time_us)))
    # THEN every bad reading is counted invalid, nothing raised, and the batches were the
    # good ones (the same update count)
    assert nav.health.airspeed_invalid == len(bad)
    assert nav.health.airspeed_fused == clean.health.airspeed_fused > 0
    assert est[-1].lat_rad == pytest.approx(est_clean[-1].lat_rad, abs=1e-9)


def test_airspeed_off_fuses_nothing(long_flight: Prepared) -> None:
    rng = np.random.default_rng(6)
    sc = make_scenario(long_flight, rng, ERRORS)
    air = [a for a in airspeed_samples(sc, WIND, rng) if a.time_us <= 30_000_000]
    samples = merge([s for s in sc.samples if s.time_us <= 30_000_000], air)  # type: ignore[attr-defined]
    nav = NavFilter(air_config(enabled=False))
    sources = set()
    for s in samples:
        nav.step(s)
        sources.update(i.source for i in nav.innovations)
    assert nav.health.airspeed_ignored == len(air) and nav.health.airspeed_fused == 0
    assert AidSource.AIRSPEED not in sources and AidSource.SIDESLIP not in sources
    assert nav.wind_ne_mps is None and nav.air_data.state == "off"
    # a layout without the air-data block ignores air data the same way
    plain = NavFilter(FilterConfig(state_layout="ins16"))
    run(plain, samples)
    assert plain.health.airspeed_ignored == len(air)


# --------------------------------------------------------------------------- pitot faults
def _fault_run(
    prep: Prepared, fault: object, seed: int = 21, **cfg: object
) -> tuple[NavFilter, list[NavEstimate], Scenario]:
    rng = np.random.default_rng(seed)
    sc = make_scenario(prep, rng, ERRORS, gnss_outages=[OUTAGE])
    air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS, fault=fault)  # type: ignore[arg-type]
    nav = NavFilter(air_config(**cfg) if cfg else CFG)
    return nav, run(nav, merge(sc.samples, air)), sc


def _first_blocked_s(est: list[NavEstimate], after_s: float) -> float:
    return next(e.time_us * 1e-6 for e in est
                if e.time_us * 1e-6 >= after_s and e.air_data and e.air_data.state == "blocked")


@pytest.mark.slow
def test_a_pitot_reading_zero_in_an_outage_is_dropped_and_synthetic_airspeed_takes_over(
    long_flight: Prepared,
) -> None:
    # GIVEN the pitot reads zero (noise around 0 Pa) from 200 s, inside the outage
    t_fault = 200.0

    def zero(t: float, qc: float) -> float:
        return qc if t < t_fault else float(np.random.default_rng(int(t * 1e3)).normal(0, 1.0))

    nav, est, sc = _fault_run(long_flight, zero)
    # THEN it is declared blocked within 10 s (zero_time_s = 1 s after the first zero batch)
    t_block = _first_blocked_s(est, t_fault)
    assert t_block - t_fault <= 10.0
    h = nav.health
    assert h.airspeed_blockages == 1 and h.airspeed_blocked > 0 and h.airspeed_recoveries == 0
    assert at(est, 399.0).air_data.fault == "zero"  # type: ignore[union-attr]
    # AND the filter keeps dead-reckoning on the synthetic airspeed from the last wind estimate
    assert h.synthetic_airspeed_fused > 0
    assert at(est, 399.0).mode == "dead-reckoning"
    # AND it ends no worse than free inertial on the same stream (the synthetic TAS holds the
    # velocity against the wind the pitot had learned; on three seeds it ended 0.2-0.75x of
    # free inertial, +55 m over a healthy pitot on two of them)
    off = NavFilter(air_config(enabled=False))
    est_off = run(off, list(sc.samples))
    assert horizontal_error_m(sc, est[-1]) < horizontal_error_m(sc, est_off[-1])


def test_a_stuck_pitot_in_an_outage_is_dropped_within_10_s(long_flight: Prepared) -> None:
    # GIVEN the pitot output latches at 200 s (a frozen sensor: the same reading every sample)
    t_fault = 200.0
    held: list[float] = []

    def stuck(t: float, qc: float) -> float:
        if t < t_fault:
            return qc
        if not held:
            held.append(qc)
        return held[0]

    nav, est, _ = _fault_run(long_flight, stuck)
    # THEN it is blocked within 10 s (the stuck window is 4 s), not fused afterwards
    t_block = _first_blocked_s(est, t_fault)
    assert t_block - t_fault <= 10.0
    assert at(est, 399.0).air_data.fault == "stuck"  # type: ignore[union-attr]
    fused_after = [e for e in est if e.time_us * 1e-6 > t_block + 0.5
                   and e.aiding is not None and e.aiding.airspeed.time_last_fused_us is not None
                   and e.aiding.airspeed.time_last_fused_us > (t_block + 0.5) * 1e6
                   and e.air_data is not None and e.air_data.state != "synthetic"]
    assert nav.health.airspeed_recoveries == 0
    assert all(e.air_data is not None and e.air_data.state in ("blocked",) for e in fused_after)


def test_a_blocked_pitot_is_trusted_again_only_after_its_consistency_check(
    long_flight: Prepared,
) -> None:
    # GIVEN the pitot reads zero from 40 to 50 s (GNSS good) and is healthy again after
    def dropout(t: float, qc: float) -> float:
        return 0.0 if 40.0 <= t < 50.0 else qc

    nav, est, _ = _fault_run(long_flight, dropout)
    rec = nav.config.airspeed.recover_time_s
    # THEN it is blocked during the drop-out, still blocked for recover_time_s after it, and
    # fused again later; the zero readings were never fused
    assert nav.health.airspeed_blockages == 1 and nav.health.airspeed_recoveries == 1
    assert at(est, 45.0).air_data.state == "blocked"  # type: ignore[union-attr]
    assert at(est, 50.0 + 0.8 * rec).air_data.state == "blocked"  # type: ignore[union-attr]
    assert at(est, 50.0 + rec + 3.0).air_data.state == "fusing"  # type: ignore[union-attr]


# --------------------------------------------------------------------------- no pitot
@pytest.mark.slow
def test_synthetic_airspeed_without_a_pitot_beats_free_inertial(long_flight: Prepared) -> None:
    # GIVEN a fixed-wing without a pitot, synthetic airspeed on (the wind is learned from
    # sideslip and GNSS velocity), then GNSS is lost for 300 s; four seeds
    ratios = []
    for seed in (31, 32, 33, 34):
        errs = {}
        for synthetic in (True, False):
            rng = np.random.default_rng(seed)
            sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
            nav = NavFilter(air_config(synthetic_when_no_pitot=synthetic))
            est = run(nav, sc.samples)
            errs[synthetic] = horizontal_error_m(sc, est[-1])
            h = nav.health
            if synthetic:
                assert h.wind_resets == 1 and h.synthetic_airspeed_fused > 250
                assert est[-1].mode == "dead-reckoning"
                assert est[-1].air_data is not None and est[-1].air_data.state == "synthetic"
                w = np.array(at(est, 99.0).air_data.wind_ne_mps)  # type: ignore[union-attr]
                assert np.linalg.norm(w - WIND) < 2.0, w  # sideslip + GNSS learned the wind
            else:  # off by default: a stream without air data stays free-inertial
                assert h.wind_resets == 0 and est[-1].mode == "free-inertial"
        ratios.append(errs[True] / errs[False])
    # THEN synthetic airspeed is never worse than free inertial and on average well below it:
    # it bounds the velocity error by the synthetic TAS error (the airspeed wave, 1.4 m/s RMS,
    # averaging out over its period) and the wind error of sideslip learning (~0.5-1 m/s),
    # where the free INS's velocity error grows without bound (measured 0.15-0.86, mean 0.4)
    assert max(ratios) < 1.0 and np.mean(ratios) <= 0.6, ratios


def test_a_pitot_the_gate_keeps_rejecting_is_dropped(long_flight: Prepared) -> None:
    # GIVEN GNSS good and the pitot reading 60 % high from 40 s on (a partly blocked line
    # or a wrong calibration: the TAS is 26 % high, ~8 m/s, far outside its 1 m/s sigma)
    def high(t: float, qc: float) -> float:
        return qc * 1.6 if t >= 40.0 else qc

    nav, est, _ = _fault_run(long_flight, high)
    rej = nav.config.airspeed.reject_time_s
    # THEN every batch is rejected and after reject_time_s the pitot is declared blocked
    t_block = _first_blocked_s(est, 40.0)
    assert rej <= t_block - 40.0 <= rej + 1.0
    assert at(est, 60.0).air_data.fault == "rejected"  # type: ignore[union-attr]
    assert nav.health.airspeed_rejected >= rej * nav.config.airspeed.fuse_rate_hz
    assert nav.health.airspeed_recoveries == 0  # it never becomes consistent again


def test_wind_process_noise_grows_with_the_climb_rate() -> None:
    from fusion.error_model import ErrorModel, ProcessNoise

    nz = ProcessNoise(gyro_noise=1e-4, accel_noise=1e-3, gyro_bias_sigma=1e-5,
                      gyro_bias_tau_s=600.0, accel_bias_sigma=1e-3, accel_bias_tau_s=600.0,
                      baro_bias_sigma=5.0, baro_bias_tau_s=1000.0)  # fmt: skip
    model = ErrorModel(layout_for("ins16+air"), nz)
    level = model.air_process_noise(0.01, 0.0)
    climb = model.air_process_noise(0.01, -4.0)  # 4 m/s up (NED: negative)
    # (0.05 (1 + 0.5 * 4))^2 * 0.01 = 9x the level-flight value; the scale's does not change
    assert level[0] == pytest.approx(0.05**2 * 0.01)
    assert climb[0] == pytest.approx(9.0 * level[0]) and climb[1] == level[1] == 1e-8 * 0.01


@pytest.mark.slow
def test_a_stuck_noisy_pitot_that_misses_an_airspeed_change_is_dropped_within_10_s() -> None:
    # GIVEN a flight whose airspeed swings +-5 m/s (40 s period) and a pitot that keeps its
    # value at 200 s (inside the outage) but still shows its 1 Pa noise: only the failure to
    # follow the airspeed change the INS sees gives it away
    turns = [(20.0, 35.0, 0.2), (60.0, 75.0, -0.2)]
    prep = prepare(Flight(duration_s=260.0, speed_mps=30.0, wind_ne_mps=WIND, turns=turns,
                          speed_wave_mps=5.0))  # fmt: skip
    held: list[float] = []
    noise = np.random.default_rng(5)

    def stuck(t: float, qc: float) -> float:
        if t < 200.0:
            return qc
        if not held:
            held.append(qc)
        return held[0] + float(noise.normal(0.0, 1.0))

    rng = np.random.default_rng(21)
    sc = make_scenario(prep, rng, ERRORS, gnss_outages=[(100.0, 260.0)])
    air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS, fault=stuck)
    nav = NavFilter(CFG)
    est = run(nav, merge(sc.samples, air))
    # THEN it is declared stuck within 10 s: the check undoes the corrections the fused
    # stuck readings made to the velocity (4.2 s on the 400 s test flight with this fault,
    # 14.8 s there without undoing them)
    t_block = _first_blocked_s(est, 200.0)
    assert t_block - 200.0 <= 10.0
    assert est[-1].air_data is not None and est[-1].air_data.fault == "stuck"


def _vehicle_state(sc: Scenario, rng: np.random.Generator) -> list[object]:
    """20 Hz controls and rpm of an aircraft whose power setting follows its airspeed (the
    throttle loop of a speed-holding autopilot): throttle and propeller speed are smooth
    functions of the true air-relative speed, read with a little noise."""
    from sim.samples import ActuatorSample, RpmSample

    period_us = 50_000
    end_us = round(float(sc.imu_time_s[-1]) * 1e6)
    times = np.arange(period_us, end_us + 1, period_us, dtype=np.int64)
    kin = sc.traj(times * 1e-6)
    out: list[object] = []
    for i, t_us in enumerate(times.tolist()):
        v = kin.v_ned_mps[i]
        tas = math.sqrt((v[0] - WIND[0]) ** 2 + (v[1] - WIND[1]) ** 2 + v[2] ** 2)
        throttle = 0.55 + 0.04 * (tas - 30.0) + float(rng.normal(0.0, 0.005))
        controls = (0.0, 0.02, 0.0, throttle) + (0.0,) * 12
        out.append(ActuatorSample(t_us, controls))
        out.append(RpmSample(t_us, 2100.0 + 25.0 * tas + float(rng.normal(0.0, 5.0))))
    return out


def test_gmdh_airspeed_without_a_pitot_learns_the_airspeed_and_flies_the_outage_on_it(
    long_flight: Prepared,
) -> None:
    # GIVEN a fixed-wing without a pitot whose controls and rpm follow its airspeed (a 2 m/s
    # wave the latched synthetic airspeed cannot follow), 150 s of GNSS (the wind converges
    # in the first turns, then the model learns), then 250 s without
    from fusion.bridging.registry import make_bridge

    errs: dict[str, list[float]] = {"learned": [], "synthetic": []}
    for seed in (41, 42, 43):
        for method in ("learned", "synthetic"):
            rng = np.random.default_rng(seed)
            sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[(150.0, OUTAGE[1])])
            samples = merge(sc.samples, _vehicle_state(sc, np.random.default_rng(seed + 100)))
            if method == "learned":
                nav = NavFilter(air_config(), bridge=make_bridge("gmdh-airspeed"))
            else:
                nav = NavFilter(air_config(synthetic_when_no_pitot=True))
            est = run(nav, samples)
            errs[method].append(horizontal_error_m(sc, est[-1]))
            if method == "learned":
                h, st = nav.health, nav.bridge_status
                # THEN the model trained on the aided airspeed and its prediction was fused
                # through the outage at 1 Hz, in dead reckoning
                assert st.state == "trained" and st.refits >= 2 and "GMDH" in st.model
                assert h.learned_airspeed_fused > 200 and h.synthetic_airspeed_fused == 0
                assert est[-1].mode == "dead-reckoning"
                # its held-out error: throttle and rpm noise (0.13 / 0.2 m/s of airspeed) and
                # the sideslip-learned wind in its target (~0.5 m/s), well under the 2 m/s wave
                assert st.model_rmse < 1.0
    # AND it holds the outage better than the latched synthetic airspeed on every seed
    ratios = [a / b for a, b in zip(errs["learned"], errs["synthetic"], strict=True)]
    assert max(ratios) < 1.0, (ratios, errs)


def test_gmdh_airspeed_without_controls_reports_no_inputs_and_flies_as_the_filter(
    long_flight: Prepared,
) -> None:
    from fusion.bridging.registry import make_bridge

    rng = np.random.default_rng(44)
    sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
    nav = NavFilter(air_config(), bridge=make_bridge("gmdh-airspeed"))
    est = run(nav, sc.samples)
    assert nav.bridge_status.state == "no inputs"
    assert nav.health.learned_airspeed_fused == 0
    ref = run(NavFilter(air_config()), sc.samples)
    assert (est[-1].lat_rad, est[-1].lon_rad) == (ref[-1].lat_rad, ref[-1].lon_rad)


def test_gmdh_wind_learns_a_flat_profile_in_a_wind_without_shear_and_does_no_harm(
    long_flight: Prepared,
) -> None:
    # GIVEN the long flight (a 45 m climb with GNSS, the 45 m descent inside the outage) in a
    # wind that does not change with height
    from fusion.bridging.registry import make_bridge

    for seed in (41, 42):
        errs = {}
        for bridge in ("none", "gmdh-wind"):
            rng = np.random.default_rng(seed)
            sc = make_scenario(long_flight, rng, ERRORS, gnss_outages=[OUTAGE])
            air = airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS)
            samples = merge(sc.samples, air)
            nav = NavFilter(CFG, bridge=make_bridge(bridge))
            est = run(nav, samples)  # type: ignore[arg-type]
            errs[bridge] = horizontal_error_m(sc, est[-1])
            if bridge == "gmdh-wind":
                # THEN the profile trained while GNSS was good ...
                assert nav.bridge_status.state == "trained" and nav.bridge_status.refits >= 1
        # AND without shear it found no skill over a constant (or too little to matter): the
        # outage ends within 5 % of the plain air-data filter (an unguarded profile fitted to
        # the wind estimate still converging during the climb cost 4x on seed 42)
        assert errs["gmdh-wind"] <= 1.05 * errs["none"], (seed, errs)
