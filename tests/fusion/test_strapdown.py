"""fusion.strapdown: physics invariants and reproduction of analytic trajectories from an
ideal IMU (fusion.trajectory)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth, strapdown
from fusion.rotations import (
    dcm_to_rotvec,
    euler_to_quat,
    quat_multiply,
    quat_to_dcm,
    rotvec_to_quat,
)
from fusion.trajectory import (
    SplineTrajectory,
    ideal_imu_from_truth,
    ideal_increments,
    spline_from_truth,
)
from sim.samples import ImuSample, Truth
from tests.helpers.nav_synth import Flight


def stationary_increments(lat: float, h: float, q_nb: np.ndarray, dt: float, n: int):
    """A perfect IMU at rest on the rotating Earth: constant in body axes."""
    c_bn = quat_to_dcm(q_nb).T
    f_b = c_bn @ np.array([0.0, 0.0, -earth.gravity(lat, h)])
    w_b = c_bn @ earth.earth_rate_n(lat)
    return np.tile(w_b * dt, (n, 1)), np.tile(f_b * dt, (n, 1))


def errors_vs(traj: SplineTrajectory, times: np.ndarray, states: list[strapdown.InsState]):
    lla, v, q = strapdown.states_to_arrays(states)
    kin = traj(times)
    pos = np.array([earth.ned_offset_m(*a, *b) for a, b in zip(lla, kin.lla, strict=True)])
    att = dcm_to_rotvec(quat_to_dcm(q) @ np.swapaxes(quat_to_dcm(kin.q_nb), -1, -2))
    return pos, v - kin.v_ned_mps, att


def test_stationary_ins_with_perfect_imu_stays_within_1_m_over_10_min() -> None:
    # GIVEN a perfect IMU at rest, tilted and yawed, at 50 deg N
    lat, lon, h = math.radians(50.0), math.radians(10.0), 300.0
    q = euler_to_quat([math.radians(10.0), math.radians(-5.0), math.radians(60.0)])
    dt, n = 0.01, 60_000
    dth, dv = stationary_increments(lat, h, q, dt, n)
    state = strapdown.InsState.from_arrays(lat, lon, h, np.zeros(3), q)
    # WHEN the INS runs for 10 minutes at 100 Hz
    final = strapdown.integrate(state, dth, dv, dt)[-1]
    # THEN it has not moved
    pos = earth.ned_offset_m(final.lat_rad, final.lon_rad, final.alt_msl_m, lat, lon, h)
    assert np.linalg.norm(pos) < 1.0
    assert np.linalg.norm(final.v_ned_mps) < 1e-3
    att = dcm_to_rotvec(quat_to_dcm(final.q_nb) @ quat_to_dcm(q).T)
    assert np.linalg.norm(att) < 1e-9


def test_schuler_oscillation_period_and_amplitude() -> None:
    # GIVEN a resting INS started with a 0.1 m/s north velocity error
    lat, lon, h = math.radians(45.0), 0.0, 0.0
    q = euler_to_quat([0.0, 0.0, 0.0])
    r_m, _ = earth.principal_radii(lat)
    w_s = math.sqrt(earth.gravity(lat, h) / r_m)
    period = 2.0 * math.pi / w_s  # ~84 min
    dt = 0.1
    n = round(period / dt)
    dth, dv = stationary_increments(lat, h, q, dt, n)
    state = strapdown.InsState.from_arrays(lat, lon, h, [0.1, 0.0, 0.0], q)
    # WHEN it runs one Schuler period
    states = strapdown.integrate(state, dth, dv, dt)
    north = np.array([(s.lat_rad - lat) * r_m for s in states])
    # THEN the north error swings with amplitude dv / w_s and comes back after one period
    assert np.max(np.abs(north)) == pytest.approx(0.1 / w_s, rel=0.03)
    assert abs(north[-1]) < 0.03 * 0.1 / w_s
    assert np.argmax(north) == pytest.approx(n / 4, rel=0.03)


def racetrack() -> Flight:
    return Flight(
        duration_s=60.0,
        turns=[(8.0, 28.0, 0.12), (38.0, 55.0, -0.1)],
        climbs=[(5.0, 25.0, 4.0), (35.0, 50.0, -3.0)],
        speed_wave_mps=3.0,
    )


@pytest.fixture(scope="module")
def racetrack_traj() -> SplineTrajectory:
    return racetrack().truth()


@pytest.mark.parametrize("rate_hz", [50, 100, 200, 400])
def test_ideal_imu_reproduces_a_turning_climbing_trajectory(
    racetrack_traj: SplineTrajectory, rate_hz: int
) -> None:
    # GIVEN the ideal increments of coordinated turns, climbs and speed changes
    edges = np.arange(0, 60 * rate_hz + 1) / rate_hz
    inc = ideal_increments(racetrack_traj, edges)
    kin0 = racetrack_traj(edges[:1])
    state = strapdown.InsState.from_arrays(*kin0.lla[0], kin0.v_ned_mps[0], kin0.q_nb[0])
    # WHEN the mechanisation integrates them
    states = strapdown.integrate(state, inc.dtheta_b, inc.dv_b, inc.dt_s)
    pos, vel, att = errors_vs(racetrack_traj, edges, states)
    # THEN it follows the trajectory to millimetres (errors shrink with the square of the step:
    # measured 6.2 mm / 0.21 mm/s at 50 Hz, 0.10 mm / 3.3 um/s at 400 Hz after 60 s)
    tol = (50.0 / rate_hz) ** 2
    assert np.abs(pos).max() < 1e-2 * tol
    assert np.abs(vel).max() < 3e-4 * tol
    assert np.abs(att).max() < 1e-7


def test_coning_and_sculling_compensation() -> None:
    # GIVEN a 5 Hz coning (1 deg) and in-phase sculling motion, sampled at 100 Hz
    lat, lon, h = math.radians(45.0), 0.1, 100.0
    t = np.arange(0.0, 10.0 + 1e-9, 0.0005)
    beta, w = math.radians(1.0), 2.0 * math.pi * 5.0
    rv = np.column_stack([np.zeros_like(t), beta * np.cos(w * t), beta * np.sin(w * t)])
    q = quat_multiply(euler_to_quat([0.1, 0.05, 0.7]), rotvec_to_quat(rv))
    r_m, _ = earth.principal_radii(lat)
    amp = 0.05
    lla = np.column_stack(
        [lat + amp * np.sin(w * t) / (r_m + h), np.full_like(t, lon), np.full_like(t, h)]
    )
    v = np.column_stack([amp * w * np.cos(w * t), np.zeros_like(t), np.zeros_like(t)])
    traj = SplineTrajectory(t, lla, v, q)
    edges = np.arange(0, 1001) / 100.0
    inc = ideal_increments(traj, edges)
    start = strapdown.InsState.from_arrays(*lla[0], v[0], q[0])
    # WHEN integrated with and without the previous-sample coning/sculling terms
    with_comp = strapdown.integrate(start, inc.dtheta_b, inc.dv_b, inc.dt_s)[-1]
    without = start
    for th, dv, dt in zip(inc.dtheta_b.tolist(), inc.dv_b.tolist(), inc.dt_s.tolist(), strict=True):
        without = strapdown.update(without, th, dv, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), dt)
    kin = traj(edges[-1:])

    def err(s: strapdown.InsState) -> tuple[float, float]:
        a = dcm_to_rotvec(quat_to_dcm(s.q_nb) @ quat_to_dcm(kin.q_nb[0]).T)
        return float(np.linalg.norm(a)), float(np.linalg.norm(np.subtract(s.v_ned_mps, v[-1])))

    att_c, vel_c = err(with_comp)
    att_n, vel_n = err(without)
    # THEN the compensation removes most of the coning drift and sculling error
    assert att_c < att_n / 20.0
    assert vel_c < vel_n / 20.0


def test_truth_sequence_to_ideal_imu_samples_round_trip() -> None:
    # GIVEN a Truth sequence at 50 Hz (what sim.flight produces), and the reusable helper
    traj = racetrack().truth()
    times_us = np.arange(0, 60_000_001, 20_000)
    kin = traj(times_us * 1e-6)
    truth = [
        Truth(
            time_us=int(t), lat_rad=float(p[0]), lon_rad=float(p[1]), alt_msl_m=float(p[2]),
            v_ned_mps=v, q_nb=q, omega_b_rps=np.zeros(3), specific_force_b_mps2=np.zeros(3),
            static_pressure_pa=95000.0, temperature_k=280.0, airspeed_mps=40.0,
            indicated_airspeed_mps=38.0,
        )
        for t, p, v, q in zip(times_us, kin.lla, kin.v_ned_mps, kin.q_nb, strict=True)
    ]  # fmt: skip
    # WHEN it makes 200 Hz ImuSamples and the INS integrates them
    imu = ideal_imu_from_truth(truth, 200.0, make=ImuSample)
    assert all(isinstance(s, ImuSample) for s in imu)
    assert len(imu) == 12_000 and imu[0].time_us == 5_000 and imu[-1].time_us == 60_000_000
    dth = np.array([s.angular_rate_b_rps * s.dt_s for s in imu])
    dv = np.array([s.specific_force_b_mps2 * s.dt_s for s in imu])
    state = strapdown.InsState.from_arrays(*kin.lla[0], kin.v_ned_mps[0], kin.q_nb[0])
    states = strapdown.integrate(state, dth, dv, 0.005)
    # THEN the INS reproduces the truth it was made from at every truth epoch
    check = np.arange(0, len(states), 4)  # every 20 ms
    pos, vel, att = errors_vs(spline_from_truth(truth), check * 0.005, [states[i] for i in check])
    assert np.abs(pos).max() < 0.05
    assert np.abs(vel).max() < 5e-3
    assert np.abs(att).max() < 1e-5


def test_ins_state_from_arrays_validates() -> None:
    with pytest.raises(ValueError, match="v_ned_mps"):
        strapdown.InsState.from_arrays(0.0, 0.0, 0.0, [1.0, 2.0], [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="q_nb"):
        strapdown.InsState.from_arrays(0.0, 0.0, 0.0, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 0.0])
    s = strapdown.InsState.from_arrays(0.0, 0.0, 0.0, [1.0, 2.0, 3.0], [2.0, 0.0, 0.0, 0.0])
    assert s.q_nb == (1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        SplineTrajectory(
            [0.0, 0.0], np.zeros((2, 3)), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1))
        )


def reference_update(
    s: strapdown.InsState,
    dth: np.ndarray,
    dv: np.ndarray,
    pdth: np.ndarray,
    pdv: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The module docstring's three steps on numpy vectors and fusion.rotations / the array
    Earth functions (slow, readable): what the scalar hot loop must reproduce."""
    lat, lon, h = s.lat_rad, s.lon_rad, s.alt_msl_m
    v, q = np.array(s.v_ned_mps), np.array(s.q_nb)
    h_mid = h - 0.5 * v[2] * dt
    r_m, r_n = earth.principal_radii(lat)
    g = float(earth.gravity(lat, h_mid))
    w_ie = earth.earth_rate_n(lat)
    # velocity increment in n: rotation + sculling, C_nb(k-1)
    d_n = quat_to_dcm(q) @ (
        dv + np.cross(dth, dv) / 2 + (np.cross(pdth, dv) + np.cross(pdv, dth)) / 12
    )
    v_mid = v + 0.5 * d_n + [0.0, 0.0, 0.5 * g * dt]
    w_en = np.array([v_mid[1] / (r_n + h_mid), -v_mid[0] / (r_m + h_mid),
                     -v_mid[1] * math.tan(lat) / (r_n + h_mid)])  # fmt: skip
    zeta = (w_ie + w_en) * dt
    # 1. attitude
    phi = dth + np.cross(pdth, dth) / 12
    q_new = quat_multiply(rotvec_to_quat(-zeta), quat_multiply(q, rotvec_to_quat(phi)))
    q_new = q_new / np.linalg.norm(q_new) * np.sign(q_new[0])
    # 2. velocity
    v_new = (
        v
        + d_n
        - 0.5 * np.cross(zeta, d_n)
        + ([0.0, 0.0, g] - np.cross(2 * w_ie + w_en, v_mid)) * dt
    )
    # 3. position
    h_new = h - 0.5 * (v[2] + v_new[2]) * dt
    h_avg = 0.5 * (h + h_new)
    dlat = 0.5 * (v[0] + v_new[0]) * dt / (r_m + h_avg)
    c_mid = math.cos(lat) - 0.5 * math.sin(lat) * dlat
    dlon = 0.5 * (v[1] + v_new[1]) * dt / ((r_n + h_avg) * c_mid)
    return np.array([lat + dlat, lon + dlon, h_new]), v_new, q_new


@pytest.mark.parametrize("rate_scale", [1.0, 20.0])  # 20: |phi| > 0.01 rad, the exact branch
def test_scalar_update_matches_the_vector_reference_to_round_off(rate_scale: float) -> None:
    # GIVEN random states (latitudes to 80 deg, heights to 12 km, 250 m/s) and increments
    rng = np.random.default_rng(3)
    for _ in range(200):
        q = rng.normal(size=4)
        state = strapdown.InsState.from_arrays(
            rng.uniform(-1.4, 1.4), rng.uniform(-3.0, 3.0), rng.uniform(-100.0, 12_000.0),
            rng.normal(scale=150.0, size=3), q * np.sign(q[0]),
        )  # fmt: skip
        dt = float(rng.choice([0.0025, 0.005, 0.01]))
        dth, pdth = rng.normal(scale=0.2 * rate_scale * dt, size=(2, 3))
        dv, pdv = rng.normal(scale=20.0 * dt, size=(2, 3))
        # WHEN the hot-loop update and the vector reference advance it
        new = strapdown.update(state, tuple(dth), tuple(dv), tuple(pdth), tuple(pdv), dt)
        lla, v, q_ref = reference_update(state, dth, dv, pdth, pdv, dt)
        # THEN they agree to round-off (1e-15 rad is 6 nm)
        assert new.lat_rad == pytest.approx(lla[0], abs=1e-15)
        assert new.lon_rad == pytest.approx(lla[1], abs=1e-14)
        assert new.alt_msl_m == pytest.approx(lla[2], abs=1e-9)
        np.testing.assert_allclose(new.v_ned_mps, v, rtol=0, atol=1e-11)
        np.testing.assert_allclose(new.q_nb, q_ref, rtol=0, atol=1e-15)


def test_compensated_increments_invert_the_full_sensor_model() -> None:
    """A sensor ``f~ = (I + diag(s) + M) f + b`` read through ``increments_compensated`` with
    the exact ``s``, ``M``, ``b`` gives back ``f dt`` (likewise the gyro), and with ``M = 0``
    it equals the scale-only path."""
    rng = np.random.default_rng(8)
    scale_a, scale_g = rng.normal(0, 5e-3, 3), rng.normal(0, 5e-3, 3)
    mis_a, mis_g = rng.normal(0, 1e-2, 6), rng.normal(0, 1e-2, 6)
    ba, bg = rng.normal(0, 0.05, 3), rng.normal(0, 1e-3, 3)

    def matrix(s: np.ndarray, m: np.ndarray) -> np.ndarray:
        t = np.eye(3) + np.diag(s)
        t[[0, 0, 1, 1, 2, 2], [1, 2, 0, 2, 0, 1]] += m
        return t

    f, w, dt = np.array([1.2, -0.4, -9.6]), np.array([0.3, -0.2, 0.5]), 0.005
    fw = (*(matrix(scale_a, mis_a) @ f + ba), *(matrix(scale_g, mis_g) @ w + bg))
    inv_a = strapdown.sensor_inverse(tuple(scale_a), tuple(mis_a))
    inv_g = strapdown.sensor_inverse(tuple(scale_g), tuple(mis_g))
    dth, dv = strapdown.increments_compensated(fw, dt, tuple(ba), tuple(bg), inv_a, inv_g)
    # exact inverse: only round-off of a 3x3 solve with condition ~1 (|s|, |m| << 1)
    np.testing.assert_allclose(dv, f * dt, rtol=0, atol=1e-13)
    np.testing.assert_allclose(dth, w * dt, rtol=0, atol=1e-14)
    zero6 = (0.0,) * 6
    fw0 = (*(f * (1 + scale_a) + ba), *(w * (1 + scale_g) + bg))
    scaled = strapdown.increments_scaled(fw0, dt, tuple(ba), tuple(bg), tuple(scale_a),
                                         tuple(scale_g))
    full = strapdown.increments_compensated(
        fw0, dt, tuple(ba), tuple(bg), strapdown.sensor_inverse(tuple(scale_a), zero6),
        strapdown.sensor_inverse(tuple(scale_g), zero6),
    )
    np.testing.assert_allclose(np.ravel(full), np.ravel(scaled), rtol=1e-14, atol=1e-16)
