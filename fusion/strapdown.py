"""Strapdown mechanisation in the local-level NED frame (paper P0's INS), stateless.

One call advances the INS state ``(lat, lon, h, v_n, q_nb)`` over one IMU interval from the
gyro and accelerometer *increments* (``dtheta = ∫ omega_ib_b dt``, ``dv = ∫ f_b dt``),
the two-sample way (Savage; the same structure as KF-GINS ``insmech.cpp``):

1. attitude: body rotation ``phi = dtheta + dtheta_prev × dtheta / 12`` (coning), n-frame
   rotation ``zeta = omega_in_n dt``; ``q_nb(k) = q(-zeta) ⊗ q_nb(k-1) ⊗ q(phi)``;
2. velocity: ``dv_f_n = (I - [zeta×]/2) C_nb(k-1) (dv + dtheta × dv / 2 + (dtheta_prev × dv +
   dv_prev × dtheta) / 12)`` (rotation + sculling), then
   ``v(k) = v(k-1) + dv_f_n + (g_n - (2 omega_ie_n + omega_en_n) × v_mid) dt`` with gravity,
   Earth and transport rates at the interval's midpoint (Coriolis and transport terms, P0);
3. position: ``h' = -vD``, ``L' = vN / (R_M + h)``, ``l' = vE / ((R_N + h) cos L)`` integrated
   with the trapezoidal velocity.

The velocity step uses the attitude at the start of the interval with the ``(I - [zeta×]/2)``
and ``dtheta × dv / 2`` terms, which is the mid-interval attitude to second order; the order of
the three updates (attitude, velocity, position) does not change the result.

The increments come from the IMU samples with the filter's sensor-error estimates removed
(:func:`increments`, :func:`increments_scaled`); over a gap without IMU data the INS coasts at
constant velocity (:func:`coast`).

The hot loop runs at up to 400 Hz, so it works on plain floats and tuples (numpy's per-call
overhead would dominate on 3-vectors; the quaternion products and the rotation-vector quaternion
of :mod:`fusion.rotations` are written out inline here for the same reason). The functions
written here (:func:`update_python`, :func:`increments_python`, ...) are the reference; the names
the filter calls (:data:`update`, :data:`increments`, ...) are the same functions compiled
(``fusion/_strapdown.c``, bit for bit the same results) when the package was built with a C
compiler, and these Python functions otherwise (:data:`KERNEL` says which; the environment
variable ``HILNAV_KERNEL=python`` forces the reference).

Accuracy: errors are third order in the step (see ``tests/test_strapdown.py``: an analytic
coordinated turn and climb is reproduced to centimetres over minutes at 50-400 Hz)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from math import cos as _cos
from math import sin as _sin
from math import sqrt as _sqrt
from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion import earth
from physconst.kernel import python_forced

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

_ZERO3: Vec3 = (0.0, 0.0, 0.0)


class InsState(NamedTuple):
    """INS navigation state, plain floats (hot-loop friendly).

    Attributes
    ----------
    lat_rad, lon_rad : float
        Geodetic latitude / longitude, rad.
    alt_msl_m : float
        Height, m (navigation height, see :mod:`fusion`).
    v_ned_mps : tuple of 3 floats
        Velocity w.r.t. Earth in NED, m/s.
    q_nb : tuple of 4 floats
        Attitude quaternion body -> NED, scalar first.
    """

    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: Vec3
    q_nb: Quat

    @classmethod
    def from_arrays(
        cls, lat_rad: float, lon_rad: float, alt_msl_m: float, v_ned_mps: ArrayLike, q_nb: ArrayLike
    ) -> InsState:
        """Build from array-likes (validates shapes, normalises the quaternion)."""
        v = np.asarray(v_ned_mps, dtype=float)
        q = np.asarray(q_nb, dtype=float)
        if v.shape != (3,):
            raise ValueError(f"v_ned_mps must have shape (3,), got {v.shape}")
        if q.shape != (4,):
            raise ValueError(f"q_nb must have shape (4,), got {q.shape}")
        norm = float(np.linalg.norm(q))
        if not np.isfinite(norm) or norm < 1e-6:
            raise ValueError("q_nb must be a finite non-zero quaternion")
        qn = q / norm
        return cls(
            float(lat_rad),
            float(lon_rad),
            float(alt_msl_m),
            (float(v[0]), float(v[1]), float(v[2])),
            (float(qn[0]), float(qn[1]), float(qn[2]), float(qn[3])),
        )


# Earth-model constants folded once (module globals: LOAD_GLOBAL is cached, ``earth.X`` is two
# lookups per use in the per-sample loop).
_E2 = earth.E2
_A = earth.A
_ONE_MINUS_E2 = 1.0 - earth.E2
_GE = earth.GE
_KS = earth.K_SOMIGLIANA
# normal gravity height correction 1 - (_GH1 - _GH1S sin^2 L) h + _GH2 h^2 (earth.gravity)
_GH1 = 2.0 / earth.A * (1.0 + earth.F + earth.M_RATIO)
_GH1S = 4.0 * earth.F / earth.A
_GH2 = 3.0 / (earth.A * earth.A)
_RATE = earth.RATE
_TWELFTH = 1.0 / 12.0
_tuple_new = tuple.__new__  # InsState(...) without the Python-level namedtuple __new__ frame


def update_python(
    state: InsState,
    dtheta_b: Sequence[float],
    dv_b: Sequence[float],
    dtheta_prev_b: Sequence[float],
    dv_prev_b: Sequence[float],
    dt_s: float,
) -> InsState:
    """Advance the INS over one IMU interval (the Python reference of :data:`update`).

    Parameters
    ----------
    state : InsState
        State at the start of the interval.
    dtheta_b, dv_b : sequence of 3 floats
        Gyro increment ``∫ omega_ib_b dt`` (rad) and accelerometer increment ``∫ f_b dt`` (m/s)
        over this interval, bias-corrected.
    dtheta_prev_b, dv_prev_b : sequence of 3 floats
        The same for the previous interval (coning / sculling); zeros on the first sample.
    dt_s : float
        Interval length, s.

    Returns
    -------
    InsState
        State at the end of the interval.
    """
    # Written out on plain floats, every operation counted: this runs at the IMU rate.
    lat, lon, h, (vn, ve, vd), (qw, qx, qy, qz) = state
    ax, ay, az = dtheta_b
    ux, uy, uz = dv_b
    pax, pay, paz = dtheta_prev_b
    pux, puy, puz = dv_prev_b

    # Earth terms at mid-interval height (lat moves ~1e-7 rad per sample: start value is enough).
    h_mid = h - 0.5 * vd * dt_s
    s_lat = _sin(lat)
    c_lat = _cos(lat)
    sin2 = s_lat * s_lat
    x = 1.0 - _E2 * sin2
    root = _sqrt(x)
    r_n = _A / root
    rho_e = r_n + h_mid
    rho_n = r_n * _ONE_MINUS_E2 / x + h_mid
    g = (
        _GE
        * (1.0 + _KS * sin2)
        / root
        * (1.0 - (_GH1 - _GH1S * sin2) * h_mid + _GH2 * h_mid * h_mid)
    )
    tan_lat = s_lat / c_lat
    wie_n = _RATE * c_lat
    wie_d = -_RATE * s_lat

    # rotation (dtheta × dv / 2) and sculling ((dtheta_prev × dv + dv_prev × dtheta) / 12)
    wx = ux + 0.5 * (ay * uz - az * uy) + (pay * uz - paz * uy + puy * az - puz * ay) * _TWELFTH
    wy = uy + 0.5 * (az * ux - ax * uz) + (paz * ux - pax * uz + puz * ax - pux * az) * _TWELFTH
    wz = uz + 0.5 * (ax * uy - ay * ux) + (pax * uy - pay * ux + pux * ay - puy * ax) * _TWELFTH
    # C_nb(k-1) w by the quaternion directly (unit q): t = 2 q_v × w, d = w + qw t + q_v × t
    tx = 2.0 * (qy * wz - qz * wy)
    ty = 2.0 * (qz * wx - qx * wz)
    tz = 2.0 * (qx * wy - qy * wx)
    dn = wx + qw * tx + qy * tz - qz * ty
    de = wy + qw * ty + qz * tx - qx * tz
    dd = wz + qw * tz + qx * ty - qy * tx
    # Mid-interval velocity (Coriolis neglected, it is ~1e-4 of the rest) for the transport rate
    # and Coriolis terms: using the start value instead makes the whole scheme first order.
    mvn = vn + 0.5 * dn
    mve = ve + 0.5 * de
    mvd = vd + 0.5 * (dd + g * dt_s)
    wen_n = mve / rho_e
    wen_e = -mvn / rho_n
    wen_d = -mve * tan_lat / rho_e

    # ---- 1. attitude -------------------------------------------------------------------
    # coning: phi = dtheta + (dtheta_prev × dtheta) / 12; q_b = q(phi) (rotvec_quat inlined:
    # this runs at the IMU rate)
    phx = ax + (pay * az - paz * ay) * _TWELFTH
    phy = ay + (paz * ax - pax * az) * _TWELFTH
    phz = az + (pax * ay - pay * ax) * _TWELFTH
    a2 = phx * phx + phy * phy + phz * phz
    if a2 < 1e-4:
        bw = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        k = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        a = _sqrt(a2)
        bw = _cos(0.5 * a)
        k = _sin(0.5 * a) / a
    bx, by, bz = k * phx, k * phy, k * phz
    # q_n = q(-zeta), zeta = omega_in_n dt (~1e-7 rad: always the series branch in practice)
    zx = (wie_n + wen_n) * dt_s
    zy = wen_e * dt_s
    zz = (wie_d + wen_d) * dt_s
    a2 = zx * zx + zy * zy + zz * zz
    if a2 < 1e-4:
        nw = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        k = a2 / 48.0 - 0.5 - a2 * a2 / 3840.0  # negated: the rotation is -zeta
    else:
        a = _sqrt(a2)
        nw = _cos(0.5 * a)
        k = -_sin(0.5 * a) / a
    nx, ny, nz = k * zx, k * zy, k * zz
    # t = q_nb ⊗ q_b
    tw = qw * bw - qx * bx - qy * by - qz * bz
    tx = qw * bx + qx * bw + qy * bz - qz * by
    ty = qw * by - qx * bz + qy * bw + qz * bx
    tz = qw * bz + qx * by - qy * bx + qz * bw
    # q_new = q_n ⊗ t
    rw = nw * tw - nx * tx - ny * ty - nz * tz
    rx = nw * tx + nx * tw + ny * tz - nz * ty
    ry = nw * ty - nx * tz + ny * tw + nz * tx
    rz = nw * tz + nx * ty - ny * tx + nz * tw
    norm = _sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    if rw < 0.0:
        norm = -norm

    # ---- 2. velocity -------------------------------------------------------------------
    # (I - [zeta×]/2): the n frame turns during the interval; then Coriolis / transport and
    # gravity with c = 2 omega_ie + omega_en
    cx = 2.0 * wie_n + wen_n
    cz = 2.0 * wie_d + wen_d
    vn_new = vn + dn - 0.5 * (zy * dd - zz * de) - (wen_e * mvd - cz * mve) * dt_s
    ve_new = ve + de - 0.5 * (zz * dn - zx * dd) - (cz * mvn - cx * mvd) * dt_s
    vd_new = vd + dd - 0.5 * (zx * de - zy * dn) + (g - (cx * mve - wen_e * mvn)) * dt_s

    # ---- 3. position -------------------------------------------------------------------
    h_new = h - 0.5 * (vd + vd_new) * dt_s
    dh_avg = 0.5 * (h + h_new) - h_mid  # rho at the interval's mean height
    dlat = 0.5 * (vn + vn_new) * dt_s / (rho_n + dh_avg)
    # cos of the mid-interval latitude, first-order expansion
    c_mid = c_lat - 0.5 * s_lat * dlat
    lon_new = lon + 0.5 * (ve + ve_new) * dt_s / ((rho_e + dh_avg) * c_mid)
    return _tuple_new(
        InsState,
        (lat + dlat, lon_new, h_new, (vn_new, ve_new, vd_new),
         (rw / norm, rx / norm, ry / norm, rz / norm)),
    )  # fmt: skip


def increments_python(
    fw: Sequence[float], dt_s: float, accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float],
) -> tuple[Vec3, Vec3]:  # fmt: skip
    """Bias-compensated increments of one IMU interval (sensor model ``f~ = f + b_a``,
    ``omega~ = omega + b_g``).

    Parameters
    ----------
    fw : 6 floats
        Specific force (m/s^2) then angular rate (rad/s), body FRD, as sampled.
    dt_s : float
        Interval, s.
    accel_bias_b_mps2, gyro_bias_b_rps : 3 floats
        Bias estimates.

    Returns
    -------
    dtheta_b, dv_b : 3 floats each
        Gyro increment (rad) and accelerometer increment (m/s).
    """
    fx, fy, fz, wx, wy, wz = fw
    ba, bg, dt = accel_bias_b_mps2, gyro_bias_b_rps, dt_s
    return (
        ((wx - bg[0]) * dt, (wy - bg[1]) * dt, (wz - bg[2]) * dt),
        ((fx - ba[0]) * dt, (fy - ba[1]) * dt, (fz - ba[2]) * dt),
    )


def increments_scaled_python(
    fw: Sequence[float], dt_s: float, accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float], accel_scale_b: Sequence[float],
    gyro_scale_b: Sequence[float],
) -> tuple[Vec3, Vec3]:  # fmt: skip
    """:func:`increments_python` with scale-factor errors too (``f~ = (1 + s_a) f + b_a``,
    ``omega~ = (1 + s_g) omega + b_g``); ``accel_scale_b`` / ``gyro_scale_b`` are the
    dimensionless scale-factor estimates."""
    fx, fy, fz, wx, wy, wz = fw
    ba, bg, sa, sg, dt = accel_bias_b_mps2, gyro_bias_b_rps, accel_scale_b, gyro_scale_b, dt_s
    return (
        (
            (wx - bg[0]) / (1.0 + sg[0]) * dt,
            (wy - bg[1]) / (1.0 + sg[1]) * dt,
            (wz - bg[2]) / (1.0 + sg[2]) * dt,
        ),
        (
            (fx - ba[0]) / (1.0 + sa[0]) * dt,
            (fy - ba[1]) / (1.0 + sa[1]) * dt,
            (fz - ba[2]) / (1.0 + sa[2]) * dt,
        ),
    )


def increments_compensated_python(
    fw: Sequence[float], dt_s: float, accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float], accel_inverse: Sequence[float],
    gyro_inverse: Sequence[float],
) -> tuple[Vec3, Vec3]:  # fmt: skip
    """:func:`increments_python` through the full first-order sensor model
    ``f~ = (I + diag(s_a) + M_a) f + b_a`` (likewise the gyro): ``accel_inverse`` /
    ``gyro_inverse`` are ``(I + diag(s) + M)^-1`` row-major (9 floats each, see
    :func:`sensor_inverse`)."""
    fx, fy, fz, wx, wy, wz = fw
    ba, bg, a, g, dt = accel_bias_b_mps2, gyro_bias_b_rps, accel_inverse, gyro_inverse, dt_s
    wx, wy, wz = (wx - bg[0]) * dt, (wy - bg[1]) * dt, (wz - bg[2]) * dt
    fx, fy, fz = (fx - ba[0]) * dt, (fy - ba[1]) * dt, (fz - ba[2]) * dt
    return (
        (
            g[0] * wx + g[1] * wy + g[2] * wz,
            g[3] * wx + g[4] * wy + g[5] * wz,
            g[6] * wx + g[7] * wy + g[8] * wz,
        ),
        (
            a[0] * fx + a[1] * fy + a[2] * fz,
            a[3] * fx + a[4] * fy + a[5] * fz,
            a[6] * fx + a[7] * fy + a[8] * fz,
        ),
    )


def sensor_matrix(scale: Sequence[float], misalignment: Sequence[float]) -> list[list[float]]:
    """The sensor model ``I + diag(scale) + M`` as rows, ``M`` from its six off-diagonal entries
    in the order ``(0,1), (0,2), (1,0), (1,2), (2,0), (2,1)``
    (:data:`fusion.state_layout.OFF_DIAGONAL`)."""
    m01, m02, m10, m12, m20, m21 = misalignment
    return [
        [1.0 + scale[0], m01, m02],
        [m10, 1.0 + scale[1], m12],
        [m20, m21, 1.0 + scale[2]],
    ]  # fmt: skip


def sensor_inverse(scale: Sequence[float], misalignment: Sequence[float]) -> tuple[float, ...]:
    """``(I + diag(scale) + M)^-1`` row-major (:func:`sensor_matrix`)."""
    return tuple(np.linalg.inv(np.array(sensor_matrix(scale, misalignment))).ravel().tolist())


# ---- compiled kernel -----------------------------------------------------------------------
# fusion/_strapdown.c is these four functions in C, operation for operation (built by
# `pip install` when a C compiler is there; docs/development.md, "Compiled kernels"). Its
# results are bit
# for bit the Python's (tests/fusion/test_strapdown_kernel.py); inputs it does not take (ints,
# numpy scalars, other sequences) go to the Python reference unchanged.
_UpdateFn = Callable[
    [InsState, Sequence[float], Sequence[float], Sequence[float], Sequence[float], float],
    InsState,
]
_IncrementsFn = Callable[
    [Sequence[float], float, Sequence[float], Sequence[float]], tuple[Vec3, Vec3]
]
_Increments6Fn = Callable[
    [Sequence[float], float, Sequence[float], Sequence[float], Sequence[float], Sequence[float]],
    tuple[Vec3, Vec3],
]

def _load_kernel() -> ModuleType | None:
    try:
        from fusion import _strapdown
    except ImportError:  # built without a C compiler: the Python reference, same numbers
        return None
    _strapdown.bind(
        InsState,
        (update_python, increments_python, increments_scaled_python,
         increments_compensated_python),
        (_E2, _A, _ONE_MINUS_E2, _GE, _KS, _GH1, _GH1S, _GH2, _RATE, _TWELFTH),
    )  # fmt: skip
    return _strapdown


_compiled = _load_kernel()  # bound even when not used (tests compare it with the reference)
_kernel = None if python_forced(os.environ) else _compiled
#: Which implementation :data:`update` and the ``increments*`` functions are: ``"c"`` (the
#: compiled kernel) or ``"python"`` (the reference; no compiler at install time, or
#: ``HILNAV_KERNEL=python``).
KERNEL = "python" if _kernel is None else "c"
#: Advance the INS over one IMU interval: :func:`update_python` (see there), compiled when
#: :data:`KERNEL` is ``"c"``.
update: _UpdateFn = update_python if _kernel is None else _kernel.update
#: :func:`increments_python`, compiled when :data:`KERNEL` is ``"c"``.
increments: _IncrementsFn = increments_python if _kernel is None else _kernel.increments
#: :func:`increments_scaled_python`, compiled when :data:`KERNEL` is ``"c"``.
increments_scaled: _Increments6Fn = (
    increments_scaled_python if _kernel is None else _kernel.increments_scaled
)
#: :func:`increments_compensated_python`, compiled when :data:`KERNEL` is ``"c"``.
increments_compensated: _Increments6Fn = (
    increments_compensated_python if _kernel is None else _kernel.increments_compensated
)


def coast(state: InsState, gap_s: float) -> InsState:
    """Dead reckoning at constant velocity and attitude over ``gap_s`` without IMU data.

    Parameters
    ----------
    state : InsState
        State at the start of the gap.
    gap_s : float
        Gap length, s.

    Returns
    -------
    InsState
        Position moved by ``v_n gap_s``; velocity and attitude unchanged.
    """
    lt = earth.local_terms(state.lat_rad, state.alt_msl_m)
    vn, ve, vd = state.v_ned_mps
    return InsState(
        state.lat_rad + vn * gap_s / lt.rho_n_m,
        state.lon_rad + ve * gap_s / (lt.rho_e_m * lt.cos_lat),
        state.alt_msl_m - vd * gap_s,
        state.v_ned_mps,
        state.q_nb,
    )


def integrate(
    state: InsState,
    dtheta_b: ArrayLike,
    dv_b: ArrayLike,
    dt_s: ArrayLike,
) -> list[InsState]:
    """Run :func:`update` over a sequence of increments (pure INS; for tests and tools).

    Parameters
    ----------
    state : InsState
        Initial state.
    dtheta_b, dv_b : array_like, shape (N, 3)
        Gyro / accelerometer increments, rad and m/s.
    dt_s : float or array_like, shape (N,)
        Interval lengths, s.

    Returns
    -------
    list of InsState, length N + 1
        The initial state followed by the state after every interval.
    """
    dth = np.asarray(dtheta_b, dtype=float)
    dvb = np.asarray(dv_b, dtype=float)
    dts: NDArray[np.float64] = np.broadcast_to(np.asarray(dt_s, dtype=float), (len(dth),))
    if dth.shape != dvb.shape or dth.ndim != 2 or dth.shape[1] != 3:
        raise ValueError(f"dtheta_b and dv_b must both be (N, 3), got {dth.shape}, {dvb.shape}")
    out = [state]
    prev_th: Sequence[float] = _ZERO3
    prev_dv: Sequence[float] = _ZERO3
    for th, dv, dt in zip(dth.tolist(), dvb.tolist(), dts.tolist(), strict=True):
        state = update(state, th, dv, prev_th, prev_dv, dt)
        out.append(state)
        prev_th, prev_dv = th, dv
    return out


def states_to_arrays(
    states: Sequence[InsState],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Stack states: ``lla (N, 3)`` (rad, rad, m), ``v_ned (N, 3)`` (m/s), ``q_nb (N, 4)``."""
    lla = np.array([(s.lat_rad, s.lon_rad, s.alt_msl_m) for s in states])
    v = np.array([s.v_ned_mps for s in states])
    q = np.array([s.q_nb for s in states])
    return lla, v, q
