"""fusion.error_model: the analytic F against a numerically propagated, perturbed INS."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion import earth, strapdown
from fusion.error_model import ErrorModel, ProcessNoise
from fusion.rotations import (
    dcm_from_quat,
    dcm_to_rotvec,
    quat_multiply,
    quat_to_dcm,
    rotvec_to_quat,
)
from fusion.state_layout import (
    INS16,
    INS16_GNSS,
    INS22,
    INS22_GNSS,
    INS35,
    INS35_GNSS,
    OFF_DIAGONAL,
    StateLayout,
)
from fusion.trajectory import ImuIncrements, ideal_increments
from tests.helpers.nav_synth import Flight

NOISE = ProcessNoise(
    gyro_noise=1e-4, accel_noise=1e-3,
    gyro_bias_sigma=5e-5, gyro_bias_tau_s=300.0,
    accel_bias_sigma=1e-2, accel_bias_tau_s=200.0,
    baro_bias_sigma=5.0, baro_bias_tau_s=500.0,
    gyro_scale_sigma=1e-3, gyro_scale_tau_s=1000.0,
    accel_scale_sigma=1e-3, accel_scale_tau_s=800.0,
    gnss_bias_sigma_h_m=1.4, gnss_bias_sigma_v_m=2.4,
    gnss_bias_tau_h_s=120.0, gnss_bias_tau_v_s=90.0,
    gyro_misalignment_sigma=1e-3, accel_misalignment_sigma=1e-3,
)  # fmt: skip


@pytest.fixture(scope="module")
def segment() -> tuple[ImuIncrements, object]:
    """2 s of a climbing, accelerating 0.12 rad/s turn at 60 deg N, ideal IMU at 100 Hz."""
    flight = Flight(
        duration_s=30.0, turns=[(5.0, 25.0, 0.12)], climbs=[(5.0, 25.0, 4.0)],
        speed_wave_mps=3.0, lat0_rad=math.radians(60.0),
    )  # fmt: skip
    traj = flight.truth()
    edges = 12.0 + np.arange(0, 201) / 100.0
    return ideal_increments(traj, edges), traj(edges[:1])


def start_state(kin0: object, dx: np.ndarray) -> strapdown.InsState:
    """True start state plus navigation error ``dx[:9]`` (estimated minus true)."""
    lat, lon, h = kin0.lla[0]  # type: ignore[attr-defined]
    t = earth.local_terms(lat, h)
    return strapdown.InsState.from_arrays(
        lat + dx[0] / t.rho_n_m,
        lon + dx[1] / (t.rho_e_m * t.cos_lat),
        h - dx[2],
        kin0.v_ned_mps[0] + dx[3:6],  # type: ignore[attr-defined]
        quat_multiply(rotvec_to_quat(dx[6:9]), kin0.q_nb[0]),  # type: ignore[attr-defined]
    )


def perturbed_run(
    layout: StateLayout, inc: ImuIncrements, kin0: object, dx: np.ndarray
) -> strapdown.InsState:
    """Run the INS from the true start plus error ``dx`` (estimated minus true); sensor-error
    estimates wrong by ``dx`` stay wrong by that much (random constants)."""
    state = start_state(kin0, dx)
    prev = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    for k, dt in enumerate(inc.dt_s.tolist()):
        dv = inc.dv_b[k] - dx[layout.ba] * dt
        th = inc.dtheta_b[k] - dx[layout.bg] * dt
        if layout.ma is not None and layout.mg is not None:
            dv = np.linalg.solve(sensor_matrix(layout, dx, "a"), dv)
            th = np.linalg.solve(sensor_matrix(layout, dx, "g"), th)
        elif layout.sa is not None and layout.sg is not None:
            dv = dv / (1.0 + dx[layout.sa])
            th = th / (1.0 + dx[layout.sg])
        th_t, dv_t = tuple(th.tolist()), tuple(dv.tolist())
        state = strapdown.update(state, th_t, dv_t, *prev, dt)
        prev = (th_t, dv_t)
    return state


def sensor_matrix(layout: StateLayout, dx: np.ndarray, triad: str) -> np.ndarray:
    """``I + diag(ds) + dM`` of the estimate errors in ``dx``."""
    scale, mis = (layout.sa, layout.ma) if triad == "a" else (layout.sg, layout.mg)
    assert scale is not None and mis is not None
    t = np.eye(3) + np.diag(dx[scale])
    for (i, j), m in zip(OFF_DIAGONAL, dx[mis], strict=True):
        t[i, j] += m
    return t


def nav_error(a: strapdown.InsState, b: strapdown.InsState) -> np.ndarray:
    e = np.zeros(9)
    e[0:3] = earth.ned_offset_m(
        a.lat_rad, a.lon_rad, a.alt_msl_m, b.lat_rad, b.lon_rad, b.alt_msl_m
    )
    e[3:6] = np.subtract(a.v_ned_mps, b.v_ned_mps)
    e[6:9] = dcm_to_rotvec(quat_to_dcm(a.q_nb) @ quat_to_dcm(b.q_nb).T)
    return e


def analytic_transition(model: ErrorModel, inc: ImuIncrements, kin0: object) -> np.ndarray:
    """Product of per-step transitions along the nominal INS path."""
    lay = model.layout
    states = [start_state(kin0, np.zeros(lay.n))]
    prev = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    phi = np.eye(lay.n)
    for k, dt in enumerate(inc.dt_s.tolist()):
        th, dv = tuple(inc.dtheta_b[k].tolist()), tuple(inc.dv_b[k].tolist())
        s0 = states[-1]
        s1 = strapdown.update(s0, th, dv, *prev, dt)
        prev = (th, dv)
        states.append(s1)
        t = earth.local_terms(s1.lat_rad, s1.alt_msl_m)
        vn, ve, vd = s1.v_ned_mps
        tan = t.sin_lat / t.cos_lat
        cx = 2.0 * earth.RATE * t.cos_lat + ve / t.rho_e_m
        cy = -vn / t.rho_n_m
        cz = -2.0 * earth.RATE * t.sin_lat - ve * tan / t.rho_e_m
        v0 = s0.v_ned_mps
        f_n = (
            (vn - v0[0]) / dt + (cy * vd - cz * ve),
            (ve - v0[1]) / dt + (cz * vn - cx * vd),
            (vd - v0[2]) / dt - t.gravity_mps2 + (cx * ve - cy * vn),
        )
        f = model.continuous_matrix(
            s1.lat_rad, s1.alt_msl_m, s1.v_ned_mps, dcm_from_quat(s1.q_nb), f_n,
            tuple((inc.dv_b[k] / dt).tolist()), tuple((inc.dtheta_b[k] / dt).tolist()),
        )  # fmt: skip
        phi = model.transition_matrix(f, dt) @ phi
    return phi


# perturbation sizes: small enough to stay linear, large enough to beat rounding (the GNSS
# bias states of the "+gnss" layouts follow the baro bias or the scale factors: 1 m)
EPS = [10.0] * 3 + [0.1] * 3 + [1e-3] * 3 + [1e-2] * 3 + [1e-4] * 3 + [1.0] + [1e-3] * 19


def eps_for(layout: StateLayout) -> list[float]:
    eps = EPS[: layout.n]
    if layout.gnss is not None:
        eps = EPS[: layout.GNSS] + [1.0] * 3
    return eps


@pytest.mark.parametrize(
    "layout", [INS16, INS22, INS22_GNSS, INS35, INS35_GNSS], ids=lambda lay: lay.name
)
def test_F_matches_numerical_propagation_of_a_perturbed_ins(layout: StateLayout, segment) -> None:
    inc, kin0 = segment
    model = ErrorModel(layout, NOISE)
    phi = analytic_transition(model, inc, kin0)
    nominal = perturbed_run(layout, inc, kin0, np.zeros(layout.n))
    eye = np.eye(layout.n)
    eps = eps_for(layout)
    for j in range(layout.n):
        dx = np.zeros(layout.n)
        dx[j] = eps[j]
        # central difference of the navigation error after 2 s (a GNSS-bias error does not
        # enter the INS: its columns must come out zero)
        num = (
            nav_error(perturbed_run(layout, inc, kin0, dx), nominal)
            - nav_error(perturbed_run(layout, inc, kin0, -dx), nominal)
        ) / (2.0 * eps[j])
        col_scale = np.abs(phi[:9, j]).max()
        for blk in (slice(0, 3), slice(3, 6), slice(6, 9)):
            # compare Phi - I per block so that small couplings (transport rate, gravity
            # gradient, Earth rate) are checked against their own size, not against the 1s
            an = phi[blk, j] - eye[blk, j]
            nm = num[blk] - eye[blk, j]
            tol = 1e-2 * np.abs(an).max() + 1e-9 * col_scale
            np.testing.assert_allclose(
                nm, an, rtol=0.0, atol=tol, err_msg=f"{layout.labels[j]} -> rows {blk}"
            )
    # the IMU error states are random constants (plus random walks): they do not decay
    imu_states = [*range(layout.BA, layout.BG + 3)]
    imu_states += [] if layout.sa is None else [*range(layout.SA, layout.SG + 3)]
    imu_states += [] if layout.ma is None else [*range(layout.MA, layout.MG + 6)]
    imu_states += [] if layout.bs is None else [layout.BS]  # the baro scale likewise
    np.testing.assert_array_equal(np.diag(phi)[imu_states], 1.0)
    # the baro and GNSS bias states (zero-mean processes) decay with their correlation times
    tau = {layout.BARO: NOISE.baro_bias_tau_s}
    if layout.gnss is not None:
        g = layout.GNSS
        tau |= {g: NOISE.gnss_bias_tau_h_s, g + 1: NOISE.gnss_bias_tau_h_s,
                g + 2: NOISE.gnss_bias_tau_v_s}  # fmt: skip
        # the bias block is decoupled from the INS both ways
        others = [i for i in range(layout.n) if i not in range(g, g + 3)]
        np.testing.assert_array_equal(phi[np.ix_(others, range(g, g + 3))], 0.0)
        np.testing.assert_array_equal(phi[np.ix_(range(g, g + 3), others)], 0.0)
    for i, t in tau.items():
        assert phi[i, i] == pytest.approx(math.exp(-2.0 / t), rel=1e-6)


def test_gnss_bias_block_of_f_and_q() -> None:
    # GIVEN the INS16 layout with and without the GNSS bias block
    args = (0.9, 800.0, (40.0, -10.0, 2.0), (1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0), (0.5, -1.0, -9.7))
    f16 = ErrorModel(INS16, NOISE).continuous_matrix(*args)
    model = ErrorModel(INS16_GNSS, NOISE)
    f = model.continuous_matrix(*args)
    g = INS16_GNSS.gnss
    assert g is not None
    # THEN the INS part of F is unchanged and the bias block is -1/tau on its diagonal only
    np.testing.assert_array_equal(f[:16, :16], f16)
    np.testing.assert_array_equal(f[:16, g], 0.0)
    np.testing.assert_array_equal(f[g, :16], 0.0)
    np.testing.assert_allclose(
        f[g, g], -np.diag([1 / 120.0, 1 / 120.0, 1 / 90.0]), rtol=1e-15
    )
    # AND Q holds the exact discrete Gauss-Markov variance sigma^2 (1 - exp(-2 T / tau))
    q = np.diag(model.process_noise(0.2))
    np.testing.assert_allclose(q[g], [1.4**2 * (1 - math.exp(-0.4 / 120.0))] * 2
                               + [2.4**2 * (1 - math.exp(-0.4 / 90.0))])  # fmt: skip


def test_first_order_transition_and_process_noise() -> None:
    model = ErrorModel(INS22, NOISE)
    args = (0.9, 800.0, (40.0, -10.0, 2.0), (1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0), (0.5, -1.0, -9.7),
            0.01, (0.3, 0.2, -9.8), (0.01, 0.02, 0.1))  # fmt: skip
    f = model.continuous_matrix(*args[:5], *args[6:])
    np.testing.assert_allclose(
        model.first_order_transition(*args), np.eye(22) + 0.01 * f, atol=1e-15
    )
    # the propagation's in-place form: the same bits, whatever the previous call wrote
    fresh = model.first_order_transition(*args)
    other = (0.2, 10.0, (-5.0, 3.0, -1.0), args[3], (2.0, 1.0, -9.0), 0.01, (1.0, -2.0, -9.0),
             (0.5, -0.4, 0.3))  # fmt: skip
    model.first_order_transition(*other, scratch=True)
    again = model.first_order_transition(*args, scratch=True)
    np.testing.assert_array_equal(again.view(np.int64), fresh.view(np.int64))
    assert model.first_order_transition(*args, scratch=True) is again
    q = np.diag(model.process_noise(0.01))
    lay = INS22
    np.testing.assert_allclose(q[lay.vel], NOISE.accel_noise**2 * 0.01)
    np.testing.assert_allclose(q[lay.att], NOISE.gyro_noise**2 * 0.01)
    gm = NOISE.gyro_bias_sigma**2 * (1.0 - math.exp(-0.02 / NOISE.gyro_bias_tau_s))
    np.testing.assert_allclose(q[lay.bg], gm)
    assert q[lay.POS] == 0.0


@pytest.mark.parametrize("lat_deg", [0.0, 47.0, -75.0])
def test_position_and_velocity_couplings_match_the_continuous_equations(lat_deg: float) -> None:
    """F_vr, F_vv, F_phi,r, F_phi,v against finite differences of v' = f + g - (2 w_ie + w_en) × v
    and of -omega_in (the attitude error picks up -d omega_in)."""
    lat, h = math.radians(lat_deg), 1200.0
    v = np.array([45.0, -30.0, 3.0])
    f_n = (0.5, -1.0, -9.7)
    model = ErrorModel(INS16, NOISE)
    c_nb = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    F = model.continuous_matrix(lat, h, tuple(v), c_nb, f_n)
    lay = INS16

    def rates(dr: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r_m, _ = earth.principal_radii(lat)
        la, hh, vv = lat + dr[0] / (r_m + h), h - dr[2], v + dv
        w_ie = earth.earth_rate_n(la)
        w_en = earth.transport_rate_n(la, hh, vv)
        g_n = np.array([0.0, 0.0, earth.gravity(la, hh)])
        v_dot = np.array(f_n) + g_n - np.cross(2 * w_ie + w_en, vv)
        return v_dot, -(w_ie + w_en)

    for blk, eps in ((lay.pos, 1.0), (lay.vel, 1e-3)):
        for i in range(3):
            d = np.zeros(3)
            d[i] = eps
            args_p = (d, np.zeros(3)) if blk == lay.pos else (np.zeros(3), d)
            args_m = (-d, np.zeros(3)) if blk == lay.pos else (np.zeros(3), -d)
            vp, wp = rates(*args_p)
            vm, wm = rates(*args_m)
            col = blk.start + i
            for rows, num in ((lay.vel, (vp - vm) / (2 * eps)), (lay.att, (wp - wm) / (2 * eps))):
                an = F[rows, col]
                scale = max(np.abs(F[rows, blk]).max(), 1e-15)
                np.testing.assert_allclose(
                    an, num, rtol=0.0, atol=1e-2 * scale, err_msg=f"rows {rows} col {col}"
                )
