"""The pitot-static sensor model (sim.pitot), its presets, its place in the sensor suite, and
the barometer's static-port position error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from physconst.airdata import air_density_kgpm3, impact_pressure_pa, true_airspeed_mps
from sim.baro import BaroConfig, BaroModel
from sim.pitot import PitotConfig, PitotModel, air_velocity_b_mps, probe_misalignment_factor
from sim.presets import available_pitot_presets, pitot_preset, suite_config
from sim.samples import AirspeedSample, Truth
from sim.sensors import SensorSuite

P_PA = 89_875.0  # ~1000 m
T_K = 281.65
TAS = 50.0


def air_truth(
    k: int,
    rate_hz: float = 50.0,
    *,
    tas_mps: float = TAS,
    alpha_rad: float = 0.0,
    beta_rad: float = 0.0,
) -> Truth:
    """Straight flight north at ``tas_mps`` in still air (synthetic truth, no JSBSim)."""
    return Truth(
        time_us=round(k * 1e6 / rate_hz),
        lat_rad=math.radians(47.0),
        lon_rad=math.radians(8.0),
        alt_msl_m=1000.0,
        v_ned_mps=np.array([tas_mps, 0.0, 0.0]),
        q_nb=np.array([1.0, 0.0, 0.0, 0.0]),
        omega_b_rps=np.zeros(3),
        specific_force_b_mps2=np.array([0.0, 0.0, -9.80665]),
        static_pressure_pa=P_PA,
        temperature_k=T_K,
        airspeed_mps=tas_mps,
        indicated_airspeed_mps=tas_mps,
        alpha_rad=alpha_rad,
        beta_rad=beta_rad,
    )


def readings(config: PitotConfig, seed: int, n: int, **truth: float) -> np.ndarray:
    model = PitotModel(config, np.random.default_rng(seed))
    return np.array([model.measure(air_truth(k, **truth)).diff_pressure_pa for k in range(n)])


Q_C = impact_pressure_pa(TAS, P_PA, T_K)


def test_ideal_sensor_reads_the_isentropic_impact_pressure_exactly() -> None:
    model = PitotModel(pitot_preset("ideal"), np.random.default_rng(0))  # type: ignore[arg-type]
    s = model.measure(air_truth(0))
    assert isinstance(s, AirspeedSample)
    assert s.diff_pressure_pa == Q_C and s.temperature_k == T_K
    # and inverts to the truth's airspeed (the relations round-trip to rounding)
    assert true_airspeed_mps(s.diff_pressure_pa, P_PA, T_K) == pytest.approx(TAS, rel=1e-12)
    # compressibility: above the incompressible q by about M²/4
    q_inc = 0.5 * air_density_kgpm3(P_PA, T_K) * TAS**2
    assert 1.004 < Q_C / q_inc < 1.006


def test_white_noise_matches_its_configured_sigma() -> None:
    sigma, n = 2.0, 20_000
    e = readings(PitotConfig(noise_pa=sigma), seed=4, n=n) - Q_C
    # mean: 5 standard errors; standard deviation: 5 standard errors of a sample sd (1/√2n)
    assert abs(e.mean()) < 5.0 * sigma / math.sqrt(n)
    assert abs(e.std(ddof=1) / sigma - 1.0) < 5.0 / math.sqrt(2.0 * n)


def test_turn_on_offset_and_scale_are_per_seed_draws_of_their_sigma() -> None:
    cfg = PitotConfig(noise_pa=0.0, offset_sigma_pa=1.5, scale_error_sigma=0.02)
    seeds = 600
    offsets, scales = [], []
    for seed in range(seeds):
        m = PitotModel(cfg, np.random.default_rng(seed))
        dp = m.measure(air_truth(0)).diff_pressure_pa
        assert dp == pytest.approx(Q_C * m.scale + m.turn_on_offset_pa, rel=1e-14)
        offsets.append(m.turn_on_offset_pa)
        scales.append(m.scale - 1.0)
    tol = 5.0 / math.sqrt(2.0 * seeds)  # relative standard error of a sample sd, 5x
    assert abs(np.std(offsets, ddof=1) / 1.5 - 1.0) < tol
    assert abs(np.std(scales, ddof=1) / 0.02 - 1.0) < tol
    assert abs(np.mean(offsets)) < 5.0 * 1.5 / math.sqrt(seeds)


def test_offset_random_walk_grows_with_the_square_root_of_time() -> None:
    rw, dt_s, steps, seeds = 0.5, 0.1, 400, 300  # 40 s at 10 Hz
    cfg = PitotConfig(noise_pa=0.0, offset_random_walk_pa_per_rth=rw)
    final = []
    for seed in range(seeds):
        m = PitotModel(cfg, np.random.default_rng(seed))
        for k in range(steps + 1):
            m.measure(air_truth(k, rate_hz=1.0 / dt_s))
        final.append(m.offset_drift_pa)
    want = rw * math.sqrt(steps * dt_s)
    assert abs(np.std(final, ddof=1) / want - 1.0) < 5.0 / math.sqrt(2.0 * seeds)


def test_gauss_markov_offset_keeps_its_stationary_sigma() -> None:
    sigma, seeds = 3.0, 400
    cfg = PitotConfig(noise_pa=0.0, offset_gm_sigma_pa=sigma, offset_gm_tau_s=60.0)
    values = []
    for seed in range(seeds):
        m = PitotModel(cfg, np.random.default_rng(seed))
        for k in range(101):  # 100 s at 1 Hz: past the correlation time
            m.measure(air_truth(k, rate_hz=1.0))
        values.append(m.offset_drift_pa)
    assert abs(np.std(values, ddof=1) / sigma - 1.0) < 5.0 / math.sqrt(2.0 * seeds)


def test_probe_misalignment_loses_impact_pressure_with_the_square_of_the_flow_angle() -> None:
    cfg = PitotConfig(noise_pa=0.0, k_alpha_per_rad2=0.3, k_beta_per_rad2=0.5,
                      probe_incidence_deg=2.0)
    a, b = 0.1, -0.05
    (dp,) = readings(cfg, 0, 1, alpha_rad=a, beta_rad=b)
    g = 1.0 - 0.3 * (a - math.radians(2.0)) ** 2 - 0.5 * b**2
    assert dp == pytest.approx(Q_C * g, rel=1e-14)
    assert probe_misalignment_factor(math.nan, math.nan, 0.3, 0.5) == 1.0  # unknown angles
    assert probe_misalignment_factor(3.0, 0.0, 1.0, 0.0) == 0.0  # never negative


def test_static_position_error_is_linear_in_the_angle_of_attack() -> None:
    # GIVEN a static port whose error is 0.3 of q_c per rad of angle of attack
    cfg = PitotConfig(noise_pa=0.0, static_error_alpha_per_rad=0.3, probe_incidence_deg=1.0)
    # THEN the sensed pressure is q_c (1 - 0.3 (alpha - alpha_probe)) at every angle
    for a in (-0.02, 0.05, 0.15):
        (dp,) = readings(cfg, 0, 1, alpha_rad=a)
        assert dp == pytest.approx(Q_C * (1.0 - 0.3 * (a - math.radians(1.0))), rel=1e-14)
    # and an unknown angle (truth decoded from MAVLink) adds nothing
    (dp,) = readings(cfg, 0, 1, alpha_rad=math.nan)
    assert dp == Q_C
    # AND the -pe presets are the plain sensors with this error; the plain ones have none
    for name in ("ms4525do", "sdp33"):
        plain, pe = pitot_preset(name), pitot_preset(f"{name}-pe")
        assert plain is not None and pe is not None and plain.static_error_alpha_per_rad == 0.0
        assert pe == plain.model_copy(update={"static_error_alpha_per_rad": 0.3})


def test_lag_is_the_exact_first_order_response() -> None:
    tau, rate = 0.2, 50.0
    m = PitotModel(PitotConfig(noise_pa=0.0, lag_time_constant_s=tau), np.random.default_rng(0))
    m.measure(air_truth(0, tas_mps=20.0))
    q0, q1 = impact_pressure_pa(20.0, P_PA, T_K), impact_pressure_pa(40.0, P_PA, T_K)
    for k in range(1, 26):
        dp = m.measure(air_truth(k, tas_mps=40.0)).diff_pressure_pa
        want = q1 + (q0 - q1) * math.exp(-k / (rate * tau))
        assert dp == pytest.approx(want, rel=1e-12)


def test_resolution_and_range() -> None:
    ms = pitot_preset("ms4525do")
    assert ms is not None and ms.resolution_pa is not None
    dp = readings(ms, 1, 200)
    assert np.allclose(dp / ms.resolution_pa, np.round(dp / ms.resolution_pa), atol=1e-9)
    sdp = pitot_preset("sdp33")
    assert sdp is not None
    fast = readings(sdp, 1, 5, tas_mps=80.0)  # q_c ~ 3.6 kPa, beyond ±1500 Pa
    assert np.all(fast == 1500.0)


def test_presets_are_listed_with_none_for_no_pitot() -> None:
    assert set(available_pitot_presets()) == {"ideal", "ms4525do", "ms4525do-pe", "none",
                                             "sdp33", "sdp33-pe"}
    assert pitot_preset("none") is None
    with pytest.raises(ValueError, match="valid choices: ideal, ms4525do, ms4525do-pe, none"):
        pitot_preset("pitot-9000")
    with pytest.raises(ValidationError, match="noise_pa"):
        PitotConfig(noise_pa=-1.0)


def test_same_seed_same_stream_other_seed_other_stream() -> None:
    cfg = pitot_preset("ms4525do")
    assert cfg is not None
    a, b, c = readings(cfg, 7, 300), readings(cfg, 7, 300), readings(cfg, 8, 300)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def _suite_stream(pitot: str, seed: int = 11, steps: int = 1000) -> list[object]:
    suite = SensorSuite(suite_config(pitot=pitot), seed=seed, sim_rate_hz=200.0)
    out: list[object] = []
    for k in range(steps):
        out.extend(suite.step(air_truth(k, rate_hz=200.0, alpha_rad=0.05)))
    return out


def _as_bytes(s: object) -> tuple[object, ...]:
    return (type(s).__name__, *(np.asarray(getattr(s, f)).tobytes() for f in s.__slots__))  # type: ignore[attr-defined]


def test_fitting_a_pitot_leaves_every_other_stream_bit_identical() -> None:
    with_pitot, without = _suite_stream("ms4525do"), _suite_stream("none")
    airspeed = [s for s in with_pitot if isinstance(s, AirspeedSample)]
    assert len(airspeed) == 250  # 5 s at 50 Hz
    assert not any(isinstance(s, AirspeedSample) for s in without)
    others = [_as_bytes(s) for s in with_pitot if not isinstance(s, AirspeedSample)]
    assert others == [_as_bytes(s) for s in without]


def test_suite_rejects_a_pitot_rate_above_the_simulation_rate() -> None:
    with pytest.raises(ValueError, match="pitot_rate_hz"):
        SensorSuite(suite_config(pitot_rate_hz=400.0), seed=0, sim_rate_hz=200.0)
    SensorSuite(suite_config(pitot="none", pitot_rate_hz=400.0), seed=0, sim_rate_hz=200.0)


# --------------------------------------------------------------------- baro position error


def test_air_velocity_from_alpha_beta_follows_jsbsim_definitions() -> None:
    u, v, w = air_velocity_b_mps(air_truth(0, alpha_rad=0.1, beta_rad=0.05))
    assert math.hypot(u, v, w) == pytest.approx(TAS, rel=1e-14)
    assert math.atan2(w, u) == pytest.approx(0.1, rel=1e-12)
    assert math.asin(v / TAS) == pytest.approx(0.05, rel=1e-12)


def test_static_port_error_is_coefficient_times_dynamic_pressure_by_direction() -> None:
    cfg = BaroConfig(
        noise_pa=0.0, position_error_fwd=-0.02, position_error_bck=0.5,
        position_error_rgt=-0.1, position_error_lft=0.2, position_error_dn=0.03,
        position_error_up=-0.4,
    )
    plain = BaroModel(BaroConfig(noise_pa=0.0), np.random.default_rng(0))
    model = BaroModel(cfg, np.random.default_rng(0))
    p0 = plain.measure(0, 1000.0).pressure_pa
    t0 = plain.measure(0, 1000.0).temperature_k
    rho = air_density_kgpm3(p0, t0)
    for vel, coeff in (
        ((50.0, 4.0, 3.0), (-0.02, -0.1, 0.03)),
        ((50.0, -4.0, -3.0), (-0.02, 0.2, -0.4)),
        ((-5.0, 0.0, 0.0), (0.5, 0.0, 0.0)),
    ):
        got = model.measure(0, 1000.0, vel).pressure_pa - p0
        want = 0.5 * rho * sum(c * x * x for c, x in zip(coeff, vel, strict=True))
        assert got == pytest.approx(want, rel=1e-9, abs=1e-9)


def test_baro_without_position_error_ignores_the_air_velocity_bit_for_bit() -> None:
    cfg = suite_config().baro
    a = BaroModel(cfg, np.random.default_rng(5))
    b = BaroModel(cfg, np.random.default_rng(5))
    for k in range(300):
        t = k * 20_000
        assert a.measure(t, 1000.0) == b.measure(t, 1000.0, (50.0, 1.0, 2.0))
