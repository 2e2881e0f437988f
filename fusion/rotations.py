"""Rotations: Hamilton quaternions (scalar first), direction cosine matrices, Euler angles,
rotation vectors.

Conventions (see :mod:`fusion`): ``q_nb`` / ``C_nb`` map body FRD vectors to NED,
``v_n = C_nb @ v_b``; Euler angles are ``(roll, pitch, yaw)`` of the 3-2-1 sequence, so
``C_nb = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Quaternion products are Hamilton's:
``q_ac = q_ab ⊗ q_bc``.

The array functions broadcast over leading dimensions: a quaternion argument may be ``(4,)``
or ``(N, 4)``, a vector ``(3,)`` or ``(N, 3)``, a matrix ``(3, 3)`` or ``(N, 3, 3)``.

The scalar functions at the end (:func:`dcm_from_quat`, :func:`euler_from_quat`,
:func:`quat_product`, :func:`rotvec_quat`, :func:`wrap_pi`) work on plain floats and tuples:
numpy's per-call overhead dominates on one quaternion, and the filter's per-sample loops use
these (one definition each, used everywhere in :mod:`fusion`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
Quat = tuple[float, float, float, float]


def _as(a: ArrayLike, tail: tuple[int, ...], name: str) -> FloatArray:
    """Float array whose trailing dimensions are ``tail`` (ValueError naming ``name`` if not)."""
    arr = np.asarray(a, dtype=float)
    if arr.shape[arr.ndim - len(tail) :] != tail or arr.ndim < len(tail):
        raise ValueError(
            f"{name} must have shape (..., {', '.join(map(str, tail))}), got {arr.shape}"
        )
    return arr


def skew(v: ArrayLike) -> FloatArray:
    """Cross-product matrix: ``skew(a) @ b == cross(a, b)``.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    v = _as(v, (3,), "v")
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def quat_multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Hamilton product ``p ⊗ q`` (scalar first).

    Parameters
    ----------
    p, q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    p = _as(p, (4,), "p")
    q = _as(q, (4,), "q")
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate (the inverse of a unit quaternion), shape (..., 4)."""
    arr = _as(q, (4,), "q")
    return arr * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: ArrayLike) -> FloatArray:
    """Unit quaternion with a non-negative scalar part (the canonical sign), shape (..., 4)."""
    arr = _as(q, (4,), "q")
    arr = arr / np.linalg.norm(arr, axis=-1, keepdims=True)
    return np.where(arr[..., :1] < 0.0, -arr, arr)


def quat_to_dcm(q: ArrayLike) -> FloatArray:
    """Direction cosine matrix of a unit quaternion: ``quat_to_dcm(q_nb) = C_nb``.

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = _as(q, (4,), "q")
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = w * w + x * x - y * y - z * z
    out[..., 0, 1] = 2.0 * (x * y - w * z)
    out[..., 0, 2] = 2.0 * (x * z + w * y)
    out[..., 1, 0] = 2.0 * (x * y + w * z)
    out[..., 1, 1] = w * w - x * x + y * y - z * z
    out[..., 1, 2] = 2.0 * (y * z - w * x)
    out[..., 2, 0] = 2.0 * (x * z - w * y)
    out[..., 2, 1] = 2.0 * (y * z + w * x)
    out[..., 2, 2] = w * w - x * x - y * y + z * z
    return out


def dcm_to_quat(dcm: ArrayLike) -> FloatArray:
    """Unit quaternion (scalar part >= 0) of a rotation matrix, Shepperd's method.

    Parameters
    ----------
    dcm : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    c = _as(dcm, (3, 3), "dcm")
    tr = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    # Pick the largest of 4w^2, 4x^2, 4y^2, 4z^2 to divide by: no cancellation anywhere.
    cand = np.stack([tr, c[..., 0, 0], c[..., 1, 1], c[..., 2, 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty((*c.shape[:-2], 4))
    w_case = 1.0 + tr
    x_case = 1.0 + c[..., 0, 0] - c[..., 1, 1] - c[..., 2, 2]
    y_case = 1.0 - c[..., 0, 0] + c[..., 1, 1] - c[..., 2, 2]
    z_case = 1.0 - c[..., 0, 0] - c[..., 1, 1] + c[..., 2, 2]
    q0 = np.stack(
        [
            w_case,
            c[..., 2, 1] - c[..., 1, 2],
            c[..., 0, 2] - c[..., 2, 0],
            c[..., 1, 0] - c[..., 0, 1],
        ],
        axis=-1,
    )
    q1 = np.stack(
        [
            c[..., 2, 1] - c[..., 1, 2],
            x_case,
            c[..., 0, 1] + c[..., 1, 0],
            c[..., 0, 2] + c[..., 2, 0],
        ],
        axis=-1,
    )
    q2 = np.stack(
        [
            c[..., 0, 2] - c[..., 2, 0],
            c[..., 0, 1] + c[..., 1, 0],
            y_case,
            c[..., 1, 2] + c[..., 2, 1],
        ],
        axis=-1,
    )
    q3 = np.stack(
        [
            c[..., 1, 0] - c[..., 0, 1],
            c[..., 0, 2] + c[..., 2, 0],
            c[..., 1, 2] + c[..., 2, 1],
            z_case,
        ],
        axis=-1,
    )
    q = np.where(
        (k == 0)[..., None],
        q0,
        np.where((k == 1)[..., None], q1, np.where((k == 2)[..., None], q2, q3)),
    )
    return quat_normalize(q)


def euler_to_dcm(euler_rad: ArrayLike) -> FloatArray:
    """``C_nb = Rz(yaw) Ry(pitch) Rx(roll)`` from ``(roll, pitch, yaw)``, rad.

    Parameters
    ----------
    euler_rad : array_like, shape (..., 3)
        Roll, pitch, yaw (3-2-1 sequence), rad.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    e = _as(euler_rad, (3,), "euler_rad")
    sr, cr = np.sin(e[..., 0]), np.cos(e[..., 0])
    sp, cp = np.sin(e[..., 1]), np.cos(e[..., 1])
    sy, cy = np.sin(e[..., 2]), np.cos(e[..., 2])
    out = np.empty((*e.shape[:-1], 3, 3))
    out[..., 0, 0] = cp * cy
    out[..., 0, 1] = sr * sp * cy - cr * sy
    out[..., 0, 2] = cr * sp * cy + sr * sy
    out[..., 1, 0] = cp * sy
    out[..., 1, 1] = sr * sp * sy + cr * cy
    out[..., 1, 2] = cr * sp * sy - sr * cy
    out[..., 2, 0] = -sp
    out[..., 2, 1] = sr * cp
    out[..., 2, 2] = cr * cp
    return out


def dcm_to_euler(dcm: ArrayLike) -> FloatArray:
    """``(roll, pitch, yaw)`` of ``C_nb``, rad; yaw in (-pi, pi], pitch in [-pi/2, pi/2].

    Parameters
    ----------
    dcm : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    c = _as(dcm, (3, 3), "dcm")
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = np.arcsin(np.clip(-c[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_to_quat(euler_rad: ArrayLike) -> FloatArray:
    """``q_nb`` from ``(roll, pitch, yaw)``, rad; shape (..., 3) -> (..., 4)."""
    e = _as(euler_rad, (3,), "euler_rad")
    hr, hp, hy = 0.5 * e[..., 0], 0.5 * e[..., 1], 0.5 * e[..., 2]
    sr, cr = np.sin(hr), np.cos(hr)
    sp, cp = np.sin(hp), np.cos(hp)
    sy, cy = np.sin(hy), np.cos(hy)
    q = np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_to_euler(q: ArrayLike) -> FloatArray:
    """``(roll, pitch, yaw)`` of ``q_nb``, rad; shape (..., 4) -> (..., 3)."""
    return dcm_to_euler(quat_to_dcm(q))


def rotvec_to_quat(rotvec: ArrayLike) -> FloatArray:
    """Quaternion of a rotation vector (axis times angle, rad); exact, series near zero.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    r = _as(rotvec, (3,), "rotvec")
    angle2 = np.sum(r * r, axis=-1)
    angle = np.sqrt(angle2)
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    # sin(a/2)/a by its Taylor series for small angles (error < 1e-18 below 1e-4 rad).
    k = np.where(small, 0.5 - angle2 / 48.0, np.sin(0.5 * safe) / safe)
    w = np.where(small, 1.0 - angle2 / 8.0, np.cos(0.5 * angle))
    return np.concatenate([w[..., None], k[..., None] * r], axis=-1)


def quat_to_rotvec(q: ArrayLike) -> FloatArray:
    """Rotation vector (rad) of a unit quaternion, angle in [0, pi]; shape (..., 4) -> (..., 3)."""
    q = _as(q, (4,), "q")
    q = np.where(q[..., :1] < 0.0, -q, q)
    vec_norm = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(vec_norm, q[..., 0])
    small = vec_norm < 1e-9
    k = np.where(
        small, 2.0 / np.where(small, q[..., 0], 1.0), angle / np.where(small, 1.0, vec_norm)
    )
    return k[..., None] * q[..., 1:]


def rotvec_to_dcm(rotvec: ArrayLike) -> FloatArray:
    """Rotation matrix of a rotation vector (Rodrigues), shape (..., 3) -> (..., 3, 3)."""
    return quat_to_dcm(rotvec_to_quat(rotvec))


def dcm_to_rotvec(dcm: ArrayLike) -> FloatArray:
    """Rotation vector of a rotation matrix, shape (..., 3, 3) -> (..., 3)."""
    return quat_to_rotvec(dcm_to_quat(dcm))


def quat_rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """Rotate vectors: ``quat_rotate(q_nb, v_b) = C_nb @ v_b``; shapes (..., 4), (..., 3)."""
    c = quat_to_dcm(q)
    return np.einsum("...ij,...j->...i", c, np.asarray(v, dtype=float))


# ---------------------------------------------------------------------------------------------
# Scalar paths (plain floats)
# ---------------------------------------------------------------------------------------------


def dcm_from_quat(q: Sequence[float]) -> tuple[float, ...]:
    """``C_nb`` of ``q_nb`` as 9 floats, row-major (scalar path of :func:`quat_to_dcm`).

    Parameters
    ----------
    q : sequence of 4 floats
        Unit quaternion, scalar first.

    Returns
    -------
    tuple of 9 floats
    """
    qw, qx, qy, qz = q
    ww, xx, yy, zz = qw * qw, qx * qx, qy * qy, qz * qz
    return (
        ww + xx - yy - zz, 2.0 * (qx * qy - qw * qz), 2.0 * (qx * qz + qw * qy),
        2.0 * (qx * qy + qw * qz), ww - xx + yy - zz, 2.0 * (qy * qz - qw * qx),
        2.0 * (qx * qz - qw * qy), 2.0 * (qy * qz + qw * qx), ww - xx - yy + zz,
    )  # fmt: skip


def euler_from_quat(q: Sequence[float]) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of a unit quaternion (scalar path of :func:`quat_to_euler`).

    Parameters
    ----------
    q : sequence of 4 floats
        ``q_nb``, scalar first.

    Returns
    -------
    (float, float, float)
        Roll, pitch, yaw of the 3-2-1 sequence, rad.
    """
    qw, qx, qy, qz = q
    roll = math.atan2(2.0 * (qy * qz + qw * qx), qw * qw - qx * qx - qy * qy + qz * qz)
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (qw * qy - qx * qz))))
    yaw = math.atan2(2.0 * (qx * qy + qw * qz), qw * qw + qx * qx - qy * qy - qz * qz)
    return roll, pitch, yaw


def quat_product(p: Sequence[float], q: Sequence[float]) -> Quat:
    """Hamilton product ``p ⊗ q`` of two quaternions (scalar path of :func:`quat_multiply`).

    Parameters
    ----------
    p, q : sequence of 4 floats
        Scalar first.

    Returns
    -------
    tuple of 4 floats
        Not normalised.
    """
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def rotvec_quat(x: float, y: float, z: float) -> Quat:
    """Quaternion of a rotation vector (rad); a Taylor series for the usual tiny per-sample
    angles (scalar counterpart of :func:`rotvec_to_quat`, whose series differs in the last
    bits).

    Parameters
    ----------
    x, y, z : float
        Rotation vector (axis times angle), rad.

    Returns
    -------
    tuple of 4 floats
        Unit quaternion, scalar first.
    """
    a2 = x * x + y * y + z * z
    if a2 < 1e-4:
        # error of the truncated series < a^6 / 46080 < 3e-17 for a < 1e-2
        w = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        k = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        a = math.sqrt(a2)
        w = math.cos(0.5 * a)
        k = math.sin(0.5 * a) / a
    return (w, k * x, k * y, k * z)


def wrap_pi(angle_rad: float) -> float:
    """Angle wrapped to [-pi, pi), rad."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi
