"""fusion.rotations: round trips and a cross-check against scipy's Rotation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from fusion import rotations as rot


def random_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return rot.quat_normalize(q)


def to_scipy(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]])


def test_quat_to_dcm_matches_scipy() -> None:
    q = random_quats(100)
    np.testing.assert_allclose(rot.quat_to_dcm(q), to_scipy(q).as_matrix(), atol=1e-14)


def test_dcm_to_quat_round_trip_including_near_180_deg() -> None:
    q = random_quats(200)
    # add rotations of almost exactly pi, where a naive trace formula breaks down
    axes = np.random.default_rng(1).normal(size=(20, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    q = np.vstack([q, rot.rotvec_to_quat(axes * (math.pi - 1e-9))])
    np.testing.assert_allclose(
        rot.dcm_to_quat(rot.quat_to_dcm(q)), rot.quat_normalize(q), atol=1e-12
    )


def test_euler_is_the_321_sequence_of_scipy() -> None:
    rng = np.random.default_rng(2)
    e = np.column_stack(
        [rng.uniform(-3, 3, 100), rng.uniform(-1.5, 1.5, 100), rng.uniform(-3, 3, 100)]
    )
    ref = Rotation.from_euler("ZYX", e[:, ::-1])  # yaw, pitch, roll intrinsic
    np.testing.assert_allclose(rot.euler_to_dcm(e), ref.as_matrix(), atol=1e-14)
    np.testing.assert_allclose(rot.quat_to_dcm(rot.euler_to_quat(e)), ref.as_matrix(), atol=1e-14)
    np.testing.assert_allclose(rot.dcm_to_euler(rot.euler_to_dcm(e)), e, atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_euler(rot.euler_to_quat(e)), e, atol=1e-12)


def test_pure_yaw_and_level_flight_conventions() -> None:
    # 90 deg yaw: body forward points east
    c = rot.euler_to_dcm([0.0, 0.0, math.pi / 2])
    np.testing.assert_allclose(c @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    # positive pitch: nose up, body forward has a negative down component
    c = rot.euler_to_dcm([0.0, 0.2, 0.0])
    assert (c @ [1.0, 0.0, 0.0])[2] < 0.0
    # positive roll: right wing down
    c = rot.euler_to_dcm([0.2, 0.0, 0.0])
    assert (c @ [0.0, 1.0, 0.0])[2] > 0.0


def test_rotvec_matches_scipy_and_small_angles() -> None:
    rng = np.random.default_rng(3)
    r = rng.normal(size=(100, 3))
    r *= (rng.uniform(0.0, 3.1, 100) / np.linalg.norm(r, axis=1))[:, None]  # angles < pi
    r[50:] *= 1e-6
    q = rot.rotvec_to_quat(r)
    np.testing.assert_allclose(rot.quat_to_dcm(q), Rotation.from_rotvec(r).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), r, atol=1e-13)
    np.testing.assert_allclose(rot.dcm_to_rotvec(rot.rotvec_to_dcm(r)), r, atol=1e-12)
    np.testing.assert_allclose(rot.rotvec_to_quat(np.zeros(3)), [1.0, 0.0, 0.0, 0.0])


def test_hamilton_product_composes_like_matrices() -> None:
    p, q = random_quats(50, 4), random_quats(50, 5)
    np.testing.assert_allclose(
        rot.quat_to_dcm(rot.quat_multiply(p, q)),
        rot.quat_to_dcm(p) @ rot.quat_to_dcm(q),
        atol=1e-14,
    )
    ident = rot.quat_multiply(p, rot.quat_conjugate(p))
    np.testing.assert_allclose(ident, np.tile([1.0, 0.0, 0.0, 0.0], (50, 1)), atol=1e-15)


def test_skew_and_rotate() -> None:
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 4.0, -1.0])
    np.testing.assert_allclose(rot.skew(a) @ b, np.cross(a, b))
    q = random_quats(1, 6)[0]
    np.testing.assert_allclose(rot.quat_rotate(q, b), to_scipy(q).apply(b), atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-math.pi, math.pi),
    st.floats(-1.5, 1.5),
    st.floats(-math.pi, math.pi),
)
def test_euler_quaternion_round_trip_property(roll: float, pitch: float, yaw: float) -> None:
    e = np.array([roll, pitch, yaw])
    back = rot.quat_to_euler(rot.euler_to_quat(e))
    # compare as rotations (angles wrap at +-pi)
    np.testing.assert_allclose(rot.euler_to_dcm(back), rot.euler_to_dcm(e), atol=1e-12)


def test_normalize_gives_canonical_sign() -> None:
    q = rot.quat_normalize([-2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(q, [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        rot.dcm_to_quat(np.eye(2))


# --------------------------------------------------------------------------- scalar paths
def test_scalar_dcm_and_product_are_the_array_functions_bit_for_bit() -> None:
    # GIVEN random unit quaternions
    qs = random_quats(200, seed=3)
    for p, q in zip(qs, qs[::-1], strict=True):
        # THEN the scalar paths compute the same operations in the same order
        assert rot.dcm_from_quat(q.tolist()) == tuple(rot.quat_to_dcm(q).ravel().tolist())
        assert rot.quat_product(p.tolist(), q.tolist()) == tuple(
            rot.quat_multiply(p, q).tolist()
        )


def test_scalar_euler_matches_the_array_function() -> None:
    for q in random_quats(200, seed=4):
        np.testing.assert_allclose(rot.euler_from_quat(q.tolist()), rot.quat_to_euler(q),
                                   atol=1e-12)  # fmt: skip


def test_scalar_rotvec_quat_matches_the_array_function_on_both_branches() -> None:
    rng = np.random.default_rng(5)
    for scale in (1e-6, 1e-3, 0.5, 3.0):  # series (angle^2 < 1e-4) and closed form
        v = rng.normal(size=3) * scale
        np.testing.assert_allclose(rot.rotvec_quat(*v.tolist()), rot.rotvec_to_quat(v),
                                   rtol=0.0, atol=1e-15)  # fmt: skip


def test_wrap_pi_range_and_identity_inside() -> None:
    for a in np.linspace(-20.0, 20.0, 401).tolist():
        w = rot.wrap_pi(a)
        assert -math.pi <= w < math.pi
        assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-12)
        assert math.isclose(math.sin(w), math.sin(a), abs_tol=1e-12)
    assert rot.wrap_pi(0.25) == 0.25 and rot.wrap_pi(math.pi) == -math.pi
