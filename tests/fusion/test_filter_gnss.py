"""fusion.filter.NavFilter: GNSS fusion (gating, latency, lever arm, outages, resets, the GNSS
bias states) on synthetic flights."""

from __future__ import annotations

import dataclasses
import math
import typing

import numpy as np
import pytest

from fusion import earth
from fusion.config import (
    FilterConfig,
    GnssTuning,
)
from fusion.filter import NavFilter
from sim.samples import GnssFix, ImuSample
from tests.fusion.filter_scenarios import CFG, ERRORS, errors_at, run, with_gm_gnss_error
from tests.helpers.nav_synth import (
    Prepared,
    Scenario,
    make_scenario,
)


# --------------------------------------------------------------------------- GNSS
def test_a_5_sigma_gnss_jump_is_rejected_where_it_appears(racetrack: Prepared) -> None:
    # GIVEN a fix at t = 30 s displaced 5 sigma (7.5 m) north of the truth
    sc = make_scenario(
        racetrack, np.random.default_rng(6), ERRORS, gnss_glitches={149: np.array([7.5, 0, 0])}
    )
    nav = NavFilter(CFG)
    glitch = next(s for s in sc.samples if isinstance(s, GnssFix) and s.time_us == 30_000_000)
    before = None
    for s in sc.samples:
        if s is glitch:
            before = nav.health
        nav.step(s)
        if s is glitch:
            break
    assert before is not None
    # WHEN it is processed
    after = nav.health
    est = nav.estimate()
    assert est is not None
    # THEN it is rejected in that very update, with a position test ratio > 1
    assert est.test_ratios.gnss_pos > 1.0
    assert after.gnss_rejected == before.gnss_rejected + 1
    assert np.linalg.norm(errors_at(sc, est)[0]) < 1.5
    # AND the next fixes are fused again
    rest = run(nav, sc.samples[sc.samples.index(glitch) + 1 :])
    assert rest[-1].test_ratios.gnss_pos < 1.0
    assert nav.health.gnss_resets == 0


def test_gnss_latency_is_compensated(racetrack: Prepared) -> None:
    # GIVEN fixes delivered 200 ms after their time of validity (8 m of travel at 40 m/s)
    sc = make_scenario(racetrack, np.random.default_rng(7), ERRORS, gnss_latency_s=0.2)
    nav = NavFilter(CFG)
    # WHEN the filter fuses them against its buffered past states
    est = run(nav, sc.samples)
    # THEN the position has no along-track lag
    pos = np.array([errors_at(sc, e)[0] for e in est if e.time_us > 10_000_000])
    assert np.sqrt(np.mean(np.sum(pos[:, :2] ** 2, axis=1))) < 1.0
    assert nav.health.gnss_too_old == 0 and nav.health.gnss_fused > 200


def test_lever_arm(racetrack: Prepared) -> None:
    arm = (0.5, 0.3, -0.8)
    sc = make_scenario(racetrack, np.random.default_rng(8), ERRORS, lever_arm_b_m=arm)
    nav = NavFilter(CFG.model_copy(update={"gnss": GnssTuning(lever_arm_b_m=arm)}))
    est = run(nav, sc.samples)
    pos = np.array([errors_at(sc, e)[0] for e in est if e.time_us > 26_000_000])
    assert np.abs(pos).max() < 1.5
    assert nav.health.gnss_rejected < 10


def test_outage_free_inertial_and_reacquisition(racetrack: Prepared) -> None:
    # GIVEN no GNSS between 20 and 35 s
    sc = make_scenario(racetrack, np.random.default_rng(9), ERRORS, gnss_outages=[(20.0, 35.0)])
    nav = NavFilter(CFG)
    est = run(nav, sc.samples)
    modes = {round(e.time_us * 1e-6, 2): e.mode for e in est}
    # THEN gnss until 1 s after the last fix, free-inertial during, gnss again after 3 good fixes
    assert modes[20.5] == "gnss"
    assert modes[21.0] == "free-inertial" and modes[34.0] == "free-inertial"
    assert modes[35.2] == "free-inertial" and modes[35.5] == "gnss"
    assert nav.health.gnss_outages == 1
    mid = next(e for e in est if e.time_us == 30_000_000)
    assert mid.time_since_gnss_s == pytest.approx(10.2, abs=0.05)
    before = next(e for e in est if e.time_us == 19_000_000)
    assert mid.P_diag[0] > 4.0 * before.P_diag[0]  # sigma at least doubled during the outage
    assert np.linalg.norm(errors_at(sc, mid)[0]) < 30.0
    assert np.linalg.norm(errors_at(sc, est[-1])[0]) < 2.0


def test_reset_to_gnss_when_the_ins_drifted_beyond_the_gate(racetrack: Prepared) -> None:
    # GIVEN an outage after which the GNSS solution is 60 m away (e.g. a new datum)
    jump = {k: np.array([60.0, -40.0, 0.0]) for k in range(150, 225)}
    sc = make_scenario(
        racetrack,
        np.random.default_rng(10),
        ERRORS,
        gnss_outages=[(20.0, 30.0)],
        gnss_glitches=jump,
    )
    nav = NavFilter(CFG)
    est = run(nav, sc.samples)
    # THEN the first re-acquired fix resets the position instead of being rejected forever
    assert nav.health.gnss_resets >= 1
    assert est[-1].mode == "gnss"
    pos = errors_at(sc, est[-1])[0]
    np.testing.assert_allclose(pos[:2], [60.0, -40.0], atol=3.0)


def test_gnss_bias_relaxes_to_its_prior_in_an_outage_and_is_reset_with_the_position(
    racetrack: Prepared,
) -> None:
    # GIVEN the GNSS bias states (tau 3 s), correlated GNSS error, an outage from 20 to 30 s
    # and, after it, a GNSS solution 60 m away (the INS is then reset to GNSS)
    tau, sb_h, sb_v = 3.0, 1.4, 2.4
    cfg = FilterConfig(gnss=GnssTuning(bias_sigma_h_m=sb_h, bias_sigma_v_m=sb_v,
                                       bias_tau_h_s=tau, bias_tau_v_s=tau),
                       state_layout="ins16+gnss")
    jump = {k: np.array([60.0, -40.0, 0.0]) for k in range(150, 225)}
    sc = make_scenario(racetrack, np.random.default_rng(10), ERRORS, gnss_sigma_h_m=0.5,
                       gnss_sigma_v_m=0.8, gnss_outages=[(20.0, 30.0)], gnss_glitches=jump)
    sc, _ = with_gm_gnss_error(sc, np.random.default_rng(11), sb_h, sb_v, tau,
                               np.array([1.0, -1.0, 2.0]))  # fmt: skip
    nav = NavFilter(cfg)
    lay = nav.layout
    g = lay.gnss
    assert g is not None and lay.name == "ins16+gnss"
    sb2 = np.array([sb_h**2, sb_h**2, sb_v**2])
    at_outage: tuple[int, np.ndarray] | None = None
    late_outage: tuple[int, np.ndarray, np.ndarray] | None = None
    after_reset: tuple[np.ndarray, np.ndarray] | None = None
    for smp in sc.samples:
        nav.step(smp)
        if not isinstance(smp, ImuSample):
            if after_reset is None and nav.health.gnss_resets == 1:
                gb = nav.gnss_bias_ned_m
                assert gb is not None
                after_reset = (np.array(gb), nav.covariance)
            continue
        if at_outage is None and smp.time_us >= 19_900_000:
            at_outage = (smp.time_us, np.array(nav.gnss_bias_ned_m))
        if late_outage is None and smp.time_us >= 29_900_000:
            late_outage = (smp.time_us, np.array(nav.gnss_bias_ned_m), nav.covariance)
    assert at_outage is not None and late_outage is not None and after_reset is not None
    # WHEN GNSS is lost THEN the bias estimate decays like the Gauss-Markov mean (the baro
    # updates move it a little through its correlations) and its covariance returns to the prior
    t1, b1 = at_outage
    t2, b2, cov2 = late_outage
    assert np.linalg.norm(b1[:2]) > 0.3  # there was something to forget
    np.testing.assert_allclose(b2[:2], b1[:2] * math.exp(-(t2 - t1) * 1e-6 / tau), atol=0.02)
    np.testing.assert_allclose(np.diag(cov2)[g], sb2, rtol=0.03)
    # WHEN the re-acquired fixes are rejected and the position is reset to GNSS, THEN the bias
    # goes back to its prior: estimate zero, sigma_b, position error = -bias error + white noise
    b3, cov3 = after_reset
    assert nav.health.gnss_resets >= 1
    np.testing.assert_allclose(b3, 0.0, atol=1e-9)
    np.testing.assert_allclose(np.diag(cov3)[g], sb2, rtol=0.02)
    np.testing.assert_allclose(np.diag(cov3[lay.pos, g]), -sb2, rtol=0.02)
    assert np.all(np.diag(cov3)[lay.pos] > sb2)



def _fixes_from(sc: Scenario, start_us: int, change: typing.Callable[[GnssFix], GnssFix]
                ) -> list[object]:
    return [change(s) if isinstance(s, GnssFix) and s.time_us >= start_us else s
            for s in sc.samples]


def test_implausible_fixes_are_invalid_never_fused_or_reset_to(racetrack: Prepared) -> None:
    # GIVEN fixes with a longitude beyond +-180 deg, an altitude of 2,147 km, or 700 m/s,
    # from 20 s on (each in its own run)
    sc = make_scenario(racetrack, np.random.default_rng(41), ERRORS)
    changes = {
        "longitude": lambda f: dataclasses.replace(f, lon_rad=math.radians(-214.7)),
        "altitude": lambda f: dataclasses.replace(f, alt_msl_m=2_147_000.0),
        "speed": lambda f: dataclasses.replace(f, v_ned_mps=np.array([700.0, 0.0, 0.0])),
    }
    for name, change in changes.items():
        nav = NavFilter(CFG)
        est = run(nav, _fixes_from(sc, 20_000_000, change))
        # THEN every one of them is invalid: no update, no reset, the INS coasts
        h = nav.health
        assert h.gnss_invalid >= 5 * 24 and h.gnss_resets == 0, name
        assert est[-1].mode != "gnss", name
        assert np.linalg.norm(errors_at(sc, est[-1])[0]) < 30.0, name


def test_resets_are_bounded_by_what_the_ins_knows(racetrack: Prepared) -> None:
    sc = make_scenario(racetrack, np.random.default_rng(42), ERRORS)
    # GIVEN fixes jumping 1 km north with eph 1 m from 20 s on (consistent among themselves)
    def jump(f: GnssFix) -> GnssFix:
        rho = earth.local_terms(f.lat_rad, f.alt_msl_m).rho_n_m
        return dataclasses.replace(f, lat_rad=f.lat_rad + 1000.0 / rho, eph_m=1.0)

    nav = NavFilter(CFG)
    est = run(nav, _fixes_from(sc, 20_000_000, jump))
    # THEN the filter never resets to them while its own sigma contradicts the jump
    h = nav.health
    assert h.gnss_resets == 0 and h.gnss_resets_refused > 0
    assert np.linalg.norm(errors_at(sc, est[-1])[0]) < 30.0
    # GIVEN instead fixes reporting 327 m/s while their positions move with the aircraft
    def fast(f: GnssFix) -> GnssFix:
        return dataclasses.replace(f, v_ned_mps=np.array([327.0, 0.0, 0.0]))

    nav = NavFilter(CFG)
    est = run(nav, _fixes_from(sc, 20_000_000, fast))
    # THEN no velocity reset: the fixes contradict themselves (position vs velocity)
    assert nav.health.gnss_resets == 0 and nav.health.gnss_resets_refused > 0
    assert np.linalg.norm(errors_at(sc, est[-1])[1]) < 2.0
