"""Kalman filter steps: prediction and Joseph-form correction with a chi-square gate.

Pure functions on arrays; the error-state bookkeeping lives in :mod:`fusion.filter` and
:mod:`fusion.feedback`.
Observation model: ``z = H x + v``, ``v ~ N(0, R)``. In the error-state filter ``z`` is
"INS-predicted minus measured" and ``x`` the error estimate (zero after every feedback).
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

FloatArray = NDArray[np.float64]
_dot = np.dot
_add = np.add


class Correction(NamedTuple):
    """Result of :func:`correct`."""

    x: FloatArray
    """(n,) corrected state (the input state when the gate rejected the observation)."""
    P: FloatArray
    """(n, n) corrected covariance (the input covariance when rejected)."""
    innovation: FloatArray
    """(m,) innovation ``y = z - H x``."""
    S: FloatArray
    """(m, m) innovation covariance ``H P H^T + R``."""
    test_ratio: float
    """``y^T S^-1 y / gate`` (normalised innovation squared over the gate); > 1 = rejected.
    With no gate it is the plain NIS divided by the observation dimension."""


@lru_cache(maxsize=64)
def chi2_gate(dof: int, probability: float) -> float:
    """Chi-square quantile: the NIS threshold exceeded with ``1 - probability`` by a consistent
    filter (``chi2_gate(3, 0.999) = 16.27``).

    Parameters
    ----------
    dof : int
        Observation dimension.
    probability : float
        Acceptance probability in (0, 1).
    """
    if dof < 1:
        raise ValueError(f"dof must be >= 1, got {dof}")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability must be in (0, 1), got {probability}")
    return float(chdtri(dof, 1.0 - probability))


def predict(
    x: FloatArray, P: FloatArray, Phi: FloatArray, Q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Time update.

    Parameters
    ----------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    Phi : ndarray, shape (n, n)
        Transition matrix over the interval.
    Q : ndarray, shape (n, n)
        Discrete process noise over the interval.

    Returns
    -------
    x, P : ndarray
        New arrays (inputs untouched).
    """
    # x = Phi x
    x_new = Phi @ x
    # P = Phi P Phi^T + Q
    P_new = Phi @ P @ Phi.T + Q
    return x_new, P_new


def correct(
    x: FloatArray,
    P: FloatArray,
    z: FloatArray,
    H: FloatArray,
    R: FloatArray,
    gate: float | None = None,
) -> Correction:
    """Measurement update in Joseph form, optionally gated on the normalised innovation.

    Parameters
    ----------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    z : ndarray, shape (m,)
        Observation.
    H : ndarray, shape (m, n)
    R : ndarray, shape (m, m)
    gate : float, optional
        Chi-square threshold on ``y^T S^-1 y`` (e.g. :func:`chi2_gate`); when exceeded the
        observation is not applied and the returned ``test_ratio`` is > 1.

    Returns
    -------
    Correction
        New arrays; inputs are not modified.
    """
    # (np.dot: the same BLAS calls as @ with less dispatch overhead on these small arrays)
    # y = z - H x
    y = z - _dot(H, x)
    PHt = _dot(P, H.T)
    # S = H P H^T + R
    S = _dot(H, PHt) + R
    # S^-1 and the NIS y^T S^-1 y on plain floats: for m <= 3 this is several times cheaper
    # than numpy/LAPACK calls on 3x3 arrays
    s_inv, nis = _inverse_and_nis(S.tolist(), y.tolist())
    test_ratio = nis / gate if gate is not None else nis / len(y)
    if gate is not None and test_ratio > 1.0:
        return Correction(x, P, y, S, test_ratio)
    # K = P H^T S^-1
    K = _dot(PHt, np.array(s_inv)) if len(s_inv) > 1 else PHt * s_inv[0][0]
    # x = x + K y
    x_new = x + _dot(K, y)
    # P = (I - K H) P (I - K H)^T + K R K^T   (Joseph form: stays symmetric positive definite)
    A = _eye(len(x)) - _dot(K, H)
    P_new = _dot(_dot(A, P), A.T)
    P_new += _dot(_dot(K, R), K.T)
    # remove the rounding asymmetry so it cannot accumulate over thousands of updates:
    # P = (P + P^T) / 2, each entry P_ij + P_ji in that operand order (as an in-place
    # ``P += P.T`` computes it); the transpose copied first (one fast C-order copy) instead of
    # the strided overlapping read numpy buffers for ``P += P.T``: same bits, C-contiguous
    P_sym = P_new.T.copy()
    _add(P_new, P_sym, out=P_sym)
    P_sym *= 0.5
    return Correction(x_new, P_sym, y, S, test_ratio)


def _inverse_and_nis(s: list[list[float]], y: list[float]) -> tuple[list[list[float]], float]:
    """Inverse of a small symmetric positive-definite matrix (given as lists) and y^T S^-1 y."""
    m = len(y)
    if m == 1:
        inv = 1.0 / s[0][0]
        return [[inv]], y[0] * y[0] * inv
    if m == 2:
        a, b, d = s[0][0], 0.5 * (s[0][1] + s[1][0]), s[1][1]
        det = a * d - b * b
        inv2 = [[d / det, -b / det], [-b / det, a / det]]
    elif m == 3:
        # symmetric part, then the adjugate
        a, b, c = s[0][0], 0.5 * (s[0][1] + s[1][0]), 0.5 * (s[0][2] + s[2][0])
        d, e, f = s[1][1], 0.5 * (s[1][2] + s[2][1]), s[2][2]
        c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
        det = a * c00 + b * c01 + c * c02
        c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
        inv2 = [
            [c00 / det, c01 / det, c02 / det],
            [c01 / det, c11 / det, c12 / det],
            [c02 / det, c12 / det, c22 / det],
        ]
    else:
        arr = np.asarray(s)
        inv2 = np.linalg.inv(0.5 * (arr + arr.T)).tolist()
    nis = sum(y[i] * inv2[i][j] * y[j] for i in range(m) for j in range(m))
    return inv2, nis


@lru_cache(maxsize=8)
def _eye(n: int) -> FloatArray:
    eye = np.eye(n)
    eye.flags.writeable = False
    return eye
