"""WGS-84 Earth model: radii of curvature, normal gravity, Earth and transport rates.

Every function here takes latitude in radians and height in metres. The array functions accept
scalars or arrays (numpy broadcasting); :func:`local_terms` is the scalar fast path that the
strapdown loop calls once per IMU sample (plain ``math``, no array allocation).

References: NIMA TR8350.2 (WGS-84 constants, Somigliana); Titterton & Weston, *Strapdown
Inertial Navigation Technology*, 2nd ed., ch. 3 (radii, transport rate, gravity height
correction); Groves, *Principles of GNSS, Inertial and Multisensor Integrated Navigation*,
2nd ed., eq. 2.105-2.106 and 2.139.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

import physconst

# The WGS-84 ellipsoid (physconst), under the short names of this model's equations.
#: Semi-major axis, m.
A = physconst.WGS84_A_M
#: Flattening.
F = physconst.WGS84_F
#: Semi-minor axis, m.
B = physconst.WGS84_B_M
#: First eccentricity squared.
E2 = physconst.WGS84_E2
#: Earth rotation rate w.r.t. inertial space, rad/s.
RATE = physconst.EARTH_RATE_RPS
#: Earth gravitational constant GM (with atmosphere), m^3/s^2.
GM = physconst.WGS84_GM_M3PS2
#: Normal gravity at the equator / at the poles, m/s^2 (Somigliana).
GE = 9.7803253359
GP = 9.8321849378
#: Somigliana constant k = (b gp) / (a ge) - 1.
K_SOMIGLIANA = B * GP / (A * GE) - 1.0
#: m = omega^2 a^2 b / GM, the ratio of centrifugal to gravitational acceleration at the equator.
M_RATIO = RATE**2 * A**2 * B / GM

FloatOrArray = float | NDArray[np.float64]

# Folded constants of the scalar fast paths (local_terms, gravity_gradient): the normal gravity
# height correction is 1 - (_GH1 - _GH1S sin^2 L) h + _GH2 h^2.
_ONE_MINUS_E2 = 1.0 - E2
_GH1 = 2.0 / A * (1.0 + F + M_RATIO)
_GH1S = 4.0 * F / A
_GH2 = 3.0 / (A * A)
_TWO_GE_K = 2.0 * GE * K_SOMIGLIANA
_sin, _cos, _sqrt = math.sin, math.cos, math.sqrt
_tuple_new = tuple.__new__  # NamedTuple(...) without its Python-level __new__ frame


def principal_radii(lat_rad: ArrayLike) -> tuple[FloatOrArray, FloatOrArray]:
    """Meridian and transverse (prime-vertical) radii of curvature.

    Parameters
    ----------
    lat_rad : float or array_like
        Geodetic latitude, rad.

    Returns
    -------
    r_meridian_m, r_transverse_m : float or ndarray
        ``R_M = a (1 - e^2) / (1 - e^2 sin^2 L)^(3/2)`` and ``R_N = a / sqrt(1 - e^2 sin^2 L)``, m.
    """
    sin_lat = np.sin(lat_rad)
    x = 1.0 - E2 * sin_lat**2
    r_transverse = A / np.sqrt(x)
    r_meridian = r_transverse * (1.0 - E2) / x
    return r_meridian, r_transverse


def gravity(lat_rad: ArrayLike, alt_m: ArrayLike) -> FloatOrArray:
    """Magnitude of normal gravity (gravitation + centrifugal), m/s^2, positive down.

    Somigliana's closed formula on the ellipsoid with the second-order free-air height
    correction ``g(h) = g0 [1 - 2 h / a (1 + f + m - 2 f sin^2 L) + 3 h^2 / a^2]``.

    Parameters
    ----------
    lat_rad, alt_m : float or array_like
        Geodetic latitude (rad) and height (m).

    Returns
    -------
    float or ndarray
        Normal gravity, m/s^2. In NED the gravity vector is ``[0, 0, g]``.
    """
    sin2 = np.sin(lat_rad) ** 2
    h = np.asarray(alt_m, dtype=float)
    g0 = GE * (1.0 + K_SOMIGLIANA * sin2) / np.sqrt(1.0 - E2 * sin2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * sin2) * h + 3.0 * h**2 / A**2)


def gravity_gradient(lat_rad: float, alt_m: float) -> tuple[float, float]:
    """Partial derivatives of :func:`gravity` w.r.t. latitude and height.

    Returns
    -------
    dg_dlat : float
        m/s^2 per rad.
    dg_dh : float
        1/s^2 (about ``-2 g / R``: gravity weakens upwards, the root of the unstable
        vertical channel).
    """
    # d sin^2 L / dL = 2 sin L cos L; written on few operations (runs at the covariance rate)
    s = _sin(lat_rad)
    sc = s * _cos(lat_rad)
    sin2 = s * s
    x = 1.0 - E2 * sin2
    root = _sqrt(x)
    g0 = GE * (1.0 + K_SOMIGLIANA * sin2) / root
    k1 = _GH1 - _GH1S * sin2
    h = alt_m
    corr = 1.0 - k1 * h + _GH2 * h * h
    # d g0 / dL = sin L cos L (2 GE k / root + g0 e^2 / root^2); d corr / dL = 2 _GH1S sc h
    dg_dlat = sc * ((_TWO_GE_K / root + g0 * E2 / x) * corr + 2.0 * _GH1S * h * g0)
    return dg_dlat, g0 * (2.0 * _GH2 * h - k1)


def earth_rate_n(lat_rad: ArrayLike) -> NDArray[np.float64]:
    """Earth rate expressed in NED, ``omega_ie_n = Omega [cos L, 0, -sin L]``.

    Returns
    -------
    ndarray, shape (..., 3)
        rad/s.
    """
    lat = np.asarray(lat_rad, dtype=float)
    return np.stack([RATE * np.cos(lat), np.zeros_like(lat), -RATE * np.sin(lat)], axis=-1)


def transport_rate_n(lat_rad: ArrayLike, alt_m: ArrayLike, v_n: ArrayLike) -> NDArray[np.float64]:
    """Transport rate (rotation of NED w.r.t. ECEF) in NED.

    ``omega_en_n = [vE / (R_N + h), -vN / (R_M + h), -vE tan L / (R_N + h)]``.

    Parameters
    ----------
    lat_rad, alt_m : float or array_like
        Geodetic latitude (rad) and height (m).
    v_n : array_like, shape (..., 3)
        Velocity NED, m/s.

    Returns
    -------
    ndarray, shape (..., 3)
        rad/s.
    """
    v = np.asarray(v_n, dtype=float)
    r_m, r_n = principal_radii(lat_rad)
    rho_e = r_n + np.asarray(alt_m, dtype=float)
    rho_n = r_m + np.asarray(alt_m, dtype=float)
    return np.stack(
        [v[..., 1] / rho_e, -v[..., 0] / rho_n, -v[..., 1] * np.tan(lat_rad) / rho_e], axis=-1
    )


class LocalTerms(NamedTuple):
    """Earth quantities at one point, plain floats (see :func:`local_terms`)."""

    rho_n_m: float
    """R_M + h: meridian radius plus height, m (north metres per radian of latitude)."""
    rho_e_m: float
    """R_N + h: transverse radius plus height, m (east metres per radian of longitude / cos L)."""
    gravity_mps2: float
    sin_lat: float
    cos_lat: float


def local_terms(lat_rad: float, alt_m: float) -> LocalTerms:
    """Scalar fast path: radii plus height, normal gravity, sin/cos of latitude.

    Same formulas as :func:`principal_radii` and :func:`gravity` using ``math`` (about ten times
    faster than numpy on scalars), for the per-sample strapdown loop.
    """
    s = _sin(lat_rad)
    sin2 = s * s
    x = 1.0 - E2 * sin2
    root = _sqrt(x)
    r_n = A / root
    r_m = r_n * _ONE_MINUS_E2 / x
    g = (
        GE
        * (1.0 + K_SOMIGLIANA * sin2)
        / root
        * (1.0 - (_GH1 - _GH1S * sin2) * alt_m + _GH2 * alt_m * alt_m)
    )
    return _tuple_new(LocalTerms, (r_m + alt_m, r_n + alt_m, g, s, _cos(lat_rad)))


def lla_to_ecef(lat_rad: ArrayLike, lon_rad: ArrayLike, alt_m: ArrayLike) -> NDArray[np.float64]:
    """Geodetic (WGS-84) to ECEF.

    Returns
    -------
    ndarray, shape (..., 3)
        ECEF coordinates, m.
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    h = np.asarray(alt_m, dtype=float)
    _, r_n = principal_radii(lat)
    cos_lat = np.cos(lat)
    return np.stack(
        [
            (r_n + h) * cos_lat * np.cos(lon),
            (r_n + h) * cos_lat * np.sin(lon),
            (r_n * (1.0 - E2) + h) * np.sin(lat),
        ],
        axis=-1,
    )


def ecef_to_lla(r_e: ArrayLike) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """ECEF to geodetic (WGS-84) by fixed-point iteration on latitude (converges to < 1e-12 rad).

    Parameters
    ----------
    r_e : array_like, shape (..., 3)
        ECEF position, m.

    Returns
    -------
    lat_rad, lon_rad, alt_m : float or ndarray
    """
    r = np.asarray(r_e, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    lat = np.arctan2(z, p * (1.0 - E2))
    h = np.zeros_like(p)
    for _ in range(8):
        _, r_n = principal_radii(lat)
        cos_lat = np.cos(lat)
        # Away from the poles use p / cos L; near them z / sin L is the well-conditioned form.
        h = np.where(
            np.abs(cos_lat) > 1e-3,
            p / np.where(np.abs(cos_lat) > 1e-3, cos_lat, 1.0) - r_n,
            z / np.sin(lat) - r_n * (1.0 - E2),
        )
        lat = np.arctan2(z, p * (1.0 - E2 * r_n / (r_n + h)))
    return lat, lon, h


def lla_to_ned(
    lat_rad: ArrayLike,
    lon_rad: ArrayLike,
    alt_m: ArrayLike,
    lat0_rad: float,
    lon0_rad: float,
    alt0_m: float,
) -> NDArray[np.float64]:
    """Exact NED coordinates of points w.r.t. a reference point (via ECEF).

    Returns
    -------
    ndarray, shape (..., 3)
        North, east, down of the points in the NED frame at the reference, m.
    """
    d_e = lla_to_ecef(lat_rad, lon_rad, alt_m) - lla_to_ecef(lat0_rad, lon0_rad, alt0_m)
    sl, cl = math.sin(lat0_rad), math.cos(lat0_rad)
    so, co = math.sin(lon0_rad), math.cos(lon0_rad)
    c_ne = np.array([[-sl * co, -sl * so, cl], [-so, co, 0.0], [-cl * co, -cl * so, -sl]])
    return np.asarray(d_e @ c_ne.T, dtype=float)


def ned_offset_m(
    lat_rad: float,
    lon_rad: float,
    alt_m: float,
    lat_ref_rad: float,
    lon_ref_rad: float,
    alt_ref_m: float,
) -> tuple[float, float, float]:
    """Small-offset NED difference ``(point - reference)`` through the radii of curvature.

    ``dN = dL (R_M + h)``, ``dE = dl (R_N + h) cos L``, ``dD = -dh``; exact to first order in the
    offset (error ~ offset^2 / R, i.e. < 1 mm for 100 m). This is how position errors are
    expressed in the filter (metres N/E/D).
    """
    t = local_terms(lat_ref_rad, alt_ref_m)
    return (
        (lat_rad - lat_ref_rad) * t.rho_n_m,
        (lon_rad - lon_ref_rad) * t.rho_e_m * t.cos_lat,
        -(alt_m - alt_ref_m),
    )
