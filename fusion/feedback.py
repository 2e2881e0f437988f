"""Error feedback and resets of the error-state filter, as pure functions.

After each accepted measurement update the error estimate ``dx`` (estimated minus true,
:mod:`fusion.error_model`) is moved into the nominal state at once and the error state is zero
again (closed loop): position, velocity and the sensor-error estimates are corrected by
subtraction, attitude by ``q_nb <- q(-phi) ⊗ q_nb`` (:func:`feedback`). A reset sets a block of
the state to a measurement instead (``dx = z`` on that block) and decorrelates it in ``P``
(:func:`reset_block`, :func:`reset_position_with_bias`, :func:`reset_baro_bias`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.nominal import NominalState
from fusion.rotations import quat_product, rotvec_quat
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState, sensor_matrix

FloatArray = NDArray[np.float64]
Vec3 = tuple[float, float, float]
_tuple_new = tuple.__new__  # NamedTuple(...) without its Python-level __new__ frame
_inv = np.linalg.inv


def feedback(layout: StateLayout, state: NominalState, dx: FloatArray) -> NominalState:
    """Move the error estimate ``dx`` into the nominal state (subtract: errors are estimated
    minus true).

    Parameters
    ----------
    layout : StateLayout
    state : NominalState
        The nominal state the error refers to; its GNSS bias estimate must refer to the same
        time (layouts with the GNSS bias block).
    dx : ndarray, shape (n,)
        Error estimate in ``layout``.

    Returns
    -------
    NominalState
        The corrected state. Blocks ``layout`` does not have (scale factors, misalignments,
        baro scale, GNSS bias) are passed through unchanged.
    """
    d = dx.tolist()
    p, v, a = layout.POS, layout.VEL, layout.ATT
    ins = state.ins
    lt = earth.local_terms(ins.lat_rad, ins.alt_msl_m)
    vn, ve, vd = ins.v_ned_mps
    # q <- q(-phi) ⊗ q
    rw, rx, ry, rz = quat_product(rotvec_quat(-d[a], -d[a + 1], -d[a + 2]), ins.q_nb)
    norm = math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    if rw < 0.0:
        norm = -norm
    new = InsState(
        ins.lat_rad - d[p] / lt.rho_n_m,
        ins.lon_rad - d[p + 1] / (lt.rho_e_m * lt.cos_lat),
        ins.alt_msl_m + d[p + 2],
        (vn - d[v], ve - d[v + 1], vd - d[v + 2]),
        (rw / norm, rx / norm, ry / norm, rz / norm),
    )
    ba, bg, b, g = state.accel_bias_b_mps2, state.gyro_bias_b_rps, layout.BA, layout.BG
    new_ba = (ba[0] - d[b], ba[1] - d[b + 1], ba[2] - d[b + 2])
    new_bg = (bg[0] - d[g], bg[1] - d[g + 1], bg[2] - d[g + 2])
    gb = state.gnss_bias_ned_m
    if layout.has_gnss_bias:
        g = layout.GNSS
        gb = (gb[0] - d[g], gb[1] - d[g + 1], gb[2] - d[g + 2])
    sa, sg = state.accel_scale_b, state.gyro_scale_b
    if layout.has_scale_factors:
        b = layout.SA
        sa = (sa[0] - d[b], sa[1] - d[b + 1], sa[2] - d[b + 2])
        b = layout.SG
        sg = (sg[0] - d[b], sg[1] - d[b + 1], sg[2] - d[b + 2])
    ma, mg = state.accel_misalignment_b, state.gyro_misalignment_b
    if layout.has_misalignment:
        # element by element (no generator: this runs at every accepted update)
        b = layout.MA
        ma = (ma[0] - d[b], ma[1] - d[b + 1], ma[2] - d[b + 2], ma[3] - d[b + 3],
              ma[4] - d[b + 4], ma[5] - d[b + 5])  # fmt: skip
        b = layout.MG
        mg = (mg[0] - d[b], mg[1] - d[b + 1], mg[2] - d[b + 2], mg[3] - d[b + 3],
              mg[4] - d[b + 4], mg[5] - d[b + 5])  # fmt: skip
    bs = state.baro_scale
    if layout.has_baro_scale:
        bs -= d[layout.BS]
    # this runs at every accepted update: the tuple directly, not NominalState(...)
    return _tuple_new(NominalState, (
        new, new_ba, new_bg, sa, sg, ma, mg, state.baro_bias_m - d[layout.BARO], bs,
        state.baro_reference_alt_m, gb, state.gnss_bias_time_us,
    ))  # fmt: skip


def nav_corrections(layout: StateLayout, dx: list[float]) -> list[float]:
    """The 9 position (m NED), velocity (m/s NED) and attitude (rad) corrections that
    :func:`feedback` subtracts from the INS (:meth:`fusion.history.InsHistory.add_correction`).

    Parameters
    ----------
    layout : StateLayout
    dx : list of n floats
        The error estimate fed back (``ndarray.tolist()``).

    Returns
    -------
    list of 9 floats
    """
    p, v, a = layout.POS, layout.VEL, layout.ATT
    return dx[p : p + 3] + dx[v : v + 3] + dx[a : a + 3]


def sensor_inverses(
    accel_scale_b: Sequence[float], accel_misalignment_b: Sequence[float],
    gyro_scale_b: Sequence[float], gyro_misalignment_b: Sequence[float],
) -> tuple[tuple[float, ...], tuple[float, ...]]:  # fmt: skip
    """Both sensor-model inverses after a feedback: :func:`fusion.strapdown.sensor_inverse`
    of the accelerometer and of the gyro (each ``(I + diag(s) + M)^-1`` row-major) in one
    ``np.linalg.inv`` call on the stack of the two matrices.

    The same bits as two calls: numpy's ``inv`` gufunc copies each matrix of a stack into
    its own buffer and solves it by its own LAPACK ``gesv`` call whatever the stack's length,
    so a stack of two only halves the Python and dispatch overhead (two per accepted update,
    misalignment layouts). ``tests/fusion/test_feedback.py`` checks the bits against
    :func:`fusion.strapdown.sensor_inverse`.

    Returns
    -------
    accel_inverse, gyro_inverse : 9 floats each
    """
    t = np.array([
        sensor_matrix(accel_scale_b, accel_misalignment_b),
        sensor_matrix(gyro_scale_b, gyro_misalignment_b),
    ])  # fmt: skip
    inv_a, inv_g = _inv(t).reshape(2, 9).tolist()
    return tuple(inv_a), tuple(inv_g)


def reset_block(
    P: FloatArray, n: int, block: slice, z: FloatArray, variances: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Reset one block of the state to a measurement.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Covariance before the reset (not modified).
    n : int
        State dimension.
    block : slice
        The block (e.g. ``layout.vel``).
    z : ndarray
        The measurement innovation on that block (INS minus measurement).
    variances : ndarray
        The measurement's variances: the block's new (uncorrelated) variances.

    Returns
    -------
    dx : ndarray, shape (n,)
        The error estimate to feed back (``z`` on the block, zero elsewhere).
    P : ndarray, shape (n, n)
        The covariance with the block decorrelated from the rest.
    """
    dx = np.zeros(n)
    dx[block] = z
    P = P.copy()
    P[block, :] = 0.0
    P[:, block] = 0.0
    P[block, block] = np.diag(variances)
    return dx, P


def reset_position_with_bias(
    P: FloatArray,
    layout: StateLayout,
    z: FloatArray,
    variances: FloatArray,
    gnss_bias_ned_m: Sequence[float],
    bias_variances: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Reset the position to a GNSS fix in a layout with the GNSS bias block.

    The bias also goes back to its prior (estimate 0, sigma_b): the INS position becomes the
    fix itself, whose error is bias plus white noise, ``dr = -db + w``, hence the covariance
    ``[[sb^2 + r, -sb^2], [-sb^2, sb^2]]``.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Covariance before the reset (not modified).
    layout : StateLayout
        A layout with the GNSS bias block.
    z : ndarray, shape (3,)
        The position innovation, which holds ``+ b^`` (INS minus fix plus the bias estimate).
    variances : ndarray, shape (3,)
        The fix's white variances.
    gnss_bias_ned_m : 3 floats
        The bias estimate ``b^`` at the current time, m NED.
    bias_variances : ndarray, shape (3,)
        The bias prior ``sb^2`` (N, E, D), m^2.

    Returns
    -------
    dx : ndarray, shape (n,)
        The error estimate to feed back.
    P : ndarray, shape (n, n)
    """
    gb = np.array(gnss_bias_ned_m)
    dx = np.zeros(layout.n)
    dx[layout.pos] = z - gb  # z holds + b^: the INS moves onto the fix, not onto fix - b^
    dx[layout.gnss] = gb  # b^ <- b^ - dx = 0
    sb2 = bias_variances
    P = P.copy()
    for blk in (layout.pos, layout.gnss):
        P[blk, :] = 0.0
        P[:, blk] = 0.0
    P[layout.pos, layout.pos] = np.diag(variances + sb2)
    P[layout.gnss, layout.gnss] = np.diag(sb2)
    P[layout.pos, layout.gnss] = P[layout.gnss, layout.pos] = -np.diag(sb2)
    return dx, P


def reset_baro_bias(P: FloatArray, layout: StateLayout, noise_m: float) -> FloatArray:
    """Covariance after the baro bias is set from a sample (``b^ = h_baro - h^``).

    The bias error is then ``dr_D + noise``, so its covariance row is that of the
    down-position error plus the baro noise on the diagonal.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Covariance before (not modified).
    layout : StateLayout
    noise_m : float
        Baro noise sigma, m.

    Returns
    -------
    ndarray, shape (n, n)
    """
    d, b = layout.POS + 2, layout.BARO
    P = P.copy()
    row = P[d, :].copy()
    row[b] = P[d, d] + noise_m**2
    P[b, :] = row
    P[:, b] = row
    return P
