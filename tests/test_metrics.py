"""Scorecard metrics against hand-made trajectories with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth
from scenarios import metrics
from scenarios.metrics import Track, Window


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
    t = np.arange(n) * 0.1
    sig = np.tile([2.0, 2.0, 3.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.02], (n, 1))
    e = rng.normal(size=(n, 9)) * sig
    err = metrics.Errors(t, e[:, 0:3], e[:, 3:6], e[:, 6:9], e[:, 0] * 0, e[:, 0] * 0, sig)
    c = metrics.consistency(err)
    assert c["nees_mean"] == pytest.approx(9.0, rel=0.03)
    for g in ("pos", "vel", "att"):
        assert c[f"rms_z_{g}"] == pytest.approx(1.0, rel=0.03)
        assert c[f"within_3sigma_{g}"] > 0.98


def test_gnss_on_mask_excludes_settling_and_outages() -> None:
    t = np.arange(0.0, 300.0, 1.0)
    m = metrics.gnss_on_mask(t, [Window(100.0, 130.0)], settle_s=20.0)
    assert not m[t < 20].any()
    assert not m[(t >= 100) & (t < 150)].any()
    assert m[(t >= 20) & (t < 100)].all() and m[t >= 150].all()
