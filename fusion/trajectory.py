"""Ideal IMU from a trajectory: the inverse of the strapdown mechanisation.

Given a sequence of true states (time, position, velocity, attitude) this module builds a smooth
trajectory through them and integrates what a perfect IMU would output over each sampling
interval, *with this package's Earth model* (so a perfect INS reproduces the trajectory; an IMU
made with another gravity model, e.g. JSBSim's, would not):

- position: cubic Hermite splines of latitude, longitude and height whose slopes come from the
  given NED velocities, so both position and velocity are matched at every knot;
- attitude: :class:`scipy.spatial.transform.RotationSpline` of ``C_nb`` (continuous angular
  rate and acceleration; its first derivative is ``omega_nb_b``);
- ``omega_ib_b = omega_nb_b + C_bn (omega_ie_n + omega_en_n)``,
  ``f_b = C_bn (dv_n/dt + (2 omega_ie_n + omega_en_n) × v_n - g_n)``;
- increments ``dtheta = ∫ omega_ib_b dt`` and ``dv = ∫ f_b dt`` by Gauss-Legendre quadrature.

Use :func:`ideal_imu_from_truth` on any objects with ``Truth``'s attributes (``sim.samples.Truth``
satisfies it), passing the sample class to build, e.g.
``ideal_imu_from_truth(truths, 200.0, make=sim.samples.ImuSample)``: ``fusion`` never imports
``sim``. Deterministic, no noise: add sensor errors elsewhere.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicHermiteSpline
from scipy.spatial.transform import Rotation, RotationSpline

from fusion import earth

FloatArray = NDArray[np.float64]
T = TypeVar("T")


class TruthLike(Protocol):
    """The attributes of ``sim.samples.Truth`` that the ideal IMU needs."""

    @property
    def time_us(self) -> int: ...
    @property
    def lat_rad(self) -> float: ...
    @property
    def lon_rad(self) -> float: ...
    @property
    def alt_msl_m(self) -> float: ...
    @property
    def v_ned_mps(self) -> FloatArray: ...
    @property
    def q_nb(self) -> FloatArray: ...


class Kinematics(NamedTuple):
    """Trajectory quantities at a set of times (rows)."""

    lla: FloatArray
    """(N, 3) latitude (rad), longitude (rad), height (m)."""
    v_ned_mps: FloatArray
    """(N, 3) velocity NED, m/s."""
    a_ned_mps2: FloatArray
    """(N, 3) time derivative of the NED velocity components, m/s^2."""
    q_nb: FloatArray
    """(N, 4) attitude quaternion, scalar first."""
    omega_nb_b_rps: FloatArray
    """(N, 3) rate of body w.r.t. NED, in body, rad/s."""


class ImuIncrements(NamedTuple):
    """Ideal IMU output over consecutive intervals (row k covers ``(t_k - dt_k, t_k]``)."""

    time_s: FloatArray
    """(K,) end time of each interval, s."""
    dt_s: FloatArray
    """(K,) interval lengths, s."""
    dtheta_b: FloatArray
    """(K, 3) gyro increments, rad."""
    dv_b: FloatArray
    """(K, 3) accelerometer increments, m/s."""


class SplineTrajectory:
    """Smooth trajectory through sampled true states (see module docstring).

    Parameters
    ----------
    time_s : array_like, shape (N,)
        Strictly increasing times, s.
    lla : array_like, shape (N, 3)
        Latitude (rad), longitude (rad), height (m).
    v_ned_mps : array_like, shape (N, 3)
        Velocity NED, m/s (sets the position splines' slopes).
    q_nb : array_like, shape (N, 4)
        Attitude quaternions, scalar first.
    """

    def __init__(
        self, time_s: ArrayLike, lla: ArrayLike, v_ned_mps: ArrayLike, q_nb: ArrayLike
    ) -> None:
        t = np.asarray(time_s, dtype=float)
        p = np.asarray(lla, dtype=float)
        v = np.asarray(v_ned_mps, dtype=float)
        q = np.asarray(q_nb, dtype=float)
        n = len(t)
        if n < 2 or p.shape != (n, 3) or v.shape != (n, 3) or q.shape != (n, 4):
            raise ValueError(
                f"need N >= 2 and shapes (N,), (N,3), (N,3), (N,4); got {t.shape}, {p.shape}, "
                f"{v.shape}, {q.shape}"
            )
        if np.any(np.diff(t) <= 0.0):
            raise ValueError("time_s must be strictly increasing")
        r_m, r_n = earth.principal_radii(p[:, 0])
        lat_dot = v[:, 0] / (r_m + p[:, 2])
        lon_dot = v[:, 1] / ((r_n + p[:, 2]) * np.cos(p[:, 0]))
        h_dot = -v[:, 2]
        self.t0_s = float(t[0])
        self.t1_s = float(t[-1])
        self._lat = CubicHermiteSpline(t, p[:, 0], lat_dot)
        self._lon = CubicHermiteSpline(t, p[:, 1], lon_dot)
        self._h = CubicHermiteSpline(t, p[:, 2], h_dot)
        # scipy quaternions are scalar last
        self._rot = RotationSpline(t, Rotation.from_quat(q[:, [1, 2, 3, 0]]))

    def __call__(self, t_s: ArrayLike) -> Kinematics:
        """Position, velocity, acceleration, attitude and body rate at times ``t_s`` (M,)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        lat, lon, h = self._lat(t), self._lon(t), self._h(t)
        dlat, dlon, dh = self._lat(t, 1), self._lon(t, 1), self._h(t, 1)
        ddlat, ddlon, ddh = self._lat(t, 2), self._lon(t, 2), self._h(t, 2)
        s, c = np.sin(lat), np.cos(lat)
        x = 1.0 - earth.E2 * s**2
        r_n = earth.A / np.sqrt(x)
        r_m = r_n * (1.0 - earth.E2) / x
        # dR/dlat of the radii of curvature
        dr_n = r_n * earth.E2 * s * c / x
        dr_m = 3.0 * r_m * earth.E2 * s * c / x
        vn = (r_m + h) * dlat
        ve = (r_n + h) * c * dlon
        vd = -dh
        an = (dr_m * dlat + dh) * dlat + (r_m + h) * ddlat
        ae = (dr_n * dlat + dh) * c * dlon - (r_n + h) * s * dlat * dlon + (r_n + h) * c * ddlon
        ad = -ddh
        rot = self._rot(t)
        qs = rot.as_quat()
        q = np.column_stack([qs[:, 3], qs[:, :3]])
        omega = np.asarray(self._rot(t, 1), dtype=float)
        return Kinematics(
            np.column_stack([lat, lon, h]),
            np.column_stack([vn, ve, vd]),
            np.column_stack([an, ae, ad]),
            q,
            omega,
        )


def imu_rates(kin: Kinematics) -> tuple[FloatArray, FloatArray]:
    """Ideal gyro and accelerometer outputs at the trajectory points.

    Returns
    -------
    omega_ib_b : ndarray, shape (N, 3)
        rad/s.
    f_b : ndarray, shape (N, 3)
        Specific force, m/s^2.
    """
    lat, h = kin.lla[:, 0], kin.lla[:, 2]
    v = kin.v_ned_mps
    w_ie = earth.earth_rate_n(lat)
    w_en = earth.transport_rate_n(lat, h, v)
    g_n = np.zeros_like(v)
    g_n[:, 2] = earth.gravity(lat, h)
    f_n = kin.a_ned_mps2 + np.cross(2.0 * w_ie + w_en, v) - g_n
    from fusion.rotations import quat_to_dcm

    c_nb = quat_to_dcm(kin.q_nb)
    # C_bn x = C_nb^T x
    omega_ib_b = kin.omega_nb_b_rps + np.einsum("nji,nj->ni", c_nb, w_ie + w_en)
    f_b = np.einsum("nji,nj->ni", c_nb, f_n)
    return omega_ib_b, f_b


def ideal_increments(
    trajectory: Callable[[FloatArray], Kinematics],
    time_edges_s: ArrayLike,
    n_nodes: int = 4,
) -> ImuIncrements:
    """Integrate ideal gyro and accelerometer outputs over consecutive intervals.

    Parameters
    ----------
    trajectory : callable
        ``trajectory(t) -> Kinematics``, e.g. a :class:`SplineTrajectory`.
    time_edges_s : array_like, shape (K + 1,)
        Interval boundaries, s (increasing).
    n_nodes : int
        Gauss-Legendre nodes per interval (4 integrates the splines' polynomials exactly).

    Returns
    -------
    ImuIncrements
    """
    edges = np.asarray(time_edges_s, dtype=float)
    if edges.ndim != 1 or len(edges) < 2 or np.any(np.diff(edges) <= 0.0):
        raise ValueError("time_edges_s must be an increasing 1-D array with >= 2 entries")
    nodes, weights = np.polynomial.legendre.leggauss(n_nodes)
    t0, t1 = edges[:-1], edges[1:]
    half = 0.5 * (t1 - t0)
    mid = 0.5 * (t1 + t0)
    t = (mid[:, None] + half[:, None] * nodes[None, :]).ravel()
    omega, f = imu_rates(trajectory(t))
    k = len(t0)
    w = (half[:, None] * weights[None, :])[..., None]
    dtheta = np.sum(omega.reshape(k, n_nodes, 3) * w, axis=1)
    dv = np.sum(f.reshape(k, n_nodes, 3) * w, axis=1)
    return ImuIncrements(t1, t1 - t0, dtheta, dv)


def spline_from_truth(truth: Sequence[TruthLike]) -> SplineTrajectory:
    """:class:`SplineTrajectory` through a sequence of ``Truth``-like samples."""
    t = np.array([s.time_us for s in truth], dtype=float) * 1e-6
    lla = np.array([(s.lat_rad, s.lon_rad, s.alt_msl_m) for s in truth], dtype=float)
    v = np.array([np.asarray(s.v_ned_mps, dtype=float) for s in truth])
    q = np.array([np.asarray(s.q_nb, dtype=float) for s in truth])
    return SplineTrajectory(t, lla, v, q)


def ideal_imu_from_truth(
    truth: Sequence[TruthLike],
    rate_hz: float,
    make: Callable[..., T],
) -> list[T]:
    """Perfect IMU samples (interval averages) along a ``Truth`` sequence.

    Parameters
    ----------
    truth : sequence of Truth-like
        True states, strictly increasing ``time_us``; sampled densely enough that the splines
        follow the motion (>= 50 Hz for aircraft manoeuvres).
    rate_hz : float
        IMU rate; the first sample covers ``(t_0, t_0 + 1/rate]``.
    make : callable
        Sample constructor called with keywords ``time_us``, ``dt_s``, ``specific_force_b_mps2``,
        ``angular_rate_b_rps`` (e.g. ``sim.samples.ImuSample``).

    Returns
    -------
    list
        ``make(...)`` for every whole interval inside the truth's time span.
    """
    if not rate_hz > 0.0:
        raise ValueError(f"rate_hz must be positive, got {rate_hz}")
    traj = spline_from_truth(truth)
    t0_us = int(truth[0].time_us)
    period_us = round(1e6 / rate_hz)
    n = int((int(truth[-1].time_us) - t0_us) // period_us)
    edges_us = t0_us + period_us * np.arange(n + 1, dtype=np.int64)
    inc = ideal_increments(traj, edges_us * 1e-6)
    dt = period_us * 1e-6
    return [
        make(
            time_us=int(edges_us[k + 1]),
            dt_s=dt,
            specific_force_b_mps2=inc.dv_b[k] / dt,
            angular_rate_b_rps=inc.dtheta_b[k] / dt,
        )
        for k in range(n)
    ]
