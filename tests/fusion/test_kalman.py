"""fusion.kalman: Joseph-form correction, gating, prediction; cross-checked with filterpy."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from fusion import kalman


def random_problem(m: int, n: int = 16, seed: int = 0):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    P = a @ a.T + n * np.eye(n)
    H = rng.normal(size=(m, n))
    r = rng.normal(size=(m, m))
    R = r @ r.T + np.eye(m)
    x = rng.normal(size=n)
    z = H @ x + rng.normal(size=m)
    return x, P, z, H, R


@pytest.mark.parametrize("m", [1, 2, 3, 6])
def test_correct_matches_filterpy_joseph_update(m: int) -> None:
    x, P, z, H, R = random_problem(m, seed=m)
    kf = KalmanFilter(dim_x=len(x), dim_z=m)
    kf.x, kf.P, kf.H, kf.R = x.copy(), P.copy(), H, R
    kf.update(z)
    res = kalman.correct(x, P, z, H, R)
    np.testing.assert_allclose(res.x, kf.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(res.P, kf.P, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(res.innovation, z - H @ x)
    np.testing.assert_allclose(res.S, H @ P @ H.T + R, rtol=1e-12)
    nis = (z - H @ x) @ np.linalg.solve(H @ P @ H.T + R, z - H @ x)
    assert res.test_ratio == pytest.approx(nis / m)


def test_correct_keeps_covariance_symmetric_positive_definite() -> None:
    x, P, z, H, R = random_problem(3)
    for k in range(200):  # many updates with a tiny R: the textbook form loses symmetry here
        res = kalman.correct(x, P, z, H, 1e-6 * R)
        x, P = res.x, res.P
        H = np.roll(H, k % 5, axis=1)
    np.testing.assert_array_equal(P, P.T)
    assert np.all(np.linalg.eigvalsh(P) > 0.0)


def test_gate_rejects_and_leaves_state_untouched() -> None:
    x, P, _, H, R = random_problem(3, seed=7)
    S = H @ P @ H.T + R
    gate = kalman.chi2_gate(3, 0.999)
    # an innovation with NIS exactly 2 x gate
    direction = np.linalg.cholesky(S) @ np.array([1.0, 0.0, 0.0])
    z = H @ x + direction * np.sqrt(2.0 * gate)
    res = kalman.correct(x, P, z, H, R, gate)
    assert res.test_ratio == pytest.approx(2.0)
    assert res.x is x and res.P is P
    ok = kalman.correct(x, P, H @ x + 0.1 * direction, H, R, gate)
    assert ok.test_ratio < 1.0 and not np.allclose(ok.x, x)


def test_chi2_gate_values_and_validation() -> None:
    assert kalman.chi2_gate(1, 0.95) == pytest.approx(3.841, abs=1e-3)
    assert kalman.chi2_gate(3, 0.999) == pytest.approx(16.266, abs=1e-3)
    with pytest.raises(ValueError, match="probability"):
        kalman.chi2_gate(3, 1.0)
    with pytest.raises(ValueError, match="dof"):
        kalman.chi2_gate(0, 0.9)


def test_predict_matches_textbook() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=4)
    P = np.eye(4)
    Phi = np.eye(4) + 0.1 * rng.normal(size=(4, 4))
    Q = 0.01 * np.eye(4)
    x2, P2 = kalman.predict(x, P, Phi, Q)
    np.testing.assert_allclose(x2, Phi @ x)
    np.testing.assert_allclose(P2, Phi @ P @ Phi.T + Q)


@pytest.mark.parametrize("m", [1, 3])
def test_correct_symmetrises_as_p_plus_p_transposed_over_two_bit_for_bit(m: int) -> None:
    # the documented step, written out: P = (A P A^T + K R K^T); P += P^T; P *= 0.5 (an
    # in-place add reads the transpose as it was); correct() must give the same bits
    x, P, z, H, R = random_problem(m, n=43, seed=11 + m)
    res = kalman.correct(x, P, z, H, R)
    PHt = P @ H.T
    K = PHt @ np.linalg.inv(H @ PHt + R)
    A = np.eye(len(x)) - np.dot(K, H)
    joseph = np.dot(np.dot(A, P), A.T) + np.dot(np.dot(K, R), K.T)
    expected = np.empty_like(joseph)
    for i in range(len(x)):
        for j in range(len(x)):
            expected[i, j] = (joseph[i, j] + joseph[j, i]) * 0.5
    if m == 1:  # the K of correct() for m = 1 is PHt * (1 / S): the same bits only there
        np.testing.assert_array_equal(res.P.view(np.int64), expected.view(np.int64))
    np.testing.assert_array_equal(res.P, res.P.T)
    assert res.P.flags.c_contiguous
