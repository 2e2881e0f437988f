"""fusion.earth: WGS-84 radii, normal gravity, Earth and transport rates, frame conversions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth
from fusion.rotations import dcm_to_rotvec


def c_en(lat: float, lon: float) -> np.ndarray:
    """NED -> ECEF rotation (written independently of fusion.earth)."""
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-sl * co, -so, -cl * co], [-sl * so, co, -cl * so], [cl, 0.0, -sl]])


def test_radii_at_equator_and_pole() -> None:
    r_m, r_n = earth.principal_radii(0.0)
    assert r_n == pytest.approx(earth.A, abs=1e-6)
    assert r_m == pytest.approx(earth.A * (1.0 - earth.E2), abs=1e-6)
    r_m, r_n = earth.principal_radii(math.pi / 2)
    assert r_m == pytest.approx(earth.A**2 / earth.B, abs=1e-6)
    assert r_n == pytest.approx(earth.A**2 / earth.B, abs=1e-6)


def test_normal_gravity_published_values() -> None:
    # Somigliana on the ellipsoid: equator and pole values, 45 deg (NIMA TR8350.2)
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.gravity(math.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert earth.gravity(math.radians(45.0), 0.0) == pytest.approx(9.806199, abs=2e-6)
    # free-air gradient ~ -3.086e-6 /s^2
    g0 = earth.gravity(math.radians(45.0), 0.0)
    g1 = earth.gravity(math.radians(45.0), 1000.0)
    assert (g1 - g0) / 1000.0 == pytest.approx(-3.086e-6, rel=3e-3)


@pytest.mark.parametrize("lat_deg, h", [(0.0, 0.0), (47.0, 800.0), (-63.0, 9000.0)])
def test_gravity_gradient_matches_finite_differences(lat_deg: float, h: float) -> None:
    lat = math.radians(lat_deg)
    dg_dlat, dg_dh = earth.gravity_gradient(lat, h)
    eps_lat, eps_h = 1e-5, 1.0
    fd_lat = (earth.gravity(lat + eps_lat, h) - earth.gravity(lat - eps_lat, h)) / (2 * eps_lat)
    fd_h = (earth.gravity(lat, h + eps_h) - earth.gravity(lat, h - eps_h)) / (2 * eps_h)
    assert dg_dlat == pytest.approx(fd_lat, rel=1e-6, abs=1e-9)
    assert dg_dh == pytest.approx(fd_h, rel=1e-6)


def test_local_terms_match_array_functions() -> None:
    for lat in np.radians([-80.0, -10.0, 0.0, 33.0, 89.0]):
        for h in (-100.0, 0.0, 12000.0):
            t = earth.local_terms(float(lat), h)
            r_m, r_n = earth.principal_radii(lat)
            assert t.rho_n_m == pytest.approx(r_m + h, rel=1e-15)
            assert t.rho_e_m == pytest.approx(r_n + h, rel=1e-15)
            assert t.gravity_mps2 == pytest.approx(earth.gravity(lat, h), rel=1e-15)


def test_ecef_known_points_and_round_trip() -> None:
    np.testing.assert_allclose(earth.lla_to_ecef(0.0, 0.0, 0.0), [earth.A, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(
        earth.lla_to_ecef(math.pi / 2, 0.3, 0.0), [0.0, 0.0, earth.B], atol=1e-6
    )
    rng = np.random.default_rng(0)
    lat = rng.uniform(-math.pi / 2 + 1e-6, math.pi / 2 - 1e-6, 200)
    lon = rng.uniform(-math.pi, math.pi, 200)
    h = rng.uniform(-500.0, 30000.0, 200)
    lat2, lon2, h2 = earth.ecef_to_lla(earth.lla_to_ecef(lat, lon, h))
    np.testing.assert_allclose(lat2, lat, atol=1e-12)
    np.testing.assert_allclose(lon2, lon, atol=1e-12)
    np.testing.assert_allclose(h2, h, atol=1e-6)


def test_earth_rate_is_the_ecef_z_axis_rotation_in_ned() -> None:
    lat, lon = math.radians(47.0), math.radians(8.0)
    w_e = np.array([0.0, 0.0, earth.RATE])
    np.testing.assert_allclose(earth.earth_rate_n(lat), c_en(lat, lon).T @ w_e, atol=1e-18)


def test_transport_rate_is_the_rotation_rate_of_ned() -> None:
    # move along a path and measure how the NED frame turns w.r.t. ECEF
    lat, lon, h = math.radians(52.0), math.radians(-3.0), 1500.0
    v_n = np.array([60.0, -45.0, 5.0])
    dt = 1e-2
    r_m, r_n = earth.principal_radii(lat)
    lat2 = lat + v_n[0] / (r_m + h) * dt
    lon2 = lon + v_n[1] / ((r_n + h) * math.cos(lat)) * dt
    c_n1n2 = c_en(lat, lon).T @ c_en(lat2, lon2)
    measured = dcm_to_rotvec(c_n1n2) / dt
    np.testing.assert_allclose(earth.transport_rate_n(lat, h, v_n), measured, rtol=1e-4, atol=1e-12)


def test_ned_offset_matches_exact_ned_for_small_offsets() -> None:
    lat0, lon0, h0 = math.radians(47.0), math.radians(8.0), 400.0
    r_m, r_n = earth.principal_radii(lat0)
    lat = lat0 + 150.0 / (r_m + h0)
    lon = lon0 - 80.0 / ((r_n + h0) * math.cos(lat0))
    h = h0 + 30.0
    exact = earth.lla_to_ned(lat, lon, h, lat0, lon0, h0)
    approx = earth.ned_offset_m(lat, lon, h, lat0, lon0, h0)
    np.testing.assert_allclose(approx, exact, atol=3e-3)
