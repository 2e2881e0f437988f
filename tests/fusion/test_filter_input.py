"""fusion.filter.NavFilter: bad input is counted, never integrated (samples, stamps, restarts,
unknown sample types)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fusion.filter import NavFilter
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample
from tests.fusion.filter_scenarios import CFG, ERRORS, errors_at, run
from tests.helpers.nav_synth import (
    Prepared,
    make_scenario,
)


# --------------------------------------------------------------------------- bad input
def test_bad_input_is_counted_never_integrated(racetrack: Prepared) -> None:
    sc = make_scenario(racetrack, np.random.default_rng(11), ERRORS, mag_rate_hz=5.0)
    samples: list[object] = []
    nan3 = np.array([math.nan, 0.0, 0.0])
    for s in sc.samples:
        if isinstance(s, ImuSample) and 6_000_000 <= s.time_us < 7_500_000:
            continue  # a 1.5 s hole in straight flight: time jump
        samples.append(s)
        if isinstance(s, ImuSample):
            if s.time_us == 10_000_000:
                samples.append(s)  # duplicate
            if s.time_us == 11_000_000:
                samples.append(dataclasses.replace(s, time_us=s.time_us - 30_000))  # backwards
            if s.time_us in (12_000_000, 12_010_000):
                samples[-1] = dataclasses.replace(s, specific_force_b_mps2=nan3)
            if s.time_us == 13_000_000:
                samples[-1] = dataclasses.replace(s, angular_rate_b_rps=np.array([0.0, 1e3, 0.0]))
            if s.time_us == 14_000_000:
                samples[-1] = dataclasses.replace(s, dt_s=math.inf)
        if isinstance(s, GnssFix) and s.time_us == 16_000_000:
            samples[-1] = dataclasses.replace(s, fix_type=2)
        if isinstance(s, GnssFix) and s.time_us == 17_000_000:
            samples[-1] = dataclasses.replace(s, lat_rad=math.nan)
        if isinstance(s, BaroSample) and s.time_us == 18_000_000:
            samples[-1] = dataclasses.replace(s, pressure_pa=math.nan)
        if isinstance(s, BaroSample) and s.time_us == 18_040_000:
            samples[-1] = dataclasses.replace(s, time_us=math.nan)  # type: ignore[arg-type]
        if isinstance(s, GnssFix) and s.time_us == 20_000_000:
            samples[-1] = dataclasses.replace(s, time_us=s.time_us + 3_600_000_000)  # +1 h
        if isinstance(s, MagSample) and s.time_us == 19_000_000:
            samples[-1] = dataclasses.replace(s, field_b_tesla=np.array([math.inf, 0.0, 0.0]))
    nav = NavFilter(CFG)
    est = run(nav, samples)
    h = nav.health
    assert h.imu_nan == 3 and h.imu_out_of_range == 1
    assert h.duplicates == 1 and h.time_backwards == 1 and h.time_jump == 2
    assert h.gnss_no_fix == 1 and h.gnss_invalid == 1
    assert h.baro_invalid == 2 and h.mag_invalid == 1
    # the first samples after the hole are quarantined until they confirm the new time: the
    # confirming one is integrated (coasting the gap), the ones before it are lost
    confirm = CFG.imu.time_base_confirm_samples
    assert h.time_quarantined == confirm and h.time_rebases == 0
    assert h.imu_ok == len([s for s in samples if isinstance(s, ImuSample)]) - 6 - (confirm - 1)
    for e in est:
        assert np.all(np.isfinite(e.v_ned_mps)) and np.all(np.isfinite(e.P_diag))
    # the held samples and the coasted gap did not spoil the solution
    assert max(np.linalg.norm(errors_at(sc, e)[0]) for e in est if e.time_us > 3_000_000) < 5.0
    assert h.gnss_resets == 0
    # the fix stamped an hour ahead did not block the GNSS stream
    assert est[-1].mode == "gnss" and h.gnss_fused > 180


def test_health_counters_cover_every_field() -> None:
    from fusion.estimate import HEALTH_FIELDS, HealthCounters

    assert set(HealthCounters.__annotations__) == set(HEALTH_FIELDS)
    assert NavFilter().health == type(NavFilter().health)()


def test_unknown_sample_type_raises_and_nothing_before_alignment() -> None:
    nav = NavFilter()
    assert nav.estimate() is None and nav.mode == "initializing"
    with pytest.raises(TypeError, match="not an IMU"):
        nav.step(object())  # type: ignore[arg-type]
    assert nav.step(ImuSample(1000, 0.01, np.zeros(3), np.zeros(3))) == []



def test_one_far_future_or_overflowing_imu_stamp_does_not_stop_the_filter(
    racetrack: Prepared,
) -> None:
    # GIVEN the racetrack with one IMU sample stamped an hour ahead and one at 2^64 - 1
    sc = make_scenario(racetrack, np.random.default_rng(31), ERRORS)
    hostile: list[object] = []
    for s in sc.samples:
        hostile.append(s)
        if isinstance(s, ImuSample) and s.time_us in (15_000_000, 30_000_000):
            later = s.time_us + 3_600_000_000 if s.time_us == 15_000_000 else 2**64 - 1
            hostile.append(dataclasses.replace(s, time_us=later))
    clean_nav, nav = NavFilter(CFG), NavFilter(CFG)
    clean, est = run(clean_nav, sc.samples), run(nav, hostile)
    # THEN both were quarantined, the clock never moved, and the run is the clean run's
    h = nav.health
    assert h.time_quarantined == 2 and h.time_rebases == 0 and h.time_jump == 0
    assert len(est) == len(clean) and est[-1].time_us == clean[-1].time_us
    for e, c in zip(est, clean, strict=True):
        assert e.time_us == c.time_us and np.all(np.isfinite(e.P_diag))
        np.testing.assert_array_equal(e.v_ned_mps, c.v_ned_mps)


def test_a_simulator_restart_re_initialises_the_filter_cleanly(racetrack: Prepared) -> None:
    # GIVEN a flight, then the simulator restarted: the same kind of flight from time 0 again
    first = make_scenario(racetrack, np.random.default_rng(32), ERRORS)
    second = make_scenario(racetrack, np.random.default_rng(33), ERRORS)
    nav = NavFilter(CFG)
    run(nav, first.samples)
    # WHEN the second flight's samples follow the first's (time steps back 45 s)
    est = run(nav, second.samples)
    # THEN the filter re-initialised once, realigned and navigates the second flight
    h = nav.health
    assert h.time_rebases == 1
    assert h.time_backwards >= CFG.imu.time_base_confirm_samples  # the run that confirmed it
    late = [e for e in est if e.time_us > 20_000_000]
    assert late and all(e.mode == "gnss" for e in late)
    assert max(np.linalg.norm(errors_at(second, e)[0]) for e in late) < 5.0
