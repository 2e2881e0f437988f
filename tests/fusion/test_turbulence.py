"""fusion.aiding.turbulence and fusion.aiding.position_error: the turbulence intensity and the
pitot-static position error the air-data filter learns while GNSS is good."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.aiding.airspeed import AirspeedAiding
from fusion.aiding.position_error import PositionErrorFit
from fusion.aiding.turbulence import TurbulenceEstimator
from fusion.config import AirspeedTuning
from fusion.error_model import ErrorModel, ProcessNoise
from fusion.estimate import HealthCounters
from fusion.state_layout import layout_for

CFG = AirspeedTuning()


def gust_residuals(sigma_mps: float, n: int, seed: int, tau_s: float = 6.0) -> np.ndarray:
    """1 Hz samples of a first-order Gauss-Markov gust of ``sigma_mps`` (Dryden-like L/V)."""
    rng = np.random.default_rng(seed)
    phi = math.exp(-1.0 / tau_s)
    g = np.empty(n)
    g[0] = sigma_mps * rng.standard_normal()
    for k in range(1, n):
        g[k] = phi * g[k - 1] + sigma_mps * math.sqrt(1.0 - phi * phi) * rng.standard_normal()
    return g


def feed(est: TurbulenceEstimator, r: np.ndarray, sensor_sigma: float, seed: int) -> None:
    noise = np.random.default_rng(seed + 1000).normal(0.0, sensor_sigma, r.size)
    for x in r + noise:
        est.add(float(x), sensor_sigma**2)


@pytest.mark.parametrize("sigma", [0.8, 1.5, 2.5])
def test_the_estimate_finds_the_gust_sigma_under_the_sensor_noise(sigma: float) -> None:
    # GIVEN 20 min of 1 Hz residuals: a gust of `sigma` plus 0.5 m/s of pitot noise
    est = TurbulenceEstimator(CFG)
    feed(est, gust_residuals(sigma, 1200, seed=3), 0.5, seed=3)
    # THEN the estimate is the gust's, the sensor's share removed (a 120 s window of a process
    # correlated over 6 s holds ~10 independent values: 25 % is about 2.5 of its sigmas)
    assert est.estimate_mps == pytest.approx(sigma, rel=0.25)
    # AND above still air the gust states keep the prior, unless told to take the estimate
    assert est.source == "turbulent" and est.sigma_mps == CFG.gust_sigma_mps
    cfg = CFG.model_copy(update={"gust_sigma_estimated_above_still_air": True})
    taking = TurbulenceEstimator(cfg)
    feed(taking, gust_residuals(sigma, 1200, seed=3), 0.5, seed=3)
    assert taking.source == "estimated" and taking.sigma_mps == est.estimate_mps


def test_calm_air_reaches_the_floor_and_an_outage_holds_the_estimate() -> None:
    # GIVEN residuals that are pitot noise only
    est = TurbulenceEstimator(CFG)
    feed(est, np.zeros(600), 0.3, seed=5)
    # THEN the gust sigma is the floor, far below the fixed default
    assert est.source == "estimated"
    assert est.sigma_mps == est.estimate_mps == CFG.gust_sigma_min_mps < CFG.gust_sigma_mps
    # AND nothing added (an outage) changes nothing
    assert est.sigma_mps == est.sigma_mps and est.count == 600


def test_the_prior_is_used_until_enough_residuals_and_when_not_adaptive() -> None:
    est = TurbulenceEstimator(CFG)
    feed(est, np.zeros(CFG.turbulence_min_residuals - 1), 0.3, seed=1)
    assert est.source == "default" and est.sigma_mps == CFG.gust_sigma_mps
    assert math.isnan(est.estimate_mps)
    fixed = TurbulenceEstimator(CFG.model_copy(update={"adaptive_turbulence": False}))
    feed(fixed, np.zeros(600), 0.3, seed=1)
    assert fixed.source == "default" and fixed.sigma_mps == CFG.gust_sigma_mps


def test_a_scatter_beyond_any_plausible_air_saturates_to_the_ceiling() -> None:
    est = TurbulenceEstimator(CFG)
    feed(est, gust_residuals(12.0, 300, seed=2), 0.3, seed=2)
    assert est.saturated and est.source == "saturated"
    assert est.sigma_mps == CFG.gust_sigma_max_mps
    # non-finite input is ignored
    n = est.count
    est.add(math.nan, 0.1)
    assert est.count == n


def test_the_position_error_slope_is_fitted_against_the_angle_of_attack() -> None:
    # GIVEN ratios TAS / |a| = 1.02 + 0.15 (alpha - 0.05) with 1 % gust noise, the angle of
    # attack moving by a few degrees (turns, climbs)
    rng = np.random.default_rng(4)
    fit = PositionErrorFit(CFG)
    alpha = 0.05 + 0.03 * np.sin(np.arange(900) / 40.0)
    for a in alpha:
        fit.add(float(a), 1.02 + 0.15 * (a - 0.05) + 0.01 * rng.standard_normal())
    # THEN the slope is recovered, and the correction removes it around the mean
    assert fit.coefficient_per_rad == pytest.approx(0.15, abs=0.03)
    assert fit.alpha_ref_rad == pytest.approx(0.05, abs=0.005)
    tas = 50.0 * (1.0 + 0.15 * (0.08 - fit.alpha_ref_rad))
    assert fit.correct(tas, 0.08) == pytest.approx(50.0, rel=2e-3)


def test_no_slope_from_gusts_that_move_the_angle_of_attack_and_the_ratio_apart() -> None:
    # GIVEN turbulence: the angle of attack moves by ~1.5 deg with vertical gusts and the ratio
    # by 3 % with horizontal ones, independent of each other (no position error)
    fit = PositionErrorFit(CFG)
    alpha = 0.05 + 0.025 * gust_residuals(1.0, 900, seed=8)
    ratio = 1.0 + 0.03 * gust_residuals(1.0, 900, seed=9)
    for a, r in zip(alpha, ratio, strict=True):
        fit.add(float(a), float(r))
    # THEN no slope is taken from them
    assert fit.coefficient_per_rad == 0.0


def test_no_slope_without_angle_of_attack_variation_and_a_bound_on_it() -> None:
    fit = PositionErrorFit(CFG)
    for _ in range(300):
        fit.add(0.05, 1.01)
    assert fit.coefficient_per_rad == 0.0 and fit.correct(50.0, 0.08) == 50.0
    steep = PositionErrorFit(CFG)
    for a in np.linspace(0.0, 0.1, 300):
        steep.add(float(a), 1.0 + 3.0 * a)
    assert steep.coefficient_per_rad == CFG.position_error_max_per_rad


def test_the_filter_learns_still_air_and_flags_an_implausible_pitot() -> None:
    # GIVEN 150 s of GNSS-aided flight at 30 m/s through a steady wind with a pitot whose
    # airspeed carries only 0.3 m/s of white noise (no turbulence); from 120 s the pitot
    # reads ten times the impact pressure (an airspeed ~65 m/s off the ground speed)
    from fusion.config import FilterConfig
    from fusion.filter import NavFilter
    from tests.helpers.nav_synth import (
        Flight,
        SensorErrors,
        airspeed_samples,
        make_scenario,
        merge,
        prepare,
    )

    cfg = FilterConfig(state_layout="ins16+air")
    prep = prepare(Flight(duration_s=150.0, speed_mps=30.0, wind_ne_mps=(5.0, -3.0),
                          turns=[(20.0, 35.0, 0.2)]))  # fmt: skip
    rng = np.random.default_rng(7)
    sc = make_scenario(prep, rng, SensorErrors.from_config(cfg))
    air = airspeed_samples(sc, (5.0, -3.0), rng, tas_noise_mps=0.3,
                           fault=lambda t, qc: qc if t < 120.0 else 10.0 * qc)
    nav = NavFilter(cfg)
    out = [e for s in merge(sc.samples, air) for e in nav.step(s)]
    before = min(out, key=lambda e: abs(e.time_us * 1e-6 - 119.0)).air_data
    last = out[-1].air_data
    # THEN the turbulence is estimated well below the fixed 1.5 m/s (the white noise batched
    # at 1 Hz is ~0.07 m/s: the floor) and was not flagged while the pitot was sound
    assert before is not None and before.turbulence_source == "estimated"
    assert before.turbulence_mps < 0.5 and before.flags == ""
    # AND the bad pitot is flagged, counted and never fused
    assert last is not None and "pitot_implausible" in last.flags
    assert nav.health.airspeed_implausible > 0
    assert nav.health.wind_implausible == 0


def _aiding(cfg: AirspeedTuning) -> AirspeedAiding:
    lay = layout_for("ins16+air")
    return AirspeedAiding(cfg, lay, HealthCounters(), lambda *_a: None,
                          lambda: np.zeros((lay.n, lay.n)), lambda *_a: None)  # fmt: skip


def test_still_air_slows_the_wind_walk_and_an_outage_holds_it_but_turbulence_does_not() -> None:
    # GIVEN a still-air walk of 0.01 with the climb part held, a pitot fused 0.5 s ago
    cfg = CFG.model_copy(update={"still_air_wind_noise_mps2_rthz": 0.01,
                                 "outage_climb_noise_factor": 0.0})  # fmt: skip
    air = _aiding(cfg)
    air.last_measured_fused_us = 10_000_000
    now = 10_500_000
    # WHEN the turbulence is still the prior (1.5 m/s: not yet known to be still air)
    # THEN the wind, its climb part and the scale walk as configured, GNSS or not
    assert air.noise_factors(True, now) == air.noise_factors(False, now) == (1.0, 1.0, 1.0)
    # WHEN the residuals show still air
    feed(air.turbulence, np.zeros(600), 0.3, seed=5)
    # THEN with GNSS the wind walks at the still-air noise (level and climb parts), the
    # scale as before; in an outage both are held
    still = 0.01 / cfg.wind_noise_mps2_rthz
    assert air.noise_factors(True, now) == pytest.approx((still, still, 1.0))
    assert air.noise_factors(False, now) == (0.0, 0.0, 0.0)
    # AND without a usable pitot (nothing fused for longer than the timeout) nothing changes
    assert air.noise_factors(False, now + 5_000_000) == (1.0, 1.0, 1.0)
    # AND the error model takes the factors: the climb part scales, the scale walk apart
    model = ErrorModel(layout_for("ins16+air"), ProcessNoise(
        gyro_noise=1e-4, accel_noise=1e-3, gyro_bias_sigma=1e-5, gyro_bias_tau_s=600.0,
        accel_bias_sigma=1e-3, accel_bias_tau_s=600.0, baro_bias_sigma=5.0,
        baro_bias_tau_s=1000.0))  # fmt: skip
    qw, qk = model.air_process_noise(1.0, -4.0, 0.2, 0.0, 0.5)
    assert qw == pytest.approx((0.05 * 0.2) ** 2) and qk == pytest.approx((0.5e-4) ** 2)


def test_straight_flight_starts_the_estimate_on_the_along_track_wind_alone() -> None:
    # GIVEN straight flight North at 45 m/s through a steady wind, with GNSS: the wind along
    # the air-relative track known to 0.3 m/s, across it only to 2.5 m/s (a weakly observed
    # heading: nothing but turns tells the crosswind from a heading error)
    from types import SimpleNamespace

    from fusion.strapdown import InsState
    from physconst.airdata import impact_pressure_pa
    from sim.samples import AirspeedSample

    lay = layout_for("ins16+air")
    P = np.zeros((lay.n, lay.n))
    w = lay.WIND
    ins = InsState(0.8, 0.2, 500.0, (45.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
    va = math.hypot(45.0 - 3.0, -2.0)
    accepted = SimpleNamespace(test_ratio=0.0)  # every update taken (the filter's part)

    def fly(along_sigma_mps: float, across_sigma_mps: float) -> AirspeedAiding:
        """A pitot read at 20 Hz for the residuals the estimate needs and 50 s more, with the
        wind (3, 2) m/s started and known to these sigmas North (along) and East (across)."""
        P[w, w], P[w + 1, w + 1] = along_sigma_mps**2, across_sigma_mps**2
        air = AirspeedAiding(CFG, lay, HealthCounters(), lambda *_a: accepted, lambda: P,
                             lambda *_a: None)  # fmt: skip
        air.state.active = True
        air.state.start((3.0, 2.0))
        # the pitot's own noise on the airspeed the mean wind predicts
        rng = np.random.default_rng(3)
        noise_mps = air._sensor_sigma(va, 101_325.0, 288.15)
        for k in range(20 * (CFG.turbulence_min_residuals + 50)):
            now = 1_000_000 + k * 50_000
            tas = va + noise_mps * float(rng.standard_normal())
            air.add_sample(AirspeedSample(now, impact_pressure_pa(tas, 101_325.0, 288.15),
                                          288.15), now)
            air.tick(now, ins, lambda _t: ins, 101_325.0, 288.15, True)
        return air

    # WHEN the pitot's residuals come in
    air = fly(0.3, 2.5)
    # THEN the estimate starts (still air: at its floor), since the crosswind enters the
    # airspeed only to second order
    assert air.turbulence.source == "estimated"
    assert air.turbulence.sigma_mps == pytest.approx(CFG.gust_sigma_min_mps)
    # AND a wind unknown along the track keeps it waiting
    waiting = fly(2.5, 0.3)
    assert waiting.turbulence.count == 0 and waiting.turbulence.source == "default"


def test_the_wind_waits_for_the_heading_but_not_for_ever() -> None:
    # GIVEN a pitot read at 20 Hz on a straight leg at 40 m/s with GNSS, and a heading known
    # only to 10 deg (no magnetometer, no turn), then to 2 deg
    from types import SimpleNamespace

    from fusion.strapdown import InsState
    from physconst.airdata import impact_pressure_pa
    from sim.samples import AirspeedSample

    lay = layout_for("ins16+air")
    P = np.zeros((lay.n, lay.n))
    P[lay.ATT + 2, lay.ATT + 2] = math.radians(10.0) ** 2
    started: list[int] = []
    accepted = SimpleNamespace(test_ratio=0.0)  # every update taken (the filter's part)
    air = AirspeedAiding(CFG, lay, HealthCounters(), lambda *_a: accepted, lambda: P,
                         lambda *_a: started.append(now))  # fmt: skip
    ins = InsState(0.8, 0.2, 500.0, (40.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
    qc = impact_pressure_pa(40.0, 95_000.0, 283.0)

    def fly(t0_s: float, t1_s: float) -> None:
        nonlocal now
        for k in range(round(t0_s * 20), round(t1_s * 20)):
            now = k * 50_000
            air.add_sample(AirspeedSample(now, qc, 283.0), now)
            air.tick(now, ins, lambda _t: ins, 95_000.0, 283.0, True)

    now = 0
    # WHEN it flies for less than the longest wait
    fly(0.0, CFG.wind_start_max_wait_s - 5.0)
    # THEN the wind has not started (a wind computed against that heading would be wrong by
    # 7 m/s across track with no correlation to the heading)
    assert not started and air.status(now).state == "waiting"
    # AND once the wait is over it starts all the same: air data for a heading that stays
    # unknown, right on the course flown
    fly(CFG.wind_start_max_wait_s - 5.0, CFG.wind_start_max_wait_s + 5.0)
    assert len(started) == 1
    assert CFG.wind_start_max_wait_s * 1e6 <= started[0] < (CFG.wind_start_max_wait_s + 2.0) * 1e6
    # AND a heading known to 2 deg starts it at the first airspeed
    P[lay.ATT + 2, lay.ATT + 2] = math.radians(2.0) ** 2
    started.clear()
    accepted = SimpleNamespace(test_ratio=0.0)  # every update taken (the filter's part)
    air = AirspeedAiding(CFG, lay, HealthCounters(), lambda *_a: accepted, lambda: P,
                         lambda *_a: started.append(now))  # fmt: skip
    fly(100.0, 103.0)
    assert len(started) == 1 and started[0] < 101_100_000
