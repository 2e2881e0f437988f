"""Scorecard metrics against hand-made trajectories with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth
from hil.tracks import Fixes, HealthSeries, Track
from scenarios import event_metrics, metrics
from scenarios.metrics import Window


def _track(t: np.ndarray, north_m: np.ndarray, east_m: np.ndarray, down_m: np.ndarray,
           sigma: np.ndarray | None = None) -> Track:
    lat0, lon0, h0 = math.radians(47.0), math.radians(8.0), 1000.0
    r_n, r_e = earth.principal_radii(lat0)
    lat = lat0 + north_m / (float(r_n) + h0)
    lon = lon0 + east_m / ((float(r_e) + h0) * math.cos(lat0))
    n = t.size
    return Track(t, lat, lon, h0 - down_m, np.zeros((n, 3)), np.zeros((n, 3)), sigma)


def test_constant_offset_gives_exact_horizontal_and_vertical_errors() -> None:
    t = np.arange(0.0, 100.0, 0.5)
    zero = np.zeros_like(t)
    truth = _track(t, zero, zero, zero)
    est = _track(t, zero + 3.0, zero + 4.0, zero - 2.0)
    err = metrics.errors(est, truth)
    np.testing.assert_allclose(err.horizontal_m, 5.0, rtol=1e-6)
    np.testing.assert_allclose(err.pos_ned_m[:, 2], -2.0, atol=1e-6)
    rm = metrics.component_rmse(err)
    assert rm["horizontal_m"] == pytest.approx(5.0, rel=1e-6)
    assert rm["h_m"] == pytest.approx(2.0, rel=1e-6)
    # 3 m of latitude at 47 deg N is 3 / (R_M + h) rad
    r_m = float(earth.principal_radii(math.radians(47.0))[0])
    assert rm["lat_deg"] == pytest.approx(math.degrees(3.0 / (r_m + 1000.0)), rel=1e-6)


def test_outage_metrics_linear_drift() -> None:
    """Error growing 1 m/s inside a 60 s outage: RMSE, max, error-at and CEP are analytic."""
    t = np.arange(0.0, 200.0, 0.1)
    zero = np.zeros_like(t)
    drift = np.where((t >= 50.0) & (t < 110.0), t - 50.0, 0.0)
    err = metrics.errors(_track(t, drift, zero, zero), _track(t, zero, zero, zero))
    om = metrics.outage_metrics(err, Window(50.0, 110.0))
    assert om is not None
    assert om.horizontal_error_m_at["10"] == pytest.approx(10.0, abs=1e-3)
    assert om.horizontal_error_m_at["30"] == pytest.approx(30.0, abs=1e-3)
    assert om.horizontal_error_m_at["60"] is None  # 110 s itself is outside [50, 110)
    assert om.horizontal_error_m_at["120"] is None
    assert om.horizontal_max_m == pytest.approx(59.9, abs=1e-3)
    assert om.horizontal_rmse_m == pytest.approx(60.0 / math.sqrt(3.0), rel=0.01)
    assert om.cep50_m == pytest.approx(30.0, abs=0.1)
    assert om.cep95_m == pytest.approx(57.0, abs=0.1)


def test_outages_from_fix_gaps() -> None:
    fixes = np.r_[np.arange(0.0, 50.0, 0.2), np.arange(75.0, 100.0, 0.2)]
    w = metrics.outages_from_fix_times(fixes, end_s=130.0)
    assert len(w) == 2
    assert w[0].start_s == pytest.approx(49.8) and w[0].end_s == pytest.approx(75.0)
    assert w[1].start_s == pytest.approx(99.8) and w[1].end_s == 130.0
    assert metrics.outages_from_fix_times(np.arange(0.0, 10.0, 0.2), end_s=10.0) == []


def test_consistency_of_matching_sigma() -> None:
    """Gaussian errors drawn with the reported sigma: NEES ~ 9, rms(e/sigma) ~ 1."""
    rng = np.random.default_rng(3)
    n = 20000
    t: np.ndarray = np.arange(n) * 0.1
    sig = np.tile([2.0, 2.0, 3.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.02], (n, 1))
    e = rng.normal(size=(n, 9)) * sig
    err = metrics.Errors(t, e[:, 0:3], e[:, 3:6], e[:, 6:9], e[:, 0] * 0, e[:, 0] * 0, sig)
    c = metrics.consistency(err)
    assert c["nees_mean"] == pytest.approx(9.0, rel=0.03)
    for g in ("pos", "vel", "att"):
        assert c[f"rms_z_{g}"] == pytest.approx(1.0, rel=0.03)
        assert c[f"within_3sigma_{g}"] > 0.98


def test_nees_uses_the_full_covariance() -> None:
    """Correlated Gaussian errors drawn from the reported 9x9 covariance give NEES 9 with the
    full covariance; errors that break the reported correlation (velocity sign flipped) are
    caught by it, while the diagonal approximation cannot tell the two apart."""
    rng = np.random.default_rng(4)
    n = 20000
    t = np.arange(n) * 0.1
    a = rng.normal(size=(9, 9)) * np.r_[2.0, 2.0, 3.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.02][:, None]
    cov = a @ a.T
    e = rng.multivariate_normal(np.zeros(9), cov, size=n)
    sig = np.tile(np.sqrt(np.diag(cov)), (n, 1))
    covs = np.broadcast_to(cov, (n, 9, 9))
    z0 = np.zeros(n)

    def errs(v: np.ndarray, full: bool) -> metrics.Errors:
        return metrics.Errors(t, e[:, 0:3], v, e[:, 6:9], z0, z0, sig, e[:, 6:9],
                              covs if full else None)

    # chi-square(9): mean 9, standard error sqrt(18 / n)
    tol = 5.0 * math.sqrt(18.0 / n)
    assert metrics.consistency(errs(e[:, 3:6], True))["nees_mean"] == pytest.approx(9.0, abs=tol)
    assert metrics.consistency(errs(-e[:, 3:6], True))["nees_mean"] > 9.0 + 20 * tol
    diag_same = metrics.consistency(errs(e[:, 3:6], False))["nees_mean"]
    assert metrics.consistency(errs(-e[:, 3:6], False))["nees_mean"] == pytest.approx(diag_same)


def test_attitude_error_is_the_filter_tilt_and_euler_sigma_maps_it() -> None:
    """A known small rotation about North applied to a truth heading 90 deg (East): the tilt
    error is that rotation (about North), which is a pitch error for an aircraft heading East;
    the Euler-mapped sigma follows."""
    from fusion import rotations

    t = np.arange(0.0, 10.0, 1.0)
    n = t.size
    zero = np.zeros(n)
    base = _track(t, zero, zero, zero)
    euler_true = np.tile([0.0, 0.1, math.pi / 2], (n, 1))
    phi = np.array([2e-3, 0.0, 0.0])  # about North
    c_est = rotations.rotvec_to_dcm(phi) @ rotations.euler_to_dcm(euler_true)
    euler_est = rotations.dcm_to_euler(c_est)
    sig = np.tile([1.0] * 6 + [1e-3, 4e-3, 9e-3], (n, 1))
    truth = Track(base.time_s, base.lat_rad, base.lon_rad, base.alt_m, base.v_ned_mps, euler_true)
    est = Track(base.time_s, base.lat_rad, base.lon_rad, base.alt_m, base.v_ned_mps, euler_est,
                sig)
    err = metrics.errors(est, truth)
    assert err.tilt_rad is not None and err.att_sigma_rad is not None
    np.testing.assert_allclose(err.tilt_rad, np.tile(phi, (n, 1)), atol=1e-9)
    # heading East, small pitch: a rotation about North is minus a pitch change
    assert err.att_rad[0, 1] == pytest.approx(-2e-3, rel=1e-2)
    assert abs(err.att_rad[0, 0]) < 1e-5 and abs(err.att_rad[0, 2]) < 1e-5  # second order
    # heading East: pitch error = -tilt North, roll error = tilt East / cos(pitch),
    # yaw error = tilt Down + tan(pitch) tilt East (the map is taken at the estimate's
    # attitude, 2 mrad of pitch from the truth's: 1e-3 relative)
    assert err.att_sigma_rad[0, 1] == pytest.approx(1e-3, rel=1e-9)
    assert err.att_sigma_rad[0, 0] == pytest.approx(4e-3 / math.cos(0.1), rel=1e-3)
    assert err.att_sigma_rad[0, 2] == pytest.approx(math.hypot(9e-3, 4e-3 * math.tan(0.1)),
                                                    rel=1e-3)
    assert metrics.consistency(err)["rms_z_att"] == pytest.approx(2.0 / math.sqrt(3.0), rel=1e-6)


def test_gnss_on_mask_excludes_settling_and_outages() -> None:
    t = np.arange(0.0, 300.0, 1.0)
    m = metrics.gnss_on_mask(t, [Window(100.0, 130.0)], settle_s=20.0)
    assert not m[t < 20].any()
    assert not m[(t >= 100) & (t < 150)].any()
    assert m[(t >= 20) & (t < 100)].all() and m[t >= 150].all()


# ------------------------------------------------------------------ containment, drift, settle


def _errors(t: np.ndarray, pos: np.ndarray, sigma: np.ndarray | None = None) -> metrics.Errors:
    n = t.size
    z = np.zeros(n)
    return metrics.Errors(t, pos, np.zeros((n, 3)), np.zeros((n, 3)), z, z, sigma)


def _sigma(n: int, s_pos: tuple[float, float, float]) -> np.ndarray:
    return np.tile([*s_pos, 0.1, 0.1, 0.1, 0.01, 0.01, 0.01], (n, 1))


def test_containment_counts_the_99_73_percent_ellipse() -> None:
    """GIVEN sigma (1, 2, 1) m and errors placed inside or outside the bounds by hand
    THEN the fractions are exact; (3 sN, 1 sE) is inside the 2-D bound (9 + 1 < 11.83),
    (3 sN, 2 sE) is not (13 > 11.83); the vertical bound is |e_D| <= 3 sD."""
    t = np.arange(4.0)
    pos = np.array([[3.0, 2.0, 2.9], [3.0, 4.0, 3.1], [0.0, 0.0, 0.0], [-3.0, -2.0, -3.5]])
    c = metrics.containment_3sigma(_errors(t, pos, _sigma(4, (1.0, 2.0, 1.0))))
    assert c == {"horizontal": 0.75, "vertical": 0.5}
    m = np.array([False, True, True, False])
    assert metrics.containment_3sigma(_errors(t, pos, _sigma(4, (1.0, 2.0, 1.0))), m) == {
        "horizontal": 0.5, "vertical": 0.5}
    nan = metrics.containment_3sigma(_errors(t, pos))
    assert math.isnan(nan["horizontal"]) and math.isnan(nan["vertical"])


def test_containment_of_a_consistent_filter_is_99_73_percent() -> None:
    rng = np.random.default_rng(11)
    n = 400_000
    sig = _sigma(n, (2.0, 5.0, 3.0))
    err = _errors(np.arange(n) * 0.02, rng.normal(size=(n, 3)) * sig[:, :3], sig)
    c = metrics.containment_3sigma(err)
    assert c["horizontal"] == pytest.approx(metrics.P_3SIGMA, abs=5e-4)
    assert c["vertical"] == pytest.approx(metrics.P_3SIGMA, abs=5e-4)
    # the plotted radius is exact for equal sigmas: sqrt(11.83) * 2 m
    r = metrics.horizontal_bound_3sigma(_sigma(1, (2.0, 2.0, 1.0)))
    assert r[0] == pytest.approx(2.0 * math.sqrt(metrics.CHI2_2DOF_3SIGMA))


def test_outage_metrics_new_fields() -> None:
    """Linear drift 1 m/s north, height error 0.5 m/s down, sigma 1 m: vertical error-at,
    containment (inside while the error < 3.44 m horizontally / 3 m vertically), drift curve."""
    t = np.arange(0.0, 200.0, 0.1)
    zero = np.zeros_like(t)
    inside = (t >= 50.0) & (t < 110.0)
    drift = np.where(inside, t - 50.0, 0.0)
    sig = _sigma(t.size, (1.0, 1.0, 1.0))
    err = metrics.errors(_track(t, drift, zero, 0.5 * drift, sig), _track(t, zero, zero, zero))
    om = metrics.outage_metrics(err, Window(50.0, 110.0), drift_step_s=5.0)
    assert om is not None
    assert om.vertical_error_m_at["10"] == pytest.approx(5.0, abs=1e-3)
    assert om.vertical_error_m_at["30"] == pytest.approx(15.0, abs=1e-3)
    assert om.vertical_error_m_at["60"] is None
    assert om.vertical_max_m == pytest.approx(29.95, abs=1e-3)
    # horizontal inside while tau <= sqrt(11.83) = 3.439 s -> 35 of 600 samples
    assert om.containment_3sigma["horizontal"] == pytest.approx(35 / 600)
    # vertical inside while 0.5 tau <= 3 -> tau <= 6 s -> 61 of 600 samples
    assert om.containment_3sigma["vertical"] == pytest.approx(61 / 600)
    np.testing.assert_allclose(om.drift_m, np.arange(0.0, 60.0, 5.0), atol=1e-3)
    d = om.as_dict()
    for key in ("cep50_m", "cep95_m", "containment_3sigma", "reconverge_s", "drift",
                "vertical_error_m_at", "nees_mean"):
        assert key in d


def test_mean_drift_curve_over_outages_of_different_length() -> None:
    tau1 = np.arange(0.0, 60.01, 0.1)
    tau2 = np.arange(0.0, 30.01, 0.1)
    grid, mean, count = metrics.mean_drift_curve([(tau1, 1.0 * tau1), (tau2, 3.0 * tau2)])
    assert grid[-1] == pytest.approx(60.0) and grid[1] == pytest.approx(1.0)
    assert mean[10] == pytest.approx(20.0)  # (10 + 30) / 2
    assert mean[45] == pytest.approx(45.0)  # only the long outage reaches 45 s
    assert count[10] == 2 and count[45] == 1
    g, m, c = metrics.mean_drift_curve([])
    assert g.size == m.size == c.size == 0


def _h_errors(t: np.ndarray, h: np.ndarray) -> metrics.Errors:
    return _errors(t, np.column_stack([h, np.zeros_like(h), np.zeros_like(h)]))


def test_reconverge_time_waits_for_the_hold() -> None:
    """GIVEN GNSS back at 100 s with a 50 m error decaying 5 m/s, and a spike above 5 m at
    115 s WHEN the threshold is 5 m held 10 s THEN the first run (109-115 s) is too short and
    re-convergence is at 115.1 s."""
    t = np.round(np.arange(0.0, 200.0, 0.1), 6)
    h = np.where(t < 100.0, 1.0, np.maximum(50.0 - 5.0 * (t - 100.0), 1.0))
    h[np.isclose(t, 115.0)] = 8.0
    err = _h_errors(t, h)
    r = metrics.reconverge_time(err, 100.0, threshold_m=5.0, hold_s=10.0)
    assert r == pytest.approx(15.1, abs=1e-9)
    # without the spike the error is below 5 m from just after 109 s
    h2 = np.where(t < 100.0, 1.0, np.maximum(50.0 - 5.0 * (t - 100.0), 1.0))
    assert metrics.reconverge_time(_h_errors(t, h2), 100.0, threshold_m=5.0,
                                   hold_s=10.0) == pytest.approx(9.1, abs=1e-9)
    # already converged when GNSS returns
    assert metrics.reconverge_time(_h_errors(t, np.ones_like(t)), 100.0, threshold_m=5.0,
                                   hold_s=10.0) == pytest.approx(0.0)
    # never below the threshold
    assert metrics.reconverge_time(_h_errors(t, h2 + 10.0), 100.0, threshold_m=5.0,
                                   hold_s=10.0) is None
    # a run cut by the next outage counts, one cut by the end of the data must last hold_s
    assert metrics.reconverge_time(err, 100.0, threshold_m=5.0, hold_s=10.0,
                                   until_s=113.0) == pytest.approx(9.1, abs=1e-9)
    t_short = t[t < 112.0]
    assert metrics.reconverge_time(_h_errors(t_short, h2[t < 112.0]), 100.0,
                                   threshold_m=5.0, hold_s=10.0) is None


# ------------------------------------------------------------------ events


def _series(t: np.ndarray, **fields: object) -> HealthSeries:
    return HealthSeries(time_s=t, **fields)  # type: ignore[arg-type]


def _steps(t: np.ndarray, times: list[float] | np.ndarray) -> np.ndarray:
    """A cumulative counter that increases by one at each of ``times``."""
    return np.searchsorted(np.sort(np.asarray(times, dtype=float)), t, side="right").astype(
        np.int64)


T50 = np.round(np.arange(0.0, 200.0, 0.02), 6)  # 50 Hz output


def test_spoof_detected_then_reaccepted_after_a_reset() -> None:
    """GIVEN a spoof 100-160 s; fixes fused at 5 Hz until the first rejection at 103 s, then a
    reset to the spoofed fix at 130 s and fusion again from 130.2 s WHEN scored THEN detect_s = 3,
    max error is the error's max in the window, and the re-accepts are counted."""
    fused_t = np.r_[np.arange(0.1, 103.0, 0.2), np.arange(130.2, 160.0, 0.2)]
    h = np.where((T50 >= 100.0) & (T50 <= 160.0), T50 - 100.0, 1.0)
    err = _h_errors(T50, h)
    health = _series(
        T50, gnss_fused=_steps(T50, fused_t), gnss_rejected=_steps(T50, np.arange(103.0, 130.0,
        0.2)), gnss_resets=_steps(T50, [130.0]))  # fmt: skip
    ev = event_metrics.EventWindow("gnss_spoof_hijack", 100.0, 160.0)
    assert ev.kind == "spoof" and ev.sensor == "gnss"
    em = event_metrics.event_metrics(err, ev, health=health)
    assert em.detect_s == pytest.approx(3.0)
    assert em.max_horizontal_m == pytest.approx(60.0)
    expected = 1 + np.count_nonzero((fused_t > 103.0) & (fused_t <= 160.0))
    assert em.reaccept_count == expected and em.reaccepted_early is True
    # the same filter without the reset and the re-fusion is clean
    clean = _series(T50, gnss_fused=_steps(T50, fused_t[fused_t < 103.0]),
                    gnss_rejected=_steps(T50, np.arange(103.0, 160.0, 0.2)))
    em2 = event_metrics.event_metrics(err, ev, health=clean)
    assert em2.detect_s == pytest.approx(3.0)
    assert em2.reaccepted_early is False and em2.reaccept_count == 0
    assert em2.as_dict()["detected"] is True


def test_detection_ignores_stale_ratios_and_uses_the_events_sensor() -> None:
    """A test ratio > 1 left over from before the event is not a detection; a fresh one is.
    A baro glitch is detected by the baro checks, not by GNSS rejections."""
    r = np.full(T50.size, np.nan)
    r[T50 >= 90.0] = 2.0  # one old test
    r[T50 >= 105.0] = 1.5  # a new test at 105 s
    health = _series(T50, ratio_gnss_pos=r, gnss_rejected=_steps(T50, [100.5]),
                     baro_rejected=_steps(T50, [101.5]))
    stale = HealthSeries(T50, ratio_gnss_pos=r)
    ev = event_metrics.EventWindow("gnss_spoof_drift", 100.0, 150.0)
    assert event_metrics.event_metrics(_h_errors(T50, T50 * 0), ev, health=stale).detect_s == \
        pytest.approx(5.0)
    baro = event_metrics.EventWindow("baro_glitch", 100.0, 150.0)
    assert baro.kind == "glitch" and baro.sensor == "baro"
    assert event_metrics.detect_time(health, 100.0, 150.0, "baro") == pytest.approx(101.5)
    assert event_metrics.detect_time(health, 100.0, 150.0, "gnss") == pytest.approx(100.5)
    assert event_metrics.detect_time(health, 100.0, 150.0, "mag") is None
    # a test before the window and none in it: never detected
    assert event_metrics.detect_time(stale, 100.0, 104.9, "gnss") is None


def test_jamming_detected_when_the_filter_declares_gnss_lost() -> None:
    mode = np.where((T50 >= 112.0) & (T50 < 140.0), "free-inertial", "gnss")
    health = _series(T50, mode=mode)
    ev = event_metrics.EventWindow("gnss_jamming", 100.0, 140.0)
    assert ev.kind == "jamming"
    em = event_metrics.event_metrics(_h_errors(T50, T50 * 0), ev, health=health)
    assert em.detect_s == pytest.approx(12.0)
    # jamming: no fix data, so the re-accept check does not apply
    assert em.reaccepted_early is None and em.reaccept_count is None


def test_undetected_slow_spoof_counts_the_bad_fixes_fused() -> None:
    """GIVEN fixes at 5 Hz pulled off 1 m/s from 100 s (1 m error before) and a filter that fuses
    every fix until 120 s without ever rejecting one WHEN a fix > 10 m off must not be fused THEN
    the fixes of 109.1 ... 119.9 s (55) are counted and the event is flagged."""
    fix_t = np.round(np.arange(0.1, 200.0, 0.2), 6)
    fix_err = np.where(fix_t >= 100.0, 1.0 + (fix_t - 100.0), 1.0)
    fixes = Fixes(fix_t, fix_t * 0, fix_t * 0, fix_t * 0)
    fused_at = fix_t[fix_t < 120.0] + 0.01  # fused 10 ms after the time of validity
    health = _series(T50, gnss_fused=_steps(T50, fused_at), gnss_rejected=T50 * 0,
                     fixes=fixes)
    ev = event_metrics.EventWindow("gnss_spoof_drift", 100.0, 160.0)
    em = event_metrics.event_metrics(_h_errors(T50, T50 * 0), ev, health=health, fix_err_m=fix_err,
                               bad_fix_m=10.0)
    assert em.detect_s is None
    assert em.bad_fixes_fused == 55
    assert em.reaccept_count == 55 and em.reaccepted_early is True


def test_pitot_blockage_detected_when_the_filter_declares_it_blocked() -> None:
    """GIVEN a pitot blockage 100-160 s inside a GNSS outage (mode dead-reckoning throughout)
    and a filter that declares the pitot blocked at 106.5 s WHEN scored THEN the event concerns
    the airspeed sensor, is detected 6.5 s in, and the outage's mode change does not count."""
    mode = np.where(T50 >= 50.0, "dead-reckoning", "gnss")
    health = _series(T50, mode=mode, airspeed_blockages=_steps(T50, [106.5]))
    ev = event_metrics.EventWindow("pitot_blockage", 100.0, 160.0)
    assert ev.sensor == "airspeed" and ev.kind == "generic"
    em = event_metrics.event_metrics(_h_errors(T50, T50 * 0), ev, health=health)
    assert em.detect_s == pytest.approx(6.5)
    # a blockage declared before the event (an earlier fault) is no detection of this one
    early = _series(T50, mode=mode, airspeed_blockages=_steps(T50, [80.0]))
    assert event_metrics.event_metrics(_h_errors(T50, T50 * 0), ev, health=early).detect_s \
        is None
    # the GNSS outage itself is detected by the mode change, under its own sensor
    outage = event_metrics.EventWindow("gnss_outage", 40.0, 200.0)
    rows = [event_metrics.event_metrics(_h_errors(T50, T50 * 0), e, health=h).as_dict()
            for e, h in ((outage, health), (ev, health), (ev, early))]
    by_sensor = event_metrics.detect_s_by_sensor(rows)
    assert by_sensor["gnss"] == [pytest.approx(10.0)]
    assert by_sensor["airspeed"] == [pytest.approx(6.5), None]
    assert by_sensor["baro"] == [] and set(by_sensor) == set(event_metrics.EVENT_SENSORS)


def test_fix_errors_against_truth() -> None:
    t = np.arange(0.0, 10.0, 0.5)
    zero = np.zeros_like(t)
    truth = _track(t, zero, zero, zero)
    spoofed = _track(t, zero + 30.0, zero + 40.0, zero)
    fixes = Fixes(np.r_[t, 20.0], np.r_[spoofed.lat_rad, 0.0], np.r_[spoofed.lon_rad, 0.0],
                          np.r_[spoofed.alt_m, 0.0])
    e = event_metrics.fix_errors(fixes, truth)
    np.testing.assert_allclose(e[:-1], 50.0, rtol=1e-6)
    assert math.isnan(e[-1])  # after the truth ends


def test_event_and_series_validation() -> None:
    with pytest.raises(ValueError, match="kind"):
        event_metrics.EventWindow("gnss_outage", 10.0, 20.0, kind="meteor")
    with pytest.raises(ValueError, match="end_s"):
        event_metrics.EventWindow("gnss_outage", 10.0, 5.0)
    with pytest.raises(ValueError, match="gnss_fused"):
        HealthSeries(np.arange(5.0), gnss_fused=np.zeros(4, dtype=np.int64))
    with pytest.raises(ValueError, match="no 'start_s'"):
        event_metrics.EventWindow.from_mapping({"type": "gnss_outage"})
    ev = event_metrics.EventWindow.from_mapping(
        {"type": "weather_front", "start_s": 5, "end_s": None})
    assert ev.sensor == "baro" and ev.kind == "generic" and ev.end_s == math.inf
    assert event_metrics.event_sensor("imu_bias_step") == "imu"
    assert event_metrics.event_sensor("solar_flare") == "any"
    assert event_metrics.event_sensor("pitot_drift") == "airspeed"
    assert event_metrics.event_sensor("airspeed_failure") == "airspeed"


def test_rejections_outside_windows() -> None:
    health = _series(T50, gnss_rejected=_steps(T50, [5.0, 50.0, 101.0, 150.0]),
                     baro_rejected=_steps(T50, [120.0]))
    out = event_metrics.rejections_outside(health, [(100.0, 130.0)], after_s=10.0)
    assert out == {"gnss_rejected": 2, "baro_rejected": 0}


def test_nees_in_blocks_equals_nees_in_one_piece_and_reads_selected_rows() -> None:
    """GIVEN random SPD 9x9 covariances (one singular, one with a NaN) for more samples than
    one block holds
    WHEN the NEES is computed block by block, with and without a row selection
    THEN every value equals the one-piece computation bit for bit (each sample's NEES is its
    own), and a selection reads exactly the selected covariances."""
    rng = np.random.default_rng(7)
    n = metrics.NEES_BLOCK_ROWS * 2 + 37
    a = rng.normal(size=(n, 9, 9))
    cov = a @ np.swapaxes(a, 1, 2) + 1e-3 * np.eye(9)
    cov[5, 2, :] = cov[5, :, 2] = 0.0  # singular: a state held exactly
    cov[11, 0, 0] = np.nan
    e = rng.normal(size=(n, 9))
    one_piece = metrics._nees_block(e, cov)
    np.testing.assert_array_equal(metrics.nees(e, cov), one_piece)
    assert np.isnan(one_piece[11]) and np.isfinite(one_piece[12])
    rows = np.flatnonzero(rng.random(n) < 0.6)
    np.testing.assert_array_equal(metrics.nees(e[rows], cov, rows), one_piece[rows])
    with pytest.raises(ValueError, match="rows"):
        metrics.nees(e[:3], cov, rows)


def _random_tracks(n_est: int, n_truth: int, *, with_cov: bool) -> tuple[Track, Track]:
    """Estimate and truth tracks of random (but plausible) values; the estimate starts before
    and ends after the truth, so some estimates are dropped."""
    rng = np.random.default_rng(11)
    tp = np.sort(rng.uniform(0.0, 100.0, n_truth))
    t = np.sort(rng.uniform(-1.0, 101.0, n_est))
    yaw_t = np.cumsum(rng.normal(0.0, 0.3, n_truth))  # wraps past +-pi several times
    truth = Track(tp, 0.8 + rng.normal(0.0, 1e-4, n_truth), 0.14 + rng.normal(0.0, 1e-4, n_truth),
                  1000.0 + rng.normal(0.0, 5.0, n_truth), rng.normal(0.0, 30.0, (n_truth, 3)),
                  np.column_stack([rng.normal(0.0, 0.3, n_truth), rng.normal(0.0, 0.2, n_truth),
                                   np.angle(np.exp(1j * yaw_t))]))  # fmt: skip
    a = rng.normal(size=(n_est, 9, 9))
    cov = a @ np.swapaxes(a, 1, 2) + 1e-3 * np.eye(9) if with_cov else None
    sigma = np.abs(rng.normal(1.0, 0.3, (n_est, 9)))
    est = Track(t, 0.8 + rng.normal(0.0, 1e-4, n_est), 0.14 + rng.normal(0.0, 1e-4, n_est),
                1000.0 + rng.normal(0.0, 5.0, n_est), rng.normal(0.0, 30.0, (n_est, 3)),
                rng.uniform(-np.pi, np.pi, (n_est, 3)) * [0.5, 0.4, 1.0], sigma=sigma, cov=cov)
    return est, truth


@pytest.mark.parametrize("with_cov", [True, False])
def test_errors_in_blocks_equal_errors_in_one_piece(with_cov: bool) -> None:
    """GIVEN estimate and truth tracks (yaw wrapping, estimates outside the truth's span)
    WHEN errors() runs in blocks of 7, of 256 and in one block
    THEN every output array is the same bit for bit (each sample's error is its own; the
    truth's attitude is unwrapped once, whole)."""
    est, truth = _random_tracks(1000, 700, with_cov=with_cov)
    whole = metrics.errors(est, truth, block_rows=10**6)
    assert 0 < whole.time_s.size < est.time_s.size  # some dropped: the selection path
    for block_rows in (7, 256):
        part = metrics.errors(est, truth, block_rows=block_rows)
        for name in ("time_s", "pos_ned_m", "vel_ned_mps", "att_rad", "lat_deg", "lon_deg",
                     "sigma", "tilt_rad", "cov", "att_sigma_rad"):
            np.testing.assert_array_equal(getattr(part, name), getattr(whole, name),
                                          err_msg=name)
    # and the one-block result is the estimate minus truth it always was
    k = 500
    i = int(np.flatnonzero(est.time_s == whole.time_s[k])[0])
    alt_t = np.interp(whole.time_s[k], truth.time_s, truth.alt_m)
    assert whole.pos_ned_m[k, 2] == -(est.alt_m[i] - alt_t)
    if with_cov:  # estimates in time order: the covariances are a view, never a copy
        assert np.shares_memory(whole.cov, est.cov)
    # an estimate outside the truth's span in the middle: the kept rows are gathered
    order = np.r_[1:500, 0, 500:est.time_s.size]
    assert est.time_s[0] < truth.time_s[0]
    shuffled = Track(*(None if a is None else a[order] for a in (
        est.time_s, est.lat_rad, est.lon_rad, est.alt_m, est.v_ned_mps, est.euler_rad,
        est.sigma, est.cov)))  # fmt: skip
    gathered = metrics.errors(shuffled, truth, block_rows=7)
    for name in ("time_s", "pos_ned_m", "tilt_rad", "att_sigma_rad", "cov"):
        np.testing.assert_array_equal(getattr(gathered, name), getattr(whole, name),
                                      err_msg=name)
    with pytest.raises(ValueError, match="block_rows"):
        metrics.errors(est, truth, block_rows=0)


# ------------------------------------------------------------------ outages as users count them


def test_gaps_inside_one_jamming_event_are_one_outage() -> None:
    """GIVEN the fix gaps of a jammer (10 s blackout, then fixes flapping every 2 s) and a
    later, separate outage WHEN merged with the jamming window THEN the jamming is one outage
    from its first gap's start to its last gap's end, listing its gaps; the later outage
    stays on its own."""
    jam = metrics.Window(305.0, 395.0)
    gaps = [metrics.Window(304.9, 315.1)]
    gaps += [metrics.Window(t - 0.1, t + 1.1) for t in np.arange(317.0, 395.0, 2.0)]
    later = metrics.Window(500.0, 530.0)
    out = metrics.merge_gaps([*gaps, later], denied=[jam], merge_s=0.0)
    assert [(o.start_s, o.end_s) for o in out] == [(304.9, gaps[-1].end_s), (500.0, 530.0)]
    assert out[0].gaps == tuple(gaps) and out[1].gaps == (later,)


def test_close_gaps_merge_and_far_ones_do_not() -> None:
    """GIVEN gaps 2 s apart and then 20 s apart WHEN merged with a 3 s merge time (no
    scripted event) THEN the first two form one outage and the third stays apart; with no
    merge time every gap is its own outage."""
    gaps = [metrics.Window(100.0, 110.0), metrics.Window(112.0, 120.0),
            metrics.Window(140.0, 150.0)]
    merged = metrics.merge_gaps(gaps, merge_s=3.0)
    assert [(o.start_s, o.end_s, len(o.gaps)) for o in merged] == [
        (100.0, 120.0, 2), (140.0, 150.0, 1)]
    assert len(metrics.merge_gaps(gaps, merge_s=0.0)) == 3
