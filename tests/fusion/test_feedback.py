"""fusion.feedback: error feedback into the nominal state and the covariance resets (pure)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth, strapdown
from fusion.feedback import (
    feedback,
    nav_corrections,
    reset_baro_bias,
    reset_block,
    reset_position_with_bias,
    sensor_inverses,
)
from fusion.nominal import initial_nominal
from fusion.rotations import quat_multiply, quat_normalize, rotvec_to_quat
from fusion.state_layout import INS16, INS16_GNSS, INS22, INS22_GNSS, StateLayout
from fusion.strapdown import InsState

INS = InsState(0.8, 0.2, 350.0, (40.0, -3.0, 1.5), tuple(quat_normalize([0.9, 0.1, -0.2, 0.3])))


def _random_dx(layout: StateLayout, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, 1e-3, layout.n)


@pytest.mark.parametrize("layout", [INS16, INS16_GNSS, INS22, INS22_GNSS])
def test_feedback_subtracts_every_error_and_rotates_the_attitude_back(layout: StateLayout) -> None:
    # GIVEN an error estimate over the whole layout and some sensor-error estimates
    dx = _random_dx(layout, 1)
    ba, bg, sa, sg = (0.01, -0.02, 0.03), (1e-5, 2e-5, -3e-5), (1e-4, 0.0, -1e-4), (0.0, 2e-4, 0.0)
    gb = (0.5, -0.4, 1.1)
    state = initial_nominal(INS, 7)._replace(
        accel_bias_b_mps2=ba, gyro_bias_b_rps=bg, baro_bias_m=2.5, gnss_bias_ned_m=gb,
        accel_scale_b=sa, gyro_scale_b=sg, baro_reference_alt_m=300.0,
    )
    fb = feedback(layout, state, dx)
    p, v, a = layout.POS, layout.VEL, layout.ATT
    # THEN position moves by -dr (metres to radians), velocity by -dv
    lt = earth.local_terms(INS.lat_rad, INS.alt_msl_m)
    assert fb.ins.lat_rad == pytest.approx(INS.lat_rad - dx[p] / lt.rho_n_m, rel=0, abs=1e-15)
    assert fb.ins.alt_msl_m == pytest.approx(INS.alt_msl_m + dx[p + 2], abs=1e-12)
    np.testing.assert_allclose(fb.ins.v_ned_mps, np.array(INS.v_ned_mps) - dx[v : v + 3],
                               atol=1e-12)  # fmt: skip
    # AND the attitude is q(-phi) ⊗ q, unit, with a non-negative scalar part
    want = quat_normalize(quat_multiply(rotvec_to_quat(-dx[a : a + 3]), INS.q_nb))
    np.testing.assert_allclose(fb.ins.q_nb, want, atol=1e-15)
    assert math.isclose(float(np.linalg.norm(fb.ins.q_nb)), 1.0, abs_tol=1e-15)
    # AND every sensor-error estimate loses its error
    np.testing.assert_allclose(fb.accel_bias_b_mps2, np.array(ba) - dx[layout.ba], atol=1e-15)
    np.testing.assert_allclose(fb.gyro_bias_b_rps, np.array(bg) - dx[layout.bg], atol=1e-15)
    assert fb.baro_bias_m == 2.5 - dx[layout.BARO]
    if layout.has_gnss_bias:
        np.testing.assert_allclose(fb.gnss_bias_ned_m, np.array(gb) - dx[layout.gnss])
    else:  # blocks the layout lacks pass through
        assert fb.gnss_bias_ned_m == gb
    if layout.has_scale_factors:
        np.testing.assert_allclose(fb.accel_scale_b, np.array(sa) - dx[layout.sa], atol=1e-15)
        np.testing.assert_allclose(fb.gyro_scale_b, np.array(sg) - dx[layout.sg], atol=1e-15)
    else:
        assert (fb.accel_scale_b, fb.gyro_scale_b) == (sa, sg)
    # AND what is not an estimate (reference height, GNSS-bias time) is kept
    assert (fb.baro_reference_alt_m, fb.gnss_bias_time_us) == (300.0, 7)
    # AND the 9 navigation corrections are handed on for the history
    d = dx.tolist()
    assert nav_corrections(layout, d) == [*d[p : p + 3], *d[v : v + 3], *d[a : a + 3]]


def test_feedback_of_zero_is_the_identity_up_to_normalisation() -> None:
    state = initial_nominal(INS, 0)._replace(accel_bias_b_mps2=(0.1, 0.2, 0.3), baro_bias_m=1.0)
    fb = feedback(INS16, state, np.zeros(16))
    assert fb.ins[:4] == INS[:4]
    np.testing.assert_allclose(fb.ins.q_nb, INS.q_nb, atol=1e-16)
    assert fb.accel_bias_b_mps2 == (0.1, 0.2, 0.3) and fb.baro_bias_m == 1.0
    assert fb[1:] == state[1:]


def _spd(n: int, seed: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def test_reset_block_sets_the_block_and_decorrelates_it() -> None:
    P = _spd(16, 2)
    before = P.copy()
    z = np.array([0.3, -0.2, 0.1])
    var = np.array([0.04, 0.05, 0.06])
    dx, Pn = reset_block(P, 16, INS16.vel, z, var)
    np.testing.assert_array_equal(P, before)  # input untouched
    np.testing.assert_array_equal(dx[INS16.vel], z)
    assert np.count_nonzero(dx) == 3
    np.testing.assert_array_equal(Pn[INS16.vel, INS16.vel], np.diag(var))
    other = np.r_[0:3, 6:16]
    assert not Pn[INS16.vel][:, other].any() and not Pn[other][:, INS16.vel].any()
    np.testing.assert_array_equal(Pn[np.ix_(other, other)], P[np.ix_(other, other)])


def test_position_reset_with_bias_takes_the_bias_back_to_its_prior() -> None:
    lay = INS16_GNSS
    P = _spd(lay.n, 3)
    z = np.array([5.0, -4.0, 2.0])  # holds + b^
    var = np.array([0.25, 0.25, 0.64])
    gb = (1.0, -0.5, 0.2)
    sb2 = np.array([1.96, 1.96, 5.76])
    dx, Pn = reset_position_with_bias(P, lay, z, var, gb, sb2)
    # THEN the INS moves onto the fix (z - b^) and the bias estimate goes to zero (b^ - b^)
    np.testing.assert_array_equal(dx[lay.pos], z - np.array(gb))
    np.testing.assert_array_equal(dx[lay.gnss], gb)
    # AND the covariance is [[sb^2 + r, -sb^2], [-sb^2, sb^2]] on the two blocks, zero elsewhere
    np.testing.assert_array_equal(Pn[lay.pos, lay.pos], np.diag(var + sb2))
    np.testing.assert_array_equal(Pn[lay.gnss, lay.gnss], np.diag(sb2))
    np.testing.assert_array_equal(Pn[lay.pos, lay.gnss], -np.diag(sb2))
    np.testing.assert_array_equal(Pn, Pn.T)
    assert not Pn[lay.pos, 3:16].any()
    assert np.all(np.linalg.eigvalsh(Pn[np.r_[0:3, 16:19]][:, np.r_[0:3, 16:19]]) > 0.0)


def test_baro_bias_reset_copies_the_down_position_row() -> None:
    lay = INS16
    P = _spd(lay.n, 4)
    Pn = reset_baro_bias(P, lay, 0.5)
    d, b = lay.POS + 2, lay.BARO
    row = P[d].copy()
    row[b] = P[d, d] + 0.25
    np.testing.assert_array_equal(Pn[b], row)
    np.testing.assert_array_equal(Pn[:, b], row)
    np.testing.assert_array_equal(Pn[:b, :b], P[:b, :b])


def test_sensor_inverses_are_two_sensor_inverse_calls_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    bits = np.int64
    for k in range(300):
        scale = rng.normal(0.0, 10.0 ** rng.uniform(-6, -1), size=6)
        mis = rng.normal(0.0, 10.0 ** rng.uniform(-6, -1), size=12)
        if k % 10 == 0:  # exact zeros (and a negative zero) as the first feedback has
            scale[:3] = 0.0
            mis[:6] = -0.0
        sa, sg = tuple(scale[:3].tolist()), tuple(scale[3:].tolist())
        ma, mg = tuple(mis[:6].tolist()), tuple(mis[6:].tolist())
        inv_a, inv_g = sensor_inverses(sa, ma, sg, mg)
        for got, want in ((inv_a, strapdown.sensor_inverse(sa, ma)),
                          (inv_g, strapdown.sensor_inverse(sg, mg))):  # fmt: skip
            np.testing.assert_array_equal(np.array(got).view(bits), np.array(want).view(bits))
